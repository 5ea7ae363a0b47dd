// electric_downdate.cpp - the potential from one LDL' factor of K_ff kept exact through a cut
// (issue #11), the contact nodes' columns solved as the tool touches them.
//
// Per contact set c, as capacitance: z_j = K_ff^-1 e_j for each contact node, the small SPD
// system Z_cc f = u_c, u = Z_:c f. What differs is how it follows a cut. The factor is a
// simplicial LDL' (CHOLMOD's supernodal factorization converted at setMatrix), solved by
// ldlSolve, and updateMatrix edits it in place as the structural phase edits its own:
//   1. the rows leaving the free set (their last tet removed, an island cut off, a node
//      newly grounded) become identity rows in one multiple-rank update by L's own columns
//      (CholmodFactor::deleteRows, ldlTakeRows);
//   2. the change E = K' - K on the rows staying free is written as a sum of rank-one terms
//      that cannot fill in L: for each changed entry (i, j) below the diagonal, c (e_i - e_j)
//      (e_i - e_j)' with c = -E_ij (an edge of the mesh: (i, j) is in L's pattern), and for
//      each row the rest of its diagonal, r_i e_i e_i' with r_i = E_ii + sum_j E_ij. The
//      positive terms are added first (ldlUpdown), then the negative ones taken away, so
//      every matrix in between is K' plus a semidefinite matrix: positive definite. A
//      removal's terms are mostly negative (its conductances leave); an obtuse tet's
//      negative off-diagonal conductance gives a positive one.
// Nothing is checked by solves afterwards (capacitance's Woodbury term needs s solves to
// check itself): the pivots must stay positive, else setMatrix; the result against a fresh
// factorization is tested (electric_downdate_test: a groove cut in 12 steps, 1e-12;
// electric_solver_test: 1e-9 over cuts that orphan nodes, cut off an island and take a node off
// the return electrode; simulation_test: a whole cut). The columns solved before an update are
// dropped by it (correcting them costs a solve each, as solving them again does), so a column
// is solved in the frame the tool first touches its node after the last removal; prefetch
// fills columns until the next update.
// When the change has more terms than kMaxTermShare of the free nodes, a new factorization is
// cheaper: setMatrix (stats.fellBack).
#include <algorithm>
#include <cmath>
#include <string>

#include "sim/core_error.h"
#include "sim/electric_solver.h"

namespace esim::electric_detail {
namespace {

// above this share of the free nodes in rank-one terms, updateMatrix refactorizes instead: a
// guard for removals of a large part of the mesh, not tuned: esim bench electric --only-update
// --update-sizes 8000 --update-tets 95,400 --update-strategies downdate (7200 free nodes, the
// guard at 900 terms): 95 tets gave 81 terms, updated in 5.4 ms against 72 ms for setMatrix,
// 400 tets 208 terms in 5.1 against 43 ms
constexpr double kMaxTermShare = 0.125;
// a row's remaining diagonal r_i under this share of |E_ii| is rounding (a row whose removed
// conductances all lead to nodes still free sums to 0): left out
constexpr double kDiagonalRounding = 1e-13;
// columns solved together (see solveColumns)
constexpr int kBlockColumns = 4;

class DowndateSolver final : public ElectricSolver {
 public:
  explicit DowndateSolver(const ElectricSolverOptions& options) : options_(options) {}

  void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) override {
    const ResetOnThrow guard(free_.current);
    free_.set(K, grounded);
    dropColumns();
    slotOf_.assign(free_.size(), -1);
    if (free_.size() == 0) return;
    setBlasThreads(options_.threads);
    factor_.analyze(free_.matrix);
    factor_.factorize(free_.matrix, "downdate");
    factor_.toSimplicial();
  }

