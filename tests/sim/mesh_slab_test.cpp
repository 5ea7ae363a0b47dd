// Tests for sim/mesh_slab.cpp: the paper's slab at its sizes, volume, area, grading.
#include "sim/mesh_slab.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "sim/core_error.h"

namespace esim {
namespace {

SlabSpec paperSlab(int nodes) {
  SlabSpec s;
  s.targetNodes = nodes;
  return s;
}

TEST(MeshSlab, VolumeAreaAndOrientation) {
  const TetMesh m = makeSlab(paperSlab(1013));
  EXPECT_NEAR(meshVolume(m), 1.0e-4, 1.0e-4 * 1e-12);
  const auto faces = boundaryFaces(m);
  EXPECT_NEAR(surfaceArea(m, faces), 2.4e-2, 2.4e-2 * 1e-12);
  for (int e = 0; e < m.numTets(); ++e) ASSERT_GT(tetVolume(m, e), 0.0) << "tet " << e;
  EXPECT_NO_THROW(validateMesh(m, "slab"));
  // structured grid: 6 tets per hex, 2 triangles per boundary quad
  const auto p = slabNodesPerAxis(paperSlab(1013));
  EXPECT_EQ(m.numNodes(), p[0] * p[1] * p[2]);
  EXPECT_EQ(m.numTets(), 6 * (p[0] - 1) * (p[1] - 1) * (p[2] - 1));
  const int quads = (p[0] - 1) * (p[1] - 1) + (p[0] - 1) * (p[2] - 1) + (p[1] - 1) * (p[2] - 1);
  EXPECT_EQ(static_cast<int>(faces.size()), 4 * quads);
  EXPECT_EQ(static_cast<int>(m.nodeSets.at("top").size()), p[0] * p[1]);
  for (int v : m.nodeSets.at("top")) EXPECT_DOUBLE_EQ(m.nodes[v].z(), 0.01);
  for (int v : m.nodeSets.at("bottom")) EXPECT_DOUBLE_EQ(m.nodes[v].z(), 0.0);
}

TEST(MeshSlab, PaperNodeCountsWithinThreePercent) {
  for (int target : {506, 643, 1013}) {
    const TetMesh m = makeSlab(paperSlab(target));
    EXPECT_LE(std::abs(m.numNodes() - target), 0.03 * target)
        << "target " << target << " got " << m.numNodes();
    EXPECT_NEAR(meshVolume(m), 1.0e-4, 1e-16);
  }
}

TEST(MeshSlab, ScalesTo200kNodes) {
  const TetMesh m = makeSlab(paperSlab(200000));
  EXPECT_LE(std::abs(m.numNodes() - 200000), 0.03 * 200000);
  EXPECT_NEAR(meshVolume(m), 1.0e-4, 1.0e-4 * 1e-11);
  int inverted = 0;
  for (int e = 0; e < m.numTets(); ++e) inverted += tetVolume(m, e) <= 0;
  EXPECT_EQ(inverted, 0);
}

TEST(MeshSlab, GradingIsFinerAlongTheCut) {
  SlabSpec s = paperSlab(20000);
  s.grading.enabled = true;
  s.grading.cutFrom = Vec3(-0.04, 0.0, 0.01);
  s.grading.cutTo = Vec3(0.04, 0.0, 0.01);
  s.grading.ratio = 4.0;
  s.grading.widthM = 0.01;
  const TetMesh m = makeSlab(s);
  EXPECT_NEAR(meshVolume(m), 1.0e-4, 1.0e-4 * 1e-12);
  for (int e = 0; e < m.numTets(); ++e) ASSERT_GT(tetVolume(m, e), 0.0);
  // y spacing: distinct y coordinates of the top face
  std::vector<double> ys;
  for (int v : m.nodeSets.at("top")) ys.push_back(m.nodes[v].y());
  std::sort(ys.begin(), ys.end());
  ys.erase(std::unique(ys.begin(), ys.end()), ys.end());
  double fine = INFINITY, coarse = 0;
  for (size_t i = 0; i + 1 < ys.size(); ++i) {
    const double h = ys[i + 1] - ys[i], mid = 0.5 * (ys[i] + ys[i + 1]);
    if (std::abs(mid) < 0.005) fine = std::min(fine, h);
    if (std::abs(mid) > 0.03) coarse = std::max(coarse, h);
  }
  EXPECT_NEAR(coarse / fine, 4.0, 0.4);
  // x spans the cut: the x spacing stays fine (uniform within the cut's x range)
  EXPECT_GT(m.nodeSets.at("top").size(), 0u);
}

TEST(MeshSlab, BadSpecIsAnError) {
  SlabSpec s;
  s.sizeM = Vec3(0.1, -0.1, 0.01);
  EXPECT_THROW(makeSlab(s), Error);
  SlabSpec g;
  g.grading.enabled = true;
  g.grading.ratio = 0.5;
  EXPECT_THROW(makeSlab(g), Error);
}

}  // namespace
}  // namespace esim
