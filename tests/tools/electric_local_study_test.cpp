// electric_local_study_test.cpp - tools/electric_local_study end to end on a small slab: a row
// per model (the region covering the body, the held far field and the coarse grid, each
// alone or with a region of each margin), its self-check (the whole-body region equals the
// full solve), and what every row must satisfy whatever the mesh: each model keeps the
// Dirichlet values and minimizes the energy over its functions, so its power never falls
// below the truth's and its excess never grows with the region; bad arguments exit 2 naming
// them. Times are never asserted.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tests/tools/cli_test_util.h"

namespace {

using esim::cli_test::shell;

std::string study(const std::string& args) {
  return std::string("\"") + ELECTRIC_LOCAL_STUDY_EXE + "\" " + args;
}

struct Row {
  double nodes = -1, powerExcess = -1, nearErr = -1, l2 = -1, phiErr = -1;
};

// the table's rows by name: "| name | nodes | build | solve | cb / cs | excess | near | L2 | phi |"
std::map<std::string, Row> tableRows(const std::string& output, double& check) {
  std::map<std::string, Row> rows;
  std::istringstream lines(output);
  std::string line;
  check = -1;
  while (std::getline(lines, line)) {
    std::sscanf(line.c_str(),
                "check: the whole-body region against the truth, relative difference %lf", &check);
    if (line.rfind("| ", 0) != 0 || line.find("---") != std::string::npos) continue;
    std::vector<std::string> cells;
    std::istringstream in(line.substr(1));
    std::string cell;
    while (std::getline(in, cell, '|')) cells.push_back(cell.substr(1, cell.size() - 2));
    if (cells.size() != 9 || cells[0] == "model") continue;
    Row row;
    row.nodes = std::stod(cells[1]);
    row.powerExcess = std::stod(cells[5]);
    row.nearErr = std::stod(cells[6]);
    row.l2 = std::stod(cells[7]);
    row.phiErr = std::stod(cells[8]);
    rows[cells[0]] = row;
  }
  return rows;
}

TEST(ElectricLocalStudy, PrintsARowPerModelAndTheWholeBodyEqualsTheFullSolve) {
  const auto r = shell(study("1500 3 6 --frames 4 --lag 2"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  double check = -1;
  std::map<std::string, Row> rows = tableRows(r.output, check);
  ASSERT_EQ(rows.size(), 6u) << r.output;
  for (const char* name :
       {"whole (check)", "held 3.0 mm", "held 6.0 mm", "coarse", "coarse+3.0 mm", "coarse+6.0 mm"})
    ASSERT_EQ(rows.count(name), 1u) << name << "\n" << r.output;
  EXPECT_GE(check, 0.0) << r.output;
  EXPECT_LT(check, 1e-10) << r.output;
  const Row& whole = rows["whole (check)"];
  EXPECT_LT(std::abs(whole.powerExcess), 1e-12) << r.output;
  EXPECT_LT(whole.nearErr, 1e-12) << r.output;
  EXPECT_LT(whole.phiErr, 1e-12) << r.output;
  // regions grow with the margin; the coarse solve alone has none
  EXPECT_EQ(rows["coarse"].nodes, 0.0) << r.output;
  EXPECT_GT(rows["held 3.0 mm"].nodes, 0.0) << r.output;
  EXPECT_GT(rows["held 6.0 mm"].nodes, rows["held 3.0 mm"].nodes) << r.output;
  EXPECT_GT(whole.nodes, rows["held 6.0 mm"].nodes) << r.output;
  EXPECT_EQ(rows["coarse+6.0 mm"].nodes, rows["held 6.0 mm"].nodes) << r.output;
  // the energy's minimum over nested spaces: no model's power is below the truth's, and
  // a wider region never raises the excess (3 significant digits printed)
  for (const auto& [name, row] : rows)
    EXPECT_GE(row.powerExcess, -1e-12) << name << "\n" << r.output;
  const double slack = 1.006;
  EXPECT_GT(rows["coarse"].powerExcess, 1e-4) << r.output;  // the coarse grid alone is not exact
  EXPECT_LE(rows["coarse+3.0 mm"].powerExcess, rows["coarse"].powerExcess * slack) << r.output;
  EXPECT_LE(rows["coarse+6.0 mm"].powerExcess, rows["coarse+3.0 mm"].powerExcess * slack)
      << r.output;
  EXPECT_GT(rows["held 3.0 mm"].powerExcess, 1e-4) << r.output;  // the moved tool is felt
  EXPECT_LE(rows["held 6.0 mm"].powerExcess, rows["held 3.0 mm"].powerExcess * slack) << r.output;
}

TEST(ElectricLocalStudy, BadArgumentsExitTwoNamingThem) {
  const std::pair<const char*, const char*> cases[] = {
      {"8k", "FINE_NODES '8k'"},
      {"50", "FINE_NODES '50'"},
      {"1500 0", "MARGIN_MM '0'"},
      {"1500 4mm", "MARGIN_MM '4mm'"},
      {"1500 --lag 0", "--lag '0'"},
      {"1500 --grid", "--grid needs a value"},
      {"1500 --frames 2.5", "--frames '2.5'"},
      {"", "usage"},
  };
  for (const auto& [args, named] : cases) {
    const auto r = shell(study(args));
    EXPECT_EQ(r.exitCode, 2) << args << ": " << r.output;
    EXPECT_NE(r.output.find(named), std::string::npos) << args << ": " << r.output;
  }
}

TEST(ElectricLocalStudy, ASlabTooCoarseForTheBladeIsNamed) {
  const auto r = shell(study("1000 --frames 1"));
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("no contact in frame 0"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("take more nodes"), std::string::npos) << r.output;
}

}  // namespace
