// Tests for sim/two_level_preconditioner.cpp: the aggregates (a partition into connected
// groups), the preconditioner's symmetry and definiteness (also with positive off-diagonal
// entries, and with rows excluded from the coarse space, a whole aggregate among them), CG
// with it reaching a direct solve's answer, iterations that stay flat as a grid is refined
// where Jacobi's grow, the deflated form equal to it where CG runs it, and the error messages.
#include "sim/two_level_preconditioner.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <queue>
#include <string>
#include <vector>

#include "sim/core_error.h"

namespace esim {
namespace {

// a k x k x k grid's 7-point Laplacian with the nodes of the bottom face held at 0
// (eliminated into the diagonal): SPD, both triangles stored. A positive `skew` adds a
// positive coupling between diagonal neighbours (x+1, y+1), as obtuse tets give, with the
// diagonal raised to keep it positive definite.
SparseMatrix gridLaplacian(int k, double skew = 0) {
  const int n = k * k * k;
  std::vector<Eigen::Triplet<double>> t;
  const auto id = [k](int x, int y, int z) { return x + k * (y + k * z); };
  for (int z = 0; z < k; ++z)
    for (int y = 0; y < k; ++y)
      for (int x = 0; x < k; ++x) {
        const int i = id(x, y, z);
        double diag = z == 0 ? 1.0 : 0.0;  // the held face below
        const auto couple = [&](int j, double w) {
          t.emplace_back(i, j, -w);
          t.emplace_back(j, i, -w);
          diag += std::abs(w);
          t.emplace_back(j, j, std::abs(w));
        };
        if (x + 1 < k) couple(id(x + 1, y, z), 1.0 + 0.3 * ((i * 7) % 5));  // varied weights
        if (y + 1 < k) couple(id(x, y + 1, z), 1.0);
        if (z + 1 < k) couple(id(x, y, z + 1), 2.0);
        if (skew > 0 && x + 1 < k && y + 1 < k) couple(id(x + 1, y + 1, z), -skew);
        t.emplace_back(i, i, diag);
      }
  SparseMatrix a(n, n);
  a.setFromTriplets(t.begin(), t.end());
  a.makeCompressed();
  return a;
}

// M^-1 as a dense matrix, column by column
Eigen::MatrixXd denseInverse(const TwoLevelPreconditioner& p, int n) {
  Eigen::MatrixXd m(n, n);
  Eigen::VectorXd z;
  for (int j = 0; j < n; ++j) {
    p.apply(Eigen::VectorXd::Unit(n, j), z);
    m.col(j) = z;
  }
  return m;
}

// k with the rows and columns `out` marks replaced by the identity's, as the contact rows of
// the potential's reduced system are
SparseMatrix withRowsExcluded(const SparseMatrix& k, const std::vector<char>& out) {
  SparseMatrix a = k;
  for (int j = 0; j < a.cols(); ++j)
    for (SparseMatrix::InnerIterator it(a, j); it; ++it)
      if (out[it.row()] || out[j]) it.valueRef() = it.row() == j ? 1.0 : 0.0;
  return a;
}

// preconditioned CG from x (in: the start) to ||b - A x|| <= tol ||b||; returns the
// iterations (x out), -1 if 10000 do not reach it
template <class Apply>
int cgFrom(const SparseMatrix& a, const Eigen::VectorXd& b, double tol, Apply precondition,
           Eigen::VectorXd& x) {
  Eigen::VectorXd r = b - a * x, z(b.size());
  precondition(r, z);
  Eigen::VectorXd p = z;
  double rz = r.dot(z);
  for (int it = 1; it <= 10000; ++it) {
    const Eigen::VectorXd ap = a * p;
    const double alpha = rz / p.dot(ap);
    x += alpha * p;
    r -= alpha * ap;
    if (r.norm() <= tol * b.norm()) return it;
    precondition(r, z);
    const double rzNew = r.dot(z);
    p = z + (rzNew / rz) * p;
    rz = rzNew;
  }
  return -1;
}

// ... from zero
template <class Apply>
int cg(const SparseMatrix& a, const Eigen::VectorXd& b, double tol, Apply precondition,
       Eigen::VectorXd& x) {
  x.setZero(b.size());
  return cgFrom(a, b, tol, precondition, x);
}

TEST(TwoLevelPreconditioner, AggregatesPartitionTheGraphIntoConnectedGroups) {
  const SparseMatrix a = gridLaplacian(10);
  const int n = static_cast<int>(a.rows());
  for (int passes : {1, 2}) {
    SCOPED_TRACE(std::to_string(passes) + " pass(es)");
    TwoLevelPreconditioner p;
    p.setGraph(a, passes);
    const int m = p.numAggregates();
    const std::vector<int>& of = p.aggregateOf();
    ASSERT_EQ(static_cast<int>(of.size()), n);
    std::vector<int> size(m, 0);
    for (int i = 0; i < n; ++i) {
      ASSERT_GE(of[i], 0);
      ASSERT_LT(of[i], m);
      ++size[of[i]];
    }
    EXPECT_GT(*std::min_element(size.begin(), size.end()), 0);  // no aggregate empty
    // 7-point stencil: a first-pass aggregate is a node and its (up to 6) neighbours, with
    // leftovers attached; the second groups those
    if (passes == 1) {
      EXPECT_GT(m, n / 12);
      EXPECT_LT(m, n / 4);
    } else {
      EXPECT_LT(m, n / 30);
    }
    // each aggregate connected: a search from one member inside the aggregate meets all
    std::vector<char> seen(n, 0);
    int components = 0;
    for (int s = 0; s < n; ++s) {
      if (seen[s]) continue;
      ++components;
      std::queue<int> q;
      q.push(s);
      seen[s] = 1;
      while (!q.empty()) {
        const int i = q.front();
        q.pop();
        for (SparseMatrix::InnerIterator it(a, i); it; ++it)
          if (!seen[it.row()] && of[it.row()] == of[i]) {
            seen[it.row()] = 1;
            q.push(static_cast<int>(it.row()));
          }
      }
    }
    EXPECT_EQ(components, m);
  }
}

TEST(TwoLevelPreconditioner, IsSymmetricPositiveDefiniteWithRowsExcluded) {
  // positive off-diagonal entries (no M-matrix), rows excluded as contact rows are: their
  // rows and columns of A the identity
  for (double skew : {0.0, 0.4}) {
    SCOPED_TRACE("skew " + std::to_string(skew));
    const SparseMatrix k = gridLaplacian(6, skew);
    const int n = static_cast<int>(k.rows());
    TwoLevelPreconditioner p;
    p.setGraph(k, 1);
    // the rows of aggregate 0 (all of them: an aggregate without a column) and two more
    std::vector<int> excluded;
    for (int i = 0; i < n; ++i)
      if (p.aggregateOf()[i] == 0) excluded.push_back(i);
    excluded.push_back(n / 2);
    excluded.push_back(n - 1);
    std::vector<char> out(n, 0);
    for (int i : excluded) out[i] = 1;
    const SparseMatrix a = withRowsExcluded(k, out);
    ASSERT_EQ(Eigen::LLT<Eigen::MatrixXd>(Eigen::MatrixXd(a)).info(), Eigen::Success);
    p.compute(a, excluded);
    ASSERT_TRUE(p.ready());
    const Eigen::MatrixXd m = denseInverse(p, n);
    EXPECT_LT((m - m.transpose()).norm(), 1e-12 * m.norm());
    const Eigen::VectorXd eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(
                                    0.5 * (m + m.transpose()), Eigen::EigenvaluesOnly)
                                    .eigenvalues();
    EXPECT_GT(eig.minCoeff(), 1e-8 * eig.maxCoeff());
    // M^-1 A's eigenvalues in (0, 1]: 1 on the coarse space, and l1-Jacobi's Gershgorin
    // bound lambda_max(S A) <= 1 on the rest (plain Jacobi exceeds it with skew)
    const Eigen::MatrixXd ma = m * Eigen::MatrixXd(a);
    const Eigen::VectorXcd mae = ma.eigenvalues();
    double lo = 1e300, hi = 0;
    for (int i = 0; i < n; ++i) {
      EXPECT_NEAR(mae[i].imag(), 0.0, 1e-8);
      lo = std::min(lo, mae[i].real());
      hi = std::max(hi, mae[i].real());
    }
    EXPECT_GT(lo, 0.0);
    EXPECT_LE(hi, 1.0 + 1e-9);
    std::cout << "skew " << skew << ": eig(M^-1 A) in [" << lo << ", " << hi << "], "
              << p.numAggregates() << " aggregates\n";
  }
}

TEST(TwoLevelPreconditioner, CgReachesTheDirectAnswerInIterationsThatStayFlat) {
  int previousTwoLevel = 0, previousJacobi = 0;
  for (int k : {8, 16, 24}) {
    SCOPED_TRACE("grid " + std::to_string(k));
    const SparseMatrix a = gridLaplacian(k);
    const int n = static_cast<int>(a.rows());
    Eigen::VectorXd b(n);
    for (int i = 0; i < n; ++i) b[i] = std::sin(0.37 * i) + (i == n / 2 ? 10.0 : 0.0);
    const Eigen::VectorXd exact = Eigen::SimplicialLDLT<SparseMatrix>(a).solve(b);
    TwoLevelPreconditioner p;
    p.setGraph(a, 1);
    p.compute(a, {});
    Eigen::VectorXd x;
    const int twoLevel = cg(
        a, b, 1e-10, [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) { p.apply(r, z); }, x);
    ASSERT_GT(twoLevel, 0);
    EXPECT_LT((x - exact).norm(), 1e-8 * exact.norm());
    const Eigen::VectorXd diagonal = a.diagonal();
    const int jacobi = cg(
        a, b, 1e-10,
        [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) { z = r.cwiseQuotient(diagonal); }, x);
    ASSERT_GT(jacobi, 0);
    std::cout << "k " << k << " (" << n << " rows): two-level " << twoLevel << ", Jacobi " << jacobi
              << " iterations, " << p.numAggregates() << " aggregates\n";
    EXPECT_LT(twoLevel, jacobi);
    if (previousJacobi > 0) {
      // h halves (k 8 -> 16): Jacobi's iterations grow ~ 1/h, the two-level's far less
      EXPECT_GT(jacobi, 1.3 * previousJacobi);
      EXPECT_LT(twoLevel, 1.25 * previousTwoLevel);
    }
    previousJacobi = jacobi;
    previousTwoLevel = twoLevel;
  }
}

// The deflated form (A-DEF2) that pcg runs: on residuals without a coarse component (Z' r = 0,
// which deflate's start gives and CG keeps) it is apply's M^-1 to rounding, so CG from deflate's
// start takes the same iterations to the same answer, for one coarse solve an iteration
TEST(TwoLevelPreconditioner, TheDeflatedFormIsTheSameCgForOneCoarseSolve) {
  for (double skew : {0.0, 0.4}) {
    SCOPED_TRACE("skew " + std::to_string(skew));
    const SparseMatrix k = gridLaplacian(10, skew);
    const int n = static_cast<int>(k.rows());
    TwoLevelPreconditioner p;
    p.setGraph(k, 1);
    // rows excluded as contact rows are (identity rows and columns), a whole aggregate too
    std::vector<char> out(n, 0);
    std::vector<int> excluded;
    for (int i = 0; i < n; ++i)
      if (p.aggregateOf()[i] == 3 || i % 97 == 5) {
        out[i] = 1;
        excluded.push_back(i);
      }
    const SparseMatrix a = withRowsExcluded(k, out);
    p.compute(a, excluded);
    // Z' r: the sum of r over each aggregate's rows that are not excluded
    const auto coarsePart = [&](const Eigen::VectorXd& r) {
      Eigen::VectorXd s = Eigen::VectorXd::Zero(p.numAggregates());
      for (int i = 0; i < n; ++i)
        if (!out[i]) s[p.aggregateOf()[i]] += r[i];
      return s;
    };
    // 1. a residual with Z' r = 0 (each aggregate's mean taken out): the two forms agree
    Eigen::VectorXd r(n);
    for (int i = 0; i < n; ++i) r[i] = std::sin(0.91 * i) + 0.3 * std::cos(0.13 * i * i);
    Eigen::VectorXd mean = coarsePart(r);
    Eigen::VectorXd count = coarsePart(Eigen::VectorXd::Ones(n));
    for (int i = 0; i < n; ++i)
      if (!out[i]) r[i] -= mean[p.aggregateOf()[i]] / count[p.aggregateOf()[i]];
    ASSERT_LT(coarsePart(r).norm(), 1e-13 * r.norm());
    Eigen::VectorXd zFull, zDeflated;
    p.apply(r, zFull);
    p.applyDeflated(r, zDeflated);
    EXPECT_LT((zFull - zDeflated).norm(), 1e-12 * zFull.norm());
    // ... and off that subspace they differ (so the test can fail)
    Eigen::VectorXd e = Eigen::VectorXd::Unit(n, 0);
    if (out[0]) e = Eigen::VectorXd::Unit(n, n / 2 + 1);
    p.apply(e, zFull);
    p.applyDeflated(e, zDeflated);
    EXPECT_GT((zFull - zDeflated).norm(), 1e-3 * zFull.norm());
    // 2. deflate's start has no coarse residual
    Eigen::VectorXd b(n), x(n);
    for (int i = 0; i < n; ++i) {
      b[i] = out[i] ? 0.0 : std::cos(0.29 * i) + (i == n / 2 ? 5.0 : 0.0);
      x[i] = out[i] ? 0.0 : 0.1 * std::sin(0.7 * i);  // a warm start, as the previous frame's
    }
    const Eigen::VectorXd exact = Eigen::SimplicialLDLT<SparseMatrix>(a).solve(b);
    p.deflate(a, b, x);
    EXPECT_LT(coarsePart(b - a * x).norm(), 1e-12 * b.norm());
    // 3. CG from there: the direct answer, in the iterations of the symmetric form from the
    // same start (within one)
    Eigen::VectorXd xFull = x, xDeflated = x;
    const int full = cgFrom(
        a, b, 1e-10, [&](const Eigen::VectorXd& v, Eigen::VectorXd& z) { p.apply(v, z); }, xFull);
    const int deflated = cgFrom(
        a, b, 1e-10, [&](const Eigen::VectorXd& v, Eigen::VectorXd& z) { p.applyDeflated(v, z); },
        xDeflated);
    ASSERT_GT(full, 0);
    ASSERT_GT(deflated, 0);
    EXPECT_LE(std::abs(full - deflated), 1);
    EXPECT_LT((xDeflated - exact).norm(), 1e-8 * exact.norm());
    EXPECT_LT((xFull - exact).norm(), 1e-8 * exact.norm());
    std::cout << "skew " << skew << ": " << full << " iterations with apply, " << deflated
              << " with applyDeflated\n";
  }
}

// a new matrix of the same pattern (conductivities following the temperature) keeps the
// aggregates, and the preconditioner equals a fresh one of that matrix; a new pattern
// aggregates again
TEST(TwoLevelPreconditioner, AGraphSetAgainKeepsItsAggregatesAndANewOneIsAggregated) {
  const SparseMatrix a = gridLaplacian(7);
  const SparseMatrix b = gridLaplacian(7, 0.3);  // a's pattern and diagonal couplings
  TwoLevelPreconditioner kept, fresh;
  kept.setGraph(a, 1);
  kept.compute(a, {3});
  SparseMatrix scaled = a * 3.0;  // same pattern, other values
  kept.setGraph(scaled, 1);
  EXPECT_FALSE(kept.ready());  // compute must follow
  kept.compute(scaled, {5});
  fresh.setGraph(scaled, 1);
  fresh.compute(scaled, {5});
  EXPECT_EQ(kept.aggregateOf(), fresh.aggregateOf());
  Eigen::VectorXd r = Eigen::VectorXd::LinSpaced(a.rows(), -1.0, 2.0), zKept, zFresh;
  kept.apply(r, zKept);
  fresh.apply(r, zFresh);
  EXPECT_EQ(zKept, zFresh);
  // another pattern (diagonal couplings added): aggregated again, as a fresh one does
  ASSERT_NE(b.nonZeros(), a.nonZeros());
  kept.setGraph(b, 1);
  kept.compute(b, {});
  TwoLevelPreconditioner other;
  other.setGraph(b, 1);
  other.compute(b, {});
  EXPECT_EQ(kept.aggregateOf(), other.aggregateOf());
  kept.apply(r, zKept);
  other.apply(r, zFresh);
  EXPECT_EQ(zKept, zFresh);
}

// the degenerate systems a cut leaves: one unknown, nodes with no neighbour left, every row
// excluded (every free node in contact): M stays the exact inverse or l1-Jacobi, finite
TEST(TwoLevelPreconditioner, TinyAndDegenerateSystemsStaySolvable) {
  // one unknown
  SparseMatrix one(1, 1);
  one.insert(0, 0) = 4.0;
  one.makeCompressed();
  TwoLevelPreconditioner p;
  p.setGraph(one, 1);
  p.compute(one, {});
  Eigen::VectorXd z;
  p.apply(Eigen::VectorXd::Constant(1, 2.0), z);
  EXPECT_NEAR(z[0], 0.5, 1e-15);                 // the coarse level is the whole system: exact
  Eigen::VectorXd x = Eigen::VectorXd::Zero(1);  // ... and deflate's start is the answer
  p.deflate(one, Eigen::VectorXd::Constant(1, 2.0), x);
  EXPECT_NEAR(x[0], 0.5, 1e-15);
  // isolated nodes (a diagonal matrix) and a pair
  SparseMatrix d(4, 4);
  d.insert(0, 0) = 2.0;
  d.insert(1, 1) = 3.0;
  d.insert(2, 2) = 2.0;
  d.insert(3, 3) = 2.0;
  d.insert(2, 3) = -1.0;
  d.insert(3, 2) = -1.0;
  d.makeCompressed();
  p.setGraph(d, 2);
  p.compute(d, {});
  const Eigen::MatrixXd inverse = denseInverse(p, 4);
  EXPECT_LT((inverse * Eigen::MatrixXd(d) - Eigen::MatrixXd::Identity(4, 4)).norm(), 1e-12)
      << "isolated nodes and a pair: each aggregate's coarse solve is exact";
  // every row excluded: no coarse column, M = l1-Jacobi
  const SparseMatrix a = gridLaplacian(3);
  std::vector<int> all(27);
  for (int i = 0; i < 27; ++i) all[i] = i;
  SparseMatrix ai = a;  // the pattern of a, the identity's values
  for (int j = 0; j < 27; ++j)
    for (SparseMatrix::InnerIterator it(ai, j); it; ++it) it.valueRef() = it.row() == j ? 1.0 : 0.0;
  p.setGraph(a, 1);
  p.compute(ai, all);
  p.apply(Eigen::VectorXd::LinSpaced(27, 1.0, 27.0), z);
  EXPECT_LT((z - Eigen::VectorXd::LinSpaced(27, 1.0, 27.0)).norm(), 1e-12);
  // the deflated form and start too (nothing to deflate)
  p.applyDeflated(Eigen::VectorXd::LinSpaced(27, 1.0, 27.0), z);
  EXPECT_LT((z - Eigen::VectorXd::LinSpaced(27, 1.0, 27.0)).norm(), 1e-12);
  x = Eigen::VectorXd::Constant(27, 3.0);
  p.deflate(ai, Eigen::VectorXd::Zero(27), x);
  EXPECT_EQ(x, Eigen::VectorXd::Constant(27, 3.0));
}

TEST(TwoLevelPreconditioner, BadInputIsAnErrorNamingIt) {
  const SparseMatrix a = gridLaplacian(4);
  TwoLevelPreconditioner p;
  const auto message = [](auto&& f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message([&] { p.setGraph(a, 0); }).find("0 aggregation passes; expected 1 to 3"),
            std::string::npos);
  p.setGraph(a, 1);
  EXPECT_NE(message([&] { p.compute(gridLaplacian(5), {}); }).find("not the pattern"),
            std::string::npos);
  EXPECT_NE(message([&] { p.compute(a, {64}); }).find("excluded row 64 outside [0, 64)"),
            std::string::npos);
  SparseMatrix indefinite = a;
  indefinite.coeffRef(0, 0) = -100;  // E's first entry negative
  EXPECT_NE(message([&] { p.compute(indefinite, {}); }).find("not positive definite"),
            std::string::npos);
  EXPECT_FALSE(p.ready());
}

}  // namespace
}  // namespace esim
