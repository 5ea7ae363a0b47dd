// coarse_local_study - what a coarse global structural solve with a fine local correction
// around the tool gives up against the full solve, and what it costs (issue #11; README,
// "Why 50 000 nodes at 30 Hz stays out of reach here"). A study, not a solver of the phase.
//
// Scene: slab_cut's slab (scenarios/slab_cut.yaml's: 60 x 30 x 10 mm, graded along the cut
// line and toward the top),
// the paper's E and nu, the bottom face clamped. Frame k of F: the tool at x_k on the top
// face along y = 0 (x from -20 to +20 mm), the expansion e_v = kPeakExpansion exp(-d^2 / 2
// r^2) (d: the centroid's distance to the path up to the tool, r = kLoadRadiusM) loading
// every alive tet (the vapour trapped along the trail); after each frame the tets over the
// critical stress in the truth are removed (a groove opens as in a cut), and so are the
// pieces that cuts loose, so each frame's flips are the tets the model would remove
// differently from the same history.
//   truth:  StructuralPhase built on that alive set, solve(e_v) (its solve time: "full ms");
//   coarse: u_0 = P K_c^-1 P' f, P the P1 interpolation from a uniform coarse slab of the
//           same box (COARSE nodes; graded as the fine one with --graded-coarse) to the
//           fine nodes (zero rows on held components), K_c = P' K P (Galerkin: the groove
//           is in it), factorized each frame;
//   local:  u = u_0 + d, K_UU d_U = (f - K u_0)_U on U, the free components of the fine
//           nodes within MARGIN of the tool point, d = 0 elsewhere (one step of a two-level
//           multiplicative Schwarz method: coarse, then the region).
//   +ref:   the coarse space with one more column, the truth of kReferenceLag frames before
//           (the far field "held from an earlier full solve", as the issue puts it, but
//           within a Galerkin solve instead of as boundary values), by block elimination.
// Errors per frame from frame kReferenceLag on, against the truth, over the alive tets: the
// largest |vm - vm_true| within kNearM of the tool and anywhere (over the critical stress,
// 24.5 kPa), the relative L2 error of vm, the energy-norm error ||u - u_true||_K /
// ||u_true||_K, and the tets on the other side of the critical stress (which a cut would
// remove differently), within kNearM of the tool (n_flips) and anywhere (flips). The table
// gives the worst frame (errors), the sum over the frames (flips) and the median (times;
// "build" is a region's assembly and CHOLMOD factorization, "coarse_b" P' K P and its
// factorization, both redone every frame here: a solver would keep them and update them).
// The study checks itself: with a region covering the body, the result must equal the
// truth (relative difference printed; exit 1 above 1e-8). The coarse slab must be coarser
// than the graded fine one everywhere (else P' K P is singular: exit 1, saying so).
// Usage: coarse_local_study FINE_NODES COARSE_NODES [MARGIN_MM ...] [--graded-coarse]
// (default margins 2 4 8; --graded-coarse: the coarse slab graded as the fine one)
#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "sim/fem_p1.h"
#include "sim/mesh_slab.h"
#include "sim/simulation.h"
#include "sim/structural.h"
#include "tools/study_util.h"

using namespace esim;
using study::median;
using study::seconds;

namespace {

// the defaults (paper Tables 1 and 2), from the one source of them
const double kYoungsModulusPa = defaultSimulationConfig().structural.youngsModulusPa;
const double kPoissonRatio = defaultSimulationConfig().structural.poissonRatio;
const double kCriticalStressPa = defaultSimulationConfig().criticalStressPa;
constexpr double kPeakExpansion = 2.0;  // e_v on the path (boiling tissue: 0.9-3)
constexpr double kLoadRadiusM = 1e-3;   // the expansion's Gaussian radius
constexpr double kNearM = 2e-3;         // "near the tool"
constexpr int kFrames = 10;
constexpr int kReferenceLag = 2;  // frames: the "+ref" rows' reference
const Vec3 kPathFrom(-0.02, 0, 0.01), kPathTo(0.02, 0, 0.01);

double distanceToSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm();
}

