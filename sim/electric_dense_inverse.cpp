// electric_dense_inverse.cpp - the paper's proposed method (eq. 8-13).
//
// Pre-processing: L = K_ff^-1 as a dense n_f x n_f matrix (column-major), computed
// from one CHOLMOD factorization by solving for blocks of identity columns. The
// return electrode is eliminated first, so K_ff is SPD.
// Per contact set c: f_c = L_cc^-1 u_c (small dense Cholesky), u = L_:c f_c (one
// BLAS daxpy per contact column; rows of c give back u_c).
// Memory n_f^2 * 8 bytes: refused above denseMemoryLimitBytes with a message that
// names the capacitance strategy (same answer, sparse memory).
// setMatrix recomputes the whole inverse.
#include <cblas.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cstdio>

#include "sim/core_error.h"
#include "sim/electric_solver.h"

namespace esim::electric_detail {
namespace {

std::string formatGb(double bytes) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3g GB", bytes / 1e9);
  return buf;
}

class DenseInverseSolver final : public ElectricSolver {
 public:
  explicit DenseInverseSolver(const ElectricSolverOptions& options) : options_(options) {}

  void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) override {
    setBlasThreads(options_.threads);
    const ResetOnThrow guard(classes_);
    classes_.build(K, grounded);
    const int nf = classes_.numFree();
    const double need = 8.0 * static_cast<double>(nf) * static_cast<double>(nf);
    if (need > options_.denseMemoryLimitBytes) {
      inverse_.resize(0, 0);
      throw Error("dense-inverse: the inverse of the " + std::to_string(nf) + " x " +
                  std::to_string(nf) + " reduced matrix needs " + formatGb(need) +
                  ", above the limit of " + formatGb(options_.denseMemoryLimitBytes) +
                  " (solvers.electric.dense_memory_limit_mb); use the 'capacitance' strategy, "
                  "which gives the "
                  "same answer from one sparse factorization and cached columns");
    }
    inverse_.resize(nf, nf);
    if (nf == 0) return;
    const SparseMatrix kff = restrictToFree(K, classes_);
    CholmodFactor factor;
    factor.analyze(kff);
    factor.factorize(kff, "dense-inverse");
    // solve for blocks of identity columns straight into the inverse
    const int block = 64;
    Eigen::MatrixXd identity;
    for (int j0 = 0; j0 < nf; j0 += block) {
      const int cols = std::min(block, nf - j0);
      identity.setZero(nf, cols);
      for (int k = 0; k < cols; ++k) identity(j0 + k, k) = 1.0;
      factor.solve(identity.data(), inverse_.data() + static_cast<size_t>(j0) * nf, cols);
    }
  }

  ElectricSolveStats solve(const std::vector<int>& contact, double voltageV,
                           Eigen::VectorXd& potential) override {
    ESIM_CHECK(classes_.n > 0);  // setMatrix before solve
    const std::vector<int> cf = classes_.contactFreeIndices(contact);
    if (cf.empty()) {
      potential.setZero(classes_.n);
      return {};
    }
    setBlasThreads(options_.threads);
    const int c = static_cast<int>(cf.size());
    const int nf = classes_.numFree();
    // f_c = L_cc^-1 u_c
    Eigen::MatrixXd lcc(c, c);
    for (int j = 0; j < c; ++j)
      for (int i = 0; i < c; ++i) lcc(i, j) = inverse_(cf[i], cf[j]);
    Eigen::LLT<Eigen::MatrixXd> llt(lcc);
    ESIM_VERIFY(llt.info() == Eigen::Success, "dense-inverse: L_cc is not positive definite");
    const Eigen::VectorXd fc = llt.solve(Eigen::VectorXd::Constant(c, voltageV));
    // u = L_:c f_c
    Eigen::VectorXd u = Eigen::VectorXd::Zero(nf);
    for (int j = 0; j < c; ++j)
      cblas_daxpy(nf, fc[j], inverse_.data() + static_cast<size_t>(cf[j]) * nf, 1, u.data(), 1);
    scatterPotential(classes_, u, cf, voltageV, potential);
    return {};
  }

  double memoryBytes() const override { return 8.0 * static_cast<double>(inverse_.size()); }
  const char* name() const override { return "dense-inverse"; }

 private:
  ElectricSolverOptions options_;
  NodeClasses classes_;
  Eigen::MatrixXd inverse_;  // K_ff^-1, column-major
};

}  // namespace

std::unique_ptr<ElectricSolver> makeDenseInverseSolver(const ElectricSolverOptions& options) {
  return std::make_unique<DenseInverseSolver>(options);
}

}  // namespace esim::electric_detail
