// Tests for sim/electric_phase.cpp with the electric solvers: the patch test
// (linear potential between plates, exact), the disc electrode on a half-space
// (R = 1/(4 sigma a), convergence under refinement), current conservation and
// power balance, removed elements and bad input.
#include "sim/electric_phase.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <limits>
#include <random>

#include "sim/core_error.h"
#include "sim/electric_solver.h"
#include "sim/electrode.h"
#include "sim/mesh_slab.h"
#include "tools/app/analytic_disc.h"

namespace esim {
namespace {

constexpr double kSigma = 0.144;

// slab [-L/2, L/2]^2 x [0, H] with every node jittered inside its face/edge/volume
// so the mesh is unstructured but the boundary stays planar
TetMesh perturbedSlab(double L, double H, std::array<int, 3> n, unsigned seed) {
  SlabSpec s;
  s.sizeM = Vec3(L, L, H);
  s.nodesPerAxis = n;
  TetMesh m = makeSlab(s);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  const Vec3 h(L / (n[0] - 1), L / (n[1] - 1), H / (n[2] - 1));
  const double eps = 1e-9;
  for (auto& p : m.nodes) {
    const bool onX = std::abs(std::abs(p.x()) - L / 2) < eps;
    const bool onY = std::abs(std::abs(p.y()) - L / 2) < eps;
    const bool onZ = p.z() < eps || p.z() > H - eps;
    if (!onX) p.x() += u(rng) * h.x();
    if (!onY) p.y() += u(rng) * h.y();
    if (!onZ) p.z() += u(rng) * h.z();
  }
  validateMesh(m, "perturbedSlab");
  return m;
}

TEST(ElectricPhase, PatchTestLinearPotentialBetweenPlatesIsExactForEveryStrategy) {
  const double L = 0.02, H = 0.01, V0 = 72.0;
  const TetMesh m = perturbedSlab(L, H, {7, 7, 5}, 11);
  const auto geo = tetGeometry(m);
  const std::vector<double> sigma(m.numTets(), kSigma);
  const SparseMatrix K = assembleElectricStiffness(m, geo, sigma);
  const auto& top = m.nodeSets.at("top");
  const auto& bottom = m.nodeSets.at("bottom");
  for (ElectricStrategy s : {ElectricStrategy::Refactor, ElectricStrategy::DenseInverse,
                             ElectricStrategy::Capacitance, ElectricStrategy::Pcg}) {
    auto solver = makeElectricSolver({.strategy = s, .pcgTolerance = 1e-14});
    solver->setMatrix(K, bottom);
    Eigen::VectorXd u;
    solver->solve(top, V0, u);
    double maxErr = 0;
    for (int i = 0; i < m.numNodes(); ++i)
      maxErr = std::max(maxErr, std::abs(u[i] - V0 * m.nodes[i].z() / H));
    EXPECT_LT(maxErr, 1e-10) << electricStrategyName(s);
    const ElectricFields f = computeElectricFields(m, geo, sigma, K, u, top, bottom, V0);
    const double area = L * L, power = kSigma * area * V0 * V0 / H;
    EXPECT_NEAR(f.powerW, power, 1e-10 * power);
    EXPECT_NEAR(f.toolCurrentA * V0, power, 1e-9 * power);
    EXPECT_NEAR(f.returnCurrentA, f.toolCurrentA, 1e-9 * f.toolCurrentA);
    EXPECT_NEAR(f.impedanceOhm, H / (kSigma * area), 1e-9 * H / (kSigma * area));
    for (int e = 0; e < m.numTets(); ++e) {
      EXPECT_NEAR(f.fieldV_m[e].z(), -V0 / H, 1e-8 * V0 / H);
      EXPECT_NEAR(f.currentDensityA_m2[e].z(), -kSigma * V0 / H, 1e-8 * kSigma * V0 / H);
      EXPECT_NEAR(f.joulePowerW_m3[e], kSigma * V0 * V0 / (H * H),
                  1e-8 * kSigma * V0 * V0 / (H * H));
    }
  }
}

// the disc electrode on the half-space at h = a / m (tools/app/analytic_disc.h: the same
// case `esim bench accuracy` reports); the current it draws leaves through the far faces
double discResistance(int m, double a) {
  const app::DiscResult r = app::discResistance(m, a, kSigma);
  EXPECT_NEAR(r.toolCurrentA, r.returnCurrentA, 1e-9 * r.toolCurrentA);
  return r.resistanceOhm;
}

TEST(ElectricPhase, DiscElectrodeResistanceConvergesToOneOverFourSigmaA) {
  const double a = 0.002;
  const double exact = 1 / (4 * kSigma * a);
  const int levels[] = {2, 3, 4, 6, 8};
  std::vector<double> err;
  for (int m : levels) {
    const double r = discResistance(m, a);
    err.push_back(std::abs(r - exact) / exact);
    std::cout << "disc electrode h = a/" << m << ": R = " << r << " ohm (exact " << exact
              << "), relative error " << err.back();
    if (err.size() > 1) {
      const size_t k = err.size() - 1;
      const double rate =
          std::log(err[k - 1] / err[k]) / std::log(static_cast<double>(levels[k]) / levels[k - 1]);
      std::cout << ", observed rate " << rate;
    }
    std::cout << "\n";
  }
  // monotone decrease at the expected first order: the potential's r^-1/2 edge
  // singularity limits P1 to O(h) in the current
  for (size_t k = 1; k < err.size(); ++k) EXPECT_LT(err[k], err[k - 1]);
  const size_t k = err.size() - 1;
  const double rate = std::log(err[k - 1] / err[k]) / std::log(8.0 / 6.0);
  EXPECT_GT(rate, 0.8);
  EXPECT_LT(rate, 1.3);
  EXPECT_LT(err.back(), 0.06);
}

TEST(ElectricPhase, BladeOnPaperSlabConservesCurrentAndBalancesPower) {
  SlabSpec s;
  s.targetNodes = 5000;
  const TetMesh m = makeSlab(s);
  const auto geo = tetGeometry(m);
  const std::vector<double> sigma(m.numTets(), kSigma);
  const SparseMatrix K = assembleElectricStiffness(m, geo, sigma);
  const auto surface = boundaryNodes(m, boundaryFaces(m));
  const auto grounded = returnElectrodeNodes(m, surface, ReturnElectrode{});
  const ElectrodeShape blade;  // 3 mm x 20 mm, 0.5 mm thick
  const ToolPose pose{Vec3(0.01, 0.0, 0.0095), Eigen::Quaterniond::Identity()};
  const auto contact = findContacts(m, surface, blade, pose, 0.002);
  ASSERT_GE(contact.size(), 2u);
  auto solver = makeElectricSolver({});
  solver->setMatrix(K, grounded);
  Eigen::VectorXd u;
  solver->solve(contact, 72.0, u);
  const ElectricFields f = computeElectricFields(m, geo, sigma, K, u, contact, grounded, 72.0);
  EXPECT_GT(f.toolCurrentA, 0);
  EXPECT_NEAR(f.returnCurrentA, f.toolCurrentA, 1e-9 * f.toolCurrentA);
  EXPECT_NEAR(f.powerW, 72.0 * f.toolCurrentA, 1e-9 * f.powerW);
  EXPECT_NEAR(f.impedanceOhm, 72.0 / f.toolCurrentA, 1e-12 * f.impedanceOhm);
  // the maximum principle: 0 <= V <= 72
  EXPECT_GE(u.minCoeff(), -1e-9);
  EXPECT_LE(u.maxCoeff(), 72.0 + 1e-9);
}

TEST(ElectricPhase, RemovedTetsCarryNothingAndNoContactMeansNoCurrent) {
  const TetMesh base = perturbedSlab(0.02, 0.01, {6, 6, 4}, 5);
  TetMesh m = base;
  for (int e = 0; e < m.numTets(); e += 7) m.alive[e] = 0;
  const auto geo = tetGeometry(m);
  std::vector<double> sigma(m.numTets(), kSigma);
  sigma[7] = std::numeric_limits<double>::quiet_NaN();  // removed: ignored
  const SparseMatrix K = assembleElectricStiffness(m, geo, sigma);
  const auto& top = m.nodeSets.at("top");
  const auto& bottom = m.nodeSets.at("bottom");
  auto solver = makeElectricSolver({});
  solver->setMatrix(K, bottom);
  Eigen::VectorXd u;
  solver->solve(top, 10.0, u);
  const ElectricFields f = computeElectricFields(m, geo, sigma, K, u, top, bottom, 10.0);
  for (int e = 0; e < m.numTets(); e += 7) {
    EXPECT_EQ(f.joulePowerW_m3[e], 0.0);
    EXPECT_EQ(f.fieldV_m[e].norm(), 0.0);
  }
  EXPECT_NEAR(f.returnCurrentA, f.toolCurrentA, 1e-9 * f.toolCurrentA);
  EXPECT_NEAR(f.powerW, 10.0 * f.toolCurrentA, 1e-9 * f.powerW);
  // no contact: zero potential, zero current, infinite impedance, no NaN
  solver->solve({}, 10.0, u);
  const ElectricFields off = computeElectricFields(m, geo, sigma, K, u, {}, bottom, 10.0);
  EXPECT_EQ(off.powerW, 0.0);
  EXPECT_EQ(off.toolCurrentA, 0.0);
  EXPECT_TRUE(std::isinf(off.impedanceOhm));
}

TEST(ElectricPhase, BadConductivityIsAnErrorNamingTheTet) {
  const TetMesh m = perturbedSlab(0.02, 0.01, {4, 4, 3}, 1);
  const auto geo = tetGeometry(m);
  for (double bad : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                     std::numeric_limits<double>::infinity()}) {
    std::vector<double> sigma(m.numTets(), kSigma);
    sigma[3] = bad;
    try {
      assembleElectricStiffness(m, geo, sigma);
      FAIL() << "no throw for " << bad;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("tet 3"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(assembleElectricStiffness(m, geo, std::vector<double>(2, kSigma)), Error);
}

}  // namespace
}  // namespace esim
