// hard_case.h - the per-frame invariants every hard case asserts (issue #12), and the small
// scenes they share. Header-only: each hard-case test file is its own binary.
//
// FrameChecker::step() advances the simulation by one frame and asserts:
//   finite      every field the frame produced (potential, Joule power, sigma, temperature,
//               enthalpy, von Mises) and the record's numbers;
//   electric    the discrete equation holds: the residual (K u)_i at the solved nodes (not
//               tool, not ground) is below residualRelTol ||b||, b = -K_oc V the load of the
//               tool's nodes; the tool current equals the return current, to currentRelTol
//               of the tool current and never by more than sum |r_o| allows; power = V I;
//               optionally 0 <= u <= V (the maximum principle of the Laplace equation);
//   thermal     stored heat - initial stored heat = delivered - convected - removed, where
//               "removed" is the heat of tissue that rupture took away (tracked from the
//               model's stored energy before and after each rebuild) and the vapour the
//               sub-grid contact zone vented, to energyRelTol of the largest energy involved;
//               stored heat is the mesh's plus the sub-grid contact model's (its zone and the
//               vapour it trapped in alive tets; sim/subgrid_contact.h); the source integral,
//               less the sub-grid model's nodal heat and plus its own input, is the delivered
//               energy;
//               optionally the maximum principle (both sides, or only the lower bound).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <ostream>
#include <string>
#include <vector>

#include "sim/core_error.h"
#include "sim/mesh_slab.h"
#include "sim/simulation.h"

namespace esim::hard {

enum class MaxPrinciple {
  None,   // a sink and a source, or removal: no bound
  Lower,  // a positive source and no sink: T never below the initial minimum
  Both    // no source and no sink: T within the initial [min, max]
};

struct Invariants {
  double residualRelTol = 1e-8;  // electric: ||r_o|| <= tol ||b||
  double currentRelTol = 1e-9;   // |I_tool - I_return| <= tol |I_tool|
  bool currentRelCheck = true;   // false for an iterative solve at a loose tolerance
  bool potentialBounds = false;  // 0 <= u <= V (Laplace maximum principle)
  double energyRelTol = 1e-9;    // thermal balance, relative to the largest energy
  MaxPrinciple maxPrinciple = MaxPrinciple::None;
  double maxPrincipleTolK = 1e-9;
};

// the invariants of one run, checked frame by frame (gtest failures name the frame)
class FrameChecker {
 public:
  FrameChecker(Simulation& sim, Invariants inv) : sim_(sim), inv_(inv) {
    // the local potential is not the discrete solution: the residual at its region's edge
    // and the currents' imbalance are its approximation's (measured in the README, "The
    // potential solved around the tool, built"), not checked; the rest is (the power's
    // identity against the residual it has, the bounds, finiteness, the heat balance)
    if (sim.config().electricSolver.strategy == ElectricStrategy::Local) {
      inv_.residualRelTol = std::numeric_limits<double>::infinity();
      inv_.currentRelCheck = false;
    }
    if (const ThermalState* t = sim.thermalState()) {
      minC_ = t->temperatureC.minCoeff();
      maxC_ = t->temperatureC.maxCoeff();
      stored0J_ = sim.model().thermal->storedEnergyJ(*t) + sim.subgridStoredEnergyJ();
    }
  }

  // one frame of the simulation, checked (its exceptions propagate)
  const FrameRecord& step() {
    // a rupture frame swaps in the new model after its physics: keep what its solve used
    if (sim_.hasElectric() && sim_.config().phases.rupture) {
      aliveBefore_ = sim_.mesh().alive;
      groundBefore_ = sim_.model().ground;
    }
    const FrameRecord& r = sim_.step();
    check(r);
    return r;
  }

  // false once some check (or anything else) of the test has failed
  static bool ok() { return !::testing::Test::HasFailure(); }

  int frames() const { return frames_; }         // frames checked
  double removedJ() const { return removedJ_; }  // heat removed with tets [J]
  double minSeenC() const { return minSeenC_; }  // over the alive tets' nodes
  double maxSeenC() const { return maxSeenC_; }
  double worstResidualRel() const { return worstResidual_; }  // electric, relative
  double worstEnergyRel() const { return worstEnergy_; }      // thermal balance, relative

