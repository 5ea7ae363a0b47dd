// The multiple-rank LDL' update of ldl_updown.h. For each column j on a pass's paths (in
// increasing order, so children before parents): D(j) and the pass's alpha/gamma from row
// j of W (cholmod_updown's ALPHA_GAMMA), then every entry (i, j) below the diagonal:
//   for k < 8: W(i, k) -= W(j, k) L(i, j);  L(i, j) -= gamma(k) W(i, k)
// Eight entries at a time: their rows of W (8 doubles each) are loaded and transposed, so
// that W(:, k) over the eight rows is one vector and the loop over k runs on vectors, then
// transposed back and stored (the rows of one column of L are distinct: no conflicts).
#include "sim/ldl_updown.h"

// GCC 12's AVX-512 intrinsics warn of their own undefined vectors (_mm512_undefined_pd in
// the shuffles) as maybe uninitialized: a false positive
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <thread>

#include "sim/two_threads.h"

namespace esim {
namespace {

constexpr int kWidth = 8;  // columns of C a pass (one AVX-512 vector of doubles)
// the passes pipelined on two threads from this many entries of L walked (below, handing
// the odd passes to a helper thread costs more than it saves)
constexpr long kMinPipelinedEntries = 100000;

// 8 x 8 transpose of r[0..7] in place
__attribute__((target("avx512f,fma"))) inline void transpose8(__m512d* r) {
  const __m512d t0 = _mm512_unpacklo_pd(r[0], r[1]), t1 = _mm512_unpackhi_pd(r[0], r[1]);
  const __m512d t2 = _mm512_unpacklo_pd(r[2], r[3]), t3 = _mm512_unpackhi_pd(r[2], r[3]);
  const __m512d t4 = _mm512_unpacklo_pd(r[4], r[5]), t5 = _mm512_unpackhi_pd(r[4], r[5]);
  const __m512d t6 = _mm512_unpacklo_pd(r[6], r[7]), t7 = _mm512_unpackhi_pd(r[6], r[7]);
  const __m512d u0 = _mm512_shuffle_f64x2(t0, t2, 0x88), u1 = _mm512_shuffle_f64x2(t0, t2, 0xdd);
  const __m512d u2 = _mm512_shuffle_f64x2(t4, t6, 0x88), u3 = _mm512_shuffle_f64x2(t4, t6, 0xdd);
  const __m512d u4 = _mm512_shuffle_f64x2(t1, t3, 0x88), u5 = _mm512_shuffle_f64x2(t1, t3, 0xdd);
  const __m512d u6 = _mm512_shuffle_f64x2(t5, t7, 0x88), u7 = _mm512_shuffle_f64x2(t5, t7, 0xdd);
  r[0] = _mm512_shuffle_f64x2(u0, u2, 0x88);
  r[4] = _mm512_shuffle_f64x2(u0, u2, 0xdd);
  r[2] = _mm512_shuffle_f64x2(u1, u3, 0x88);
  r[6] = _mm512_shuffle_f64x2(u1, u3, 0xdd);
  r[1] = _mm512_shuffle_f64x2(u4, u6, 0x88);
  r[5] = _mm512_shuffle_f64x2(u4, u6, 0xdd);
  r[3] = _mm512_shuffle_f64x2(u5, u7, 0x88);
  r[7] = _mm512_shuffle_f64x2(u5, u7, 0xdd);
}

// the rows below G columns j_0 < ... < j_{G-1} of a chain in the elimination tree with
// the same pattern there (rows li[0..count)): column m's values at lx[m][0..count), its
// W row and gamma in z[m], g[m]; per row the columns in order, as G single columns would
template <int G>
__attribute__((target("avx512f,fma"))) void updateRows(const double (*z)[kWidth],
                                                       const double (*g)[kWidth], const int* li,
                                                       double* const* lx, int count, double* w) {
  int q = 0;
  for (; q + 8 <= count; q += 8) {
    __m512d r[8];
    for (int m = 0; m < 8; ++m) r[m] = _mm512_loadu_pd(w + kWidth * static_cast<long>(li[q + m]));
    transpose8(r);  // r[k]: W(rows, k)
    for (int c = 0; c < G; ++c) {
      __m512d l = _mm512_loadu_pd(lx[c] + q);
      for (int k = 0; k < kWidth; ++k) {
        r[k] = _mm512_fnmadd_pd(_mm512_set1_pd(z[c][k]), l, r[k]);
        l = _mm512_fnmadd_pd(_mm512_set1_pd(g[c][k]), r[k], l);
      }
      _mm512_storeu_pd(lx[c] + q, l);
    }
    transpose8(r);
    for (int m = 0; m < 8; ++m) _mm512_storeu_pd(w + kWidth * static_cast<long>(li[q + m]), r[m]);
  }
  for (; q < count; ++q) {
    double* wi = w + kWidth * static_cast<long>(li[q]);
    for (int c = 0; c < G; ++c) {
      double l = lx[c][q];
      for (int k = 0; k < kWidth; ++k) {
        wi[k] = std::fma(-z[c][k], l, wi[k]);
        l = std::fma(-g[c][k], wi[k], l);
      }
      lx[c][q] = l;
    }
  }
}

// the marks sized to a factor of n rows (kept across calls on the same factor)
void sizeMarks(LdlUpdownWork& work, size_t n) {
  if (work.mark.size() == n) return;
  work.mark.assign(n, 0);
  work.stamp = 0;
}

int nextStamp(LdlUpdownWork& work) {
  if (++work.stamp == 0x7fffffff) {
    std::fill(work.mark.begin(), work.mark.end(), 0);
    work.stamp = 1;
  }
  return work.stamp;
}

// one pass: the columns [k0, k0 + rank) of C (its path, ascending, built before) with the
// workspace w (zero on entry and on return). Pipelined (see vectorPasses): before each group of
// columns it waits until the previous pass has finished every column up to the group's last
// (*previous > that column), and after it tells the next pass how far it is (*progress).
void runPass(bool update, int k0, int rank, const std::vector<int>& path, cholmod_factor& l,
             const LdlUpdownWork& work, double* w, const std::atomic<int>* previous,
             std::atomic<int>* progress) {
  const int* lp = static_cast<const int*>(l.p);
  const int* li = static_cast<const int*>(l.i);
  const int* lnz = static_cast<const int*>(l.nz);
  double* lx = static_cast<double*>(l.x);
  const int* cp = work.cp.data();
  const int* ci = work.ci.data();
  const double* cx = work.cx.data();
  double alpha[kWidth];
  for (int k = 0; k < kWidth; ++k) alpha[k] = 1.0;
  for (int k = 0; k < rank; ++k)
    for (int p = cp[k0 + k]; p < cp[k0 + k + 1]; ++p)
      w[kWidth * static_cast<long>(ci[p]) + k] = cx[p];
  for (size_t at = 0; at < path.size();) {
    // a group of 1, 2 or 4 columns: each the parent of the one before and the next on
    // the path (so no other column of the path comes between), with the same pattern
    // below the group (cholmod_updown's dual and quad columns)
    const int j = path[at];
    const int p0 = lp[j], n0 = lnz[j];
    int group = 1;
    const auto joins = [&](int t) {  // column at + t continues the chain
      return at + t < path.size() && n0 > t && li[p0 + t] == path[at + t] &&
             lnz[path[at + t]] == n0 - t;
    };
    if (joins(1)) group = joins(2) && joins(3) ? 4 : 2;
    if (previous) {
      const int last = path[at + group - 1];
      for (int spins = 0; previous->load(std::memory_order_acquire) <= last; ++spins)
        if (spins < 64)
          _mm_pause();
        else
          std::this_thread::yield();  // the other thread may have lost its core
    }
    double z[4][kWidth], g[4][kWidth];
    double* lxs[4];
    for (int m = 0; m < group; ++m) {
      const int jm = path[at + m];
      double* wj = w + kWidth * static_cast<long>(jm);
      double dj = lx[lp[jm]];
      for (int k = 0; k < kWidth; ++k) {
        z[m][k] = wj[k];
        wj[k] = 0.0;
        g[m][k] = 0.0;
        if (z[m][k] == 0.0) continue;  // this column's path does not pass jm
        const double a =
            update ? alpha[k] + z[m][k] * z[m][k] / dj : alpha[k] - z[m][k] * z[m][k] / dj;
        dj *= a;
        g[m][k] = update ? -z[m][k] / dj : z[m][k] / dj;
        dj /= alpha[k];
        alpha[k] = a;
      }
      lx[lp[jm]] = dj;
      // the entries (j_t, j_m) inside the group, into the rows of W still to come
      for (int t = m + 1; t < group; ++t) {
        double* wt = w + kWidth * static_cast<long>(path[at + t]);
        double& lv = lx[lp[jm] + t - m];
        for (int k = 0; k < kWidth; ++k) {
          wt[k] = std::fma(-z[m][k], lv, wt[k]);
          lv = std::fma(-g[m][k], wt[k], lv);
        }
      }
      lxs[m] = lx + lp[jm] + group - m;  // the rows below the group
    }
    const int* rows = li + p0 + group;
    const int count = n0 - group;
    if (group == 1)
      updateRows<1>(z, g, rows, lxs, count, w);
    else if (group == 2)
      updateRows<2>(z, g, rows, lxs, count, w);
    else
      updateRows<4>(z, g, rows, lxs, count, w);
    at += group;
    if (progress)
      progress->store(at < path.size() ? path[at] : std::numeric_limits<int>::max(),
                      std::memory_order_release);
  }
  if (progress) progress->store(std::numeric_limits<int>::max(), std::memory_order_release);
}

// the kernel's passes over the columns in work.cp, work.ci, work.cx (see ldlUpdown): their
// paths first (the marks are shared), then the passes in order; on two threads (work.threads)
// pipelined when there is enough of them: the even passes here, the odd ones on a second
// thread with its own W, pass p working on a column only after pass p - 1 is done with it
// (the passes change each column of L in the same order as one thread would: the same bits)
void vectorPasses(bool update, int ncol, cholmod_factor& l, LdlUpdownWork& work) {
  const int* lp = static_cast<const int*>(l.p);
  const int* li = static_cast<const int*>(l.i);
  const int* lnz = static_cast<const int*>(l.nz);
  const int* cp = work.cp.data();
  const int* ci = work.ci.data();
  const int passes = (ncol + kWidth - 1) / kWidth;
  if (static_cast<int>(work.paths.size()) < passes) work.paths.resize(passes);
  long entries = 0;  // of L the passes walk
  for (int pass = 0; pass < passes; ++pass) {
    const int k0 = pass * kWidth, rank = std::min(kWidth, ncol - k0);
    const int s = nextStamp(work);
    std::vector<int>& path = work.paths[pass];
    path.clear();
    for (int k = 0; k < rank; ++k) {
      if (cp[k0 + k] == cp[k0 + k + 1]) continue;
      for (int j = ci[cp[k0 + k]]; j >= 0 && work.mark[j] != s;
           j = lnz[j] > 1 ? li[lp[j] + 1] : -1) {
        work.mark[j] = s;
        path.push_back(j);
        entries += lnz[j];
      }
    }
    std::sort(path.begin(), path.end());
  }
  const auto rankOf = [ncol](int pass) { return std::min(kWidth, ncol - pass * kWidth); };
  HelperRun other;
  std::vector<std::atomic<int>> progress(
      work.threads >= 2 && passes >= 2 && entries >= kMinPipelinedEntries ? passes : 0);
  if (!progress.empty()) {
    if (work.w2.size() != work.w.size()) work.w2.assign(work.w.size(), 0.0);
    for (auto& p : progress) p.store(-1, std::memory_order_relaxed);
    other = runOnHelper([&] {
      for (int pass = 1; pass < passes; pass += 2)
        runPass(update, pass * kWidth, rankOf(pass), work.paths[pass], l, work, work.w2.data(),
                &progress[pass - 1], pass + 1 < passes ? &progress[pass] : nullptr);
    });
  }
  if (!other.running()) {
    for (int pass = 0; pass < passes; ++pass)
      runPass(update, pass * kWidth, rankOf(pass), work.paths[pass], l, work, work.w.data(),
              nullptr, nullptr);
    work.pipelined = false;
    return;
  }
  for (int pass = 0; pass < passes; pass += 2)
    runPass(update, pass * kWidth, rankOf(pass), work.paths[pass], l, work, work.w.data(),
            pass > 0 ? &progress[pass - 1] : nullptr,
            pass + 1 < passes ? &progress[pass] : nullptr);
  other.wait();
  work.pipelined = true;
}

}  // namespace

bool ldlUpdownAvailable() { return __builtin_cpu_supports("avx512f"); }

bool ldlColumnFillsIn(const cholmod_factor& l, const int* rows, int count, LdlUpdownWork& work) {
  if (count <= 1) return false;
  const int* lp = static_cast<const int*>(l.p);
  const int* li = static_cast<const int*>(l.i);
  const int* lnz = static_cast<const int*>(l.nz);
  sizeMarks(work, l.n);
  const int r0 = rows[0];
  const int st = nextStamp(work);
  for (int p = lp[r0]; p < lp[r0] + lnz[r0]; ++p) work.mark[li[p]] = st;
  for (int q = 1; q < count; ++q)
    if (work.mark[rows[q]] != st) return true;
  return false;
}

bool ldlUpdown(bool update, const cholmod_sparse& c, cholmod_factor& l, LdlUpdownWork& work,
               cholmod_common& cm) {
  cholmod_sparse cc = c;  // cholmod_updown's argument is not const
  if (!ldlUpdownAvailable() || l.is_super || l.is_ll || l.itype != CHOLMOD_INT ||
      l.xtype != CHOLMOD_REAL || l.dtype != CHOLMOD_DOUBLE || c.itype != CHOLMOD_INT ||
      c.xtype != CHOLMOD_REAL || c.dtype != CHOLMOD_DOUBLE || !c.packed || !c.sorted ||
      c.nrow != l.n)
    return cholmod_updown(update, &cc, &l, &cm);
  const int ncol = static_cast<int>(c.ncol);
  sizeMarks(work, l.n);
  if (work.w.size() != kWidth * l.n) work.w.assign(kWidth * l.n, 0.0);
  // The kernel takes the columns that cannot fill in: every row in L's column at the
  // column's first row (then its path stays inside L's pattern: a column's pattern, but for
  // its parent, is in its parent's); cholmod_updown the others, after it (the order of the
  // rank-1 changes does not matter but to rounding)
  const int* p0 = static_cast<const int*>(c.p);
  const int* i0 = static_cast<const int*>(c.i);
  const double* x0 = static_cast<const double*>(c.x);
  std::vector<int>&cp = work.cp, &ci = work.ci, &restP = work.restP, &restI = work.restI;
  std::vector<double>&cx = work.cx, &restX = work.restX;
  cp.assign(1, 0);
  restP.assign(1, 0);
  ci.clear();
  cx.clear();
  restI.clear();
  restX.clear();
  // The kernel's columns in the order of their first rows (L's row order, a postorder of the
  // elimination tree: nearby first rows share more of their paths), so that the 8 columns of
  // a pass walk fewer columns of L between them. Measured (the passes' walked entries,
  // temporary instrumentation): 7.6 % fewer on liver_incision (30 frames), 6.2 % on esim
  // bench cut's 50k slab (30 frames), 1.5 % on slab_cut, where the shared top separators
  // carry the work. Ties keep C's order, so the order depends on C alone.
  std::vector<std::pair<int, int>>& order = work.order;
  order.clear();
  for (int k = 0; k < ncol; ++k) {
    if (p0[k] == p0[k + 1]) continue;
    if (ldlColumnFillsIn(l, i0 + p0[k], p0[k + 1] - p0[k], work)) {
      restI.insert(restI.end(), i0 + p0[k], i0 + p0[k + 1]);
      restX.insert(restX.end(), x0 + p0[k], x0 + p0[k + 1]);
      restP.push_back(static_cast<int>(restI.size()));
    } else {
      order.emplace_back(i0[p0[k]], k);
    }
  }
  std::stable_sort(order.begin(), order.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [first, k] : order) {
    ci.insert(ci.end(), i0 + p0[k], i0 + p0[k + 1]);
    cx.insert(cx.end(), x0 + p0[k], x0 + p0[k + 1]);
    cp.push_back(static_cast<int>(ci.size()));
  }
  work.vectorColumns += static_cast<long>(cp.size()) - 1;
  work.choleskyColumns += static_cast<long>(restP.size()) - 1;
  vectorPasses(update, static_cast<int>(cp.size()) - 1, l, work);
  if (restP.size() == 1) return true;
  cholmod_sparse rest = c;
  rest.ncol = restP.size() - 1;
  rest.nzmax = std::max<size_t>(1, restI.size());
  rest.p = restP.data();
  rest.i = restI.data();
  rest.x = restX.data();
  return cholmod_updown(update, &rest, &l, &cm);
}

void ldlRowSubtree(const cholmod_factor& l, int k, const int* from, int count, LdlUpdownWork& work,
                   std::vector<int>& out) {
  const int* lp = static_cast<const int*>(l.p);
  const int* li = static_cast<const int*>(l.i);
  const int* lnz = static_cast<const int*>(l.nz);
  sizeMarks(work, l.n);
  const int st = nextStamp(work);
  const size_t start = out.size();
  for (int q = 0; q < count; ++q) {
    int j = from[q];
    std::vector<int>& path = work.path;
    path.clear();
    while (j >= 0 && j < k && work.mark[j] != st) {
      path.push_back(j);
      j = lnz[j] > 1 ? li[lp[j] + 1] : -1;  // the parent in the elimination tree
    }
    if (j != k && (j < 0 || j > k)) continue;  // not below k in the tree: L(k, .) = 0 there
    for (int p : path) work.mark[p] = st;
    out.insert(out.end(), path.begin(), path.end());
  }
  std::sort(out.begin() + static_cast<long>(start), out.end());
}

bool ldlTakeRows(const std::vector<int>& rows,
                 const std::function<void(int, std::vector<int>&)>& rowSubtree, cholmod_factor& l,
                 std::vector<int>& wp, std::vector<int>& wi, std::vector<double>& wx) {
  const int* lp = static_cast<const int*>(l.p);
  const int* li = static_cast<const int*>(l.i);
  const int* lnz = static_cast<const int*>(l.nz);
  double* lx = static_cast<double*>(l.x);
  const auto deleted = [&](int row) { return std::binary_search(rows.begin(), rows.end(), row); };
  // W, from the columns H before anything changes
  wp.assign(1, 0);
  wi.clear();
  wx.clear();
  for (int k : rows)
    if (!(lx[lp[k]] > 0)) return false;
  for (int k : rows) {
    const double scale = std::sqrt(lx[lp[k]]);
    for (int q = lp[k] + 1; q < lp[k] + lnz[k]; ++q)
      if (lx[q] != 0 && !deleted(li[q])) {
        wi.push_back(li[q]);
        wx.push_back(lx[q] * scale);
      }
    if (static_cast<int>(wi.size()) > wp.back()) wp.push_back(static_cast<int>(wi.size()));
  }
  // rows H cleared in the columns before them (each row's subtree), then columns H
  std::vector<int> subtree;
  for (int k : rows) {
    subtree.clear();
    rowSubtree(k, subtree);
    for (int j : subtree) {
      const int* first = li + lp[j] + 1;
      const int* last = li + lp[j] + lnz[j];
      const int* at = std::lower_bound(first, last, k);
      if (at != last && *at == k) lx[at - li] = 0;
    }
  }
  for (int k : rows) {
    lx[lp[k]] = 1;
    for (int q = lp[k] + 1; q < lp[k] + lnz[k]; ++q) lx[q] = 0;
  }
  return true;
}

double pivotedLdl(Eigen::MatrixXd& g, double pivotShare, bool indefinite,
                  const std::function<void(double d, const Eigen::VectorXd& c)>& column) {
  const int m = static_cast<int>(g.rows());
  // a diagonal's size as a pivot: semidefinite, one <= 0 is round-off, never a pivot
  const auto size = [indefinite](double x) { return indefinite ? std::abs(x) : x; };
  double largest = 0;
  for (int a = 0; a < m; ++a) largest = std::max(largest, size(g(a, a)));
  std::vector<std::uint8_t> done(m, 0);
  Eigen::VectorXd c(m);
  for (;;) {
    double most = 0;
    for (int a = 0; a < m; ++a)
      if (!done[a]) most = std::max(most, size(g(a, a)));
    if (!(most > 1e-12 * largest)) break;
    int p = 0;
    while (done[p] || size(g(p, p)) < pivotShare * most) ++p;
    const double d = g(p, p);
    for (int a = 0; a < m; ++a) c[a] = done[a] ? 0.0 : (a >= p ? g(a, p) : g(p, a));
    column(d, c);
    g.selfadjointView<Eigen::Lower>().rankUpdate(c, -1 / d);
    done[p] = 1;
  }
  double rest = 0;
  for (int b = 0; b < m; ++b)
    for (int a = b; a < m; ++a)
      if (!done[a] && !done[b]) rest = std::max(rest, std::abs(g(a, b)));
  return rest == 0 ? 0.0 : rest / largest;  // (largest 0, rest not: infinite)
}

}  // namespace esim
