// electric_capacitance.cpp - one sparse factorization, cached inverse columns.
//
// Same algebra as the paper's dense inverse, without its n^2 memory:
//   pre-processing: K_ff = L L^T (CHOLMOD supernodal, METIS/AMD ordering);
//   per contact set c: z_i = K_ff^-1 e_i for every contact node (cached across
//   frames), the small SPD "capacitance" system Z_cc f = u_c, then u = Z_:c f
//   (one daxpy per column).
// Columns are solved in fixed blocks: a node is solved alone unless the caller gave
// contact candidates (setContactCandidates: the surface), which are grouped once per
// setMatrix into patches of up to capacitancePatchNodes neighbouring candidates
// (breadth-first over the graph of K, from the lowest id). Touching one node of a
// patch solves the whole patch in one pass over the factor (multi-right-hand-side
// BLAS 3, a few times the cost of one column for 16 of them), so the nodes the tool
// reaches next are usually cached already. A block's composition never depends on
// history, so every column has the same bits whoever asked for it first: results
// are bit-reproducible whatever the cache size, eviction or prefetching.
// The cache holds at most cacheMemoryLimitBytes of columns (never fewer than the
// current contact set needs); above it the least recently used column goes first
// (ties: the lower node id).
// prefetch() fills the cache ahead of contact (e.g. the contact nodes along a
// scripted tool path, at setup or a few frames ahead).
// setMatrix refactorizes and empties the cache (the patches are rebuilt).
#include <cblas.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>

#include "sim/core_error.h"
#include "sim/electric_solver.h"

namespace esim::electric_detail {
namespace {

class CapacitanceSolver final : public ElectricSolver {
 public:
  explicit CapacitanceSolver(const ElectricSolverOptions& options) : options_(options) {}

  void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) override {
    setBlasThreads(options_.threads);
    const ResetOnThrow guard(classes_);
    classes_.build(K, grounded);
    const int nf = classes_.numFree();
    columns_.clear();
    slotNode_.clear();
    lastUsed_.clear();
    slotOf_.assign(nf, -1);
    kff_ = SparseMatrix();
    if (nf == 0) return;
    kff_ = restrictToFree(K, classes_);
    factor_.analyze(kff_);
    factor_.factorize(kff_, "capacitance");
    buildPatches();
  }

  void setContactCandidates(const std::vector<int>& nodes) override {
    candidates_ = nodes;
    std::sort(candidates_.begin(), candidates_.end());
    candidates_.erase(std::unique(candidates_.begin(), candidates_.end()), candidates_.end());
    if (classes_.n > 0) {
      // new blocks: drop the cache so that every column keeps one block composition
      columns_.clear();
      slotNode_.clear();
      lastUsed_.clear();
      slotOf_.assign(classes_.numFree(), -1);
      buildPatches();
    }
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
    ++frame_;
    const int c = static_cast<int>(cf.size());
    const int nf = classes_.numFree();
    // 1. the columns of the contact nodes (cached ones marked used first: never evicted)
    for (int j : cf)
      if (slotOf_[j] >= 0) lastUsed_[slotOf_[j]] = frame_;
    std::vector<int> missing;
    for (int j : cf)
      if (slotOf_[j] < 0) missing.push_back(j);
    stats.newColumns = computeColumns(missing);
    std::vector<const double*> z(c);
    for (int k = 0; k < c; ++k) {
      lastUsed_[slotOf_[cf[k]]] = frame_;
      z[k] = columns_[slotOf_[cf[k]]].data();
    }
    // 2. the capacitance system Z_cc f = u_c
    Eigen::MatrixXd zcc(c, c);
    for (int k = 0; k < c; ++k)
      for (int i = 0; i < c; ++i) zcc(i, k) = z[k][cf[i]];
    Eigen::LLT<Eigen::MatrixXd> llt(zcc);
    ESIM_VERIFY(llt.info() == Eigen::Success, "capacitance: Z_cc is not positive definite");
    const Eigen::VectorXd f = llt.solve(Eigen::VectorXd::Constant(c, voltageV));
    // 3. u = Z f
    Eigen::VectorXd u = Eigen::VectorXd::Zero(nf);
    for (int k = 0; k < c; ++k) cblas_daxpy(nf, f[k], z[k], 1, u.data(), 1);
    scatterPotential(classes_, u, cf, voltageV, potential);
    return stats;
  }

  void prefetch(const std::vector<int>& nodes) override {
    if (classes_.n == 0 || classes_.numFree() == 0) return;
    setBlasThreads(options_.threads);
    std::vector<int> missing;
    for (int node : nodes) {
      if (node < 0 || node >= classes_.n) continue;
      const int j = classes_.freeIndex[node];
      if (j >= 0 && slotOf_[j] < 0) missing.push_back(j);
    }
    std::sort(missing.begin(), missing.end());
    missing.erase(std::unique(missing.begin(), missing.end()), missing.end());
    ++frame_;                             // prefetched columns count as used now
    computeColumns(missing, maxSlots());  // never more than the cache holds
  }

  double memoryBytes() const override {
    double bytes = factor_.memoryBytes() + 12.0 * static_cast<double>(kff_.nonZeros());
    for (const auto& col : columns_) bytes += 8.0 * static_cast<double>(col.size());
    return bytes;
  }
  const char* name() const override { return "capacitance"; }

