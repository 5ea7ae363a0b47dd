// electric_pcg.cpp - preconditioned conjugate gradients: the accuracy/time dial.
//
// Solves the same reduced system as `refactor` (K_ff with the contact rows and
// columns replaced by the identity, b_o = -K_oc u_c, b_c = 0; SPD) with Eigen's
// conjugate gradients, warm-started from the input potential (the previous frame),
// until ||b - A x|| <= pcgTolerance ||b|| or pcgMaxIterations. Preconditioner:
// Jacobi (default) or incomplete Cholesky (Eigen, AMD ordering): IC halves to
// thirds the iterations but is recomputed whenever the contact set or the matrix
// changes, which on the slab benchmark costs more than it saves (`esim bench
// electric --pcg-preconditioner ic`). setMatrix only replaces the matrix: the warm start
// carries over, so a small conductivity change costs a few iterations. updateMatrix
// (a cut) is setMatrix: O(nnz), nothing to update.
// Not converging is not an exception: stats.residual > pcgTolerance says so.
// Single-threaded (Eigen without OpenMP), deterministic.
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>
#include <cstdio>
#include <memory>
#include <string>

#include "sim/core_error.h"
#include "sim/electric_solver.h"

namespace esim::electric_detail {
namespace {

class PcgSolver final : public ElectricSolver {
 public:
  explicit PcgSolver(const ElectricSolverOptions& options) : options_(options) {
    ic_.setTolerance(options_.pcgTolerance);
    ic_.setMaxIterations(options_.pcgMaxIterations);
    jacobi_.setTolerance(options_.pcgTolerance);
    jacobi_.setMaxIterations(options_.pcgMaxIterations);
  }

  void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) override {
    const ResetOnThrow guard(classes_);
    classes_.build(K, grounded);
    kff_ = restrictToFree(K, classes_);
    system_ = kff_;  // a new pattern: the preconditioner is computed again
    prepared_ = false;
  }

  // a new matrix is all pcg needs (O(nnz); the warm start carries over)
  ElectricUpdateStats updateMatrix(const SparseMatrix& K,
                                   const std::vector<int>& grounded) override {
    setMatrix(K, grounded);
    return {};
  }

  ElectricSolveStats solve(const std::vector<int>& contact, double voltageV,
                           Eigen::VectorXd& potential) override {
    ESIM_CHECK(classes_.n > 0);  // setMatrix before solve
    ElectricSolveStats stats;
    const std::vector<int> cf = classes_.contactFreeIndices(contact);
    if (cf.empty()) {
      potential.setZero(classes_.n);
      return stats;
    }
    const int nf = classes_.numFree();
    Eigen::VectorXd b;
    dirichletSystem(kff_, cf, voltageV, system_, b);
    // warm start from the input potential
    Eigen::VectorXd x0 = Eigen::VectorXd::Zero(nf);
    if (potential.size() == classes_.n && potential.allFinite())
      for (int i = 0; i < nf; ++i) x0[i] = potential[classes_.freeNodes[i]];
    // the contact rows are decoupled identity rows: solve them as 0 = 0 so that the
    // relative residual measures the unknowns only (u_c is scattered below)
    for (int c : cf) x0[c] = b[c] = 0.0;
    Eigen::VectorXd x;
    if (options_.pcgPreconditioner == PcgPreconditioner::IncompleteCholesky) {
      if (!prepared_ || cf != preparedContact_) ic_.compute(system_);
      ESIM_VERIFY(ic_.info() == Eigen::Success, "pcg: incomplete Cholesky preconditioner failed");
      x = ic_.solveWithGuess(b, x0);
      stats.iterations = static_cast<int>(ic_.iterations());
      stats.residual = ic_.error();
    } else {
      if (!prepared_ || cf != preparedContact_) jacobi_.compute(system_);
      x = jacobi_.solveWithGuess(b, x0);
      stats.iterations = static_cast<int>(jacobi_.iterations());
      stats.residual = jacobi_.error();
    }
    prepared_ = true;
    preparedContact_ = cf;
    ESIM_RUN_CHECK(x.allFinite(), "pcg: the iteration produced a non-finite potential");
    // CG's recursive residual drifts from the true one at large conductivity contrasts: the
    // tolerance is checked on the true ||b - A x|| / ||b||, after one restart from x
    const double bNorm = b.norm();
    if (bNorm > 0 && stats.residual <= options_.pcgTolerance) {
      double trueResidual = (b - system_ * x).norm() / bNorm;
      if (trueResidual > options_.pcgTolerance) {
        int more = 0;
        if (options_.pcgPreconditioner == PcgPreconditioner::IncompleteCholesky) {
          x = ic_.solveWithGuess(b, Eigen::VectorXd(x));
          more = static_cast<int>(ic_.iterations());
        } else {
          x = jacobi_.solveWithGuess(b, Eigen::VectorXd(x));
          more = static_cast<int>(jacobi_.iterations());
        }
        stats.iterations += more;
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
    scatterPotential(classes_, x, cf, voltageV, potential);
    return stats;
  }

  double memoryBytes() const override {
    return 2.0 * 12.0 * static_cast<double>(kff_.nonZeros()) +
           (options_.pcgPreconditioner == PcgPreconditioner::IncompleteCholesky
                ? 12.0 * static_cast<double>(kff_.nonZeros())
                : 8.0 * kff_.rows());
  }
  const char* name() const override { return "pcg"; }

 private:
  using Ic = Eigen::ConjugateGradient<
      SparseMatrix, Eigen::Lower | Eigen::Upper,
      Eigen::IncompleteCholesky<double, Eigen::Lower, Eigen::AMDOrdering<int>>>;
  using Jacobi = Eigen::ConjugateGradient<SparseMatrix, Eigen::Lower | Eigen::Upper,
                                          Eigen::DiagonalPreconditioner<double>>;

  ElectricSolverOptions options_;
  NodeClasses classes_;
  SparseMatrix kff_;
  SparseMatrix system_;
  Ic ic_;
  Jacobi jacobi_;
  bool prepared_ = false;
  std::vector<int> preparedContact_;
};

}  // namespace

std::unique_ptr<ElectricSolver> makePcgSolver(const ElectricSolverOptions& options) {
  return std::make_unique<PcgSolver>(options);
}

}  // namespace esim::electric_detail
