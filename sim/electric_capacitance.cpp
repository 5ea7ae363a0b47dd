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
// are bit-reproducible whatever the cache size, eviction or prefetching (after an
// updateMatrix, to round-off only: a column evicted and solved again with the Woodbury
// term and one kept and corrected from the log differ in the last bits, ~1e-16 relative;
// with the same cache size, runs stay bit-identical).
// The cache holds at most cacheMemoryLimitBytes of columns (never fewer than the
// current contact set needs); above it the least recently used column goes first
// (ties: the lower node id). limitCache lowers that cap later and evicts at once.
// prefetch() fills the cache ahead of contact (e.g. the contact nodes along a
// scripted tool path, at setup or a few frames ahead).
// setMatrix refactorizes and empties the cache (the patches are rebuilt).
//
// updateMatrix (a cut, issue #11), in the base indices of the last setMatrix (nodes that
// stop being free keep their index with an identity row and column). E = K' - K is
// supported on a few rows S (the nodes of the removed elements, the nodes leaving the
// free set):
//   1. the factor, two ways (ElectricSolverOptions::capacitanceUpdate):
//      Woodbury (default): the supernodal factor of K0 (the matrix last factorized) is
//        kept; with E0 = K' - K0 on the accumulated rows S0 (s0 of them),
//          K'^-1 b = x - Y0 M x_S0,  x = K0^-1 b,  Y0 = K0^-1 I_:S0,
//          M = E0 (I + Y0_S0 E0)^-1  (s0 x s0, one LU per update),
//        so an update costs one supernodal block solve for the new rows of S0 and an
//        s0^3 LU, and every later solve 2 n_f s0 flops more. When that exceeds half of a
//        solve (2 n_f s0 > 2 nnz(L)) the factor is recomputed numerically with the kept
//        ordering (stats.refactored; no symbolic analysis; the cached columns are then
//        corrected only if the s solves for Y pay, else dropped).
//      Downdate: rows leaving the free set are deleted (cholmod_rowdel), then E on the
//        rows staying free, split by an eigendecomposition into C+ C+^T - C- C-^T (a
//        removal is negative semidefinite: C+ is empty up to rounding), is applied by
//        cholmod_updown. CHOLMOD modifies only a simplicial LDL' factor: the supernodal
//        one is converted at the first update, and its column solves are 1.6-2.6x
//        slower (measured: esim bench electric --only-update, 8k-50k nodes; the
//        Woodbury solves cost the same as a fresh factor's), which is why this is not
//        the default. Its updates were also 1.5-2.5x slower than Woodbury's.
//      Afterwards Y = K'^-1 I_:S (S: the changed rows staying free; Woodbury: from Y0
//      without a solve) must satisfy ||K' Y - I||_F / sqrt(s) <= 1e-10
//      (ElectricSolverOptions::updateResidual; and, Downdate, every pivot > 0).
//      Woodbury: else Y takes one step of iterative refinement (s solves with the same
//      operator), and so does every later solve with this term (stats.refined), until the
//      next factor replaces the term, when its s solves cost under half a factorization
//      (kRefineShare); the factor is recomputed in the frame when they cost more, or if the
//      refined Y still misses. Downdate: else setMatrix.
//   2. cached columns: z = K^-1 e_j gives K' z = e_j + E z, so
//        z' = K'^-1 e_j = z - K'^-1 (E z) = z - Y (E z)_S,   Y = K'^-1 I_:S
//      (S: the rows of E staying free; rows leaving the free set give z'_D = 0). Y from
//      step 1 (when a refactorization left none, only if its s solves cost less than
//      kCorrectionShare of solving the cache again; else the cache is dropped). The
//      update logs (S, Y, E_S) and each cached column is corrected on its next use, by
//      the corrections it has not seen (2 n_f s flops each, against 4 nnz(L) to solve it
//      again): a cut corrects the few columns the tool comes back to, not the whole cache
//      (measured: the path's prefetched columns made the eager correction of every
//      column the electric update's largest part). The log is trimmed of corrections
//      every column has seen; above a quarter of the cache's memory the columns still
//      behind go instead (solved again if the tool returns).
//   3. patches: kept; setContactCandidates with the new surface adds patches for the new
//      candidates and keeps the cache; prefetch their columns outside the frame loop.
// After an update, a column corrected in place and one solved with the updated factor
// agree to rounding, not to the bit: results stay deterministic for a given sequence of
// calls, but no longer independent of cache size and eviction.
#include <cblas.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <deque>
#include <future>
#include <limits>
#include <memory>

#include "sim/core_error.h"
#include "sim/electric_solver.h"

