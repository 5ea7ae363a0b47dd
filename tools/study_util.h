// study_util.h - what the studies under tools/*_study share: slab_cut's slab (the scene of
// coarse_local_study and electric_local_study), a clock and a median.
#pragma once

#include <algorithm>
#include <chrono>
#include <vector>

#include "sim/mesh_slab.h"

namespace esim::study {

// scenarios/slab_cut.yaml's slab: 60 x 30 x 10 mm, graded 4x finer along the cut line and
// toward the top (graded false: uniform)
inline SlabSpec slabCutSpec(int nodes, bool graded = true) {
  SlabSpec s;
  s.sizeM = {0.06, 0.03, 0.01};
  s.targetNodes = nodes;
  s.grading.enabled = graded;
  s.grading.cutFrom = {-0.025, 0, 0.01};
  s.grading.cutTo = {0.025, 0, 0.01};
  s.grading.ratio = 4;
  s.grading.widthM = 0.004;
  s.grading.towardTop = true;
  return s;
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