// P (3 n_f x 3 n_c): fine node i at barycentric weights w of coarse tet c gets
// u_i = sum_k w_k u_c[k], per component. Each fine node goes to the coarse tet whose
// smallest barycentric coordinate is largest (inside: >= 0; a node on the surface, just
// outside by round-off, to the nearest).
SparseMatrix interpolation(const TetMesh& fine, const TetMesh& coarse) {
  const std::vector<TetGeometry> geo = tetGeometry(coarse);
  // the coarse tets by a uniform grid of their bounding boxes
  Eigen::AlignedBox3d box;
  for (const Vec3& p : coarse.nodes) box.extend(p);
  const int cells = std::max(1, static_cast<int>(std::cbrt(coarse.numTets() / 4.0)));
  const Vec3 size = box.sizes() / cells;
  auto cellOf = [&](const Vec3& p, int a) {
    return std::clamp(static_cast<int>((p(a) - box.min()(a)) / size(a)), 0, cells - 1);
  };
  std::vector<std::vector<int>> grid(cells * cells * cells);
  for (int t = 0; t < coarse.numTets(); ++t) {
    Eigen::AlignedBox3d b;
    for (int v : coarse.tets[t]) b.extend(coarse.nodes[v]);
    for (int i = cellOf(b.min(), 0); i <= cellOf(b.max(), 0); ++i)
      for (int j = cellOf(b.min(), 1); j <= cellOf(b.max(), 1); ++j)
        for (int k = cellOf(b.min(), 2); k <= cellOf(b.max(), 2); ++k)
          grid[(i * cells + j) * cells + k].push_back(t);
  }
  std::vector<Eigen::Triplet<double>> entries;
  for (int v = 0; v < fine.numNodes(); ++v) {
    const Vec3& p = fine.nodes[v];
    const std::vector<int>& candidates =
        grid[(cellOf(p, 0) * cells + cellOf(p, 1)) * cells + cellOf(p, 2)];
    int best = -1;
    double bestMin = -1e300;
    Eigen::Vector4d bestW;
    for (int t : candidates) {
      // N_k(p) = N_k(x_0) + grad N_k . (p - x_0), N_k(x_0) = (k == 0)
      Eigen::Vector4d w;
      const Vec3 d = p - coarse.nodes[coarse.tets[t][0]];
      for (int k = 0; k < 4; ++k) w(k) = (k == 0 ? 1.0 : 0.0) + geo[t].grad.row(k).dot(d);
      if (w.minCoeff() > bestMin) {
        bestMin = w.minCoeff();
        best = t;
        bestW = w;
      }
    }
    if (best < 0) {
      std::fprintf(stderr, "coarse_local_study: fine node %d lies in no coarse grid cell\n", v);
      std::exit(1);
    }
    for (int k = 0; k < 4; ++k)
      for (int a = 0; a < 3; ++a)
        entries.emplace_back(3 * v + a, 3 * coarse.tets[best][k] + a, bestW(k));
  }
  SparseMatrix p(3 * fine.numNodes(), 3 * coarse.numNodes());
  p.setFromTriplets(entries.begin(), entries.end());
  return p;
}

// the pairs of tets sharing a face
std::vector<std::array<int, 2>> facePairs(const TetMesh& mesh) {
  std::vector<std::pair<std::array<int, 3>, int>> faces;
  for (int t = 0; t < mesh.numTets(); ++t)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> f;
      for (int i = 0, k = 0; i < 4; ++i)
        if (i != skip) f[k++] = mesh.tets[t][i];
      std::sort(f.begin(), f.end());
      faces.emplace_back(f, t);
    }
  std::sort(faces.begin(), faces.end());
  std::vector<std::array<int, 2>> pairs;
  for (size_t i = 1; i < faces.size(); ++i)
    if (faces[i].first == faces[i - 1].first)
      pairs.push_back({faces[i - 1].second, faces[i].second});
  return pairs;
}

