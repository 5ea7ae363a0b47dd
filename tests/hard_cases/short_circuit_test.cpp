// Hard case (issue #12), a bug this suite found, fixed since: tests/hard_cases/README.md,
// "Bugs found". What it was:
//
// A tool pushed through the tissue onto the return electrode within one frame touches
// grounded nodes: a short circuit. The run cannot go on, which the core reports with an
// esim::Error of kind Input (thrown by NodeClasses::contactFreeIndices, an ESIM_VERIFY meant
// for a caller's bad contact list), whose message names no stage and no frame:
//   "electric solver: short circuit: the tool touches node 312, which belongs to the return
//    electrode (grounded)".
// Expected: a Run error (core_error.h: "a run that cannot go on"; tools/app/run.cpp's frame
// loop lists "a tool reaching the return electrode" among them) naming the stage and frame,
// like find_contacts' own check for a tip in a tet whose nodes are all grounded.
#include <gtest/gtest.h>

#include "hard_case.h"

namespace esim {
namespace {

using hard::FrameChecker;
using hard::Invariants;
using hard::MaxPrinciple;

TEST(HardContactFailing, ToolPushedOntoTheReturnElectrode) {
  SimulationConfig c = hard::toolAt(ElectrodeKind::Sphere, Vec3::Zero(), true);
  const double dt = c.frameDtS;
  hard::moveTool(c, Vec3(0, 0, 0.01 + 0.0005), 0, Vec3(0, 0, -0.0005), dt);
  Simulation sim(makeSlab(hard::smallSlabSpec()), c);
  Invariants inv;
  inv.maxPrinciple = MaxPrinciple::Lower;
  inv.potentialBounds = true;
  FrameChecker check(sim, inv);
  check.step();  // on the top face
  ASSERT_TRUE(check.ok());
  const auto [kind, message] = hard::errorOf([&] { sim.step(); });
  EXPECT_EQ(kind, ErrorKind::Run) << message;  // fails: Input
  EXPECT_TRUE(hard::contains(message, "short circuit")) << message;
  EXPECT_TRUE(hard::contains(message, "frame 1")) << message;  // fails: no frame
}

// a tool resting on the top face whose contact distance reaches across the 10 mm slab to
// the return pad: the message names the node, the tip and the contact distance, and says
// which of the two it can be
TEST(HardContactFailing, AContactDistanceAcrossTheSlabNamesItself) {
  SimulationConfig c = hard::toolAt(ElectrodeKind::Sphere, Vec3(0, 0, 0.0105), false);
  c.contactDistanceM = 0.012;
  Simulation sim(makeSlab(hard::smallSlabSpec()), c);
  const auto [kind, message] = hard::errorOf([&] { sim.step(); });
  EXPECT_EQ(kind, ErrorKind::Run) << message;
  EXPECT_TRUE(hard::contains(message, "find_contacts, frame 0: short circuit")) << message;
  EXPECT_TRUE(hard::contains(message, "tool.contact_distance_m = 0.012 m")) << message;
  EXPECT_TRUE(hard::contains(message, "tool tip at (0, 0, 0.0105) m")) << message;
  EXPECT_TRUE(hard::contains(message, "its contact distance reaches across it")) << message;
}

}  // namespace
}  // namespace esim
