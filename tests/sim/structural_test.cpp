// Tests for sim/structural.cpp against the uniform-eigenstrain solutions of
// ../shared/REFERENCE.md (case 7), exact for P1 on any mesh: clamped body
// (hydrostatic), laterally constrained layer, free expansion (no stress); plus removed
// tets, linearity and bad input.
#include "sim/structural.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>

#include "sim/core_error.h"
#include "sim/mesh_slab.h"

namespace esim {
namespace {

constexpr double kE = 4.75e4, kNu = 0.4, kEv = 0.02;  // paper's E, nu; 2 % expansion
constexpr double kLx = 0.02, kLy = 0.016, kLz = 0.01;

bool onBoundary(const Vec3& p) {
  auto at = [](double v, double a) { return std::abs(v - a) < 1e-12; };
  return at(p.x(), -kLx / 2) || at(p.x(), kLx / 2) || at(p.y(), -kLy / 2) || at(p.y(), kLy / 2) ||
         at(p.z(), 0) || at(p.z(), kLz);
}

// a 5 x 4 x 4-node slab whose interior nodes are moved by up to 20 % of the spacing
// (deterministic), so that nothing depends on a regular grid
TetMesh distortedSlab() {
  SlabSpec s;
  s.sizeM = {kLx, kLy, kLz};
  s.nodesPerAxis = {5, 4, 4};
  TetMesh mesh = makeSlab(s);
  std::uint32_t state = 12345;
  auto rnd = [&] {  // uniform in [-1, 1)
    state = state * 1664525u + 1013904223u;
    return static_cast<double>(state >> 8) / (1u << 23) - 1.0;
  };
  for (Vec3& p : mesh.nodes)
    if (!onBoundary(p)) p += 0.2 * Vec3(rnd() * kLx / 4, rnd() * kLy / 3, rnd() * kLz / 3);
  return mesh;
}

std::vector<Support> hold(const TetMesh& mesh, bool (*pick)(const Vec3&), std::vector<int> axes) {
  std::vector<Support> out;
  for (int v = 0; v < mesh.numNodes(); ++v)
    if (pick(mesh.nodes[v]))
      for (int a : axes) out.push_back({v, a});
  return out;
}

StructuralOptions paper() {
  StructuralOptions o;
  o.youngsModulusPa = kE;
  o.poissonRatio = kNu;
  return o;
}

TEST(Structural, ClampedBodyIsHydrostatic) {
  const TetMesh mesh = distortedSlab();
  StructuralPhase phase(mesh, paper(), hold(mesh, onBoundary, {0, 1, 2}));
  phase.solve(std::vector<double>(mesh.numTets(), kEv));
  const double sigma = -kE * kEv / (3 * (1 - 2 * kNu));  // -1583 Pa
  for (int t = 0; t < mesh.numTets(); ++t) {
    const VoigtStress& s = phase.stressPa()[t];
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(s[i], sigma, 1e-9 * std::abs(sigma)) << "tet " << t;
    for (int i = 3; i < 6; ++i) EXPECT_NEAR(s[i], 0, 1e-9 * std::abs(sigma));
    EXPECT_LT(phase.vonMisesPa()[t], 1e-8 * std::abs(sigma));
  }
  EXPECT_LT(phase.displacementM().cwiseAbs().maxCoeff(), 1e-15);
}

TEST(Structural, LaterallyConstrainedLayer) {
  const TetMesh mesh = distortedSlab();
  std::vector<Support> s =
      hold(mesh, [](const Vec3& p) { return std::abs(std::abs(p.x()) - kLx / 2) < 1e-12; }, {0});
  for (const Support& y :
       hold(mesh, [](const Vec3& p) { return std::abs(std::abs(p.y()) - kLy / 2) < 1e-12; }, {1}))
    s.push_back(y);
  for (const Support& z : hold(mesh, [](const Vec3& p) { return p.z() < 1e-12; }, {2}))
    s.push_back(z);
  StructuralPhase phase(mesh, paper(), s);
  phase.solve(std::vector<double>(mesh.numTets(), kEv));
  const double lateral = -kE * kEv / (3 * (1 - kNu));  // -527.8 Pa
  for (int t = 0; t < mesh.numTets(); ++t) {
    const VoigtStress& st = phase.stressPa()[t];
    EXPECT_NEAR(st[0], lateral, 1e-9 * std::abs(lateral));
    EXPECT_NEAR(st[1], lateral, 1e-9 * std::abs(lateral));
    EXPECT_NEAR(st[2], 0, 1e-9 * std::abs(lateral));
    EXPECT_NEAR(phase.vonMisesPa()[t], std::abs(lateral), 1e-9 * std::abs(lateral));
  }
  // u_z = e_v z (1 + nu) / (3 (1 - nu)) everywhere, so the top rises by that times H
  const double strainZ = kEv * (1 + kNu) / (3 * (1 - kNu));
  for (int v = 0; v < mesh.numNodes(); ++v)
    EXPECT_NEAR(phase.displacementM()(3 * v + 2), strainZ * mesh.nodes[v].z(), 1e-15);
}

TEST(Structural, FreeExpansionIsStressFree) {
  const TetMesh mesh = distortedSlab();
  // 3-2-1 supports at three corners: no rigid motion, no constraint on the expansion
  int a = -1, b = -1, c = -1;
  for (int v = 0; v < mesh.numNodes(); ++v) {
    const Vec3& p = mesh.nodes[v];
    if (p.z() > 1e-12) continue;
    if (p.x() < -kLx / 2 + 1e-12 && p.y() < -kLy / 2 + 1e-12) a = v;
    if (p.x() > kLx / 2 - 1e-12 && p.y() < -kLy / 2 + 1e-12) b = v;
    if (p.x() < -kLx / 2 + 1e-12 && p.y() > kLy / 2 - 1e-12) c = v;
  }
  ASSERT_TRUE(a >= 0 && b >= 0 && c >= 0);
  StructuralPhase phase(mesh, paper(), {{a, 0}, {a, 1}, {a, 2}, {b, 1}, {b, 2}, {c, 2}});
  phase.solve(std::vector<double>(mesh.numTets(), kEv));
  for (int t = 0; t < mesh.numTets(); ++t) EXPECT_LT(phase.vonMisesPa()[t], 1e-9 * kE * kEv);
  for (int v = 0; v < mesh.numNodes(); ++v) {
    const Vec3 want = (kEv / 3) * (mesh.nodes[v] - mesh.nodes[a]);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(phase.displacementM()(3 * v + k), want(k), 1e-15);
  }
}

TEST(Structural, RemovedTetsCarryNothingAndLinearityHolds) {
  TetMesh mesh = distortedSlab();
  // remove the tets of the top layer and clamp the new top too: the rest is still a
  // clamped body (nodes of removed tets only are held by the phase itself)
  int removed = 0;
  for (int t = 0; t < mesh.numTets(); ++t) {
    double zMin = 1;
    for (int v : mesh.tets[t]) zMin = std::min(zMin, mesh.nodes[v].z());
    if (zMin > 0.6 * kLz) {
      mesh.alive[t] = 0;
      ++removed;
    }
  }
  ASSERT_GT(removed, 0);
  std::vector<Support> clamped = hold(mesh, onBoundary, {0, 1, 2});
  for (int t = 0; t < mesh.numTets(); ++t)
    if (!mesh.alive[t])
      for (int v : mesh.tets[t])
        for (int a = 0; a < 3; ++a) clamped.push_back({v, a});
  StructuralPhase phase(mesh, paper(), clamped);
  std::vector<double> ev(mesh.numTets(), kEv);
  for (int t = 0; t < mesh.numTets(); ++t)
    if (!mesh.alive[t]) ev[t] = 1e3;  // ignored
  phase.solve(ev);
  const double sigma = -kE * kEv / (3 * (1 - 2 * kNu));
  for (int t = 0; t < mesh.numTets(); ++t) {
    if (!mesh.alive[t]) {
      EXPECT_EQ(phase.vonMisesPa()[t], 0.0);
      continue;
    }
    EXPECT_NEAR(phase.stressPa()[t][0], sigma, 1e-9 * std::abs(sigma));
  }
  // a single expanding tet: doubling its eigenstrain doubles every output
  std::vector<double> one(mesh.numTets(), 0.0);
  one[0] = kEv;
  phase.solve(one);
  const Eigen::VectorXd u1 = phase.displacementM();
  const double vm1 = phase.vonMisesPa()[0];
  one[0] = 2 * kEv;
  phase.solve(one);
  EXPECT_GT(vm1, 0);
  EXPECT_NEAR(phase.vonMisesPa()[0], 2 * vm1, 1e-12 * vm1);
  EXPECT_LT((phase.displacementM() - 2 * u1).norm(), 1e-12 * u1.norm());
}

TEST(Structural, ExpansionOfTheTissueWater) {
  EXPECT_NEAR(waterDensityKg_m3(37), 993.1, 1e-9);  // 998.2 + 17/20 (992.2 - 998.2)
  EXPECT_EQ(waterDensityKg_m3(5), 998.2);
  EXPECT_EQ(waterDensityKg_m3(130), 958.4);
  const ExpansionParams p;  // w 0.78, rho 1060, T0 37, Tb 100, ratio 1602
  const double phi = 0.78 * 1060 / 993.1;
  EXPECT_NEAR(volumetricExpansion(p, 37, 0), 0, 1e-15);
  // liquid water expands by 3.62 % from 37 to 100 C (../shared/REFERENCE.md: +3.6 %)
  const double liquid = phi * (993.1 / 958.4 - 1);
  EXPECT_NEAR(volumetricExpansion(p, 100, 0), liquid, 1e-12);
  EXPECT_NEAR(liquid, 0.03014, 1e-5);
  EXPECT_NEAR(volumetricExpansion(p, 180, 0), liquid, 1e-12);  // held at Tb when dry
  // vapour: 1 per mille of the water boiled multiplies its volume fraction by 1.601
  EXPECT_NEAR(volumetricExpansion(p, 100, 1e-3), liquid + phi * 1.601, 1e-12);
  // capped once the vapour would vent
  EXPECT_EQ(volumetricExpansion(p, 100, 0.05), p.maxExpansion);
  ExpansionParams uncapped = p;
  uncapped.maxExpansion = 1e9;
  EXPECT_NEAR(volumetricExpansion(uncapped, 100, 0.05), liquid + phi * 0.05 * 1601, 1e-9);
  // in a laterally constrained layer the von Mises stress E e_v / (3 (1 - nu)) reaches the
  // critical stress 2.45e4 Pa at e_v = 0.93 (../shared/REFERENCE.md: ~0.9), i.e. once 6.7e-4 of the
  // water has boiled
  const double ev = 3 * (1 - kNu) * 2.45e4 / kE;
  EXPECT_NEAR(ev, 0.928, 1e-3);
  EXPECT_NEAR((ev - liquid) / (phi * 1601), 6.74e-4, 0.01e-4);
}

TEST(Structural, FloatingIslandIsHeldInPlace) {
  SlabSpec spec;
  spec.sizeM = {kLx, kLy, kLz};
  spec.nodesPerAxis = {5, 4, 4};
  TetMesh mesh = makeSlab(spec);
  // remove the middle layer of tets: the top layer is cut loose from the clamped bottom
  for (int t = 0; t < mesh.numTets(); ++t) {
    double zc = 0;
    for (int v : mesh.tets[t]) zc += mesh.nodes[v].z() / 4;
    if (zc > kLz / 3 && zc < 2 * kLz / 3) mesh.alive[t] = 0;
  }
  StructuralPhase phase(mesh, paper(),
                        hold(mesh, [](const Vec3& p) { return p.z() < 1e-12; }, {0, 1, 2}));
  EXPECT_EQ(phase.numFloatingIslands(), 1);
  phase.solve(std::vector<double>(mesh.numTets(), kEv));
  for (int v = 0; v < mesh.numNodes(); ++v) {
    if (mesh.nodes[v].z() > kLz / 2) {
      EXPECT_EQ(phase.displacementM().segment<3>(3 * v).norm(), 0.0);
    }
  }
  // the bottom layer is still laterally free and expands: it carries stress
  double maxVm = 0;
  for (int t = 0; t < mesh.numTets(); ++t) maxVm = std::max(maxVm, phase.vonMisesPa()[t]);
  EXPECT_GT(maxVm, 0.0);
}

// two tets sharing one node: the upper one could turn about it (singular K) unless the
// phase recognises it as a separate rigid piece and holds it
TEST(Structural, PieceHangingByANodeIsHeld) {
  TetMesh mesh;
  const double h = 0.01;
  mesh.nodes = {Vec3(0, 0, 0), Vec3(h, 0, 0), Vec3(0, h, 0),    Vec3(0, 0, h),
                Vec3(h, 0, h), Vec3(0, h, h), Vec3(0, 0, 2 * h)};
  mesh.tets = {{0, 1, 2, 3}, {3, 4, 5, 6}};
  mesh.alive = {1, 1};
  std::vector<Support> s;
  for (int v = 0; v < 3; ++v)
    for (int a = 0; a < 3; ++a) s.push_back({v, a});
  StructuralPhase phase(mesh, paper(), s);
  EXPECT_EQ(phase.numFloatingIslands(), 1);
  EXPECT_EQ(phase.numFreeDofs(), 0);  // node 3 is held with the hanging piece
  phase.solve({kEv, kEv});
  EXPECT_EQ(phase.displacementM().norm(), 0.0);
  // fully held: the hydrostatic stress of a clamped body
  EXPECT_NEAR(phase.stressPa()[0][0], -kE * kEv / (3 * (1 - 2 * kNu)), 1e-9);
}

TEST(Structural, RejectsBadInput) {
  const TetMesh mesh = distortedSlab();
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::vector<Support> clamped = hold(mesh, onBoundary, {0, 1, 2});
  StructuralOptions o = paper();
  o.poissonRatio = 0.5;
  EXPECT_NE(message([&] { StructuralPhase p(mesh, o, clamped); }).find("poissonRatio"),
            std::string::npos);
  // held only in z on the bottom: free to slide in x, y and to spin about z
  const std::vector<Support> slides = hold(mesh, [](const Vec3& p) { return p.z() < 1e-12; }, {2});
  EXPECT_NE(message([&] { StructuralPhase p(mesh, paper(), slides); }).find("free to translate"),
            std::string::npos);
  EXPECT_NE(message([&] {
              StructuralPhase p(mesh, paper(), {{mesh.numNodes(), 0}});
            }).find("out of range"),
            std::string::npos);
  StructuralPhase p(mesh, paper(), clamped);
  EXPECT_NE(message([&] { p.solve({1.0}); }).find("eigenstrains for"), std::string::npos);
  std::vector<double> nan(mesh.numTets(), 0.0);
  nan[3] = std::nan("");
  EXPECT_NE(message([&] { p.solve(nan); }).find("not finite"), std::string::npos);
}

}  // namespace
}  // namespace esim