 private:
  void check(const FrameRecord& r) {
    const std::string at = "frame " + std::to_string(r.frame);
    EXPECT_TRUE(std::isfinite(r.toolCurrentA) && std::isfinite(r.returnCurrentA) &&
                std::isfinite(r.powerW) && std::isfinite(r.maxTemperatureC) &&
                std::isfinite(r.maxVonMisesPa))
        << at;
    expectFinite(sim_.potentialV(), "potential", at);
    expectFinite(sim_.joulePowerW_m3(), "Joule power", at);
    expectFinite(sim_.conductivityS_m(), "conductivity", at);
    if (const auto* vm = sim_.vonMisesPa()) expectFinite(*vm, "von Mises", at);
    if (sim_.hasElectric()) checkElectric(r, at);
    if (sim_.thermalState()) checkThermal(r, at);
    ++frames_;
  }

  template <class V>
  static void expectFinite(const V& v, const char* what, const std::string& at) {
    for (size_t i = 0; i < static_cast<size_t>(v.size()); ++i)
      if (!std::isfinite(v[i])) {
        ADD_FAILURE() << at << ": " << what << " [" << i << "] = " << v[i];
        return;
      }
  }

  void checkElectric(const FrameRecord& r, const std::string& at) {
    // the frame's solve used the model before the swap: the alive set before the frame and the
    // conductivity the new model took over (sigma(T) refreshes it before the solve)
    const bool swapped = r.removedTets > 0;
    SparseMatrix solved;
    if (swapped) {
      TetMesh before = sim_.mesh();
      before.alive = aliveBefore_;
      solved = assembleStiffness(before, *sim_.model().geo, sim_.model().sigmaAssembled);
    }
    const SparseMatrix& stiffness = swapped ? solved : sim_.model().stiffness;
    const std::vector<int>& ground = swapped ? groundBefore_ : sim_.model().ground;
    const std::vector<int>& contact = sim_.contactNodes();
    const Eigen::VectorXd& u = sim_.potentialV();
    const double v = sim_.config().toolVoltageV;
    if (contact.empty() || !r.generatorOn) {
      EXPECT_EQ(r.toolCurrentA, 0.0) << at;
      EXPECT_EQ(r.powerW, 0.0) << at;
      return;
    }
    const int n = static_cast<int>(u.size());
    std::vector<std::uint8_t> fixed(n, 0);
    for (int c : contact) fixed[c] = 1;
    for (int g : ground) fixed[g] = 2;
    Eigen::VectorXd uc = Eigen::VectorXd::Zero(n);
    for (int c : contact) uc[c] = v;
    const Eigen::VectorXd ku = stiffness * u, kc = stiffness * uc;
    double r2 = 0, b2 = 0, rSum = 0;
    for (int i = 0; i < n; ++i) {
      if (fixed[i]) continue;
      r2 += ku[i] * ku[i];
      b2 += kc[i] * kc[i];
      rSum += std::abs(ku[i]);
    }
    const double rel = b2 > 0 ? std::sqrt(r2 / b2) : std::sqrt(r2);
    worstResidual_ = std::max(worstResidual_, rel);
    EXPECT_LE(rel, inv_.residualRelTol) << at << ": electric residual above its tolerance";
    // sum_i (K u)_i = 0 (constants are in the kernel of K): the imbalance is the residual
    const double imbalance = std::abs(r.toolCurrentA - r.returnCurrentA);
    EXPECT_LE(imbalance, rSum * (1 + 1e-9) + 1e-12 * std::abs(r.toolCurrentA)) << at;
    if (inv_.currentRelCheck) {
      EXPECT_LE(imbalance, inv_.currentRelTol * std::abs(r.toolCurrentA))
          << at << ": tool " << r.toolCurrentA << " A, return " << r.returnCurrentA << " A";
    }
    // u^T K u = V I_tool + sum_o u_o r_o
    EXPECT_NEAR(r.powerW, v * r.toolCurrentA,
                u.cwiseAbs().maxCoeff() * rSum * (1 + 1e-9) + 1e-9 * std::abs(r.powerW) + 1e-15)
        << at;
    if (inv_.potentialBounds) {
      const double lo = std::min(0.0, v), hi = std::max(0.0, v), tol = 1e-9 * std::abs(v);
      EXPECT_GE(u.minCoeff(), lo - tol) << at << ": potential below the return electrode's";
      EXPECT_LE(u.maxCoeff(), hi + tol) << at << ": potential above the tool's";
    }
  }

