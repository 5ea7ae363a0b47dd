// electric_local_study - what a local potential solve around the tool gives up against the
// full one, and what it costs (issue #11; README, "Why 50 000 nodes at 30 Hz stays out of
// reach here": the structural half of a coarse global model with a fine region around the
// tool is measured by coarse_local_study; this is the electric half). A study, not a solver
// of the phase.
//
// Scene: scenarios/slab_cut.yaml's slab (60 x 30 x 10 mm, graded along the cut line and
// toward the top; mesh.slab.nodes set to FINE_NODES), conductivity, blade, voltage, contact
// rule and distance, and return pad, read from the file. Frame k: the blade posed by the
// scene's tool path at frame kFirstFrame + k (x = -5 mm in frame 0 of slab_cut's 40 mm in
// 120 frames), a groove behind it (the tets whose centroid lies within kGrooveHalfWidthM of
// the path's line, above kGrooveFloorM, between the path's start and 1 mm behind the tip
// removed, so the contacts and the field see the cut's walls).
//   truth:  K_FF phi_F = -K_FD phi_D over the free nodes (CHOLMOD, factorized every frame as
//           the contact set changes; "direct ms");
//   held:   the nodes within MARGIN of the tip solved with every other node held at the
//           truth of LAG frames before (the far field "held from an earlier full solve",
//           as the issue puts it: refreshed every LAG frames on a thread, at best), the
//           Dirichlet nodes at their values of this frame;
//   coarse: phi_0 = g + P c, g the Dirichlet values (0 elsewhere), P the trilinear
//           interpolation from a uniform grid of cells of at most GRID mm (rows of
//           Dirichlet nodes zero), P' K P c = -P' K g (Galerkin); then, with a margin, the
//           region's correction with phi_0 outside (a two-level Schwarz step, as in
//           coarse_local_study).
// Errors per frame against the truth, the worst frame printed: the total Joule power's
// relative error (what heats the tissue in all: P = sum_e sigma V_e |grad phi|^2; printed
// signed, (P - P_true) / P_true, the frame of the largest magnitude), the
// largest error of a tet's power within kNearM of the tip over the largest tet power (the
// heating's shape where the tissue boils), the relative L2 error of the tets' power, and the
// largest |phi - phi_true| over the tool's voltage. Times are medians over the frames.
// Every model keeps this frame's Dirichlet values and minimizes the energy phi' K phi over
// its functions (the region's nodes free, the rest held), so its power exceeds the truth's
// by ||phi - phi_true||_K^2: the power error is the relative energy-norm error squared, and
// it never grows with the margin (nested spaces) for a given held or coarse field.
// The study checks itself: the held model with a region covering the body equals the truth
// (exit 1 above 1e-8).
// Usage: electric_local_study FINE_NODES [MARGIN_MM ...] [--lag FRAMES] [--grid MM]
//        [--frames F] (default margins 2 4 6 8, lag 3, grid 5 mm, 12 frames)
#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#include "sim/electrode.h"
#include "sim/fem_p1.h"
#include "sim/mesh_slab.h"
#include "sim/simulation.h"
#include "tools/app/run_config.h"
#include "tools/study_util.h"

using namespace esim;
using study::median;
using study::seconds;

