// two_level_preconditioner.cpp - l1-Jacobi and an aggregation coarse level (see the header).
#include "sim/two_level_preconditioner.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "sim/core_error.h"

namespace esim {
namespace {

// one greedy aggregation pass over a graph (CSR-like: the neighbours of i are
// inner[outer[i] .. outer[i+1]), self-loops ignored); returns the aggregate of each node and
// their count. 1: a node whose neighbours are all free starts an aggregate of itself and
// them; 2: a node left joins the first phase-1 aggregate among its neighbours; 3: a node
// still left starts an aggregate with its free neighbours.
int aggregatePass(int n, const int* outer, const int* inner, std::vector<int>& aggregateOf) {
  aggregateOf.assign(n, -1);
  int count = 0;
  for (int i = 0; i < n; ++i) {
    if (aggregateOf[i] >= 0) continue;
    bool free = true;
    for (int p = outer[i]; p < outer[i + 1] && free; ++p)
      free = inner[p] == i || aggregateOf[inner[p]] < 0;
    if (!free) continue;
    aggregateOf[i] = count;
    for (int p = outer[i]; p < outer[i + 1]; ++p) aggregateOf[inner[p]] = count;
    ++count;
  }
  const std::vector<int> first = aggregateOf;
  for (int i = 0; i < n; ++i) {
    if (aggregateOf[i] >= 0) continue;
    for (int p = outer[i]; p < outer[i + 1]; ++p)
      if (first[inner[p]] >= 0) {
        aggregateOf[i] = first[inner[p]];
        break;
      }
  }
  for (int i = 0; i < n; ++i) {
    if (aggregateOf[i] >= 0) continue;
    aggregateOf[i] = count;
    for (int p = outer[i]; p < outer[i + 1]; ++p)
      if (aggregateOf[inner[p]] < 0) aggregateOf[inner[p]] = count;
    ++count;
  }
  return count;
}

// the graph of the aggregates: a and b adjacent when a node of a neighbours one of b
void coarseGraph(int n, const int* outer, const int* inner, const std::vector<int>& aggregateOf,
                 int count, std::vector<int>& coarseOuter, std::vector<int>& coarseInner) {
  std::vector<std::vector<int>> members(count);
  for (int i = 0; i < n; ++i) members[aggregateOf[i]].push_back(i);
  std::vector<int> mark(count, -1);
  coarseOuter.assign(1, 0);
  coarseInner.clear();
  for (int a = 0; a < count; ++a) {
    for (int i : members[a])
      for (int p = outer[i]; p < outer[i + 1]; ++p) {
        const int b = aggregateOf[inner[p]];
        if (b != a && mark[b] != a) {
          mark[b] = a;
          coarseInner.push_back(b);
        }
      }
    coarseOuter.push_back(static_cast<int>(coarseInner.size()));
  }
}

}  // namespace

void TwoLevelPreconditioner::setGraph(const SparseMatrix& K, int passes) {
  ESIM_VERIFY(passes >= 1 && passes <= 3, "two-level preconditioner: " + std::to_string(passes) +
                                              " aggregation passes; expected 1 to 3");
  ESIM_VERIFY(K.rows() == K.cols() && K.isCompressed(),
              "two-level preconditioner: the matrix must be square and compressed");
  const int n = static_cast<int>(K.rows());
  ready_ = false;
  // the same graph as last time (a new matrix of the same pattern: conductivities that
  // follow the temperature): the aggregates and patterns stand
  if (passes == passes_ && static_cast<int>(graphOuter_.size()) == n + 1 &&
      std::equal(graphOuter_.begin(), graphOuter_.end(), K.outerIndexPtr()) &&
      static_cast<long>(graphInner_.size()) == K.nonZeros() &&
      std::equal(graphInner_.begin(), graphInner_.end(), K.innerIndexPtr()))
    return;
  passes_ = passes;
  graphOuter_.assign(K.outerIndexPtr(), K.outerIndexPtr() + n + 1);
  graphInner_.assign(K.innerIndexPtr(), K.innerIndexPtr() + K.nonZeros());
  // K is symmetric: its columns are the rows' neighbour lists. Each pass aggregates the
  // last pass's aggregates over their own graph.
  std::vector<int> outer = graphOuter_, inner = graphInner_;
  aggregateOf_.resize(n);
  std::iota(aggregateOf_.begin(), aggregateOf_.end(), 0);
  int size = n;
  for (int pass = 0; pass < passes; ++pass) {
    std::vector<int> level;
    const int count = aggregatePass(size, outer.data(), inner.data(), level);
    for (int& a : aggregateOf_) a = level[a];
    if (pass + 1 < passes) {
      std::vector<int> coarseOuter, coarseInner;
      coarseGraph(size, outer.data(), inner.data(), level, count, coarseOuter, coarseInner);
      outer.swap(coarseOuter);
      inner.swap(coarseInner);
    }
    size = count;
  }
  numAggregates_ = size;
  // the patterns of A Z (n x m; a column's rows in the order met) and of E's lower
  // triangle (m x m), and where each entry of A adds into them: one pass over A per
  // aggregate's members, with a mark per row (O(nnz))
  const int* kOuter = K.outerIndexPtr();
  const int* kInner = K.innerIndexPtr();
  std::vector<int> memberStart(numAggregates_ + 1, 0), members(n);
  for (int j = 0; j < n; ++j) ++memberStart[aggregateOf_[j] + 1];
  std::partial_sum(memberStart.begin(), memberStart.end(), memberStart.begin());
  {
    std::vector<int> next(memberStart.begin(), memberStart.end() - 1);
    for (int j = 0; j < n; ++j) members[next[aggregateOf_[j]]++] = j;
  }
  azSlot_.assign(K.nonZeros(), -1);
  eSlot_.assign(K.nonZeros(), -1);
  azOuter_.assign(1, 0);
  azRow_.clear();
  azRow_.reserve(K.nonZeros());
  std::vector<int> mark(std::max(n, numAggregates_), -1), place(std::max(n, numAggregates_));
  std::vector<Eigen::Triplet<double>> eEntries;
  for (int b = 0; b < numAggregates_; ++b) {
    for (int q = memberStart[b]; q < memberStart[b + 1]; ++q) {
      const int j = members[q];
      for (int p = kOuter[j]; p < kOuter[j + 1]; ++p) {
        const int i = kInner[p];
        if (mark[i] != b) {
          mark[i] = b;
          place[i] = static_cast<int>(azRow_.size());
          azRow_.push_back(i);
        }
        azSlot_[p] = place[i];
      }
    }
    azOuter_.push_back(static_cast<int>(azRow_.size()));
  }
  // E's columns: the aggregates at or below the diagonal that a row of A Z's column b is in
  std::fill(mark.begin(), mark.end(), -1);
  for (int b = 0; b < numAggregates_; ++b) {
    eEntries.emplace_back(b, b, 0.0);
    mark[b] = b;
    for (int q = azOuter_[b]; q < azOuter_[b + 1]; ++q) {
      const int a = aggregateOf_[azRow_[q]];
      if (a > b && mark[a] != b) {
        mark[a] = b;
        eEntries.emplace_back(a, b, 0.0);
      }
    }
  }
  e_.resize(numAggregates_, numAggregates_);
  e_.setFromTriplets(eEntries.begin(), eEntries.end());
  eDiagonal_.resize(numAggregates_);
  for (int b = 0; b < numAggregates_; ++b) {
    for (int q = e_.outerIndexPtr()[b]; q < e_.outerIndexPtr()[b + 1]; ++q)
      place[e_.innerIndexPtr()[q]] = q;
    eDiagonal_[b] = place[b];
    for (int q = memberStart[b]; q < memberStart[b + 1]; ++q) {
      const int j = members[q];
      for (int p = kOuter[j]; p < kOuter[j + 1]; ++p) {
        const int a = aggregateOf_[kInner[p]];
        if (a >= b) eSlot_[p] = place[a];
      }
    }
  }
  azValue_.assign(azRow_.size(), 0.0);
  coarse_.analyzePattern(e_);
}

void TwoLevelPreconditioner::compute(const SparseMatrix& A, const std::vector<int>& excluded) {
  const int n = static_cast<int>(aggregateOf_.size());
  ESIM_VERIFY(A.rows() == n && A.cols() == n && A.nonZeros() == static_cast<long>(eSlot_.size()),
              "two-level preconditioner: the matrix is " + std::to_string(A.rows()) + " x " +
                  std::to_string(A.cols()) + " with " + std::to_string(A.nonZeros()) +
                  " entries, not the pattern of setGraph's (" + std::to_string(n) + " rows, " +
                  std::to_string(eSlot_.size()) + " entries)");
  ready_ = false;
  coarseOf_ = aggregateOf_;
  for (int i : excluded) {
    ESIM_VERIFY(i >= 0 && i < n, "two-level preconditioner: excluded row " + std::to_string(i) +
                                     " outside [0, " + std::to_string(n) + ")");
    coarseOf_[i] = -1;
  }
  // l1-Jacobi, A Z and E = Z' A Z over the rows kept, into setGraph's patterns
  smoother_.setZero(n);
  std::fill(azValue_.begin(), azValue_.end(), 0.0);
  std::fill(e_.valuePtr(), e_.valuePtr() + e_.nonZeros(), 0.0);
  std::vector<char> populated(numAggregates_, 0);
  const int* outer = A.outerIndexPtr();
  const int* inner = A.innerIndexPtr();
  const double* value = A.valuePtr();
  double* az = azValue_.data();
  double* e = e_.valuePtr();
  for (int j = 0; j < n; ++j) {
    const int aj = coarseOf_[j];
    if (aj >= 0) populated[aj] = 1;
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      const int i = inner[p];
      smoother_[i] += std::abs(value[p]);
      if (aj < 0) continue;
      az[azSlot_[p]] += value[p];
      if (coarseOf_[i] >= 0 && eSlot_[p] >= 0) e[eSlot_[p]] += value[p];
    }
  }
  for (int i = 0; i < n; ++i) {
    ESIM_VERIFY(smoother_[i] > 0 && std::isfinite(smoother_[i]),
                "two-level preconditioner: row " + std::to_string(i) + " of the matrix is " +
                    (smoother_[i] > 0 ? "not finite" : "empty"));
    smoother_[i] = 1.0 / smoother_[i];
  }
  for (int a = 0; a < numAggregates_; ++a)  // every row of an aggregate excluded: no column
    if (!populated[a]) e[eDiagonal_[a]] = 1.0;
  coarse_.factorize(e_);
  ESIM_RUN_CHECK(coarse_.info() == Eigen::Success && (coarse_.vectorD().array() > 0).all(),
                 "two-level preconditioner: the coarse matrix is not positive definite");
  coarseRhs_.resize(numAggregates_);
  ready_ = true;
}