namespace esim::electric_detail {
namespace {

// columns are corrected in place when that costs less than this share of solving them
// again (the share of the cache the tool still needs is unknown; see the header)
constexpr double kCorrectionShare = 0.5;
// an update is done in place while the solves for its new rows of S (4 nnz(L) flops
// each) cost less than kRefactorShare of a numeric factorization (CHOLMOD's flop count)
// or kMinRefactorFlops; above, Woodbury refactorizes numerically (same ordering) and
// Downdate does setMatrix. Measured (esim bench electric --only-update --update-tets
// 5,50,200, 20k and 50k nodes, Woodbury, shared machine): in place is 2.5-6x faster than
// setMatrix at 5 tets (s ~ 9), about even at 50 tets at 20k (s ~ 30, the cache
// correction dominating), slower beyond; these solves alone reach one factorization at
// s ~ 70-85. The cached columns are corrected only when that is cheaper than solving
// them again (kCorrectionShare), whatever the factor did.
constexpr double kRefactorShare = 1.0;
constexpr double kMinRefactorFlops = 5e7;
// Woodbury: the term is also folded into a numeric refactorization when it costs more
// than this share of a solve with the factor (2 n_f s0 flops vs 4 nnz(L) per column), or
// above kMaxWoodburyRows rows
constexpr double kWoodburyShare = 0.5;
constexpr int kMaxWoodburyRows = 1024;
// ... and at this share of that limit the next factor is computed on a thread
constexpr double kNextFactorShare = 0.5;
// ... and adopted by the first update at least this many solves after it started. Adopted
// by the very next update, it was waited for at two removals in consecutive frames: 3 ms of
// a 1013-node frame (esim bench cut --sizes 1013 --strategy update --stages, temporary
// instrumentation), the structural update sharing its core
constexpr int kAdoptAfterSolves = 2;
// A term that misses the accuracy check is refined (one step, s solves, see refine_) when
// those cost less than this share of a factorization's flops, else refactorized. Measured
// (esim bench cut --strategy update --stages, temporary instrumentation): at 8000 nodes the
// misses had s = 8-56 rows (0.16-1.1 of a factorization's flops), refined in 17-79 ms each
// against 100-270 ms for a refactorization in the frame; at 20 000 nodes s = 45-93 (0.85-0.95
// for s = 72-81), 50-290 ms against ~250 ms, and the term, refined every time, kept missing
// (residuals to 3.5e-8). Refining every miss, two alternating pairs each against no
// refinement: --sizes 8000 --frames 60 electric update p95 84-103 against 139-202 ms;
// --sizes 20000 --frames 40 median 231-258 against 133-156 ms (worse); refining a term once
// and refactorizing its next miss: worse at 20 000 nodes still (median 278-306 against
// 144-168 ms)
constexpr double kRefineShare = 0.5;

class CapacitanceSolver final : public ElectricSolver {
 public:
  explicit CapacitanceSolver(const ElectricSolverOptions& options) : options_(options) {}

  void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) override {
    dropNextFactor();  // of a matrix this one replaces
    setBlasThreads(options_.threads);
    const ResetOnThrow guard(free_.current);
    free_.set(K, grounded);
    const int nf = free_.size();
    columns_.clear();
    slotNode_.clear();
    lastUsed_.clear();
    slotVersion_.clear();
    clearLog();
    slotOf_.assign(nf, -1);
    patchOf_.assign(nf, -1);
    patches_.clear();
    if (nf == 0) return;
    factor_.analyze(free_.matrix);
    refactorNumeric();
    buildPatches();
  }

  ElectricUpdateStats updateMatrix(const SparseMatrix& K, const std::vector<int>& grounded,
                                   const std::vector<int>* changedNodes) override {
    ESIM_CHECK(free_.current.n > 0);  // setMatrix before updateMatrix
    const ResetOnThrow guard(free_.current);
    const BaseChange change = free_.diff(K, grounded, changedNodes);
    ElectricUpdateStats stats;
    const auto fallBack = [&](const std::string& why) {
      const int cached = cachedColumns();
      setMatrix(K, grounded);
      stats.fellBack = true;
      stats.fallbackReason = why;
      stats.columnsDropped = cached;
      stats.rank = 0;
      stats.refactored = false;
      stats.columnsCorrected = 0;
      return stats;
    };
    if (!change.fallback.empty()) return fallBack(change.fallback);
    stats.changedNodes = static_cast<int>(change.touched.size());
    stats.droppedNodes = static_cast<int>(change.dropped.size());
    if (change.empty()) return stats;
    const int nf = free_.size();
    const bool downdate = options_.capacitanceUpdate == CapacitanceUpdate::Downdate;
    if (downdate && rowSolveFlops(change.touched.size() + change.dropped.size()) > refactorFlops())
      return fallBack(std::to_string(change.touched.size() + change.dropped.size()) +
                      " rows change: a new factorization is cheaper");
    setBlasThreads(options_.threads);
    std::vector<int> rows;
    Eigen::MatrixXd y;
    // 1. the factor
    try {
      if (downdate) {
        for (int d : change.dropped) factor_.deleteRow(d);
        stats.rank = modifyFactor(change);
        free_.apply(change);
        if (!factor_.pivotsPositive())
          return fallBack("the downdate lost positive definiteness (a pivot <= 0)");
      } else {
        // the next factor is adopted once due (kAdoptAfterSolves), or when the term
        // would outgrow its limit (extendWoodbury), never merely because it is done:
        // which factor a solve uses depends on the calls, not on the thread's timing
        std::vector<int> carried;
        if (nextFactor_.valid() && solvesSinceNextFactor_ >= kAdoptAfterSolves)
          stats.adoptedFactor = adoptNextFactor(carried);
        free_.apply(change);
        stats.rank = extendWoodbury(change, carried, stats);
      }
      // Y = K'^-1 I_:S on the rows S of E staying free: checks the update along the
      // directions it changed, then corrects the cached columns
      // (a new numeric factorization needs no check)
      rows = stayingRows(change);
      if (!stats.refactored) {
        y = inverseColumns(rows);
        double residual = free_.identityResidual(rows, y);
        if (!(residual <= options_.updateResidual) && !downdate &&
            rowSolveFlops(rows.size()) <= kRefineShare * factor_.factorizeFlops()) {
          // one step of iterative refinement, here and in every later solve with this term
          // (see refine_), where it costs less than a refactorization in the frame
          refine_ = true;
          stats.refined = true;
          refineIdentity(rows, y);
          residual = free_.identityResidual(rows, y);
        }
        if (!(residual <= options_.updateResidual)) {
          if (downdate)
            return fallBack("the updated factor solves to a residual of " +
                            messageNumber(residual));
          refactorNumeric();
          stats.refactored = true;
          y.resize(0, 0);
        }
      }
      // 2. the cached columns (after a refactorization Y costs s solves: only if it pays)
      const double entries = factor_.factorEntries(), cached = cachedColumns();
      if (y.cols() != static_cast<int>(rows.size()) &&
          4.0 * entries * rows.size() + 2.0 * nf * rows.size() * cached <
              kCorrectionShare * 4.0 * entries * cached)
        y = inverseColumns(rows);
    } catch (const Error& e) {
      if (e.kind() == ErrorKind::Internal) throw;
      return fallBack(std::string("the factor update failed: ") + e.what());
    }
    correctColumns(change, rows, std::move(y), stats);
    if (!downdate) startNextFactor();
    return stats;
  }