  ElectricUpdateStats updateMatrix(const SparseMatrix& K,
                                   const std::vector<int>& grounded) override {
    ESIM_CHECK(free_.current.n > 0);  // setMatrix before updateMatrix
    const ResetOnThrow guard(free_.current);
    const BaseChange change = free_.diff(K, grounded);
    ElectricUpdateStats stats;
    const auto fallBack = [&](const std::string& why) {
      stats.columnsDropped += static_cast<int>(columns_.size());  // (none left once dropped)
      setMatrix(K, grounded);
      stats.fellBack = true;
      stats.fallbackReason = why;
      stats.rank = 0;
      return stats;
    };
    if (!change.fallback.empty()) return fallBack(change.fallback);
    stats.changedNodes = static_cast<int>(change.touched.size());
    stats.droppedNodes = static_cast<int>(change.dropped.size());
    if (change.empty()) return stats;
    const std::vector<Term> terms = rankOneTerms(change);
    if (static_cast<double>(terms.size()) > kMaxTermShare * free_.size())
      return fallBack(std::to_string(terms.size()) +
                      " rank-one changes: a new factorization is cheaper");
    stats.columnsDropped = static_cast<int>(columns_.size());
    dropColumns();
    try {
      if (!factor_.deleteRows(change.dropped, free_.matrix))
        return fallBack("a row leaving the free set had a pivot <= 0");
      free_.apply(change);
      for (bool update : {true, false}) {
        const SparseMatrix c = termColumns(terms, update);
        factor_.updateDowndate(update, c);
        stats.rank += static_cast<int>(c.cols());
      }
    } catch (const Error& e) {
      if (e.kind() == ErrorKind::Internal) throw;
      return fallBack(std::string("the factor update failed: ") + e.what());
    }
    if (!factor_.pivotsPositive())
      return fallBack("the downdate lost positive definiteness (a pivot <= 0)");
    return stats;
  }

  ElectricSolveStats solve(const std::vector<int>& contact, double voltageV,
                           Eigen::VectorXd& potential) override {
    ElectricSolveStats stats;
    const std::vector<int> cf = free_.contactsOrZero(contact, potential);
    if (cf.empty()) return stats;
    stats.newColumns = solveColumns(cf, cf);
    std::vector<const double*> z;
    for (int j : cf) z.push_back(columns_[slotOf_[j]].data());
    Eigen::VectorXd u;
    combineColumns(z, cf, voltageV, free_.size(), "downdate", u);
    free_.scatter(u, cf, voltageV, potential);
    return stats;
  }

  void prefetch(const std::vector<int>& nodes) override {
    if (free_.current.n == 0 || free_.current.numFree() == 0) return;
    std::vector<int> want;
    for (int node : nodes) {
      if (node < 0 || node >= free_.current.n || free_.current.freeIndex[node] < 0) continue;
      want.push_back(free_.base.freeIndex[node]);
    }
    std::sort(want.begin(), want.end());
    want.erase(std::unique(want.begin(), want.end()), want.end());
    solveColumns(want, {});
  }

  double memoryBytes() const override {
    return factor_.memoryBytes() + 20.0 * static_cast<double>(free_.matrix.nonZeros()) +
           8.0 * static_cast<double>(columns_.size()) * free_.size();
  }

  double limitCache(double bytes) override {
    options_.cacheMemoryLimitBytes = std::max(bytes, 8.0 * std::max(1, free_.size()));
    const double before = 8.0 * static_cast<double>(columns_.size()) * free_.size();
    if (before <= options_.cacheMemoryLimitBytes) return 0;
    dropColumns();
    return before;
  }

  const char* name() const override { return "downdate"; }

 private:
  struct Term {
    int i, j;      // rows (base indices); j == i: a diagonal term
    double value;  // the term is value (e_i - e_j)(e_i - e_j)' (diagonal: value e_i e_i')
  };

  // E = K' - K on the rows staying free as rank-one terms (see the file comment), in the
  // order of the base indices
  std::vector<Term> rankOneTerms(const BaseChange& change) const {
    std::vector<Term> terms;
    const auto stays = [&](int b) {
      return free_.active[b] &&
             !std::binary_search(change.dropped.begin(), change.dropped.end(), b);
    };
    for (int j : change.touched) {
      double diagonal = 0, rest = 0;
      for (SparseMatrix::InnerIterator it(change.delta, j); it; ++it) {
        const int i = static_cast<int>(it.row());
        if (i == j) {
          diagonal = it.value();
        } else if (stays(i)) {
          rest += it.value();
          if (i > j) terms.push_back({i, j, -it.value()});
        }
      }
      const double r = diagonal + rest;
      if (std::abs(r) > kDiagonalRounding * std::abs(diagonal)) terms.push_back({j, j, r});
    }
    return terms;
  }

