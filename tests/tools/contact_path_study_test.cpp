// contact_path_study_test.cpp - tools/contact_path_study end to end on a small slab: a row per
// size with the four ways' potentials (the downdate solver's among them) equal to round-off, the
// paths walking fewer entries of L than the full column solves would; bad arguments exit 2 naming
// them. Times are never asserted.
#include <gtest/gtest.h>

#include <cstdio>
#include <sstream>
#include <string>

#include "tests/tools/cli_test_util.h"

namespace {

using esim::cli_test::shell;

std::string study(const std::string& args) {
  return std::string("\"") + CONTACT_PATH_STUDY_EXE + "\" " + args;
}

TEST(ContactPathStudy, ThePathsGiveTheSamePotentialWalkingLessOfL) {
  const auto r = shell(study("--contacts 6 1013 2000"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  std::istringstream lines(r.output);
  std::string line;
  int rows = 0;
  while (std::getline(lines, line)) {
    int nodes = 0, free = 0, contacts = 0;
    long entries = 0, pathEntries = 0;
    double columns = 0, blocks = 0, paths = 0, difference = 1, solver = 0;
    if (line.empty() || line[0] == '#') continue;
    ASSERT_EQ(
        std::sscanf(line.c_str(), "%d %d %ld %d %lf %lf %lf %ld %lf %lf", &nodes, &free, &entries,
                    &contacts, &columns, &blocks, &paths, &pathEntries, &difference, &solver),
        10)
        << line;
    EXPECT_GT(nodes, 900) << line;
    EXPECT_LT(free, nodes) << line;  // the return pad's nodes are grounded
    EXPECT_EQ(contacts, 6) << line;
    EXPECT_LE(difference, 1e-12) << line;
    // a full solve walks L twice a column; the paths once each, on part of it
    EXPECT_GT(pathEntries, 0) << line;
    EXPECT_LT(pathEntries, 2L * contacts * entries) << line;
    EXPECT_GT(columns, 0.0) << line;
    EXPECT_GT(blocks, 0.0) << line;
    EXPECT_GT(paths, 0.0) << line;
    EXPECT_GT(solver, 0.0) << line;
    ++rows;
  }
  EXPECT_EQ(rows, 2) << r.output;
}

TEST(ContactPathStudy, BadArgumentsAreNamed) {
  auto r = shell(study("12"));
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("'12': expected a node count from 100 to 2000000"), std::string::npos)
      << r.output;
  r = shell(study("--contacts 0 1013"));
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--contacts 0: expected 1 to 10000"), std::string::npos) << r.output;
}

}  // namespace
