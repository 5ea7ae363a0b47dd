// Tests for sim/ldl_updown.cpp: the vectorized multiple-rank LDL' update against CHOLMOD's
// cholmod_updown on the same factor and columns (the factor's values, and the solve of the
// changed matrix), columns that would fill in left to CHOLMOD, a downdate back to the start,
// and a downdate that loses definiteness. Without AVX-512 every column goes to CHOLMOD and
// the same checks hold.
#include "sim/ldl_updown.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "sim/cholmod_view.h"
#include "tests/sim/grid_operator_util.h"

namespace esim {
namespace {

// a 3-D grid operator (7-point stencil plus a diagonal shift: symmetric positive definite),
// k x k x k nodes, lower triangle in CHOLMOD's form
struct Grid {
  cholmod_common cm;
  cholmod_sparse* a = nullptr;
  cholmod_factor* base = nullptr;  // simplicial LDL'
  int n = 0;
  explicit Grid(int k) {
    cholmod_start(&cm);
    cm.supernodal = CHOLMOD_SIMPLICIAL;
    cm.final_ll = false;
    n = k * k * k;
    a = testing_util::gridOperator(k, 1, cm);
    base = cholmod_analyze(a, &cm);
    cholmod_factorize(a, base, &cm);
    EXPECT_EQ(cm.status, CHOLMOD_OK);
    EXPECT_FALSE(base->is_super);
    EXPECT_FALSE(base->is_ll);
  }
  ~Grid() {
    cholmod_free_factor(&base, &cm);
    cholmod_free_sparse(&a, &cm);
    cholmod_finish(&cm);
  }
  cholmod_factor* copy() { return cholmod_copy_factor(base, &cm); }
  // column j of L: its rows below the diagonal
  std::vector<int> below(const cholmod_factor* l, int j) const {
    const int* lp = static_cast<const int*>(l->p);
    const int* li = static_cast<const int*>(l->i);
    const int* lnz = static_cast<const int*>(l->nz);
    return std::vector<int>(li + lp[j] + 1, li + lp[j] + lnz[j]);
  }
};

// columns of C in L's row order: (rows ascending, values)
struct Columns {
  std::vector<int> p{0}, i;
  std::vector<double> x;
  void add(const std::vector<int>& rows, std::uint32_t& seed) {
    for (int r : rows) {
      seed = seed * 1664525u + 1013904223u;
      i.push_back(r);
      x.push_back(0.2 + 0.6 * static_cast<double>(seed >> 8) / (1u << 24));
    }
    p.push_back(static_cast<int>(i.size()));
  }
  cholmod_sparse view(int n) {
    return cholmodViewColumns(n, p.size() - 1, p.data(), i.data(), x.data());
  }
};

// fill-free columns: a row r0 and some of the rows of L's column r0 (every third)
Columns fillFree(Grid& g, int rank, std::uint32_t seed) {
  Columns c;
  for (int k = 0; k < rank; ++k) {
    const int r0 = (37 * k + 11) % (g.n - 10);
    std::vector<int> rows{r0};
    const std::vector<int> below = g.below(g.base, r0);
    for (size_t q = k % 3; q < below.size(); q += 3) rows.push_back(below[q]);
    c.add(rows, seed);
  }
  return c;
}

double maxAbs(const cholmod_factor* l) {
  double m = 0;
  for (size_t q = 0; q < l->nzmax; ++q) m = std::max(m, std::abs(static_cast<double*>(l->x)[q]));
  return m;
}

// the largest difference of the two factors' values (same pattern), relative
double valueDifference(const cholmod_factor* a, const cholmod_factor* b) {
  EXPECT_EQ(a->nzmax, b->nzmax);
  double d = 0;
  for (size_t q = 0; q < std::min(a->nzmax, b->nzmax); ++q)
    d = std::max(d, std::abs(static_cast<double*>(a->x)[q] - static_cast<double*>(b->x)[q]));
  return d / maxAbs(b);
}

// x = A^-1 b through the factor, b = (1, 2, 3, ...)
Eigen::VectorXd solveWith(Grid& g, cholmod_factor* l) {
  cholmod_dense* b = cholmod_zeros(g.n, 1, CHOLMOD_REAL, &g.cm);
  for (int i = 0; i < g.n; ++i) static_cast<double*>(b->x)[i] = 1 + i % 5;
  cholmod_dense* x = cholmod_solve(CHOLMOD_A, l, b, &g.cm);
  Eigen::VectorXd v = Eigen::Map<const Eigen::VectorXd>(static_cast<double*>(x->x), g.n);
  cholmod_free_dense(&x, &g.cm);
  cholmod_free_dense(&b, &g.cm);
  return v;
}

TEST(LdlUpdown, UpdateAndDowndateMatchCholmodUpdown) {
  Grid g(9);  // 729 rows
  const bool vector = ldlUpdownAvailable();
  if (!vector) std::cout << "no AVX-512 here: every column goes to cholmod_updown\n";
  // ranks: one pass part-filled, one full, several with a remainder
  for (int rank : {1, 5, 8, 13, 21}) {
    SCOPED_TRACE("rank " + std::to_string(rank));
    Columns c = fillFree(g, rank, 1234u + rank);
    cholmod_sparse cs = c.view(g.n);
    cholmod_factor* mine = g.copy();
    cholmod_factor* theirs = g.copy();
    LdlUpdownWork work;
    ASSERT_TRUE(ldlUpdown(true, cs, *mine, work, g.cm));
    ASSERT_TRUE(cholmod_updown(true, &cs, theirs, &g.cm));
    EXPECT_EQ(work.vectorColumns, vector ? rank : 0);
    EXPECT_EQ(work.choleskyColumns, vector ? 0 : rank);
    EXPECT_LT(valueDifference(mine, theirs), 1e-13);
    EXPECT_GT(valueDifference(mine, g.base), 1e-3);  // it did change
    // and back: the downdate by the same columns returns the factor (same workspace: left
    // zero by the update)
    ASSERT_TRUE(ldlUpdown(false, cs, *mine, work, g.cm));
    EXPECT_LT(valueDifference(mine, g.base), 1e-12);
    for (double w : work.w) ASSERT_EQ(w, 0.0);
    cholmod_free_factor(&mine, &g.cm);
    cholmod_free_factor(&theirs, &g.cm);
  }
}

// LdlUpdownWork::threads 2: the passes pipelined on two threads change L exactly as one thread
// does (the same bits), for an update and a downdate of many passes, and leave both W zero
// the kernel takes its columns in the order of their first rows (passes of nearby columns
// walk less of L): columns given in another order give the same factor to the bit, and the
// same as cholmod_updown to rounding
TEST(LdlUpdown, TheColumnsOrderDoesNotChangeTheFactor) {
  if (!ldlUpdownAvailable()) GTEST_SKIP() << "no AVX-512: every column goes to cholmod_updown";
  Grid g(9);
  // 20 fill-free columns with distinct first rows, and the same columns reversed
  const Columns forward = fillFree(g, 20, 7);
  Columns reversed;
  for (int k = static_cast<int>(forward.p.size()) - 2; k >= 0; --k) {
    reversed.i.insert(reversed.i.end(), forward.i.begin() + forward.p[k],
                      forward.i.begin() + forward.p[k + 1]);
    reversed.x.insert(reversed.x.end(), forward.x.begin() + forward.p[k],
                      forward.x.begin() + forward.p[k + 1]);
    reversed.p.push_back(static_cast<int>(reversed.i.size()));
  }
  std::vector<int> firsts;
  for (size_t k = 0; k + 1 < forward.p.size(); ++k) firsts.push_back(forward.i[forward.p[k]]);
  std::sort(firsts.begin(), firsts.end());
  ASSERT_EQ(std::unique(firsts.begin(), firsts.end()), firsts.end()) << "first rows repeat";
  cholmod_factor* a = g.copy();
  cholmod_factor* b = g.copy();
  cholmod_factor* reference = g.copy();
  LdlUpdownWork wa, wb;
  Columns f = forward, r = reversed, ref = forward;
  cholmod_sparse ca = f.view(g.n), cb = r.view(g.n), cr = ref.view(g.n);
  ASSERT_TRUE(ldlUpdown(true, ca, *a, wa, g.cm));
  ASSERT_TRUE(ldlUpdown(true, cb, *b, wb, g.cm));
  ASSERT_TRUE(cholmod_updown(true, &cr, reference, &g.cm));
  EXPECT_EQ(wa.vectorColumns, 20);
  EXPECT_EQ(valueDifference(a, b), 0.0);
  EXPECT_LT(valueDifference(a, reference), 1e-13);
  cholmod_free_factor(&reference, &g.cm);
  cholmod_free_factor(&b, &g.cm);
  cholmod_free_factor(&a, &g.cm);
}

TEST(LdlUpdown, PipelinedPassesGiveTheSameBitsAsOneThread) {
  if (!ldlUpdownAvailable()) GTEST_SKIP() << "no AVX-512 here: no kernel to pipeline";
  Grid g(24);  // 13 824 rows: the passes walk far more than the pipeline's minimum
  for (int rank : {9, 16, 61}) {
    SCOPED_TRACE("rank " + std::to_string(rank));
    Columns c = fillFree(g, rank, 77u + rank);
    cholmod_sparse cs = c.view(g.n);
    cholmod_factor* one = g.copy();
    cholmod_factor* two = g.copy();
    LdlUpdownWork w1, w2;
    w2.threads = 2;
    for (bool update : {true, false}) {
      ASSERT_TRUE(ldlUpdown(update, cs, *one, w1, g.cm));
      ASSERT_TRUE(ldlUpdown(update, cs, *two, w2, g.cm));
      EXPECT_FALSE(w1.pipelined);
      EXPECT_TRUE(w2.pipelined);
      ASSERT_EQ(one->nzmax, two->nzmax);
      const double* a = static_cast<const double*>(one->x);
      const double* b = static_cast<const double*>(two->x);
      size_t differ = 0;
      for (size_t q = 0; q < one->nzmax; ++q) differ += a[q] != b[q];
      EXPECT_EQ(differ, 0u) << (update ? "update" : "downdate");
    }
    EXPECT_LT(valueDifference(two, g.base), 1e-12);  // and back
    for (double w : w2.w) ASSERT_EQ(w, 0.0);
    for (double w : w2.w2) ASSERT_EQ(w, 0.0);
    cholmod_free_factor(&one, &g.cm);
    cholmod_free_factor(&two, &g.cm);
  }
}

// a column with a row outside L's column at its first row would fill in: it goes to
// cholmod_updown (after the others), and the factor solves the changed matrix as CHOLMOD's
TEST(LdlUpdown, ColumnsThatWouldFillInGoToCholmod) {
  Grid g(8);
  Columns c = fillFree(g, 10, 99u);
  // the filling column: row 0 and a row not in L's column 0
  const std::vector<int> below = g.below(g.base, 0);
  int outside = g.n - 1;
  while (std::binary_search(below.begin(), below.end(), outside)) --outside;
  ASSERT_GT(outside, 0);
  std::uint32_t seed = 5;
  c.add({0, outside}, seed);
  LdlUpdownWork work;
  EXPECT_FALSE(ldlColumnFillsIn(*g.base, c.i.data(), c.p[1] - c.p[0], work));
  EXPECT_TRUE(ldlColumnFillsIn(*g.base, c.i.data() + c.p[10], 2, work));
  cholmod_sparse cs = c.view(g.n);
  cholmod_factor* mine = g.copy();
  cholmod_factor* theirs = g.copy();
  ASSERT_TRUE(ldlUpdown(true, cs, *mine, work, g.cm));
  ASSERT_TRUE(cholmod_updown(true, &cs, theirs, &g.cm));
  EXPECT_EQ(work.vectorColumns + work.choleskyColumns, 11);
  EXPECT_EQ(work.choleskyColumns, ldlUpdownAvailable() ? 1 : 11);
  const Eigen::VectorXd a = solveWith(g, mine), b = solveWith(g, theirs);
  EXPECT_LT((a - b).norm() / b.norm(), 1e-13);
  EXPECT_GT((a - solveWith(g, g.base)).norm() / b.norm(), 1e-3);
  cholmod_free_factor(&mine, &g.cm);
  cholmod_free_factor(&theirs, &g.cm);
}

// a downdate by more than the matrix holds leaves a pivot <= 0 (what StructuralPhase checks
// on the columns it walked), as cholmod_updown does
TEST(LdlUpdown, DowndateLosingDefinitenessLeavesANonPositivePivot) {
  Grid g(6);
  const int j = 40;
  const double* lx = static_cast<const double*>(g.base->x);
  const double djj = lx[static_cast<const int*>(g.base->p)[j]];
  Columns c;
  c.p = {0, 1};
  c.i = {j};
  c.x = {2 * std::sqrt(djj)};  // e_j e_j' * 4 D_jj: more than A_jj
  cholmod_sparse cs = c.view(g.n);
  for (int kernel = 0; kernel < 2; ++kernel) {
    cholmod_factor* l = g.copy();
    LdlUpdownWork work;
    if (kernel)
      ldlUpdown(false, cs, *l, work, g.cm);
    else
      cholmod_updown(false, &cs, l, &g.cm);
    const double* x = static_cast<const double*>(l->x);
    EXPECT_LE(x[static_cast<const int*>(l->p)[j]], 0.0) << (kernel ? "kernel" : "cholmod");
    cholmod_free_factor(&l, &g.cm);
  }
}

// pivotedLdl: a semidefinite g of rank 2 (3 x 3) gives two columns whose sum c c' / d is g, the
// rest round-off; an indefinite g gives a negative pivot (an update column) and is g again;
// one whose diagonal is zero gives no column and says its rest is not round-off; a pivot
// tiny against the largest diagonal is passed over for the next index
TEST(PivotedLdl, ColumnsSumToTheMatrixAndTheRestSaysWhatIsLeft) {
  const auto run = [](Eigen::MatrixXd g, bool indefinite, double share, std::vector<double>& d,
                      std::vector<int>& first) {
    const Eigen::MatrixXd g0 = g;
    Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(g.rows(), g.cols());
    d.clear();
    first.clear();
    const double rest = pivotedLdl(g, share, indefinite, [&](double p, const Eigen::VectorXd& c) {
      d.push_back(p);
      int k = 0;
      while (c[k] == 0.0) ++k;
      first.push_back(k);
      sum += c * c.transpose() / p;
    });
    if (rest <= 1e-12) EXPECT_LT((sum - g0).norm(), 1e-14 * g0.norm());
    return rest;
  };
  std::vector<double> d;
  std::vector<int> first;
  Eigen::Vector3d u(1, 2, 3), v(0, 1, -1);
  EXPECT_LE(run(u * u.transpose() + v * v.transpose(), false, 1e-3, d, first), 1e-12);
  EXPECT_EQ(d.size(), 2u);
  EXPECT_EQ(first, (std::vector<int>{0, 1}));
  Eigen::Matrix2d h;
  h << 1, 2, 2, 1;  // eigenvalues 3 and -1
  EXPECT_LE(run(h, true, 1e-3, d, first), 1e-12);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0], 1.0);
  EXPECT_EQ(d[1], -3.0);
  h << 0, 1, 1, 0;
  EXPECT_GT(run(h, true, 1e-3, d, first), 1e-12);
  EXPECT_TRUE(d.empty());
  h << 1e-6, 0, 0, 1;  // the first diagonal under 1e-3 of the largest
  run(h, false, 1e-3, d, first);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(first[0], 1);
  EXPECT_EQ(first[1], 0);
}

}  // namespace
}  // namespace esim
