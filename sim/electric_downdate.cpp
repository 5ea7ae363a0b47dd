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
// the return electrode; simulation_test: a whole cut).
// The contact columns are not solved whole. With P K_ff P' = L D L', the column of contact j
// is z_j = P' L'^-1 D^-1 y_j with y_j = L^-1 e_(row of j), and y_j is nonzero only on the path
// from j's row up the elimination tree (L's column k has its rows among k's ancestors): a
// sparse forward solve over that path's columns, kept as the contact's "path" until the next
// update drops it. Then Z_cc = Y' D^-1 Y over the union of the contacts' paths (one small
// dense product), Z_cc f = 1, and the potential of unit voltage is u = P' L'^-1 D^-1 (Y f):
// one backward solve (ldlSolveBackward), half a solve, whatever the number of contacts.
// Measured before it was built (tools/contact_path_study, README "The potential on a factor
// kept exact through the cut"): 24 contacts on slab_cut's factor, 3.7-4.2 ms against 18.8-18.9
// ms for the columns in CHOLMOD's blocks of 4 at 8000 nodes, 17-18 against 94-101 ms at 26 928.
// The unit potential is kept with its contact set until the next update: a frame whose
// contacts did not change costs a scaling. prefetch solves paths ahead of need.
// When the change has more terms than kMaxTermShare of the free nodes, a new factorization is
// cheaper: setMatrix (stats.fellBack).
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "sim/cholmod_view.h"
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

// w = L_UU^-1 w for the rows U of L (ascending, closed under the elimination tree's
// ancestors: every row of a column of U is in U) and m right-hand sides, w row-major (the row
// of U's k-th row at w + slot[row] * m): column by column, each read once for all m
__attribute__((target_clones("avx512f", "avx2", "default"))) void forwardBlock(
    const SimplicialView& l, const std::vector<int>& rows, const int* slot, int m, double* w) {
  for (int k : rows) {
    const double* wk = w + static_cast<size_t>(slot[k]) * m;
    bool any = false;
    for (int q = 0; q < m; ++q) any |= wk[q] != 0.0;
    if (!any) continue;
    for (int p = l.p[k] + 1; p < l.p[k] + l.nz[k]; ++p) {
      double* wr = w + static_cast<size_t>(slot[l.i[p]]) * m;
      const double lk = l.x[p];
      for (int q = 0; q < m; ++q) wr[q] -= lk * wk[q];
    }
  }
}

class DowndateSolver final : public ElectricSolver {
 public:
  explicit DowndateSolver(const ElectricSolverOptions& options) : options_(options) {}

