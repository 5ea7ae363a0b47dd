// coarse_local_study_test.cpp - tools/coarse_local_study end to end on a small slab: a row
// per region (the coarse solve alone, each margin, the whole body), its self-check (the
// whole-body region equals StructuralPhase's solve, also with a graded coarse slab) and the
// invariants of its rows (the whole body has no error, the energy error never grows with the
// space); bad arguments exit 2 naming them. Times are never asserted.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <sstream>
#include <string>

#include "tests/tools/cli_test_util.h"

namespace {

using esim::cli_test::shell;

std::string study(const std::string& args) {
  return std::string("\"") + COARSE_LOCAL_STUDY_EXE + "\" " + args;
}

struct Row {
  double dofs = -1, nearErr = -1, maxErr = -1, l2 = -1, energy = -1;
  int nearFlips = -1, flips = -1;
};

TEST(CoarseLocalStudy, PrintsARowPerRegionAndTheWholeBodyEqualsTheFullSolve) {
  const auto r = shell(study("900 150 3 6"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  std::istringstream lines(r.output);
  std::string line;
  std::map<std::string, Row> rows;
  double check = -1;
  while (std::getline(lines, line)) {
    char name[16] = {};
    Row row;
    double build = 0, solve = 0, coarseBuild = 0, coarseSolve = 0;
    if (std::sscanf(line.c_str(), "%15s %lf %lf %lf %lf %lf %lf %lf %lf %lf %d %d", name, &row.dofs,
                    &build, &solve, &coarseBuild, &coarseSolve, &row.nearErr, &row.maxErr, &row.l2,
                    &row.energy, &row.nearFlips, &row.flips) == 12)
      rows[name] = row;
    std::sscanf(line.c_str(),
                "check: the whole-body region against the truth, relative difference %lf", &check);
  }
  ASSERT_EQ(rows.size(), 7u) << r.output;
  for (const char* name :
       {"coarse", "coarse+ref", "3.00mm", "3.00mm+ref", "6.00mm", "6.00mm+ref", "whole"})
    ASSERT_EQ(rows.count(name), 1u) << name << "\n" << r.output;
  EXPECT_GE(check, 0.0) << r.output;
  EXPECT_LT(check, 1e-10) << r.output;
  EXPECT_EQ(rows["whole"].maxErr, 0.0) << r.output;  // printed to 3 decimals
  EXPECT_EQ(rows["whole"].flips, 0) << r.output;
  EXPECT_EQ(rows["coarse"].dofs, 0.0) << r.output;
  EXPECT_GT(rows["3.00mm"].dofs, 0.0) << r.output;
  EXPECT_GT(rows["6.00mm"].dofs, rows["3.00mm"].dofs) << r.output;
  EXPECT_GT(rows["whole"].dofs, rows["6.00mm"].dofs) << r.output;
  EXPECT_EQ(rows["6.00mm+ref"].dofs, rows["6.00mm"].dofs) << r.output;
  EXPECT_GT(rows["coarse"].energy, 1e-3) << r.output;  // the coarse solve alone is not exact
  EXPECT_LT(rows["whole"].energy, 1e-10) << r.output;
  // Galerkin on nested spaces: the energy error never grows as the space grows (the coarse
  // space with the reference; a wider region on the same coarse solve)
  const double slack = 1 + 1e-9;
  EXPECT_LE(rows["coarse+ref"].energy, rows["coarse"].energy * slack) << r.output;
  for (const char* with : {"", "+ref"}) {
    const std::string coarse = std::string("coarse") + with, narrow = std::string("3.00mm") + with,
                      wide = std::string("6.00mm") + with;
    EXPECT_LE(rows[narrow].energy, rows[coarse].energy * slack) << with << "\n" << r.output;
    EXPECT_LE(rows[wide].energy, rows[narrow].energy * slack) << with << "\n" << r.output;
  }
}

TEST(CoarseLocalStudy, AGradedCoarseSlabChecksToo) {
  const auto r = shell(study("--graded-coarse 900 150 3"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("tets, graded)"), std::string::npos) << r.output;
  double check = -1;
  std::istringstream lines(r.output);
  std::string line;
  while (std::getline(lines, line))
    std::sscanf(line.c_str(),
                "check: the whole-body region against the truth, relative difference %lf", &check);
  EXPECT_GE(check, 0.0) << r.output;
  EXPECT_LT(check, 1e-10) << r.output;
}

TEST(CoarseLocalStudy, BadArgumentsExitTwoNamingThem) {
  const std::pair<const char*, const char*> cases[] = {
      {"8k 100", "FINE_NODES '8k'"},       {"50 27", "FINE_NODES '50'"},
      {"900 1000", "COARSE_NODES '1000'"}, {"900 150 0", "MARGIN_MM '0'"},
      {"900 150 4mm", "MARGIN_MM '4mm'"},  {"900", "usage"},
  };
  for (const auto& [args, named] : cases) {
    const auto r = shell(study(args));
    EXPECT_EQ(r.exitCode, 2) << args << ": " << r.output;
    EXPECT_NE(r.output.find(named), std::string::npos) << args << ": " << r.output;
  }
}

}  // namespace
