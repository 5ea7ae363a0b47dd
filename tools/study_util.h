// study_util.h - what the studies under tools/*_study share: their scene, read from
// scenarios/slab_cut.yaml (the one source of its slab, blade, voltage, contact rule and return
// pad, so a study measures the scene `esim bench cut` and the demo run), a clock and a median.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "sim/io/scenario.h"
#include "tools/app/run_config.h"
#include "tools/app/source_tree.h"

namespace esim::study {

// scenarios/slab_cut.yaml (found from the source tree, as the benches find it) with
// mesh.slab.nodes set to `nodes`; a study that cannot read it exits 1 saying why
inline Scenario slabCutScenario(int nodes) {
  const std::string name = "scenarios/slab_cut.yaml";
  const std::string path = app::findSourceTreeFile(name).string();
  if (path.empty()) {
    std::fprintf(stderr, "%s: not found above this executable nor in its source tree\n",
                 name.c_str());
    std::exit(1);
  }
  try {
    return loadScenario(path, {"mesh.slab.nodes=" + std::to_string(nodes)});
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    std::exit(1);
  }
}

// a steady clock [s]
inline double seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// the upper median (0 for none)
inline double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace esim::study
