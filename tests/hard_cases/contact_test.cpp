// Hard cases (issue #12): the tool's contact with the tissue. Near-degenerate tets under the
// tool, contact on one node and on a whole face, and a tool that goes through, under, inside
// and across the tissue within one frame (onto the return electrode:
// short_circuit_test.cpp). Every frame is checked by hard::FrameChecker (hard_case.h).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>

#include "hard_case.h"

namespace esim {
namespace {

using hard::FrameChecker;
using hard::Invariants;
using hard::MaxPrinciple;

constexpr double kLz = 0.01;  // slab height [m]

Invariants jouleHeating() {
  Invariants inv;
  inv.maxPrinciple = MaxPrinciple::Lower;  // a positive Joule source, insulated
  inv.potentialBounds = true;
  return inv;
}

// the smallest tet volume over the largest, and the smallest dihedral angle [deg]
std::pair<double, double> shape(const TetMesh& mesh) {
  double lo = INFINITY, hi = 0;
  for (int e = 0; e < mesh.numTets(); ++e) {
    lo = std::min(lo, tetVolume(mesh, e));
    hi = std::max(hi, tetVolume(mesh, e));
  }
  return {lo / hi, meshQuality(mesh).minDihedralDeg};
}

// Slivers: the nodes within 4 mm of the tool (top layer and the one below, not on the slab's
// sides) are pushed along fixed pseudo-random directions by the largest common distance that
// keeps every tet positive, times 0.995: some tets are then nearly flat (four almost coplanar
// nodes) right where the current enters. `tip`: where the top centre node went.
TetMesh sliverSlab(Vec3& tip) {
  TetMesh mesh = makeSlab(hard::smallSlabSpec());
  int centre = -1;
  for (int i = 0; i < mesh.numNodes(); ++i)
    if ((mesh.nodes[i] - Vec3(0, 0, kLz)).norm() < 1e-9) centre = i;
  std::vector<int> moved;
  std::vector<Vec3> dir;
  std::uint64_t seed = 12345;
  auto uniform = [&seed]() {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(seed >> 11) / 9007199254740992.0 - 0.5;
  };
  for (int i = 0; i < mesh.numNodes(); ++i) {
    const Vec3& p = mesh.nodes[i];
    if (std::hypot(p.x(), p.y()) <= 0.004 && p.z() >= kLz - 0.0026) {
      moved.push_back(i);
      dir.push_back(Vec3(uniform(), uniform(), uniform()).normalized());
    }
  }
  const std::vector<Vec3> original = mesh.nodes;
  auto place = [&](double s) {
    for (size_t k = 0; k < moved.size(); ++k)
      mesh.nodes[moved[k]] = original[moved[k]] + s * dir[k];
  };
  auto positive = [&]() {
    for (int e = 0; e < mesh.numTets(); ++e)
      if (tetVolume(mesh, e) <= 0) return false;
    return true;
  };
  double ok = 0, bad = 0.0025;  // one grid spacing always inverts something
  place(bad);
  EXPECT_FALSE(positive());
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (ok + bad);
    place(mid);
    (positive() ? ok : bad) = mid;
  }
  place(0.995 * ok);
  tip = mesh.nodes[centre];
  return mesh;
}

TEST(HardContact, SliversUnderTheTool) {
  Vec3 tip;
  TetMesh mesh = sliverSlab(tip);
  const auto [volumeRatio, minDihedral] = shape(mesh);
  std::printf("slivers: smallest / largest tet volume %.3g, smallest dihedral angle %.3g deg\n",
              volumeRatio, minDihedral);
  EXPECT_LT(volumeRatio, 1e-2);
  EXPECT_LT(minDihedral, 3.0);  // near-degenerate
  // a ball resting on the displaced top centre node
  SimulationConfig c = hard::toolAt(ElectrodeKind::Sphere, tip + Vec3(0, 0, 0.0005), true);
  c.toolVoltageV = 150;
  Simulation sim(std::move(mesh), c);
  FrameChecker check(sim, jouleHeating());
  hard::runChecked(check, 10);
  EXPECT_EQ(check.frames(), 10);
  EXPECT_GT(sim.lastRecord().toolCurrentA, 0.0);
  EXPECT_GT(check.maxSeenC(), 37.0);
}

// Needles: the grid planes next to the tool are moved to 1e-3 of a cell from their
// neighbours in x and in y, so that the column of cells under the tool is 2.5 um x 2.5 um
// x 2.5 mm: tets with an aspect ratio of 1000 carry the current.
TEST(HardContact, NeedlesUnderTheTool) {
  TetMesh mesh = makeSlab(hard::smallSlabSpec());
  const double h = 0.0025, eps = 1e-3 * h;
  for (Vec3& p : mesh.nodes)
    for (int a = 0; a < 2; ++a)
      if (std::abs(p[a] - h) < 1e-9) p[a] = eps;  // the plane x = h (y = h) moves to eps
  EXPECT_GT(meshQuality(mesh).maxRadiusEdgeRatio, 100.0);
  SimulationConfig c =
      hard::toolAt(ElectrodeKind::Sphere, Vec3(eps / 2, eps / 2, kLz + 0.0005), true);
  c.toolVoltageV = 150;
  Simulation sim(std::move(mesh), c);
  FrameChecker check(sim, jouleHeating());
  hard::runChecked(check, 10);
  EXPECT_EQ(check.frames(), 10);
  EXPECT_GE(sim.lastRecord().contactNodes, 4);  // the needle column's four top nodes
  EXPECT_GT(check.maxSeenC(), 37.0);
}

// a ball whose surface is half the contact distance above one top node: that node alone
TEST(HardContact, ContactOnOneNode) {
  SimulationConfig c = hard::toolAt(ElectrodeKind::Sphere, Vec3(0, 0, kLz + 0.0005 + 0.0004), true);
  Simulation sim(makeSlab(hard::smallSlabSpec()), c);
  FrameChecker check(sim, jouleHeating());
  for (int f = 0; f < 10; ++f) {
    const FrameRecord& r = check.step();
    ASSERT_TRUE(check.ok());
    EXPECT_EQ(r.contactNodes, 1);
    EXPECT_FALSE(r.contactByTet);
    EXPECT_GT(r.toolCurrentA, 0.0);
  }
  EXPECT_TRUE(sim.warnings().empty());
}

// a blade laid flat over the whole top face, the return pad under the whole bottom face: a
// one-dimensional field, which P1 represents exactly: I = sigma A V / Lz, a uniform Joule
// source sigma (V / Lz)^2 and (lumped mass) a uniform temperature
TEST(HardContact, ContactOnTheWholeTopFace) {
  const double side = 0.06, sigma = 0.144, volts = 72;
  SimulationConfig c = hard::toolAt(ElectrodeKind::Blade, Vec3(0, -side / 2, kLz + 0.0005), true);
  c.toolPath.keys[0].orientation = eulerXyzDegToQuaternion(Vec3(-90, 0, 0));  // axis along +y
  c.electrode.widthM = side + 0.002;
  c.electrode.lengthM = side + 0.002;
  c.toolPath.keys[0].positionM.y() -= 0.001;
  c.returnElectrode.radiusM = 0.05;  // the whole bottom face
  Simulation sim(makeSlab(hard::smallSlabSpec()), c);
  FrameChecker check(sim, jouleHeating());
  const double current = sigma * side * side * volts / kLz;
  const double q = sigma * (volts / kLz) * (volts / kLz);
  for (int f = 0; f < 10; ++f) {
    const FrameRecord& r = check.step();
    ASSERT_TRUE(check.ok());
    EXPECT_EQ(r.contactNodes, 25 * 25);
    EXPECT_NEAR(r.toolCurrentA, current, 1e-9 * current);
    for (double qe : sim.joulePowerW_m3()) ASSERT_NEAR(qe, q, 1e-9 * q);
    const Eigen::VectorXd t = sim.temperatureC();
    const double rise = q * (f + 1) * c.frameDtS / c.thermal.heatCapacityJ_m3K;
    EXPECT_NEAR(t.maxCoeff(), 37.0 + rise, 1e-9 * rise);
    EXPECT_NEAR(t.minCoeff(), 37.0 + rise, 1e-9 * rise);
  }
}

// tool.contact volume, a tool holding every node but the return pad's: a plate inside the
// slab (the blade laid flat, 7.5 mm thick) over the four node layers z = 2.5 .. 10 mm, the pad
// under the whole bottom face. No node is left free; the field is that of the plate and the
// pad 2.5 mm apart, I = sigma A V / h, its Joule heat in the bottom layer of cells only. Every
// electric strategy takes the empty free set.
TEST(HardContact, ContactOnEveryNodeButTheReturnPad) {
  const double side = 0.06, sigma = 0.144, volts = 72, h = kLz / 4;
  for (ElectricStrategy s :
       {ElectricStrategy::DenseInverse, ElectricStrategy::Capacitance, ElectricStrategy::Refactor,
        ElectricStrategy::Pcg, ElectricStrategy::Local}) {
    SimulationConfig c =
        hard::toolAt(ElectrodeKind::Blade, Vec3(0, side / 2 + 0.001, 0.00625), true);
    c.contactNodes = ContactNodes::Volume;
    c.electricSolver.strategy = s;
    c.toolPath.keys[0].orientation = eulerXyzDegToQuaternion(Vec3(90, 0, 0));  // axis along -y
    c.electrode.radiusM = 0.00375;
    c.electrode.widthM = side + 0.002;
    c.electrode.lengthM = side + 0.002;
    c.returnElectrode.radiusM = 0.05;  // the whole bottom face
    Simulation sim(makeSlab(hard::smallSlabSpec()), c);
    FrameChecker check(sim, jouleHeating());
    const double current = sigma * side * side * volts / h;
    for (int f = 0; f < 3; ++f) {
      const FrameRecord& r = check.step();
      ASSERT_TRUE(check.ok()) << "strategy " << static_cast<int>(s);
      EXPECT_EQ(r.contactNodes, 4 * 25 * 25);
      EXPECT_NEAR(r.toolCurrentA, current, 1e-9 * current);
      double heated = 0;
      for (int e = 0; e < sim.mesh().numTets(); ++e) {
        double zMax = 0;
        for (int v : sim.mesh().tets[e]) zMax = std::max(zMax, sim.mesh().nodes[v].z());
        if (zMax > h * (1 + 1e-9)) {
          EXPECT_EQ(sim.joulePowerW_m3()[e], 0.0);
        } else {
          heated += sim.joulePowerW_m3()[e] * tetVolume(sim.mesh(), e);
        }
      }
      EXPECT_NEAR(heated, volts * current, 1e-9 * volts * current);
    }
  }
}

// the return pad off-centre (x, y > 5 mm), so that a tool reaching the bottom face away from
// it is a contact, not a short circuit
SimulationConfig offCentrePad(SimulationConfig c) {
  c.returnElectrode.centerM = Vec3(0.018, 0.018, 0);
  c.returnElectrode.radiusM = 0.01;
  return c;
}

// a ball that falls through the 10 mm slab within one frame (the third), on the line of a
// column of nodes, away from the return pad
SimulationConfig ballFallingThrough(ContactNodes rule) {
  SimulationConfig c = offCentrePad(hard::toolAt(ElectrodeKind::Sphere, Vec3::Zero(), true));
  c.contactNodes = rule;
  const double dt = c.frameDtS;
  hard::moveTool(c, Vec3(-0.01, -0.01, kLz + 0.005), dt, Vec3(-0.01, -0.01, -0.005), 2 * dt);
  return c;
}

// the falling ball's contacts along its path (top and bottom nodes on its line) carry the
// current of that frame; before and after, nothing
TEST(HardContact, ToolThroughTheTissueInOneFrame) {
  Simulation sim(makeSlab(hard::smallSlabSpec()), ballFallingThrough(ContactNodes::Surface));
  FrameChecker check(sim, jouleHeating());
  for (int f = 0; f < 6; ++f) {
    const FrameRecord& r = check.step();
    ASSERT_TRUE(check.ok());
    if (f == 2) {
      EXPECT_TRUE(r.toolSwept);
      EXPECT_GE(r.contactNodes, 2);  // the top and the bottom node under the path
      EXPECT_GT(r.toolCurrentA, 0.0);
    } else {
      EXPECT_EQ(r.contactNodes, 0) << "frame " << f;  // above, then below the slab
    }
  }
  // the path through the tissue (set-up), then the frame that swept it
  ASSERT_EQ(sim.warnings().size(), 2u);
  EXPECT_TRUE(hard::contains(sim.warnings()[0], "under the tissue's surface")) << sim.warnings()[0];
}

// a ball pressed against the bottom face from below, away from the pad
TEST(HardContact, ToolUnderTheTissue) {
  SimulationConfig c =
      offCentrePad(hard::toolAt(ElectrodeKind::Sphere, Vec3(-0.015, -0.015, -0.0005), true));
  c.toolVoltageV = 150;
  Simulation sim(makeSlab(hard::smallSlabSpec()), c);
  FrameChecker check(sim, jouleHeating());
  for (int f = 0; f < 10; ++f) {
    const FrameRecord& r = check.step();
    ASSERT_TRUE(check.ok());
    EXPECT_EQ(r.contactNodes, 1);
    EXPECT_GT(r.toolCurrentA, 0.0);
  }
  EXPECT_GT(check.maxSeenC(), 37.0);
  EXPECT_TRUE(sim.warnings().empty());
}

// a ball buried 5 mm deep, moving 20 mm inside the tissue: no surface node within reach in any
// frame; the nearest node of the tet holding its tip carries the current, with a warning
TEST(HardContact, ToolInsideTheTissue) {
  SimulationConfig c = hard::toolAt(ElectrodeKind::Sphere, Vec3::Zero(), true);
  hard::moveTool(c, Vec3(-0.01, 0.0011, 0.005), 0, Vec3(0.01, 0.0011, 0.005), 10 * c.frameDtS);
  Simulation sim(makeSlab(hard::smallSlabSpec()), c);
  FrameChecker check(sim, jouleHeating());
  for (int f = 0; f < 10; ++f) {
    const FrameRecord& r = check.step();
    ASSERT_TRUE(check.ok());
    EXPECT_TRUE(r.contactByTet) << "frame " << f;
    EXPECT_EQ(r.contactNodes, 1);
    EXPECT_GT(r.toolCurrentA, 0.0);
  }
  // the path 5 mm deep (set-up), then the frames the tet's node carried the current
  ASSERT_EQ(sim.warnings().size(), 2u);
  EXPECT_TRUE(hard::contains(sim.warnings()[0], "the tool reaches 5.5 mm under the tissue's"))
      << sim.warnings()[0];
  EXPECT_TRUE(hard::contains(sim.warnings()[1], "10 frames"));
}

// the same ball with tool.contact: volume. It reaches a node (1.1 mm off its line, 1.3 mm of
// reach) only within 0.69 mm of each node's x: those frames hold the nodes in reach, the
// others fall back to the tet's node; the set-up says nothing of the depth. Falling through
// the slab within one frame, it touches every node on its line, the three inside too.
TEST(HardContact, ToolInsideTheTissueWithVolumeContact) {
  SimulationConfig c = hard::toolAt(ElectrodeKind::Sphere, Vec3::Zero(), true);
  c.contactNodes = ContactNodes::Volume;
  hard::moveTool(c, Vec3(-0.01, 0.0011, 0.005), 0, Vec3(0.01, 0.0011, 0.005), 10 * c.frameDtS);
  Simulation sim(makeSlab(hard::smallSlabSpec()), c);
  FrameChecker check(sim, jouleHeating());
  int touched = 0, byTet = 0;
  for (int f = 0; f < 11; ++f) {
    const FrameRecord& r = check.step();
    ASSERT_TRUE(check.ok());
    EXPECT_GT(r.toolCurrentA, 0.0) << "frame " << f;
    if (r.contactByTet) {
      ++byTet;
      continue;
    }
    ++touched;
    for (int v : sim.contactNodes())
      EXPECT_LE(electrodeDistance(c.electrode, sim.state().pose, sim.mesh().nodes[v]),
                c.contactDistanceM)
          << "frame " << f;
  }
  EXPECT_GT(touched, 0);
  EXPECT_GT(byTet, 0);
  for (const std::string& w : sim.warnings())
    EXPECT_FALSE(hard::contains(w, "under the tissue's surface")) << w;

  Simulation through(makeSlab(hard::smallSlabSpec()), ballFallingThrough(ContactNodes::Volume));
  FrameChecker checkThrough(through, jouleHeating());
  for (int f = 0; f < 4; ++f) {
    const FrameRecord& r = checkThrough.step();
    ASSERT_TRUE(checkThrough.ok());
    if (f == 2) {
      EXPECT_EQ(r.contactNodes, 5);  // the five nodes on its line, z = 0 to 10 mm
    }
  }
}

// a blade pressed 0.2 mm into the top face sweeps across the whole 60 mm slab (from 10 mm
// before it to 10 mm past it) within one frame
TEST(HardContact, ToolAcrossTheTissueInOneFrame) {
  SimulationConfig c = hard::toolAt(ElectrodeKind::Blade, Vec3::Zero(), true);
  const double dt = c.frameDtS;
  hard::moveTool(c, Vec3(-0.04, 0, kLz - 0.0002), dt, Vec3(0.04, 0, kLz - 0.0002), 2 * dt);
  Simulation sim(makeSlab(hard::smallSlabSpec()), c);
  FrameChecker check(sim, jouleHeating());
  for (int f = 0; f < 5; ++f) {
    const FrameRecord& r = check.step();
    ASSERT_TRUE(check.ok());
    if (f == 2) {
      EXPECT_TRUE(r.toolSwept);
      EXPECT_GE(r.contactNodes, 25);  // the whole row of top nodes on y = 0
      EXPECT_GT(r.toolCurrentA, 0.0);
    } else {
      EXPECT_EQ(r.contactNodes, 0) << "frame " << f;
    }
  }
}

}  // namespace
}  // namespace esim
