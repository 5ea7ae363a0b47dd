// electric_downdate.cpp - the potential from one LDL' factor of K_ff kept exact through a cut
// (issue #11), the contact nodes' columns solved as the tool touches them.
//
// Per contact set c, as capacitance: z_j = K_ff^-1 e_j for each contact node, the small SPD
// system Z_cc f = u_c, u = Z_:c f. What differs is how it follows a cut. The factor is a
// simplicial LDL' (CHOLMOD's supernodal factorization converted at setMatrix), and
// updateMatrix edits it in place as the structural phase edits its own:
//   1. the rows leaving the free set (their last tet removed, an island cut off, a node
//      newly grounded) become identity rows in one multiple-rank update by L's own columns
//      (CholmodFactor::deleteRows, ldlTakeRows);
//   2. the change E = K' - K on the rows staying free is written as rank-one terms (for each
//      changed entry (i, j) below the diagonal, c (e_i - e_j)(e_i - e_j)' with c = -E_ij, an
//      edge of the mesh, and for each row the rest of its diagonal, r_i e_i e_i' with r_i =
//      E_ii + sum_j E_ij), and the rows the terms join form clusters; each cluster's -E is
//      factored by an LDL' with threshold pivoting in L's row order (changeColumns: as the
//      structural phase factors its removed tets' stiffness) into columns, a downdate for a
//      positive pivot, an update for a negative one: for a removal, whose -E is the removed
//      conductances (semidefinite), downdates only, about half as many as the terms
//      (bench electric --only-update: 95 tets at 8000 nodes rank 42 against 81 terms). A
//      cluster the LDL' cannot take (too large, indefinite past its diagonal, a column that
//      would fill in L) takes its terms, which cannot fill in. The updates are added first
//      (ldlUpdown), then the downdates taken away, so every matrix in between is K' plus a
//      semidefinite matrix: positive definite.
// Nothing is checked by solves afterwards (capacitance's Woodbury term needs s solves to
// check itself): the pivots must stay positive (those on the paths the updates walked:
// CholmodFactor::pivotsPositive), else setMatrix; the result against a fresh
// factorization is tested (electric_downdate_test: a groove cut in 12 steps, 1e-12;
// electric_solver_test: 1e-9 over cuts that orphan nodes, cut off an island and take a node off
// the return electrode; simulation_test: a whole cut).
// The contact columns are not solved whole. With P K_ff P' = L D L', the column of contact j
// is z_j = P' L'^-1 D^-1 y_j with y_j = L^-1 e_(row of j), and y_j is nonzero only on the path
// from j's row up the elimination tree (L's column k has its rows among k's ancestors): a
// sparse forward solve over that path's columns, kept as the contact's "path" until the next
// update drops it. The paths of the contacts new in a solve are solved together over their
// union (forwardRuns: each column of L read once; the paths' common top, dense, by BLAS). Then
// Z_cc = Y' D^-1 Y over the union of the contacts' paths, Z_cc f = 1, and the potential of unit
// voltage is u = P' L'^-1 D^-1 (Y f): one backward solve (ldlSolveBackward), half a solve,
// whatever the number of contacts. tools/contact_path_study times this solve against the
// columns in CHOLMOD's blocks of 4 it replaced (README "The potential on a factor kept exact
// through the cut"): 24 contacts 2.7 against 16.0 ms at 8000 nodes, 23.0 against 216 ms at
// 49 966; 150 contacts 20.3 against 722 ms at 20 130.
// The unit potential is kept with its contact set until the next update: a frame whose
// contacts did not change costs a scaling. prefetch solves paths ahead of need.
// When the change has more terms than kMaxTermShare of the free nodes, a new factorization is
// cheaper: setMatrix (stats.fellBack).
#include <cblas.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "sim/cholmod_view.h"
#include "sim/core_error.h"
#include "sim/electric_solver.h"
#include "sim/ldl_updown.h"

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
// a run of the paths' union (forwardRuns) is solved dense from kRunMinRows rows and
// kRunMinContacts contacts, and cut every kRunMaxRows rows (its triangle: 8 MB at 1024)
constexpr int kRunMinRows = 8;
constexpr int kRunMinContacts = 16;
constexpr int kRunMaxRows = 1024;
// changeColumns: a pivot at least this share of the largest remaining diagonal (the
// structural phase's kPivotShare, structural.cpp), clusters up to this many rows (its dense
// LDL' ~m^3/3 flops)
constexpr double kPivotShare = 1e-3;
constexpr int kMaxClusterRows = 256;

