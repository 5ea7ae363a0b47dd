// structural.cpp - linear thermo-elastic P1 tetrahedra (see structural.h).
#include "sim/structural.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <functional>
#include <limits>
#include <string>
#include <thread>

#include "sim/cholmod_view.h"
#include "sim/core_error.h"
#include "sim/fem_p1.h"
#include "sim/ldl_solve.h"
#include "sim/ldl_updown.h"
#include "sim/structural_coarse.h"
#include "sim/two_threads.h"

extern "C" void openblas_set_num_threads(int num_threads);

namespace esim {
namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat6x12 = Eigen::Matrix<double, 6, 12>;

// isotropic elasticity in Voigt order with engineering shear strains
Mat6 elasticity(double e, double nu) {
  const double lambda = e * nu / ((1 + nu) * (1 - 2 * nu));
  const double mu = e / (2 * (1 + nu));
  Mat6 d = Mat6::Zero();
  d.topLeftCorner<3, 3>().setConstant(lambda);
  for (int i = 0; i < 3; ++i) {
    d(i, i) = lambda + 2 * mu;
    d(3 + i, 3 + i) = mu;
  }
  return d;
}

// strain (xx, yy, zz, 2yz, 2xz, 2xy) = B u_e, u_e = (x0, y0, z0, x1, ...)
Mat6x12 strainMatrix(const TetGeometry& g) {
  Mat6x12 b = Mat6x12::Zero();
  for (int i = 0; i < 4; ++i) {
    const double gx = g.grad(i, 0), gy = g.grad(i, 1), gz = g.grad(i, 2);
    const int c = 3 * i;
    b(0, c) = gx;
    b(1, c + 1) = gy;
    b(2, c + 2) = gz;
    b(3, c + 1) = gz;
    b(3, c + 2) = gy;
    b(4, c) = gz;
    b(4, c + 2) = gx;
    b(5, c) = gy;
    b(5, c + 1) = gx;
  }
  return b;
}

// do the held components remove all six rigid motions? (rank of the rigid motions'
// values at the supports, positions taken about the supports' centroid and scaled)
bool supportsFixRigidMotions(const std::vector<Vec3>& nodes, const std::vector<Support>& supports) {
  if (supports.empty()) return false;
  Vec3 centre = Vec3::Zero();
  for (const Support& s : supports) centre += nodes[s.node];
  centre /= static_cast<double>(supports.size());
  double scale = 0;
  for (const Support& s : supports) scale = std::max(scale, (nodes[s.node] - centre).norm());
  if (scale == 0) scale = 1;
  Mat6 gram = Mat6::Zero();
  for (const Support& s : supports) {
    const Vec3 p = (nodes[s.node] - centre) / scale;
    // component `axis` of the translations e_x, e_y, e_z and the rotations e_k x p
    Eigen::Matrix<double, 6, 1> row = Eigen::Matrix<double, 6, 1>::Zero();
    row(s.axis) = 1;
    for (int k = 0; k < 3; ++k) row(3 + k) = Vec3::Unit(k).cross(p)(s.axis);
    gram += row * row.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(gram, Eigen::EigenvaluesOnly);
  return eig.eigenvalues()(0) > 1e-10 * eig.eigenvalues()(5);
}

// steam tables: liquid water density at 20, 40, 60, 80, 100 C [kg/m^3]
constexpr double kWaterTableC[] = {20, 40, 60, 80, 100};
constexpr double kWaterDensity[] = {998.2, 992.2, 983.2, 971.8, 958.4};

}  // namespace

double waterDensityKg_m3(double temperatureC) {
  if (!(temperatureC > kWaterTableC[0])) return kWaterDensity[0];
  for (int i = 1; i < 5; ++i)
    if (temperatureC <= kWaterTableC[i]) {
      const double f =
          (temperatureC - kWaterTableC[i - 1]) / (kWaterTableC[i] - kWaterTableC[i - 1]);
      return kWaterDensity[i - 1] + f * (kWaterDensity[i] - kWaterDensity[i - 1]);
    }
  return kWaterDensity[4];
}

double volumetricExpansion(const ExpansionParams& p, double temperatureC, double vaporFraction) {
  const double rho0 = waterDensityKg_m3(p.initialTemperatureC);
  const double phi = p.waterFraction * p.densityKg_m3 / rho0;
  const double liquid = rho0 / waterDensityKg_m3(std::min(temperatureC, p.boilingTemperatureC)) - 1;
  const double x = std::clamp(vaporFraction, 0.0, 1.0);
  return std::min(phi * (liquid + x * (p.vaporLiquidVolumeRatio - 1)), p.maxExpansion);
}

double vonMises(const VoigtStress& s) {
  const double a = s[0] - s[1], b = s[1] - s[2], c = s[2] - s[0];
  return std::sqrt(0.5 * (a * a + b * b + c * c) + 3 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]));
}

Eigen::Matrix3Xd rigidFollowDisplacement(const Eigen::Matrix3Xd& anchorRestM,
                                         const Eigen::Matrix3Xd& anchorDispM,
                                         const Eigen::Matrix3Xd& restM) {
  ESIM_CHECK(anchorRestM.cols() == anchorDispM.cols());
  const Eigen::Index a = anchorRestM.cols();
  if (a == 0) return Eigen::Matrix3Xd::Zero(3, restM.cols());
  const Eigen::Vector3d centroid = anchorRestM.rowwise().mean();
  const Eigen::Vector3d meanDisp = anchorDispM.rowwise().mean();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  if (a >= 2) {
    const Eigen::Matrix3Xd centred = anchorRestM.colwise() - centroid;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> spread(centred * centred.transpose());
    const Eigen::Vector3d extent = spread.eigenvalues().cwiseMax(0).cwiseSqrt();  // ascending
    if (a >= 3 && extent(1) > kRigidFollowLineRatio * extent(2)) {
      const Eigen::Matrix3Xd moved = anchorRestM + anchorDispM;
      rotation = Eigen::umeyama(anchorRestM, moved, false).topLeftCorner<3, 3>();
    } else if (extent(2) > 0) {
      // the line: the outermost anchors along its direction
      const Eigen::VectorXd along = spread.eigenvectors().col(2).transpose() * centred;
      Eigen::Index lo = 0, hi = 0;
      along.minCoeff(&lo);
      along.maxCoeff(&hi);
      const Eigen::Vector3d from = anchorRestM.col(hi) - anchorRestM.col(lo);
      const Eigen::Vector3d to = from + anchorDispM.col(hi) - anchorDispM.col(lo);
      if (to.squaredNorm() > 0)
        rotation = Eigen::Quaterniond::FromTwoVectors(from, to).toRotationMatrix();
    }
  }
  rotation -= Eigen::Matrix3d::Identity();
  return (rotation * (restM.colwise() - centroid)).colwise() + meanDisp;
}

Eigen::Matrix<double, 12, 12> elasticTetStiffness(const TetGeometry& g, double youngsModulusPa,
                                                  double poissonRatio) {
  const Mat6x12 b = strainMatrix(g);
  return g.volume * b.transpose() * (elasticity(youngsModulusPa, poissonRatio) * b);
}

SparseMatrix assembleElasticLower(
    int numNodes, const std::vector<Tet>& tets, const std::uint8_t* alive, const std::uint8_t* held,
    const std::function<Eigen::Matrix<double, 12, 12>(int)>& elementStiffness, const int* rowOfDof,
    int numRows) {
  const int nt = static_cast<int>(tets.size());
  const int nd = 3 * numNodes;
  const int m = rowOfDof ? numRows : nd;
  // the result's row (and column) of a dof: -1 for a dof left out or held (a held dof keeps
  // its diagonal only when every dof is kept)
  const auto rowOf = [&](int dof) { return rowOfDof ? rowOfDof[dof] : dof; };
  const Adjacency tetsAt = aliveTetsAtNodes(numNodes, tets, alive);
  // the pattern, column by column: column dof 3 v + b holds the free dofs >= it of the nodes
  // sharing an alive tet with v (ascending), or only its diagonal when held
  std::vector<int> outer(static_cast<size_t>(m) + 1, 0), inner, seen(numNodes, -1), near;
  inner.reserve(tetsAt.ids.size() * 6);
  for (int v = 0; v < numNodes; ++v) {
    near.clear();
    for (const int* t = tetsAt.begin(v); t != tetsAt.end(v); ++t)
      for (int u : tets[*t])
        if (seen[u] != v) {
          seen[u] = v;
          near.push_back(u);
        }
    std::sort(near.begin(), near.end());
    for (int b = 0; b < 3; ++b) {
      const int col = rowOf(3 * v + b);
      if (col < 0) continue;
      if (held[3 * v + b]) {
        inner.push_back(col);
      } else {
        for (int u : near)
          for (int a = 0; a < 3; ++a) {
            const int row = rowOf(3 * u + a);
            if (row >= col && !held[3 * u + a]) inner.push_back(row);
          }
      }
      outer[col + 1] = static_cast<int>(inner.size());
    }
  }
  SparseMatrix k = patternOfZeros(m, outer, inner);
  double* value = k.valuePtr();
  for (int dof = 0; dof < nd; ++dof)
    if (held[dof] && rowOf(dof) >= 0) value[outer[rowOf(dof)]] = 1.0;
  for (int t = 0; t < nt; ++t) {
    if (!alive[t]) continue;
    const Eigen::Matrix<double, 12, 12> ke = elementStiffness(t);
    for (int j = 0; j < 12; ++j) {
      const int dj = 3 * tets[t][j / 3] + j % 3, cj = rowOf(dj);
      if (cj < 0 || held[dj]) continue;
      const int* lo = inner.data() + outer[cj];
      const int* hi = inner.data() + outer[cj + 1];
      for (int i = 0; i < 12; ++i) {
        const int di = 3 * tets[t][i / 3] + i % 3, ri = rowOf(di);
        if (ri >= cj && !held[di]) value[std::lower_bound(lo, hi, ri) - inner.data()] += ke(i, j);
      }
    }
  }
  return k;
}

namespace {

// tetStrain's body, inlined into the phase's per-tet stresses (a call a tet otherwise)
inline std::array<double, 6> strainOf(const TetGeometry& g, const std::array<const double*, 4>& u) {
  std::array<double, 6> strain{};
  for (int i = 0; i < 4; ++i) {
    const double gx = g.grad(i, 0), gy = g.grad(i, 1), gz = g.grad(i, 2);
    const double* ui = u[i];
    strain[0] += gx * ui[0];
    strain[1] += gy * ui[1];
    strain[2] += gz * ui[2];
    strain[3] += gz * ui[1] + gy * ui[2];
    strain[4] += gz * ui[0] + gx * ui[2];
    strain[5] += gy * ui[0] + gx * ui[1];
  }
  return strain;
}

}  // namespace

std::array<double, 6> tetStrain(const TetGeometry& g, const std::array<const double*, 4>& u) {
  return strainOf(g, u);
}

// ---- the phase's state ----

namespace {

using Mat12 = Eigen::Matrix<double, 12, 12>;
using Voigt = Eigen::Matrix<double, 6, 1>;

// a rigid piece: alive tets connected through shared faces
struct Piece {
  int tets = 0;               // alive tets in it (0: gone)
  bool island = false;        // out of K: its own supports leave a rigid motion free
  std::vector<int> supports;  // ascending indices of the supports on its nodes (not islands)
};

// a phase's per-tet stresses on two threads from this many tets (~0.1 us a tet; a thread's
// start, 50-100 us here, made the 1026-node slab's solve 0.1 ms slower with 2000: esim bench
// structural)
constexpr int kMinTetsForTwoShares = 20000;

// an error about the supports, with StructuralOptions::supportsNote
std::string supportsMessage(const std::string& what, const std::string& note) {
  return "structural: " + what + (note.empty() ? "" : " (" + note + ")");
}

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void verifySolveThreads(int threads) {
  ESIM_VERIFY(threads >= 0 && threads <= 2,
              "structural: solveThreads must be 0 (CHOLMOD's solve), 1 or 2, got " +
                  std::to_string(threads));
}

// the volumetric strain at the nodes works with the full solve method only (structural.h)
void verifyVolumetricMethod(bool nodal, StructuralSolveMethod method) {
  ESIM_VERIFY(!nodal || method == StructuralSolveMethod::full,
              "structural: the volumetric strain at the nodes works with the full solve "
              "method only (not local or coarse)");
}

void verifyLocalOptions(const LocalSolveOptions& o) {
  ESIM_VERIFY(std::isfinite(o.marginM) && o.marginM >= 0,
              "structural: local.marginM must be >= 0, got " + messageNumber(o.marginM));
  ESIM_VERIFY(std::isfinite(o.slackM) && o.slackM >= 0,
              "structural: local.slackM must be >= 0, got " + messageNumber(o.slackM));
  ESIM_VERIFY(
      o.loadTolerance >= 0 && o.loadTolerance < 1,
      "structural: local.loadTolerance must be in [0, 1), got " + messageNumber(o.loadTolerance));
  ESIM_VERIFY(o.refreshEvery >= 0,
              "structural: local.refreshEvery must be >= 0, got " + std::to_string(o.refreshEvery));
  ESIM_VERIFY(o.maxRegionFraction > 0 && o.maxRegionFraction <= 1,
              "structural: local.maxRegionFraction must be in (0, 1], got " +
                  messageNumber(o.maxRegionFraction));
  ESIM_VERIFY(o.coarseLoadTolerance >= 0 && o.coarseLoadTolerance < 1,
              "structural: local.coarseLoadTolerance must be in [0, 1), got " +
                  messageNumber(o.coarseLoadTolerance));
  ESIM_VERIFY(std::isfinite(o.coarseSpacingM) && o.coarseSpacingM >= 0,
              "structural: local.coarseSpacingM must be >= 0 (0: automatic), got " +
                  messageNumber(o.coarseSpacingM));
}

}  // namespace