double TwoLevelPreconditioner::memoryBytes() const {
  const double ints = static_cast<double>(
      graphOuter_.size() + graphInner_.size() + aggregateOf_.size() + coarseOf_.size() +
      azOuter_.size() + azRow_.size() + azSlot_.size() + eSlot_.size() + eDiagonal_.size());
  const double doubles =
      static_cast<double>(smoother_.size() + azValue_.size() + 3 * coarseRhs_.size());
  const double factor =
      ready_ ? static_cast<double>(coarse_.matrixL().nestedExpression().nonZeros()) : 0.0;
  return 4.0 * ints + 8.0 * doubles + 12.0 * (static_cast<double>(e_.nonZeros()) + factor);
}

// coarseRhs_ = Z' r: the sum of r over each aggregate's rows in the coarse space
void TwoLevelPreconditioner::restrictToCoarse(const Eigen::VectorXd& r) const {
  coarseRhs_.setZero();
  for (int i = 0; i < r.size(); ++i)
    if (coarseOf_[i] >= 0) coarseRhs_[coarseOf_[i]] += r[i];
}

// coarseRhs_ -= (A Z)' z
void TwoLevelPreconditioner::subtractAzTransposed(const Eigen::VectorXd& z) const {
  const int* outer = azOuter_.data();
  const int* inner = azRow_.data();
  const double* value = azValue_.data();
  for (int a = 0; a < numAggregates_; ++a) {
    double s = 0;
    for (int p = outer[a]; p < outer[a + 1]; ++p) s += value[p] * z[inner[p]];
    coarseRhs_[a] -= s;
  }
}