  void setContactCandidates(const std::vector<int>& nodes) override {
    candidates_ = nodes;
    std::sort(candidates_.begin(), candidates_.end());
    candidates_.erase(std::unique(candidates_.begin(), candidates_.end()), candidates_.end());
    // after setMatrix: existing patches and the cache stay, new candidates get patches
    if (free_.current.n > 0) buildPatches();
  }

  ElectricSolveStats solve(const std::vector<int>& contact, double voltageV,
                           Eigen::VectorXd& potential) override {
    if (nextFactor_.valid()) ++solvesSinceNextFactor_;
    ElectricSolveStats stats;
    const std::vector<int> cf = free_.contactsOrZero(contact, potential);
    if (cf.empty()) return stats;
    setBlasThreads(options_.threads);
    ++frame_;
    const int c = static_cast<int>(cf.size());
    const int nf = free_.size();
    // 1. the columns of the contact nodes (cached ones marked used first: never evicted)
    for (int j : cf)
      if (slotOf_[j] >= 0) lastUsed_[slotOf_[j]] = frame_;
    std::vector<int> missing;
    for (int j : cf)
      if (slotOf_[j] < 0) missing.push_back(j);
    stats.newColumns = computeColumns(missing);
    std::vector<const double*> z(c);
    std::vector<int> behind;  // slots missing logged corrections
    for (int k = 0; k < c; ++k) {
      const int slot = slotOf_[cf[k]];
      lastUsed_[slot] = frame_;
      if (slotVersion_[slot] < version_) behind.push_back(slot);
      z[k] = columns_[slot].data();
    }
    bringUpToDate(behind);
    // 2. the capacitance system Z_cc f = u_c, then u = Z f
    Eigen::VectorXd u;
    combineColumns(z, cf, voltageV, nf, "capacitance", u);
    free_.scatter(u, cf, voltageV, potential);
    return stats;
  }

  void prefetch(const std::vector<int>& nodes) override {
    if (free_.current.n == 0 || free_.current.numFree() == 0) return;
    setBlasThreads(options_.threads);
    std::vector<int> missing;
    for (int node : nodes) {
      if (node < 0 || node >= free_.current.n || free_.current.freeIndex[node] < 0) continue;
      const int j = free_.base.freeIndex[node];
      if (slotOf_[j] < 0) missing.push_back(j);
    }
    std::sort(missing.begin(), missing.end());
    missing.erase(std::unique(missing.begin(), missing.end()), missing.end());
    ++frame_;                             // prefetched columns count as used now
    computeColumns(missing, maxSlots());  // never more than the cache holds
  }

  double memoryBytes() const override {
    double bytes = factor_.memoryBytes() + 20.0 * static_cast<double>(free_.matrix.nonZeros()) +
                   8.0 * static_cast<double>(y0_.size() + m_.size() + stale_.size());
    for (const auto& col : columns_) bytes += 8.0 * static_cast<double>(col.size());
    for (const Correction& c : log_) bytes += 8.0 * static_cast<double>(c.y.size());
    return bytes;
  }
  const char* name() const override { return "capacitance"; }

