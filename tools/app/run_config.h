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

// every check the run's set-up makes before its first frame, on the configuration and, for
// a generated slab (milliseconds to build), on its mesh (return electrode nodes, clamped
// nodes); throws Error naming the scenario key
void checkRunnable(const Scenario& scenario);

}  // namespace esim::app
