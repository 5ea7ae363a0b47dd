// structural_coarse.cpp - see structural_coarse.h.
#include "sim/structural_coarse.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "sim/cholmod_view.h"
#include "sim/core_error.h"

extern "C" void openblas_set_num_threads(int num_threads);

namespace esim {

namespace {

// grid nodes of cells of at most h along each axis of a box of `size` (at least one cell each)
double gridNodesFor(const Vec3& size, double h) {
  double n = 1;
  for (int a = 0; a < 3; ++a) n *= std::max(1.0, std::ceil(size(a) / h - 1e-9)) + 1;
  return n;
}

}  // namespace

CoarseSpace::CoarseSpace(const std::vector<Vec3>& nodes, double spacingM) {
  ESIM_VERIFY(std::isfinite(spacingM) && spacingM >= 0,
              "structural: the coarse grid's spacing must be >= 0 m (0: automatic), got " +
                  messageNumber(spacingM));
  Eigen::AlignedBox3d box;
  for (const Vec3& p : nodes) box.extend(p);
  if (nodes.empty()) box.extend(Vec3::Zero());
  const Vec3 size = box.sizes();
  if (spacingM == 0) {  // automatic: the finest of a geometric sequence within kAutoGridNodes
    spacingM = std::max(size.maxCoeff(), 1e-9);
    while (gridNodesFor(size, 0.97 * spacingM) <= kAutoGridNodes && spacingM > 1e-9)
      spacingM *= 0.97;
  }
  spacing_ = spacingM;
  const double gridNodes = gridNodesFor(size, spacingM);
  if (gridNodes > kMaxGridNodes)
    throw Error("structural: a coarse grid (solvers.structural.coarse_spacing_m) of spacing " +
                messageNumber(spacingM) + " m over the mesh's " + messageNumber(size(0)) + " x " +
                messageNumber(size(1)) + " x " + messageNumber(size(2)) + " m box has " +
                messageNumber(gridNodes) + " nodes, more than " + std::to_string(kMaxGridNodes) +
                "; use a larger spacing");
  for (int a = 0; a < 3; ++a)
    cells_[a] = static_cast<int>(std::max(1.0, std::ceil(size(a) / spacingM - 1e-9)));
  cholmod_start(&common_);
  common_.print = 0;
  common_.error_handler = nullptr;
  gridNodes_ = static_cast<int>(gridNodes);
  const int nx = cells_[0] + 1, ny = cells_[1] + 1;
  gridOf_.resize(nodes.size());
  weightOf_.resize(nodes.size());
  for (size_t v = 0; v < nodes.size(); ++v) {
    std::array<int, 3> cell;
    std::array<double, 3> local;
    for (int a = 0; a < 3; ++a) {
      const double h = size(a) > 0 ? size(a) / cells_[a] : 1.0;
      const double s = (nodes[v](a) - box.min()(a)) / h;
      cell[a] = std::clamp(static_cast<int>(std::floor(s)), 0, cells_[a] - 1);
      local[a] = std::clamp(s - cell[a], 0.0, 1.0);
    }
    for (int c = 0; c < 8; ++c) {
      const int i = c & 1, j = (c >> 1) & 1, k = (c >> 2) & 1;
      gridOf_[v][c] = (cell[0] + i) + nx * ((cell[1] + j) + ny * (cell[2] + k));
      weightOf_[v][c] = (i ? local[0] : 1 - local[0]) * (j ? local[1] : 1 - local[1]) *
                        (k ? local[2] : 1 - local[2]);
    }
  }
}

CoarseSpace::~CoarseSpace() {
  if (factor_) cholmod_free_factor(&factor_, &common_);
  if (x_) cholmod_free_dense(&x_, &common_);
  if (y_) cholmod_free_dense(&y_, &common_);
  if (e_) cholmod_free_dense(&e_, &common_);
  cholmod_finish(&common_);
}

void CoarseSpace::build(const SparseMatrix& lowerK, const std::uint8_t* held) {
  const int nf = static_cast<int>(gridOf_.size()), m = 3 * gridNodes_;
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(3 * nf) * 8);
  for (int v = 0; v < nf; ++v)
    for (int a = 0; a < 3; ++a)
      if (!held[3 * v + a])
        for (int c = 0; c < 8; ++c)
          if (weightOf_[v][c] != 0)
            triplets.emplace_back(3 * v + a, 3 * gridOf_[v][c] + a, weightOf_[v][c]);
  SparseMatrix p(3 * nf, m);
  p.setFromTriplets(triplets.begin(), triplets.end());
  // K P with K symmetric from its lower triangle (the held dofs' rows of P are 0, so their
  // entries of K, the identity, drop out)
  const SparseMatrix kp = lowerK.selfadjointView<Eigen::Lower>() * p;
  const SparseMatrix pkp = SparseMatrix(p.transpose()) * kp;
  // every diagonal entry in the pattern (a grid node that spans nothing has an empty column:
  // the identity row factorize() gives it)
  SparseMatrix eye(m, m);
  eye.setIdentity();
  kc_ = SparseMatrix(pkp.triangularView<Eigen::Lower>()) + 0.0 * eye;
  kc_.makeCompressed();
  diag0_.assign(m, 0.0);
  for (int j = 0; j < m; ++j) diag0_[j] = kc_.coeff(j, j);
  if (factor_) cholmod_free_factor(&factor_, &common_);
  dirty_ = true;
  factorize();
}

