// Tests for sim/electrode.cpp: distances to the sphere and blade, contact sets of a
// tool moved across a small slab (against hand-derived and brute-force sets), the
// grid finder against the brute force, the return pad.
#include "sim/electrode.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sim/core_error.h"
#include "sim/mesh_slab.h"

namespace esim {
namespace {

// 4 x 4 x 2 mm slab, 1 mm grid: x, y in {-2..2} mm, z in {0, 1, 2} mm
TetMesh tinySlab() {
  SlabSpec s;
  s.sizeM = Vec3(0.004, 0.004, 0.002);
  s.nodesPerAxis = {5, 5, 3};
  return makeSlab(s);
}

std::vector<int> surfaceOf(const TetMesh& m) { return boundaryNodes(m, boundaryFaces(m)); }

// node id of the grid point (i, j, k) mm, by search
int nodeAt(const TetMesh& m, double xmm, double ymm, double zmm) {
  for (int i = 0; i < m.numNodes(); ++i)
    if ((m.nodes[i] - Vec3(xmm, ymm, zmm) * 1e-3).norm() < 1e-9) return i;
  return -1;
}

TEST(Electrode, SphereAndBladeDistances) {
  const ElectrodeShape sphere{ElectrodeKind::Sphere, 0.001, 0, 0};
  const ToolPose at{Vec3(0.01, 0, 0), Eigen::Quaterniond::Identity()};
  EXPECT_NEAR(electrodeDistance(sphere, at, Vec3(0.013, 0, 0)), 0.002, 1e-15);
  EXPECT_NEAR(electrodeDistance(sphere, at, Vec3(0.01, 0, 0)), -0.001, 1e-15);
  // blade: width 4 mm (local x), length 10 mm up local z, half-thickness 0.5 mm
  const ElectrodeShape blade{ElectrodeKind::Blade, 0.0005, 0.01, 0.004};
  // rotate 90 deg about z: local x -> world y
  const ToolPose rot{Vec3(0, 0, 0.001),
                     Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Vec3::UnitZ()))};
  EXPECT_NEAR(electrodeDistance(blade, rot, Vec3(0, 0.002, 0.001)), -0.0005, 1e-12);  // edge corner
  EXPECT_NEAR(electrodeDistance(blade, rot, Vec3(0, 0.003, 0.001)), 0.0005, 1e-12);  // beyond width
  EXPECT_NEAR(electrodeDistance(blade, rot, Vec3(0.002, 0, 0.005)), 0.0015, 1e-12);  // off the face
  EXPECT_NEAR(electrodeDistance(blade, rot, Vec3(0, 0, -0.001)), 0.0015, 1e-12);  // below the tip
  EXPECT_NEAR(electrodeDistance(blade, rot, Vec3(0, 0, 0.013)), 0.0015, 1e-12);   // above the top
  // corner region: below the tip and beyond the width
  EXPECT_NEAR(electrodeDistance(blade, rot, Vec3(0, 0.005, -0.003)),
              std::sqrt(0.003 * 0.003 + 0.004 * 0.004) - 0.0005, 1e-12);
}

TEST(Electrode, BladeSweptAcrossTinySlabTouchesTheExpectedNodes) {
  const TetMesh m = tinySlab();
  const auto surface = surfaceOf(m);
  // vertical blade, width 2 mm along x, tip edge 0.3 mm above the top face (z = 2 mm),
  // contact distance 0.3 mm + thickness 0.1 mm: touches the top nodes with |x - x0| <= 1 mm, y = 0
  const ElectrodeShape blade{ElectrodeKind::Blade, 0.0001, 0.01, 0.002};
  for (int step = -2; step <= 2; ++step) {
    const ToolPose pose{Vec3(step * 1e-3, 0, 0.0023), Eigen::Quaterniond::Identity()};
    const auto c = findContacts(m, surface, blade, pose, 0.0002 + 1e-9);
    std::vector<int> expected;
    for (int dx = -1; dx <= 1; ++dx) {
      const int id = nodeAt(m, step + dx, 0, 2);
      if (id >= 0) expected.push_back(id);
    }
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(c, expected) << "step " << step;
  }
  // lifted out of reach: nothing
  const ToolPose lifted{Vec3(0, 0, 0.003), Eigen::Quaterniond::Identity()};
  EXPECT_TRUE(findContacts(m, surface, blade, lifted, 0.0002).empty());
  // a sphere on the side face x = +2 mm touches exactly one node
  const ElectrodeShape sphere{ElectrodeKind::Sphere, 0.0002, 0, 0};
  const ToolPose side{Vec3(0.0023, 0.001, 0.001), Eigen::Quaterniond::Identity()};
  EXPECT_EQ(findContacts(m, surface, sphere, side, 0.00015), std::vector<int>{nodeAt(m, 2, 1, 1)});
}

