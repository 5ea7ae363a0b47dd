// Hard cases (issue #12): element removal. An island cut loose from the tissue (before the run
// and by rupture during it), removal that reaches the return electrode, and removal of nearly
// everything. The heat of removed tissue leaves with it: FrameChecker's energy balance counts
// it from the stored heat before and after each rebuild.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "hard_case.h"

namespace esim {
namespace {

using hard::FrameChecker;
using hard::Invariants;
using hard::MaxPrinciple;

constexpr double kLz = 0.01;

Vec3 centroid(const TetMesh& mesh, int e) {
  Vec3 c = Vec3::Zero();
  for (int v : mesh.tets[e]) c += 0.25 * mesh.nodes[v];
  return c;
}

bool inBox(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
}

// the island: the cells of [-20, -10] x [-20, -10] x [5, 10] mm; the moat: the cells one cell
// (2.5 mm) around it at the sides and below, removed before the run; `bridge`: keep one moat
// cell at the island's east side, top layer (x in [-10, -7.5], y in [-17.5, -15] mm)
TetMesh islandSlab(bool bridge) {
  TetMesh mesh = makeSlab(hard::smallSlabSpec());
  const Vec3 lo(-0.02, -0.02, 0.005), hi(-0.01, -0.01, kLz);
  const Vec3 d(0.0025, 0.0025, 0.0025);
  for (int e = 0; e < mesh.numTets(); ++e) {
    const Vec3 c = centroid(mesh, e);
    const bool island = inBox(c, lo, hi);
    const bool moat = !island && inBox(c, lo - d, hi + Vec3(d.x(), d.y(), 0));
    const bool bridged =
        bridge && inBox(c, Vec3(-0.01, -0.0175, 0.0075), Vec3(-0.0075, -0.015, kLz));
    if (moat && !bridged) mesh.alive[e] = 0;
  }
  return mesh;
}

std::vector<int> islandNodes(const TetMesh& mesh) {
  std::vector<int> out;
  for (int i = 0; i < mesh.numNodes(); ++i)
    if (inBox(mesh.nodes[i], Vec3(-0.02, -0.02, 0.005) - Vec3::Constant(1e-9),
              Vec3(-0.01, -0.01, kLz) + Vec3::Constant(1e-9)))
      out.push_back(i);
  return out;
}

// every case in each way the model follows a removal (hard::removalWays)
class HardRemoval : public ::testing::TestWithParam<hard::RemovalWay> {};

// full physics on a slab with an island cut loose before the run: a ball on the island for
// 10 frames (its nodes float: no current, no heat, the island stays at 37 C exactly), then on
// the mainland (current flows, the island still does not warm)
TEST_P(HardRemoval, IsolatedIslandCarriesNoCurrentAndNoHeat) {
  SimulationConfig c = hard::toolAt(ElectrodeKind::Sphere, Vec3::Zero(), true);
  c.phases.boiling = c.phases.structural = c.phases.rupture = true;
  c.toolVoltageV = 150;
  const double dt = c.frameDtS;
  hard::moveTool(c, Vec3(-0.015, -0.015, kLz + 0.0005), 9 * dt, Vec3(0.01, 0.01, kLz + 0.0005),
                 10 * dt);
  hard::applyWay(GetParam(), c);
  Simulation sim(islandSlab(false), c);
  const std::vector<int> island = islandNodes(sim.mesh());
  ASSERT_EQ(island.size(), 5u * 5u * 3u);
  Invariants inv;
  inv.maxPrinciple = MaxPrinciple::Lower;
  inv.potentialBounds = true;
  FrameChecker check(sim, inv);
  for (int f = 0; f < 16; ++f) {
    const FrameRecord& r = check.step();
    ASSERT_TRUE(check.ok());
    ASSERT_GT(r.contactNodes, 0);
    if (f < 10) {
      EXPECT_EQ(r.toolCurrentA, 0.0) << "frame " << f << ": the island floats";
    } else {
      EXPECT_GT(r.toolCurrentA, 0.0) << "frame " << f;
    }
    for (int v : island) ASSERT_EQ(sim.temperatureC()[v], 37.0) << "frame " << f << " node " << v;
    for (int v : island) ASSERT_EQ(sim.potentialV()[v], 0.0) << "frame " << f << " node " << v;
  }
}

// the same island held by a one-cell bridge; a flat blade over the island's whole top at 800 V
// and a critical stress of 1 kPa: all the current crosses the bridge, which heats first and
// breaks with its surroundings; the island (what is left of it) is then cut loose by rupture:
// its current drops to zero while the blade still touches it, and nothing breaks in the
// solvers
TEST_P(HardRemoval, RuptureCutsAnIslandLoose) {
  SimulationConfig c = hard::toolAt(ElectrodeKind::Blade, Vec3(-0.015, -0.021, kLz + 0.0005), true);
  c.toolPath.keys[0].orientation = eulerXyzDegToQuaternion(Vec3(-90, 0, 0));  // flat, along +y
  c.electrode.widthM = 0.0095;
  c.electrode.lengthM = 0.012;
  c.phases.boiling = c.phases.structural = c.phases.rupture = true;
  c.toolVoltageV = 800;
  c.criticalStressPa = 1e3;
  hard::applyWay(GetParam(), c);
  Simulation sim(islandSlab(true), c);
  Invariants inv;
  inv.maxPrinciple = MaxPrinciple::Lower;
  inv.potentialBounds = true;
  FrameChecker check(sim, inv);
  double first = 0;
  int cutLooseAt = -1;
  for (int f = 0; f < 90 && cutLooseAt < 0; ++f) {
    const FrameRecord& r = check.step();
    ASSERT_TRUE(check.ok());
    ASSERT_GT(r.contactNodes, 0) << "frame " << f;
    if (f == 0) first = r.toolCurrentA;
    if (r.toolCurrentA == 0.0) cutLooseAt = f;
  }
  ASSERT_GT(first, 0.0);
  ASSERT_GE(cutLooseAt, 0) << "the bridge never broke";
  EXPECT_GT(sim.removedTets(), 0);
  int islandTets = 0;
  for (int e = 0; e < sim.mesh().numTets(); ++e)
    islandTets += sim.mesh().isAlive(e) && inBox(centroid(sim.mesh(), e), Vec3(-0.02, -0.02, 0.005),
                                                 Vec3(-0.01, -0.01, kLz));
  std::printf("cut loose at frame %d: %d tets removed, %d island tets left\n", cutLooseAt,
              sim.removedTets(), islandTets);
  EXPECT_GT(islandTets, 0);
  for (int f = 0; f < 5; ++f) {  // and the run goes on
    const FrameRecord& r = check.step();
    ASSERT_TRUE(check.ok());
    EXPECT_EQ(r.toolCurrentA, 0.0);
  }
}

// a one-layer slab (2.5 mm) on a small return pad (5 nodes), a ball on top of it at 300 V, and
// a critical stress of 1 kPa: the tissue between the ball and the pad boils and breaks, down to
// the pad. Once no tissue touches the pad the run cannot go on: a Run error that says why
TEST_P(HardRemoval, RemovalReachesTheReturnElectrode) {
  SlabSpec spec;
  spec.sizeM = Vec3(0.03, 0.03, 0.0025);
  spec.nodesPerAxis = {13, 13, 2};
  SimulationConfig c = hard::toolAt(ElectrodeKind::Sphere, Vec3(0, 0, 0.0025 + 0.0005), true);
  c.returnElectrode.radiusM = 0.0026;
  c.phases.boiling = c.phases.structural = c.phases.rupture = true;
  c.criticalStressPa = 1e3;
  c.toolVoltageV = 300;
  hard::applyWay(GetParam(), c);
  Simulation sim(makeSlab(spec), c);
  ASSERT_EQ(sim.groundNodes().size(), 5u);
  Invariants inv;
  inv.maxPrinciple = MaxPrinciple::Lower;
  inv.potentialBounds = true;
  FrameChecker check(sim, inv);
  int stoppedAt = -1;
  for (int f = 0; f < 30 && stoppedAt < 0; ++f) {
    try {
      check.step();
      ASSERT_TRUE(check.ok());
    } catch (const Error& e) {
      stoppedAt = f;
      std::printf("stopped at frame %d: %s\n", f, e.what());
      EXPECT_EQ(e.kind(), ErrorKind::Run) << e.what();
      EXPECT_TRUE(hard::contains(e.what(), "return electrode")) << e.what();
    }
  }
  EXPECT_GT(stoppedAt, 0) << "removed " << sim.removedTets() << " tets, the pad still has tissue";
}

// thermal only: a Gaussian source (1e9 W/m^3, 10 mm) under the top face, a critical stress of
// 100 Pa: frame after frame the tissue that warms breaks, until only the bottom layer (where
// it is clamped) and the far corners are left: more than three quarters removed, and every
// frame's invariants (the heat of the removed tissue leaves with it) hold throughout
TEST_P(HardRemoval, RemovalOfNearlyEverything) {
  SimulationConfig c;
  c.phases.thermal = c.phases.boiling = c.phases.structural = c.phases.rupture = true;
  c.thermal.integrator = ThermalIntegrator::BackwardEuler;
  c.heatSource.enabled = true;
  c.heatSource.centerM = Vec3(0, 0, kLz);
  c.heatSource.radiusM = 0.01;
  c.heatSource.powerDensityW_m3 = 1e9;
  c.criticalStressPa = 100.0;
  hard::applyWay(GetParam(), c);
  Simulation sim(makeSlab(hard::quarterSlabSpec()), c);
  const int tets = sim.mesh().numTets();
  Invariants inv;
  inv.maxPrinciple = MaxPrinciple::Lower;
  FrameChecker check(sim, inv);
  hard::runChecked(check, 30);
  EXPECT_EQ(check.frames(), 30);
  std::printf("%d of %d tets left, %.3g J left with the removed tissue\n", sim.mesh().numAlive(),
              tets, check.removedJ());
  EXPECT_LT(sim.mesh().numAlive(), tets / 4);
  EXPECT_GT(check.removedJ(), 0.0);
}

// a critical stress of 1 Pa: the whole slab breaks in the first frame. A Run error saying that
// everything was removed, never a crash or an empty matrix
TEST_P(HardRemoval, RemovalOfEverythingIsARunError) {
  SimulationConfig c;
  c.phases.thermal = c.phases.boiling = c.phases.structural = c.phases.rupture = true;
  c.thermal.integrator = ThermalIntegrator::BackwardEuler;
  c.heatSource.enabled = true;
  c.heatSource.centerM = Vec3(0, 0, kLz);
  c.heatSource.radiusM = 0.01;
  c.heatSource.powerDensityW_m3 = 1e9;
  c.criticalStressPa = 1.0;
  hard::applyWay(GetParam(), c);
  Simulation sim(makeSlab(hard::quarterSlabSpec()), c);
  const auto [kind, message] = hard::errorOf([&] { sim.step(); });
  EXPECT_EQ(kind, ErrorKind::Run) << message;
  EXPECT_TRUE(hard::contains(message, "every element")) << message;
}

INSTANTIATE_TEST_SUITE_P(Modes, HardRemoval, hard::removalWays(), hard::removalWayName);

}  // namespace
}  // namespace esim
