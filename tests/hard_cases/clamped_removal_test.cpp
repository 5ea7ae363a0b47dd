// Hard case (issue #12), a bug this suite found, fixed since: tests/hard_cases/README.md,
// "Bugs found". What it was:
//
// Rupture that removes every tet touching the clamped bottom (the structural supports) stops
// the run with an esim::Error of kind Input, thrown by the StructuralPhase constructor in the
// rebuild (structural.cpp, ESIM_VERIFY(m.islands < pieces, ...)):
//   "structural: no piece of the body is held by the supports"
// The message names neither rupture nor the frame, and the kind says "bad input" (exit 2,
// "writes nothing") for a run that went on for frames. The initial build wraps the same
// structural errors into a Run error naming effects.structural_clamp_band_m
// (Simulation::buildInitialModel); the rebuild does not. Expected: a Run error like the
// rebuild's other two ("rupture: every element of the tissue has been removed", "rupture: the
// cut removed all the tissue on the return electrode"). Now: "rupture, frame N: structural:
// no piece of the body is held by the supports (clamped: K bottom nodes within
// effects.structural_clamp_band_m = B m of the lowest node)", the clamp named by the
// structural phase itself (StructuralOptions::supportsNote).
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "hard_case.h"

namespace esim {
namespace {

using hard::FrameChecker;
using hard::Invariants;
using hard::MaxPrinciple;

// every case in each way the model follows a removal (hard::removalWays)
class HardRemovalFailing : public ::testing::TestWithParam<hard::RemovalWay> {};

// thermal only: a broad Gaussian source (3e8 W/m^3, 20 mm), critical stress 10 Pa: the slab
// breaks through to its clamped bottom in frame 3
TEST_P(HardRemovalFailing, RemovalOfTheClampedTissueIsARunError) {
  SimulationConfig c;
  c.phases.thermal = c.phases.boiling = c.phases.structural = c.phases.rupture = true;
  c.thermal.integrator = ThermalIntegrator::BackwardEuler;
  c.heatSource.enabled = true;
  c.heatSource.centerM = Vec3(0, 0, 0.01);
  c.heatSource.radiusM = 0.02;
  c.heatSource.powerDensityW_m3 = 3e8;
  c.criticalStressPa = 10.0;
  hard::applyWay(GetParam(), c);
  Simulation sim(makeSlab(hard::quarterSlabSpec()), c);
  Invariants inv;
  inv.maxPrinciple = MaxPrinciple::Lower;
  FrameChecker check(sim, inv);
  int stoppedAt = -1;
  for (int f = 0; f < 30 && stoppedAt < 0; ++f) {
    try {
      check.step();
      ASSERT_TRUE(check.ok());
    } catch (const Error& e) {
      stoppedAt = f;
      std::printf("stopped at frame %d (%s error): %s\n", f, errorKindName(e.kind()), e.what());
      EXPECT_EQ(e.kind(), ErrorKind::Run) << e.what();  // failed: Input
      EXPECT_TRUE(hard::contains(e.what(), "rupture, frame " + std::to_string(f) + ": "))
          << e.what();  // failed
      // the clamp that held the tissue, and its key (StructuralOptions::supportsNote)
      EXPECT_TRUE(
          hard::contains(e.what(), "no piece of the body is held by the supports (clamped: "))
          << e.what();
      EXPECT_TRUE(hard::contains(e.what(), "effects.structural_clamp_band_m = ")) << e.what();
    }
  }
  EXPECT_GT(stoppedAt, 0);
}

INSTANTIATE_TEST_SUITE_P(Modes, HardRemovalFailing, hard::removalWays(), hard::removalWayName);

}  // namespace
}  // namespace esim