// The union U of the paths of some contacts up the elimination tree (closed under ancestors),
// the contacts numbered 0 .. c-1 in the order of their rows of L. A row is on the paths of the
// contacts [lo, hi] at most: CHOLMOD postorders the tree, so the contacts below a row form a
// contiguous range, and a range holding them all is correct in any case (the values of the
// others there stay 0). Its values are kept jagged: U's s-th row holds the hi - lo + 1 values
// of its range at offset[s], so consecutive rows with one range form a dense row-major block.
struct PathUnion {
  std::vector<int> rows;            // U, ascending (rows of L)
  std::vector<int> lo, hi;          // each row's range of contacts
  std::vector<std::size_t> offset;  // each row's values; offset.back(): their number
  int width(int s) const { return hi[s] - lo[s] + 1; }

  // from the contacts' rows of L, ascending; slot: row of L -> place in U, -1 on entry and
  // left so until release()
  void build(const SimplicialView& l, const std::vector<int>& starts, std::vector<int>& slot) {
    rows.clear();
    for (int start : starts)
      for (int k = start; k >= 0 && slot[k] < 0; k = l.parent(k)) {
        slot[k] = 0;
        rows.push_back(k);
      }
    std::sort(rows.begin(), rows.end());
    const int u = static_cast<int>(rows.size());
    for (int s = 0; s < u; ++s) slot[rows[s]] = s;
    lo.assign(u, static_cast<int>(starts.size()));
    hi.assign(u, -1);
    for (int q = 0; q < static_cast<int>(starts.size()); ++q)
      for (int k = starts[q]; k >= 0; k = l.parent(k)) {
        lo[slot[k]] = std::min(lo[slot[k]], q);
        hi[slot[k]] = std::max(hi[slot[k]], q);
      }
    offset.assign(u + 1, 0);
    for (int s = 0; s < u; ++s) offset[s + 1] = offset[s] + width(s);
  }
  void release(std::vector<int>& slot) const {
    for (int k : rows) slot[k] = -1;
  }
};

// releases a union's slots at the end of a scope, thrown through or not
struct ReleaseUnion {
  const PathUnion& u;
  std::vector<int>& slot;
  ~ReleaseUnion() { u.release(slot); }
};

// the forward solve's part for the union's columns [first, last) (w jagged as PathUnion's
// values): column by column, each read once, each row updated on its column's range of
// contacts only (the rows below a column are its ancestors, whose ranges hold its own)
inline __attribute__((always_inline)) void forwardColumnsBody(const SimplicialView& l,
                                                              const PathUnion& u, const int* slot,
                                                              int first, int last, double* w) {
  for (int s = first; s < last; ++s) {
    const int k = u.rows[s];
    const double* wk = w + u.offset[s];
    const int width = u.width(s);
    for (int p = l.p[k] + 1; p < l.p[k] + l.nz[k]; ++p) {
      const int r = slot[l.i[p]];
      double* wr = w + u.offset[r] + (u.lo[s] - u.lo[r]);
      const double lk = l.x[p];
      for (int t = 0; t < width; ++t) wr[t] -= lk * wk[t];
    }
  }
}

// ... compiled twice, for AVX2 + FMA and for any x86-64, chosen once by the CPU (no ifunc:
// ThreadSanitizer's runtime is not up when the loader resolves one)
__attribute__((target("avx2,fma"))) void forwardColumnsAvx2(const SimplicialView& l,
                                                            const PathUnion& u, const int* slot,
                                                            int first, int last, double* w) {
  forwardColumnsBody(l, u, slot, first, last, w);
}
void forwardColumnsGeneric(const SimplicialView& l, const PathUnion& u, const int* slot, int first,
                           int last, double* w) {
  forwardColumnsBody(l, u, slot, first, last, w);
}
void forwardColumns(const SimplicialView& l, const PathUnion& u, const int* slot, int first,
                    int last, double* w) {
  static const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  (avx2 ? forwardColumnsAvx2 : forwardColumnsGeneric)(l, u, slot, first, last, w);
}