  void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) override {
    const ResetOnThrow guard(free_.current);
    free_.set(K, grounded);
    dropPaths();
    slotOf_.assign(free_.size(), -1);
    const int nf = free_.size();
    rowOf_.assign(nf, -1);
    scratch_.assign(nf, 0.0);
    unionSlot_.assign(nf, -1);
    if (nf == 0) return;
    setBlasThreads(options_.threads);
    factor_.analyze(free_.matrix);
    factor_.factorize(free_.matrix, "downdate");
    factor_.toSimplicial();
    const std::vector<int> perm = factor_.ordering();
    for (int k = 0; k < nf; ++k) rowOf_[perm[k]] = k;
  }

  ElectricUpdateStats updateMatrix(const SparseMatrix& K,
                                   const std::vector<int>& grounded) override {
    ESIM_CHECK(free_.current.n > 0);  // setMatrix before updateMatrix
    const ResetOnThrow guard(free_.current);
    const BaseChange change = free_.diff(K, grounded);
    ElectricUpdateStats stats;
    const auto fallBack = [&](const std::string& why) {
      stats.columnsDropped += static_cast<int>(paths_.size());  // (none left once dropped)
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
    stats.columnsDropped = static_cast<int>(paths_.size());
    dropPaths();
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
    if (!unitValid_ || cf != unitContacts_) {
      stats.newColumns = solvePaths(cf, cf);
      unitPotential(cf);
    }
    free_.scatter(voltageV * unit_, cf, voltageV, potential);
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
    solvePaths(want, {});
  }

  // the factor, K_ff, the paths, and five vectors of the free nodes (the unit potential, the
  // backward solve's input, the row maps and the scratch)
  double memoryBytes() const override {
    return factor_.memoryBytes() + 20.0 * static_cast<double>(free_.matrix.nonZeros()) +
           pathBytes_ + 32.0 * free_.size();
  }

  double limitCache(double bytes) override {
    options_.cacheMemoryLimitBytes = std::max(bytes, 0.0);
    const double before = pathBytes_;
    if (before <= options_.cacheMemoryLimitBytes) return 0;
    dropPaths();
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

  // a contact's path up the elimination tree and y = L^-1 e_(its row) there
  struct Path {
    std::vector<int> rows;  // rows of L, ascending (the contact's row first, the root last)
    std::vector<double> y;  // y on those rows
    double bytes() const { return 12.0 * static_cast<double>(rows.size()); }
  };

  // solves and keeps the paths of the base indices `want` not kept yet; keep: those that must
  // survive a full cache. Returns the number solved.
  int solvePaths(const std::vector<int>& want, const std::vector<int>& keep) {
    std::vector<int> missing;
    for (int j : want)
      if (slotOf_[j] < 0) missing.push_back(j);
    if (missing.empty()) return 0;
    if (pathBytes_ > options_.cacheMemoryLimitBytes) {
      // over the cap: only the paths this call must keep stay
      std::vector<Path> kept;
      std::vector<int> keptNode;
      for (size_t slot = 0; slot < paths_.size(); ++slot)
        if (std::binary_search(keep.begin(), keep.end(), slotNode_[slot])) {
          kept.push_back(std::move(paths_[slot]));
          keptNode.push_back(slotNode_[slot]);
        }
      dropPaths();
      for (size_t slot = 0; slot < kept.size(); ++slot)
        keepPath(keptNode[slot], std::move(kept[slot]));
    }
    // the union of the missing paths (closed under ancestors), in L's row order
    const SimplicialView l(&factor_.cholmod());
    std::vector<int> rows;
    for (int j : missing)
      for (int k = rowOf_[j]; k >= 0 && unionSlot_[k] < 0; k = l.parent(k)) {
        unionSlot_[k] = 0;
        rows.push_back(k);
      }
    std::sort(rows.begin(), rows.end());
    for (size_t r = 0; r < rows.size(); ++r) unionSlot_[rows[r]] = static_cast<int>(r);
    // W = L_UU^-1 E, E the unit columns of the missing contacts' rows: one pass over the
    // union's columns of L for all of them (W row-major, a row's m values contiguous)
    checkInterrupt();
    const int m = static_cast<int>(missing.size());
    block_.assign(rows.size() * m, 0.0);
    for (int q = 0; q < m; ++q)
      block_[static_cast<size_t>(unionSlot_[rowOf_[missing[q]]]) * m + q] = 1.0;
    forwardBlock(l, rows, unionSlot_.data(), m, block_.data());
    for (int q = 0; q < m; ++q) {
      Path path;
      for (int k = rowOf_[missing[q]]; k >= 0; k = l.parent(k)) {
        path.rows.push_back(k);
        path.y.push_back(block_[static_cast<size_t>(unionSlot_[k]) * m + q]);
      }
      keepPath(missing[q], std::move(path));
    }
    for (int k : rows) unionSlot_[k] = -1;
    return m;
  }

  void keepPath(int j, Path path) {
    slotOf_[j] = static_cast<int>(paths_.size());
    slotNode_.push_back(j);
    pathBytes_ += path.bytes();
    paths_.push_back(std::move(path));
  }

  // unit_ = the potential of the contacts cf (paths solved) at 1 V: Y on the union U of their
  // paths, Z_cc = Y_U' D_U^-1 Y_U, Z_cc f = 1, unit_ = P' L'^-1 D^-1 (Y f)
  void unitPotential(const std::vector<int>& cf) {
    const SimplicialView l(&factor_.cholmod());
    const int c = static_cast<int>(cf.size());
    std::vector<int> rows;  // U
    for (int j : cf)
      for (int k : paths_[slotOf_[j]].rows)
        if (unionSlot_[k] < 0) {
          unionSlot_[k] = static_cast<int>(rows.size());
          rows.push_back(k);
        }
    const int u = static_cast<int>(rows.size());
    Eigen::MatrixXd y = Eigen::MatrixXd::Zero(u, c);
    for (int q = 0; q < c; ++q) {
      const Path& path = paths_[slotOf_[cf[q]]];
      for (size_t s = 0; s < path.rows.size(); ++s) y(unionSlot_[path.rows[s]], q) = path.y[s];
    }
    Eigen::VectorXd inverseD(u);
    for (int r = 0; r < u; ++r) inverseD[r] = 1.0 / l.diagonal(rows[r]);
    const Eigen::MatrixXd zcc = y.transpose() * (inverseD.asDiagonal() * y);
    const Eigen::LLT<Eigen::MatrixXd> llt(zcc);
    ESIM_VERIFY(llt.info() == Eigen::Success, "downdate: Z_cc is not positive definite");
    const Eigen::VectorXd f = llt.solve(Eigen::VectorXd::Ones(c));
    const Eigen::VectorXd yf = y * f;
    for (int r = 0; r < u; ++r) scratch_[rows[r]] = yf[r];
    unit_.resize(free_.size());
    factor_.solveBackward(scratch_.data(), unit_.data());
    for (int k : rows) {
      scratch_[k] = 0.0;
      unionSlot_[k] = -1;
    }
    unitContacts_ = cf;
    unitValid_ = true;
  }

  void dropPaths() {
    for (int j : slotNode_) slotOf_[j] = -1;
    slotNode_.clear();
    paths_.clear();
    pathBytes_ = 0;
    unitValid_ = false;
  }

  ElectricSolverOptions options_;
  FreeBase free_;  // node classes, K_ff in base indices
  CholmodFactor factor_;
  std::vector<int> rowOf_;         // base index -> row of L
  std::vector<Path> paths_;        // the contacts' paths for the current factor
  std::vector<int> slotNode_;      // slot -> base index j
  std::vector<int> slotOf_;        // base index -> slot (-1: not solved)
  double pathBytes_ = 0;           // the paths' memory
  std::vector<double> scratch_;    // n_f zeros between uses (L's row order)
  std::vector<int> unionSlot_;     // row of L -> its place in U (-1 between uses)
  std::vector<double> block_;      // the paths' forward solve (solvePaths)
  Eigen::VectorXd unit_;           // the potential of unitContacts_ at 1 V (base indices)
  std::vector<int> unitContacts_;  // ... whose contacts
  bool unitValid_ = false;         // ... computed on the current factor
};

}  // namespace

std::unique_ptr<ElectricSolver> makeDowndateSolver(const ElectricSolverOptions& options) {
  return std::make_unique<DowndateSolver>(options);
}

}  // namespace esim::electric_detail
