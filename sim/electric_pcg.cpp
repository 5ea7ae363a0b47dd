// electric_pcg.cpp - preconditioned conjugate gradients: the accuracy/time dial.
//
// Solves the same reduced system as `refactor` (K_ff with the contact rows and
// columns replaced by the identity, b_o = -K_oc u_c, b_c = 0; SPD) with Eigen's
// conjugate gradients, warm-started from the input potential (the previous frame),
// until ||b - A x|| <= pcgTolerance ||b|| or pcgMaxIterations. Preconditioners:
// - two-level (default): l1-Jacobi and a coarse level on aggregates of nodes
//   (sim/two_level_preconditioner.h). Its iterations barely grow with the mesh where
//   Jacobi's grow as 1/h: on slab_cut (8000 nodes) 55 against 180 a frame, on
//   liver_incision (27908) 37 against 268; solve_potential 7.6 against 11.2 ms and 33
//   against 110 ms (README, "The potential's two-level preconditioner"). setMatrix
//   aggregates a new graph again (1 ms at 8000 nodes, 8 ms at 27908; the same pattern
//   keeps its aggregates); a new contact set
//   costs the coarse matrix's assembly and factorization (0.4 ms at 8000 nodes). CG runs
//   its deflated form (applyDeflated from deflate's start: one coarse solve an iteration
//   instead of two, the same iterates to rounding): `esim bench electric --strategies pcg`
//   27.1-27.8 against 32.8-32.9 ms a solve at 50k nodes, 4.6 against 5.5 ms at 8000, the
//   same iterations (README, "The potential's two-level preconditioner").
// - Jacobi: nothing to set up, O(1/h) iterations.
// - incomplete Cholesky (Eigen, AMD ordering): IC halves to thirds Jacobi's iterations
//   but is recomputed whenever the contact set or the matrix changes, which on the slab
//   benchmark costs more than it saves (`esim bench electric --pcg-preconditioner ic`).
// setMatrix only replaces the matrix: the warm start carries over, so a small conductivity
// change costs a few iterations. updateMatrix (a cut) takes the change in place (FreeBase:
// read from the changed nodes' columns when told them, the nodes leaving the free set kept
// as identity rows), so the aggregates stay those of the last setMatrix: the nodes that left
// are out of the coarse space, as the contact rows are, and their rows stay exactly 0 in
// CG's iterates. Before (setMatrix at every removal: the node classes' search, K_ff copied
// anew, the graph compared or aggregated again) it cost O(nnz) (README, "The potential's
// two-level preconditioner").
// Not converging is an error (esim::RunError naming the residual), never a silent result.
// Single-threaded (Eigen without OpenMP), deterministic.
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>
#include <cstdio>
#include <memory>
#include <string>

#include "sim/core_error.h"
#include "sim/electric_solver.h"
#include "sim/two_level_preconditioner.h"

namespace esim::electric_detail {
namespace {

// Eigen's ConjugateGradient takes its preconditioner by type: this one forwards to a
// TwoLevelPreconditioner set up by the solver (compute does nothing: the solver computes
// the coarse level itself, with the contact rows it knows)
class TwoLevelAdapter {
 public:
  template <class Matrix>
  TwoLevelAdapter& analyzePattern(const Matrix&) {
    return *this;
  }
  template <class Matrix>
  TwoLevelAdapter& factorize(const Matrix&) {
    return *this;
  }
  template <class Matrix>
  TwoLevelAdapter& compute(const Matrix&) {
    return *this;
  }
  template <class Rhs>
  Eigen::VectorXd solve(const Rhs& r) const {
    Eigen::VectorXd z;
    preconditioner->applyDeflated(r, z);  // CG starts from TwoLevelPreconditioner::deflate
    return z;
  }
  Eigen::ComputationInfo info() const { return Eigen::Success; }
  const TwoLevelPreconditioner* preconditioner = nullptr;
};

// aggregation passes of the two-level preconditioner: one (aggregates of ~20 nodes) took
// 55 iterations a frame on slab_cut, two (~300 nodes) 96, in 7.6 against 9.3 ms
constexpr int kAggregationPasses = 1;

class PcgSolver final : public ElectricSolver {
 public:
  PcgSolver(const PcgSolver&) = delete;  // twoLevel_ points at coarse_
  PcgSolver& operator=(const PcgSolver&) = delete;
  explicit PcgSolver(const ElectricSolverOptions& options) : options_(options) {
    twoLevel_.setTolerance(options_.pcgTolerance);
    twoLevel_.setMaxIterations(options_.pcgMaxIterations);
    twoLevel_.preconditioner().preconditioner = &coarse_;
    ic_.setTolerance(options_.pcgTolerance);
    ic_.setMaxIterations(options_.pcgMaxIterations);
    jacobi_.setTolerance(options_.pcgTolerance);
    jacobi_.setMaxIterations(options_.pcgMaxIterations);
  }

