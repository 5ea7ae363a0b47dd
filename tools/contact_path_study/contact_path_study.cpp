// contact_path_study - what the potential of a new contact set costs on a kept factor, two ways
// (issue #11: the columns `downdate` solved again after each removal; README, "The potential on a
// factor kept exact through the cut").
// The scene is slab_cut's (scenarios/slab_cut.yaml: its graded slab at NODES nodes, its
// conductivity, its return pad grounded); the potential's matrix K_ff on the nodes off the pad is
// factorized as `downdate` factorizes it (CholmodFactor: supernodal, then simplicial LDL'); the
// contacts are the CONTACTS free nodes nearest the blade's edge (x in [-2.5, 2.5] mm, y = 0, on the
// top face) at 1 V. Capacitance's algebra (sim/electric_solver.h): Z = K_ff^-1 E_C, Z_CC f = 1, u =
// Z f.
//   columns:  each column of Z by a full solve, one by one (ldl_solve.h, one thread);
//   blocks:   the same by CHOLMOD's simplicial solve in blocks of 4 (what `downdate` does);
//   paths:    y_c = L^-1 e_c, whose nonzeros lie on c's path up the elimination tree, solved
//             on that path alone; Z_CC = Y' D^-1 Y over the paths' common rows; then one full
//             solve u = K_ff^-1 E_C f.
//   downdate: the solver as built (sim/electric_downdate.cpp): the same paths in one pass over
//             their union's columns of L for all contacts, Z_CC, then u = P' L'^-1 D^-1 (Y f),
//             the backward half of a solve; its kept paths dropped before each time.
// Each time is the best of five. The study checks what it times: the three potentials agree
// (the largest relative difference is printed; exit 1 above 1e-10).
// Usage: contact_path_study [--contacts N] [NODES ...] (default 24 contacts; 8000 27000 50000)
#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "sim/cholmod_view.h"
#include "sim/electric_solver.h"
#include "sim/electrode.h"
#include "sim/fem_p1.h"
#include "sim/mesh_tet.h"
#include "tools/app/run_config.h"
#include "tools/study_util.h"

using namespace esim;

