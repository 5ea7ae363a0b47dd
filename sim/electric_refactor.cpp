// electric_refactor.cpp - the conventional method (paper eq. 6-7): factorize the
// reduced matrix again whenever the contact set changes.
//
// The contact rows/columns of K_ff are replaced by the identity instead of being
// removed, so the sparsity pattern never changes: the symbolic analysis (ordering)
// is done once per setMatrix and each contact change costs one numeric CHOLMOD
// supernodal factorization. A solve with an unchanged contact set and voltage
// reuses the factorization (one triangular solve pair).
// updateMatrix keeps the indices, pattern and symbolic analysis of the last setMatrix
// (nodes that stop being free get identity rows) and only rewrites the values, O(nnz);
// the next solve refactors numerically, as it would for a new contact set.
#include <algorithm>

#include "sim/core_error.h"
#include "sim/electric_solver.h"

namespace esim::electric_detail {
namespace {

class RefactorSolver final : public ElectricSolver {
 public:
  explicit RefactorSolver(const ElectricSolverOptions& options) : options_(options) {}

  void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) override {
    setBlasThreads(options_.threads);
    const ResetOnThrow guard(free_.current);
    free_.set(K, grounded);
    system_ = free_.matrix;
    if (free_.size() > 0) factor_.analyze(system_);
    hasFactor_ = false;
  }

  ElectricUpdateStats updateMatrix(const SparseMatrix& K, const std::vector<int>& grounded,
                                   const std::vector<int>* changedNodes) override {
    const ResetOnThrow guard(free_.current);
    BaseChange change;
    const ElectricUpdateStats stats =
        updateFreeBase(free_, K, grounded, changedNodes, change, [&] { setMatrix(K, grounded); });
    if (!stats.fellBack && !change.empty()) hasFactor_ = false;  // the next solve refactors
    return stats;
  }

  ElectricSolveStats solve(const std::vector<int>& contact, double voltageV,
                           Eigen::VectorXd& potential) override {
    ElectricSolveStats stats;
    const std::vector<int> cf = free_.contactsOrZero(contact, potential);
    if (cf.empty()) return stats;
    setBlasThreads(options_.threads);
    Eigen::VectorXd b;
    dirichletSystem(free_.matrix, cf, voltageV, system_, b);
    if (!hasFactor_ || cf != factoredContact_) {
      factor_.factorize(system_, "refactor");
      factoredContact_ = cf;
      hasFactor_ = true;
      stats.refactored = true;
    }
    Eigen::VectorXd x(b.size());
    factor_.solve(b.data(), x.data());
    free_.scatter(x, cf, voltageV, potential);
    return stats;
  }

  double memoryBytes() const override {
    return factor_.memoryBytes() + 2.0 * 12.0 * static_cast<double>(free_.matrix.nonZeros());
  }
  const char* name() const override { return "refactor"; }

 private:
  ElectricSolverOptions options_;
  FreeBase free_;        // K restricted to the free nodes (base indices)
  SparseMatrix system_;  // free_.matrix with the contact rows/columns set to the identity
  CholmodFactor factor_;
  bool hasFactor_ = false;
  std::vector<int> factoredContact_;
};

}  // namespace

std::unique_ptr<ElectricSolver> makeRefactorSolver(const ElectricSolverOptions& options) {
  return std::make_unique<RefactorSolver>(options);
}

}  // namespace esim::electric_detail