struct StructuralPhase::Impl {
  // ---- model: fixed at construction ----
  std::vector<Vec3> nodes;  // positions [m] (the supports' rigid-motion test)
  std::vector<Tet> tets;    // copied from the mesh: the phase outlives no mesh
  std::vector<TetGeometry> geo;
  Mat6 d;                        // elasticity (Voigt); stress = D (B_e u_e - eps*); with the
                                 // volumetric strain at the nodes its deviatoric part D_dev
  double bulkModulusPa = 0;      // lambda + 2 mu / 3: D eps* = K_b e_v (1, 1, 1, 0, 0, 0)
  bool nodalVolumetric = false;  // StructuralOptions::volumetric == nodal (structural.h)
  std::vector<Support> supports;
  Adjacency tetsOfNode;      // every tet, removed or not
  Adjacency supportsOfNode;  // ascending support indices per node
  Adjacency faceNeighbours;  // tets sharing a face, removed or not
  // ---- state: changed by removeTets ----
  std::vector<std::uint8_t> alive;   // per tet, 1 when it is in K: alive in the mesh and in a
                                     // piece the supports hold (an island's tets are not)
  std::vector<int> aliveTetsOfNode;  // per node, its tets in K (none: the node is held)
  std::vector<std::uint8_t> held;    // per dof: 1 held at 0 (identity row of A)
  int numFree = 0;
  std::vector<int> pieceOf;   // per tet, -1 when removed from the mesh (islands' tets too)
  std::vector<Piece> pieces;  // by id; ids are never reused
  int livePieces = 0, islands = 0;
  // per island: its nodes held only for it (placed), and its nodes in K or on a support
  // (anchors); rebuilt at the next placeIslands after the islands changed
  std::vector<std::vector<int>> islandOwn, islandAnchors;
  bool islandsChanged = true;
  std::string failure;      // set when a removal left no piece held
  std::string noPieceHeld;  // its message (StructuralOptions::supportsNote in it)
  std::string notPositive;  // a factorization's, "not positive definite" (the same)
  // ---- the factor of A = K on the free dofs, identity on the held ones (3n x 3n) ----
  cholmod_common common;
  cholmod_factor* symbolic = nullptr;  // analysis of the first A: every later A fits in it
  cholmod_factor* factor = nullptr;    // supernodal LL' after a factorization, LDL' once updated
  std::vector<int> rowOfDof;           // dof -> row of L (inverse of L->Perm)
  double refactorFlops = 0;            // CHOLMOD's flop count of one factorization
  double updateCostLimit = 1;          // StructuralOptions::updateCostLimit
  bool vectorizedUpdate = true;        // StructuralOptions::vectorizedUpdate
  bool prepareForUpdates = false;      // StructuralOptions::prepareForUpdates
  cholmod_dense *x = nullptr, *y = nullptr, *e = nullptr;  // solve workspaces
  LdlSolveWork wholeSolve, regionSolve;  // ldl_solve.h's, of the whole factor and the region's
  Eigen::VectorXd regionCorrection;      // d_U of a local solve by ldl_solve.h
  int solveThreads = 2;                  // StructuralOptions::solveThreads
  Eigen::VectorXd rhs, u;
  struct RowMarks {  // per row of L: etree walks of an update
    std::vector<int> mark;
    int stamp = 0;
    LdlUpdownWork updown;     // the vectorized update's workspace for this factor
  } wholeMarks, regionMarks;  // the whole factor's (maybe on the refresh thread), the region's
  std::vector<int> tetMark;   // per tet: piece searches (in the frame, stamp)
  int stamp = 0;
  // what a factor operation reads of the state: the phase's own, or the copy a refresh took
  struct StateView {
    const std::uint8_t* alive;
    const std::uint8_t* held;
    int numFree;
  };
  StateView current() const { return {alive.data(), held.data(), numFree}; }
  // removals not yet applied to the factor (local method with its refresh on a thread: the
  // next refresh, or the next full solve, applies them in one update; see LocalSolveOptions)
  struct Pending {
    std::vector<int> removed, held;  // tets out of K, and dofs held since the factor's A
  } pending;
  // the factor an update changes: the whole one (every dof a row), or the local solve's
  // region's (the dofs of U, in its own order; the others are not unknowns of it)
  struct Target {
    cholmod_factor** factor;
    const std::vector<int>* rowOf;  // per dof: its row of L, -1 when not an unknown
    double refactorFlops;           // CHOLMOD's flop count of its factorization
    bool whole;                     // else the region (whose caller rebuilds it on a fallback)
    RowMarks* marks;
  };
  Target wholeTarget() { return {&factor, &rowOfDof, refactorFlops, true, &wholeMarks}; }
  // ---- the local solve (see LocalSolveOptions) ----
  StructuralSolveMethod method = StructuralSolveMethod::full;
  LocalSolveOptions local;
  bool hasReference = false;               // a full solve since local solves were chosen
  std::vector<double> refEv;               // per tet: e_ref, the load of the last full solve
  Eigen::VectorXd refU;                    // u_ref [m]
  std::vector<Voigt> refElastic;           // per tet: D B_e u_ref [Pa]
  std::vector<int> changedNodes;           // of removed tets, or held since the reference
  int localSinceFull = 0;                  // local solves since the last full one
  bool regionValid = false;                // the region below fits the current A
  Eigen::AlignedBox3d regionBox;           // the box grown by slackM it was built around
  std::vector<int> regionDofs;             // U: its free dofs, ascending
  std::vector<int> localOfDof;             // per dof: index in regionDofs, -1 outside
  std::vector<int> regionTets;             // alive tets with a node in U
  std::vector<std::uint8_t> inRegion;      // per tet: in regionTets
  cholmod_factor* regionFactor = nullptr;  // K_UU
  cholmod_dense *rx = nullptr, *ry = nullptr, *re = nullptr;  // its solve workspaces
  std::vector<int> appliedDofs;                               // dofs where u holds u_ref + d
  std::vector<int> regionRowOf;  // per dof: its row of the region's L (-1 outside U)
  double regionFlops = 0;        // CHOLMOD's flop count of the region's factorization
  Pending regionPending;         // removals in the region its factor has not seen
  // the coarse method (see LocalSolveOptions::coarseSpacingM)
  std::unique_ptr<CoarseSpace> coarse;  // made at set-up or setSolveMethod
  bool coarseStale = true;              // K_c to be built (at first, and after some removals)
  std::vector<double> prevEv;           // the load of the last coarse solve (empty: none)
  struct Refresh {                      // LocalSolveOptions::refreshOnThread
    std::thread worker;
    bool running = false;
    int solvesSinceStart = 0;
    std::vector<double> ev;                 // the load it solves
    std::vector<std::uint8_t> alive, held;  // the state it solves on (copied at its start)
    int numFree = 0;
    Pending job;                    // the removals it applies to the factor first
    std::vector<int> heldSince;     // dofs held since its start ...
    std::vector<int> changedSince;  // ... and the nodes removals changed since
    StateView view() const { return {alive.data(), held.data(), numFree}; }
    Eigen::VectorXd rhs, u;
    std::vector<Voigt> elastic;
    std::exception_ptr error;
    cholmod_common common;
    cholmod_dense *x = nullptr, *y = nullptr, *e = nullptr;
    LdlSolveWork solve;
  } refresh;
  StructuralSolveStats lastSolve;
  // ---- outputs ----
  std::vector<VoigtStress> stress;
  std::vector<double> vonMisesPa;
  double factorSeconds = 0;

  Impl() {
    cholmod_start(&common);
    common.print = 0;
    common.error_handler = nullptr;
    common.supernodal = CHOLMOD_SUPERNODAL;  // the fast first factorization (BLAS 3)
    common.grow2 = 0;                        // downdates never grow a column of L: pack it
    cholmod_start(&refresh.common);
    refresh.common.print = 0;
    refresh.common.error_handler = nullptr;
  }
  ~Impl() {
    if (refresh.worker.joinable()) refresh.worker.join();
    if (refresh.x) cholmod_free_dense(&refresh.x, &refresh.common);
    if (refresh.y) cholmod_free_dense(&refresh.y, &refresh.common);
    if (refresh.e) cholmod_free_dense(&refresh.e, &refresh.common);
    cholmod_finish(&refresh.common);
    if (factor) cholmod_free_factor(&factor, &common);
    if (symbolic) cholmod_free_factor(&symbolic, &common);
    if (x) cholmod_free_dense(&x, &common);
    if (y) cholmod_free_dense(&y, &common);
    if (e) cholmod_free_dense(&e, &common);
    if (regionFactor) cholmod_free_factor(&regionFactor, &common);
    if (rx) cholmod_free_dense(&rx, &common);
    if (ry) cholmod_free_dense(&ry, &common);
    if (re) cholmod_free_dense(&re, &common);
    cholmod_finish(&common);
  }

  int numDofs() const { return static_cast<int>(held.size()); }

  // StructuralOptions::solveThreads: the solves', the stresses' and the update kernel's
  void setThreads(int threads) {
    solveThreads = threads;
    wholeMarks.updown.threads = regionMarks.updown.threads = threads >= 2 ? 2 : 1;
  }

  Mat12 elementStiffness(int t) const {
    const Mat6x12 b = strainMatrix(geo[t]);
    return geo[t].volume * b.transpose() * (d * b);
  }

  // holds the 3 components of a node; returns how many were free
  int holdNode(int v, std::vector<int>& newlyHeld) {
    int count = 0;
    for (int a = 0; a < 3; ++a)
      if (!held[3 * v + a]) {
        held[3 * v + a] = 1;
        newlyHeld.push_back(3 * v + a);
        --numFree;
        ++count;
      }
    return count;
  }

  // sorted unique nodes of a list of tets
  std::vector<int> nodesOf(const std::vector<int>& tetList) const {
    std::vector<int> out;
    out.reserve(4 * tetList.size());
    for (int t : tetList)
      for (int v : tets[t]) out.push_back(v);
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
  }

  // do the supports listed (ascending indices) fix the rigid motions of their piece?
  bool fixes(const std::vector<int>& supportIds) const {
    std::vector<Support> own;
    own.reserve(supportIds.size());
    for (int s : supportIds) own.push_back(supports[s]);
    return supportsFixRigidMotions(nodes, own);
  }

  // ascending indices of the supports on the given nodes
  std::vector<int> supportsOn(const std::vector<int>& nodeList) const {
    std::vector<int> out;
    for (int v : nodeList) out.insert(out.end(), supportsOfNode.begin(v), supportsOfNode.end(v));
    std::sort(out.begin(), out.end());
    return out;
  }

  // does node v still have an alive tet in piece p?
  bool nodeInPiece(int v, int p) const {
    for (const int* t = tetsOfNode.begin(v); t != tetsOfNode.end(v); ++t)
      if (pieceOf[*t] == p) return true;
    return false;
  }

  // every tet of piece p, by a flood fill from one of them
  std::vector<int> tetsOfPiece(int p, int start) {
    std::vector<int> out{start};
    ++stamp;
    tetMark[start] = stamp;
    for (size_t k = 0; k < out.size(); ++k)
      for (const int* nb = faceNeighbours.begin(out[k]); nb != faceNeighbours.end(out[k]); ++nb)
        if (pieceOf[*nb] == p && tetMark[*nb] != stamp) {
          tetMark[*nb] = stamp;
          out.push_back(*nb);
        }
    return out;
  }

  void classifyPieces();
  std::vector<std::vector<int>> splitPiece(const std::vector<int>& seeds);
  SparseMatrix assemble(const StateView& s) const;
  SparseMatrix assembleNodal(const StateView& s) const;
  // volumetric strain at the nodes: V_n over the alive tets, and sum_{e at n} (V_e / 4) x_e
  // for a per-tet x (into out, one per node)
  void nodeVolumes(const StateView& s, std::vector<double>& out) const;
  void nodeSums(const StateView& s, const std::function<double(int)>& x,
                std::vector<double>& out) const;
  void factorize(cholmod_common& c, const StateView& s);
  void toSimplicial(cholmod_common& c, cholmod_factor* f);
  Voigt elasticStress(int t, const Eigen::VectorXd& disp) const;
  void fullSolve(const std::vector<double>& ev);
  void fullDisplacement(const std::vector<double>& ev, const StateView& s, Eigen::VectorXd& f,
                        Eigen::VectorXd& out, cholmod_common& c, cholmod_dense*& wx,
                        cholmod_dense*& wy, cholmod_dense*& we, LdlSolveWork& lw,
                        int threads) const;
  StructuralUpdateStats applyPending(Pending job, const StateView& s, cholmod_common& c);
  void bringFactorUpToDate();
  void startRefresh(const std::vector<double>& ev);
  void finishRefresh(bool adopt);
  std::vector<int> holdInReference(const std::vector<int>& dofs);
  bool localSolve(const std::vector<double>& ev);
  bool coarseSolve(const std::vector<double>& ev);
  Eigen::AlignedBox3d changedBox(const std::vector<double>& ev, const std::vector<double>& before,
                                 double tolerance) const;
  double readyCoarse();
  void loadVector(const std::vector<double>& ev, const StateView& s, Eigen::VectorXd& f) const;
  bool readyRegion(const Eigen::AlignedBox3d& box);
  template <class Elastic>
  Eigen::VectorXd regionResidual(const std::vector<double>& ev, const Elastic& elastic) const;
  const double* regionCorrect(const Eigen::VectorXd& r);
  // the coarse method's K_c += sign P_e' K_e P_e for tet t, dof held when heldAt(dof)
  template <class Held>
  void addToCoarse(int t, double sign, const Held& heldAt) {
    coarse->addTet(tets[t], elementStiffness(t), sign, heldAt);
  }
  bool buildRegion(const Eigen::AlignedBox3d& box);
  void dropRegion();
  enum class From { solution, region, reference };  // where outputs() takes D B u from
  void outputs(const std::vector<double>& ev, From from);
  void placeIslands();
  std::vector<int> rowPattern(int dof, const Target& target);
  bool deleteRows(const std::vector<int>& dofs, const Target& target, cholmod_common& cm);
  // L D L' +- C C' on the target's factor: the vectorized kernel (ldl_updown.h) or, without
  // vectorizedUpdate, cholmod_updown; the columns counted in the target's work either way
  bool updown(bool update, cholmod_sparse& c, const Target& target, cholmod_common& cm) {
    if (vectorizedUpdate) return ldlUpdown(update, c, **target.factor, target.marks->updown, cm);
    target.marks->updown.choleskyColumns += static_cast<long>(c.ncol);
    return cholmod_updown(update, &c, *target.factor, &cm);
  }
  bool kernelUpdates() const { return vectorizedUpdate && ldlUpdownAvailable(); }
  StructuralUpdateStats removeTets(const std::vector<int>& ids);
  std::function<StructuralUpdateStats()> beginRemoval(const std::vector<int>& ids);
  StructuralUpdateStats updateFactor(std::chrono::steady_clock::time_point t0,
                                     StructuralUpdateStats stats, const std::vector<int>& removed,
                                     const std::vector<int>& newlyHeld, const StateView& s,
                                     cholmod_common& c, const Target& target);
};

