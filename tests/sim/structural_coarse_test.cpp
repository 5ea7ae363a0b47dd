// Tests for sim/structural_coarse.cpp: the grid; a field in the coarse space (linear,
// zero on the clamp) solved exactly (Galerkin); K_c kept up to date by per-tet
// contributions equal to one built afresh (tets removed, dofs newly held); bad spacings.
#include "sim/structural_coarse.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "sim/core_error.h"
#include "sim/fem_p1.h"
#include "sim/mesh_slab.h"
#include "sim/structural.h"

namespace esim {
namespace {

constexpr double kE = 4.75e4, kNu = 0.4;

TetMesh slab() {
  SlabSpec s;
  s.sizeM = {0.02, 0.016, 0.01};
  s.nodesPerAxis = {9, 7, 5};
  return makeSlab(s);
}

// the lower triangle of K over all 3n dofs from the alive tets, held dofs' rows and columns
// dropped (the identity on their diagonal, as the phase's A)
SparseMatrix lowerStiffness(const TetMesh& mesh, const std::vector<std::uint8_t>& alive,
                            const std::vector<std::uint8_t>& held) {
  const std::vector<TetGeometry> geo = tetGeometry(mesh);
  std::vector<Eigen::Triplet<double>> triplets;
  for (int t = 0; t < mesh.numTets(); ++t) {
    if (!alive[t]) continue;
    const Eigen::Matrix<double, 12, 12> ke = elasticTetStiffness(geo[t], kE, kNu);
    for (int i = 0; i < 12; ++i)
      for (int j = 0; j < 12; ++j) {
        const int di = 3 * mesh.tets[t][i / 3] + i % 3, dj = 3 * mesh.tets[t][j / 3] + j % 3;
        if (!held[di] && !held[dj] && dj <= di) triplets.emplace_back(di, dj, ke(i, j));
      }
  }
  const int n = 3 * mesh.numNodes();
  for (int d = 0; d < n; ++d)
    if (held[d]) triplets.emplace_back(d, d, 1.0);
  SparseMatrix k(n, n);
  k.setFromTriplets(triplets.begin(), triplets.end());
  return k;
}

std::vector<std::uint8_t> clampBottom(const TetMesh& mesh) {
  std::vector<std::uint8_t> held(3 * mesh.numNodes(), 0);
  for (int v = 0; v < mesh.numNodes(); ++v)
    if (mesh.nodes[v].z() < 1e-12)
      for (int a = 0; a < 3; ++a) held[3 * v + a] = 1;
  return held;
}

TEST(CoarseSpace, GridCoversTheBoxWithCellsNoLargerThanTheSpacing) {
  const TetMesh mesh = slab();  // 20 x 16 x 10 mm
  CoarseSpace c(mesh.nodes, 0.004);
  EXPECT_EQ(c.cells(), (std::array<int, 3>{5, 4, 3}));
  EXPECT_EQ(c.numGridNodes(), 6 * 5 * 4);
  CoarseSpace coarse(mesh.nodes, 1.0);  // one cell
  EXPECT_EQ(coarse.numGridNodes(), 8);
}

TEST(CoarseSpace, AutomaticSpacingIsTheFinestWithinItsNodeCount) {
  SlabSpec s;  // slab_cut's box
  s.sizeM = {0.06, 0.03, 0.01};
  s.nodesPerAxis = {7, 4, 3};
  const TetMesh mesh = makeSlab(s);
  CoarseSpace c(mesh.nodes, 0);
  EXPECT_LE(c.numGridNodes(), CoarseSpace::kAutoGridNodes);
  EXPECT_EQ(c.cells(), (std::array<int, 3>{12, 6, 2}));  // 5 mm cells, 273 nodes
  EXPECT_GT(c.spacingM(), 0.005 - 1e-12);
  // the next finer spacing of the sequence has too many nodes
  CoarseSpace finer(mesh.nodes, 0.97 * c.spacingM());
  EXPECT_GT(finer.numGridNodes(), CoarseSpace::kAutoGridNodes);
}

TEST(CoarseSpace, FieldInTheCoarseSpaceIsSolvedExactly) {
  // u* = z (1, -2, 3) mm/m: linear (in every trilinear space), 0 on the clamped bottom;
  // with f = K u*, the Galerkin coarse solution is u* whatever the grid
  const TetMesh mesh = slab();
  const std::vector<std::uint8_t> held = clampBottom(mesh);
  const std::vector<std::uint8_t> alive(mesh.numTets(), 1);
  const SparseMatrix k = lowerStiffness(mesh, alive, held);
  Eigen::VectorXd exact = Eigen::VectorXd::Zero(3 * mesh.numNodes());
  for (int v = 0; v < mesh.numNodes(); ++v)
    for (int a = 0; a < 3; ++a)
      if (!held[3 * v + a]) exact(3 * v + a) = 1e-3 * mesh.nodes[v].z() * (a == 1 ? -2 : a + 1);
  const Eigen::VectorXd f = k.selfadjointView<Eigen::Lower>() * exact;
  for (double spacing : {0.003, 0.0055, 0.02, 0.0}) {
    CoarseSpace c(mesh.nodes, spacing);
    c.build(k, held.data());
    Eigen::VectorXd u;
    c.solve(f, held.data(), u);
    EXPECT_LT((u - exact).norm(), 1e-7 * exact.norm()) << "spacing " << spacing;
  }
}

TEST(CoarseSpace, RemovalsByPerTetContributionsEqualAFreshBuild) {
  const TetMesh mesh = slab();
  std::vector<std::uint8_t> held = clampBottom(mesh);
  std::vector<std::uint8_t> alive(mesh.numTets(), 1);
  const std::vector<TetGeometry> geo = tetGeometry(mesh);
  CoarseSpace updated(mesh.nodes, 0.004);
  updated.build(lowerStiffness(mesh, alive, held), held.data());
  // remove a block of tets near the top centre, then hold the nodes of one more tet
  std::vector<int> removed;
  for (int t = 0; t < mesh.numTets(); ++t) {
    Vec3 c = Vec3::Zero();
    for (int v : mesh.tets[t]) c += mesh.nodes[v] / 4;
    if (c.z() > 0.006 && std::abs(c.x()) < 0.004 && std::abs(c.y()) < 0.003) removed.push_back(t);
  }
  ASSERT_GT(removed.size(), 10u);
  for (int t : removed) {
    updated.addTet(mesh.tets[t], elasticTetStiffness(geo[t], kE, kNu), -1,
                   [&](int d) { return held[d] != 0; });
    alive[t] = 0;
  }
  int other = 0;
  while (!alive[other] || mesh.nodes[mesh.tets[other][0]].z() < 1e-12) ++other;
  const int v = mesh.tets[other][0];
  std::vector<std::uint8_t> before = held;
  for (int a = 0; a < 3; ++a) held[3 * v + a] = 1;
  for (int t = 0; t < mesh.numTets(); ++t) {
    bool touches = false;
    for (int w : mesh.tets[t]) touches = touches || w == v;
    if (!alive[t] || !touches) continue;
    const Eigen::Matrix<double, 12, 12> ke = elasticTetStiffness(geo[t], kE, kNu);
    updated.addTet(mesh.tets[t], ke, -1, [&](int d) { return before[d] != 0; });
    updated.addTet(mesh.tets[t], ke, 1, [&](int d) { return held[d] != 0; });
  }
  CoarseSpace fresh(mesh.nodes, 0.004);
  fresh.build(lowerStiffness(mesh, alive, held), held.data());
  Eigen::VectorXd f(3 * mesh.numNodes());
  for (int d = 0; d < f.size(); ++d) f(d) = std::sin(0.7 * d) * 1e-3;
  Eigen::VectorXd a, b;
  updated.solve(f, held.data(), a);
  fresh.solve(f, held.data(), b);
  EXPECT_GT(a.norm(), 0);
  EXPECT_LT((a - b).norm(), 1e-9 * b.norm());
}

TEST(CoarseSpace, RejectsBadSpacings) {
  const TetMesh mesh = slab();
  for (double s : {-1.0, std::nan(""), 1e-6}) {
    try {
      CoarseSpace c(mesh.nodes, s);
      ADD_FAILURE() << "no error for " << s;
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::Input);
      const std::string what = e.what();
      EXPECT_NE(what.find("coarse grid"), std::string::npos) << what;
      if (s == 1e-6) {
        EXPECT_NE(what.find("use a larger spacing"), std::string::npos) << what;
      }
    }
  }
}

}  // namespace
}  // namespace esim
