// subgrid_cut_test.cpp - issue #13: the paper's own scene cuts at the paper's resolution.
// scenarios/paper_slab_cut.yaml (1013 nodes, 72 V blade, the sub-grid contact model), built
// as `esim run` builds it (tools/app/run_config), every frame checked by hard_case.h's
// FrameChecker (energy balance 1e-9 with the sub-grid zone and its vapour, current balance,
// P = V I); then the groove: tets removed along the whole path, every one of them an element
// the blade's path crosses (centroid within 3 mm of the line, within the path's ends plus an
// element), none elsewhere. Without the model the same scene removes nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "sim/io/scenario.h"
#include "tests/hard_cases/hard_case.h"
#include "tools/app/accuracy_metrics.h"
#include "tools/app/run_config.h"

namespace esim {
namespace {

const std::string kScene = std::string(ESIM_SOURCE_DIR) + "/scenarios/paper_slab_cut.yaml";

// the removed tets against the blade's path, the x axis on the top face (z = 10 mm):
// along = centroid x, off the path = |centroid y|
app::RemovedExtents grooveOf(const Simulation& sim) {
  return app::removedTetExtents(sim.mesh(), *sim.model().geo, Vec3(0, 0, 0.01), Vec3(1, 0, 0.01),
                                0.01);
}

TEST(HardSubgridCut, PaperSlabCutRemovesTetsAlongThePath) {
  const Scenario s = loadScenario(kScene);
  app::checkRunnable(s);
  const SimulationConfig config = app::makeSimulationConfig(s);
  ASSERT_EQ(config.subgrid.mode, SubgridMode::Auto);
  Simulation sim(app::buildMesh(s), config);
  ASSERT_NEAR(sim.mesh().numNodes(), 1013, 0.03 * 1013);  // the paper's resolution
  hard::Invariants inv;
  inv.potentialBounds = true;
  hard::FrameChecker check(sim, inv);
  const int frames = frameCount(s);
  int active = 0, withContact = 0;
  for (int f = 0; f < frames && check.ok(); ++f) {
    const FrameRecord& r = check.step();
    if (r.contactNodes > 0) ++withContact;
    if (r.subgridActive) ++active;
  }
  ASSERT_TRUE(check.ok());
  EXPECT_EQ(active, withContact);  // 5-6 mm cells against a ~1 mm contact: on throughout
  const app::RemovedExtents g = grooveOf(sim);
  std::printf(
      "paper_slab_cut: %d tets removed (%.0f mm^3), x %.1f .. %.1f mm, off the line <= "
      "%.2f mm, depth <= %.1f mm; %.2f J delivered, energy balance %.2g\n",
      g.tets, g.volumeM3 * 1e9, g.alongMinM * 1e3, g.alongMaxM * 1e3, g.maxOffPathM * 1e3,
      g.maxDepthM * 1e3, sim.energyDeliveredJ(), check.worstEnergyRel());
  // a groove along the path (-35 .. 35 mm at y = 0) ...
  EXPECT_GE(g.tets, 20);
  EXPECT_LT(g.alongMinM, -25e-3);
  EXPECT_GT(g.alongMaxM, 25e-3);
  // ... of elements the path crosses, and nothing else
  EXPECT_LE(g.maxOffPathM, 3e-3);
  EXPECT_GE(g.alongMinM, -35e-3 - 6e-3);
  EXPECT_LE(g.alongMaxM, 35e-3 + 6e-3);
  EXPECT_LE(g.maxDepthM, 5e-3 + 1e-9);  // the top layer of elements only
  EXPECT_LT(check.worstEnergyRel(), 1e-9);
}

// the same scene without the model: the mesh alone spreads the heat and nothing breaks
TEST(HardSubgridCut, WithoutTheModelThePaperSlabDoesNotCut) {
  const Scenario s = loadScenario(kScene, {"subgrid_contact.mode=off", "time.duration_s=2"});
  Simulation sim(app::buildMesh(s), app::makeSimulationConfig(s));
  hard::FrameChecker check(sim, hard::Invariants{});
  for (int f = 0; f < frameCount(s) && check.ok(); ++f) check.step();
  EXPECT_EQ(sim.removedTets(), 0);
  EXPECT_LT(sim.maxTemperatureSeenC(), 50.0);
}

}  // namespace
}  // namespace esim