// rigid pieces of the alive tets (union-find over the face neighbours, one pass over the
// tets): tets connected through shared faces, as a piece joined to another by an edge or a
// node only can still turn about it. Pieces whose own supports leave a rigid motion free
// (cut loose, or hanging by an edge or a node) are islands: their tets leave K (alive 0).
void StructuralPhase::Impl::classifyPieces() {
  const int nt = static_cast<int>(tets.size());
  std::vector<int> parent(nt);
  for (int t = 0; t < nt; ++t) parent[t] = t;
  auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (int t = 0; t < nt; ++t) {
    if (!alive[t]) continue;
    for (const int* nb = faceNeighbours.begin(t); nb != faceNeighbours.end(t); ++nb)
      if (alive[*nb]) {
        const int a = find(t), b = find(*nb);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
      }
  }
  pieceOf.assign(nt, -1);
  std::vector<int> idOfRoot(nt, -1);
  std::vector<std::vector<int>> members;
  for (int t = 0; t < nt; ++t) {
    if (!alive[t]) continue;
    const int r = find(t);
    if (idOfRoot[r] < 0) {
      idOfRoot[r] = static_cast<int>(members.size());
      members.emplace_back();
    }
    pieceOf[t] = idOfRoot[r];
    members[idOfRoot[r]].push_back(t);
  }
  pieces.assign(members.size(), Piece{});
  livePieces = static_cast<int>(members.size());
  islands = 0;
  for (size_t p = 0; p < members.size(); ++p) {
    const std::vector<int> pieceNodes = nodesOf(members[p]);
    pieces[p].tets = static_cast<int>(members[p].size());
    pieces[p].supports = supportsOn(pieceNodes);
    if (fixes(pieces[p].supports)) continue;
    pieces[p].island = true;
    pieces[p].supports.clear();
    ++islands;
    for (int t : members[p]) alive[t] = 0;
  }
}

// The components of a piece after some of its tets were removed. Every component holds one
// of the seeds (the alive face neighbours of the removed tets), so one search starts from
// each seed; the searches advance one tet each in turn, merge when they meet, and stop once
// at most one is still going: the finished ones are the pieces split off (small ones finish
// early), the one still going is the rest, never walked in full. Returns the tets of the
// pieces split off; none when the piece held together.
std::vector<std::vector<int>> StructuralPhase::Impl::splitPiece(const std::vector<int>& seeds) {
  struct Search {
    std::vector<int> tets;      // visited
    std::vector<int> frontier;  // visited, neighbours not yet looked at (a stack)
  };
  std::vector<Search> searches;
  std::vector<int> parent;
  ++stamp;
  const int base = stamp;  // tetMark[t] - base: the search that visited t
  for (int s : seeds) {
    if (tetMark[s] >= base) continue;
    tetMark[s] = base + static_cast<int>(searches.size());
    searches.push_back({{s}, {s}});
    parent.push_back(static_cast<int>(parent.size()));
  }
  stamp = base + static_cast<int>(searches.size());
  if (searches.size() < 2) {
    stamp += 1;
    return {};
  }
  auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  std::vector<int> going(searches.size());
  for (size_t s = 0; s < searches.size(); ++s) going[s] = static_cast<int>(s);
  while (going.size() > 1) {
    std::vector<int> next;
    for (int s : going) {
      if (find(s) != s || searches[s].frontier.empty()) continue;  // merged or finished
      const int t = searches[s].frontier.back();
      searches[s].frontier.pop_back();
      for (const int* nb = faceNeighbours.begin(t); nb != faceNeighbours.end(t); ++nb) {
        if (pieceOf[*nb] < 0) continue;  // removed (the alive ones are the piece's)
        const int me = find(s);
        if (tetMark[*nb] < base) {
          tetMark[*nb] = base + me;
          searches[me].tets.push_back(*nb);
          searches[me].frontier.push_back(*nb);
          continue;
        }
        const int other = find(tetMark[*nb] - base);
        if (other == me) continue;
        // merge the smaller search into the larger one
        int big = me, small = other;
        if (searches[big].tets.size() < searches[small].tets.size()) std::swap(big, small);
        parent[small] = big;
        Search& a = searches[big];
        Search& b = searches[small];
        a.tets.insert(a.tets.end(), b.tets.begin(), b.tets.end());
        a.frontier.insert(a.frontier.end(), b.frontier.begin(), b.frontier.end());
        b = Search{};
        next.push_back(big);
      }
      if (find(s) == s && !searches[s].frontier.empty()) next.push_back(s);
    }
    // the searches still going (unique roots with a frontier)
    std::vector<int> roots;
    for (int s : next) {
      const int r = find(s);
      if (!searches[r].frontier.empty()) roots.push_back(r);
    }
    std::sort(roots.begin(), roots.end());
    roots.erase(std::unique(roots.begin(), roots.end()), roots.end());
    going.swap(roots);
  }
  // finished searches are whole pieces; the rest (going, or else the largest) keeps the id
  std::vector<int> finished;
  for (size_t s = 0; s < searches.size(); ++s)
    if (find(static_cast<int>(s)) == static_cast<int>(s) && searches[s].frontier.empty())
      finished.push_back(static_cast<int>(s));
  if (going.empty()) {
    auto largest = std::max_element(finished.begin(), finished.end(), [&](int a, int b) {
      return searches[a].tets.size() < searches[b].tets.size();
    });
    finished.erase(largest);
  }
  std::vector<std::vector<int>> out;
  for (int s : finished) {
    std::sort(searches[s].tets.begin(), searches[s].tets.end());
    out.push_back(std::move(searches[s].tets));
  }
  return out;
}

// A over all 3n dofs, lower triangle: K from the alive tets on the free dofs, 1 on the
// diagonal of the held ones
SparseMatrix StructuralPhase::Impl::assemble(const StateView& s) const {
  if (nodalVolumetric) return assembleNodal(s);
  return assembleElasticLower(static_cast<int>(nodes.size()), tets, s.alive, s.held,
                              [this](int t) { return elementStiffness(t); });
}

void StructuralPhase::Impl::nodeVolumes(const StateView& s, std::vector<double>& out) const {
  nodeSums(
      s, [](int) { return 1.0; }, out);
}

void StructuralPhase::Impl::nodeSums(const StateView& s, const std::function<double(int)>& x,
                                     std::vector<double>& out) const {
  out.assign(nodes.size(), 0.0);
  for (size_t t = 0; t < tets.size(); ++t) {
    if (!s.alive[t]) continue;
    const double share = geo[t].volume / 4 * x(static_cast<int>(t));
    for (int v : tets[t]) out[v] += share;
  }
}

// A over all 3n dofs, lower triangle, with the volumetric strain at the nodes (structural.h,
// VolumetricStrain): sum_e V_e B_e' D_dev B_e + sum_n K_b V_n g_n g_n', g_n = grad theta_n =
// sum_{e at n} (V_e / 4) b_e / V_n over the alive tets (b_e: grad N_i per component). Column
// 3 v + b holds the free dofs >= it of the nodes two rings from v (through alive tets).
SparseMatrix StructuralPhase::Impl::assembleNodal(const StateView& s) const {
  const int n = static_cast<int>(nodes.size()), nd = 3 * n;
  // nodes sharing an alive tet with v (v included), ascending
  std::vector<int> ringStart(n + 1, 0), ring;
  {
    std::vector<int> seen(n, -1), near;
    for (int v = 0; v < n; ++v) {
      near.clear();
      for (const int* t = tetsOfNode.begin(v); t != tetsOfNode.end(v); ++t) {
        if (!s.alive[*t]) continue;
        for (int u : tets[*t])
          if (seen[u] != v) {
            seen[u] = v;
            near.push_back(u);
          }
      }
      std::sort(near.begin(), near.end());
      ring.insert(ring.end(), near.begin(), near.end());
      ringStart[v + 1] = static_cast<int>(ring.size());
    }
  }
  // the pattern: two rings
  std::vector<int> outer(static_cast<size_t>(nd) + 1, 0), inner, seen(n, -1), near;
  for (int v = 0; v < n; ++v) {
    near.clear();
    for (int i = ringStart[v]; i < ringStart[v + 1]; ++i)
      for (int j = ringStart[ring[i]]; j < ringStart[ring[i] + 1]; ++j)
        if (seen[ring[j]] != v) {
          seen[ring[j]] = v;
          near.push_back(ring[j]);
        }
    std::sort(near.begin(), near.end());
    for (int b = 0; b < 3; ++b) {
      const int col = 3 * v + b;
      if (s.held[col]) {
        inner.push_back(col);
      } else {
        for (int u : near)
          for (int a = 0; a < 3; ++a)
            if (3 * u + a >= col && !s.held[3 * u + a]) inner.push_back(3 * u + a);
      }
      outer[col + 1] = static_cast<int>(inner.size());
    }
  }
  SparseMatrix k = patternOfZeros(nd, outer, inner);
  double* value = k.valuePtr();
  const auto add = [&](int row, int col, double x) {
    if (row < col || s.held[row] || s.held[col]) return;
    const int* lo = inner.data() + outer[col];
    const int* hi = inner.data() + outer[col + 1];
    value[std::lower_bound(lo, hi, row) - inner.data()] += x;
  };
  for (int dof = 0; dof < nd; ++dof)
    if (s.held[dof]) value[outer[dof]] = 1.0;
  // the deviatoric part, tet by tet
  for (size_t t = 0; t < tets.size(); ++t) {
    if (!s.alive[t]) continue;
    const Mat12 ke = elementStiffness(static_cast<int>(t));
    for (int j = 0; j < 12; ++j)
      for (int i = 0; i < 12; ++i)
        add(3 * tets[t][i / 3] + i % 3, 3 * tets[t][j / 3] + j % 3, ke(i, j));
  }
  // the volumetric part, node by node: g_n over the dofs of its ring
  std::vector<double> volume;
  nodeVolumes(s, volume);
  std::vector<int> local(n, -1);
  std::vector<double> g;
  for (int v = 0; v < n; ++v) {
    if (volume[v] <= 0) continue;
    const int count = ringStart[v + 1] - ringStart[v];
    for (int i = 0; i < count; ++i) local[ring[ringStart[v] + i]] = i;
    g.assign(3 * static_cast<size_t>(count), 0.0);
    for (const int* t = tetsOfNode.begin(v); t != tetsOfNode.end(v); ++t) {
      if (!s.alive[*t]) continue;
      const double share = geo[*t].volume / 4 / volume[v];
      for (int i = 0; i < 4; ++i)
        for (int a = 0; a < 3; ++a) g[3 * local[tets[*t][i]] + a] += share * geo[*t].grad(i, a);
    }
    const double scale = bulkModulusPa * volume[v];
    for (int j = 0; j < 3 * count; ++j) {
      if (g[j] == 0) continue;
      const int col = 3 * ring[ringStart[v] + j / 3] + j % 3;
      for (int i = 0; i < 3 * count; ++i)
        if (g[i] != 0) add(3 * ring[ringStart[v] + i / 3] + i % 3, col, scale * g[i] * g[j]);
    }
  }
  return k;
}

