// Tests for sim/rupture_debris.cpp: the pieces a removal cuts loose against a brute-force
// labelling of every face-connected piece of the mesh, and the cases the rules name: a layer
// cut off whole at its exact volume, a support that keeps a piece, the last piece kept.
#include "sim/rupture_debris.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <vector>

#include "sim/mesh_slab.h"

namespace esim {
namespace {

TetMesh slab(std::array<int, 3> nodes) {
  SlabSpec s;
  s.sizeM = Vec3(0.006, 0.004, 0.003);
  s.nodesPerAxis = nodes;
  TetMesh m = makeSlab(s);
  m.alive.assign(m.numTets(), 1);
  return m;
}

double centroidZ(const TetMesh& m, int e) {
  double z = 0;
  for (int v : m.tets[e]) z += m.nodes[v].z() / 4;
  return z;
}

// the definition, over the whole mesh: union-find of the alive tets left over their shared
// faces; a piece is debris when it holds a face neighbour of a removed tet, its volume is at
// most maxV and none of its nodes is supported; none when that is all the tissue left
std::vector<int> bruteDebris(const TetMesh& m, const std::vector<std::array<int, 4>>& nb,
                             const std::vector<TetGeometry>& geo,
                             const std::vector<std::uint8_t>& supported,
                             const std::vector<int>& removed, double maxV) {
  const int nt = m.numTets();
  std::vector<std::uint8_t> left(nt);
  for (int t = 0; t < nt; ++t) left[t] = m.isAlive(t);
  for (int t : removed) left[t] = 0;
  std::vector<int> parent(nt);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (int t = 0; t < nt; ++t)
    for (int o : nb[t])
      if (o >= 0 && left[t] && left[o]) parent[find(t)] = find(o);
  std::vector<double> volume(nt, 0);
  std::vector<std::uint8_t> held(nt, 0), touched(nt, 0);
  int total = 0;
  for (int t = 0; t < nt; ++t) {
    if (!left[t]) continue;
    ++total;
    volume[find(t)] += geo[t].volume;
    for (int v : m.tets[t])
      if (!supported.empty() && supported[v]) held[find(t)] = 1;
  }
  for (int r : removed)
    for (int o : nb[r])
      if (o >= 0 && left[o]) touched[find(o)] = 1;
  std::vector<int> out;
  for (int t = 0; t < nt; ++t) {
    const int p = find(t);
    if (left[t] && touched[p] && volume[p] <= maxV && !held[p]) out.push_back(t);
  }
  if (static_cast<int>(out.size()) == total) out.clear();
  return out;
}

TEST(RuptureDebris, EqualsTheBruteForcePiecesOfRandomRemovals) {
  TetMesh m = slab({7, 6, 5});
  const auto nb = tetFaceNeighbours(m);
  const auto geo = tetGeometry(m);
  const double meanV = meshVolume(m) / m.numTets();
  std::vector<std::uint8_t> supported(m.numNodes(), 0);
  for (int v = 0; v < m.numNodes(); ++v) supported[v] = m.nodes[v].z() < 1e-9;  // the base
  std::mt19937 g(7);
  int debrisSeen = 0, casesWithDebris = 0;
  for (int round = 0; round < 40; ++round) {
    // an alive set with earlier removals, then a batch to remove
    TetMesh cut = m;
    std::bernoulli_distribution dead(0.25 + 0.01 * round), pick(0.15);
    std::vector<int> removed;
    for (int t = 0; t < cut.numTets(); ++t) {
      if (dead(g)) {
        cut.alive[t] = 0;
      } else if (pick(g)) {
        removed.push_back(t);
      }
    }
    for (double pieces : {0.5, 3.0, 40.0, 1e9}) {
      const double maxV = pieces * meanV;
      for (const auto& sup : {supported, std::vector<std::uint8_t>{}}) {
        const std::vector<int> got = debrisCutLoose(cut, nb, geo, sup, removed, maxV);
        ASSERT_EQ(got, bruteDebris(cut, nb, geo, sup, removed, maxV))
            << "round " << round << ", max volume " << pieces << " mean tets";
        debrisSeen += static_cast<int>(got.size());
        casesWithDebris += got.empty() ? 0 : 1;
      }
    }
  }
  EXPECT_GT(casesWithDebris, 100);  // the comparison saw debris, not only empty sets
  EXPECT_GT(debrisSeen, 1000);
}

// a slab of four layers of cells: removing the second cuts off the base layer (on the
// supports) and the two layers above (volume twice the base's)
TEST(RuptureDebris, APieceCutOffGoesAtItsVolumeAndNotBelow) {
  const TetMesh m = slab({4, 3, 5});  // cells 2 x 2 x 0.75 mm
  const auto nb = tetFaceNeighbours(m);
  const auto geo = tetGeometry(m);
  std::vector<int> second, top, base;
  double topV = 0;
  for (int t = 0; t < m.numTets(); ++t) {
    const double z = centroidZ(m, t);
    if (z < 0.00075) base.push_back(t);
    if (z > 0.00075 && z < 0.0015) second.push_back(t);
    if (z > 0.0015) {
      top.push_back(t);
      topV += geo[t].volume;
    }
  }
  ASSERT_NEAR(topV, 0.006 * 0.004 * 0.0015, 1e-18);
  std::vector<std::uint8_t> onBase(m.numNodes(), 0);
  for (int v = 0; v < m.numNodes(); ++v) onBase[v] = m.nodes[v].z() < 1e-9;
  EXPECT_EQ(debrisCutLoose(m, nb, geo, onBase, second, topV * (1 + 1e-9)), top);
  EXPECT_TRUE(debrisCutLoose(m, nb, geo, onBase, second, topV * (1 - 1e-9)).empty());
  EXPECT_TRUE(debrisCutLoose(m, nb, geo, onBase, second, 0.0).empty());  // off
  // a support on the top keeps it, and the base piece then goes
  std::vector<std::uint8_t> onTop(m.numNodes(), 0);
  for (int v = 0; v < m.numNodes(); ++v) onTop[v] = m.nodes[v].z() > 0.003 - 1e-9;
  EXPECT_EQ(debrisCutLoose(m, nb, geo, onTop, second, topV), base);
  // no supports: under a limit between the two pieces' volumes only the base goes; above
  // both, both pieces would: that is all the tissue left, so neither goes
  EXPECT_EQ(debrisCutLoose(m, nb, geo, {}, second, topV * 0.75), base);
  EXPECT_TRUE(debrisCutLoose(m, nb, geo, {}, second, 1.0).empty());
}

// removing all but one tet: the last tet is the whole tissue left, never debris
TEST(RuptureDebris, TheLastPieceIsNeverDebris) {
  const TetMesh m = slab({3, 3, 3});
  const auto nb = tetFaceNeighbours(m);
  const auto geo = tetGeometry(m);
  std::vector<int> removed(m.numTets() - 1);
  std::iota(removed.begin(), removed.end(), 1);
  EXPECT_TRUE(debrisCutLoose(m, nb, geo, {}, removed, 1.0).empty());
}

}  // namespace
}  // namespace esim