  void checkThermal(const FrameRecord& r, const std::string& at) {
    const ThermalState& t = *sim_.thermalState();
    expectFinite(t.temperatureC, "temperature", at);
    expectFinite(t.enthalpyJ_m3, "enthalpy", at);
    const SubgridEnergy& sg = sim_.subgridEnergy();
    const double stored = sim_.model().thermal->storedEnergyJ(t) + sim_.subgridStoredEnergyJ();
    const double before = t.sensibleJ + t.latentJ + sg.storedJ;  // after the heat stage
    if (r.removedTets > 0) {
      removedJ_ += before - stored;  // left with the removed tets
    } else {
      EXPECT_NEAR(before, stored, 1e-9 * std::max(1e-12, std::abs(stored))) << at;
    }
    const double delivered = t.sourceJ - sg.toMeshJ + sg.inputJ;
    const double expected = stored0J_ + delivered - t.convectedJ - removedJ_ - sg.ventedJ;
    const double scale =
        std::max({1e-12, std::abs(stored0J_), std::abs(stored), t.sourceJ, std::abs(t.convectedJ),
                  std::abs(removedJ_), sg.inputJ, std::abs(sg.toMeshJ)});
    worstEnergy_ = std::max(worstEnergy_, std::abs(stored - expected) / scale);
    EXPECT_NEAR(stored, expected, inv_.energyRelTol * scale)
        << at << ": stored " << stored << " J, delivered " << delivered << " J, convected "
        << t.convectedJ << " J, removed " << removedJ_ << " J, vented " << sg.ventedJ
        << " J, initial " << stored0J_ << " J";
    EXPECT_NEAR(delivered, sim_.energyDeliveredJ(), 1e-10 * std::max(1e-12, t.sourceJ)) << at;
    // the maximum principle over the nodes that still belong to the tissue
    const TetMesh& mesh = sim_.mesh();
    double lo = INFINITY, hi = -INFINITY;
    for (int e = 0; e < mesh.numTets(); ++e) {
      if (!mesh.isAlive(e)) continue;
      for (int v : mesh.tets[e]) {
        lo = std::min(lo, t.temperatureC[v]);
        hi = std::max(hi, t.temperatureC[v]);
      }
    }
    minSeenC_ = std::min(minSeenC_, lo);
    maxSeenC_ = std::max(maxSeenC_, hi);
    if (inv_.maxPrinciple != MaxPrinciple::None) {
      EXPECT_GE(lo, minC_ - inv_.maxPrincipleTolK)
          << at << ": temperature undershoots the initial minimum " << minC_ << " C";
    }
    if (inv_.maxPrinciple == MaxPrinciple::Both) {
      EXPECT_LE(hi, maxC_ + inv_.maxPrincipleTolK)
          << at << ": temperature overshoots the initial maximum " << maxC_ << " C";
    }
  }

