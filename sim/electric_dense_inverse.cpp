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
// updateMatrix (a cut): with E = K'_ff - K_ff supported on the s base indices S whose
// rows change (a node leaving the free set gets an identity row and column), the
// Sherman-Morrison-Woodbury identity
//   K'^-1 = K^-1 - K^-1_{:S} E_SS (I + K^-1_SS E_SS)^-1 K^-1_{S:}
// costs one s x s LU and one rank-s BLAS-3 product, 2 n_f^2 s flops; recomputing is a
// factorization plus n_f solves (about 4 nnz(L) n_f flops, at a far lower rate than
// dgemm). Above s > kMaxUpdateFraction n_f the inverse is recomputed (setMatrix), and so it
// is when the updated columns S miss ||K' Y - I_:S||_F / sqrt(s) <= updateResidual (a node
// nearly cut off makes I + K^-1_SS E_SS ill-conditioned; the error would stay in the inverse
// for the rest of the run). Measured on the cut (esim bench cut at 1013 and 2002 nodes,
// temporary instrumentation): 1.2e-15 to 1.1e-13 over 61 updates.
#include <cblas.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
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

// largest changed set, as a fraction of n_f, updated in place (above: recompute).
// Measured (esim bench electric --only-update --update-sizes 5000 --update-tets
// 5,50,200 --update-strategies dense-inverse, one core): rank 9, 34, 84 updates take
// 25, 48, 113 ms against 1.4-1.9 s to recompute (BLAS-3 dgemm near peak vs n_f sparse
// solves), so the crossover is near s ~ 0.3 n_f; 0.2 leaves a margin.
constexpr double kMaxUpdateFraction = 0.2;

class DenseInverseSolver final : public ElectricSolver {
 public:
  explicit DenseInverseSolver(const ElectricSolverOptions& options) : options_(options) {}

  void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) override {
    setBlasThreads(options_.threads);
    const ResetOnThrow guard(free_.current);
    free_.set(K, grounded);
    const int nf = free_.size();
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
    const SparseMatrix& kff = free_.matrix;
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

  ElectricUpdateStats updateMatrix(const SparseMatrix& K, const std::vector<int>& grounded,
                                   const std::vector<int>* changedNodes) override {
    ESIM_CHECK(free_.current.n > 0);  // setMatrix before updateMatrix
    const ResetOnThrow guard(free_.current);
    const BaseChange change = free_.diff(K, grounded, changedNodes);
    ElectricUpdateStats stats;
    const auto fallBack = [&](const std::string& why) {
      setMatrix(K, grounded);
      stats.fellBack = true;
      stats.fallbackReason = why;
      return stats;
    };
    if (!change.fallback.empty()) return fallBack(change.fallback);
    stats.changedNodes = static_cast<int>(change.touched.size());
    stats.droppedNodes = static_cast<int>(change.dropped.size());
    if (change.empty()) return stats;
    // S: every base index with a changed row (both triangles are stored: rows = columns)
    const int nf = free_.size();
    std::vector<int> where(nf, -1), rows;
    for (int j = 0; j < nf; ++j)
      for (SparseMatrix::InnerIterator it(change.delta, j); it; ++it)
        if (where[it.row()] < 0) where[it.row()] = 1;
    for (int i = 0; i < nf; ++i)
      if (where[i] >= 0) {
        where[i] = static_cast<int>(rows.size());
        rows.push_back(i);
      }
    const int s = static_cast<int>(rows.size());
    if (s > kMaxUpdateFraction * nf)
      return fallBack("the change has rank " + std::to_string(s) + " > " +
                      messageNumber(kMaxUpdateFraction) + " n_f: recomputing is cheaper");
    setBlasThreads(options_.threads);
    Eigen::MatrixXd e = Eigen::MatrixXd::Zero(s, s);
    for (int j = 0; j < nf; ++j)
      for (SparseMatrix::InnerIterator it(change.delta, j); it; ++it)
        e(where[it.row()], where[j]) = it.value();
    Eigen::MatrixXd y(nf, s);  // K^-1_{:S}
    for (int k = 0; k < s; ++k) y.col(k) = inverse_.col(rows[k]);
    Eigen::MatrixXd g(s, s);  // K^-1_SS
    for (int k = 0; k < s; ++k) g.row(k) = y.row(rows[k]);
    // w = E (I + G E)^-1, i.e. (I + G E)^T w^T = E^T = E
    const Eigen::MatrixXd t = Eigen::MatrixXd::Identity(s, s) + g * e;
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(t.transpose());
    const Eigen::MatrixXd w = lu.solve(e).transpose();
    const Eigen::MatrixXd wyT = w * y.transpose();  // s x nf
    // inverse -= y * wyT
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, nf, nf, s, -1.0, y.data(), nf,
                wyT.data(), s, 1.0, inverse_.data(), nf);
    for (int d : change.dropped) {
      inverse_.col(d).setZero();
      inverse_.row(d).setZero();
      inverse_(d, d) = 1.0;
    }
    free_.apply(change);
    stats.rank = s;
    // the check along the directions it changed (rows of S staying free)
    std::vector<int> staying;
    for (int i : rows)
      if (free_.active[i]) staying.push_back(i);
    Eigen::MatrixXd ys(nf, static_cast<Eigen::Index>(staying.size()));
    for (size_t k = 0; k < staying.size(); ++k) ys.col(k) = inverse_.col(staying[k]);
    const double residual = free_.identityResidual(staying, ys);
    if (!(residual <= options_.updateResidual))
      return fallBack("the updated inverse solves to a residual of " + messageNumber(residual));
    return stats;
  }

  ElectricSolveStats solve(const std::vector<int>& contact, double voltageV,
                           Eigen::VectorXd& potential) override {
    const std::vector<int> cf = free_.contactsOrZero(contact, potential);
    if (cf.empty()) return {};
    setBlasThreads(options_.threads);
    const int c = static_cast<int>(cf.size());
    const int nf = free_.size();
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
    free_.scatter(u, cf, voltageV, potential);
    return {};
  }

  double memoryBytes() const override { return 8.0 * static_cast<double>(inverse_.size()); }
  const char* name() const override { return "dense-inverse"; }

 private:
  ElectricSolverOptions options_;
  FreeBase free_;            // node classes and K_ff in base indices
  Eigen::MatrixXd inverse_;  // K_ff^-1 (base indices), column-major
};

}  // namespace

std::unique_ptr<ElectricSolver> makeDenseInverseSolver(const ElectricSolverOptions& options) {
  return std::make_unique<DenseInverseSolver>(options);
}

}  // namespace esim::electric_detail
