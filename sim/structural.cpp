// structural.cpp - linear thermo-elastic P1 tetrahedra (see structural.h).
#include "sim/structural.h"

#include <Eigen/CholmodSupport>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <string>

#include "sim/core_error.h"
#include "sim/fem_p1.h"

extern "C" void openblas_set_num_threads(int num_threads);

namespace esim {
namespace {

using Cholesky = Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower>;
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
bool supportsFixRigidMotions(const TetMesh& mesh, const std::vector<Support>& supports) {
  if (supports.empty()) return false;
  Vec3 centre = Vec3::Zero();
  for (const Support& s : supports) centre += mesh.nodes[s.node];
  centre /= static_cast<double>(supports.size());
  double scale = 0;
  for (const Support& s : supports) scale = std::max(scale, (mesh.nodes[s.node] - centre).norm());
  if (scale == 0) scale = 1;
  Mat6 gram = Mat6::Zero();
  for (const Support& s : supports) {
    const Vec3 p = (mesh.nodes[s.node] - centre) / scale;
    // component `axis` of the translations e_x, e_y, e_z and the rotations e_k x p
    Eigen::Matrix<double, 6, 1> row = Eigen::Matrix<double, 6, 1>::Zero();
    row(s.axis) = 1;
    for (int k = 0; k < 3; ++k) row(3 + k) = Vec3::Unit(k).cross(p)(s.axis);
    gram += row * row.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(gram, Eigen::EigenvaluesOnly);
  return eig.eigenvalues()(0) > 1e-10 * eig.eigenvalues()(5);
}

// rigid pieces of the alive tets: tets connected through shared faces (a piece joined
// to another by an edge or a node only can still turn about it); per alive tet its piece
std::vector<int> alivePieces(const TetMesh& mesh, int& count) {
  const int nt = mesh.numTets();
  std::vector<int> parent(nt);
  for (int t = 0; t < nt; ++t) parent[t] = t;
  auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  struct Face {
    std::array<int, 3> key;
    int tet;
  };
  std::vector<Face> faces;
  faces.reserve(4 * static_cast<size_t>(nt));
  for (int t = 0; t < nt; ++t) {
    if (!mesh.isAlive(t)) continue;
    const Tet& tet = mesh.tets[t];
    for (int k = 0; k < 4; ++k) {
      std::array<int, 3> key{tet[(k + 1) % 4], tet[(k + 2) % 4], tet[(k + 3) % 4]};
      std::sort(key.begin(), key.end());
      faces.push_back({key, t});
    }
  }
  std::sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) {
    return a.key < b.key || (a.key == b.key && a.tet < b.tet);
  });
  for (size_t f = 1; f < faces.size(); ++f)
    if (faces[f].key == faces[f - 1].key) {
      const int a = find(faces[f].tet), b = find(faces[f - 1].tet);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  std::vector<int> piece(nt, -1), idOfRoot(nt, -1);
  count = 0;
  for (int t = 0; t < nt; ++t) {
    if (!mesh.isAlive(t)) continue;
    const int r = find(t);
    if (idOfRoot[r] < 0) idOfRoot[r] = count++;
    piece[t] = idOfRoot[r];
  }
  return piece;
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

struct StructuralPhase::Impl {
  std::vector<Tet> tets;            // copied from the mesh: the phase outlives no mesh
  std::vector<std::uint8_t> alive;  // per tet, 1 alive
  std::vector<TetGeometry> geo;
  Mat6 d;                      // elasticity (Voigt); stress = D (B_e u_e - eps*)
  std::vector<int> freeIndex;  // dof -> unknown, -1 when held
  double bulkModulusPa = 0;    // lambda + 2 mu / 3: D eps* = K_b e_v (1, 1, 1, 0, 0, 0)
  Cholesky factor;
  Eigen::VectorXd rhs, freeSolution, u;
  std::vector<VoigtStress> stress;
  std::vector<double> vonMisesPa;
  double factorSeconds = 0;
  int islands = 0;
  int numFree = 0;
};

StructuralPhase::StructuralPhase(const TetMesh& mesh, const StructuralOptions& options,
                                 const std::vector<Support>& supports)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  const double e = options.youngsModulusPa, nu = options.poissonRatio;
  ESIM_VERIFY(std::isfinite(e) && e > 0,
              "structural: youngsModulusPa must be > 0, got " + std::to_string(e));
  ESIM_VERIFY(std::isfinite(nu) && nu >= 0 && nu < 0.5,
              "structural: poissonRatio must be in [0, 0.5), got " + std::to_string(nu));
  const int n = mesh.numNodes();
  m.tets = mesh.tets;
  m.alive.resize(mesh.numTets());
  for (int t = 0; t < mesh.numTets(); ++t) m.alive[t] = mesh.isAlive(t) ? 1 : 0;
  m.geo = tetGeometry(mesh);
  m.d = elasticity(e, nu);
  m.bulkModulusPa = e / (3 * (1 - 2 * nu));

  // 1. unknowns: every component not held, of nodes that touch an alive tet
  std::vector<std::uint8_t> held(3 * static_cast<size_t>(n), 1);
  for (int t = 0; t < mesh.numTets(); ++t)
    if (mesh.isAlive(t))
      for (int node : mesh.tets[t])
        for (int a = 0; a < 3; ++a) held[3 * node + a] = 0;
  for (const Support& s : supports) {
    ESIM_VERIFY(s.node >= 0 && s.node < n && s.axis >= 0 && s.axis < 3,
                "structural: support (node " + std::to_string(s.node) + ", axis " +
                    std::to_string(s.axis) + ") is out of range (" + std::to_string(n) +
                    " nodes, axes 0..2)");
    held[3 * s.node + s.axis] = 1;
  }
  ESIM_VERIFY(supportsFixRigidMotions(mesh, supports),
              "structural: the supports leave the body free to translate or rotate; hold at "
              "least 6 independent displacement components (e.g. clamp a face)");
  // rigid pieces whose own supports leave a rigid motion free (cut loose, or hanging by an
  // edge or a node) are held in place, all their nodes
  int pieces = 0;
  const std::vector<int> pieceOfTet = alivePieces(mesh, pieces);
  if (pieces > 1) {
    std::vector<std::vector<int>> nodesOf(pieces);
    for (int t = 0; t < mesh.numTets(); ++t)
      if (pieceOfTet[t] >= 0)
        for (int v : mesh.tets[t]) nodesOf[pieceOfTet[t]].push_back(v);
    std::vector<std::uint8_t> inPiece(n, 0);
    for (int p = 0; p < pieces; ++p) {
      std::vector<int>& nodes = nodesOf[p];
      std::sort(nodes.begin(), nodes.end());
      nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
      for (int v : nodes) inPiece[v] = 1;
      std::vector<Support> own;
      for (const Support& s : supports)
        if (inPiece[s.node]) own.push_back(s);
      for (int v : nodes) inPiece[v] = 0;
      if (supportsFixRigidMotions(mesh, own)) continue;
      ++m.islands;
      for (int v : nodes)
        for (int a = 0; a < 3; ++a) held[3 * v + a] = 1;
    }
    ESIM_VERIFY(m.islands < pieces, "structural: no piece of the body is held by the supports");
  }
  m.freeIndex.assign(3 * static_cast<size_t>(n), -1);
  int nf = 0;
  for (size_t dof = 0; dof < held.size(); ++dof)
    if (!held[dof]) m.freeIndex[dof] = nf++;

  // 2. K over the unknowns (lower triangle)
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(mesh.numAlive()) * 78);
  for (int t = 0; t < mesh.numTets(); ++t) {
    if (!mesh.isAlive(t)) continue;
    const Mat6x12 b = strainMatrix(m.geo[t]);
    const Eigen::Matrix<double, 12, 12> ke = m.geo[t].volume * b.transpose() * (m.d * b);
    for (int i = 0; i < 12; ++i) {
      const int fi = m.freeIndex[3 * mesh.tets[t][i / 3] + i % 3];
      if (fi < 0) continue;
      for (int j = 0; j < 12; ++j) {
        const int fj = m.freeIndex[3 * mesh.tets[t][j / 3] + j % 3];
        if (fj >= 0 && fj <= fi) triplets.emplace_back(fi, fj, ke(i, j));
      }
    }
  }
  m.numFree = nf;
  SparseMatrix k(nf, nf);
  k.setFromTriplets(triplets.begin(), triplets.end());
  k.makeCompressed();