// removes the alive tets no chain of shared faces links to a tet with a face on the clamp:
// pieces the removals cut loose (StructuralPhase holds them still; here they go)
void dropLoosePieces(TetMesh& mesh, const std::vector<std::array<int, 2>>& faceTets,
                     const std::vector<char>& onClamp) {
  const int nt = mesh.numTets();
  std::vector<std::vector<int>> next(nt);
  for (const auto& [a, b] : faceTets)
    if (mesh.alive[a] && mesh.alive[b]) {
      next[a].push_back(b);
      next[b].push_back(a);
    }
  std::vector<char> held(nt, 0);
  std::vector<int> stack;
  for (int t = 0; t < nt; ++t) {
    int clamped = 0;
    for (int v : mesh.tets[t]) clamped += onClamp[v];
    if (mesh.alive[t] && clamped >= 3) {
      held[t] = 1;
      stack.push_back(t);
    }
  }
  while (!stack.empty()) {
    const int t = stack.back();
    stack.pop_back();
    for (int u : next[t])
      if (!held[u]) {
        held[u] = 1;
        stack.push_back(u);
      }
  }
  for (int t = 0; t < nt; ++t)
    if (!held[t]) mesh.alive[t] = 0;
}

struct Row {
  double margin = 0;      // [m]; < 0: the whole body (the check)
  bool enriched = false;  // the coarse space holds the reference too
  std::vector<double> regionDofs, regionBuildMs, regionSolveMs, coarseBuildMs, coarseSolveMs;
  double nearMax = 0, anyMax = 0, l2 = 0;  // worst frame, errors over kCriticalStressPa
  double energy = 0;                       // worst frame, ||u - u_true||_K / ||u_true||_K
  int flips = 0, nearFlips = 0;            // over all frames (near: within kNearM)
  int above = 0, nearAbove = 0;            // the truth's tets over the critical stress
};

}  // namespace