// a fresh supernodal factorization of A within the first analysis (A only loses entries)
void StructuralPhase::Impl::factorize(cholmod_common& c, const StateView& s) {
  const SparseMatrix a = assemble(s);
  cholmod_sparse view = cholmodViewLower(a);
  if (!symbolic) {
    // a factor to be updated: METIS's nested dissection. CHOLMOD's default takes AMD alone
    // below fl/lnz 500 (the 1k-node slabs), whose deeper elimination tree makes each
    // update's paths longer; measured (esim bench cut --sizes 1013 --strategy update
    // --stages, three alternating runs): the first removal's estimate no longer exceeds
    // a refactorization, the slowest frame 8-16 ms against 25-34 ms, update median about
    // the same; at 8000 nodes the default picks METIS already (lnz 7.4M against AMD's 9.4M)
    const int methods = c.nmethods, ordering = c.method[0].ordering;
    if (prepareForUpdates) {
      c.nmethods = 1;
      c.method[0].ordering = CHOLMOD_METIS;
      symbolic = cholmod_analyze(&view, &c);
      c.nmethods = methods;
      c.method[0].ordering = ordering;
    }
    if (!symbolic) symbolic = cholmod_analyze(&view, &c);  // (or METIS unavailable)
    if (symbolic == nullptr) throwIfOutOfResources(c);
    ESIM_RUN_CHECK(symbolic != nullptr, "structural: CHOLMOD analysis failed");
    refactorFlops = c.fl;
    const int* perm = static_cast<const int*>(symbolic->Perm);
    rowOfDof.assign(numDofs(), 0);
    for (int k = 0; k < numDofs(); ++k) rowOfDof[perm[k]] = k;
  }
  if (factor) cholmod_free_factor(&factor, &c);
  factor = cholmod_copy_factor(symbolic, &c);
  if (factor == nullptr) throw std::bad_alloc();  // (copying fails only so)
  openblas_set_num_threads(1);                    // see the header: BLAS threads only spin here
  const int ok = cholmod_factorize(&view, factor, &c);
  throwIfOutOfResources(c);
  ESIM_RUN_CHECK(ok && c.status == CHOLMOD_OK && factor->minor == factor->n, notPositive);
  if (prepareForUpdates) toSimplicial(c, factor);
}

// L as simplicial LDL' (what cholmod_updown and rowdel take); O(nnz(L))
void StructuralPhase::Impl::toSimplicial(cholmod_common& c, cholmod_factor* f) {
  if (!f->is_super && !f->is_ll) return;
  const int ok = cholmod_change_factor(CHOLMOD_REAL, false, false, false, false, f, &c);
  if (!ok) throwIfOutOfResources(c);
  ESIM_RUN_CHECK(ok, "structural: CHOLMOD could not convert the factor");
}

// Rows j < k of L's row k = rowOfDof[dof] that may hold a nonzero (what deleting the row
// must clear): the row subtree (ldlRowSubtree), climbed up the elimination tree of L from the
// couplings of the dof in the first A (every tet at its node) until k. Updates and row
// deletions only change values inside L's pattern, so this superset stays valid.
std::vector<int> StructuralPhase::Impl::rowPattern(int dof, const Target& target) {
  const std::vector<int>& rowOf = *target.rowOf;
  const int v = dof / 3;
  // the nodes coupled to v in the first A: those of its tets, and with the volumetric strain at
  // the nodes those two rings out (every tet at a node of v's tets)
  std::vector<int> coupled;
  for (const int* t = tetsOfNode.begin(v); t != tetsOfNode.end(v); ++t)
    for (int w : tets[*t]) {
      if (!nodalVolumetric) {
        coupled.push_back(w);
        continue;
      }
      for (const int* t2 = tetsOfNode.begin(w); t2 != tetsOfNode.end(w); ++t2)
        coupled.insert(coupled.end(), tets[*t2].begin(), tets[*t2].end());
    }
  std::sort(coupled.begin(), coupled.end());
  coupled.erase(std::unique(coupled.begin(), coupled.end()), coupled.end());
  std::vector<int> from, out;
  for (int w : coupled)
    for (int a = 0; a < 3; ++a) from.push_back(rowOf[3 * w + a]);
  ldlRowSubtree(**target.factor, rowOf[dof], from.data(), static_cast<int>(from.size()),
                target.marks->updown, out);
  return out;
}

// Deletes the rows (and columns) of the dofs from the simplicial LDL' factor: they become
// identity rows, as cholmod_rowdel makes them, but in one multiple-rank update by L's own
// columns instead of a rank-1 pass up the elimination tree per row (ldlTakeRows, ldl_updown.h;
// the update by cholmod_updown or the kernel, as updown chooses). Measured
// against one cholmod_rowdel per row (temporary instrumentation, both in one binary, the same
// removals): esim bench cut --sizes 8000 --frames 60 --strategy update, 37 removals holding
// 495 rows, the row deletions 1115 -> 753 ms in all (with the update's bookkeeping before
// them), the downdates 2441 / 2496 ms; liver_incision in update mode, 20 frames, 17 removals
// holding 438 rows: 3745 -> 2371 ms, the whole structural update 13.4 -> 11.6 s. The paths are
// long enough that a pass's flops, not its memory traffic, set its time: 8 columns in a pass
// still cost about 5 of 8 single passes
bool StructuralPhase::Impl::deleteRows(const std::vector<int>& dofs, const Target& target,
                                       cholmod_common& cm) {
  cholmod_factor* f = *target.factor;
  std::vector<std::pair<int, int>> rowDof;  // (row of L, dof), by row
  for (int dof : dofs) rowDof.emplace_back((*target.rowOf)[dof], dof);
  std::sort(rowDof.begin(), rowDof.end());
  std::vector<int> rows;
  for (const auto& rd : rowDof) rows.push_back(rd.first);
  std::vector<int> wp, wi;
  std::vector<double> wx;
  const bool taken = ldlTakeRows(
      rows,
      [&](int k, std::vector<int>& out) {
        const auto at = std::lower_bound(rowDof.begin(), rowDof.end(), std::make_pair(k, -1));
        const std::vector<int> pattern = rowPattern(at->second, target);
        out.insert(out.end(), pattern.begin(), pattern.end());
      },
      *f, wp, wi, wx);
  if (!taken) return false;  // not positive definite: the caller refactorizes
  if (wp.size() == 1) return true;
  cholmod_sparse w = cholmodViewColumns(f->n, wp.size() - 1, wp.data(), wi.data(), wx.data());
  return updown(true, w, target, cm);
}

// ---- solves ----

// D B_e u_e: the elastic part of the tet's stress for the displacement disp [Pa]
Voigt StructuralPhase::Impl::elasticStress(int t, const Eigen::VectorXd& disp) const {
  // the strain B_e u_e straight from the stored gradients (the rows of strainMatrix,
  // without its 72 zeros: the outputs of a solve were a third of its time at 1k nodes,
  // perf); keeping D B_e per tet would cost 576 bytes a tet (92 MB for the liver's 161k)
  const double* u = disp.data();
  const std::array<int, 4>& v = tets[t];
  const std::array<double, 6> strain =
      strainOf(geo[t], {u + 3 * v[0], u + 3 * v[1], u + 3 * v[2], u + 3 * v[3]});
  return d * Eigen::Map<const Voigt>(strain.data());
}

// f = sum_e V_e B_e^T D eps*_e; D eps* = K_b e_v (1,1,1,0,0,0), so node i of the tet gets
// V_e K_b e_v grad N_i; 0 on the held dofs (their rows of A are the identity)
void StructuralPhase::Impl::loadVector(const std::vector<double>& ev, const StateView& s,
                                       Eigen::VectorXd& f) const {
  const int nt = static_cast<int>(tets.size());
  f.setZero(numDofs());
  // with the volumetric strain at the nodes, f = sum_n K_b V_n theta*_n g_n = sum_e V_e K_b
  // (mean of theta* over the tet's nodes) b_e
  std::vector<double> volume, thetaStar;
  if (nodalVolumetric) {
    nodeVolumes(s, volume);
    nodeSums(
        s, [&](int t) { return ev[t]; }, thetaStar);
    for (size_t v = 0; v < volume.size(); ++v)
      if (volume[v] > 0) thetaStar[v] /= volume[v];
  }
  for (int t = 0; t < nt; ++t) {
    if (!s.alive[t]) continue;
    double e = ev[t];
    if (nodalVolumetric) {
      e = 0;
      for (int v : tets[t]) e += thetaStar[v] / 4;
    }
    if (e == 0) continue;
    const double load = geo[t].volume * bulkModulusPa * e;
    for (int i = 0; i < 4; ++i)
      for (int a = 0; a < 3; ++a) {
        const int dof = 3 * tets[t][i] + a;
        if (!s.held[dof]) f(dof) += load * geo[t].grad(i, a);
      }
  }
}

// u solving K u = f(ev) over the whole body, with the given CHOLMOD workspace
void StructuralPhase::Impl::fullDisplacement(const std::vector<double>& ev, const StateView& s,
                                             Eigen::VectorXd& f, Eigen::VectorXd& out,
                                             cholmod_common& c, cholmod_dense*& wx,
                                             cholmod_dense*& wy, cholmod_dense*& we,
                                             LdlSolveWork& lw, int threads) const {
  loadVector(ev, s, f);
  out.setZero(numDofs());
  if (s.numFree == 0) return;
  if (threads > 0 && ldlSolveSupports(*factor)) {  // updated (simplicial LDL'): ldl_solve.h
    ldlSolve(*factor, f.data(), out.data(), threads, lw);
    for (int dof = 0; dof < numDofs(); ++dof)
      if (s.held[dof]) out(dof) = 0;
    return;
  }
  cholmod_dense b = cholmodViewDense(f.data(), numDofs());
  const int ok = cholmod_solve2(CHOLMOD_A, factor, &b, nullptr, &wx, nullptr, &wy, &we, &c);
  if (!ok) throwIfOutOfResources(c);
  ESIM_RUN_CHECK(ok, "structural: CHOLMOD solve failed");
  const double* xs = static_cast<const double*>(wx->x);
  for (int dof = 0; dof < numDofs(); ++dof)
    if (!s.held[dof]) out(dof) = xs[dof];
}

// the pending removals applied to the factor in one update (see Pending), reading the
// state s (the phase's own, or a refresh's copy) with the CHOLMOD workspace c
StructuralUpdateStats StructuralPhase::Impl::applyPending(Pending job, const StateView& s,
                                                          cholmod_common& c) {
  const auto t0 = std::chrono::steady_clock::now();
  StructuralUpdateStats stats;
  std::sort(job.removed.begin(), job.removed.end());
  std::sort(job.held.begin(), job.held.end());
  stats.tetsRemoved = static_cast<int>(job.removed.size());
  stats.dofsHeld = static_cast<int>(job.held.size());
  return updateFactor(t0, stats, job.removed, job.held, s, c, wholeTarget());
}

// a full solve in the frame needs the factor of the current A: joins a refresh (its
// removals applied, its solve dropped) and applies what is pending
void StructuralPhase::Impl::bringFactorUpToDate() {
  finishRefresh(false);
  if (pending.removed.empty()) return;
  applyPending(std::move(pending), current(), common);
  pending = Pending{};
}

// K u = f over the whole body; with the local method, the new reference
void StructuralPhase::Impl::fullSolve(const std::vector<double>& ev) {
  bringFactorUpToDate();  // a refresh running is older than this solve
  openblas_set_num_threads(1);
  fullDisplacement(ev, current(), rhs, u, common, x, y, e, wholeSolve, solveThreads);
  lastSolve.solveThreads =
      solveThreads > 0 && ldlSolveSupports(*factor) ? wholeSolve.threadsUsed : 0;
  appliedDofs.clear();
  if (method == StructuralSolveMethod::local) {
    hasReference = true;
    refEv = ev;
    refU = u;
    refElastic.resize(tets.size());
    changedNodes.clear();
    localSinceFull = 0;
  }
  outputs(ev, From::solution);
}

// a full solve of ev on the thread, with its elastic stresses (the next reference)
void StructuralPhase::Impl::startRefresh(const std::vector<double>& ev) {
  refresh.ev = ev;
  refresh.alive = alive;  // the frame goes on removing tets while the thread runs
  refresh.held = held;
  refresh.numFree = numFree;
  refresh.job = std::move(pending);
  pending = Pending{};
  refresh.heldSince.clear();
  refresh.changedSince.clear();
  refresh.running = true;
  refresh.solvesSinceStart = 0;
  refresh.error = nullptr;
  refresh.worker = std::thread([this] {
    try {
      const StateView s = refresh.view();
      if (!refresh.job.removed.empty()) applyPending(std::move(refresh.job), s, refresh.common);
      // one thread: this one runs beside the frame's (the same bits as two)
      fullDisplacement(refresh.ev, s, refresh.rhs, refresh.u, refresh.common, refresh.x, refresh.y,
                       refresh.e, refresh.solve, 1);
      refresh.elastic.resize(tets.size());
      for (size_t t = 0; t < tets.size(); ++t)
        if (s.alive[t]) refresh.elastic[t] = elasticStress(static_cast<int>(t), refresh.u);
    } catch (...) {
      refresh.error = std::current_exception();
    }
  });
}

// u_ref set to 0 on dofs now held, and the elastic stress of the alive tets at their nodes;
// returns those nodes (of the dofs whose u_ref changed), ascending
std::vector<int> StructuralPhase::Impl::holdInReference(const std::vector<int>& dofs) {
  std::vector<int> heldNodes;
  for (int dof : dofs)
    if (refU(dof) != 0) {
      refU(dof) = 0;
      heldNodes.push_back(dof / 3);
    }
  std::sort(heldNodes.begin(), heldNodes.end());
  heldNodes.erase(std::unique(heldNodes.begin(), heldNodes.end()), heldNodes.end());
  for (int v : heldNodes)
    for (const int* t = tetsOfNode.begin(v); t != tetsOfNode.end(v); ++t)
      if (alive[*t]) refElastic[*t] = elasticStress(*t, refU);
  return heldNodes;
}

