// cmd_compare.cpp - `esim compare RUN_A RUN_B`: regression check of two runs' frames.
//
// 1. Read both runs' hashes.json (per frame xxh3 of the raw RGB bytes + dHash).
// 2. Exact comparison of the frame hashes.
// 3. For frames that differ and have a PNG in both runs (output.png_every), a tolerant
//    comparison: PSNR and the share of pixels off by more than 16 levels (thresholds and
//    why: render/image_hash.h), and a diff image.
// 4. Print a summary and, with --report DIR, write a report there (compare.json and a diff
//    PNG per differing frame with PNGs in both runs); nothing is written into either run
//    (a sweep's run would no longer match its manifest). Exit 0 when all frames are
//    identical or within tolerance (--exact: identical only), 3 otherwise.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "render/image_hash.h"
#include "sim/core_error.h"
#include "sim/message_text.h"
#include "tools/app/compare_runs.h"
#include "tools/esim/command.h"

namespace esim::cli {
using namespace ::esim::app;

namespace fs = std::filesystem;

namespace {

struct CompareOptions {
  std::string runA, runB, report;
  bool exact = false;
};

int runCompare(const CompareOptions& o) {
  const std::string& report = o.report;
  const CompareResult r = compareRuns(o.runA, o.runB, report, true);
  std::cout << "esim compare " << printablePath(o.runA) << " " << printablePath(o.runB) << "\n";
  std::cout << "  frames        " << r.framesA << " vs " << r.framesB << "\n";
  std::cout << "  renderer/libs " << (r.sameRenderer ? "same" : "DIFFERENT") << "\n";
  std::cout << "  esim build    "
            << (r.buildDiffers.empty() ? "same: " + r.buildA : "DIFFERENT: " + r.buildDiffers)
            << "\n";
  std::cout << "  inputs        "
            << (r.inputsDiffer.empty() ? "same (the scenario's hash and the files it names)"
                                       : "DIFFERENT: " + r.inputsDiffer)
            << "\n";
  const auto printReport = [&] {
    if (report.empty())
      std::cout << "  report        none (--report DIR writes compare.json and the diff PNGs)\n";
    else
      std::cout << "  report        " << printablePath((fs::path(report) / "compare.json").string())
                << "\n";
  };
  if (r.identical()) {
    printReport();
    std::cout << "  result        identical (every frame hash equal)\n";
    return kExitOk;
  }
  std::cout << "  differing     " << r.diffs.size() << " frames\n";
  int shown = 0;
  for (const auto& d : r.diffs) {
    if (shown++ == 10) {
      std::cout << "  ...\n";
      break;
    }
    std::cout << "    frame " << d.frame << ": dhash " << d.dhashBits << " bits";
    if (d.hasImages)
      std::cout << ", PSNR " << d.psnrDb << " dB, " << 100 * d.offShare << " % pixels off, max "
                << d.maxDiff << (d.withinTolerance ? " (within tolerance)" : " (OUT of tolerance)");
    else
      std::cout << " (no PNG of this frame in both runs: no tolerant comparison)";
    std::cout << "\n";
  }
  printReport();
  if (!o.exact && r.withinTolerance()) {
    std::cout << "  result        within tolerance\n";
    return kExitOk;
  }
  std::cout << "  result        MISMATCH";
  // the reason, when it is not a frame of both runs
  int withoutImages = 0, outOfTolerance = 0;
  for (const auto& d : r.diffs) {
    withoutImages += d.hasImages ? 0 : 1;
    outOfTolerance += d.hasImages && !d.withinTolerance ? 1 : 0;
  }
  if (!o.exact && r.framesA == r.framesB && outOfTolerance == 0 && withoutImages > 0)
    std::cout << " (" << withoutImages << " differing frame" << (withoutImages == 1 ? "" : "s")
              << " without a PNG in both runs, so not comparable within a tolerance; "
                 "output.png_every: 1 writes every frame's)";
  if (r.framesA != r.framesB)
    std::cout << " (the runs have " << r.framesA << " and " << r.framesB << " frames"
              << (r.diffs.empty() ? "; the " + std::to_string(std::min(r.framesA, r.framesB)) +
                                        " frames of both are identical)"
                                  : ")");
  std::cout << "\n";
  return kExitMismatch;
}

Registrar reg({"compare"}, "Compare two runs' frames: exact hashes, then a tolerant image diff",
              [](CLI::App& app) -> Runner {
                auto o = std::make_shared<CompareOptions>();
                app.add_option("run_a", o->runA, "reference run folder")->required();
                app.add_option("run_b", o->runB, "run folder to check")->required();
                app.add_option("--report", o->report,
                               "write compare.json and the diff PNGs into this folder (new, "
                               "or holding an earlier report, which is replaced)");
                app.add_flag("--exact", o->exact, "fail on any hash difference");
                return [o] { return runCompare(*o); };
              });

}  // namespace
}  // namespace esim::cli