  void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) override {
    const ResetOnThrow guard(free_.current);
    free_.set(K, grounded);
    system_ = free_.matrix;  // a new pattern: the preconditioner is computed again
    if (options_.pcgPreconditioner == PcgPreconditioner::TwoLevel)
      coarse_.setGraph(free_.matrix, kAggregationPasses);
    prepared_ = false;
  }

  // the change in place (the warm start carries over); setMatrix where FreeBase cannot
  ElectricUpdateStats updateMatrix(const SparseMatrix& K, const std::vector<int>& grounded,
                                   const std::vector<int>* changedNodes) override {
    const ResetOnThrow guard(free_.current);
    BaseChange change;
    const ElectricUpdateStats stats =
        updateFreeBase(free_, K, grounded, changedNodes, change, [&] { setMatrix(K, grounded); });
    if (!stats.fellBack && !change.empty()) prepared_ = false;  // the preconditioner anew
    return stats;
  }

  ElectricSolveStats solve(const std::vector<int>& contact, double voltageV,
                           Eigen::VectorXd& potential) override {
    ElectricSolveStats stats;
    const std::vector<int> cf = free_.contactsOrZero(contact, potential);
    if (cf.empty()) return stats;
    const int nf = free_.size();
    Eigen::VectorXd b;
    dirichletSystem(free_.matrix, cf, voltageV, system_, b);
    // warm start from the input potential (the rows that left the free set: 0, their b)
    Eigen::VectorXd x = Eigen::VectorXd::Zero(nf);
    if (potential.size() == free_.base.n && potential.allFinite())
      for (int i = 0; i < nf; ++i)
        if (free_.active[i]) x[i] = potential[free_.base.freeNodes[i]];
    // the contact rows are decoupled identity rows: solve them as 0 = 0 so that the
    // relative residual measures the unknowns only (u_c is scattered below)
    for (int c : cf) x[c] = b[c] = 0.0;
    if (!prepared_ || cf != preparedContact_) {  // the preconditioner of this system
      if (options_.pcgPreconditioner == PcgPreconditioner::TwoLevel) {
        // the contact rows, and those that left the free set, out of its coarse space
        std::vector<int> excluded = cf;
        for (int b = 0; b < nf; ++b)
          if (!free_.active[b]) excluded.push_back(b);
        coarse_.compute(system_, excluded);
      } else if (options_.pcgPreconditioner == PcgPreconditioner::IncompleteCholesky) {
        ic_.compute(system_);
        ESIM_VERIFY(ic_.info() == Eigen::Success, "pcg: incomplete Cholesky preconditioner failed");
      } else {
        jacobi_.compute(system_);
      }
    }
    iterate(b, x, stats);
    prepared_ = true;
    preparedContact_ = cf;
    ESIM_RUN_CHECK(x.allFinite(), "pcg: the iteration produced a non-finite potential");
    // CG's recursive residual drifts from the true one at large conductivity contrasts: the
    // tolerance is checked on the true ||b - A x|| / ||b||, after one restart from x
    const double bNorm = b.norm();
    if (bNorm > 0 && stats.residual <= options_.pcgTolerance) {
      double trueResidual = (b - system_ * x).norm() / bNorm;
      if (trueResidual > options_.pcgTolerance) {
        ElectricSolveStats more;
        iterate(b, x, more);
        stats.iterations += more.iterations;
        trueResidual = (b - system_ * x).norm() / bNorm;
      }
      ESIM_RUN_CHECK(trueResidual <= options_.pcgTolerance,
                     "solve_potential: pcg cannot reach solvers.electric.tolerance = " +
                         messageNumber(options_.pcgTolerance) + ": the true relative residual " +
                         "stays at " + messageNumber(trueResidual) +
                         " (the attainable accuracy of this matrix); loosen the tolerance or "
                         "use a direct strategy (capacitance)");
      stats.residual = trueResidual;
    }
    // an unconverged potential is an error, never a silent result (its energy can be off
    // by tens of per cent)
    ESIM_RUN_CHECK(
        stats.residual <= options_.pcgTolerance,
        "solve_potential: pcg did not converge: relative residual " +
            messageNumber(stats.residual) + " after " + std::to_string(stats.iterations) +
            " iterations, above solvers.electric.tolerance = " +
            messageNumber(options_.pcgTolerance) + "; raise solvers.electric.max_iterations (now " +
            std::to_string(options_.pcgMaxIterations) +
            "), loosen the tolerance, or use a direct strategy (capacitance)");
    free_.scatter(x, cf, voltageV, potential);
    return stats;
  }

