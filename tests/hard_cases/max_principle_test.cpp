// Hard cases (issue #12): the maximum principle of the allowed thermal configurations that do
// not keep it; found by this suite (tests/hard_cases/README.md, "Bugs found"), now warned.
//
// The thermal maximum principle fails in two families of allowed configurations (the lumped
// mass with explicit, backward Euler and Crank-Nicolson at 1e-6 .. 10 s holds it:
// time_step_test.cpp):
//  1. consistent mass (solvers.thermal.mass: consistent), every integrator, every frame step
//     from 1e-6 s to 10 s: a 90 C ball in 37 C insulated tissue, no source, leaves [37, 90] in
//     its first frame, e.g. 36.99 / 90.005 C at 1 ms, 36.89 / 90.15 C at 1/30 s, 33.7 / 94.6 C
//     (explicit, 1 s), 35.0 C (Crank-Nicolson, 10 s); heated with the top face cooled to 37 C
//     it drops below 37 C (33.6 C explicit at 10 s). The consistent P1 mass is not an
//     M-matrix: (c rho M / dt + theta K) has positive off-diagonal entries, and M^-1 (explicit)
//     has negative ones.
//  2. Crank-Nicolson with lumped mass at steps far above the diffusion time of an element:
//     lambda = 10 W/(m K) at 10 s (or 100 W/(m K) at 1 s): 7.85 C; lambda = 100 W/(m K) at
//     10 s: -10.9 C from a 37 .. 90 C field (both values inside the schema: lambda <= 100,
//     fps >= 0.1). Crank-Nicolson is A-stable, not L-stable: its amplification -> -1 for the
//     stiff modes, which then oscillate.
// Expected (a design decision for whoever fixes it): either the scheme keeps the bounds (mass
// lumping for the consistent mode's time derivative; Crank-Nicolson limited to steps where
// (1 - theta) dt K_ii <= c rho m_i, i.e. sub-stepped or switched to backward Euler above it,
// the way the explicit bound is enforced), or the configuration is refused up front / warned
// about in Simulation::warnings(), never a silent 48 K undershoot.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <tuple>

#include "hard_case.h"