namespace {

constexpr int kFirstFrame = 45;  // the scene's frame of the study's frame 0
constexpr double kGrooveHalfWidthM = 7e-4;
constexpr double kGrooveFloorM = 0.0085;  // [m] above the slab's bottom (its top: 10 mm)
constexpr double kGrooveLagM = 1e-3;      // the groove ends this far behind the tip
constexpr double kNearM = 2e-3;           // "near the tool"

// P (n x grid nodes): node v in cell c at local (x, y, z) in [0, 1]^3 gets the 8 trilinear
// weights; the rows of nodes that are not free are zero. Columns no free node reaches are
// dropped (their number returned in `columns`).
SparseMatrix trilinear(const TetMesh& mesh, const std::vector<char>& isFree, double spacingM,
                       int& columns) {
  Eigen::AlignedBox3d box;
  for (const Vec3& p : mesh.nodes) box.extend(p);
  int cells[3];
  for (int a = 0; a < 3; ++a)
    cells[a] = std::max(1, static_cast<int>(std::ceil(box.sizes()(a) / spacingM - 1e-9)));
  const Vec3 h(box.sizes()(0) / cells[0], box.sizes()(1) / cells[1], box.sizes()(2) / cells[2]);
  auto gridId = [&](int i, int j, int k) { return (i * (cells[1] + 1) + j) * (cells[2] + 1) + k; };
  std::vector<Eigen::Triplet<double>> entries;
  for (int v = 0; v < mesh.numNodes(); ++v) {
    if (!isFree[v]) continue;
    int c[3];
    double f[3];
    for (int a = 0; a < 3; ++a) {
      const double s = (mesh.nodes[v](a) - box.min()(a)) / h(a);
      c[a] = std::clamp(static_cast<int>(s), 0, cells[a] - 1);
      f[a] = std::clamp(s - c[a], 0.0, 1.0);
    }
    for (int corner = 0; corner < 8; ++corner) {
      const int di = corner & 1, dj = (corner >> 1) & 1, dk = (corner >> 2) & 1;
      const double w = (di ? f[0] : 1 - f[0]) * (dj ? f[1] : 1 - f[1]) * (dk ? f[2] : 1 - f[2]);
      if (w != 0) entries.emplace_back(v, gridId(c[0] + di, c[1] + dj, c[2] + dk), w);
    }
  }
  // renumber the grid nodes some free node reaches
  const int all = (cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1);
  std::vector<int> col(all, -1);
  columns = 0;
  for (const auto& e : entries)
    if (col[e.col()] < 0) col[e.col()] = 0;
  for (int g = 0; g < all; ++g)
    if (col[g] == 0) col[g] = columns++;
  for (auto& e : entries) e = Eigen::Triplet<double>(e.row(), col[e.col()], e.value());
  SparseMatrix p(mesh.numNodes(), columns);
  p.setFromTriplets(entries.begin(), entries.end());
  return p;
}

struct Model {
  Model(std::string n, double m, bool c) : name(std::move(n)), marginM(m), coarse(c) {}
  std::string name;
  double marginM = 0;  // < 0: the whole body (the check)
  bool coarse = false;
  double powerErr = 0, nearErr = 0, l2Err = 0, phiErr = 0;  // the worst frame
  std::vector<double> regionNodes, buildMs, solveMs, coarseBuildMs, coarseSolveMs;
};

}  // namespace

