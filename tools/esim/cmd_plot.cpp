// cmd_plot.cpp - `esim plot RUN_DIR`: timing.png of an existing run folder
// (tools/plot_timing.py through tools/app/plot_script.h; `esim run --plots` does the same at
// the end of a run).
//
// 1. Check RUN_DIR holds a run's timing.csv, and -o names a .png in a folder that exists
//    (else bad input, exit 2). A sweep's run (DIR/runs/<id>/run of `esim sweep`) needs -o:
//    its files are in DIR/manifest.jsonl, and a timing.png added to it would fail
//    `esim dataset verify DIR`.
// 2. Run the script; exit 0 when the PNG is written, 2 when it refuses timing.csv or
//    timing.json (a cut or edited file: its message names the line and field), 1 with the
//    reason when it cannot be written (python3 or matplotlib missing, a failing script).
#include <filesystem>
#include <iostream>
#include <memory>

#include "sim/core_error.h"
#include "tools/app/dataset.h"
#include "tools/app/plot_script.h"
#include "tools/esim/command.h"

namespace esim::cli {
namespace {

struct PlotOptions {
  std::string runDir;
  std::string png;  // "" = RUN_DIR/timing.png
};

int plotRun(const PlotOptions& opt) {
  namespace fs = std::filesystem;
  std::error_code ec;
  ESIM_VERIFY(fs::exists(opt.runDir, ec), "esim plot: '" + opt.runDir +
                                              "' does not exist (expected the folder of an "
                                              "esim run, e.g. out/demo)");
  ESIM_VERIFY(fs::is_directory(opt.runDir, ec),
              "esim plot: '" + opt.runDir +
                  "' is a file; expected the folder of an esim run (e.g. out/demo), which "
                  "holds timing.csv");
  ESIM_VERIFY(fs::is_regular_file(fs::path(opt.runDir) / "timing.csv", ec),
              "esim plot: '" + opt.runDir +
                  "' holds no timing.csv (expected the folder of an esim run, e.g. out/demo)");
  if (opt.png.empty()) {
    const fs::path sweep = app::dataset::sweepOfRun(opt.runDir);
    ESIM_VERIFY(sweep.empty(), "esim plot: '" + opt.runDir + "' is a run of the sweep '" +
                                   sweep.string() +
                                   "' (manifest.jsonl lists its files: a timing.png added there "
                                   "would fail esim dataset verify); give -o PNG outside it");
  } else {  // a PNG file in a folder that exists (matplotlib would add .png)
    checkOutputFileName("esim plot: -o", opt.png, ".png");
  }
  const app::PlotResult r = app::plotTiming(opt.runDir, opt.png);
  if (r.status == app::PlotStatus::Written) {
    std::cout << "esim: " << r.message << "\n";
    return kExitOk;
  }
  std::cerr << "esim: error: no timing.png: " << r.message << "\n";
  return r.status == app::PlotStatus::BadInput ? kExitBadInput : kExitFailure;
}

Registrar reg({"plot"},
              "Plot a run's timing: timing.png (stage times per frame against 33.3 ms, "
              "rebuild waits, power, temperature, removed tets)",
              [](CLI::App& app) -> Runner {
                auto opt = std::make_shared<PlotOptions>();
                app.add_option("run_dir", opt->runDir, "folder of an esim run")->required();
                app.add_option("-o,--out", opt->png, "PNG to write (default RUN_DIR/timing.png)");
                return [opt] { return plotRun(*opt); };
              });

}  // namespace
}  // namespace esim::cli