  // the terms of one sign as the columns of C (C C' their sum, signs dropped): sqrt|value|
  // times e_i - e_j, or e_i
  SparseMatrix termColumns(const std::vector<Term>& terms, bool positive) const {
    std::vector<Eigen::Triplet<double>> t;
    int cols = 0;
    for (const Term& term : terms) {
      if ((term.value > 0) != positive || term.value == 0) continue;
      const double scale = std::sqrt(std::abs(term.value));
      t.emplace_back(term.i, cols, scale);
      if (term.j != term.i) t.emplace_back(term.j, cols, -scale);
      ++cols;
    }
    SparseMatrix c(free_.size(), cols);
    c.setFromTriplets(t.begin(), t.end());
    return c;
  }

  // solves and keeps the columns of the base indices `want` not kept yet (one solve each);
  // keep: those that must survive a full cache. Returns the number solved.
  int solveColumns(const std::vector<int>& want, const std::vector<int>& keep) {
    const int nf = free_.size();
    std::vector<int> missing;
    for (int j : want)
      if (slotOf_[j] < 0) missing.push_back(j);
    if (missing.empty()) return 0;
    const double columnBytes = 8.0 * nf;
    if (columnBytes * static_cast<double>(columns_.size() + missing.size()) >
        options_.cacheMemoryLimitBytes) {
      // over the cap: only the columns this call must keep stay
      std::vector<Eigen::VectorXd> kept;
      std::vector<int> keptNode;
      for (size_t slot = 0; slot < columns_.size(); ++slot)
        if (std::binary_search(keep.begin(), keep.end(), slotNode_[slot])) {
          kept.push_back(std::move(columns_[slot]));
          keptNode.push_back(slotNode_[slot]);
        }
      dropColumns();
      for (size_t slot = 0; slot < kept.size(); ++slot) {
        slotOf_[keptNode[slot]] = static_cast<int>(slot);
        slotNode_.push_back(keptNode[slot]);
        columns_.push_back(std::move(kept[slot]));
      }
    }
    // in blocks of kBlockColumns right-hand sides (CHOLMOD's simplicial solve reads L once for
    // up to four)
    const int count = static_cast<int>(missing.size());
    for (int first = 0; first < count; first += kBlockColumns) {
      checkInterrupt();
      const int cols = std::min(kBlockColumns, count - first);
      rhs_.setZero(nf, cols);
      for (int k = 0; k < cols; ++k) rhs_(missing[first + k], k) = 1.0;
      block_.resize(nf, cols);
      factor_.solve(rhs_.data(), block_.data(), cols);
      for (int k = 0; k < cols; ++k) {
        slotOf_[missing[first + k]] = static_cast<int>(columns_.size());
        slotNode_.push_back(missing[first + k]);
        columns_.push_back(block_.col(k));
      }
    }
    return count;
  }

  void dropColumns() {
    for (int j : slotNode_) slotOf_[j] = -1;
    slotNode_.clear();
    columns_.clear();
  }

  ElectricSolverOptions options_;
  FreeBase free_;  // node classes, K_ff in base indices
  CholmodFactor factor_;
  std::vector<Eigen::VectorXd> columns_;  // K_ff^-1 e_j for the current factor
  std::vector<int> slotNode_;             // slot -> base index j
  std::vector<int> slotOf_;               // base index -> slot (-1: not solved)
  Eigen::MatrixXd rhs_, block_;           // unit right-hand sides and their solutions
};

}  // namespace

std::unique_ptr<ElectricSolver> makeDowndateSolver(const ElectricSolverOptions& options) {
  return std::make_unique<DowndateSolver>(options);
}

}  // namespace esim::electric_detail
