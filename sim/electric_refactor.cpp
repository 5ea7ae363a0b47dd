// electric_refactor.cpp - the conventional method (paper eq. 6-7): factorize the
// reduced matrix again whenever the contact set changes.
//
// The contact rows/columns of K_ff are replaced by the identity instead of being
// removed, so the sparsity pattern never changes: the symbolic analysis (ordering)
// is done once per setMatrix and each contact change costs one numeric CHOLMOD
// supernodal factorization. A solve with an unchanged contact set and voltage
// reuses the factorization (one triangular solve pair).
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
    const ResetOnThrow guard(classes_);
    classes_.build(K, grounded);
    kff_ = restrictToFree(K, classes_);
    system_ = kff_;
    if (classes_.numFree() > 0) factor_.analyze(system_);
    hasFactor_ = false;
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
    setBlasThreads(options_.threads);
    Eigen::VectorXd b;
    dirichletSystem(kff_, cf, voltageV, system_, b);
    if (!hasFactor_ || cf != factoredContact_) {
      factor_.factorize(system_, "refactor");
      factoredContact_ = cf;
      hasFactor_ = true;
      stats.refactored = true;
    }
    Eigen::VectorXd x(b.size());
    factor_.solve(b.data(), x.data());
    scatterPotential(classes_, x, cf, voltageV, potential);
    return stats;
  }

  double memoryBytes() const override {
    return factor_.memoryBytes() + 2.0 * 12.0 * static_cast<double>(kff_.nonZeros());
  }
  const char* name() const override { return "refactor"; }

 private:
  ElectricSolverOptions options_;
  NodeClasses classes_;
  SparseMatrix kff_;     // K restricted to the free nodes
  SparseMatrix system_;  // kff_ with the contact rows/columns set to the identity
  CholmodFactor factor_;
  bool hasFactor_ = false;
  std::vector<int> factoredContact_;
};

}  // namespace

std::unique_ptr<ElectricSolver> makeRefactorSolver(const ElectricSolverOptions& options) {
  return std::make_unique<RefactorSolver>(options);
}

}  // namespace esim::electric_detail
