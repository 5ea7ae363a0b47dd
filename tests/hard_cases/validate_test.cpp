// Hard case (issue #12), a bug this suite found, fixed since: tests/hard_cases/README.md,
// "Bugs found". What it was:
//
// tools/app/run_config.h promises that "a file that `esim validate` accepts never fails at
// set-up" (checkRunnable runs every check of the set-up). The explicit integrator's sub-step
// bound is not among them: it needs the mesh's stability limit (element and Gershgorin bounds,
// ThermalPhase::stableExplicitDtS, one pass over the tets), which checkRunnable does not
// compute. Reproducer: scenarios/paper_slab.yaml with
//   --set material.heat_capacity_j_per_m3k=1   (allowed: (0, 1e8])
// `esim validate` prints "ok", `esim run` exits 2 at set-up with "solvers.thermal.integrator:
// explicit needs 3759 sub-steps per frame ... above the limit of 1000
// (solvers.thermal.max_substeps); use backward-euler ...". The same with the schema's
// thermal_conductivity_w_per_mk = 100 on a fine slab, or time.fps = 0.1.
// Second defect in that message: `solvers.thermal.max_substeps` is not a scenario key (the
// schema has no such field: `--set solvers.thermal.max_substeps=5000` is an unknown key), so
// the bound it names cannot be raised from a scenario.
// Expected: checkRunnable refuses what the set-up refuses (compute the limit for a slab, as it
// already builds the slab mesh), and the message names a key that exists (add
// solvers.thermal.max_substeps to the schema, or drop the key from the message).
#include <gtest/gtest.h>

#include <string>

#include "hard_case.h"
#include "sim/io/scenario.h"
#include "tools/app/run_config.h"

namespace esim {
namespace {

// the paper's slab (1013 nodes), explicit integrator (the default), c rho = 1 J/(m^3 K)
constexpr const char* kScene = R"(name: hard_validate
mesh:
  source: slab
  slab: {size_m: [0.1, 0.1, 0.01], nodes: 1013}
material: {heat_capacity_j_per_m3k: 1}
physics: [electric, thermal, boiling]
output: {video: false, hashes: false}
)";

TEST(HardMaterialFailing, ValidateRefusesWhatTheSetUpRefuses) {
  const Scenario s = parseScenario(kScene, "hard_validate.yaml");
  std::string setUp;
  try {
    Simulation sim(app::buildMesh(s), app::makeSimulationConfig(s));
  } catch (const Error& e) {
    setUp = e.what();
  }
  ASSERT_FALSE(setUp.empty()) << "the set-up accepts it now";
  EXPECT_TRUE(hard::contains(setUp, "solvers.thermal.max_substeps")) << setUp;
  // `esim validate` must refuse it too: fails, checkRunnable accepts
  const auto [kind, message] = hard::errorOf([&] { app::checkRunnable(s); });
  EXPECT_EQ(kind, ErrorKind::Input) << message;
  // the same words, named by the file as `esim run` names the set-up's (tools/app/run.cpp)
  EXPECT_EQ(message, "hard_validate.yaml: " + setUp);
}

TEST(HardMaterialFailing, TheSubstepBoundTheMessageNamesIsAScenarioKey) {
  // fails: "unknown key"
  EXPECT_NO_THROW(
      parseScenario(kScene, "hard_validate.yaml", {"solvers.thermal.max_substeps=5000"}));
}

}  // namespace
}  // namespace esim