// joins the thread's refresh (if any); adopt: it becomes the reference
void StructuralPhase::Impl::finishRefresh(bool adopt) {
  if (!refresh.running) return;
  refresh.worker.join();
  refresh.running = false;
  if (refresh.error) std::rethrow_exception(refresh.error);
  if (!adopt) return;
  refEv.swap(refresh.ev);
  refU.swap(refresh.u);
  refElastic.swap(refresh.elastic);
  // removals since the refresh started: the dofs they held are 0 in the reference, and the
  // tets at those nodes change stress; what they changed is the next region's box
  holdInReference(refresh.heldSince);
  u = refU;  // outside the region too
  appliedDofs.clear();
  changedNodes = refresh.changedSince;
  localSinceFull = 0;
}

// the box of the alive tets whose load changed from `before` by more than tolerance times the
// largest change, and of the nodes removals changed (changedNodes); empty when neither
Eigen::AlignedBox3d StructuralPhase::Impl::changedBox(const std::vector<double>& ev,
                                                      const std::vector<double>& before,
                                                      double tolerance) const {
  const int nt = static_cast<int>(tets.size());
  double largest = 0;
  for (int t = 0; t < nt; ++t)
    if (alive[t]) largest = std::max(largest, std::abs(ev[t] - before[t]));
  Eigen::AlignedBox3d box;  // empty
  if (largest > 0) {
    const double threshold = tolerance * largest;
    for (int t = 0; t < nt; ++t)
      if (alive[t] && std::abs(ev[t] - before[t]) > threshold)
        for (int v : tets[t]) box.extend(nodes[v]);
  }
  for (int v : changedNodes) box.extend(nodes[v]);
  return box;
}

// the local solve (see LocalSolveOptions); false when a full solve is due instead
bool StructuralPhase::Impl::localSolve(const std::vector<double>& ev) {
  if (!hasReference || numFree == 0) return false;
  if (local.refreshOnThread) {
    // the refresh started refreshEvery solves ago becomes the reference; the next starts
    if (refresh.running && ++refresh.solvesSinceStart >= local.refreshEvery) {
      finishRefresh(true);
      lastSolve.refreshAdopted = true;
    }
  } else if (local.refreshEvery > 0 && localSinceFull + 1 >= local.refreshEvery) {
    return false;
  }
  // 1. the box around the load change (and what removals changed)
  const Eigen::AlignedBox3d box = changedBox(ev, refEv, local.loadTolerance);
  // 2. the region: kept while the box stays inside the one it was built around
  ++localSinceFull;
  const auto startNextRefresh = [&] {  // once this solve is local
    if (local.refreshOnThread && !refresh.running && local.refreshEvery > 0) {
      startRefresh(ev);
      lastSolve.refreshStarted = true;
    }
  };
  lastSolve.local = true;
  if (box.isEmpty()) {  // nothing changed: the reference
    for (int dof : appliedDofs) u(dof) = refU(dof);
    appliedDofs.clear();
    startNextRefresh();
    outputs(ev, From::reference);
    return true;
  }
  if (!readyRegion(box)) {
    --localSinceFull;
    lastSolve.local = false;
    return false;
  }
  // 3. r_U = -sum_e V_e B_e^T sigma_e(u_ref, e_v) over the tets touching U
  const Eigen::VectorXd r =
      regionResidual(ev, [&](int t) -> const Voigt& { return refElastic[t]; });
  // 4. K_UU d_U = r_U; u = u_ref + d on U, u_ref elsewhere
  for (int dof : appliedDofs) u(dof) = refU(dof);
  const double* correction = regionCorrect(r);
  for (size_t k = 0; k < regionDofs.size(); ++k)
    u(regionDofs[k]) = refU(regionDofs[k]) + correction[k];
  appliedDofs = regionDofs;
  startNextRefresh();
  outputs(ev, From::region);
  return true;
}

// the region for the box: kept while the box stays inside the one it was built around, its
// factor updated for removals in it; false when a region would be too large (nothing built)
bool StructuralPhase::Impl::readyRegion(const Eigen::AlignedBox3d& box) {
  if (!(regionValid && regionBox.contains(box))) {
    const auto t0 = std::chrono::steady_clock::now();
    Eigen::AlignedBox3d grown = box;
    grown.min().array() -= local.slackM;
    grown.max().array() += local.slackM;
    if (!buildRegion(grown)) return false;
    lastSolve.regionBuilt = true;
    lastSolve.regionFactorSeconds = secondsSince(t0);
  } else if (!regionPending.removed.empty() || !regionPending.held.empty()) {
    // removals in it: its factor updated, or the region built again
    const auto t0 = std::chrono::steady_clock::now();
    Pending job = std::move(regionPending);
    regionPending = Pending{};
    std::sort(job.removed.begin(), job.removed.end());
    std::sort(job.held.begin(), job.held.end());
    const StructuralUpdateStats st =
        updateFactor(t0, StructuralUpdateStats{}, job.removed, job.held, current(), common,
                     {&regionFactor, &regionRowOf, regionFlops, false, &regionMarks});
    lastSolve.regionUpdated = true;
    lastSolve.regionRefactorized = st.refactorized;
    // an update that would cost more than a factorization (or failed): the region built
    // again around the same box (supernodal; a simplicial refactorization in place measured
    // 0.8-1.2 s against 0.3 s at 8000 nodes)
    if (st.refactorized && !buildRegion(Eigen::AlignedBox3d(regionBox))) return false;
    lastSolve.regionFactorSeconds = secondsSince(t0);
  }
  lastSolve.regionDofs = static_cast<int>(regionDofs.size());
  lastSolve.regionTets = static_cast<int>(regionTets.size());
  return true;
}

// r_U = -sum_e V_e B_e^T sigma_e(u_base, e_v) over the tets touching U, elastic(t) giving
// D B_e u_base
template <class Elastic>
Eigen::VectorXd StructuralPhase::Impl::regionResidual(const std::vector<double>& ev,
                                                      const Elastic& elastic) const {
  Eigen::VectorXd r = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(regionDofs.size()));
  for (int t : regionTets) {
    const Voigt& s = elastic(t);
    const double p = bulkModulusPa * ev[t];
    const double sxx = s(0) - p, syy = s(1) - p, szz = s(2) - p, syz = s(3), sxz = s(4), sxy = s(5);
    const double vol = geo[t].volume;
    for (int i = 0; i < 4; ++i) {
      const double gx = geo[t].grad(i, 0), gy = geo[t].grad(i, 1), gz = geo[t].grad(i, 2);
      const double force[3] = {gx * sxx + gy * sxy + gz * sxz, gx * sxy + gy * syy + gz * syz,
                               gx * sxz + gy * syz + gz * szz};
      for (int a = 0; a < 3; ++a) {
        const int dof = 3 * tets[t][i] + a;
        const int k = localOfDof[dof];
        if (k >= 0 && !held[dof]) r(k) -= vol * force[a];  // held since the build: d = 0
      }
    }
  }
  return r;
}

// d_U solving K_UU d_U = r_U (valid until the next region solve)
const double* StructuralPhase::Impl::regionCorrect(const Eigen::VectorXd& r) {
  if (solveThreads > 0 && ldlSolveSupports(*regionFactor)) {  // kept simplicial: ldl_solve.h
    regionCorrection.resize(static_cast<Eigen::Index>(regionDofs.size()));
    ldlSolve(*regionFactor, r.data(), regionCorrection.data(), solveThreads, regionSolve);
    lastSolve.solveThreads = regionSolve.threadsUsed;
    return regionCorrection.data();
  }
  cholmod_dense b = cholmodViewDense(r.data(), regionDofs.size());
  openblas_set_num_threads(1);
  const int ok =
      cholmod_solve2(CHOLMOD_A, regionFactor, &b, nullptr, &rx, nullptr, &ry, &re, &common);
  if (!ok) throwIfOutOfResources(common);
  ESIM_RUN_CHECK(ok, "structural: CHOLMOD solve failed");
  return static_cast<const double*>(rx->x);
}

// the coarse method's grid and K_c (built when stale); returns the seconds it took
double StructuralPhase::Impl::readyCoarse() {
  const auto t0 = std::chrono::steady_clock::now();
  if (!coarse) coarse = std::make_unique<CoarseSpace>(nodes, local.coarseSpacingM);
  if (coarseStale && numFree > 0) {
    coarse->build(assemble(current()), held.data());
    coarseStale = false;
  }
  return secondsSince(t0);
}

// the coarse method (see LocalSolveOptions); false when a full solve is due instead
bool StructuralPhase::Impl::coarseSolve(const std::vector<double>& ev) {
  if (numFree == 0) return false;
  // 1. u_0 = P_h K_c^-1 P_h' f
  if (coarseStale) lastSolve.coarseFactorSeconds = readyCoarse();
  loadVector(ev, current(), rhs);
  const bool refactor = coarse->needsFactorization();
  coarse->solve(rhs, held.data(), refU);
  if (refactor) lastSolve.coarseFactorSeconds = coarse->lastFactorSeconds();
  lastSolve.local = true;
  // 2. the box: the load changed since the last solve, and what removals changed
  if (prevEv.size() != ev.size()) prevEv.assign(ev.size(), 0.0);
  Eigen::AlignedBox3d box = changedBox(ev, prevEv, local.coarseLoadTolerance);
  prevEv = ev;
  changedNodes.clear();
  // 3. the region's correction (a region kept when nothing changed)
  u = refU;
  if (local.coarseCorrection && !(box.isEmpty() && !regionValid)) {
    if (!box.isEmpty() || !regionPending.removed.empty() || !regionPending.held.empty()) {
      if (box.isEmpty()) box = regionBox;
      if (!readyRegion(box)) {
        lastSolve.local = false;
        return false;
      }
    }
    lastSolve.regionDofs = static_cast<int>(regionDofs.size());
    lastSolve.regionTets = static_cast<int>(regionTets.size());
    const Eigen::VectorXd r = regionResidual(ev, [&](int t) { return elasticStress(t, refU); });
    const double* correction = regionCorrect(r);
    for (size_t k = 0; k < regionDofs.size(); ++k) u(regionDofs[k]) += correction[k];
  }
  outputs(ev, From::solution);
  return true;
}

void StructuralPhase::Impl::dropRegion() {
  regionValid = false;
  regionPending = Pending{};
  for (int dof : regionDofs) regionRowOf[dof] = -1;
  for (int t : regionTets) inRegion[t] = 0;
  for (int dof : regionDofs) localOfDof[dof] = -1;
  regionTets.clear();
  regionDofs.clear();
  if (regionFactor) cholmod_free_factor(&regionFactor, &common);
}

// U = the free dofs of the nodes within marginM of the box, the alive tets touching them,
// and the factor of K_UU; false (nothing built) when U is too large a part of the body
bool StructuralPhase::Impl::buildRegion(const Eigen::AlignedBox3d& box) {
  dropRegion();
  const int n = static_cast<int>(nodes.size());
  localOfDof.resize(numDofs(), -1);
  inRegion.resize(tets.size(), 0);
  std::vector<int> dofs;
  for (int v = 0; v < n; ++v) {
    if (aliveTetsOfNode[v] == 0 || box.exteriorDistance(nodes[v]) > local.marginM) continue;
    for (int a = 0; a < 3; ++a)
      if (!held[3 * v + a]) dofs.push_back(3 * v + a);
  }
  if (dofs.empty() || dofs.size() > local.maxRegionFraction * numFree) return false;
  regionDofs = std::move(dofs);
  for (size_t k = 0; k < regionDofs.size(); ++k) localOfDof[regionDofs[k]] = static_cast<int>(k);
  for (int dof : regionDofs) {
    if (dof % 3 != 0 && localOfDof[dof - dof % 3] >= 0) continue;  // node seen
    const int v = dof / 3;
    for (const int* t = tetsOfNode.begin(v); t != tetsOfNode.end(v); ++t)
      if (alive[*t] && !inRegion[*t]) {
        inRegion[*t] = 1;
        regionTets.push_back(*t);
      }
  }
  std::sort(regionTets.begin(), regionTets.end());
  // K_UU, lower triangle, in the order of regionDofs (ascending): the region's tets scattered
  // into its pattern as the whole body's K is
  const int m = static_cast<int>(regionDofs.size());
  const SparseMatrix kuu = assembleElasticLower(
      n, tets, inRegion.data(), held.data(), [this](int t) { return elementStiffness(t); },
      localOfDof.data(), m);
  cholmod_sparse view = cholmodViewLower(kuu);
  openblas_set_num_threads(1);
  // the ordering: the whole factor's, restricted to U (no ordering cost; measured at 50k
  // nodes, CHOLMOD's own AMD/METIS search took most of a region's build)
  std::vector<int> order(m);
  for (int k = 0; k < m; ++k) order[k] = k;
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return rowOfDof[regionDofs[a]] < rowOfDof[regionDofs[b]]; });
  regionFactor = cholmodAnalyzeGiven(&view, order.data(), &common);
  if (regionFactor == nullptr) throwIfOutOfResources(common);
  ESIM_RUN_CHECK(regionFactor != nullptr, "structural: CHOLMOD analysis failed");
  regionFlops = common.fl;
  const int ok = cholmod_factorize(&view, regionFactor, &common);
  throwIfOutOfResources(common);
  ESIM_RUN_CHECK(ok && common.status == CHOLMOD_OK && regionFactor->minor == regionFactor->n,
                 "structural: the region's stiffness matrix is not positive definite");
  // simplicial LDL', so that removals update it (cholmod_updown) rather than refactorize it
  toSimplicial(common, regionFactor);
  const int* perm = static_cast<const int*>(regionFactor->Perm);
  regionRowOf.resize(numDofs(), -1);
  for (int k = 0; k < m; ++k) regionRowOf[regionDofs[perm[k]]] = k;
  regionBox = box;
  regionValid = true;
  return true;
}