// Z += Y_U' D_U^-1 Y_U (c x c, lower triangle) for Y jagged on the union: block by block of
// consecutive rows with one range, a block scaled by D^-1/2 (the pivots are positive) and
// added by one BLAS rank-k update (the paths' common top is one block); scratch: workspace
void addGram(const SimplicialView& l, const PathUnion& u, const double* y, Eigen::MatrixXd& z,
             std::vector<double>& scratch) {
  const int rows = static_cast<int>(u.rows.size()), c = static_cast<int>(z.rows());
  for (int s0 = 0, s1 = 0; s0 < rows; s0 = s1) {
    for (s1 = s0 + 1; s1 < rows && u.lo[s1] == u.lo[s0] && u.hi[s1] == u.hi[s0];) ++s1;
    const int len = s1 - s0, width = u.width(s0);
    scratch.resize(static_cast<std::size_t>(len) * width);
    for (int t = 0; t < len; ++t) {
      const double scale = 1.0 / std::sqrt(l.diagonal(u.rows[s0 + t]));
      const double* from = y + u.offset[s0 + t];
      for (int q = 0; q < width; ++q)
        scratch[static_cast<std::size_t>(t) * width + q] = scale * from[q];
    }
    // z is column-major: its lower triangle is the upper one of the row-major view
    cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, width, len, 1.0, scratch.data(), width, 1.0,
                z.data() + static_cast<std::size_t>(u.lo[s0]) * c + u.lo[s0], c);
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

  ElectricUpdateStats updateMatrix(const SparseMatrix& K, const std::vector<int>& grounded,
                                   const std::vector<int>* changedNodes) override {
    ESIM_CHECK(free_.current.n > 0);  // setMatrix before updateMatrix
    const ResetOnThrow guard(free_.current);
    const BaseChange change = free_.diff(K, grounded, changedNodes);
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
      const std::array<SparseMatrix, 2> c = changeColumns(terms);
      for (bool update : {true, false}) {
        factor_.updateDowndate(update, c[update]);
        stats.rank += static_cast<int>(c[update].cols());
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
    scaled_ = voltageV * unit_;  // (its storage kept from frame to frame)
    free_.scatter(scaled_, cf, voltageV, potential);
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

  // the factor, K_ff, the paths, six vectors of the free nodes (the unit potential and its
  // scaled copy, the backward solve's input, the row maps and the scratch) and the paths'
  // workspaces
  double memoryBytes() const override {
    const double work = static_cast<double>(block_.capacity() + dense_.capacity() +
                                            gather_.capacity() + product_.capacity());
    return factor_.memoryBytes() + 20.0 * static_cast<double>(free_.matrix.nonZeros()) +
           pathBytes_ + 40.0 * free_.size() + 8.0 * work;
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

  // E = K' - K on the rows staying free as the columns of two matrices, [0] the downdate
  // and [1] the update (E = C1 C1' - C0 C0'). Rows that E couples form clusters; each
  // cluster's -E (a removal's: the removed elements' conductances, a sum of positive
  // semidefinite element matrices, so semidefinite) is factored as the structural phase
  // factors its removed tets' stiffness (structural.cpp, step 4): an LDL' that takes as pivot
  // the first row (in L's order) whose remaining diagonal is at least kPivotShare of the
  // largest, and stops when the rest is rounding (1e-12 of the largest diagonal). A pivot d
  // gives the column g / sqrt|d|: a downdate for d > 0, an update for d < 0. A cluster's
  // columns are at most its rows less one where all its rows stay free (the constant
  // potential is in -E's null space), against one per changed edge (the rank-one terms,
  // each edge's e_i - e_j, which cannot fill in L): a removal's rank about halves
  // (bench electric --only-update, "rank"). A cluster of more than kMaxClusterRows rows, whose
  // rest is not rounding (an indefinite -E whose diagonal runs out first), or with a column
  // that would fill in L (a pivot out of row order) takes its rank-one terms instead.
  std::array<SparseMatrix, 2> changeColumns(const std::vector<Term>& terms) {
    std::array<std::vector<Eigen::Triplet<double>>, 2> t;
    std::array<int, 2> cols{0, 0};
    const auto add = [&](bool update, const std::vector<std::pair<int, double>>& entries) {
      for (const auto& [row, value] : entries) t[update].emplace_back(row, cols[update], value);
      ++cols[update];
    };
    // clusters: union-find over the rows the terms join
    std::vector<int> rows;
    for (const Term& term : terms) {
      rows.push_back(term.i);
      rows.push_back(term.j);
    }
    std::sort(rows.begin(), rows.end());
    rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
    const auto at = [&](int b) {
      return static_cast<int>(std::lower_bound(rows.begin(), rows.end(), b) - rows.begin());
    };
    std::vector<int> parent(rows.size());
    for (size_t k = 0; k < rows.size(); ++k) parent[k] = static_cast<int>(k);
    const auto find = [&](int k) {
      while (parent[k] != k) k = parent[k] = parent[parent[k]];
      return k;
    };
    for (const Term& term : terms) parent[find(at(term.i))] = find(at(term.j));
    std::vector<std::vector<int>> clusters;  // rows (base indices), in L's row order
    {
      std::vector<int> clusterOf(rows.size(), -1);
      for (size_t k = 0; k < rows.size(); ++k) {
        int& c = clusterOf[find(static_cast<int>(k))];
        if (c < 0) {
          c = static_cast<int>(clusters.size());
          clusters.emplace_back();
        }
        clusters[c].push_back(rows[k]);
      }
      for (auto& c : clusters)
        std::sort(c.begin(), c.end(), [&](int a, int b) { return rowOf_[a] < rowOf_[b]; });
    }
    std::vector<std::vector<Term>> termsOf(clusters.size());
    {
      std::vector<int> clusterOfRow(rows.size());
      for (size_t c = 0; c < clusters.size(); ++c)
        for (int b : clusters[c]) clusterOfRow[at(b)] = static_cast<int>(c);
      for (const Term& term : terms) termsOf[clusterOfRow[at(term.i)]].push_back(term);
    }
    std::vector<std::pair<int, double>> entries;
    std::vector<int> lRows;
    for (size_t c = 0; c < clusters.size(); ++c) {
      const std::vector<int>& cr = clusters[c];
      const int m = static_cast<int>(cr.size());
      const auto byTerms = [&] {  // the cluster's rank-one terms, as before
        for (const Term& term : termsOf[c]) {
          if (term.value == 0) continue;
          const double scale = std::sqrt(std::abs(term.value));
          entries.assign(1, {term.i, scale});
          if (term.j != term.i) entries.emplace_back(term.j, -scale);
          add(term.value > 0, entries);
        }
      };
      if (m > kMaxClusterRows) {
        byTerms();
        continue;
      }
      // -E on the cluster's rows (their order in L; the lower triangle is read)
      Eigen::MatrixXd g = Eigen::MatrixXd::Zero(m, m);
      for (const Term& term : termsOf[c]) {
        const int a = static_cast<int>(std::find(cr.begin(), cr.end(), term.i) - cr.begin());
        const int b = static_cast<int>(std::find(cr.begin(), cr.end(), term.j) - cr.begin());
        if (a == b) {
          g(a, a) -= term.value;
        } else {  // value (e_i - e_j)(e_i - e_j)'
          g(a, a) -= term.value;
          g(b, b) -= term.value;
          g(a, b) += term.value;
          g(b, a) += term.value;
        }
      }
      const size_t from[2] = {t[0].size(), t[1].size()};
      const int fromCols[2] = {cols[0], cols[1]};
      bool fills = false;
      const double rest =
          pivotedLdl(g, kPivotShare, true, [&](double d, const Eigen::VectorXd& col) {
            const double scale = 1 / std::sqrt(std::abs(d));
            entries.clear();
            lRows.clear();
            for (int a = 0; a < m; ++a)
              if (col[a] != 0.0) {
                entries.emplace_back(cr[a], col[a] * scale);
                lRows.push_back(rowOf_[cr[a]]);
              }
            fills = fills || ldlColumnFillsIn(factor_.cholmod(), lRows.data(),
                                              static_cast<int>(lRows.size()), fill_);
            add(d < 0, entries);
          });
      const bool ok = !fills && rest <= 1e-12;  // the rest must be round-off
      if (!ok) {                                // back to before the cluster, then its terms
        for (int k : {0, 1}) {
          t[k].resize(from[k]);
          cols[k] = fromCols[k];
        }
        byTerms();
      }
    }
    std::array<SparseMatrix, 2> c;
    for (int k : {0, 1}) {
      c[k].resize(free_.size(), cols[k]);
      c[k].setFromTriplets(t[k].begin(), t[k].end());
    }
    return c;
  }

  // a contact's path up the elimination tree and y = L^-1 e_(its row) there
  // (its rows are the walk up the tree from the contact's row: not kept)
  struct Path {
    std::vector<double> y;  // y on the path's rows, the contact's row first, the root last
    double bytes() const { return 8.0 * static_cast<double>(y.size()); }
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
    // their union, the contacts in row order; W = L_UU^-1 E, E their unit columns, in one
    // pass over the union's columns of L
    std::sort(missing.begin(), missing.end(), [&](int a, int b) { return rowOf_[a] < rowOf_[b]; });
    std::vector<int> starts;
    for (int j : missing) starts.push_back(rowOf_[j]);
    const SimplicialView l(&factor_.cholmod());
    checkInterrupt();
    union_.build(l, starts, unionSlot_);
    const ReleaseUnion release{union_, unionSlot_};
    block_.assign(union_.offset.back(), 0.0);
    const auto at = [&](int k, int q) {
      const int s = unionSlot_[k];
      return union_.offset[s] + (q - union_.lo[s]);
    };
    const int m = static_cast<int>(missing.size());
    for (int q = 0; q < m; ++q) block_[at(starts[q], q)] = 1.0;
    forwardRuns(l, block_.data());
    for (int q = 0; q < m; ++q) {
      Path path;
      for (int k = starts[q]; k >= 0; k = l.parent(k)) path.y.push_back(block_[at(k, q)]);
      keepPath(missing[q], std::move(path));
    }
    return m;
  }

  // w = L_UU^-1 w on union_ (w jagged on it), run by run of consecutive rows with one range
  // of contacts: a short or narrow run column by column (forwardColumns); a larger one as a
  // supernodal solve does, its own triangle of L copied dense and solved for its contacts by
  // one BLAS triangular solve, then its columns' entries below it gathered dense (the rows
  // below: ancestors, the paths' common top among them) and applied by one BLAS product
  void forwardRuns(const SimplicialView& l, double* w) {
    const int u = static_cast<int>(union_.rows.size());
    const int* slot = unionSlot_.data();
    std::vector<int> target(u, -1);  // a row below the run -> its row in the gathered block
    std::vector<int> targets;
    for (int s0 = 0, s1 = 0; s0 < u; s0 = s1) {
      for (s1 = s0 + 1; s1 < u && s1 - s0 < kRunMaxRows && union_.lo[s1] == union_.lo[s0] &&
                        union_.hi[s1] == union_.hi[s0];)
        ++s1;
      const int len = s1 - s0, width = union_.width(s0);
      if (len < kRunMinRows || width < kRunMinContacts) {
        forwardColumns(l, union_, slot, s0, s1, w);
        continue;
      }
      dense_.assign(static_cast<std::size_t>(len) * len, 0.0);  // column-major, unit diagonal
      targets.clear();
      for (int s = s0; s < s1; ++s) {
        const int k = union_.rows[s];
        for (int p = l.p[k] + 1; p < l.p[k] + l.nz[k]; ++p) {
          const int r = slot[l.i[p]];
          if (r < s1) {
            dense_[static_cast<std::size_t>(s - s0) * len + (r - s0)] = l.x[p];
          } else if (target[r] < 0) {
            target[r] = static_cast<int>(targets.size());
            targets.push_back(r);
          }
        }
      }
      double* run = w + union_.offset[s0];  // len x width, row-major
      // L X = B for B row-major is X' L' = B' for B' column-major
      cblas_dtrsm(CblasColMajor, CblasRight, CblasLower, CblasTrans, CblasUnit, width, len, 1.0,
                  dense_.data(), len, run, width);
      if (targets.empty()) continue;
      const int t = static_cast<int>(targets.size());
      gather_.assign(static_cast<std::size_t>(t) * len, 0.0);  // t x len, column-major
      for (int s = s0; s < s1; ++s) {
        const int k = union_.rows[s];
        for (int p = l.p[k] + 1; p < l.p[k] + l.nz[k]; ++p) {
          const int r = slot[l.i[p]];
          if (r >= s1) gather_[static_cast<std::size_t>(s - s0) * t + target[r]] = l.x[p];
        }
      }
      product_.resize(static_cast<std::size_t>(t) * width);
      // P = G B (t x width, row-major) as P' = B' G' (column-major)
      cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, width, t, len, 1.0, run, width,
                  gather_.data(), t, 0.0, product_.data(), width);
      for (int row = 0; row < t; ++row) {
        const int r = targets[row];
        double* wr = w + union_.offset[r] + (union_.lo[s0] - union_.lo[r]);
        const double* pr = product_.data() + static_cast<std::size_t>(row) * width;
        for (int q = 0; q < width; ++q) wr[q] -= pr[q];
        target[r] = -1;
      }
    }
  }

  void keepPath(int j, Path path) {
    slotOf_[j] = static_cast<int>(paths_.size());
    slotNode_.push_back(j);
    pathBytes_ += path.bytes();
    paths_.push_back(std::move(path));
  }

  // unit_ = the potential of the contacts cf (paths solved) at 1 V: Y on the union U of their
  // paths (the contacts in row order), Z_cc = Y_U' D_U^-1 Y_U, Z_cc f = 1, unit_ = P' L'^-1
  // D^-1 (Y f)
  void unitPotential(const std::vector<int>& cf) {
    std::vector<int> order = cf;
    std::sort(order.begin(), order.end(), [&](int a, int b) { return rowOf_[a] < rowOf_[b]; });
    std::vector<int> starts;
    for (int j : order) starts.push_back(rowOf_[j]);
    const SimplicialView l(&factor_.cholmod());
    union_.build(l, starts, unionSlot_);
    const ReleaseUnion release{union_, unionSlot_};
    const int c = static_cast<int>(order.size());
    block_.assign(union_.offset.back(), 0.0);
    for (int q = 0; q < c; ++q) {
      const std::vector<double>& y = paths_[slotOf_[order[q]]].y;
      std::size_t t = 0;
      for (int k = starts[q]; k >= 0; k = l.parent(k), ++t) {
        const int s = unionSlot_[k];
        block_[union_.offset[s] + (q - union_.lo[s])] = y[t];
      }
    }
    Eigen::MatrixXd zcc = Eigen::MatrixXd::Zero(c, c);
    addGram(l, union_, block_.data(), zcc, dense_);
    const Eigen::LLT<Eigen::MatrixXd> llt(zcc);  // reads the lower triangle
    ESIM_VERIFY(llt.info() == Eigen::Success, "downdate: Z_cc is not positive definite");
    const Eigen::VectorXd f = llt.solve(Eigen::VectorXd::Ones(c));
    for (int s = 0; s < static_cast<int>(union_.rows.size()); ++s) {
      double sum = 0;
      for (int t = 0; t < union_.width(s); ++t)
        sum += block_[union_.offset[s] + t] * f[union_.lo[s] + t];
      scratch_[union_.rows[s]] = sum;
    }
    unit_.resize(free_.size());
    factor_.solveBackward(scratch_.data(), unit_.data());
    for (int k : union_.rows) scratch_[k] = 0.0;
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
  LdlUpdownWork fill_;             // changeColumns' fill-in checks
  std::vector<Path> paths_;        // the contacts' paths for the current factor
  std::vector<int> slotNode_;      // slot -> base index j
  std::vector<int> slotOf_;        // base index -> slot (-1: not solved)
  double pathBytes_ = 0;           // the paths' memory
  std::vector<double> scratch_;    // n_f zeros between uses (L's row order)
  std::vector<int> unionSlot_;     // row of L -> its place in U (-1 between uses)
  PathUnion union_;                // the paths' union (solvePaths, unitPotential)
  std::vector<double> block_;      // values on it
  std::vector<double> dense_;      // a run's triangle of L (forwardRuns); addGram's blocks
  std::vector<double> gather_;     // a run's entries of L below it (forwardRuns)
  std::vector<double> product_;    // ... times its values
  Eigen::VectorXd unit_;           // the potential of unitContacts_ at 1 V (base indices)
  Eigen::VectorXd scaled_;         // ... times the solve's voltage
  std::vector<int> unitContacts_;  // ... whose contacts
  bool unitValid_ = false;         // ... computed on the current factor
};

}  // namespace

std::unique_ptr<ElectricSolver> makeDowndateSolver(const ElectricSolverOptions& options) {
  return std::make_unique<DowndateSolver>(options);
}

}  // namespace esim::electric_detail
