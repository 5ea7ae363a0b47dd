// Tests for sim/electric_downdate.cpp (and CholmodFactor::deleteRows, which it relies on): the
// factor kept exact through a cut as long as it goes on, against a fresh factorization and an
// independent Eigen solve; a change's columns (its clusters factored; growth an update);
// rows leaving the free set; and the fallback when a change is too large to pay.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include "sim/cholmod_view.h"
#include "sim/electric_solver.h"
#include "sim/electrode.h"
#include "sim/fem_p1.h"
#include "sim/mesh_slab.h"
#include "tests/sim/electric_reference.h"

namespace esim {
namespace {

constexpr double kSigma = 0.144;  // S/m
constexpr double kVolt = 100.0;   // V

double relError(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return (a - b).norm() / b.norm();
}

// slab_cut's graded slab, 2000 nodes, the return disc underneath, its inner nodes moved by up
// to a tenth of the shortest edge (a fixed sequence): the boxes' Kuhn tets have no obtuse
// dihedral angle, the moved ones some, so that a removal takes negative conductances away too
struct GradedSlab {
  TetMesh mesh;
  std::vector<TetGeometry> geo;
  SparseMatrix K;
  std::vector<int> grounded, surface;
  GradedSlab() {
    SlabSpec spec;
    spec.sizeM = Vec3(0.06, 0.03, 0.01);
    spec.targetNodes = 2000;
    spec.grading = {true, Vec3(-0.025, 0, 0.01), Vec3(0.025, 0, 0.01), 4.0, 0.004, true};
    mesh = makeSlab(spec);
    double shortest = 1.0;
    for (const Tet& t : mesh.tets)
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b)
          shortest = std::min(shortest, (mesh.nodes[t[a]] - mesh.nodes[t[b]]).norm());
    const Vec3 lo = Vec3(-0.03, -0.015, 0.0), hi = Vec3(0.03, 0.015, 0.01);
    unsigned seed = 12345;
    const auto next = [&] {  // in [-1, 1)
      seed = seed * 1103515245u + 12345u;
      return static_cast<double>((seed >> 8) & 0xffff) / 32768.0 - 1.0;
    };
    for (Vec3& v : mesh.nodes) {
      const bool inner = (v - lo).minCoeff() > 1e-9 && (hi - v).minCoeff() > 1e-9;
      const Vec3 move(next(), next(), next());
      if (inner) v += 0.1 * shortest * move;
    }
    geo = tetGeometry(mesh);
    assemble();
    grounded = returnElectrodeNodes(mesh, surface, ReturnElectrode{});
  }
  void assemble() {
    K = assembleStiffness(mesh, geo, std::vector<double>(mesh.numTets(), kSigma));
    surface = boundaryNodes(mesh, boundaryFaces(mesh));
  }
  // the alive tets whose centroid lies within r of p
  std::vector<int> tetsNear(const Vec3& p, double r) const {
    std::vector<int> out;
    for (int e = 0; e < mesh.numTets(); ++e) {
      if (!mesh.isAlive(e)) continue;
      Vec3 c = Vec3::Zero();
      for (int v : mesh.tets[e]) c += mesh.nodes[v] / 4;
      if ((c - p).norm() < r) out.push_back(e);
    }
    return out;
  }
  // the surface nodes nearest p (sorted ids): a blade's contact set
  std::vector<int> contactNear(const Vec3& p, int count) const {
    std::vector<std::pair<double, int>> d;
    for (int v : surface)
      if (!std::binary_search(grounded.begin(), grounded.end(), v))
        d.emplace_back((mesh.nodes[v] - p).squaredNorm(), v);
    std::sort(d.begin(), d.end());
    std::vector<int> out;
    for (int k = 0; k < count && k < static_cast<int>(d.size()); ++k) out.push_back(d[k].second);
    std::sort(out.begin(), out.end());
    return out;
  }
};

// The solver's potential for two blades' contacts equals a fresh factorization's to
// `tolerance` and the independent solve's to 1e-9 (failures traced with `what`); returns the
// larger difference to the fresh one
double expectAsFresh(ElectricSolver& solver, const GradedSlab& slab, const std::string& what,
                     double tolerance = 1e-12) {
  SCOPED_TRACE(what);
  auto fresh = makeElectricSolver({.strategy = ElectricStrategy::Downdate});
  fresh->setMatrix(slab.K, slab.grounded);
  double worst = 0;
  for (const Vec3& p : {Vec3(-0.01, 0.0, 0.01), Vec3(0.012, 0.004, 0.01)}) {
    const std::vector<int> c = slab.contactNear(p, 5);
    Eigen::VectorXd u, uf;
    solver.solve(c, kVolt, u);
    fresh->solve(c, kVolt, uf);
    worst = std::max(worst, relError(u, uf));
    EXPECT_LT(relError(u, uf), tolerance);
    EXPECT_LT(relError(u, test::referenceSolve(slab.K, slab.grounded, c, kVolt)), 1e-9);
  }
  return worst;
}

// A groove cut in twelve steps along the slab's top (each step the tets within 1.2 mm of the
// blade's next position, the contacts the nearest surface nodes): after every update the
// potential equals a fresh factorization's to 1e-12 and the independent solve's to 1e-9, with
// no fallback; the conductances taken away include negative ones (obtuse tets: as rank-one
// terms they were updates; the clusters' columns are downdates only); nodes whose last tet
// goes leave the free set.
TEST(ElectricDowndate, AGrooveCutStepByStepMatchesAFreshFactorization) {
  GradedSlab slab;
  auto solver = makeElectricSolver({.strategy = ElectricStrategy::Downdate});
  ASSERT_STREQ(solver->name(), "downdate");
  solver->setMatrix(slab.K, slab.grounded);
  Eigen::VectorXd u;
  int negativeTaken = 0, dropped = 0, rank = 0;
  for (int step = 0; step < 12; ++step) {
    SCOPED_TRACE("step " + std::to_string(step));
    const Vec3 at(-0.02 + 0.0035 * step, 0.0, 0.0095);
    const std::vector<int> contact = slab.contactNear(at, 4);
    solver->solve(contact, kVolt, u);  // columns that the update drops
    const std::vector<int> cut = slab.tetsNear(at, 0.0016);
    ASSERT_FALSE(cut.empty());
    const SparseMatrix before = slab.K;
    for (int e : cut) slab.mesh.alive[e] = 0;
    slab.assemble();
    const SparseMatrix change = slab.K - before;
    for (int k = 0; k < change.outerSize(); ++k)
      for (SparseMatrix::InnerIterator it(change, k); it; ++it)
        negativeTaken += it.row() > it.col() && it.value() < -1e-12 * kSigma;
    const ElectricUpdateStats st = solver->updateMatrix(slab.K, slab.grounded);
    EXPECT_FALSE(st.fellBack) << st.fallbackReason;
    EXPECT_GT(st.rank, 0);
    dropped += st.droppedNodes;
    rank += st.rank;
    auto fresh = makeElectricSolver({.strategy = ElectricStrategy::Downdate});
    fresh->setMatrix(slab.K, slab.grounded);
    for (const Vec3& p : {at, Vec3(at.x() + 0.003, 0.0, 0.0095), Vec3(0.0, 0.01, 0.01)}) {
      const std::vector<int> c = slab.contactNear(p, 5);
      Eigen::VectorXd uf;
      solver->solve(c, kVolt, u);
      fresh->solve(c, kVolt, uf);
      const Eigen::VectorXd ref = test::referenceSolve(slab.K, slab.grounded, c, kVolt);
      ASSERT_TRUE(u.allFinite());
      EXPECT_LT(relError(u, uf), 1e-12);
      EXPECT_LT(relError(u, ref), 1e-9);
    }
  }
  std::cout << "12 cuts: rank " << rank << ", " << dropped << " nodes left the free set, "
            << negativeTaken << " negative off-diagonal changes (obtuse conductances)\n";
  EXPECT_GT(negativeTaken, 0);  // obtuse conductances taken away
  EXPECT_GT(dropped, 0);
}

// A long run: 400 removals of one to three tets each (the frame loop's told update, the
// removed tets' nodes), anywhere in the slab's upper 6 mm, and every 25th a node's whole
// star (the node left floating), with no refactorization in between: the factor does not
// drift. Every 50 removals the potential equals a fresh factorization's to 1e-11 and the
// independent solve's to 1e-9 (the largest difference to the fresh one printed).
TEST(ElectricDowndate, FourHundredRemovalsDoNotDriftFromAFreshFactorization) {
  GradedSlab slab;
  auto solver = makeElectricSolver({.strategy = ElectricStrategy::Downdate});
  solver->setMatrix(slab.K, slab.grounded);
  unsigned seed = 777;
  const auto next = [&](int n) {  // in [0, n)
    seed = seed * 1103515245u + 12345u;
    return static_cast<int>((seed >> 8) % static_cast<unsigned>(n));
  };
  double worst = 0;
  int removed = 0, dropped = 0;
  for (int step = 1; step <= 400; ++step) {
    std::vector<int> cut;
    if (step % 25 == 0) {  // every tet of a node's star: the node floats
      int v = -1;
      while (v < 0 || slab.mesh.nodes[v].z() < 0.006) v = next(slab.mesh.numNodes());
      for (int e = 0; e < slab.mesh.numTets(); ++e)
        if (slab.mesh.isAlive(e) &&
            std::count(slab.mesh.tets[e].begin(), slab.mesh.tets[e].end(), v))
          cut.push_back(e);
    }
    for (int tries = 0; tries < 1000 && static_cast<int>(cut.size()) < 1 + step % 3; ++tries) {
      const int e = next(slab.mesh.numTets());
      Vec3 c = Vec3::Zero();
      for (int v : slab.mesh.tets[e]) c += slab.mesh.nodes[v] / 4;
      if (slab.mesh.isAlive(e) && c.z() > 0.004 &&
          std::find(cut.begin(), cut.end(), e) == cut.end())
        cut.push_back(e);
    }
    ASSERT_FALSE(cut.empty());
    for (int e : cut) slab.mesh.alive[e] = 0;
    removed += static_cast<int>(cut.size());
    slab.assemble();
    const std::vector<int> changed = nodesOfTets(slab.mesh, cut);
    const ElectricUpdateStats st = solver->updateMatrix(slab.K, slab.grounded, &changed);
    ASSERT_FALSE(st.fellBack) << "step " << step << ": " << st.fallbackReason;
    dropped += st.droppedNodes;
    if (step % 50 != 0) continue;
    worst = std::max(worst, expectAsFresh(*solver, slab, "step " + std::to_string(step), 1e-11));
  }
  std::cout << "400 removals, " << removed << " tets, " << dropped
            << " nodes left the free set; largest difference to a fresh factorization " << worst
            << "\n";
  EXPECT_GT(dropped, 0);
}

// A change's columns (changeColumns): a removal's rank is at most the rows it changes (one
// per cluster of rows, less one where the constant potential is in its null space), well
// under its rank-one terms (one per changed edge); conductances that grow (update columns),
// shrink (downdate columns) or both in one cluster (an indefinite change) give the potential
// of a fresh factorization to 1e-12, and so does a change with no pivot (its terms)
TEST(ElectricDowndate, AChangesColumnsAreItsClustersFactoredAndGrowthIsAnUpdate) {
  GradedSlab slab;
  auto solver = makeElectricSolver({.strategy = ElectricStrategy::Downdate});
  solver->setMatrix(slab.K, slab.grounded);
  // a removal: the changed edges (rank-one terms) against the rank
  const std::vector<int> cut = slab.tetsNear(Vec3(0.0, 0.0, 0.0095), 0.0016);
  const SparseMatrix before = slab.K;
  for (int e : cut) slab.mesh.alive[e] = 0;
  slab.assemble();
  const SparseMatrix change = slab.K - before;
  int edges = 0;
  for (int k = 0; k < change.outerSize(); ++k)
    for (SparseMatrix::InnerIterator it(change, k); it; ++it)
      edges += it.row() > it.col() && it.value() != 0.0;
  const ElectricUpdateStats removal = solver->updateMatrix(slab.K, slab.grounded);
  EXPECT_FALSE(removal.fellBack) << removal.fallbackReason;
  EXPECT_GT(removal.rank, 0);
  EXPECT_LE(removal.rank, removal.changedNodes);
  EXPECT_LT(2 * removal.rank, edges + removal.changedNodes);
  std::cout << "removal of " << cut.size() << " tets: " << removal.changedNodes << " rows, "
            << edges << " edges, rank " << removal.rank << "\n";
  expectAsFresh(*solver, slab, "removal");
  // conductances that grow (x2 near one point), shrink (x0.5 near another), and both in
  // turn near a third (one cluster of both signs)
  std::vector<double> sigma(slab.mesh.numTets(), kSigma);
  for (int e : slab.tetsNear(Vec3(-0.02, 0.0, 0.005), 0.002)) sigma[e] = 2 * kSigma;
  for (int e : slab.tetsNear(Vec3(0.02, 0.0, 0.005), 0.002)) sigma[e] = 0.5 * kSigma;
  int turn = 0;
  for (int e : slab.tetsNear(Vec3(0.0, 0.008, 0.005), 0.002))
    sigma[e] = (turn++ % 2 == 0 ? 2.0 : 0.5) * kSigma;
  slab.K = assembleStiffness(slab.mesh, slab.geo, sigma);
  const ElectricUpdateStats both = solver->updateMatrix(slab.K, slab.grounded);
  EXPECT_FALSE(both.fellBack) << both.fallbackReason;
  EXPECT_GT(both.rank, 0);
  expectAsFresh(*solver, slab, "growth and shrinkage");
  // one off-diagonal pair changed, the diagonal not: -E = [0 -x; -x 0] on its two rows has no
  // pivot (its diagonal is zero, its rest is not): that cluster takes its rank-one terms
  // (x (e_i - e_j)(e_i - e_j)' and x e_i e_i' + x e_j e_j', of both signs)
  const int i = slab.contactNear(Vec3(0.0, 0.0, 0.01), 1)[0];
  int j = -1;
  for (SparseMatrix::InnerIterator it(slab.K, i); it; ++it)
    if (it.row() != i && it.value() != 0.0 &&
        !std::binary_search(slab.grounded.begin(), slab.grounded.end(), it.row()))
      j = static_cast<int>(it.row());
  ASSERT_GE(j, 0);
  const double x = 0.01 * std::abs(slab.K.coeff(i, j));
  slab.K.coeffRef(i, j) += x;
  slab.K.coeffRef(j, i) += x;
  const ElectricUpdateStats pair = solver->updateMatrix(slab.K, slab.grounded);
  EXPECT_FALSE(pair.fellBack) << pair.fallbackReason;
  EXPECT_EQ(pair.rank, 3);  // the three terms, not one column per row
  expectAsFresh(*solver, slab, "an off-diagonal pair");
}

// A cluster whose first pivot is out of L's row order: -E = w1 (e_a - e_b)(e_a - e_b)' +
// w2 (e_b - e_c)(e_b - e_c)' with a < b < c in L's order, w1 under the pivot threshold, so b is
// the first pivot and its column holds a, b and c; c is not in L's column a, so that column
// would fill in L. The cluster takes its two rank-one terms instead (which cannot fill in):
// L keeps its pattern and its memory (with the fill-in check off, the column went to
// cholmod_updown, which grew L by 8 entries and its memory by 131 kB), every column goes to
// the vectorized kernel, and grounding c afterwards (its row deleted from L by the pattern of
// K_ff) still gives a fresh factorization's potential.
TEST(ElectricDowndate, AClusterColumnThatWouldFillInLTakesItsTerms) {
  GradedSlab slab;
  auto solver = makeElectricSolver({.strategy = ElectricStrategy::Downdate});
  solver->setMatrix(slab.K, slab.grounded);
  // the solver's factor, made the same way here to find such a triple in its pattern
  electric_detail::NodeClasses classes;
  classes.build(slab.K, slab.grounded);
  const SparseMatrix a = electric_detail::restrictToFree(slab.K, classes);
  electric_detail::CholmodFactor f;
  f.analyze(a);
  f.factorize(a, "test");
  f.toSimplicial();
  const std::vector<int> perm = f.ordering();
  std::vector<int> rowOf(perm.size());
  for (size_t k = 0; k < perm.size(); ++k) rowOf[perm[k]] = static_cast<int>(k);
  const SimplicialView l(&f.cholmod());
  const auto inColumn = [&](int row, int column) {  // L's rows, column `column`
    return std::find(l.i + l.p[column], l.i + l.p[column] + l.nz[column], row) !=
           l.i + l.p[column] + l.nz[column];
  };
  int ia = -1, ib = -1, ic = -1;  // free indices
  for (int x = 0; x < a.cols() && ia < 0; ++x)
    for (SparseMatrix::InnerIterator bx(a, x); bx && ia < 0; ++bx) {
      const int y = static_cast<int>(bx.row());
      if (rowOf[y] <= rowOf[x]) continue;
      for (SparseMatrix::InnerIterator cy(a, y); cy; ++cy) {
        const int z = static_cast<int>(cy.row());
        if (rowOf[z] > rowOf[y] && !inColumn(rowOf[z], rowOf[x])) {
          ia = x, ib = y, ic = z;
          break;
        }
      }
    }
  ASSERT_GE(ia, 0) << "no triple a < b < c whose column would fill in L";
  const int na = classes.freeNodes[ia], nb = classes.freeNodes[ib], nc = classes.freeNodes[ic];
  const auto lessConductance = [&](int i, int j, double w) {  // the edge's, by w [S]
    slab.K.coeffRef(i, j) += w;
    slab.K.coeffRef(j, i) += w;
    slab.K.coeffRef(i, i) -= w;
    slab.K.coeffRef(j, j) -= w;
  };
  lessConductance(na, nb, 1e-6 * std::abs(slab.K.coeff(na, nb)));
  lessConductance(nb, nc, 0.5 * std::abs(slab.K.coeff(nb, nc)));
  std::vector<int> changed = {na, nb, nc};
  std::sort(changed.begin(), changed.end());
  const double bytes = solver->memoryBytes();  // (no path solved yet)
  const ElectricUpdateStats st = solver->updateMatrix(slab.K, slab.grounded, &changed);
  EXPECT_FALSE(st.fellBack) << st.fallbackReason;
  EXPECT_EQ(solver->memoryBytes(), bytes);  // L did not grow
  EXPECT_GE(st.rank, 2);                    // the two edges' terms (and a diagonal one of rounding)
  expectAsFresh(*solver, slab, "the change");
  // c grounded: its row leaves L by K_ff's pattern
  slab.grounded.insert(std::lower_bound(slab.grounded.begin(), slab.grounded.end(), nc), nc);
  const std::vector<int> grounding = {nc};
  const ElectricUpdateStats gr = solver->updateMatrix(slab.K, slab.grounded, &grounding);
  EXPECT_FALSE(gr.fellBack) << gr.fallbackReason;
  EXPECT_EQ(gr.droppedNodes, 1);
  expectAsFresh(*solver, slab, "c grounded");
}

// Removing most of the slab in one step is a larger change than an update pays for: the
// solver factorizes again (stats.fellBack, named), with the right answer
TEST(ElectricDowndate, AChangeTooLargeToPayIsAFactorization) {
  GradedSlab slab;
  auto solver = makeElectricSolver({.strategy = ElectricStrategy::Downdate});
  solver->setMatrix(slab.K, slab.grounded);
  for (int e : slab.tetsNear(Vec3(0, 0, 0.01), 0.012)) slab.mesh.alive[e] = 0;
  slab.assemble();
  const ElectricUpdateStats st = solver->updateMatrix(slab.K, slab.grounded);
  EXPECT_TRUE(st.fellBack);
  EXPECT_NE(st.fallbackReason.find("a new factorization is cheaper"), std::string::npos)
      << st.fallbackReason;
  const std::vector<int> c = slab.contactNear(Vec3(0.025, 0.0, 0.01), 5);
  Eigen::VectorXd u;
  solver->solve(c, kVolt, u);
  EXPECT_LT(relError(u, test::referenceSolve(slab.K, slab.grounded, c, kVolt)), 1e-9);
}

// prefetch solves the contacts' paths a later solve needs (it then solves none) until the next
// update; limitCache gives the paths' memory back (the bytes returned) and changes no result
TEST(ElectricDowndate, PrefetchedPathsServeUntilAnUpdateAndACapChangesNoResult) {
  GradedSlab slab;
  auto solver = makeElectricSolver({.strategy = ElectricStrategy::Downdate});
  solver->setMatrix(slab.K, slab.grounded);
  const std::vector<int> c = slab.contactNear(Vec3(0.0, 0.0, 0.01), 5);
  solver->prefetch(c);
  Eigen::VectorXd u, capped;
  EXPECT_EQ(solver->solve(c, kVolt, u).newColumns, 0);
  const double before = solver->memoryBytes();
  const double freed = solver->limitCache(1.0);
  EXPECT_GT(freed, 0.0);
  EXPECT_NEAR(solver->memoryBytes(), before - freed, 1e-6 * before);
  EXPECT_EQ(solver->solve(c, kVolt, capped).newColumns, static_cast<int>(c.size()));
  EXPECT_EQ((u - capped).cwiseAbs().maxCoeff(), 0.0);  // the same paths: the same bits
  solver->prefetch(c);
  for (int e : slab.tetsNear(Vec3(0.0, 0.0, 0.0095), 0.0012)) slab.mesh.alive[e] = 0;
  slab.assemble();
  const ElectricUpdateStats st = solver->updateMatrix(slab.K, slab.grounded);
  EXPECT_FALSE(st.fellBack) << st.fallbackReason;
  const std::vector<int> after = slab.contactNear(Vec3(0.0, 0.0, 0.01), 5);
  EXPECT_GT(solver->solve(after, kVolt, u).newColumns, 0);  // the update dropped them
  EXPECT_LT(relError(u, test::referenceSolve(slab.K, slab.grounded, after, kVolt)), 1e-9);
}

// Many contacts at once (a blade pressed in: every surface node within 4 mm, their paths solved
// in one pass) against the independent solve; the same contacts again, at another voltage,
// solve nothing (the unit potential is kept: exactly the scaled potential); new contacts next
// to kept ones solve only theirs; a cap of 1 byte keeps only what each solve needs
TEST(ElectricDowndate, ManyContactsTheSameContactsAgainAndATinyCap) {
  GradedSlab slab;
  auto solver = makeElectricSolver({.strategy = ElectricStrategy::Downdate});
  solver->setMatrix(slab.K, slab.grounded);
  const std::vector<int> many = slab.contactNear(Vec3(0.0, 0.0, 0.01), 60);
  Eigen::VectorXd u, again;
  EXPECT_EQ(solver->solve(many, kVolt, u).newColumns, 60);
  EXPECT_LT(relError(u, test::referenceSolve(slab.K, slab.grounded, many, kVolt)), 1e-9);
  EXPECT_EQ(solver->solve(many, 2 * kVolt, again).newColumns, 0);
  EXPECT_EQ((again - 2 * u).cwiseAbs().maxCoeff(), 0.0);
  std::vector<int> more = many;
  for (int v : slab.contactNear(Vec3(0.004, 0.0, 0.01), 64))
    if (!std::binary_search(many.begin(), many.end(), v)) more.push_back(v);
  std::sort(more.begin(), more.end());
  ASSERT_GT(more.size(), many.size());
  EXPECT_EQ(solver->solve(more, kVolt, u).newColumns, static_cast<int>(more.size() - many.size()));
  EXPECT_LT(relError(u, test::referenceSolve(slab.K, slab.grounded, more, kVolt)), 1e-9);
  solver->limitCache(1.0);
  const std::vector<int> few = slab.contactNear(Vec3(-0.01, 0.0, 0.01), 3);
  std::vector<int> kept;  // after a solve over the cap: its contacts' paths only
  for (const auto* c : {&few, &many, &few}) {
    int fresh = 0;
    for (int v : *c) fresh += !std::binary_search(kept.begin(), kept.end(), v);
    EXPECT_EQ(solver->solve(*c, kVolt, u).newColumns, fresh);
    kept = *c;
    EXPECT_LT(relError(u, test::referenceSolve(slab.K, slab.grounded, *c, kVolt)), 1e-9);
  }
}

// the graded slab's K with a small shift on the diagonal: positive definite as it is
SparseMatrix shiftedSlabMatrix() {
  SparseMatrix a = GradedSlab().K;
  for (int i = 0; i < a.rows(); ++i) a.coeffRef(i, i) += kSigma * 1e-3;
  a.makeCompressed();
  return a;
}

// CholmodFactor::deleteRows: the factor of A with rows and columns set to the identity (in
// one update by L's own columns) solves that matrix as a fresh factorization of it does
TEST(CholmodFactor, DeletedRowsSolveAsAFreshFactorOfTheIdentityRows) {
  const SparseMatrix a = shiftedSlabMatrix();
  electric_detail::CholmodFactor f;
  f.analyze(a);
  f.factorize(a, "test");
  const std::vector<int> rows = {3, 150, 151, 700, static_cast<int>(a.rows()) - 1};
  ASSERT_TRUE(f.deleteRows(rows, a));
  SparseMatrix b = a;  // the same pattern, identity rows and columns
  for (int k = 0; k < b.outerSize(); ++k)
    for (SparseMatrix::InnerIterator it(b, k); it; ++it)
      if (std::count(rows.begin(), rows.end(), it.row()) ||
          std::count(rows.begin(), rows.end(), it.col()))
        it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
  electric_detail::CholmodFactor g;
  g.analyze(b);
  g.factorize(b, "test");
  const Eigen::VectorXd rhs = Eigen::VectorXd::LinSpaced(a.rows(), -1.0, 2.0);
  Eigen::VectorXd x(a.rows()), y(a.rows());
  f.solve(rhs.data(), x.data());
  g.solve(rhs.data(), y.data());
  EXPECT_LT(relError(x, y), 1e-12);
  EXPECT_LT((b * x - rhs).norm(), 1e-10 * rhs.norm());
  for (int r : rows) EXPECT_NEAR(x[r], rhs[r], 1e-12 * rhs.norm());
  EXPECT_TRUE(f.pivotsPositive());
}

// CholmodFactor::pivotsPositive checks every pivot once after a factorization, then only the
// paths the updates since walked: a downdate that takes a row's diagonal below zero is found
// there (the matrix then indefinite), an update elsewhere keeps the answer, and it stays
// false when asked again
TEST(CholmodFactor, APivotThatADowndateTookBelowZeroIsFoundOnItsPath) {
  const SparseMatrix a = shiftedSlabMatrix();
  electric_detail::CholmodFactor f;
  f.analyze(a);
  f.factorize(a, "test");
  f.toSimplicial();
  EXPECT_TRUE(f.pivotsPositive());  // the whole check
  const auto column = [&](int row, double value) {
    SparseMatrix c(a.rows(), 1);
    c.insert(row, 0) = value;
    c.makeCompressed();
    return c;
  };
  f.updateDowndate(true, column(10, 1.0));
  EXPECT_TRUE(f.pivotsPositive());  // the path from row 10
  const int k = static_cast<int>(a.rows()) / 2;
  f.updateDowndate(false, column(k, std::sqrt(2.0 * a.coeff(k, k))));  // A_kk - 2 A_kk < 0
  EXPECT_FALSE(f.pivotsPositive());
  EXPECT_FALSE(f.pivotsPositive());
}

}  // namespace
}  // namespace esim