// stress and von Mises per tet: D B u from u (solution: every tet, stored as the reference
// under the local method; region: the region's tets) or from the reference
// (each tet on its own: the two halves of the tets on solveThreads threads)
void StructuralPhase::Impl::outputs(const std::vector<double>& ev, From from) {
  const int nt = static_cast<int>(tets.size());
  const bool store = from == From::solution && method == StructuralSolveMethod::local;
  // with the volumetric strain at the nodes (only with the full method): theta - theta* per
  // node, its mean over a tet's nodes gives the tet's pressure
  std::vector<double> excess;
  if (nodalVolumetric) {
    const StateView s = current();
    std::vector<double> volume, star;
    nodeVolumes(s, volume);
    nodeSums(
        s, [&](int t) { return ev[t]; }, star);
    nodeSums(
        s,
        [&](int t) {
          double div = 0;
          for (int i = 0; i < 4; ++i)
            for (int a = 0; a < 3; ++a) div += geo[t].grad(i, a) * u(3 * tets[t][i] + a);
          return div;
        },
        excess);
    for (size_t v = 0; v < excess.size(); ++v)
      excess[v] = volume[v] > 0 ? (excess[v] - star[v]) / volume[v] : 0.0;
  }
  runTwoShares(nt >= kMinTetsForTwoShares ? solveThreads : 1, [&](int share) {
    for (int t = share * nt / 2, end = (share + 1) * nt / 2; t < end; ++t) {
      if (!alive[t]) {
        stress[t] = VoigtStress{};
        vonMisesPa[t] = 0;
        continue;
      }
      const bool fresh = from == From::solution || (from == From::region && inRegion[t]);
      const Voigt s = fresh ? elasticStress(t, u) : refElastic[t];
      if (store) refElastic[t] = s;
      // sigma = D B u - K_b e_v (1, 1, 1, 0, 0, 0); at the nodes D_dev B u + K_b (mean of
      // theta - theta* over the tet's nodes) (1, 1, 1, 0, 0, 0)
      double p = bulkModulusPa * ev[t];
      if (nodalVolumetric) {
        p = 0;
        for (int v : tets[t]) p -= bulkModulusPa * excess[v] / 4;
      }
      stress[t] = {s(0) - p, s(1) - p, s(2) - p, s(3), s(4), s(5)};
      vonMisesPa[t] = vonMises(stress[t]);
    }
  });
  placeIslands();
}

// An island's own nodes (held at 0 in K u = f: a rigid motion of it is free) follow the rigid
// motion of its anchors (the nodes it shares with the held pieces, and its supported nodes,
// at 0; rigidFollowDisplacement): a piece hanging by an edge or a node is drawn attached where
// it hangs and turned with it, one cut loose stays where it was (no anchor: 0). No tet in K
// has such a node, so no stress depends on it.
void StructuralPhase::Impl::placeIslands() {
  if (islands == 0) return;
  if (islandsChanged) {
    islandOwn.clear();
    islandAnchors.clear();
    std::vector<int> slot(pieces.size(), -1);
    for (size_t t = 0; t < tets.size(); ++t) {
      const int p = pieceOf[t];
      if (p < 0 || !pieces[p].island) continue;
      if (slot[p] < 0) {
        slot[p] = static_cast<int>(islandOwn.size());
        islandOwn.emplace_back();
        islandAnchors.emplace_back();
      }
      for (int v : tets[t])
        (aliveTetsOfNode[v] > 0 || supportsOfNode.count(v) > 0 ? islandAnchors : islandOwn)[slot[p]]
            .push_back(v);
    }
    for (auto* lists : {&islandOwn, &islandAnchors})
      for (std::vector<int>& l : *lists) {
        std::sort(l.begin(), l.end());
        l.erase(std::unique(l.begin(), l.end()), l.end());
      }
    islandsChanged = false;
  }
  for (size_t k = 0; k < islandOwn.size(); ++k) {
    const std::vector<int>& anchors = islandAnchors[k];
    const std::vector<int>& own = islandOwn[k];
    Eigen::Matrix3Xd rest(3, anchors.size()), disp(3, anchors.size()), ownRest(3, own.size());
    for (size_t i = 0; i < anchors.size(); ++i) {
      rest.col(i) = nodes[anchors[i]];
      disp.col(i) = u.segment<3>(3 * anchors[i]);
    }
    for (size_t i = 0; i < own.size(); ++i) ownRest.col(i) = nodes[own[i]];
    const Eigen::Matrix3Xd d = rigidFollowDisplacement(rest, disp, ownRest);
    for (size_t i = 0; i < own.size(); ++i) u.segment<3>(3 * own[i]) = d.col(i);
  }
}

// ---- removal ----

// What removeTets weighs (see the header): the update's work, the sum over the columns j
// of L it walks of nnz(L(:, j)) times the columns of C (and rows) that pass j, against the
// flops of a supernodal refactorization (CHOLMOD's count, Common->fl). One unit of that
// work takes as long as kUpdownCostPerEntry flops of the refactorization: measured on the
// paper slab (esim bench structural, batches of 5 to 800 tets), update 1.0 to 1.7 ns per
// unit, refactorization 0.45 ns per flop at 5k nodes, 0.28 at 20k (BLAS 3 gains with size).
constexpr double kUpdownCostPerEntry = 5;
// ... and for the vectorized update (ldl_updown.h): 0.20-0.21 ns per unit on the cut (esim
// bench cut --sizes 8000,20000 --strategy update --stages: 4.7-5.1e9 units a second of the
// update's wall time), so ~0.5-0.7 refactorization flops; 1 keeps a margin
constexpr double kVectorUpdownCostPerEntry = 1;

StructuralUpdateStats StructuralPhase::Impl::removeTets(const std::vector<int>& ids) {
  return beginRemoval(ids)();
}

std::function<StructuralUpdateStats()> StructuralPhase::Impl::beginRemoval(
    const std::vector<int>& ids) {
  const auto t0 = std::chrono::steady_clock::now();
  StructuralUpdateStats stats;
  const int nt = static_cast<int>(tets.size());
  for (int t : ids)
    ESIM_VERIFY(t >= 0 && t < nt, "structural: removeTets: tet " + std::to_string(t) +
                                      " is out of range (" + std::to_string(nt) + " tets)");
  if (!failure.empty()) throw Error(failure);
  // the local method with its refresh on a thread defers the factor's update to the next
  // refresh (or full solve); otherwise the factor is updated now (by the function returned),
  // after what an earlier setting deferred. Measured (esim bench cut --sizes 8000 --frames 60
  // --structural local, margin 10 mm, refresh every 30 in the frame): deferring to the full
  // solve in the frame, median 260 ms against 139 ms with the update on the caller's thread
  // The coarse method defers it too: it solves without the whole factor
  const bool deferred =
      (method == StructuralSolveMethod::local && local.refreshOnThread && local.refreshEvery > 0) ||
      method == StructuralSolveMethod::coarse;
  const bool keepCoarse = method == StructuralSolveMethod::coarse && coarse && !coarseStale;
  if (!keepCoarse) coarseStale = true;  // K_c (if any) is built again at the next coarse solve
  if (!deferred) bringFactorUpToDate();
  std::vector<int> removed;  // from the mesh (an island's too)
  for (int t : ids)
    if (pieceOf[t] >= 0) removed.push_back(t);
  std::sort(removed.begin(), removed.end());
  removed.erase(std::unique(removed.begin(), removed.end()), removed.end());
  stats.tetsRemoved = static_cast<int>(removed.size());
  const auto done = [t0](StructuralUpdateStats st) {  // nothing left for the factor
    return [t0, st]() mutable {
      st.seconds = secondsSince(t0);
      return st;
    };
  };
  if (removed.empty()) return done(stats);

  // the tets whose stiffness leaves K: the removed ones in K, and the pieces that become
  // islands (cut off, or left without the supports that held them)
  std::vector<int> leaving;
  for (int t : removed)
    if (alive[t]) leaving.push_back(t);
  const int removedInK = static_cast<int>(leaving.size());

  // 1. the pieces lose the removed tets
  std::vector<std::pair<int, int>> byPiece;  // (old piece, removed tet)
  for (int t : removed) {
    byPiece.emplace_back(pieceOf[t], t);
    --pieces[pieceOf[t]].tets;
    pieceOf[t] = -1;
  }

  // 2. pieces split off, and pieces that lost their supports, become islands
  std::sort(byPiece.begin(), byPiece.end());
  for (size_t r = 0; r < byPiece.size();) {
    const int p = byPiece[r].first;
    std::vector<int> gone;
    for (; r < byPiece.size() && byPiece[r].first == p; ++r) gone.push_back(byPiece[r].second);
    if (pieces[p].tets == 0) {  // removed whole
      --livePieces;
      if (pieces[p].island) --islands;
      continue;
    }
    std::vector<int> seeds;
    for (int t : gone)
      for (const int* nb = faceNeighbours.begin(t); nb != faceNeighbours.end(t); ++nb)
        if (pieceOf[*nb] == p) seeds.push_back(*nb);
    const bool wasIsland = pieces[p].island;
    std::vector<int> candidates = nodesOf(gone);  // nodes the rest may have lost
    for (std::vector<int>& part : splitPiece(seeds)) {
      const int q = static_cast<int>(pieces.size());
      pieces.emplace_back();
      for (int t : part) pieceOf[t] = q;
      pieces[q].tets = static_cast<int>(part.size());
      pieces[p].tets -= pieces[q].tets;
      ++livePieces;
      ++stats.piecesCutOff;
      if (wasIsland) {  // a part of an island has fewer supports still
        pieces[q].island = true;
        ++islands;
        continue;
      }
      const std::vector<int> partNodes = nodesOf(part);
      candidates.insert(candidates.end(), partNodes.begin(), partNodes.end());
      pieces[q].supports = supportsOn(partNodes);
      if (fixes(pieces[q].supports)) continue;
      pieces[q].island = true;
      pieces[q].supports.clear();
      ++islands;
      leaving.insert(leaving.end(), part.begin(), part.end());
    }
    if (wasIsland) continue;
    // the rest keeps its supports unless a supported node left it
    bool lost = false;
    for (int v : candidates)
      if (supportsOfNode.count(v) > 0 && !nodeInPiece(v, p)) {
        lost = true;
        break;
      }
    if (!lost) continue;
    std::vector<int>& own = pieces[p].supports;
    own.erase(std::remove_if(own.begin(), own.end(),
                             [&](int s) { return !nodeInPiece(supports[s].node, p); }),
              own.end());
    if (fixes(own)) continue;
    pieces[p].island = true;
    own.clear();
    ++islands;
    const int start =
        *std::find_if(seeds.begin(), seeds.end(), [&](int t) { return pieceOf[t] == p; });
    const std::vector<int> rest = tetsOfPiece(p, start);
    leaving.insert(leaving.end(), rest.begin(), rest.end());
  }
  if (livePieces > 0 && islands == livePieces) {
    failure = noPieceHeld;
    throw Error(failure);
  }
  std::sort(leaving.begin(), leaving.end());
  stats.tetsIntoIslands = static_cast<int>(leaving.size()) - removedInK;
  islandsChanged = true;  // (placeIslands: a pass over the tets, while islands are left)

  // the coarse matrix loses the leaving tets (under the held dofs before the removal)
  if (keepCoarse)
    for (int t : leaving) addToCoarse(t, -1, [&](int dof) { return held[dof] != 0; });

  // 3. alive flags; nodes left without a tet in K are held
  std::vector<int> newlyHeld;
  for (int t : leaving) {
    alive[t] = 0;
    for (int v : tets[t]) --aliveTetsOfNode[v];
  }
  for (int t : leaving)
    for (int v : tets[t])
      if (aliveTetsOfNode[v] == 0) holdNode(v, newlyHeld);
  std::sort(newlyHeld.begin(), newlyHeld.end());
  stats.dofsHeld = static_cast<int>(newlyHeld.size());
  // ... and the alive tets at the nodes newly held change their part of it
  if (keepCoarse && !newlyHeld.empty()) {
    std::vector<int> touched;
    for (int dof : newlyHeld)
      for (const int* t = tetsOfNode.begin(dof / 3); t != tetsOfNode.end(dof / 3); ++t)
        if (alive[*t]) touched.push_back(*t);
    std::sort(touched.begin(), touched.end());
    touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
    const auto newly = [&](int dof) {
      return std::binary_search(newlyHeld.begin(), newlyHeld.end(), dof);
    };
    for (int t : touched) {
      addToCoarse(t, -1, [&](int dof) { return held[dof] != 0 && !newly(dof); });
      addToCoarse(t, 1, [&](int dof) { return held[dof] != 0; });
    }
  }

  if (leaving.empty()) return done(stats);  // only islands' tets: K is as it was

  // the local solve's reference: u_ref is 0 on the dofs now held (the tets at their nodes
  // change stress); these nodes and the leaving tets' widen the next region's box; a
  // refresh running learns the same at its adoption
  const std::vector<int> leavingNodes = nodesOf(leaving);
  if (refresh.running) {
    refresh.heldSince.insert(refresh.heldSince.end(), newlyHeld.begin(), newlyHeld.end());
    refresh.changedSince.insert(refresh.changedSince.end(), leavingNodes.begin(),
                                leavingNodes.end());
    for (int dof : newlyHeld) refresh.changedSince.push_back(dof / 3);
  }
  if (hasReference) {
    const std::vector<int> heldNodes = holdInReference(newlyHeld);
    changedNodes.insert(changedNodes.end(), leavingNodes.begin(), leavingNodes.end());
    changedNodes.insert(changedNodes.end(), heldNodes.begin(), heldNodes.end());
  }
  // the region: the next local solve updates its factor when the removal touched it
  if (method == StructuralSolveMethod::coarse) {  // the next coarse solve's box
    changedNodes.insert(changedNodes.end(), leavingNodes.begin(), leavingNodes.end());
    for (int dof : newlyHeld) changedNodes.push_back(dof / 3);
  }
  if (method != StructuralSolveMethod::full && regionValid) {
    for (int t : leaving)
      if (inRegion[t]) {
        inRegion[t] = 0;
        regionPending.removed.push_back(t);
      }
    if (!regionPending.removed.empty())
      regionTets.erase(
          std::remove_if(regionTets.begin(), regionTets.end(), [&](int t) { return !alive[t]; }),
          regionTets.end());
    for (int dof : newlyHeld)
      if (localOfDof[dof] >= 0) regionPending.held.push_back(dof);
  } else {
    dropRegion();
  }
  if (numDofs() == 0) return done(stats);
  if (deferred) {
    pending.removed.insert(pending.removed.end(), leaving.begin(), leaving.end());
    pending.held.insert(pending.held.end(), newlyHeld.begin(), newlyHeld.end());
    stats.deferred = true;
    return done(stats);
  }
  return
      [this, t0, stats, leaving = std::move(leaving), newlyHeld = std::move(newlyHeld)]() mutable {
        return updateFactor(t0, stats, leaving, newlyHeld, current(), common, wholeTarget());
      };
}