  Simulation& sim_;
  Invariants inv_;
  std::vector<std::uint8_t> aliveBefore_;  // rupture: the alive set of the frame's solve
  std::vector<int> groundBefore_;
  double minC_ = 0, maxC_ = 0, stored0J_ = 0, removedJ_ = 0;
  double minSeenC_ = INFINITY, maxSeenC_ = -INFINITY;
  double worstResidual_ = 0, worstEnergy_ = 0;
  int frames_ = 0;
};

// runs `frames` checked frames; stops once a check has failed
inline void runChecked(FrameChecker& check, int frames) {
  for (int f = 0; f < frames && check.ok(); ++f) check.step();
}

// ---- scenes ----

// 60 x 60 x 10 mm, 2.5 mm grid (3125 nodes): simulation_test's smallSlab()
inline SlabSpec smallSlabSpec() {
  SlabSpec s;
  s.sizeM = Vec3(0.06, 0.06, 0.01);
  s.nodesPerAxis = {25, 25, 5};
  return s;
}

// 30 x 30 x 10 mm, 2.5 mm grid (845 nodes)
inline SlabSpec quarterSlabSpec() {
  SlabSpec s;
  s.sizeM = Vec3(0.03, 0.03, 0.01);
  s.nodesPerAxis = {13, 13, 5};
  return s;
}

// a tool held at `tip` (generator always on), return pad under the slab
inline SimulationConfig toolAt(ElectrodeKind kind, const Vec3& tip, bool thermal) {
  SimulationConfig c;
  c.phases.electric = true;
  c.phases.thermal = thermal;
  c.electrode.kind = kind;
  c.returnElectrode.radiusM = 0.025;
  ToolKeyframe k;
  k.positionM = tip;
  c.toolPath.keys = {k};
  c.toolPath.generatorOnS = {{0.0, 1e9}};
  c.thermal.integrator = ThermalIntegrator::BackwardEuler;
  return c;
}

// keyframes a -> b over [t0, t1]
inline void moveTool(SimulationConfig& c, const Vec3& a, double t0, const Vec3& b, double t1) {
  ToolKeyframe ka, kb;
  ka.timeS = t0;
  ka.positionM = a;
  kb.timeS = t1;
  kb.positionM = b;
  c.toolPath.keys = {ka, kb};
}

// the message of the esim::Error `f` throws (fails the test if it throws nothing)
template <class F>
std::pair<ErrorKind, std::string> errorOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return {e.kind(), e.what()};
  }
  ADD_FAILURE() << "no esim::Error was thrown";
  return {ErrorKind::Internal, ""};
}

inline bool contains(const std::string& s, const std::string& what) {
  return s.find(what) != std::string::npos;
}

// the ways the model follows a removal, which every removal case runs in: rebuilt
// (synchronous), edited in place (update), edited in place with the structural phase's
// coarse method (update_coarse: K_c and the region updated, the whole factor's update
// deferred), and edited in place with the potential by local or by pcg (their updates in
// place: the inner solvers' and pcg's own, FreeBase)
struct RemovalWay {
  RebuildMode mode;
  StructuralSolveMethod structural;
  ElectricStrategy electric = ElectricStrategy::Auto;  // Auto: the case's own strategy
};
inline void applyWay(const RemovalWay& w, SimulationConfig& c) {
  c.rebuildMode = w.mode;
  c.structural.solveMethod = w.structural;
  if (w.electric != ElectricStrategy::Auto) c.electricSolver.strategy = w.electric;
}
inline auto removalWays() {
  return ::testing::Values(
      RemovalWay{RebuildMode::Synchronous, StructuralSolveMethod::full},
      RemovalWay{RebuildMode::Update, StructuralSolveMethod::full},
      RemovalWay{RebuildMode::Update, StructuralSolveMethod::coarse},
      RemovalWay{RebuildMode::Update, StructuralSolveMethod::full, ElectricStrategy::Local},
      RemovalWay{RebuildMode::Update, StructuralSolveMethod::full, ElectricStrategy::Pcg});
}
// gtest prints the parameter by this (not as raw bytes, which showed the struct's padding)
inline void PrintTo(const RemovalWay& w, std::ostream* os) {
  *os << rebuildModeName(w.mode)
      << (w.structural == StructuralSolveMethod::coarse ? ", coarse structural" : "");
  if (w.electric != ElectricStrategy::Auto)
    *os << ", " << electricStrategyName(w.electric) << " potential";
}
inline std::string removalWayName(const ::testing::TestParamInfo<RemovalWay>& info) {
  return std::string(rebuildModeName(info.param.mode)) +
         (info.param.structural == StructuralSolveMethod::coarse ? "_coarse" : "") +
         (info.param.electric != ElectricStrategy::Auto
              ? std::string("_") + electricStrategyName(info.param.electric) + "_potential"
              : "");
}

}  // namespace esim::hard
