// Tests for sim/ldl_solve.cpp: the two-thread LDL' solve against CHOLMOD's cholmod_solve on
// the same factor (a 3-component grid operator ordered by nested dissection, as the
// structural phase's), with one and two threads, the same bits every run, the plan's
// split (both threads busy, balanced as promised), after an update and a row deletion
// (explicit zeros, a changed pattern: a new plan), and degenerate factors (one unknown, a
// diagonal: a forest of single columns); its backward half alone (ldlSolveBackward).
#include "sim/ldl_solve.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <vector>

#include "tests/sim/grid_operator_util.h"

extern "C" void openblas_set_num_threads(int num_threads);

namespace esim {
namespace {

// A = (7-point grid operator + shift) kron M3, k^3 nodes, 3 components each (SPD: both
// factors are), lower triangle; factorized supernodal by METIS and converted to simplicial
// LDL' (what the structural phase solves with after its first update)
struct Grid3 {
  cholmod_common cm;
  cholmod_sparse* a = nullptr;
  cholmod_factor* l = nullptr;
  int n = 0;
  explicit Grid3(int k) {
    openblas_set_num_threads(1);  // as the structural phase (BLAS threads would only spin)
    cholmod_start(&cm);
    cm.print = 0;
    cm.nmethods = 1;
    cm.method[0].ordering = CHOLMOD_METIS;
    n = 3 * k * k * k;
    a = testing_util::gridOperator(k, 3, cm);
    l = cholmod_analyze(a, &cm);
    cholmod_factorize(a, l, &cm);
    EXPECT_EQ(cm.status, CHOLMOD_OK);
    cholmod_change_factor(CHOLMOD_REAL, false, false, false, false, l, &cm);
    EXPECT_TRUE(ldlSolveSupports(*l));
  }
  ~Grid3() {
    cholmod_free_factor(&l, &cm);
    cholmod_free_sparse(&a, &cm);
    cholmod_finish(&cm);
  }
  std::vector<double> rhs(std::uint32_t seed) const {
    std::vector<double> b(n);
    for (double& v : b) {
      seed = seed * 1664525u + 1013904223u;
      v = static_cast<double>(seed >> 8) / (1u << 24) - 0.5;
    }
    return b;
  }
  // CHOLMOD's own solve with the same factor
  std::vector<double> cholmodSolve(const std::vector<double>& b) {
    cholmod_dense bd{};
    bd.nrow = bd.nzmax = bd.d = n;
    bd.ncol = 1;
    bd.x = const_cast<double*>(b.data());
    bd.xtype = CHOLMOD_REAL;
    bd.dtype = CHOLMOD_DOUBLE;
    cholmod_dense* x = cholmod_solve(CHOLMOD_A, l, &bd, &cm);
    std::vector<double> out(static_cast<double*>(x->x), static_cast<double*>(x->x) + n);
    cholmod_free_dense(&x, &cm);
    return out;
  }
};

double relativeDifference(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0, den = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    num += (a[k] - b[k]) * (a[k] - b[k]);
    den += b[k] * b[k];
  }
  return std::sqrt(num / den);
}

TEST(LdlSolve, MatchesCholmodWithOneAndTwoThreadsAndSplitsTheWorkEvenly) {
  Grid3 g(12);  // 5184 unknowns
  const std::vector<double> b = g.rhs(7), want = g.cholmodSolve(b);
  std::vector<double> one(g.n);
  for (int threads : {1, 2}) {
    LdlSolveWork work;
    std::vector<double> x(g.n);
    ldlSolve(*g.l, b.data(), x.data(), threads, work, 100000);
    EXPECT_LT(relativeDifference(x, want), 1e-13) << threads << " threads";
    EXPECT_EQ(work.threadsUsed, threads);
    // both shares busy; the heavier at most 55 % of the subtrees' work (the plan's rule),
    // the columns of the top (one thread) under a fifth of L on this grid
    const long total = work.work[0] + work.work[1] + work.work[2];
    const int* nz = static_cast<const int*>(g.l->nz);
    EXPECT_EQ(total, std::accumulate(nz, nz + g.n, 0L)) << "every entry of L in one share";
    EXPECT_GT(work.work[0], 0);
    EXPECT_GT(work.work[1], 0);
    EXPECT_LE(std::max(work.work[0], work.work[1]), 0.55 * (work.work[0] + work.work[1]));
    EXPECT_LT(work.work[2], 0.2 * total);
    if (threads == 1)
      one = x;
    else
      EXPECT_EQ(x, one) << "one thread runs the same plan: the same bits";
  }
  // below the minimum for a split: one share
  LdlSolveWork work;
  std::vector<double> x(g.n);
  ldlSolve(*g.l, b.data(), x.data(), 2, work, 100000000);
  EXPECT_EQ(work.threadsUsed, 1);
  EXPECT_EQ(work.work[1] + work.work[2], 0);
  EXPECT_LT(relativeDifference(x, want), 1e-13);
}

// ldlSolveBackward: from y = L^-1 P b (CHOLMOD's permutation and forward solve), the second
// half gives A^-1 b, on one thread and split over two with the same bits
TEST(LdlSolve, TheBackwardHalfFromCholmodsForwardHalfIsTheWholeSolve) {
  Grid3 g(12);
  const std::vector<double> b = g.rhs(11), want = g.cholmodSolve(b);
  cholmod_dense bd{};
  bd.nrow = bd.nzmax = bd.d = g.n;
  bd.ncol = 1;
  bd.x = const_cast<double*>(b.data());
  bd.xtype = CHOLMOD_REAL;
  bd.dtype = CHOLMOD_DOUBLE;
  cholmod_dense* pb = cholmod_solve(CHOLMOD_P, g.l, &bd, &g.cm);
  cholmod_dense* y = cholmod_solve(CHOLMOD_L, g.l, pb, &g.cm);
  ASSERT_NE(y, nullptr);
  std::vector<double> one(g.n), two(g.n);
  LdlSolveWork work;
  ldlSolveBackward(*g.l, static_cast<const double*>(y->x), one.data(), 1, work, 100000);
  EXPECT_EQ(work.threadsUsed, 1);
  ldlSolveBackward(*g.l, static_cast<const double*>(y->x), two.data(), 2, work, 100000);
  EXPECT_EQ(work.threadsUsed, 2);
  EXPECT_LT(relativeDifference(one, want), 1e-13);
  EXPECT_EQ(one, two);
  cholmod_free_dense(&y, &g.cm);
  cholmod_free_dense(&pb, &g.cm);
}

TEST(LdlSolve, GivesTheSameBitsEveryRunAndKeepsItsPlan) {
  Grid3 g(10);
  const std::vector<double> b = g.rhs(3);
  LdlSolveWork work;
  std::vector<double> first(g.n), again(g.n);
  ldlSolve(*g.l, b.data(), first.data(), 2, work, 0);
  const LdlSolvePlan* plan = work.plan.get();
  for (int run = 0; run < 20; ++run) {
    ldlSolve(*g.l, b.data(), again.data(), 2, work, 0);
    ASSERT_EQ(first, again) << "run " << run;
  }
  EXPECT_EQ(work.plan.get(), plan);
}

TEST(LdlSolve, FollowsAnUpdateAndARowDeletion) {
  Grid3 g(9);
  // a rank-2 update on a few rows, then row 40 deleted (its row and column of L zeroed,
  // D = 1: the identity row of the matrix), as the structural phase's removals do
  cholmod_sparse* c = cholmod_allocate_sparse(g.n, 2, 6, true, true, 0, CHOLMOD_REAL, &g.cm);
  int* cp = static_cast<int*>(c->p);
  int* ci = static_cast<int*>(c->i);
  double* cx = static_cast<double*>(c->x);
  const int* perm = static_cast<const int*>(g.l->Perm);
  std::vector<int> rowOf(g.n);
  for (int k = 0; k < g.n; ++k) rowOf[perm[k]] = k;
  std::vector<int> rows = {rowOf[10], rowOf[11], rowOf[500], rowOf[1500]};
  std::sort(rows.begin(), rows.end());
  cp[0] = 0;
  cp[1] = 3;
  cp[2] = 6;
  for (int q = 0; q < 3; ++q) {
    ci[q] = rows[q];
    cx[q] = 0.3 + 0.1 * q;
    ci[3 + q] = rows[q + 1];
    cx[3 + q] = 0.5 - 0.1 * q;
  }
  LdlSolveWork work;
  std::vector<double> x(g.n);
  const std::vector<double> b = g.rhs(11);
  ldlSolve(*g.l, b.data(), x.data(), 2, work, 0);
  ASSERT_TRUE(cholmod_updown(true, c, g.l, &g.cm));
  ldlSolve(*g.l, b.data(), x.data(), 2, work, 0);
  EXPECT_LT(relativeDifference(x, g.cholmodSolve(b)), 1e-13);
  ASSERT_TRUE(cholmod_rowdel(rowOf[40], nullptr, g.l, &g.cm));
  std::vector<double> b2 = b;
  b2[40] = 0;
  ldlSolve(*g.l, b2.data(), x.data(), 2, work, 0);
  const std::vector<double> want = g.cholmodSolve(b2);
  EXPECT_LT(relativeDifference(x, want), 1e-13);
  EXPECT_EQ(x[40], 0.0);
  ldlSolve(*g.l, b2.data(), x.data(), 1, work);
  EXPECT_LT(relativeDifference(x, want), 1e-13);
  cholmod_free_sparse(&c, &g.cm);
}

TEST(LdlSolve, SolvesAForestOfSingleColumnsAndOneUnknown) {
  for (int n : {1, 2, 50}) {
    cholmod_common cm;
    cholmod_start(&cm);
    cm.print = 0;
    cm.supernodal = CHOLMOD_SIMPLICIAL;
    cm.final_ll = false;
    cholmod_sparse* a = cholmod_speye(n, n, CHOLMOD_REAL, &cm);
    double* ax = static_cast<double*>(a->x);
    for (int k = 0; k < n; ++k) ax[k] = 1.0 + k;
    a->stype = -1;
    cholmod_factor* l = cholmod_analyze(a, &cm);
    cholmod_factorize(a, l, &cm);
    ASSERT_TRUE(ldlSolveSupports(*l));
    std::vector<double> b(n), x(n);
    for (int k = 0; k < n; ++k) b[k] = 2.0 * (1.0 + k);
    LdlSolveWork work;
    ldlSolve(*l, b.data(), x.data(), 2, work, 0);
    for (int k = 0; k < n; ++k) EXPECT_DOUBLE_EQ(x[k], 2.0) << n << " unknowns, row " << k;
    EXPECT_EQ(work.threadsUsed, n > 1 ? 2 : 1);  // one column: nothing to share
    cholmod_free_factor(&l, &cm);
    cholmod_free_sparse(&a, &cm);
    cholmod_finish(&cm);
  }
}

// irregular trees: random sparse SPD matrices (random couplings, diagonally dominant; some
// rows uncoupled: a forest), AMD or METIS, every one split (minimum 0): CHOLMOD's answer to
// 1e-12 on one thread and two, the same bits on both
TEST(LdlSolve, RandomSparseMatricesMatchCholmod) {
  openblas_set_num_threads(1);  // the supernodal factorizations: as the phase (see Grid3)
  std::uint32_t seed = 2026;
  const auto next = [&seed](std::uint32_t m) {
    seed = seed * 1664525u + 1013904223u;
    return (seed >> 8) % m;
  };
  for (int trial = 0; trial < 24; ++trial) {
    const int n = 1 + static_cast<int>(next(600));
    const int couplings = static_cast<int>(next(4 * n + 1));
    cholmod_common cm;
    cholmod_start(&cm);
    cm.print = 0;
    cm.supernodal = trial % 2 ? CHOLMOD_SIMPLICIAL : CHOLMOD_SUPERNODAL;
    cm.final_ll = false;
    if (trial % 3 == 0) {
      cm.nmethods = 1;
      cm.method[0].ordering = CHOLMOD_METIS;
    }
    cholmod_triplet* t = cholmod_allocate_triplet(n, n, n + couplings, -1, CHOLMOD_REAL, &cm);
    std::vector<double> rowSum(n, 0.0);
    for (int k = 0; k < couplings; ++k) {
      int i = static_cast<int>(next(n)), j = static_cast<int>(next(n));
      if (i == j) continue;
      if (i < j) std::swap(i, j);
      const double v = -0.1 - static_cast<double>(next(1000)) / 1000.0;
      static_cast<int*>(t->i)[t->nnz] = i;
      static_cast<int*>(t->j)[t->nnz] = j;
      static_cast<double*>(t->x)[t->nnz++] = v;
      rowSum[i] += std::abs(v);
      rowSum[j] += std::abs(v);
    }
    for (int i = 0; i < n; ++i) {
      static_cast<int*>(t->i)[t->nnz] = i;
      static_cast<int*>(t->j)[t->nnz] = i;
      static_cast<double*>(t->x)[t->nnz++] = rowSum[i] + 0.5;
    }
    cholmod_sparse* a = cholmod_triplet_to_sparse(t, 0, &cm);
    cholmod_free_triplet(&t, &cm);
    cholmod_factor* l = cholmod_analyze(a, &cm);
    cholmod_factorize(a, l, &cm);
    ASSERT_EQ(cm.status, CHOLMOD_OK) << "trial " << trial;
    cholmod_change_factor(CHOLMOD_REAL, false, false, false, false, l, &cm);
    ASSERT_TRUE(ldlSolveSupports(*l));
    cholmod_dense* b = cholmod_zeros(n, 1, CHOLMOD_REAL, &cm);
    for (int i = 0; i < n; ++i) static_cast<double*>(b->x)[i] = 1.0 + next(100) / 50.0;
    cholmod_dense* want = cholmod_solve(CHOLMOD_A, l, b, &cm);
    const std::vector<double> bv(static_cast<double*>(b->x), static_cast<double*>(b->x) + n);
    const std::vector<double> wv(static_cast<double*>(want->x), static_cast<double*>(want->x) + n);
    std::vector<double> x1(n), x2(n);
    LdlSolveWork w1, w2;
    ldlSolve(*l, bv.data(), x1.data(), 1, w1, 0);
    ldlSolve(*l, bv.data(), x2.data(), 2, w2, 0);
    EXPECT_LT(relativeDifference(x2, wv), 1e-12) << "trial " << trial << ", n " << n;
    EXPECT_EQ(x1, x2) << "trial " << trial;
    EXPECT_EQ(w1.work[0] + w1.work[1] + w1.work[2], w2.work[0] + w2.work[1] + w2.work[2]);
    cholmod_free_dense(&want, &cm);
    cholmod_free_dense(&b, &cm);
    cholmod_free_factor(&l, &cm);
    cholmod_free_sparse(&a, &cm);
    cholmod_finish(&cm);
  }
}

TEST(LdlSolve, TakesOnlySimplicialLdlFactors) {
  Grid3 g(4);
  cholmod_factor* ll = cholmod_copy_factor(g.l, &g.cm);
  cholmod_change_factor(CHOLMOD_REAL, true, false, false, false, ll, &g.cm);  // LL'
  EXPECT_FALSE(ldlSolveSupports(*ll));
  cholmod_free_factor(&ll, &g.cm);
  EXPECT_TRUE(ldlSolveSupports(*g.l));
}

}  // namespace
}  // namespace esim