  double memoryBytes() const override {
    const double nnz = static_cast<double>(free_.matrix.nonZeros());
    const double preconditioner =
        options_.pcgPreconditioner == PcgPreconditioner::IncompleteCholesky ? 12.0 * nnz
        : options_.pcgPreconditioner == PcgPreconditioner::TwoLevel         ? coarse_.memoryBytes()
                                                                            : 8.0 * free_.size();
    return 2.0 * 12.0 * nnz + preconditioner;
  }
  const char* name() const override { return "pcg"; }

 private:
  // CG from x with the chosen preconditioner (computed for system_), into x and stats
  void iterate(const Eigen::VectorXd& b, Eigen::VectorXd& x, ElectricSolveStats& stats) {
    const auto run = [&](auto& cg) {
      x = cg.solveWithGuess(b, Eigen::VectorXd(x));
      stats.iterations = static_cast<int>(cg.iterations());
      stats.residual = cg.error();
    };
    if (options_.pcgPreconditioner == PcgPreconditioner::TwoLevel) {
      twoLevel_.compute(system_);      // (the matrix's reference; coarse_ is computed already)
      coarse_.deflate(system_, b, x);  // the start applyDeflated needs (no coarse residual)
      run(twoLevel_);
    } else if (options_.pcgPreconditioner == PcgPreconditioner::IncompleteCholesky) {
      run(ic_);
    } else {
      run(jacobi_);
    }
  }

  using Ic = Eigen::ConjugateGradient<
      SparseMatrix, Eigen::Lower | Eigen::Upper,
      Eigen::IncompleteCholesky<double, Eigen::Lower, Eigen::AMDOrdering<int>>>;
  using Jacobi = Eigen::ConjugateGradient<SparseMatrix, Eigen::Lower | Eigen::Upper,
                                          Eigen::DiagonalPreconditioner<double>>;

  ElectricSolverOptions options_;
  FreeBase free_;        // K_ff in base indices (the nodes that left: identity rows)
  SparseMatrix system_;  // free_.matrix with the contact rows set to the identity
  using TwoLevel =
      Eigen::ConjugateGradient<SparseMatrix, Eigen::Lower | Eigen::Upper, TwoLevelAdapter>;
  Ic ic_;
  TwoLevelPreconditioner coarse_;
  TwoLevel twoLevel_;
  Jacobi jacobi_;
  bool prepared_ = false;
  std::vector<int> preparedContact_;
};

}  // namespace

std::unique_ptr<ElectricSolver> makePcgSolver(const ElectricSolverOptions& options) {
  return std::make_unique<PcgSolver>(options);
}

}  // namespace esim::electric_detail