namespace esim {
namespace {

using hard::FrameChecker;
using hard::Invariants;
using hard::MaxPrinciple;

// a 90 C ball (4 mm) at the top centre of 37 C tissue, insulated, no source
SimulationConfig hotSpot(double dt, ThermalIntegrator integrator, bool lumped, double lambda) {
  SimulationConfig c;
  c.phases.thermal = true;
  c.frameDtS = dt;
  c.thermal.integrator = integrator;
  c.thermal.lumpedMass = lumped;
  c.thermal.conductivityW_mK = lambda;
  c.hotSpot.enabled = true;
  c.hotSpot.centerM = Vec3(0, 0, 0.01);
  c.hotSpot.radiusM = 0.004;
  c.hotSpot.temperatureC = 90;
  return c;
}

bool warnsMaxPrinciple(const Simulation& sim) {
  for (const std::string& w : sim.warnings())
    if (w.find("maximum principle") != std::string::npos &&
        w.find("backward-euler") != std::string::npos)
      return true;
  return false;
}

// The consistent mass is not an M-matrix and Crank-Nicolson is not L-stable: both can leave
// the bounds of the maximum principle (the consistent mass at every step, by 0.01 K at 1 ms to
// ~5 K at 1 s; Crank-Nicolson with lumped mass at steps far above an element's diffusion
// time, by up to ~50 K). Allowed configurations, so the run goes on (every other invariant
// holds) and the departure is never silent: whenever the field leaves its bounds by more
// than the core's 1e-3 K margin, Simulation::warnings() names it with its remedy, and when it
// stays inside there is no such warning.
// returns how far the field left its bounds [K]
double expectBoundsOrWarning(Simulation& sim, MaxPrinciple bounds, double lowC, double highC) {
  Invariants inv;
  inv.maxPrinciple = MaxPrinciple::None;  // checked here, against the warning
  FrameChecker check(sim, inv);
  hard::runChecked(check, 4);
  double out = std::max(0.0, lowC - check.minSeenC());
  if (bounds == MaxPrinciple::Both) out = std::max(out, check.maxSeenC() - highC);
  std::printf("[%.12g, %.12g] C, out of bounds by %.3g K\n", check.minSeenC(), check.maxSeenC(),
              out);
  if (out > 1e-3 + 1e-9)
    EXPECT_TRUE(warnsMaxPrinciple(sim)) << "left its bounds by " << out << " K without a warning";
  else
    EXPECT_FALSE(warnsMaxPrinciple(sim)) << "a warning, but within bounds (" << out << " K)";
  return out;
}

using Combo = std::tuple<double, ThermalIntegrator>;

class HardMaxPrinciple : public ::testing::TestWithParam<Combo> {};

TEST_P(HardMaxPrinciple, ConsistentMassHotSpotLeavesItsBoundsOnlyWithAWarning) {
  const auto [dt, integrator] = GetParam();
  Simulation sim(makeSlab(hard::quarterSlabSpec()), hotSpot(dt, integrator, false, 0.502));
  expectBoundsOrWarning(sim, MaxPrinciple::Both, 37.0, 90.0);
}

TEST_P(HardMaxPrinciple, ConsistentMassHeatedAndCooledUndershootIsWarned) {
  const auto [dt, integrator] = GetParam();
  SimulationConfig c = hotSpot(dt, integrator, false, 0.502);
  c.hotSpot.enabled = false;
  c.phases.boiling = true;
  c.heatSource.enabled = true;
  c.heatSource.centerM = Vec3(0, 0, 0.01);
  c.heatSource.radiusM = 0.003;
  c.heatSource.powerDensityW_m3 = 1e8;
  c.coolTopSurface = true;
  c.thermal.convectionW_m2K = 1e3;
  c.thermal.ambientTemperatureC = 37;
  Simulation sim(makeSlab(hard::quarterSlabSpec()), c);
  expectBoundsOrWarning(sim, MaxPrinciple::Lower, 37.0, 0.0);
}

INSTANTIATE_TEST_SUITE_P(Consistent, HardMaxPrinciple,
                         ::testing::Combine(::testing::Values(1e-6, 1e-3, 1.0 / 30.0, 1.0, 10.0),
                                            ::testing::Values(ThermalIntegrator::Explicit,
                                                              ThermalIntegrator::BackwardEuler,
                                                              ThermalIntegrator::CrankNicolson,
                                                              ThermalIntegrator::TrBdf2)));

TEST(HardMaxPrincipleCn, CrankNicolsonLumpedOnConductiveTissueAtLongStepsIsWarned) {
  for (const auto& [lambda, dt] : {std::pair{10.0, 10.0}, {100.0, 1.0}, {100.0, 10.0}}) {
    SCOPED_TRACE("lambda " + std::to_string(lambda) + " W/(m K), dt " + std::to_string(dt) + " s");
    Simulation sim(makeSlab(hard::quarterSlabSpec()),
                   hotSpot(dt, ThermalIntegrator::CrankNicolson, true, lambda));
    expectBoundsOrWarning(sim, MaxPrinciple::Both, 37.0, 90.0);
  }
}

// tr-bdf2 is L-stable: the stiff modes that crank-nicolson carries with R -> -1 it damps
// (|R| <= 0.21 over z > 0, ThermalStep.EachImplicitIntegrator...). Its first stage is
// crank-nicolson's, so it is not monotone either: on the same fields it may still leave the
// bounds (warned, as crank-nicolson), by under a third of crank-nicolson's excursion
TEST(HardMaxPrincipleCn, TrBdf2LumpedLeavesTheBoundsByAFractionOfCrankNicolsons) {
  for (const auto& [lambda, dt] : {std::pair{10.0, 10.0}, {100.0, 1.0}, {100.0, 10.0}}) {
    SCOPED_TRACE("lambda " + std::to_string(lambda) + " W/(m K), dt " + std::to_string(dt) + " s");
    Simulation cn(makeSlab(hard::quarterSlabSpec()),
                  hotSpot(dt, ThermalIntegrator::CrankNicolson, true, lambda));
    const double outCn = expectBoundsOrWarning(cn, MaxPrinciple::Both, 37.0, 90.0);
    Simulation tr(makeSlab(hard::quarterSlabSpec()),
                  hotSpot(dt, ThermalIntegrator::TrBdf2, true, lambda));
    const double outTr = expectBoundsOrWarning(tr, MaxPrinciple::Both, 37.0, 90.0);
    std::printf("crank-nicolson %.3g K out, tr-bdf2 %.3g K out\n", outCn, outTr);
    EXPECT_GT(outCn, 1.0);
    EXPECT_LT(outTr, outCn / 3);
  }
}

TEST(HardMaxPrincipleCn, BackwardEulerLumpedKeepsTheBoundsWithoutAWarning) {
  for (const auto& [lambda, dt] : {std::pair{10.0, 10.0}, {100.0, 1.0}, {100.0, 10.0}}) {
    SCOPED_TRACE("lambda " + std::to_string(lambda) + " W/(m K), dt " + std::to_string(dt) + " s");
    Simulation sim(makeSlab(hard::quarterSlabSpec()),
                   hotSpot(dt, ThermalIntegrator::BackwardEuler, true, lambda));
    Invariants inv;
    inv.maxPrinciple = MaxPrinciple::Both;
    FrameChecker check(sim, inv);
    hard::runChecked(check, 4);
    EXPECT_FALSE(warnsMaxPrinciple(sim));
  }
}

}  // namespace
}  // namespace esim