  double limitCache(double bytes) override {
    options_.cacheMemoryLimitBytes = std::max(bytes, 8.0 * std::max(1, free_.size()));
    const size_t keep = maxSlots();
    // the occupied slots, most recently used first (ties: the lower node id), as acquireSlot
    // evicts them
    std::vector<int> order;
    for (size_t slot = 0; slot < columns_.size(); ++slot)
      if (slotNode_[slot] >= 0) order.push_back(static_cast<int>(slot));
    if (order.size() <= keep && columns_.size() <= keep) return 0;
    std::sort(order.begin(), order.end(), [this](int a, int b) {
      return lastUsed_[a] != lastUsed_[b] ? lastUsed_[a] > lastUsed_[b]
                                          : slotNode_[a] < slotNode_[b];
    });
    if (order.size() > keep) order.resize(keep);
    std::sort(order.begin(), order.end());  // the kept slots in their old order
    const double before = 8.0 * static_cast<double>(columns_.size()) * free_.size();
    std::vector<Eigen::VectorXd> columns;
    std::vector<int> slotNode;
    std::vector<long> lastUsed, slotVersion;
    std::fill(slotOf_.begin(), slotOf_.end(), -1);
    for (int slot : order) {
      slotOf_[slotNode_[slot]] = static_cast<int>(columns.size());
      columns.push_back(std::move(columns_[slot]));
      slotNode.push_back(slotNode_[slot]);
      lastUsed.push_back(lastUsed_[slot]);
      slotVersion.push_back(slotVersion_[slot]);
    }
    columns_ = std::move(columns);
    slotNode_ = std::move(slotNode);
    lastUsed_ = std::move(lastUsed);
    slotVersion_ = std::move(slotVersion);
    trimLog();  // its budget is a quarter of the cache's
    return before - 8.0 * static_cast<double>(columns_.size()) * free_.size();
  }

 private:
  size_t maxSlots() const {
    const double columnBytes = 8.0 * std::max(1, free_.size());
    return static_cast<size_t>(
        std::max(1.0, std::floor(options_.cacheMemoryLimitBytes / columnBytes)));
  }

  int cachedColumns() const {
    int count = 0;
    for (int node : slotNode_) count += node >= 0;
    return count;
  }

  // patches of up to capacitancePatchNodes candidate nodes still free and in no patch,
  // grown breadth-first over the graph of K_ff from the lowest unassigned candidate
  // (setMatrix clears the patches first; later calls only add patches)
  void buildPatches() {
    const int maxNodes = std::max(1, options_.capacitancePatchNodes);
    const SparseMatrix& kff = free_.matrix;
    std::vector<std::uint8_t> isCandidate(free_.size(), 0);
    std::vector<int> cand;
    for (int node : candidates_) {
      if (node < 0 || node >= free_.current.n || free_.current.freeIndex[node] < 0) continue;
      const int j = free_.base.freeIndex[node];
      if (patchOf_[j] < 0) {
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
        for (SparseMatrix::InnerIterator it(kff, patch[head]); it; ++it) {
          const int i = static_cast<int>(it.row());
          if (!isCandidate[i] || patchOf_[i] >= 0 || it.value() == 0.0) continue;
          patchOf_[i] = static_cast<int>(patches_.size());
          patch.push_back(i);
          if (static_cast<int>(patch.size()) >= maxNodes) break;
        }
      }
      std::sort(patch.begin(), patch.end());
      patches_.push_back(std::move(patch));
    }
  }

  // flops of solving for s unit right-hand sides
  double rowSolveFlops(size_t s) const {
    return 4.0 * factor_.factorEntries() * static_cast<double>(s);
  }

  // the in-place budget (see kRefactorShare)
  double refactorFlops() const {
    return std::max(kRefactorShare * factor_.factorizeFlops(), kMinRefactorFlops);
  }

  // ---- the Woodbury term (see the file comment) ----

  // factorizes the current matrix with the kept ordering; the Woodbury term is emptied
  void refactorNumeric() {
    dropNextFactor();  // of an older matrix
    factor_.factorize(free_.matrix, "capacitance");
    factoredValues_.assign(free_.matrix.valuePtr(),
                           free_.matrix.valuePtr() + free_.matrix.nonZeros());
    refine_ = false;
    woodburyRows_.clear();
    woodburyPos_.assign(free_.size(), -1);
    y0_.resize(free_.size(), 0);
    m_.resize(0, 0);
  }

  // the most rows S0 may hold before the term is folded into a refactorization
  double woodburyLimit() const {
    return std::min<double>(kMaxWoodburyRows, kWoodburyShare * 4.0 * factor_.factorEntries() /
                                                  (2.0 * std::max(1, free_.size())));
  }

