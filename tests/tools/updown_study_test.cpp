// updown_study_test.cpp - tools/updown_study end to end on a small slab: it prints a row per
// rank and checks what it times (the reach solves equal the block solve, the updated factor
// solves the updated matrix, the vectorized kernel's factor equals cholmod_updown's); a bad
// node count exits 2 naming it. Times are never asserted.
#include <gtest/gtest.h>

#include <cstdio>
#include <sstream>
#include <string>

#include "tests/tools/cli_test_util.h"

namespace {

using esim::cli_test::shell;

std::string study(const std::string& args) {
  return std::string("\"") + UPDOWN_STUDY_EXE + "\" " + args;
}

TEST(UpdownStudy, PrintsARowPerRankAndItsMethodsAgree) {
  const auto r = shell(study("300"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  std::istringstream lines(r.output);
  std::string line;
  int rows = 0;
  double reachVsBlock = -1, updated = -1, vectorVsUpdown = -1;
  while (std::getline(lines, line)) {
    int rank = 0;
    long reachRows = 0;
    double updown = 0, block = 0, reach = 0, vector = 0;
    if (std::sscanf(line.c_str(), "%d %lf %lf %lf %ld %lf", &rank, &updown, &block, &reach,
                    &reachRows, &vector) == 6) {
      EXPECT_GT(vector, 0.0) << line;
      EXPECT_EQ(rank, 6 * (rows == 0) + 24 * (rows == 1) + 72 * (rows == 2) + 144 * (rows == 3))
          << line;
      EXPECT_GT(reachRows, 0) << line;
      EXPECT_LE(reachRows, 600) << line;  // 300 nodes less the clamped face: < 600 unknowns
      ++rows;
    }
    std::sscanf(line.c_str(),
                "checks: reach solves against the block solve %lf, updated factor's residual %lf, "
                "vector against updown %lf",
                &reachVsBlock, &updated, &vectorVsUpdown);
  }
  EXPECT_EQ(rows, 4) << r.output;
  EXPECT_GE(reachVsBlock, 0.0) << r.output;
  EXPECT_LT(reachVsBlock, 1e-12) << r.output;
  EXPECT_GE(vectorVsUpdown, 0.0) << r.output;
  EXPECT_LT(vectorVsUpdown, 1e-12) << r.output;
  EXPECT_GE(updated, 0.0) << r.output;
  EXPECT_LT(updated, 1e-12) << r.output;
}

TEST(UpdownStudy, ABadNodeCountExitsTwoNamingIt) {
  for (const char* bad : {"8k", "50", "-3", "''"}) {
    const auto r = shell(study(bad));
    EXPECT_EQ(r.exitCode, 2) << bad << ": " << r.output;
    EXPECT_NE(r.output.find("expected a node count in [100, 200000]"), std::string::npos)
        << r.output;
  }
}

}  // namespace