// steps 4-7 of a removal: the factor of the new A (see beginRemoval), the whole one or the
// region's (target); removed: the tets whose stiffness leaves K
StructuralUpdateStats StructuralPhase::Impl::updateFactor(std::chrono::steady_clock::time_point t0,
                                                          StructuralUpdateStats stats,
                                                          const std::vector<int>& removed,
                                                          const std::vector<int>& newlyHeld,
                                                          const StateView& s, cholmod_common& cm,
                                                          const Target& target) {
  cholmod_factor*& factor = *target.factor;
  const std::vector<int>& rowOfDof = *target.rowOf;
  // 4. C C' = the removed tets' stiffness on the dofs free before and after. Tets that share
  // a node are summed first (one group per connected cluster, up to kMaxGroupDofs free dofs),
  // and the group's matrix G (positive semidefinite), its dofs in ascending rows of L, is
  // factored G = sum_c g_c g_c' / d_c by an LDL' that takes as pivot the first dof (lowest
  // row of L) whose remaining diagonal is at least kPivotShare of the largest remaining one,
  // and stops when that is at round-off (1e-12 of G's largest diagonal: the rigid modes).
  // C gets the columns g_c / sqrt(d_c). A cluster's rank is at most its free dofs less its
  // rigid motions, far below 6 per tet (a 13-tet cluster under the blade: 78 columns per
  // tet, ~40 summed), and the update's work is proportional to the columns.
  // Why this order: column c is zero on the rows pivoted before it, so its path up the
  // elimination tree starts at the lowest row not yet pivoted, not at the group's lowest row
  // as an eigenvector's does (the columns were G's eigenpairs before). Why the threshold:
  // without it (every pivot in row order) a pivot tiny against the other diagonals loses
  // its digits, and C C' missed G by up to 2e-4 in structural_test; with it, the error of
  // each rank-1 term stays below rounding of G's largest entry / kPivotShare (for a
  // semidefinite G, g_a^2 / d <= G_aa), and C C' matched G to 3e-14 (Frobenius, relative) with
  // the same rank as the eigenpairs on all 2364 groups of structural_test, simulation_test
  // and hard_removal_test (a temporary check). kPivotShare is 1e-3 since the vectorized
  // update (ldl_updown.h), which needs columns that do not fill in L: a pivot out of row
  // order makes the columns after it fill in, and their group then goes tet by tet (below).
  // Over 755 groups (esim bench cut --sizes 1013,8000 --frames 60 --strategy update,
  // structural_test, hard_removal_test, simulation_test's cuts; a temporary check) C C' met G
  // to 5.2e-13 at most (median 1.8e-16) against 2.9e-14 at 0.01 (2.3e-11 at 1e-4); on
  // --sizes 8000 --frames 60 --stages, one run each, the work per removal was 7.0e7 at 1e-3
  // against 9.7e7 at 0.01 (more groups tet by tet), the structural update's p95 35 against
  // 84 ms. CHOLMOD's
  // summed work estimate over esim bench cut --strategy update (units of a
  // refactorization): 1013 nodes 6.0 with kPivotShare 1 (diagonal pivoting), 4.5 at 0.1, 3.1
  // at 0.01 and below; 8000 nodes (--frames 60) 5.9 at 1, 3.2 at 0.01. Timed, each against
  // the eigenpairs in alternating runs: --sizes 1013 --stages (five pairs) the update's
  // median 1.3-1.8 against 2.7-3.0 ms, the frame p95 2.0-2.7 against 4.6-5.8 ms; --sizes 8000
  // --frames 60 --stages (two pairs) the update's median 81-85 against 142-160 ms, its p95
  // 181-205 against 399-420 ms, the frame p95 184-195 against 377-393 ms. Above
  // kMaxGroupDofs a cluster goes by parts (addSplit, below; in the measurements that follow it
  // went tet by tet, 6 columns each): the dense LDL' is ~m^3/3 flops on m^2 doubles, 150 Mflop
  // and 4.7 MB at 768. 768 (was 192, and 96 with the
  // eigenpairs, whose 192 x 192 eigenproblem took 9 ms): esim bench cut --sizes 50000
  // --frames 30 --strategy update --stages, one run each (temporary instrumentation): with
  // 192, 6 of the 27 removals had a cluster over the limit (151-392 tets, 237-408 dofs, up to
  // 2352 columns one by one instead of 408 summed); with 768 none, and the structural
  // update's p95 went 11.7 -> 8.4 s, its max 17.1 -> 13.5 s, the frame p95 11.0 -> 9.7 s
  // (the same 2975 tets removed; the median of the 21 other removals came out 2.5 -> 3.6 s,
  // the electric update's 1.2 -> 1.4 s: the machine, not the limit). --sizes 20000
  // --frames 40: one cluster over 192 (96 tets, 195 dofs), that removal's update 2.25 ->
  // 1.24 s. With 96 -> 192 (eigenpairs, --sizes 8000): the 78- and 88-tet removals of frames
  // 5 and 7 took 432 and 402 columns with 96, 126 and 104 with 192
  constexpr int kMaxGroupDofs = 768;
  constexpr double kPivotShare = 1e-3;
  std::vector<int> cp{0}, ci;
  std::vector<double> cx;
  std::vector<std::vector<int>> groups;
  {
    // clusters of removed tets through shared nodes (union-find over the removed list)
    const int k = static_cast<int>(removed.size());
    std::vector<int> parent(k);
    for (int i = 0; i < k; ++i) parent[i] = i;
    auto find = [&](int i) {
      while (parent[i] != i) i = parent[i] = parent[parent[i]];
      return i;
    };
    std::vector<std::pair<int, int>> nodeTet;  // (node, index in removed)
    for (int i = 0; i < k; ++i)
      for (int v : tets[removed[i]]) nodeTet.emplace_back(v, i);
    std::sort(nodeTet.begin(), nodeTet.end());
    for (size_t j = 1; j < nodeTet.size(); ++j)
      if (nodeTet[j].first == nodeTet[j - 1].first)
        parent[find(nodeTet[j].second)] = find(nodeTet[j - 1].second);
    std::vector<int> groupOf(k, -1);
    for (int i = 0; i < k; ++i) {  // in the order of removed: deterministic
      int& g = groupOf[find(i)];
      if (g < 0) {
        g = static_cast<int>(groups.size());
        groups.emplace_back();
      }
      groups[g].push_back(removed[i]);
    }
  }
  auto isFree = [&](int dof) { return rowOfDof[dof] >= 0 && !s.held[dof]; };
  // the free dofs of some tets, as (row of L, dof), ascending rows
  auto freeDofs = [&](const std::vector<int>& some) {
    std::vector<std::pair<int, int>> free;
    for (int t : some)
      for (int i = 0; i < 12; ++i) {
        const int dof = 3 * tets[t][i / 3] + i % 3;
        if (isFree(dof)) free.emplace_back(rowOfDof[dof], dof);
      }
    std::sort(free.begin(), free.end());
    free.erase(std::unique(free.begin(), free.end()), free.end());
    return free;
  };
  // the columns of the tets' summed stiffness on their free dofs
  auto addColumns = [&](const std::vector<int>& some,
                        const std::vector<std::pair<int, int>>& free) {
    const int m = static_cast<int>(free.size());
    if (m == 0) return;
    Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(m, m);
    for (int t : some) {
      const Mat12 ke = elementStiffness(t);
      std::array<int, 12> at;  // local index of each element dof, -1 when not free
      for (int i = 0; i < 12; ++i) {
        const int dof = 3 * tets[t][i / 3] + i % 3;
        at[i] = -1;
        for (int a = 0; a < m; ++a)
          if (free[a].second == dof) at[i] = a;
      }
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j)
          if (at[i] >= 0 && at[j] >= 0) sum(at[i], at[j]) += ke(i, j);
    }
    // (the rest: rigid modes, round-off)
    pivotedLdl(sum, kPivotShare, false, [&](double d, const Eigen::VectorXd& g) {
      const double scale = 1 / std::sqrt(d);
      for (int a = 0; a < m; ++a)
        if (g[a] != 0.0) {
          ci.push_back(free[a].first);
          cx.push_back(g[a] * scale);
        }
      cp.push_back(static_cast<int>(ci.size()));
    });
  };
  // 5. L becomes simplicial LDL' (once after each factorization: only those can be updated),
  // before C's columns, which addSplit checks against its pattern
  if (factor->is_super || factor->is_ll) {
    const auto tc = std::chrono::steady_clock::now();
    toSimplicial(cm, factor);
    stats.convertSeconds = secondsSince(tc);
  }
  // Some tets' columns summed; or, over kMaxGroupDofs free dofs or with a column that would
  // fill in L (checked when the vectorized update, ldl_updown.h, takes them: it leaves such
  // columns to cholmod_updown, which grows L for them, 190 ms for the 13 such columns of one
  // 8000-node removal, the L grown for the rest of the run; a pivot taken out of row order
  // gives the columns after it rows outside L's pattern, often), the columns of its two
  // halves, each the same way, down to single tets (a tet never fills in: its dofs are all
  // coupled in L). The halves split the tets ordered by their lowest row of L, so that each
  // half keeps tets close in the elimination tree. True when it split. Measured (temporary
  // instrumentation) before the halves, when such a group went tet by tet: 13 of 62 groups
  // in 40 frames of liver_incision and 11 of 71 in esim bench cut's 50k slab, their removals
  // 77-80 % of all the columns.
  const bool checkFill = kernelUpdates();
  const auto addSplit = [&](const auto& self, const std::vector<int>& some) -> bool {
    const std::vector<std::pair<int, int>> free = freeDofs(some);
    if (some.size() == 1) {
      addColumns(some, free);
      return false;
    }
    if (static_cast<int>(free.size()) <= kMaxGroupDofs) {
      const size_t from = cp.size() - 1;
      addColumns(some, free);
      bool fills = false;
      for (size_t c = from; checkFill && !fills && c + 1 < cp.size(); ++c)
        fills =
            ldlColumnFillsIn(*factor, ci.data() + cp[c], cp[c + 1] - cp[c], target.marks->updown);
      if (!fills) return false;
      cp.resize(from + 1);
      ci.resize(cp.back());
      cx.resize(cp.back());
    }
    std::vector<std::pair<int, int>> byRow;  // (lowest row of L of the tet's dofs, tet)
    for (int t : some) {
      int lowest = std::numeric_limits<int>::max();
      for (int i = 0; i < 12; ++i) {
        const int row = rowOfDof[3 * tets[t][i / 3] + i % 3];
        if (row >= 0) lowest = std::min(lowest, row);
      }
      byRow.emplace_back(lowest, t);
    }
    std::sort(byRow.begin(), byRow.end());
    std::vector<int> low, high;
    for (size_t q = 0; q < byRow.size(); ++q)
      (q < byRow.size() / 2 ? low : high).push_back(byRow[q].second);
    self(self, low);
    self(self, high);
    return true;
  };
  for (const std::vector<int>& group : groups) stats.groupsSplit += addSplit(addSplit, group);
  // With the volumetric strain at the nodes (the dev part above: elementStiffness is
  // V B' D_dev B then), node n of a removed tet changes its term K_b V_n g_n g_n' to the one
  // over the tets left: the new terms are added first (L D L' + W W': positive definite
  // throughout), the old ones go with C's downdate. Columns sqrt(K_b V_n) g_n on the dofs free
  // after the removal (the rows held were deleted), rows of L ascending.
  std::vector<int> wp{0}, wi;
  std::vector<double> wx;
  if (nodalVolumetric) {
    std::vector<int> touched;
    for (int t : removed) touched.insert(touched.end(), tets[t].begin(), tets[t].end());
    std::sort(touched.begin(), touched.end());
    touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
    const auto isRemoved = [&](int t) {
      return std::binary_search(removed.begin(), removed.end(), t);
    };
    std::vector<std::pair<int, double>> col;
    const auto column = [&](int v, bool before, std::vector<int>& outP, std::vector<int>& outI,
                            std::vector<double>& outX) {
      double volume = 0;
      col.clear();
      for (const int* t = tetsOfNode.begin(v); t != tetsOfNode.end(v); ++t) {
        if (!(s.alive[*t] || (before && isRemoved(*t)))) continue;
        volume += geo[*t].volume / 4;
        for (int i = 0; i < 4; ++i)
          for (int a = 0; a < 3; ++a) {
            const int dof = 3 * tets[*t][i] + a;
            if (!s.held[dof])
              col.emplace_back(rowOfDof[dof], geo[*t].volume / 4 * geo[*t].grad(i, a));
          }
      }
      if (volume <= 0 || col.empty()) return;
      std::sort(col.begin(), col.end(),
                [](const auto& x, const auto& y) { return x.first < y.first; });
      const double scale = std::sqrt(bulkModulusPa * volume) / volume;  // sqrt(K V) / V
      for (size_t k = 0; k < col.size();) {
        const int row = col[k].first;
        double sum = 0;
        for (; k < col.size() && col[k].first == row; ++k) sum += col[k].second;
        outI.push_back(row);
        outX.push_back(scale * sum);
      }
      outP.push_back(static_cast<int>(outI.size()));
    };
    for (int v : touched) {
      column(v, false, wp, wi, wx);  // the new term (update)
      column(v, true, cp, ci, cx);   // the old one (with C's downdate)
    }
  }
  stats.rank = static_cast<int>(cp.size()) - 1;

  // 6. the columns of L the update walks: up the elimination tree from each deleted or
  // added row and from the first row of each column of C; the work, those columns' lengths
  // times the columns of C (and rows) that pass them
  std::vector<int> walked;
  std::vector<double> passes;
  {
    const SimplicialView l(factor);
    std::vector<int> starts;
    for (int dof : newlyHeld) starts.push_back(rowOfDof[dof]);
    for (int c = 0; c + 1 < static_cast<int>(cp.size()); ++c) starts.push_back(ci[cp[c]]);
    for (int c = 0; c + 1 < static_cast<int>(wp.size()); ++c) starts.push_back(wi[wp[c]]);
    RowMarks& rm = *target.marks;
    const int first = ++rm.stamp;
    for (int s : starts)
      for (int j = s; j >= 0 && rm.mark[j] < first; j = l.parent(j)) {
        rm.mark[j] = first;
        walked.push_back(j);
      }
    std::sort(walked.begin(), walked.end());
    // passes per walked column: a tree sum, children before parents (ascending rows)
    std::vector<int> slot(walked.size());
    passes.assign(walked.size(), 0);
    for (int s : starts)
      passes[std::lower_bound(walked.begin(), walked.end(), s) - walked.begin()]++;
    for (size_t w = 0; w < walked.size(); ++w) {
      stats.updateWork += passes[w] * l.nz[walked[w]];
      const int up = l.parent(walked[w]);
      if (up >= 0)
        passes[std::lower_bound(walked.begin(), walked.end(), up) - walked.begin()] += passes[w];
    }
  }

  // 7. delete the rows now held, downdate by C C'; or refactorize when that costs more
  const double costPerEntry = kernelUpdates() ? kVectorUpdownCostPerEntry : kUpdownCostPerEntry;
  stats.updateCost = costPerEntry * stats.updateWork / target.refactorFlops;
  bool updated = false;
  const LdlUpdownWork& kernel = target.marks->updown;
  const long vectorBefore = kernel.vectorColumns, choleskyBefore = kernel.choleskyColumns;
  if (stats.updateCost <= updateCostLimit) {
    bool ok = newlyHeld.empty() || deleteRows(newlyHeld, target, cm);
    if (ok && wp.size() > 1) {  // the nodes' new volumetric terms, before the downdate
      cholmod_sparse w = cholmodViewColumns(factor->n, static_cast<int>(wp.size()) - 1, wp.data(),
                                            wi.data(), wx.data());
      ok = updown(true, w, target, cm);
    }
    if (ok && stats.rank > 0) {
      cholmod_sparse c = cholmodViewColumns(factor->n, stats.rank, cp.data(), ci.data(), cx.data());
      ok = updown(false, c, target, cm);
    }
    // a downdate that lost positive definiteness shows as D(j) <= 0 on the walked columns
    const SimplicialView l(factor);
    for (int j : walked) ok = ok && l.diagonal(j) > 0 && std::isfinite(l.diagonal(j));
    updated = ok && cm.status == CHOLMOD_OK;
    stats.downdateFailed = !updated;
  }
  stats.vectorColumns = kernel.vectorColumns - vectorBefore;
  stats.choleskyColumns = kernel.choleskyColumns - choleskyBefore;
  if (!updated) {
    if (target.whole) factorize(cm, s);  // the region's caller builds it again
    stats.refactorized = true;
  }
  stats.seconds = secondsSince(t0);
  return stats;
}