namespace {

constexpr int kRepeats = 5;
constexpr int kBlock = 4;  // columns a CHOLMOD solve takes at once, as `downdate` does

struct Row {
  int nodes = 0, free = 0, contacts = 0;
  long factorEntries = 0, pathEntries = 0;
  double columnsMs = 0, blocksMs = 0, pathsMs = 0, solverMs = 0, difference = 0;
};

Row measure(int targetNodes, int contacts) {
  const Scenario sc = study::slabCutScenario(targetNodes);
  const SimulationConfig config = app::makeSimulationConfig(sc);
  const TetMesh mesh = app::buildMesh(sc);
  const std::vector<TetGeometry> geo = tetGeometry(mesh);
  const int n = mesh.numNodes();
  const SparseMatrix k = assembleStiffness(
      mesh, geo, std::vector<double>(mesh.numTets(), sc.material.electricConductivitySPerM));
  electric_detail::NodeClasses classes;
  const std::vector<int> grounded =
      returnElectrodeNodes(mesh, boundaryNodes(mesh, boundaryFaces(mesh)), config.returnElectrode);
  classes.build(k, grounded);
  const SparseMatrix a = electric_detail::restrictToFree(k, classes);
  const int nf = classes.numFree();
  const std::vector<int>& freeNode = classes.freeNodes;
  // factorized as `downdate` factorizes it: supernodal, then simplicial LDL'
  electric_detail::CholmodFactor factor;
  factor.analyze(a);
  factor.factorize(a, "contact_path_study");
  factor.toSimplicial();
  const SimplicialView l(&factor.cholmod());
  std::vector<int> position(nf);  // free index -> row of L
  const std::vector<int> perm = factor.ordering();
  for (int i = 0; i < nf; ++i) position[perm[i]] = i;

  Row row;
  row.nodes = n;
  row.free = nf;
  row.factorEntries = static_cast<long>(factor.factorEntries());
  // the contacts: the free nodes nearest the blade's edge
  std::vector<std::pair<double, int>> nearest;
  for (int f = 0; f < nf; ++f) {
    const Vec3& p = mesh.nodes[freeNode[f]];
    const double x = std::clamp(p.x(), -0.0025, 0.0025);
    nearest.push_back({(p - Vec3(x, 0, 0.01)).squaredNorm(), f});
  }
  std::sort(nearest.begin(), nearest.end());
  row.contacts = std::min(contacts, nf);
  std::vector<int> c(row.contacts);
  for (int q = 0; q < row.contacts; ++q) c[q] = nearest[q].second;
  const int nc = row.contacts;
  const Eigen::VectorXd volts = Eigen::VectorXd::Ones(nc);

  std::vector<int> contactNodes;  // the contacts as mesh nodes, ascending (the solver's input)
  for (int q : c) contactNodes.push_back(freeNode[q]);
  std::sort(contactNodes.begin(), contactNodes.end());
  auto solver = makeElectricSolver({.strategy = ElectricStrategy::Downdate});
  solver->setMatrix(k, grounded);
  Eigen::VectorXd potential;

  Eigen::VectorXd uColumns, uBlocks, uPaths, uSolver(nf);
  row.columnsMs = row.blocksMs = row.pathsMs = row.solverMs = 1e30;
  for (int rep = 0; rep < kRepeats; ++rep) {
    // columns, one by one (ldl_solve.h on one thread)
    double t = study::seconds();
    Eigen::MatrixXd z(nf, nc);
    std::vector<double> e(nf, 0.0);
    for (int q = 0; q < nc; ++q) {
      e[c[q]] = 1;
      factor.solve(e.data(), z.col(q).data());
      e[c[q]] = 0;
    }
    Eigen::MatrixXd zcc(nc, nc);
    for (int p = 0; p < nc; ++p)
      for (int q = 0; q < nc; ++q) zcc(p, q) = z(c[p], q);
    uColumns = z * zcc.ldlt().solve(volts);
    row.columnsMs = std::min(row.columnsMs, 1e3 * (study::seconds() - t));

    // columns in blocks of 4 (CHOLMOD's simplicial solve)
    t = study::seconds();
    Eigen::MatrixXd zb(nf, nc);
    for (int q0 = 0; q0 < nc; q0 += kBlock) {
      const int w = std::min(kBlock, nc - q0);
      Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nf, w);
      for (int q = 0; q < w; ++q) rhs(c[q0 + q], q) = 1;
      factor.solve(rhs.data(), zb.middleCols(q0, w).data(), w);
    }
    for (int p = 0; p < nc; ++p)
      for (int q = 0; q < nc; ++q) zcc(p, q) = zb(c[p], q);
    uBlocks = zb * zcc.ldlt().solve(volts);
    row.blocksMs = std::min(row.blocksMs, 1e3 * (study::seconds() - t));

    // paths up the elimination tree, then one full solve
    t = study::seconds();
    std::vector<std::vector<int>> path(nc);
    std::vector<std::vector<double>> y(nc);
    std::vector<double> dense(nf, 0.0);
    row.pathEntries = 0;
    for (int q = 0; q < nc; ++q) {
      const int start = position[c[q]];
      for (int j = start; j >= 0; j = l.parent(j)) path[q].push_back(j);
      dense[start] = 1;
      for (int j : path[q]) {
        const double yj = dense[j];
        if (yj != 0)
          for (int p = l.p[j] + 1; p < l.p[j] + l.nz[j]; ++p) dense[l.i[p]] -= l.x[p] * yj;
        row.pathEntries += l.nz[j];
      }
      y[q].resize(path[q].size());
      for (size_t s = 0; s < path[q].size(); ++s) {
        y[q][s] = dense[path[q][s]];
        dense[path[q][s]] = 0;
      }
    }
    Eigen::MatrixXd zp(nc, nc);
    for (int p = 0; p < nc; ++p) {
      for (size_t s = 0; s < path[p].size(); ++s)
        dense[path[p][s]] = y[p][s] / l.diagonal(path[p][s]);
      for (int q = p; q < nc; ++q) {
        double sum = 0;
        for (size_t s = 0; s < path[q].size(); ++s) sum += dense[path[q][s]] * y[q][s];
        zp(p, q) = zp(q, p) = sum;
      }
      for (int j : path[p]) dense[j] = 0;
    }
    const Eigen::VectorXd f = zp.ldlt().solve(volts);
    std::vector<double> rhs(nf, 0.0);
    for (int q = 0; q < nc; ++q) rhs[c[q]] = f[q];
    uPaths.resize(nf);
    factor.solve(rhs.data(), uPaths.data());
    row.pathsMs = std::min(row.pathsMs, 1e3 * (study::seconds() - t));

    // the downdate solver, its kept paths dropped
    solver->limitCache(0);
    t = study::seconds();
    solver->solve(contactNodes, 1.0, potential);
    row.solverMs = std::min(row.solverMs, 1e3 * (study::seconds() - t));
    solver->limitCache(1e12);
  }
  for (int f = 0; f < nf; ++f) uSolver[f] = potential[freeNode[f]];
  row.difference = std::max({(uBlocks - uColumns).norm(), (uPaths - uColumns).norm(),
                             (uSolver - uColumns).norm()}) /
                   uColumns.norm();
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  int contacts = 24;
  std::vector<int> sizes;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    char* end = nullptr;
    if (arg == "--contacts" && i + 1 < argc) {
      contacts = static_cast<int>(std::strtol(argv[++i], &end, 10));
      if (*end != 0 || contacts < 1 || contacts > 10000) {
        std::fprintf(stderr, "contact_path_study: --contacts %s: expected 1 to 10000\n", argv[i]);
        return 2;
      }
      continue;
    }
    const long nodes = std::strtol(argv[i], &end, 10);
    if (*end != 0 || nodes < 100 || nodes > 2000000) {
      std::fprintf(stderr,
                   "contact_path_study: '%s': expected a node count from 100 to 2000000, or "
                   "--contacts N\n",
                   argv[i]);
      return 2;
    }
    sizes.push_back(static_cast<int>(nodes));
  }
  if (sizes.empty()) sizes = {8000, 27000, 50000};
  std::printf(
      "# the potential of a new contact set on a kept factor (best of %d, one thread)\n"
      "# nodes free entries_of_L contacts columns_ms blocks_ms paths_ms path_entries "
      "max_rel_difference downdate_ms\n",
      kRepeats);
  double worst = 0;
  for (int nodes : sizes) {
    const Row r = measure(nodes, contacts);
    std::printf("%d %d %ld %d %.3f %.3f %.3f %ld %.1e %.3f\n", r.nodes, r.free, r.factorEntries,
                r.contacts, r.columnsMs, r.blocksMs, r.pathsMs, r.pathEntries, r.difference,
                r.solverMs);
    std::fflush(stdout);
    worst = std::max(worst, r.difference);
  }
  if (!(worst <= 1e-10)) {
    std::fprintf(stderr, "contact_path_study: the potentials differ by %.1e (> 1e-10)\n", worst);
    return 1;
  }
  return 0;
}
