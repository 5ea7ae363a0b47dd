// scenario_checks.h - internal to esim_io: the cross-field rules of a scenario.
//
// Rules that no single field can check alone (phase dependencies, effects that need
// their phases, mesh sizes and the mesh file, frame count, camera, look and video
// sizes), run after the Reader has filled the Scenario; implemented in
// scenario_checks.cpp.
#pragma once

#include <string>

#include "sim/io/scenario_reader.h"

namespace esim::scenario_detail {

// "[electric, thermal, ...]"
std::string phaseList(const Scenario& s);

// throws Error at the first broken rule, located through r; resolves mesh.file.path
// into s.mesh.file.resolvedPath
void checkScenario(Scenario& s, const Reader& r);

}  // namespace esim::scenario_detail