// z += Z w
void TwoLevelPreconditioner::prolongAdd(const Eigen::VectorXd& w, Eigen::VectorXd& z) const {
  for (int i = 0; i < z.size(); ++i)
    if (coarseOf_[i] >= 0) z[i] += w[coarseOf_[i]];
}

// M^-1 r = P' S P r + Q r with Q = Z E^-1 Z', P = I - A Q (balancing Neumann-Neumann):
// w = E^-1 Z' r, t = S (r - A Z w), v = E^-1 (A Z)' t, z = t + Z (w - v)
void TwoLevelPreconditioner::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  ESIM_CHECK(ready_ && r.size() == smoother_.size());
  restrictToCoarse(r);
  coarseW_ = coarse_.solve(coarseRhs_);
  z = r;
  const int* outer = azOuter_.data();
  const int* inner = azRow_.data();
  const double* value = azValue_.data();
  for (int a = 0; a < numAggregates_; ++a) {
    const double w = coarseW_[a];
    for (int p = outer[a]; p < outer[a + 1]; ++p) z[inner[p]] -= value[p] * w;
  }
  z.array() *= smoother_.array();
  coarseRhs_.setZero();
  subtractAzTransposed(z);                      // -(A Z)' t
  coarseSolution_ = coarse_.solve(coarseRhs_);  // -v
  coarseSolution_ += coarseW_;
  prolongAdd(coarseSolution_, z);
}

// A-DEF2: z = S r + Z E^-1 (Z' r - (A Z)' S r)
void TwoLevelPreconditioner::applyDeflated(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  ESIM_CHECK(ready_ && r.size() == smoother_.size());
  z = smoother_.cwiseProduct(r);
  restrictToCoarse(r);
  subtractAzTransposed(z);
  coarseSolution_ = coarse_.solve(coarseRhs_);
  prolongAdd(coarseSolution_, z);
}

void TwoLevelPreconditioner::deflate(const SparseMatrix& A, const Eigen::VectorXd& b,
                                     Eigen::VectorXd& x) const {
  ESIM_CHECK(ready_ && b.size() == smoother_.size() && x.size() == b.size() &&
             A.rows() == b.size());
  restrictToCoarse(b - A * x);
  coarseSolution_ = coarse_.solve(coarseRhs_);
  prolongAdd(coarseSolution_, x);
}

}  // namespace esim