int main(int argc, char** argv) {
  const char* usage =
      "usage: electric_local_study FINE_NODES [MARGIN_MM ...] [--lag FRAMES] [--grid MM] "
      "[--frames F]\n";
  if (argc < 2) {
    std::fprintf(stderr, "%s", usage);
    return 2;
  }
  // a number in [lo, hi] (a whole one if `whole`), else exit 2 naming it
  const auto number = [](const char* what, const char* text, double lo, double hi, bool whole) {
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    if (end == text || *end != '\0' || !(v >= lo && v <= hi) || (whole && v != std::floor(v))) {
      std::fprintf(stderr, "electric_local_study: %s '%s': expected %s in [%g, %g]\n", what, text,
                   whole ? "a whole number" : "a number", lo, hi);
      std::exit(2);
    }
    return v;
  };
  const int fineNodes = static_cast<int>(number("FINE_NODES", argv[1], 100, 200000, true));
  std::vector<double> margins;
  int lag = 3, frames = 12;
  double gridM = 0.005;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--lag" || a == "--grid" || a == "--frames") {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "electric_local_study: %s needs a value\n%s", a.c_str(), usage);
        return 2;
      }
      const char* v = argv[++i];
      if (a == "--lag") lag = static_cast<int>(number("--lag", v, 1, 100, true));
      if (a == "--grid") gridM = 1e-3 * number("--grid", v, 0.5, 100, false);
      if (a == "--frames") frames = static_cast<int>(number("--frames", v, 1, 1000, true));
    } else {
      margins.push_back(1e-3 * number("MARGIN_MM", argv[i], 1e-3, 100, false));
    }
  }
  if (margins.empty()) margins = {0.002, 0.004, 0.006, 0.008};

  const Scenario scene = study::slabCutScenario(fineNodes);
  const SimulationConfig config = app::makeSimulationConfig(scene);
  TetMesh mesh = makeSlab(makeSlabSpec(scene));
  const int n = mesh.numNodes(), nt = mesh.numTets();
  const std::vector<TetGeometry> geo = tetGeometry(mesh);
  const std::vector<double> sigma(nt, config.conductivityS_m);
  const double voltageV = config.toolVoltageV;
  const Vec3 pathStart = config.toolPath.positionAt(0);
  std::vector<Vec3> centroid(nt);
  for (int t = 0; t < nt; ++t) {
    centroid[t] = Vec3::Zero();
    for (int v : mesh.tets[t]) centroid[t] += 0.25 * mesh.nodes[v];
  }

  std::vector<Model> models;
  models.emplace_back("whole (check)", -1, false);
  for (double m : margins)
    models.emplace_back("held " + std::to_string(m * 1e3).substr(0, 3) + " mm", m, false);
  models.emplace_back("coarse", 0, true);
  for (double m : margins)
    models.emplace_back("coarse+" + std::to_string(m * 1e3).substr(0, 3) + " mm", m, true);

  std::vector<Eigen::VectorXd> history;  // the truth of every frame
  std::vector<double> directMs, nearShare, contactCounts;
  double worstCheck = 0;
  int gridColumns = 0;
  for (int k = 0; k < lag + frames; ++k) {
    const ToolPose pose = config.toolPath.poseAt((kFirstFrame + k) * config.frameDtS);
    const Vec3& tip = pose.tipM;
    // the groove behind the tip
    for (int t = 0; t < nt; ++t) {
      const Vec3& c = centroid[t];
      mesh.alive[t] = !(std::abs(c(1) - pathStart(1)) < kGrooveHalfWidthM && c(2) > kGrooveFloorM &&
                        c(0) > pathStart(0) && c(0) < tip(0) - kGrooveLagM);
    }
    const std::vector<int> surface = boundaryNodes(mesh, boundaryFaces(mesh));
    const std::vector<int> candidates =
        config.contactNodes == ContactNodes::Surface ? surface : aliveNodes(mesh);
    const std::vector<int> contacts =
        findContacts(mesh, candidates, config.electrode, pose, config.contactDistanceM);
    const std::vector<int> ground = returnElectrodeNodes(mesh, surface, config.returnElectrode);
    if (contacts.empty()) {
      std::fprintf(stderr,
                   "electric_local_study: no contact in frame %d: no surface node within the "
                   "contact distance of the blade (too coarse a slab: take more nodes)\n",
                   k);
      return 1;
    }
    contactCounts.push_back(static_cast<double>(contacts.size()));
    std::vector<char> active(n, 0), isFree(n, 0);
    for (int t = 0; t < nt; ++t)
      if (mesh.alive[t])
        for (int v : mesh.tets[t]) active[v] = 1;
    Eigen::VectorXd g = Eigen::VectorXd::Zero(n);  // the Dirichlet values, 0 elsewhere
    std::vector<char> dirichlet(n, 0);
    for (int v : contacts) {
      dirichlet[v] = 1;
      g(v) = voltageV;
    }
    for (int v : ground) dirichlet[v] = 1;
    for (int v = 0; v < n; ++v) isFree[v] = active[v] && !dirichlet[v];
    const SparseMatrix kk = assembleStiffness(mesh, geo, sigma);

    // a solve on the free nodes of `region` (a subset of the free ones) with phi held
    // elsewhere: phi_R += K_RR^-1 (-(K phi)_R); returns its build and solve times [s]
    auto solveRegion = [&](const std::vector<int>& region, Eigen::VectorXd& phi, double& build,
                           double& solve) {
      const double t0 = seconds();
      std::vector<int> at(n, -1);
      for (size_t q = 0; q < region.size(); ++q) at[region[q]] = static_cast<int>(q);
      std::vector<Eigen::Triplet<double>> sub;
      for (int col : region)
        for (SparseMatrix::InnerIterator it(kk, col); it; ++it)
          if (at[it.row()] >= 0) sub.emplace_back(at[it.row()], at[col], it.value());
      const int m = static_cast<int>(region.size());
      SparseMatrix kuu(m, m);
      kuu.setFromTriplets(sub.begin(), sub.end());
      Eigen::CholmodSupernodalLLT<SparseMatrix> local(kuu);
      const double t1 = seconds();
      Eigen::VectorXd r(m);  // -(K phi)_R, by K's columns (symmetric): the region's cost only
      for (int q = 0; q < m; ++q) {
        double sum = 0;
        for (SparseMatrix::InnerIterator it(kk, region[q]); it; ++it)
          sum += it.value() * phi(it.row());
        r(q) = -sum;
      }
      const Eigen::VectorXd d = local.solve(r);
      for (int q = 0; q < m; ++q) phi(region[q]) += d(q);
      build = t1 - t0;
      solve = seconds() - t1;
    };

    // the truth
    std::vector<int> freeNodes;
    for (int v = 0; v < n; ++v)
      if (isFree[v]) freeNodes.push_back(v);
    Eigen::VectorXd truth = g;
    double build = 0, solve = 0;
    solveRegion(freeNodes, truth, build, solve);
    history.push_back(truth);
    if (k < lag) continue;
    directMs.push_back(1e3 * (build + solve));

    // the tets' power [W]
    auto tetPower = [&](const Eigen::VectorXd& phi) {
      std::vector<double> q(nt, 0.0);
      for (int t = 0; t < nt; ++t)
        if (mesh.alive[t])
          q[t] = sigma[t] * geo[t].volume * tetGradient(mesh, geo, t, phi).squaredNorm();
      return q;
    };
    const std::vector<double> qTrue = tetPower(truth);
    double pTrue = 0, qMax = 0, qNorm = 0, pNear = 0;
    for (int t = 0; t < nt; ++t) {
      pTrue += qTrue[t];
      qMax = std::max(qMax, qTrue[t]);
      qNorm += qTrue[t] * qTrue[t];
      if ((centroid[t] - tip).norm() < kNearM) pNear += qTrue[t];
    }
    nearShare.push_back(pNear / pTrue);

    // the coarse solve (shared by the coarse rows)
    double t0 = seconds();
    const SparseMatrix p = trilinear(mesh, isFree, gridM, gridColumns);
    const SparseMatrix kp = kk * p;
    SparseMatrix kc = SparseMatrix(p.transpose()) * kp;
    for (int c = 0; c < kc.cols(); ++c) kc.coeffRef(c, c) *= 1 + 1e-12;
    Eigen::CholmodSupernodalLLT<SparseMatrix> coarseSolver(kc);
    const double coarseBuild = seconds() - t0;
    t0 = seconds();
    const Eigen::VectorXd rhs = -(p.transpose() * (kk * g));
    const Eigen::VectorXd phi0 = g + p * coarseSolver.solve(rhs);
    const double coarseSolve = seconds() - t0;

    for (Model& model : models) {
      Eigen::VectorXd phi = model.coarse ? phi0 : history[k - lag];
      for (int v = 0; v < n; ++v)
        if (dirichlet[v]) phi(v) = g(v);
      std::vector<int> region;
      for (int v : freeNodes)
        if (model.marginM < 0 || (mesh.nodes[v] - tip).norm() < model.marginM) region.push_back(v);
      double b = 0, s = 0;
      if (!region.empty()) solveRegion(region, phi, b, s);
      const std::vector<double> q = tetPower(phi);
      double pSum = 0, nearMax = 0, num = 0, phiMax = 0;
      for (int t = 0; t < nt; ++t) {
        pSum += q[t];
        const double e = std::abs(q[t] - qTrue[t]);
        num += e * e;
        if ((centroid[t] - tip).norm() < kNearM) nearMax = std::max(nearMax, e);
      }
      for (int v = 0; v < n; ++v)
        if (active[v]) phiMax = std::max(phiMax, std::abs(phi(v) - truth(v)));
      const double excess = (pSum - pTrue) / pTrue;  // >= 0 up to round-off (see the top)
      if (std::abs(excess) >= std::abs(model.powerErr)) model.powerErr = excess;
      model.nearErr = std::max(model.nearErr, nearMax / qMax);
      model.l2Err = std::max(model.l2Err, std::sqrt(num / qNorm));
      model.phiErr = std::max(model.phiErr, phiMax / voltageV);
      if (model.marginM < 0)
        worstCheck = std::max(worstCheck, phiMax / truth.cwiseAbs().maxCoeff());
      model.regionNodes.push_back(static_cast<double>(region.size()));
      model.buildMs.push_back(1e3 * b);
      model.solveMs.push_back(1e3 * s);
      model.coarseBuildMs.push_back(model.coarse ? 1e3 * coarseBuild : 0.0);
      model.coarseSolveMs.push_back(model.coarse ? 1e3 * coarseSolve : 0.0);
    }
  }
  std::printf(
      "scenarios/slab_cut.yaml, %.0f V: %d nodes, %d tets; %d frames (tip x from %.1f to %.1f mm), "
      "lag %d frames, coarse grid "
      "%.1f mm (%d grid nodes); contacts %.0f (median); the truth (CHOLMOD, factorized and "
      "solved): %.1f ms median; power within %.0f mm of the tip: %.1f %% (median)\n",
      voltageV, n, nt, frames,
      1e3 * config.toolPath.positionAt((kFirstFrame + lag) * config.frameDtS)(0),
      1e3 * config.toolPath.positionAt((kFirstFrame + lag + frames - 1) * config.frameDtS)(0), lag,
      1e3 * gridM, gridColumns, median(contactCounts), median(directMs), 1e3 * kNearM,
      100 * median(nearShare));
  std::printf(
      "| model | region nodes | region build ms | region solve ms | coarse build / solve ms "
      "| power excess | near-tool tet power error | tet power L2 error | phi error / V |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  for (const Model& m : models)
    std::printf("| %s | %.0f | %.2f | %.2f | %.2f / %.2f | %.2e | %.2e | %.2e | %.2e |\n",
                m.name.c_str(), median(m.regionNodes), median(m.buildMs), median(m.solveMs),
                median(m.coarseBuildMs), median(m.coarseSolveMs), m.powerErr, m.nearErr, m.l2Err,
                m.phiErr);
  std::printf("check: the whole-body region against the truth, relative difference %.1e\n",
              worstCheck);
  return worstCheck <= 1e-8 ? 0 : 1;
}
