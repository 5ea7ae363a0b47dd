// removal_distance_test.cpp - tools/removal_distance.py on the fields of a short slab_cut run:
// it counts the tets the run removed (as esim's summary does), its shares grow with the
// distance, and a folder without fields is refused with a message (exit 1).
#include <gtest/gtest.h>

#include <cstdio>
#include <sstream>
#include <string>

#include "tests/scratch_dir_util.h"
#include "tests/tools/cli_test_util.h"

namespace {

using esim::cli_test::shell;

class RemovalDistance : public esim::test::ScratchDirTest {};

TEST_F(RemovalDistance, CountsTheRunsRemovalsAndItsSharesGrowWithTheDistance) {
  const std::string run = (root_ / "run").string();
  const auto ran = shell(
      std::string("\"") + ESIM_EXE +
      "\" run scenarios/slab_cut.yaml --no-video --fields 1 --frames 9 -q -o \"" + run + "\"");
  ASSERT_EQ(ran.exitCode, 0) << ran.output;
  int removedByEsim = -1;
  {
    std::istringstream lines(ran.output);
    std::string line;
    while (std::getline(lines, line))
      if (line.find("  structural") == 0) {
        const size_t at = line.find("; ");
        if (at != std::string::npos)
          std::sscanf(line.c_str() + at, "; %d tets removed", &removedByEsim);
      }
  }
  ASSERT_GT(removedByEsim, 0) << ran.output;
  const auto r = shell("python3 tools/removal_distance.py \"" + run + "\"");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  int removed = -1, frames = -1;
  double share[4] = {-1, -1, -1, -1}, median = -1, p95 = -1, largest = -1;
  std::istringstream lines(r.output);
  std::string line;
  int k = 0;
  while (std::getline(lines, line)) {
    std::sscanf(line.c_str(), "%d tets removed in %d frames", &removed, &frames);
    int mm = 0;
    double s = 0;
    if (std::sscanf(line.c_str(), "within %d mm of the tool: %lf %%", &mm, &s) == 2 && k < 4)
      share[k++] = s;
    std::sscanf(line.c_str(), "median %lf mm, p95 %lf mm, largest %lf mm", &median, &p95, &largest);
  }
  EXPECT_EQ(removed, removedByEsim) << r.output;
  EXPECT_EQ(frames, 9) << r.output;
  ASSERT_EQ(k, 4) << r.output;
  for (int i = 1; i < 4; ++i) EXPECT_GE(share[i], share[i - 1]) << r.output;
  EXPECT_LE(share[3], 100.0) << r.output;
  EXPECT_GT(median, 0.0) << r.output;
  EXPECT_LE(median, p95) << r.output;
  EXPECT_LE(p95, largest) << r.output;
}

TEST_F(RemovalDistance, AFolderWithoutFieldsIsRefused) {
  const auto r = shell("python3 tools/removal_distance.py \"" + root_.string() + "\"");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("expected fields/frame_NNNNN.vtu for every frame"), std::string::npos)
      << r.output;
}

}  // namespace