// ---- the phase ----

namespace {

// compressed rows from (row, id) pairs
Adjacency compressedRows(int rows, std::vector<std::pair<int, int>> pairs) {
  std::sort(pairs.begin(), pairs.end());
  Adjacency adj;
  adj.offsets.assign(rows + 1, 0);
  for (const auto& p : pairs) adj.offsets[p.first + 1]++;
  for (int i = 0; i < rows; ++i) adj.offsets[i + 1] += adj.offsets[i];
  for (const auto& p : pairs) adj.ids.push_back(p.second);
  return adj;
}

}  // namespace

StructuralPhase::StructuralPhase(const TetMesh& mesh, const StructuralOptions& options,
                                 const std::vector<Support>& supports)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  const double e = options.youngsModulusPa, nu = options.poissonRatio;
  ESIM_VERIFY(std::isfinite(e) && e > 0,
              "structural: youngsModulusPa must be > 0, got " + messageNumber(e));
  ESIM_VERIFY(std::isfinite(nu) && nu >= 0 && nu < 0.5,
              "structural: poissonRatio must be in [0, 0.5), got " + messageNumber(nu));
  const int n = mesh.numNodes(), nt = mesh.numTets();
  m.nodes = mesh.nodes;
  m.tets = mesh.tets;
  m.alive.resize(nt);
  for (int t = 0; t < nt; ++t) m.alive[t] = mesh.isAlive(t) ? 1 : 0;
  m.geo = tetGeometry(mesh);
  m.d = elasticity(e, nu);
  m.bulkModulusPa = e / (3 * (1 - 2 * nu));
  m.nodalVolumetric = options.volumetric == VolumetricStrain::nodal;
  if (m.nodalVolumetric) m.d.topLeftCorner<3, 3>().array() -= m.bulkModulusPa;  // D_dev
  verifyVolumetricMethod(m.nodalVolumetric, options.solveMethod);
  m.supports = supports;
  m.noPieceHeld =
      supportsMessage("no piece of the body is held by the supports", options.supportsNote);
  m.notPositive = supportsMessage(
      "the stiffness matrix is not positive definite (degenerate tets, or supports that leave "
      "part of the body free)",
      options.supportsNote);
  verifySolveThreads(options.solveThreads);
  ESIM_VERIFY(!(options.updateCostLimit < 0), "structural: updateCostLimit must be >= 0, got " +
                                                  messageNumber(options.updateCostLimit));
  m.updateCostLimit = options.updateCostLimit;
  m.vectorizedUpdate = options.vectorizedUpdate;
  m.prepareForUpdates = options.prepareForUpdates;
  m.setThreads(options.solveThreads);
  verifyLocalOptions(options.local);
  m.method = options.solveMethod;
  m.local = options.local;

  // 1. the supports
  std::vector<std::pair<int, int>> supportPairs;
  for (size_t k = 0; k < supports.size(); ++k) {
    const Support& s = supports[k];
    ESIM_VERIFY(s.node >= 0 && s.node < n && s.axis >= 0 && s.axis < 3,
                "structural: support (node " + std::to_string(s.node) + ", axis " +
                    std::to_string(s.axis) + ") is out of range (" + std::to_string(n) +
                    " nodes, axes 0..2)");
    supportPairs.emplace_back(s.node, static_cast<int>(k));
  }
  ESIM_VERIFY(supportsFixRigidMotions(m.nodes, supports),
              supportsMessage("the supports leave the body free to translate or rotate; hold "
                              "at least 6 independent displacement components, e.g. by "
                              "clamping a face",
                              options.supportsNote));

  // 2. adjacency over every tet, removed or not (removeTets walks it), and the pieces (the
  // islands' tets leave K)
  TetMesh whole;
  whole.nodes = mesh.nodes;
  whole.tets = mesh.tets;  // no alive flags: every tet
  m.tetsOfNode = nodeTets(whole);
  m.faceNeighbours = tetNeighbours(whole);
  m.supportsOfNode = compressedRows(n, std::move(supportPairs));
  m.wholeMarks.mark.assign(3 * static_cast<size_t>(n), 0);
  m.regionMarks.mark.assign(3 * static_cast<size_t>(n), 0);
  m.tetMark.assign(nt, 0);
  m.classifyPieces();
  ESIM_VERIFY(m.livePieces == 0 || m.islands < m.livePieces, m.noPieceHeld);

  // 3. held components: of nodes without a tet in K, and the supports
  m.aliveTetsOfNode.assign(n, 0);
  for (int t = 0; t < nt; ++t)
    if (m.alive[t])
      for (int v : mesh.tets[t]) ++m.aliveTetsOfNode[v];
  m.held.assign(3 * static_cast<size_t>(n), 1);
  for (int v = 0; v < n; ++v)
    if (m.aliveTetsOfNode[v] > 0)
      for (int a = 0; a < 3; ++a) m.held[3 * v + a] = 0;
  for (const Support& s : supports) m.held[3 * s.node + s.axis] = 1;
  m.numFree = static_cast<int>(std::count(m.held.begin(), m.held.end(), 0));

  // 4. assembly and factorization of A (3n x 3n), once
  m.u = Eigen::VectorXd::Zero(3 * n);
  m.stress.assign(nt, VoigtStress{});
  m.vonMisesPa.assign(nt, 0.0);
  if (n == 0) return;
  const auto t0 = std::chrono::steady_clock::now();
  m.factorize(m.common, m.current());
  m.factorSeconds = secondsSince(t0);
  // the coarse method's grid (a refused spacing fails here, not in a frame) and K_c
  if (m.method == StructuralSolveMethod::coarse) m.factorSeconds += m.readyCoarse();
}

StructuralPhase::~StructuralPhase() = default;

StructuralUpdateStats StructuralPhase::removeTets(const std::vector<int>& tets) {
  return impl_->removeTets(tets);
}

std::function<StructuralUpdateStats()> StructuralPhase::beginRemoval(const std::vector<int>& tets) {
  return impl_->beginRemoval(tets);
}

void StructuralPhase::solve(const std::vector<double>& ev) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& m = *impl_;
  const int nt = static_cast<int>(m.tets.size());
  ESIM_VERIFY(static_cast<int>(ev.size()) == nt, "structural: " + std::to_string(ev.size()) +
                                                     " eigenstrains for " + std::to_string(nt) +
                                                     " tets");
  if (!m.failure.empty()) throw Error(m.failure);
  for (int t = 0; t < nt; ++t)
    ESIM_VERIFY(m.pieceOf[t] < 0 || std::isfinite(ev[t]),
                "structural: eigenstrain of tet " + std::to_string(t) + " is not finite");
  m.lastSolve = StructuralSolveStats{};
  const bool done = (m.method == StructuralSolveMethod::local && m.localSolve(ev)) ||
                    (m.method == StructuralSolveMethod::coarse && m.coarseSolve(ev));
  if (!done) m.fullSolve(ev);
  m.lastSolve.seconds = secondsSince(t0);
}

void StructuralPhase::setSolveMethod(StructuralSolveMethod method, const LocalSolveOptions& local) {
  Impl& m = *impl_;
  verifyLocalOptions(local);
  verifyVolumetricMethod(m.nodalVolumetric, method);
  // a coarse grid of another spacing: made first, so that a refused one changes nothing
  std::unique_ptr<CoarseSpace> grid;
  if (method == StructuralSolveMethod::coarse &&
      (!m.coarse || local.coarseSpacingM != m.local.coarseSpacingM))
    grid = std::make_unique<CoarseSpace>(m.nodes, local.coarseSpacingM);
  m.finishRefresh(false);
  if (grid) {
    m.coarse = std::move(grid);
    m.coarseStale = true;
  }
  if (method == StructuralSolveMethod::coarse) m.changedNodes.clear();
  m.prevEv.clear();  // the first coarse solve's box: every loaded tet
  m.method = method;
  m.local = local;
  m.dropRegion();
  if (method != StructuralSolveMethod::local) {  // the reference is not kept up to date
    m.hasReference = false;
    m.refElastic = {};
    m.refEv = {};
  }
  if (method == StructuralSolveMethod::coarse && m.failure.empty()) m.readyCoarse();
}

const StructuralSolveStats& StructuralPhase::lastSolveStats() const { return impl_->lastSolve; }

void StructuralPhase::setSolveThreads(int threads) {
  verifySolveThreads(threads);
  impl_->setThreads(threads);
}

const Eigen::VectorXd& StructuralPhase::displacementM() const { return impl_->u; }
const std::vector<VoigtStress>& StructuralPhase::stressPa() const { return impl_->stress; }
const std::vector<double>& StructuralPhase::vonMisesPa() const { return impl_->vonMisesPa; }
int StructuralPhase::numFreeDofs() const { return impl_->numFree; }
double StructuralPhase::factorizationSeconds() const { return impl_->factorSeconds; }
int StructuralPhase::numFloatingIslands() const { return impl_->islands; }
int StructuralPhase::numIslandTets() const {
  int n = 0;
  for (const Piece& p : impl_->pieces) n += p.island ? p.tets : 0;
  return n;
}

}  // namespace esim