  // Once the term holds kNextFactorShare of its limit, the current matrix K_k is factorized
  // on a thread (its own CHOLMOD workspace, a copy of K_k). The first update at least
  // kAdoptAfterSolves solves later, or the first whose term would pass its limit, adopts it
  // (waiting if it is not done: the update it happens in is fixed by the calls, so runs
  // stay reproducible) with K_k as K0 and a term on the rows changed since K_k, so the term
  // rarely reaches its limit and the frame loop no longer pays a numeric refactorization
  // (measured: the 4-9 ms removal frames at 1k nodes, the electric update's p95 at 8k).
  void startNextFactor() {
    if (nextFactor_.valid() || free_.size() == 0 ||
        static_cast<double>(woodburyRows_.size()) < kNextFactorShare * woodburyLimit())
      return;
    nextValues_.assign(free_.matrix.valuePtr(), free_.matrix.valuePtr() + free_.matrix.nonZeros());
    solvesSinceNextFactor_ = 0;
    rowsSinceNextFactor_.clear();
    nextFactor_ =
        std::async(std::launch::async, [k = SparseMatrix(free_.matrix), threads = options_.threads,
                                        ordering = factor_.ordering()] {
          deprioritizeThisThread();
          setBlasThreads(threads);
          auto f = std::make_unique<CholmodFactor>();
          f->analyze(k, ordering);  // the same pattern: no new ordering
          f->factorize(k, "capacitance");
          return f;
        });
  }

  // the factor started by startNextFactor becomes K0, with an empty term; `carried` gets
  // the rows changed since (they start the new term). False: none, or it failed: the
  // current factor and term go on.
  bool adoptNextFactor(std::vector<int>& carried) {
    carried.clear();
    if (!nextFactor_.valid()) return false;
    std::unique_ptr<CholmodFactor> f;
    try {
      f = nextFactor_.get();
    } catch (const Error& e) {
      if (e.kind() == ErrorKind::Internal) throw;
      return false;
    }
    factor_.swap(*f);
    factoredValues_.swap(nextValues_);
    carried.swap(rowsSinceNextFactor_);
    refine_ = false;
    woodburyRows_.clear();
    woodburyPos_.assign(free_.size(), -1);
    y0_.resize(free_.size(), 0);
    m_.resize(0, 0);
    return true;
  }

  void dropNextFactor() {
    if (!nextFactor_.valid()) return;
    try {
      nextFactor_.get();
    } catch (const Error&) {
    }
  }

  // adds the rows of this change and the rows `carried` over from before an adopted
  // factor to S0 (one block solve for the new ones) and recomputes M; a term that would
  // outgrow its limit first adopts the next factor if there is one, else everything is
  // folded into a numeric refactorization. Returns the rows of the change.
  int extendWoodbury(const BaseChange& change, std::vector<int> carried,
                     ElectricUpdateStats& stats) {
    const int nf = free_.size();
    std::vector<int> rows, fresh;
    std::vector<std::uint8_t> seen(nf, 0);
    for (int j = 0; j < nf; ++j)
      for (SparseMatrix::InnerIterator it(change.delta, j); it; ++it) seen[it.row()] = 1;
    for (int i = 0; i < nf; ++i)
      if (seen[i]) rows.push_back(i);
    const auto freshRows = [&] {
      std::vector<std::uint8_t> in(seen);
      for (int i : carried) in[i] = 1;
      fresh.clear();
      for (int i = 0; i < nf; ++i)
        if (in[i] && woodburyPos_[i] < 0) fresh.push_back(i);
      return static_cast<int>(woodburyRows_.size() + fresh.size());
    };
    int s0 = freshRows();
    const double limit = woodburyLimit();
    if (s0 > limit && nextFactor_.valid() && adoptNextFactor(carried)) {
      stats.adoptedFactor = true;
      s0 = freshRows();
    }
    if (s0 > limit || rowSolveFlops(fresh.size()) > refactorFlops()) {
      refactorNumeric();
      stats.refactored = true;
      return static_cast<int>(rows.size());
    }
    if (nextFactor_.valid())
      rowsSinceNextFactor_.insert(rowsSinceNextFactor_.end(), rows.begin(), rows.end());
    // Y0 for the new rows
    if (!fresh.empty()) {
      const int k = static_cast<int>(fresh.size());
      Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nf, k), y(nf, k);
      for (int c = 0; c < k; ++c) rhs(fresh[c], c) = 1.0;
      factor_.solve(rhs.data(), y.data(), k);
      y0_.conservativeResize(nf, s0);
      y0_.rightCols(k) = y;
      for (int i : fresh) {
        woodburyPos_[i] = static_cast<int>(woodburyRows_.size());
        woodburyRows_.push_back(i);
      }
    }
    // E0 = K' - K0 on S0 (every changed entry has its row and column in S0)
    const int* outer = free_.matrix.outerIndexPtr();
    const int* inner = free_.matrix.innerIndexPtr();
    const double* value = free_.matrix.valuePtr();
    Eigen::MatrixXd e0 = Eigen::MatrixXd::Zero(s0, s0), g0(s0, s0);
    for (int b = 0; b < s0; ++b) {
      const int j = woodburyRows_[b];
      for (int p = outer[j]; p < outer[j + 1]; ++p)
        if (woodburyPos_[inner[p]] >= 0)
          e0(woodburyPos_[inner[p]], b) = value[p] - factoredValues_[p];
      g0.row(b) = y0_.row(j);
    }
    // M = E0 (I + G0 E0)^-1, i.e. (I + G0 E0)^T M^T = E0
    const Eigen::MatrixXd t = Eigen::MatrixXd::Identity(s0, s0) + g0 * e0;
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(t.transpose());
    m_ = lu.solve(e0).transpose();
    ESIM_RUN_CHECK(m_.allFinite(), "capacitance: the Woodbury term is singular");
    return static_cast<int>(rows.size());
  }

