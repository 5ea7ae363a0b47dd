// compare_runs.h - frame-by-frame comparison of two run folders (see cmd_compare.cpp).
#pragma once

#include <string>
#include <vector>

namespace esim::app {

struct FrameDiff {
  int frame = 0;
  int dhashBits = 0;       // perceptual hash distance (0..64)
  bool hasImages = false;  // both runs have this frame as PNG
  double psnrDb = 0;
  double offShare = 0;  // share of pixels off by more than 16 levels
  int maxDiff = 0;
  bool withinTolerance = false;
};

struct CompareResult {
  int framesA = 0, framesB = 0;
  bool sameRenderer = false;  // renderer strings and library versions equal
  // what differs in the runs' inputs ("" when nothing): the scenario's hash, the content of
  // a file it names (hashes.json's input_files)
  std::string inputsDiffer;
  // which esim made each run (hashes.json's esim_build: version, commit, uncommitted
  // changes): "" when the same; else what differs ("commit 4f067ee1c2d3 vs 127f1e2a9b0c"),
  // or that a run does not say (made before esim recorded it)
  std::string buildDiffers;
  std::string buildA;            // buildInfoLine of run A's build, or "" when it does not say
  std::vector<FrameDiff> diffs;  // frames whose exact hash differs
  bool identical() const { return framesA == framesB && diffs.empty(); }
  bool withinTolerance() const;
};

// compares runA (reference) with runB; unless reportDir is empty, writes compare.json (and
// diff PNGs when writeDiffs) into it: a new folder, or one holding only an earlier report,
// which is replaced (any other file there: esim::Error, nothing changed). Throws esim::Error
// on unreadable runs.
CompareResult compareRuns(const std::string& runA, const std::string& runB,
                          const std::string& reportDir, bool writeDiffs);

}  // namespace esim::app