 private:
  size_t maxSlots() const {
    const double columnBytes = 8.0 * std::max(1, classes_.numFree());
    return static_cast<size_t>(
        std::max(1.0, std::floor(options_.cacheMemoryLimitBytes / columnBytes)));
  }

  // patches of up to capacitancePatchNodes candidate nodes, grown breadth-first over
  // the graph of K_ff from the lowest unassigned candidate
  void buildPatches() {
    const int nf = classes_.numFree();
    patchOf_.assign(nf, -1);
    patches_.clear();
    const int maxNodes = std::max(1, options_.capacitancePatchNodes);
    std::vector<std::uint8_t> isCandidate(nf, 0);
    std::vector<int> cand;
    for (int node : candidates_) {
      if (node < 0 || node >= classes_.n) continue;
      const int j = classes_.freeIndex[node];
      if (j >= 0) {
        isCandidate[j] = 1;
        cand.push_back(j);
      }
    }
    for (int seed : cand) {
      if (patchOf_[seed] >= 0) continue;
      std::vector<int> patch{seed};
      patchOf_[seed] = static_cast<int>(patches_.size());
      for (size_t head = 0; head < patch.size() && static_cast<int>(patch.size()) < maxNodes;
           ++head) {
        for (SparseMatrix::InnerIterator it(kff_, patch[head]); it; ++it) {
          const int i = static_cast<int>(it.row());
          if (!isCandidate[i] || patchOf_[i] >= 0) continue;
          patchOf_[i] = static_cast<int>(patches_.size());
          patch.push_back(i);
          if (static_cast<int>(patch.size()) >= maxNodes) break;
        }
      }
      std::sort(patch.begin(), patch.end());
      patches_.push_back(std::move(patch));
    }
  }

  // a free slot, or the least recently used one not used by the current frame (ties:
  // the lower node id), or a new slot (the cap yields to the current contact set)
  int acquireSlot() {
    if (columns_.size() >= maxSlots()) {
      int slot = -1;
      long best = std::numeric_limits<long>::max();
      for (size_t s = 0; s < columns_.size(); ++s) {
        if (slotNode_[s] < 0) return static_cast<int>(s);
        if (lastUsed_[s] >= frame_) continue;
        if (lastUsed_[s] < best || (lastUsed_[s] == best && slotNode_[s] < slotNode_[slot])) {
          best = lastUsed_[s];
          slot = static_cast<int>(s);
        }
      }
      if (slot >= 0) {
        slotOf_[slotNode_[slot]] = -1;
        slotNode_[slot] = -1;
        return slot;
      }
    }
    columns_.emplace_back(classes_.numFree());
    slotNode_.push_back(-1);
    lastUsed_.push_back(0);
    return static_cast<int>(columns_.size()) - 1;
  }

  // solves the blocks (patches or single nodes) holding the given free indices and
  // caches their columns; returns the number of columns solved
  // (at most budget columns, if given)
  int computeColumns(const std::vector<int>& missing,
                     size_t budget = std::numeric_limits<size_t>::max()) {
    const int nf = classes_.numFree();
    int solved = 0;
    for (int j : missing) {
      if (slotOf_[j] >= 0) continue;  // came with an earlier patch
      checkInterrupt();               // a prefetch of many patches stops between two
      std::vector<int> block{j};
      if (patchOf_[j] >= 0) block = patches_[patchOf_[j]];
      const int cols = static_cast<int>(block.size());
      if (static_cast<size_t>(solved + cols) > budget) break;
      rhs_.setZero(nf, cols);
      for (int k = 0; k < cols; ++k) rhs_(block[k], k) = 1.0;
      block_.resize(nf, cols);
      factor_.solve(rhs_.data(), block_.data(), cols);
      solved += cols;
      for (int k = 0; k < cols; ++k) {
        const int i = block[k];
        int slot = slotOf_[i];
        if (slot < 0) slot = acquireSlot();
        columns_[slot] = block_.col(k);
        slotNode_[slot] = i;
        slotOf_[i] = slot;
        lastUsed_[slot] = frame_;
      }
    }
    return solved;
  }

  ElectricSolverOptions options_;
  NodeClasses classes_;
  SparseMatrix kff_;  // K restricted to the free nodes (patch graph)
  CholmodFactor factor_;
  std::vector<int> candidates_;            // node ids the tool may touch (sorted)
  std::vector<int> patchOf_;               // free index -> patch (-1: solved alone)
  std::vector<std::vector<int>> patches_;  // sorted free indices per patch
  std::vector<Eigen::VectorXd> columns_;   // cached K_ff^-1 e_j
  std::vector<int> slotNode_;              // slot -> free index j (-1: empty)
  std::vector<long> lastUsed_;             // slot -> frame of last use
  std::vector<int> slotOf_;                // free index -> slot (-1: not cached)
  Eigen::MatrixXd rhs_, block_;            // identity columns and their solutions
  long frame_ = 0;
};

}  // namespace

std::unique_ptr<ElectricSolver> makeCapacitanceSolver(const ElectricSolverOptions& options) {
  return std::make_unique<CapacitanceSolver>(options);
}

}  // namespace esim::electric_detail