  // x = K'^-1 b for `cols` right-hand sides: the factor's solve plus the Woodbury term,
  // then, while refine_, one step of iterative refinement with the same operator
  void solveBlock(const double* b, double* x, int cols) {
    woodburySolve(b, x, cols);
    if (!refine_) return;
    const int nf = free_.size();
    const Eigen::Map<const Eigen::MatrixXd> bm(b, nf, cols);
    Eigen::Map<Eigen::MatrixXd> xm(x, nf, cols);
    const Eigen::MatrixXd r = bm - free_.matrix * xm;
    Eigen::MatrixXd dx(nf, cols);
    woodburySolve(r.data(), dx.data(), cols);
    xm += dx;
  }

  // Y += W (I_:rows - K' Y), W the factor's solve plus the Woodbury term: one step of
  // iterative refinement of Y = K'^-1 I_:rows
  void refineIdentity(const std::vector<int>& rows, Eigen::MatrixXd& y) {
    const int s = static_cast<int>(rows.size());
    Eigen::MatrixXd r = -(free_.matrix * y), dy(free_.size(), s);
    for (int k = 0; k < s; ++k) r(rows[k], k) += 1.0;
    woodburySolve(r.data(), dy.data(), s);
    y += dy;
  }

  // the factor's solve plus the Woodbury term (see solveBlock)
  void woodburySolve(const double* b, double* x, int cols) {
    factor_.solve(b, x, cols);
    const int s0 = static_cast<int>(woodburyRows_.size());
    if (s0 == 0) return;
    const int nf = free_.size();
    Eigen::Map<Eigen::MatrixXd> xm(x, nf, cols);
    Eigen::MatrixXd xs(s0, cols);
    for (int a = 0; a < s0; ++a) xs.row(a) = xm.row(woodburyRows_[a]);
    const Eigen::MatrixXd w = m_ * xs;
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, nf, cols, s0, -1.0, y0_.data(), nf,
                w.data(), s0, 1.0, x, nf);
  }

  // applies E (on the rows staying free) to the factor: update by its positive part,
  // downdate by its negative part; returns the rank applied
  int modifyFactor(const BaseChange& change) {
    const std::vector<int>& rows = change.touched;
    const int s = static_cast<int>(rows.size());
    if (s == 0) return 0;
    std::vector<int> where(free_.size(), -1);
    for (int k = 0; k < s; ++k) where[rows[k]] = k;
    Eigen::MatrixXd e = Eigen::MatrixXd::Zero(s, s);
    for (int j : rows)
      for (SparseMatrix::InnerIterator it(change.delta, j); it; ++it)
        if (where[it.row()] >= 0) e(where[it.row()], where[j]) = it.value();
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(e);
    ESIM_RUN_CHECK(eig.info() == Eigen::Success, "capacitance: eigendecomposition failed");
    const Eigen::VectorXd& lambda = eig.eigenvalues();
    // eigenvalues at rounding level are dropped (a tet's matrix has rank 3, not 4)
    const double drop = 1e-13 * lambda.cwiseAbs().maxCoeff();
    int rank = 0;
    for (bool update : {true, false}) {
      std::vector<Eigen::Triplet<double>> t;
      int cols = 0;
      for (int k = 0; k < s; ++k) {
        const double l = update ? lambda[k] : -lambda[k];
        if (!(l > drop)) continue;
        const double scale = std::sqrt(l);
        for (int i = 0; i < s; ++i)
          if (eig.eigenvectors()(i, k) != 0.0)
            t.emplace_back(rows[i], cols, scale * eig.eigenvectors()(i, k));
        ++cols;
      }
      SparseMatrix c(free_.size(), cols);
      c.setFromTriplets(t.begin(), t.end());
      factor_.updateDowndate(update, c);
      rank += cols;
    }
    return rank;
  }

  // relative residual ||K' x - b|| / ||b|| of one solve with the modified factor
  // the base indices staying free with a changed row (ascending)
  std::vector<int> stayingRows(const BaseChange& change) const {
    const int nf = free_.size();
    std::vector<std::uint8_t> seen(nf, 0);
    for (int j = 0; j < nf; ++j)
      for (SparseMatrix::InnerIterator it(change.delta, j); it; ++it)
        if (free_.active[it.row()]) seen[it.row()] = 1;
    std::vector<int> rows;
    for (int i = 0; i < nf; ++i)
      if (seen[i]) rows.push_back(i);
    return rows;
  }

  // K'^-1 I_:rows; from Y0 without a solve when every row is in S0 (Woodbury)
  Eigen::MatrixXd inverseColumns(const std::vector<int>& rows) {
    const int nf = free_.size(), s = static_cast<int>(rows.size());
    Eigen::MatrixXd y(nf, s);
    bool inS0 = !woodburyRows_.empty();
    for (int i : rows) inS0 = inS0 && woodburyPos_[i] >= 0;
    if (inS0) {
      // x = K0^-1 I_:rows = Y0 columns; K'^-1 I_:rows = x - Y0 M x_S0
      const int s0 = static_cast<int>(woodburyRows_.size());
      Eigen::MatrixXd xs(s0, s);
      for (int k = 0; k < s; ++k) {
        y.col(k) = y0_.col(woodburyPos_[rows[k]]);
        for (int a = 0; a < s0; ++a) xs(a, k) = y0_(woodburyRows_[a], woodburyPos_[rows[k]]);
      }
      const Eigen::MatrixXd w = m_ * xs;
      cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, nf, s, s0, -1.0, y0_.data(), nf,
                  w.data(), s0, 1.0, y.data(), nf);
      return y;
    }
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nf, s);
    for (int k = 0; k < s; ++k) rhs(rows[k], k) = 1.0;
    solveBlock(rhs.data(), y.data(), s);
    return y;
  }

  // z' = z - Y (E z)_S for every cached column still free (see the file comment), on
  // each column's next use (bringUpToDate): the update logs (S, Y, E_S) and the columns
  // the tool never comes back to cost nothing. Drops the cache when y is not given (a
  // refactorization where Y did not pay); rows: S, y: K'^-1 I_:S
  void correctColumns(const BaseChange& change, const std::vector<int>& rows, Eigen::MatrixXd&& y,
                      ElectricUpdateStats& stats) {
    const int nf = free_.size();
    // columns of nodes leaving the free set go
    for (int d : change.dropped) {
      if (slotOf_[d] < 0) continue;
      slotNode_[slotOf_[d]] = -1;
      slotOf_[d] = -1;
      ++stats.columnsDropped;
    }
    const int cached = cachedColumns();
    if (cached == 0) {
      clearLog();
      return;
    }
    const int s = static_cast<int>(rows.size());
    if (y.cols() != s) {
      for (size_t slot = 0; slot < slotNode_.size(); ++slot)
        if (slotNode_[slot] >= 0) {
          slotOf_[slotNode_[slot]] = -1;
          slotNode_[slot] = -1;
        }
      stats.columnsDropped += cached;
      clearLog();
      return;
    }
    std::vector<int> where(nf, -1);
    for (int k = 0; k < s; ++k) where[rows[k]] = k;
    Correction c;
    c.y = std::move(y);
    c.dropped = change.dropped;
    for (int j = 0; j < nf; ++j)
      for (SparseMatrix::InnerIterator it(change.delta, j); it; ++it)
        if (where[it.row()] >= 0) c.entries.push_back({where[it.row()], j, it.value()});
    log_.push_back(std::move(c));
    ++version_;
    stats.columnsCorrected = cached;
    trimLog();
  }

  // applies the logged corrections the columns in these slots have not seen yet (each
  // slot's version), the columns together: each correction is one product Y R over the
  // columns behind it, so Y (n_f x s) is read once a correction rather than once a column.
  // Measured on liver_incision (esim run --frames 30 --no-video, 40-80 contact columns, two
  // alternating pairs against a matrix-vector product a column): solve_potential median
  // 35-38 against 80-89 ms; the frame loop no faster (19.3-20.0 against 20.0 s: the frames
  // wait for the structural update instead), the same 1965 tets removed.
  void bringUpToDate(std::vector<int> slots) {
    if (slots.empty()) return;
    // the columns furthest behind first: those needing a correction are then a prefix
    std::sort(slots.begin(), slots.end(), [this](int a, int b) {
      return slotVersion_[a] != slotVersion_[b] ? slotVersion_[a] < slotVersion_[b] : a < b;
    });
    const int nf = free_.size();
    const int m = static_cast<int>(slots.size());
    stale_.resize(nf, m);
    for (int i = 0; i < m; ++i) stale_.col(i) = columns_[slots[i]];
    int behind = 0;
    for (long v = slotVersion_[slots[0]]; v < version_; ++v) {
      while (behind < m && slotVersion_[slots[behind]] <= v) ++behind;
      const Correction& c = log_[static_cast<size_t>(v - logBase_)];
      const int s = static_cast<int>(c.y.cols());
      ESIM_CHECK(c.y.rows() == nf);
      Eigen::MatrixXd r = Eigen::MatrixXd::Zero(s, behind);  // (E Z)_S
      for (const CorrectionEntry& en : c.entries)
        for (int i = 0; i < behind; ++i) r(en.row, i) += en.value * stale_(en.col, i);
      if (s > 0)
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, nf, behind, s, -1.0, c.y.data(), nf,
                    r.data(), s, 1.0, stale_.data(), nf);
      for (int d : c.dropped) stale_.row(d).head(behind).setZero();
    }
    for (int i = 0; i < m; ++i) {
      columns_[slots[i]] = stale_.col(i);
      slotVersion_[slots[i]] = version_;
    }
  }

  // drops the logged corrections every cached column has seen; above the log's memory
  // budget (a quarter of the cache's), a cached column still behind is dropped (solved
  // again if the tool comes back) rather than corrected, oldest versions first
  void trimLog() {
    double bytes = 0;
    for (const Correction& c : log_) bytes += 8.0 * static_cast<double>(c.y.size());
    const double budget = 0.25 * options_.cacheMemoryLimitBytes;
    long oldest = version_;
    for (size_t slot = 0; slot < slotNode_.size(); ++slot)
      if (slotNode_[slot] >= 0) oldest = std::min(oldest, slotVersion_[slot]);
    while (!log_.empty() && (logBase_ < oldest || bytes > budget)) {
      if (logBase_ >= oldest)  // over budget: the columns still behind the oldest go
        for (size_t slot = 0; slot < slotNode_.size(); ++slot)
          if (slotNode_[slot] >= 0 && slotVersion_[slot] <= logBase_) {
            slotOf_[slotNode_[slot]] = -1;
            slotNode_[slot] = -1;
          }
      bytes -= 8.0 * static_cast<double>(log_.front().y.size());
      log_.pop_front();
      ++logBase_;
      oldest = std::max(oldest, logBase_);
    }
  }

  void clearLog() {
    log_.clear();
    logBase_ = version_;
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
    columns_.emplace_back(free_.size());
    slotNode_.push_back(-1);
    lastUsed_.push_back(0);
    slotVersion_.push_back(version_);
    return static_cast<int>(columns_.size()) - 1;
  }

  // solves the blocks (patches or single nodes) holding the given free indices and
  // caches their columns; returns the number of columns solved
  // (at most budget columns, if given)
  int computeColumns(const std::vector<int>& missing,
                     size_t budget = std::numeric_limits<size_t>::max()) {
    const int nf = free_.size();
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
      solveBlock(rhs_.data(), block_.data(), cols);
      solved += cols;
      for (int k = 0; k < cols; ++k) {
        const int i = block[k];
        if (!free_.active[i]) continue;  // left the free set: solved only to keep the block
        int slot = slotOf_[i];
        if (slot < 0) slot = acquireSlot();
        columns_[slot] = block_.col(k);
        slotVersion_[slot] = version_;  // solved with the current factor
        slotNode_[slot] = i;
        slotOf_[i] = slot;
        lastUsed_[slot] = frame_;
      }
    }
    return solved;
  }

  ElectricSolverOptions options_;
  FreeBase free_;  // node classes, K_ff in base indices (also the patch graph)
  CholmodFactor factor_;
  std::vector<int> candidates_;            // node ids the tool may touch (sorted)
  std::vector<int> patchOf_;               // free index -> patch (-1: solved alone)
  std::vector<std::vector<int>> patches_;  // sorted free indices per patch
  std::vector<Eigen::VectorXd> columns_;   // cached K_ff^-1 e_j
  std::vector<int> slotNode_;              // slot -> free index j (-1: empty)
  std::vector<long> lastUsed_;             // slot -> frame of last use
  std::vector<int> slotOf_;                // free index -> slot (-1: not cached)
  Eigen::MatrixXd rhs_, block_;            // identity columns and their solutions
  Eigen::MatrixXd stale_;                  // columns being corrected (bringUpToDate)
  // the Woodbury term: K'^-1 = K0^-1 - Y0 M Y0^T on the rows S0 (see the file comment)
  std::vector<double> factoredValues_;  // K0: free_.matrix values when factorized
  std::vector<int> woodburyRows_;       // S0, in the order added
  std::vector<int> woodburyPos_;        // base index -> position in S0 (-1: not in S0)
  Eigen::MatrixXd y0_;                  // K0^-1 I_:S0 (n_f x s0)
  Eigen::MatrixXd m_;                   // E0 (I + Y0_S0 E0)^-1 (s0 x s0)
  long frame_ = 0;
  // the corrections of the cached columns since setMatrix, applied on each column's next
  // use (see correctColumns): version_ counts them, log_ holds those from logBase_ on
  struct CorrectionEntry {
    int row, col;  // position in S, base index
    double value;  // of E
  };
  struct Correction {
    Eigen::MatrixXd y;                     // K'^-1 I_:S at the update (n_f x s)
    std::vector<CorrectionEntry> entries;  // E on the rows S
    std::vector<int> dropped;              // base indices that left the free set
  };
  std::deque<Correction> log_;
  long version_ = 0, logBase_ = 0;
  std::vector<long> slotVersion_;  // slot -> corrections its column has seen
  // the factor of K_k computed on a thread (startNextFactor), and K_k's values
  std::future<std::unique_ptr<CholmodFactor>> nextFactor_;
  // the Woodbury term failed its accuracy check alone (a node nearly cut off makes
  // I + G0 E0 ill-conditioned): every solve with it takes one step of iterative refinement;
  // false again with the next factor (adopted or computed), whose term is empty. Only
  // while its s solves cost under kRefineShare of a factorization (see there). Starting
  // the next factor at once after a refinement measured worse: its adoption, a fixed
  // update later for reproducible runs, waited 67-106 ms for it at 8000 nodes, the
  // structural update sharing its core.
  bool refine_ = false;
  std::vector<double> nextValues_;
  // solves, and rows of the term (with repeats), since the next factor started
  int solvesSinceNextFactor_ = 0;
  std::vector<int> rowsSinceNextFactor_;
};

}  // namespace

std::unique_ptr<ElectricSolver> makeCapacitanceSolver(const ElectricSolverOptions& options) {
  return std::make_unique<CapacitanceSolver>(options);
}

}  // namespace esim::electric_detail