  // 3. factorization, once
  const auto t0 = std::chrono::steady_clock::now();
  openblas_set_num_threads(1);      // see StructuralOptions: BLAS threads only spin here
  if (nf > 0) m.factor.compute(k);  // nf == 0: everything held, nothing to solve
  m.factorSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ESIM_RUN_CHECK(nf == 0 || m.factor.info() == Eigen::Success,
                 "structural: the stiffness matrix is not positive definite (degenerate tets, or "
                 "supports that leave part of the body free)");
  m.u = Eigen::VectorXd::Zero(3 * n);
  m.stress.assign(mesh.numTets(), VoigtStress{});
  m.vonMisesPa.assign(mesh.numTets(), 0.0);
}

StructuralPhase::~StructuralPhase() = default;

void StructuralPhase::solve(const std::vector<double>& ev) {
  Impl& m = *impl_;
  const int nt = static_cast<int>(m.tets.size());
  ESIM_VERIFY(static_cast<int>(ev.size()) == nt, "structural: " + std::to_string(ev.size()) +
                                                     " eigenstrains for " + std::to_string(nt) +
                                                     " tets");
  // f = sum_e V_e B_e^T D eps*_e; D eps* = K_b e_v (1,1,1,0,0,0), so node i of the tet
  // gets V_e K_b e_v grad N_i
  m.rhs.setZero(m.numFree);
  for (int t = 0; t < nt; ++t) {
    if (!m.alive[t] || ev[t] == 0) continue;
    ESIM_VERIFY(std::isfinite(ev[t]),
                "structural: eigenstrain of tet " + std::to_string(t) + " is not finite");
    const double s = m.geo[t].volume * m.bulkModulusPa * ev[t];
    for (int i = 0; i < 4; ++i)
      for (int a = 0; a < 3; ++a) {
        const int fi = m.freeIndex[3 * m.tets[t][i] + a];
        if (fi >= 0) m.rhs(fi) += s * m.geo[t].grad(i, a);
      }
  }
  if (m.numFree > 0) {
    openblas_set_num_threads(1);
    m.freeSolution = m.factor.solve(m.rhs);
  }
  m.u.setZero();
  for (size_t dof = 0; dof < m.freeIndex.size(); ++dof)
    if (m.freeIndex[dof] >= 0)
      m.u(static_cast<Eigen::Index>(dof)) = m.freeSolution(m.freeIndex[dof]);
  // sigma = D B u_e - K_b e_v (1, 1, 1, 0, 0, 0)
  for (int t = 0; t < nt; ++t) {
    if (!m.alive[t]) {
      m.stress[t] = VoigtStress{};
      m.vonMisesPa[t] = 0;
      continue;
    }
    Eigen::Matrix<double, 12, 1> ue;
    for (int i = 0; i < 4; ++i) ue.segment<3>(3 * i) = m.u.segment<3>(3 * m.tets[t][i]);
    // B_e rebuilt from the stored gradients: keeping D B_e per tet would cost 576 bytes
    // a tet (92 MB for the liver's 161k tets, twice during a background rebuild)
    const Eigen::Matrix<double, 6, 1> s = m.d * (strainMatrix(m.geo[t]) * ue);
    const double p = m.bulkModulusPa * ev[t];
    m.stress[t] = {s(0) - p, s(1) - p, s(2) - p, s(3), s(4), s(5)};
    m.vonMisesPa[t] = vonMises(m.stress[t]);
  }
}

const Eigen::VectorXd& StructuralPhase::displacementM() const { return impl_->u; }
const std::vector<VoigtStress>& StructuralPhase::stressPa() const { return impl_->stress; }
const std::vector<double>& StructuralPhase::vonMisesPa() const { return impl_->vonMisesPa; }
int StructuralPhase::numFreeDofs() const { return impl_->numFree; }
double StructuralPhase::factorizationSeconds() const { return impl_->factorSeconds; }
int StructuralPhase::numFloatingIslands() const { return impl_->islands; }

}  // namespace esim
