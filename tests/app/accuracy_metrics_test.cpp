// accuracy_metrics_test.cpp - cut metrics across different meshes
// (tools/app/accuracy_metrics.cpp) on tiny inline meshes with known answers.
#include "tools/app/accuracy_metrics.h"

#include <gtest/gtest.h>

#include <cmath>

#include "sim/mesh_slab.h"

namespace esim::app {
namespace {

TetMesh slab(Vec3 size, std::array<int, 3> nodes) {
  SlabSpec s;
  s.sizeM = size;
  s.nodesPerAxis = nodes;
  TetMesh m = makeSlab(s);
  m.alive.assign(m.numTets(), 1);
  return m;
}

Vec3 centroid(const TetMesh& m, int e) {
  Vec3 c = Vec3::Zero();
  for (int v : m.tets[e]) c += m.nodes[v] / 4.0;
  return c;
}

// removes the tets whose centroid passes the test
template <class F>
void removeWhere(TetMesh& m, F f) {
  for (int e = 0; e < m.numTets(); ++e)
    if (f(centroid(m, e))) m.alive[e] = 0;
}

TEST(AccuracyMetrics, OneRemovedTetCoversTheVoxelCentresInsideIt) {
  TetMesh m;
  m.nodes = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  m.tets = {{0, 1, 2, 3}};
  m.alive = {1};
  VoxelGrid g{Eigen::AlignedBox3d(Vec3(0, 0, 0), Vec3(1, 1, 1)), {10, 10, 10}};
  const auto none = removedVoxels(m, g);
  EXPECT_EQ(std::count(none.begin(), none.end(), 1), 0);
  m.alive = {0};
  const auto r = removedVoxels(m, g);
  // centres (i + 1/2) / 10 with i + j + k + 3/2 <= 10: i + j + k <= 8, C(11, 3) of them
  EXPECT_EQ(std::count(r.begin(), r.end(), 1), 165);
  EXPECT_EQ(r[0], 1);                      // (0.05, 0.05, 0.05)
  EXPECT_EQ(r[9], 0);                      // (0.95, 0.05, 0.05)
  EXPECT_EQ(r[8], 1);                      // (0.85, 0.05, 0.05)
  EXPECT_EQ(r[8 + 10 * (0 + 10 * 1)], 0);  // (0.85, 0.05, 0.15): 1.05 > 1
}

// the same removed region on a coarse and a fine mesh: IoU 1; a region a quarter wider on
// the fine mesh: IoU = 1/2 / (3/4)
TEST(AccuracyMetrics, IntersectionOverUnionAcrossDifferentMeshes) {
  const Vec3 size(0.04, 0.02, 0.01);
  TetMesh coarse = slab(size, {3, 3, 3}), fine = slab(size, {5, 7, 4});
  removeWhere(coarse, [](const Vec3& c) { return c.x() < 0; });
  removeWhere(fine, [](const Vec3& c) { return c.x() < 0; });
  ASSERT_NE(coarse.numTets(), fine.numTets());
  VoxelGrid g{Eigen::AlignedBox3d(Vec3(-0.02, -0.01, 0), Vec3(0.02, 0.01, 0.01)), {40, 20, 10}};
  const auto a = removedVoxels(coarse, g), b = removedVoxels(fine, g);
  EXPECT_EQ(std::count(a.begin(), a.end(), 1), 20 * 20 * 10);
  EXPECT_DOUBLE_EQ(intersectionOverUnion(a, b), 1.0);
  TetMesh wider = slab(size, {5, 7, 4});  // node planes at x = -0.01, 0, 0.01
  removeWhere(wider, [](const Vec3& c) { return c.x() < 0.01; });
  EXPECT_DOUBLE_EQ(intersectionOverUnion(a, removedVoxels(wider, g)), 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(
      intersectionOverUnion(std::vector<std::uint8_t>(5, 0), std::vector<std::uint8_t>(5, 0)), 1.0);
}

// a rectangular groove along x: 10 mm wide (|y| < 5 mm), 2.5 mm deep, on two meshes
TEST(AccuracyMetrics, GrooveWidthDepthAndVolume) {
  const Vec3 size(0.04, 0.02, 0.01);
  VoxelGrid g{Eigen::AlignedBox3d(Vec3(-0.02, -0.01, 0), Vec3(0.02, 0.01, 0.01)), {80, 40, 40}};
  for (std::array<int, 3> n : {std::array<int, 3>{5, 5, 5}, std::array<int, 3>{9, 9, 9}}) {
    TetMesh m = slab(size, n);
    removeWhere(m, [](const Vec3& c) { return std::abs(c.y()) < 0.005 && c.z() > 0.0075; });
    const GrooveShape s = grooveShape(m, g, removedVoxels(m, g), size.z());
    EXPECT_NEAR(s.removedVolumeM3, 0.04 * 0.01 * 0.0025, 1e-15) << n[0];
    EXPECT_NEAR(s.widthM, 0.01, 1e-12) << n[0];
    EXPECT_NEAR(s.depthM, 0.0025, 1e-12) << n[0];
    EXPECT_EQ(s.sections, 80) << n[0];
  }
  // a groove along half the length only, deeper at one end: medians over the sections
  TetMesh m = slab(size, {9, 9, 9});  // spacing 5 x 2.5 x 1.25 mm
  removeWhere(m, [](const Vec3& c) {
    return c.x() < 0 && std::abs(c.y()) < 0.0025 && c.z() > (c.x() < -0.015 ? 0.005 : 0.00875);
  });
  const GrooveShape s = grooveShape(m, g, removedVoxels(m, g), size.z());
  EXPECT_EQ(s.sections, 40);
  EXPECT_NEAR(s.widthM, 0.005, 1e-12);
  EXPECT_NEAR(s.depthM, 0.00125, 1e-12);  // 30 of the 40 sections are 1.25 mm deep
}

TEST(AccuracyMetrics, ProbesInterpolateLinearFieldsExactly) {
  const TetMesh m = slab(Vec3(0.04, 0.02, 0.01), {4, 5, 3});
  Eigen::VectorXd f(m.numNodes());
  auto linear = [](const Vec3& p) { return 1 + 200 * p.x() - 300 * p.y() + 50 * p.z(); };
  for (int i = 0; i < m.numNodes(); ++i) f[i] = linear(m.nodes[i]);
  const std::vector<Vec3> pts = {Vec3(0.0013, -0.0041, 0.0077), Vec3(-0.019, 0.0099, 0.0001),
                                 Vec3(0.0, 0.0, 0.005), Vec3(0.5, 0, 0)};
  const auto loc = locateProbes(m, pts);
  for (int p = 0; p < 3; ++p) {
    ASSERT_GE(loc[p].tet, 0) << p;
    EXPECT_NEAR(sampleNodal(m, f, loc[p]), linear(pts[p]), 1e-12) << p;
  }
  EXPECT_EQ(loc[3].tet, -1);
  EXPECT_TRUE(std::isnan(sampleNodal(m, f, loc[3])));
  EXPECT_NEAR(volumeIntegral(m, std::vector<double>(m.numTets(), 0.5)), 0.5 * 0.04 * 0.02 * 0.01,
              1e-15);
}

TEST(AccuracyMetrics, ConvergenceOrderAndParetoFront) {
  EXPECT_NEAR(convergenceOrder(0.2, 0.04, 0.1, 0.01), 2.0, 1e-12);
  EXPECT_NEAR(convergenceOrder(0.2, 0.04, 0.1, 0.02), 1.0, 1e-12);
  EXPECT_TRUE(std::isnan(convergenceOrder(0.2, 0.0, 0.1, 0.01)));
  const double nan = std::nan("");
  // 1 is dominated by 0 (dearer, worse), 3 by 2 (dearer, as good), 4 has no error
  const std::vector<int> f = paretoFront({1, 2, 3, 4, 0.5, 10}, {0.5, 0.6, 0.1, 0.1, nan, 0.01});
  EXPECT_EQ(f, (std::vector<int>{0, 2, 5}));
}

}  // namespace
}  // namespace esim::app
