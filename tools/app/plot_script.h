// plot_script.h - ESim's plots: Python scripts in tools/ (matplotlib, from Debian's
// python3-matplotlib) run as a child process, never linked in.
//
// A plot is an extra: when python3, matplotlib or the script is missing the caller gets
// PlotStatus::Unavailable and a message to print, and whatever it was doing (a run, a
// benchmark) keeps its outcome and exit status.
//
// Where things are found:
//   - the script: $ESIM_TOOLS_DIR/NAME, else tools/NAME in the directory of the esim
//     executable or any directory above it (build/release/tools/esim -> tools/ of the source
//     tree), else tools/NAME of the source tree this binary was built from;
//   - the interpreter: $ESIM_PYTHON, else /usr/bin/python3 (Debian's, where
//     python3-matplotlib installs), else python3 on the PATH.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace esim::app {

enum class PlotStatus {
  Written,      // the script wrote its PNG
  Unavailable,  // no python3, no matplotlib or no script: nothing written
  BadInput,     // the script refused its input (its message names file, line, field)
  Failed,       // the script ran and failed (a bug): nothing written
};

struct PlotResult {
  PlotStatus status = PlotStatus::Failed;
  std::string message;  // what happened, for the user (one line)
};

// the path of tools/NAME (see above); empty when it is nowhere
std::filesystem::path findToolScript(const std::string& name);

// runs `python3 tools/SCRIPT ARGS...`; its own output goes to this process's stdout/stderr.
// The script's exit status 2 means "input refused" (BadInput), 3 "matplotlib missing"
// (Unavailable), any other non-zero status Failed.
PlotResult runPlotScript(const std::string& script, const std::vector<std::string>& args);

// timing.png of a run folder (tools/plot_timing.py): per-frame stacked stage times against
// the 33.3 ms budget, rebuild waits marked, and power, maximum temperature and removed tets
// where the scene has them; png empty: RUN_DIR/timing.png
PlotResult plotTiming(const std::filesystem::path& runDir, const std::filesystem::path& png = {});

}  // namespace esim::app