void CoarseSpace::addEntry(int row, int col, double value) {
  const int* begin = kc_.innerIndexPtr() + kc_.outerIndexPtr()[col];
  const int* end = kc_.innerIndexPtr() + kc_.outerIndexPtr()[col + 1];
  const int* at = std::lower_bound(begin, end, row);
  // the pattern holds every coupling of the alive tets at build(); removals only lose some
  ESIM_RUN_CHECK(at != end && *at == row, "structural: coarse matrix entry outside its pattern");
  kc_.valuePtr()[at - kc_.innerIndexPtr()] += value;
}

// work_ = K_c with the columns that span nothing as identity rows, its diagonal
// regularized (see the header), and its LL'
void CoarseSpace::factorize() {
  const auto t0 = std::chrono::steady_clock::now();
  const int m = 3 * gridNodes_;
  work_ = kc_;
  dead_.assign(m, 0);
  for (int j = 0; j < m; ++j) dead_[j] = !(kc_.coeff(j, j) > 1e-9 * diag0_[j]) ? 1 : 0;
  regularization_.assign(m, 0.0);
  for (int j = 0; j < m; ++j)
    for (SparseMatrix::InnerIterator it(work_, j); it; ++it) {
      const int i = static_cast<int>(it.row());
      if (dead_[i] || dead_[j]) it.valueRef() = i == j ? 1.0 : 0.0;
    }
  openblas_set_num_threads(1);
  bool factored = false;
  for (double eps = kRegularization; eps <= 1e-2 && !factored; eps *= 100) {
    for (int j = 0; j < m; ++j)
      for (SparseMatrix::InnerIterator it(work_, j); it; ++it)
        if (it.row() == j && !dead_[j]) {
          it.valueRef() -= regularization_[j];
          regularization_[j] = eps * it.value();
          it.valueRef() += regularization_[j];
        }
    cholmod_sparse view = cholmodViewLower(work_);
    if (!factor_) {
      factor_ = cholmod_analyze(&view, &common_);
      if (factor_ == nullptr) throwIfOutOfResources(common_);
      ESIM_RUN_CHECK(factor_ != nullptr,
                     "structural: CHOLMOD analysis of the coarse matrix failed");
    }
    const int ok = cholmod_factorize(&view, factor_, &common_);
    throwIfOutOfResources(common_);
    factored = ok && common_.status == CHOLMOD_OK && factor_->minor == factor_->n;
  }
  ESIM_RUN_CHECK(factored, "structural: the coarse stiffness matrix is not positive definite");
  dirty_ = false;
  factorSeconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// x = F^-1 b, F the factorized matrix, into x_
void CoarseSpace::solveFactor(const Eigen::VectorXd& b) {
  cholmod_dense view = cholmodViewDense(b.data(), b.size());
  const int ok =
      cholmod_solve2(CHOLMOD_A, factor_, &view, nullptr, &x_, nullptr, &y_, &e_, &common_);
  if (!ok) throwIfOutOfResources(common_);
  ESIM_RUN_CHECK(ok, "structural: CHOLMOD solve of the coarse matrix failed");
}

void CoarseSpace::solve(const Eigen::VectorXd& f, const std::uint8_t* held, Eigen::VectorXd& u) {
  if (dirty_) factorize();
  const int nf = static_cast<int>(gridOf_.size()), m = 3 * gridNodes_;
  fc_.setZero(m);
  for (int v = 0; v < nf; ++v)
    for (int a = 0; a < 3; ++a)
      if (!held[3 * v + a] && f(3 * v + a) != 0)
        for (int c = 0; c < 8; ++c) fc_(3 * gridOf_[v][c] + a) += weightOf_[v][c] * f(3 * v + a);
  for (int j = 0; j < m; ++j)
    if (dead_[j]) fc_(j) = 0;
  // u_c = F^-1 fc, then refined against K_c (F = K_c + R, R the regularization): each step
  // shrinks the error in a direction of K_c's eigenvalue lambda (relative to its diagonal)
  // by eps / (lambda + eps), so the regularization leaves no trace but in the directions P_h
  // maps to (nearly) 0
  openblas_set_num_threads(1);
  solveFactor(fc_);
  uc_ = Eigen::Map<const Eigen::VectorXd>(static_cast<const double*>(x_->x), m);
  const Eigen::Map<const Eigen::VectorXd> reg(regularization_.data(), m);
  for (int step = 0; step < kRefinementSteps; ++step) {
    const Eigen::VectorXd r =
        fc_ - work_.selfadjointView<Eigen::Lower>() * uc_ + reg.cwiseProduct(uc_);
    solveFactor(r);
    const Eigen::Map<const Eigen::VectorXd> d(static_cast<const double*>(x_->x), m);
    uc_ += d;
    if (d.norm() <= 1e-15 * uc_.norm()) break;
  }
  const double* uc = uc_.data();
  u.setZero(3 * nf);
  for (int v = 0; v < nf; ++v)
    for (int a = 0; a < 3; ++a) {
      if (held[3 * v + a]) continue;
      double s = 0;
      for (int c = 0; c < 8; ++c) s += weightOf_[v][c] * uc[3 * gridOf_[v][c] + a];
      u(3 * v + a) = s;
    }
}

}  // namespace esim