TEST(Electrode, GridFinderMatchesBruteForceForRandomPoses) {
  SlabSpec s;
  s.targetNodes = 5000;
  TetMesh m = makeSlab(s);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> j(-2e-4, 2e-4);
  for (auto& p : m.nodes) p += Vec3(j(rng), j(rng), j(rng));  // unstructured positions
  const auto surface = surfaceOf(m);
  const ContactFinder finder(m, surface);
  EXPECT_EQ(finder.numNodes(), int(surface.size()));
  std::uniform_real_distribution<double> px(-0.05, 0.05), pz(0.0, 0.012), ang(-M_PI, M_PI);
  int nonEmpty = 0;
  for (int trial = 0; trial < 200; ++trial) {
    ElectrodeShape shape;
    shape.kind = trial % 3 == 0 ? ElectrodeKind::Sphere : ElectrodeKind::Blade;
    shape.radiusM = 0.0005 + 0.002 * (trial % 5);
    const ToolPose pose{
        Vec3(px(rng), px(rng), pz(rng)),
        Eigen::Quaterniond(Eigen::AngleAxisd(ang(rng), Vec3(px(rng), px(rng), 0.03).normalized()))};
    const double dist = 0.001 * (trial % 4);
    // brute force: every surface node, the distance function, no prefilter
    std::vector<int> brute;
    for (int id : surface)
      if (electrodeDistance(shape, pose, m.nodes[id]) <= dist) brute.push_back(id);
    EXPECT_EQ(findContacts(m, surface, shape, pose, dist), brute) << "trial " << trial;
    EXPECT_EQ(finder.find(shape, pose, dist), brute) << "trial " << trial;
    nonEmpty += !brute.empty();
  }
  EXPECT_GT(nonEmpty, 30);
}

// a finder edited by the surface's changes after cuts finds what a finder built on the new
// surface finds (random poses, spheres and blades), node counts included
TEST(Electrode, UpdatedFinderMatchesAFreshOneAfterCuts) {
  SlabSpec s;
  s.targetNodes = 3000;
  TetMesh m = makeSlab(s);
  m.alive.assign(m.tets.size(), 1);
  const auto neighbours = tetFaceNeighbours(m);
  const Adjacency tetsAt = nodeTets(m);
  std::vector<int> surface = surfaceOf(m);
  ContactFinder finder(m, surface);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> px(-0.05, 0.05), pz(0.0, 0.012), ang(-M_PI, M_PI);
  std::uniform_int_distribution<int> pick(0, m.numTets() - 1);
  int nonEmpty = 0;
  for (int cut = 0; cut < 6; ++cut) {
    // a groove: every tet with a node within 3 mm of a point on the top, plus random tets
    const Vec3 at(px(rng), 0.3 * px(rng), 0.01);
    std::vector<int> removed;
    for (int e = 0; e < m.numTets(); ++e) {
      if (!m.alive[e]) continue;
      bool near = pick(rng) < 20;
      for (int v : m.tets[e]) near = near || (m.nodes[v] - at).norm() < 0.003 * (1 + cut % 3);
      if (near) removed.push_back(e);
    }
    for (int e : removed) m.alive[e] = 0;
    const BoundaryNodeChange change = updateBoundaryNodes(m, neighbours, tetsAt, removed, surface);
    ASSERT_FALSE(change.joined.empty());
    finder.update(m, change.left, change.joined);
    const ContactFinder fresh(m, surface);
    ASSERT_EQ(finder.numNodes(), fresh.numNodes());
    for (int trial = 0; trial < 60; ++trial) {
      ElectrodeShape shape;
      shape.kind = trial % 3 == 0 ? ElectrodeKind::Sphere : ElectrodeKind::Blade;
      shape.radiusM = 0.0005 + 0.002 * (trial % 5);
      const ToolPose pose{Vec3(at.x() + 0.2 * px(rng), at.y() + 0.2 * px(rng), pz(rng)),
                          Eigen::Quaterniond(Eigen::AngleAxisd(
                              ang(rng), Vec3(px(rng), px(rng), 0.03).normalized()))};
      const double dist = 0.001 * (trial % 4);
      const std::vector<int> expected = fresh.find(shape, pose, dist);
      EXPECT_EQ(finder.find(shape, pose, dist), expected) << "cut " << cut << " trial " << trial;
      nonEmpty += !expected.empty();
    }
  }
  EXPECT_GT(nonEmpty, 50);
}

TEST(Electrode, ReturnPadIsTheBottomDisc) {
  SlabSpec s;
  s.targetNodes = 1013;
  const TetMesh m = makeSlab(s);
  const auto surface = surfaceOf(m);
  const ReturnElectrode pad;  // centre (0,0,0), normal -z, radius 40 mm
  const auto g = returnElectrodeNodes(m, surface, pad);
  std::vector<int> expected;
  for (int id : m.nodeSets.at("bottom"))
    if (std::hypot(m.nodes[id].x(), m.nodes[id].y()) <= 0.04 + 1e-12) expected.push_back(id);
  EXPECT_EQ(g, expected);
  EXPECT_GT(g.size(), 10u);
  // a pad off the mesh touches nothing; a bad normal is an error
  ReturnElectrode away = pad;
  away.centerM = Vec3(0, 0, -0.01);
  EXPECT_TRUE(returnElectrodeNodes(m, surface, away).empty());
  ReturnElectrode bad = pad;
  bad.normal = Vec3::Zero();
  EXPECT_THROW(returnElectrodeNodes(m, surface, bad), Error);
  bad = pad;
  bad.radiusM = -1;
  EXPECT_THROW(returnElectrodeNodes(m, surface, bad), Error);
}

}  // namespace
}  // namespace esim
