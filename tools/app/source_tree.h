// source_tree.h - files that esim reads from its source tree (tools/*.py, the benches'
// default scene), found wherever esim is run from.
#pragma once

#include <filesystem>
#include <string>

namespace esim::app {

// the file at `relative` (e.g. "tools/plot_timing.py", "scenarios/slab_cut.yaml") in the
// directory of the esim executable or any directory above it (build/release/tools/esim -> the
// source tree), else in the source tree this binary was built from; empty when it is nowhere
std::filesystem::path findSourceTreeFile(const std::string& relative);

}  // namespace esim::app
