// Tests for sim/rupture_nonlocal.cpp: the nonlocal average against its definition, computed
// here by brute force over every pair of tets, and broken() against the brute-force set.
#include "sim/rupture_nonlocal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "sim/core_error.h"
#include "sim/mesh_slab.h"

namespace esim {
namespace {

TetMesh slab() {
  SlabSpec s;
  s.sizeM = Vec3(0.01, 0.008, 0.004);
  s.nodesPerAxis = {9, 7, 4};
  return makeSlab(s);
}

Vec3 centroid(const TetMesh& m, int e) {
  Vec3 c = Vec3::Zero();
  for (int v : m.tets[e]) c += m.nodes[v] / 4.0;
  return c;
}

// the definition: every alive tet within R, weight (1 - d^2/R^2) V
double bruteAverage(const TetMesh& m, const std::vector<TetGeometry>& geo,
                    const std::vector<double>& f, int e, double r) {
  double sw = 0, s = 0;
  for (int j = 0; j < m.numTets(); ++j) {
    if (!m.isAlive(j)) continue;
    const double d2 = (centroid(m, j) - centroid(m, e)).squaredNorm();
    if (d2 >= r * r) continue;
    sw += (1 - d2 / (r * r)) * geo[j].volume;
    s += (1 - d2 / (r * r)) * geo[j].volume * f[j];
  }
  return s / sw;
}

std::vector<double> randomField(int n, unsigned seed) {
  std::mt19937 g(seed);
  std::uniform_real_distribution<double> u(0, 1e4);
  std::vector<double> f(n);
  for (double& v : f) v = u(g);
  return f;
}

TEST(NonlocalStress, AverageIsTheDefinitionWithRemovedTetsLeftOut) {
  TetMesh m = slab();
  const auto geo = tetGeometry(m);
  const auto f = randomField(m.numTets(), 1);
  m.alive.assign(m.numTets(), 1);
  for (int e = 0; e < m.numTets(); e += 7) m.alive[e] = 0;
  for (double r : {0.0004, 0.0013, 0.003}) {
    const NonlocalStress ns(m, geo, r);
    for (int e = 0; e < m.numTets(); ++e) {
      if (!m.isAlive(e)) continue;
      const double want = bruteAverage(m, geo, f, e, r);
      EXPECT_NEAR(ns.average(m, f, e), want, 1e-12 * want) << "tet " << e << ", R " << r;
    }
  }
}

TEST(NonlocalStress, ConstantStaysAndASmallRadiusIsTheLocalCriterion) {
  const TetMesh m = slab();
  const auto geo = tetGeometry(m);
  const std::vector<double> c(m.numTets(), 2.45e4);
  const NonlocalStress wide(m, geo, 0.004);
  for (int e = 0; e < m.numTets(); ++e) EXPECT_NEAR(wide.average(m, c, e), 2.45e4, 1e-9);
  // below the smallest distance between centroids: each tet alone
  const auto f = randomField(m.numTets(), 2);
  const NonlocalStress narrow(m, geo, 1e-5);
  std::vector<int> local;
  for (int e = 0; e < m.numTets(); ++e) {
    EXPECT_EQ(narrow.average(m, f, e), f[e]);
    if (f[e] > 5e3) local.push_back(e);
  }
  EXPECT_EQ(narrow.broken(m, f, 5e3), local);
  // far below the body's size (its grid then has cells wider than R)
  const NonlocalStress tiny(m, geo, 1e-12);
  EXPECT_EQ(tiny.broken(m, f, 5e3), local);
}

// two tets sharing a face: the weighted mean written out
TEST(NonlocalStress, TwoTetsByHand) {
  TetMesh m;
  m.nodes = {Vec3(0, 0, 0), Vec3(1e-3, 0, 0), Vec3(0, 1e-3, 0), Vec3(0, 0, 1e-3),
             Vec3(1e-3, 1e-3, 1e-3)};
  m.tets = {{0, 1, 2, 3}, {1, 2, 3, 4}};
  const auto geo = tetGeometry(m);
  const double v0 = 1e-9 / 6, d = (centroid(m, 0) - centroid(m, 1)).norm(), r = 1e-3;
  EXPECT_NEAR(geo[0].volume, v0, 1e-24);
  const double w = 1 - d * d / (r * r);
  const std::vector<double> f = {100.0, 400.0};
  const NonlocalStress ns(m, geo, r);
  EXPECT_NEAR(ns.average(m, f, 0), (v0 * 100 + w * geo[1].volume * 400) / (v0 + w * geo[1].volume),
              1e-9);
  EXPECT_NEAR(ns.average(m, f, 1), (w * v0 * 100 + geo[1].volume * 400) / (w * v0 + geo[1].volume),
              1e-9);
}

// broken() averages only near the tets over the limit: the same set as averaging everywhere
TEST(NonlocalStress, BrokenIsTheBruteForceSet) {
  TetMesh m = slab();
  const auto geo = tetGeometry(m);
  m.alive.assign(m.numTets(), 1);
  for (int e = 3; e < m.numTets(); e += 11) m.alive[e] = 0;
  // a hot spot over a low background, so that few tets pass
  std::vector<double> f = randomField(m.numTets(), 3);
  for (int e = 0; e < m.numTets(); ++e)
    if ((centroid(m, e) - Vec3(0.002, 0.001, 0.003)).norm() < 0.0015) f[e] += 3e4;
  for (double r : {0.0008, 0.002}) {
    const NonlocalStress ns(m, geo, r);
    for (double limit : {1e4, 2e4, 3e4}) {
      std::vector<int> want;
      for (int e = 0; e < m.numTets(); ++e)
        if (m.isAlive(e) && bruteAverage(m, geo, f, e, r) > limit) want.push_back(e);
      EXPECT_EQ(ns.broken(m, f, limit), want) << "R " << r << ", limit " << limit;
      EXPECT_FALSE(want.empty() && limit < 3e4);
    }
  }
}

// a radius of the body's size on ~19 000 tets: every frame could visit 3.6e8 pairs
TEST(NonlocalStress, RefusesARadiusThatWouldMakeFramesOfMinutes) {
  SlabSpec s;
  s.sizeM = Vec3(0.03, 0.03, 0.01);
  s.nodesPerAxis = {20, 20, 10};
  const TetMesh m = makeSlab(s);
  const auto geo = tetGeometry(m);
  try {
    NonlocalStress ns(m, geo, 0.05);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("material.critical_stress_radius_m = 0.05 m: a frame's "
                                         "average could visit"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("(at most 1e+08)"), std::string::npos) << e.what();
  }
  NonlocalStress fine(m, geo, 0.001);  // a few elements: accepted
  EXPECT_EQ(fine.radiusM(), 0.001);
}

TEST(NonlocalStress, RefusesARadiusThatIsNotPositive) {
  const TetMesh m = slab();
  const auto geo = tetGeometry(m);
  for (double r : {0.0, -1.0, std::nan("")}) {
    try {
      NonlocalStress ns(m, geo, r);
      FAIL() << r;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("material.critical_stress_radius_m must be > 0"),
                std::string::npos)
          << e.what();
    }
  }
}

}  // namespace
}  // namespace esim