int main(int argc, char** argv) {
  // --graded-coarse anywhere: the coarse slab graded as the fine one (finer along the cut)
  bool gradedCoarse = false;
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i)
    if (std::string(argv[i]) == "--graded-coarse")
      gradedCoarse = true;
    else
      args.push_back(argv[i]);
  argc = static_cast<int>(args.size());
  argv = args.data();
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: coarse_local_study FINE_NODES COARSE_NODES [MARGIN_MM ...] "
                 "[--graded-coarse]\n");
    return 2;
  }
  // a whole number in [lo, hi], else exit 2 naming it
  const auto count = [](const char* what, const char* text, long lo, long hi) {
    char* end = nullptr;
    const long v = std::strtol(text, &end, 10);
    if (end == text || *end != '\0' || v < lo || v > hi) {
      std::fprintf(stderr, "coarse_local_study: %s '%s': expected a node count in [%ld, %ld]\n",
                   what, text, lo, hi);
      std::exit(2);
    }
    return static_cast<int>(v);
  };
  const int fineNodes = count("FINE_NODES", argv[1], 100, 200000);
  const int coarseNodes = count("COARSE_NODES", argv[2], 27, fineNodes);
  std::vector<double> marginsM = {0};  // 0: the coarse solve alone
  if (argc == 3) marginsM.insert(marginsM.end(), {2e-3, 4e-3, 8e-3});
  for (int i = 3; i < argc; ++i) {
    char* end = nullptr;
    const double mm = std::strtod(argv[i], &end);
    if (end == argv[i] || *end != '\0' || !(mm > 0 && mm <= 100)) {
      std::fprintf(stderr, "coarse_local_study: MARGIN_MM '%s': expected a number in (0, 100]\n",
                   argv[i]);
      return 2;
    }
    marginsM.push_back(mm * 1e-3);
  }
  marginsM.push_back(-1);  // the whole body: must equal the truth
  std::vector<Row> rows;
  for (double m : marginsM)
    for (bool enriched : {false, true})
      if (m >= 0 || !enriched) {
        rows.push_back({});
        rows.back().margin = m;
        rows.back().enriched = enriched;
      }

  TetMesh fine = makeSlab(makeSlabSpec(study::slabCutScenario(fineNodes)));
  SlabSpec coarseSpec = makeSlabSpec(study::slabCutScenario(coarseNodes));
  coarseSpec.grading.enabled = gradedCoarse;
  const TetMesh coarse = makeSlab(coarseSpec);
  const std::vector<TetGeometry> geo = tetGeometry(fine);
  const int n = fine.numNodes(), nt = fine.numTets();
  const SparseMatrix p0 = interpolation(fine, coarse);
  std::vector<Support> clamp;
  for (int v = 0; v < n; ++v)
    if (fine.nodes[v].z() < 1e-9)
      for (int a = 0; a < 3; ++a) clamp.push_back({v, a});
  std::printf(
      "coarse_local_study: slab_cut's slab, %d fine nodes (%d tets), coarse %d nodes (%d "
      "tets, %s); %d frames, e_v %.2g on the path (radius %.2g mm), the truth's tets over "
      "%.1f kPa removed after each\n",
      n, nt, coarse.numNodes(), coarse.numTets(), gradedCoarse ? "graded" : "uniform", kFrames,
      kPeakExpansion, kLoadRadiusM * 1e3, kCriticalStressPa * 1e-3);
  std::vector<char> onClamp(n, 0);
  for (const Support& c : clamp) onClamp[c.node] = 1;
  const std::vector<std::array<int, 2>> faceTets = facePairs(fine);
  std::vector<double> fullMs;
  std::vector<Eigen::VectorXd> truths;  // the displacement of every frame so far
  double worstCheck = 0;
  const double lambda = kYoungsModulusPa * kPoissonRatio /
                        ((1 + kPoissonRatio) * (1 - 2 * kPoissonRatio)),
               mu = kYoungsModulusPa / (2 * (1 + kPoissonRatio)),
               bulk = kYoungsModulusPa / (3 * (1 - 2 * kPoissonRatio));
  std::vector<Vec3> centroid(nt, Vec3::Zero());
  for (int t = 0; t < nt; ++t)
    for (int v : fine.tets[t]) centroid[t] += fine.nodes[v] / 4;
  for (int frame = 0; frame < kFrames; ++frame) {
    const double s = (frame + 1.0) / kFrames;
    const Vec3 tool = kPathFrom + s * (kPathTo - kPathFrom);
    std::vector<double> ev(nt, 0.0);
    for (int t = 0; t < nt; ++t) {
      const double d = distanceToSegment(centroid[t], kPathFrom, tool);
      ev[t] = kPeakExpansion * std::exp(-d * d / (2 * kLoadRadiusM * kLoadRadiusM));
    }
    dropLoosePieces(fine, faceTets, onClamp);
    // the truth
    StructuralOptions so;
    so.youngsModulusPa = kYoungsModulusPa;
    so.poissonRatio = kPoissonRatio;
    StructuralPhase truth(fine, so, clamp);
    truth.solve(ev);
    if (truth.numFloatingIslands() > 0) {
      std::fprintf(stderr, "coarse_local_study: the truth holds a floating island (frame %d)\n",
                   frame);
      return 1;
    }
    fullMs.push_back(1e3 * truth.lastSolveStats().seconds);
    truths.push_back(truth.displacementM());
    std::vector<int> breaking;  // removed at the end of the frame
    for (int t = 0; t < nt; ++t)
      if (fine.alive[t] && truth.vonMisesPa()[t] > kCriticalStressPa) breaking.push_back(t);
    if (frame < kReferenceLag) {  // errors from the first frame with a reference
      for (int t : breaking) fine.alive[t] = 0;
      continue;
    }
    // K and f over all components; held: the clamp and nodes without an alive tet
    std::vector<char> held(3 * n, 1);
    for (int t = 0; t < nt; ++t)
      if (fine.alive[t])
        for (int v : fine.tets[t])
          for (int a = 0; a < 3; ++a) held[3 * v + a] = 0;
    for (const Support& c : clamp) held[3 * c.node + c.axis] = 1;
    std::vector<Eigen::Triplet<double>> entries;
    Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * n);
    for (int t = 0; t < nt; ++t) {
      if (!fine.alive[t]) continue;
      const Eigen::Matrix<double, 12, 12> ke =
          elasticTetStiffness(geo[t], kYoungsModulusPa, kPoissonRatio);
      for (int i = 0; i < 12; ++i) {
        const int di = 3 * fine.tets[t][i / 3] + i % 3;
        if (held[di]) continue;
        f(di) += geo[t].volume * bulk * ev[t] * geo[t].grad(i / 3, i % 3);
        for (int j = 0; j < 12; ++j) {
          const int dj = 3 * fine.tets[t][j / 3] + j % 3;
          if (!held[dj]) entries.emplace_back(di, dj, ke(i, j));
        }
      }
    }
    SparseMatrix k(3 * n, 3 * n);
    k.setFromTriplets(entries.begin(), entries.end());
    // the coarse solve (rows of held components zeroed; coarse components nothing uses held)
    double t0 = seconds();
    SparseMatrix p = p0;
    for (int col = 0; col < p.outerSize(); ++col)
      for (SparseMatrix::InnerIterator it(p, col); it; ++it)
        if (held[it.row()]) it.valueRef() = 0;
    p.prune(0.0);
    SparseMatrix kc = SparseMatrix(p.transpose()) * (k * p);
    for (int c = 0; c < kc.rows(); ++c)
      if (kc.coeff(c, c) == 0) kc.coeffRef(c, c) = 1;  // unused: identity
    Eigen::CholmodSupernodalLLT<SparseMatrix> coarseSolver(kc);
    if (coarseSolver.info() != Eigen::Success) {
      std::fprintf(stderr,
                   "coarse_local_study: K_c = P' K P is singular (frame %d): the coarse slab is "
                   "finer than the graded fine one somewhere (P's columns dependent); use fewer "
                   "COARSE_NODES\n",
                   frame);
      return 1;
    }
    const double coarseBuild = seconds() - t0;
    t0 = seconds();
    const Eigen::VectorXd fc = p.transpose() * f, ac = coarseSolver.solve(fc);
    const Eigen::VectorXd u0plain = p * ac;
    const double coarseSolve = seconds() - t0;
    // the coarse space with the reference v (the truth kReferenceLag frames ago, 0 on the held
    // components) as one more column: the Galerkin solve of [P v] by block elimination
    t0 = seconds();
    Eigen::VectorXd v = truths[frame - kReferenceLag];
    for (int dof = 0; dof < 3 * n; ++dof)
      if (held[dof]) v(dof) = 0;
    const Eigen::VectorXd kv = k * v, pkv = p.transpose() * kv, z = coarseSolver.solve(pkv);
    const double schur = v.dot(kv) - pkv.dot(z);
    const double beta = (v.dot(f) - pkv.dot(ac)) / schur;
    const Eigen::VectorXd u0ref = p * (ac - beta * z) + beta * v;
    const double enrichSolve = seconds() - t0;
    for (Row& row : rows) {
      const Eigen::VectorXd& u0 = row.enriched ? u0ref : u0plain;
      const Eigen::VectorXd r = f - k * u0;
      // the region: free components of nodes within the margin of the tool
      std::vector<int> region;
      for (int v = 0; v < n; ++v)
        if (row.margin < 0 || (row.margin > 0 && (fine.nodes[v] - tool).norm() < row.margin))
          for (int a = 0; a < 3; ++a)
            if (!held[3 * v + a]) region.push_back(3 * v + a);
      Eigen::VectorXd u = u0;
      double build = 0, solve = 0;
      if (!region.empty()) {
        t0 = seconds();
        std::vector<int> at(3 * n, -1);
        for (size_t q = 0; q < region.size(); ++q) at[region[q]] = static_cast<int>(q);
        std::vector<Eigen::Triplet<double>> sub;
        for (int col : region)
          for (SparseMatrix::InnerIterator it(k, col); it; ++it)
            if (at[it.row()] >= 0) sub.emplace_back(at[it.row()], at[col], it.value());
        const int m = static_cast<int>(region.size());
        SparseMatrix kuu(m, m);
        kuu.setFromTriplets(sub.begin(), sub.end());
        Eigen::CholmodSupernodalLLT<SparseMatrix> local(kuu);
        build = seconds() - t0;
        t0 = seconds();
        Eigen::VectorXd ru(m);
        for (int q = 0; q < m; ++q) ru(q) = r(region[q]);
        const Eigen::VectorXd d = local.solve(ru);
        for (int q = 0; q < m; ++q) u(region[q]) += d(q);
        solve = seconds() - t0;
      }
      // stresses and errors
      double nearMax = 0, anyMax = 0, num = 0, den = 0;
      for (int t = 0; t < nt; ++t) {
        if (!fine.alive[t]) continue;
        // sigma = D (strain - e_v / 3 I) = D strain - K_b e_v (1, 1, 1, 0, 0, 0)
        const std::array<int, 4>& tv = fine.tets[t];
        const std::array<double, 6> strain =
            tetStrain(geo[t], {u.data() + 3 * tv[0], u.data() + 3 * tv[1], u.data() + 3 * tv[2],
                               u.data() + 3 * tv[3]});
        const double tr = strain[0] + strain[1] + strain[2];
        VoigtStress sigma;
        for (int a = 0; a < 3; ++a) sigma[a] = lambda * tr + 2 * mu * strain[a] - bulk * ev[t];
        for (int a = 3; a < 6; ++a) sigma[a] = mu * strain[a];
        const double vm = vonMises(sigma), want = truth.vonMisesPa()[t];
        const double err = std::abs(vm - want);
        const bool near = (centroid[t] - tool).norm() < kNearM;
        anyMax = std::max(anyMax, err);
        if (near) nearMax = std::max(nearMax, err);
        num += err * err;
        den += want * want;
        const bool flip = (vm > kCriticalStressPa) != (want > kCriticalStressPa);
        row.flips += flip;
        row.nearFlips += flip && near;
        if (row.margin == 0) {  // once per frame
          row.above += want > kCriticalStressPa;
          row.nearAbove += near && want > kCriticalStressPa;
        }
      }
      row.nearMax = std::max(row.nearMax, nearMax / kCriticalStressPa);
      row.anyMax = std::max(row.anyMax, anyMax / kCriticalStressPa);
      row.l2 = std::max(row.l2, std::sqrt(num / den));
      const Eigen::VectorXd& want = truth.displacementM();
      const Eigen::VectorXd e = u - want;
      row.energy = std::max(row.energy, std::sqrt(e.dot(k * e) / want.dot(k * want)));
      if (row.margin < 0) worstCheck = std::max(worstCheck, e.norm() / want.norm());
      row.regionDofs.push_back(static_cast<double>(region.size()));
      row.regionBuildMs.push_back(1e3 * build);
      row.regionSolveMs.push_back(1e3 * solve);
      row.coarseBuildMs.push_back(1e3 * coarseBuild);
      row.coarseSolveMs.push_back(1e3 * (coarseSolve + (row.enriched ? enrichSolve : 0)));
    }
    for (int t : breaking) fine.alive[t] = 0;
  }
  const int above = rows.front().above, nearAbove = rows.front().nearAbove;
  std::printf(
      "full solve (StructuralPhase, %d unknowns): %.1f ms median; the truth's tets over "
      "%.1f kPa, summed over the frames: %d, %d of them within %.0f mm of the tool\n",
      3 * n, median(fullMs), kCriticalStressPa * 1e-3, above, nearAbove, kNearM * 1e3);
  std::printf("%-10s %8s %10s %10s %10s %10s %9s %9s %8s %8s %7s %7s\n", "region", "dofs",
              "build_ms", "solve_ms", "coarse_b", "coarse_s", "near_err", "max_err", "L2_err",
              "E_err", "n_flips", "flips");
  for (const Row& row : rows) {
    std::string name = row.margin < 0    ? "whole"
                       : row.margin == 0 ? "coarse"
                                         : std::to_string(row.margin * 1e3).substr(0, 4) + "mm";
    if (row.enriched) name += "+ref";
    std::printf("%-10s %8.0f %10.2f %10.2f %10.2f %10.2f %9.3f %9.3f %8.4f %8.2e %7d %7d\n",
                name.c_str(), median(row.regionDofs), median(row.regionBuildMs),
                median(row.regionSolveMs), median(row.coarseBuildMs), median(row.coarseSolveMs),
                row.nearMax, row.anyMax, row.l2, row.energy, row.nearFlips, row.flips);
  }
  std::printf("check: the whole-body region against the truth, relative difference %.1e\n",
              worstCheck);
  return worstCheck <= 1e-8 ? 0 : 1;
}
