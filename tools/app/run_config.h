// run_config.h - a scenario turned into what a run builds: the mesh, the simulation's
// configuration and the renderer's options.
//
// The one mapping from the scenario schema (sim/io/scenario.h, YAML keys) to the core's
// configuration (sim/simulation.h): the command, the benchmarks and the tests all use it.
// checkRunnable() runs, without building anything heavy, every check that the set-up of
// `esim run` would make before its first frame, so that a file that `esim validate`
// accepts never fails at set-up.
#pragma once

#include "render/renderer.h"
#include "sim/core_error.h"
#include "sim/io/scenario.h"
#include "sim/mesh_tet.h"
#include "sim/simulation.h"

namespace esim::app {

// the simulation's configuration for the scenario (phases, materials, solvers, path)
SimulationConfig makeSimulationConfig(const Scenario& scenario);

// the renderer's options for the scenario (camera, look, colour map, MSAA)
RenderOptions makeRenderOptions(const Scenario& scenario);

// the scenario's mesh: the slab generator, or the surface file meshed by CGAL [m]
TetMesh buildMesh(const Scenario& scenario);

// every check the run's set-up makes before its first frame: the configuration, the
// renderer's and the video's options and, withMesh and for a generated slab (milliseconds
// to build), the mesh (return electrode nodes, clamped nodes, the dense inverse's memory);
// throws Error naming the scenario key. `esim run` calls it without the mesh (its set-up
// checks the mesh it builds), `esim validate` with; noVideo: as `esim run --no-video`.
void checkRunnable(const Scenario& scenario, bool withMesh = true, bool noVideo = false);

// an input error of the core or the renderer (which name fields, not files) thrown again as
// "FILE: ..." for the scenario it came from; other errors, and messages that start with the
// file already, as they are (call it from the handler that caught `error`)
[[noreturn]] void rethrowNamingScenario(const Error& error, const Scenario& scenario);

}  // namespace esim::app
