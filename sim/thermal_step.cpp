// thermal_step.cpp - enthalpy heat equation, theta schemes, boiling, damage (see thermal_step.h).
#include "sim/thermal_step.h"

#include <Eigen/CholmodSupport>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "sim/core_error.h"

namespace esim {

namespace {

constexpr double kGasConstantJ_molK = 8.314462618;
constexpr double kKelvinOffset = 273.15;
constexpr double kCgMaxCondition = 4.0;  // Auto: CG when the Gershgorin bound is below this
constexpr double kCgRoundOff = 1e-13;    // CG stop floor, relative to max |T|
constexpr int kCgMaxIterations = 500;    // then Cholesky
constexpr double kPinCapacity = 1e8;     // boiling iteration: relative capacity of plateau nodes
constexpr int kPinIterations = 3;        // ... for this many iterations, then plain Chernoff
// removeTets modifies a Cholesky factor in place up to this rank (<= 4 per tet + orphans),
// else factors it again at the next step: measured break-even ~500 (8k and 50k nodes)
constexpr int kMaxFactorUpdateRank = 400;

using RowMatrix = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;
using CholeskyBase = Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower>;

// a rank-k modification A +- C C', C given by columns of (node, value) entries
using FactorColumns = std::vector<std::vector<std::pair<int, double>>>;

// CHOLMOD's supernodal Cholesky, whose factor can be modified in place (cholmod_updown):
// the factor of A becomes that of A + C C' (update) or A - C C' (downdate), at a cost
// set by the columns of L that C reaches, not by n. The first modification converts the
// factor to simplicial LDL' (O(nnz(L))); a modified factor is not refactored on its
// analysis (its pattern changed): a new Cholesky is analysed instead
class Cholesky : public CholeskyBase {
 public:
  void analyzePattern(const SparseMatrix& a) {
    inversePerm_.clear();
    CholeskyBase::analyzePattern(a);
  }
  // false if CHOLMOD refuses (the factor is then unusable)
  bool modify(bool update, const FactorColumns& columns) {
    if (columns.empty()) return true;
    cholmod_factor* factor = m_cholmodFactor;
    cholmod_common& common = cholmod();
    const int n = static_cast<int>(factor->n);
    if (factor->is_super || factor->is_ll) {
      if (!cholmod_change_factor(CHOLMOD_REAL, false, false, false, false, factor, &common))
        return false;
    }
    if (inversePerm_.empty()) {  // C's rows go in the factor's (fill-reducing) order
      const int* perm = static_cast<const int*>(factor->Perm);
      inversePerm_.resize(n);
      for (int k = 0; k < n; ++k) inversePerm_[perm ? perm[k] : k] = k;
    }
    size_t nnz = 0;
    for (const auto& col : columns) nnz += col.size();
    cholmod_sparse* c =
        cholmod_allocate_sparse(n, columns.size(), nnz, true, true, 0, CHOLMOD_REAL, &common);
    if (!c) return false;
    int* colStart = static_cast<int*>(c->p);
    int* rows = static_cast<int*>(c->i);
    double* values = static_cast<double*>(c->x);
    size_t at = 0;
    std::vector<std::pair<int, double>> sorted;
    for (size_t j = 0; j < columns.size(); ++j) {
      colStart[j] = static_cast<int>(at);
      sorted.clear();
      for (const auto& [node, value] : columns[j]) sorted.emplace_back(inversePerm_[node], value);
      std::sort(sorted.begin(), sorted.end());
      for (const auto& [row, value] : sorted) {
        rows[at] = row;
        values[at++] = value;
      }
    }
    colStart[columns.size()] = static_cast<int>(at);
    const int ok = cholmod_updown(update, c, factor, &common);
    cholmod_free_sparse(&c, &common);
    return ok && common.status == CHOLMOD_OK && factor->minor == factor->n;
  }

 private:
  std::vector<int> inversePerm_;  // node -> row of the permuted factor
};

std::string fmt(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

void requirePositive(double v, const char* key, const char* what) {
  ESIM_VERIFY(std::isfinite(v) && v > 0,
              std::string(key) + " = " + fmt(v) + ": must be > 0 and finite (" + what + ")");
}

// the element terms, written once so that removeTets recomputes bitwise what the build
// assembled (the same expressions as assembleStiffness / assembleMass / lumpedMass)
Eigen::Matrix4d elementStiffness(double coeff, double volume,
                                 const Eigen::Matrix<double, 4, 3>& grad) {
  return coeff * volume * grad * grad.transpose();
}
double elementLumpedMass(double volume) { return 1.0 * volume / 4.0; }
double elementMassEntry(double volume, bool diagonal) {
  const double m = 1.0 * volume / 20.0;
  return diagonal ? 2 * m : m;
}

// robin terms of a cooled face of area areaM2: load h T_amb A/3 per node [W]; coupling
// lumped h A/3 on the diagonal, consistent h A (1 + delta_ij)/12 [W/K]
double faceLoadW(double h, double ambientC, double areaM2) { return h * ambientC * areaM2 / 3.0; }
double faceCoupling(bool lumped, double h, double areaM2, int i, int j) {
  return lumped ? (i == j ? h * areaM2 / 3.0 : 0.0) : h * areaM2 * (i == j ? 2.0 : 1.0) / 12.0;
}

// local index (0..3 or 0..2) of node v in a tet or face, -1 if absent
template <class Nodes>
int localIndex(const Nodes& nodes, int v) {
  for (int a = 0; a < static_cast<int>(nodes.size()); ++a)
    if (nodes[a] == v) return a;
  return -1;
}

// position of entry (inner, outer) in a compressed sparse matrix's value array
template <class Matrix>
double& entryRef(Matrix& a, int outer, int inner) {
  const int* begin = a.innerIndexPtr() + a.outerIndexPtr()[outer];
  const int* end = a.innerIndexPtr() + a.outerIndexPtr()[outer + 1];
  const int* it = std::lower_bound(begin, end, inner);
  ESIM_CHECK(it != end && *it == inner);  // removeTets keeps the pattern
  return a.valuePtr()[it - a.innerIndexPtr()];
}

}  // namespace

// ---- names and validation ----

std::string explicitSubstepMessage(double dtS, double limitS, int maxSubsteps) {
  return "solvers.thermal.integrator: explicit needs " + fmt(std::ceil(dtS / limitS)) +
         " sub-steps per frame (frame step " + fmt(dtS) + " s, stability limit " + fmt(limitS) +
         " s of this mesh), above the limit of " + std::to_string(maxSubsteps) +
         " (solvers.thermal.max_substeps); use backward-euler or crank-nicolson, or a higher "
         "time.fps";
}

ThermalIntegrator parseThermalIntegrator(const std::string& name) {
  if (name == "explicit") return ThermalIntegrator::Explicit;
  if (name == "backward-euler") return ThermalIntegrator::BackwardEuler;
  if (name == "crank-nicolson") return ThermalIntegrator::CrankNicolson;
  if (name == "tr-bdf2") return ThermalIntegrator::TrBdf2;
  throw Error("unknown thermal integrator '" + name +
              "': expected one of explicit, backward-euler, crank-nicolson, tr-bdf2");
}

std::string thermalIntegratorName(ThermalIntegrator integrator) {
  switch (integrator) {
    case ThermalIntegrator::Explicit:
      return "explicit";
    case ThermalIntegrator::BackwardEuler:
      return "backward-euler";
    case ThermalIntegrator::CrankNicolson:
      return "crank-nicolson";
    case ThermalIntegrator::TrBdf2:
      return "tr-bdf2";
  }
  return "?";
}

void validateThermalParams(const ThermalParams& p) {
  // messages name the scenario keys (sim/io/scenario.h) the fields come from
  requirePositive(p.heatCapacityJ_m3K, "material.heat_capacity_j_per_m3k",
                  "volumetric heat capacity c*rho [J/(K m^3)]");
  requirePositive(p.conductivityW_mK, "material.thermal_conductivity_w_per_mk",
                  "thermal conductivity [W/(m K)]");
  ESIM_VERIFY(std::isfinite(p.initialTemperatureC) && p.initialTemperatureC > -kKelvinOffset,
              "material.initial_temperature_c = " + fmt(p.initialTemperatureC) +
                  ": must be finite and above absolute zero (-273.15 C)");
  ESIM_VERIFY(std::isfinite(p.waterFraction) && p.waterFraction >= 0 && p.waterFraction <= 1,
              "material.water_fraction = " + fmt(p.waterFraction) +
                  ": must be in [0, 1] (water mass fraction of the tissue)");
  if (p.boiling) {
    requirePositive(p.densityKg_m3, "material.density_kg_per_m3", "tissue density [kg/m^3]");
    ESIM_VERIFY(std::isfinite(p.latentHeatJ_kg) && p.latentHeatJ_kg >= 0,
                "material.latent_heat_j_per_kg = " + fmt(p.latentHeatJ_kg) +
                    ": must be >= 0 and finite (latent heat of vaporisation [J/kg])");
    ESIM_VERIFY(
        std::isfinite(p.boilingTemperatureC) && p.boilingTemperatureC > p.initialTemperatureC,
        "material.boiling_temperature_c = " + fmt(p.boilingTemperatureC) +
            ": must be finite and above material.initial_temperature_c = " +
            fmt(p.initialTemperatureC) + " C");
  }
  ESIM_VERIFY(
      std::isfinite(p.nonlinearToleranceK) && p.nonlinearToleranceK > 0,
      "ThermalParams::nonlinearToleranceK = " + fmt(p.nonlinearToleranceK) + ": must be > 0");
  ESIM_VERIFY(p.maxSubsteps >= 1,
              "solvers.thermal.max_substeps = " + std::to_string(p.maxSubsteps) + ": must be >= 1");
  ESIM_VERIFY(p.maxNonlinearIterations >= 1, "ThermalParams::maxNonlinearIterations = " +
                                                 std::to_string(p.maxNonlinearIterations) +
                                                 ": must be >= 1");
  ESIM_VERIFY(std::isfinite(p.convectionW_m2K) && p.convectionW_m2K >= 0,
              "effects.surface_cooling.h_w_per_m2k = " + fmt(p.convectionW_m2K) +
                  ": must be >= 0 and finite (heat transfer coefficient [W/(m^2 K)])");
  ESIM_VERIFY(std::isfinite(p.ambientTemperatureC) && p.ambientTemperatureC > -kKelvinOffset,
              "effects.surface_cooling.ambient_c = " + fmt(p.ambientTemperatureC) +
                  ": must be finite and above absolute zero");
  if (p.damage) {
    requirePositive(p.arrheniusA_s, "material.arrhenius_a_per_s", "frequency factor [1/s]");
    requirePositive(p.arrheniusEa_J_mol, "material.arrhenius_ea_j_per_mol",
                    "activation energy [J/mol]");
  }
}

// ---- operators, caches and workspace ----

struct ThermalPhase::Impl {
  Adjacency nodeTets;                // node -> tets, alive ones in [begin, nodeTetsEnd)
  std::vector<int> nodeTetsEnd;      // removeTets shrinks each node's range in place
  SparseMatrix stiffness;            // conduction + convection [W/K], column major
  RowMatrix stiffnessRows;           // the same, row major for products
  Eigen::VectorXd massM3;            // lumped mass (row sums) [m^3]; 0 on orphan nodes
  SparseMatrix massConsistent;       // consistent mass [m^3] (consistent mode only)
  std::vector<std::uint8_t> active;  // node has an alive tet
  Eigen::VectorXd stiffnessDiag;     // K_ii
  Eigen::VectorXd stiffnessAbsRow;   // sum_j |K_ij| (Gershgorin)
  Eigen::VectorXd convectionLoadW;   // h T_amb A/3 per node [W]
  Eigen::VectorXd convectionColSum;  // sum_i (K_h)_ij [W/K]: loss = colsum . T - sum(load)
  double convectionLoadTotalW = 0;
  bool convectionActive = false;
  std::vector<double> cooledAreaM2;              // per cooled face [m^2]
  Adjacency nodeCooled;                          // node -> cooled faces (all)
  std::vector<std::pair<int, int>> cooledByTet;  // (tet, cooled face), sorted
  int aliveCooled = 0;                           // cooled faces of alive tets

  // implicit system (c rho M/dt + theta K) T = b
  std::unique_ptr<Cholesky> factor;
  bool factorAnalyzed = false;
  bool factorModified = false;  // by removeTets: a new dt or theta analyses again
  double factorDt = -1, factorTheta = -1;
  double cgDecidedDt = -1, cgDecidedTheta = -1;
  bool useCg = false;
  std::string lastSolver = "none";
  // consistent mass factor (flux-form update, explicit)
  std::unique_ptr<Cholesky> massFactor;
  bool massFactorStale = false;  // removeTets could not modify it: factored again

  // explicit limit: the smaller of two bounds on lambda_max((c rho M)^-1 K) [1/s]
  std::vector<double> tetRate;  // element: lambda_max(K_e + cooled faces, c rho M_e)
  std::vector<int> tetsByRate;  // the alive tets of the build, fastest first
  size_t fastest = 0;           // first alive tet in tetsByRate
  std::vector<double> rowRate;  // gershgorin per node, a max-tree: leaves from rowLeaf
  int rowLeaf = 0;
  double stableDt = 0;      // 2 / the smaller bound [s]
  bool ratesBuilt = false;  // at build for the explicit integrator, else on first use
  // node i's gershgorin rate into the max-tree (the leaf only when !propagate)
  void setRowRate(int i, double crho, bool lumped, bool propagate);
  // skips removed tets at the head of tetsByRate; stableDt from both bounds
  void updateExplicitLimit(const std::vector<std::uint8_t>& alive);

  // alive tets of node i
  const int* tetsBegin(int i) const { return nodeTets.begin(i); }
  const int* tetsEnd(int i) const { return nodeTets.ids.data() + nodeTetsEnd[i]; }
  // factors the consistent mass (+1 on orphan diagonals)
  void factorMass();
  // y = M^-1 x (lumped or consistent) on the active nodes, 0 on the orphan nodes
  void solveMass(bool lumped, const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
  // state's sensible and latent heat from its enthalpy and vapour fraction
  void storeEnergySplit(double lvJ_m3, ThermalState& s) const;

  struct Stepper;  // one call of step(), in parts (see "the step")

  // workspace
  Eigen::VectorXd load, flux, rhs, g, tempNew, kTemp, tempOld, enthalpy0, work, cgR, cgZ, cgP, cgAp,
      cgKp, diagS, diagPrec;
  Eigen::VectorXd stageEnthalpyN, stageTempN, stageTempG;  // tr-bdf2's H_n, T_n, T_g
};

ThermalPhase::ThermalPhase(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                           const ThermalParams& params,
                           const std::vector<BoundaryFace>& cooledFaces)
    : params_(params), cooledFaces_(cooledFaces), impl_(std::make_unique<Impl>()) {
  validateThermalParams(params_);
  buildOperators(mesh, geo);
}

ThermalPhase::~ThermalPhase() = default;
ThermalPhase::ThermalPhase(ThermalPhase&&) noexcept = default;
ThermalPhase& ThermalPhase::operator=(ThermalPhase&&) noexcept = default;

void ThermalPhase::buildOperators(const TetMesh& mesh, const std::vector<TetGeometry>& geo) {
  ESIM_VERIFY(mesh.numNodes() > 0 && mesh.numTets() > 0, "thermal: the mesh is empty");
  ESIM_VERIFY(geo.size() == mesh.tets.size(),
              "thermal: tet geometry has " + std::to_string(geo.size()) +
                  " entries, the mesh has " + std::to_string(mesh.numTets()) + " tets");
  numNodes_ = mesh.numNodes();
  tets_ = mesh.tets;
  alive_.assign(mesh.tets.size(), 1);
  volumeM3_.assign(mesh.tets.size(), 0.0);
  gradM_.resize(mesh.tets.size());
  for (int e = 0; e < mesh.numTets(); ++e) {
    alive_[e] = mesh.isAlive(e) ? 1 : 0;
    volumeM3_[e] = geo[e].volume;
    gradM_[e] = geo[e].grad;
  }
  Impl& m = *impl_;
  const int n = numNodes_;

  // conduction
  const std::vector<double> lambda(mesh.tets.size(), params_.conductivityW_mK);
  m.stiffness = assembleStiffness(mesh, geo, lambda);
  const std::vector<double> ones(mesh.tets.size(), 1.0);
  m.massM3 = lumpedMass(mesh, geo, ones);
  m.nodeTets = esim::nodeTets(mesh);
  m.nodeTetsEnd.assign(m.nodeTets.offsets.begin() + 1, m.nodeTets.offsets.end());
  m.active.assign(n, 0);
  for (int i = 0; i < n; ++i) m.active[i] = m.massM3[i] > 0 ? 1 : 0;

  // convection on the cooled faces of alive tets (a Robin condition)
  m.convectionLoadW = Eigen::VectorXd::Zero(n);
  m.convectionColSum = Eigen::VectorXd::Zero(n);
  m.convectionLoadTotalW = 0;
  m.convectionActive = false;
  m.cooledAreaM2.assign(cooledFaces_.size(), 0.0);
  m.cooledByTet.clear();
  m.aliveCooled = 0;
  std::vector<std::pair<int, int>> nodeFace;
  if (params_.convectionW_m2K > 0) {
    std::vector<Eigen::Triplet<double>> trip;
    const double h = params_.convectionW_m2K;
    for (const BoundaryFace& f : cooledFaces_) {
      ESIM_VERIFY(f.tet >= 0 && f.tet < mesh.numTets(), "thermal: cooled face names tet " +
                                                            std::to_string(f.tet) + " of " +
                                                            std::to_string(mesh.numTets()));
      for (int v : f.nodes)
        ESIM_VERIFY(v >= 0 && v < n, "thermal: cooled face node " + std::to_string(v) +
                                         " out of range (" + std::to_string(n) + " nodes)");
      const Vec3& a = mesh.nodes[f.nodes[0]];
      const Vec3& b = mesh.nodes[f.nodes[1]];
      const Vec3& c = mesh.nodes[f.nodes[2]];
      const double areaM2 = 0.5 * (b - a).cross(c - a).norm();
      const int face = static_cast<int>(&f - cooledFaces_.data());
      m.cooledAreaM2[face] = areaM2;
      for (int v : f.nodes) nodeFace.emplace_back(v, face);
      m.cooledByTet.emplace_back(f.tet, face);
      if (!mesh.isAlive(f.tet)) continue;
      for (int i = 0; i < 3; ++i) {
        m.convectionLoadW[f.nodes[i]] += faceLoadW(h, params_.ambientTemperatureC, areaM2);
        for (int j = 0; j < 3; ++j) {
          const double kij = faceCoupling(params_.lumpedMass, h, areaM2, i, j);
          if (kij != 0) trip.emplace_back(f.nodes[i], f.nodes[j], kij);
          m.convectionColSum[f.nodes[j]] += kij;
        }
      }
      m.convectionActive = true;
      ++m.aliveCooled;
    }
    SparseMatrix kh(n, n);
    kh.setFromTriplets(trip.begin(), trip.end());
    m.stiffness += kh;
    m.convectionLoadTotalW = m.convectionLoadW.sum();
  }
  std::sort(m.cooledByTet.begin(), m.cooledByTet.end());
  // node -> cooled faces, ascending (the order in which the build summed them)
  std::sort(nodeFace.begin(), nodeFace.end());
  m.nodeCooled.offsets.assign(n + 1, 0);
  m.nodeCooled.ids.clear();
  for (const auto& [v, face] : nodeFace) {
    ++m.nodeCooled.offsets[v + 1];
    m.nodeCooled.ids.push_back(face);
  }
  for (int i = 0; i < n; ++i) m.nodeCooled.offsets[i + 1] += m.nodeCooled.offsets[i];
  m.stiffness.makeCompressed();
  m.stiffnessRows = m.stiffness;
  m.stiffnessDiag = m.stiffness.diagonal();
  m.stiffnessAbsRow = Eigen::VectorXd::Zero(n);
  for (int r = 0; r < m.stiffnessRows.outerSize(); ++r)
    for (RowMatrix::InnerIterator it(m.stiffnessRows, r); it; ++it)
      m.stiffnessAbsRow[r] += std::abs(it.value());

  // consistent mass (+ identity on orphan nodes so that it stays invertible)
  m.massFactor.reset();
  m.massFactorStale = false;
  if (!params_.lumpedMass) {
    m.massConsistent = assembleMass(mesh, geo, ones);
    m.massConsistent.makeCompressed();
    m.factorMass();
  }

  // drop every cache that depends on the operators
  m.factor.reset();
  m.factorAnalyzed = false;
  m.factorModified = false;
  m.factorDt = m.factorTheta = -1;
  m.cgDecidedDt = m.cgDecidedTheta = -1;
  m.ratesBuilt = false;
  if (params_.integrator == ThermalIntegrator::Explicit) elementRates();
  for (Eigen::VectorXd* v :
       {&m.load, &m.flux, &m.rhs, &m.g, &m.tempNew, &m.kTemp, &m.tempOld, &m.enthalpy0, &m.work,
        &m.cgR, &m.cgZ, &m.cgP, &m.cgAp, &m.cgKp, &m.diagS, &m.diagPrec})
    v->setZero(n);
}

void ThermalPhase::rebuild(const TetMesh& mesh, const std::vector<TetGeometry>& geo) {
  ESIM_VERIFY(mesh.numNodes() == numNodes_ && mesh.numTets() == numTets(),
              "thermal rebuild: the mesh has " + std::to_string(mesh.numNodes()) + " nodes and " +
                  std::to_string(mesh.numTets()) + " tets, the thermal phase " +
                  std::to_string(numNodes_) + " and " + std::to_string(numTets()) +
                  " (rebuild expects removed tets, not a renumbered mesh)");
  buildOperators(mesh, geo);
}

// ---- topology change in place ----

ThermalPhase::RemovalStats ThermalPhase::removeTets(const std::vector<int>& tets) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& m = *impl_;
  RemovalStats stats;
  // checked before anything changes
  for (int e : tets)
    ESIM_VERIFY(e >= 0 && e < numTets(), "thermal removeTets: tet " + std::to_string(e) +
                                             " out of range (" + std::to_string(numTets()) +
                                             " tets)");
  std::vector<int> removed;
  for (int e : tets)
    if (alive_[e]) removed.push_back(e);
  std::sort(removed.begin(), removed.end());
  removed.erase(std::unique(removed.begin(), removed.end()), removed.end());
  stats.removedTets = static_cast<int>(removed.size());
  if (removed.empty()) {
    stats.ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return stats;
  }

  // alive flags and node -> alive tets (each node's range shrinks, staying sorted)
  std::vector<int> nodes;
  for (int e : removed) {
    alive_[e] = 0;
    for (int v : tets_[e]) {
      int* begin = m.nodeTets.ids.data() + m.nodeTets.offsets[v];
      int* end = m.nodeTets.ids.data() + m.nodeTetsEnd[v];
      int* last = std::remove(begin, end, e);
      m.nodeTetsEnd[v] = static_cast<int>(last - m.nodeTets.ids.data());
      nodes.push_back(v);
    }
  }
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());

  // lumped mass of the touched nodes, summed over their alive tets in tet order (as built)
  std::vector<int> orphans;  // by this call
  for (int v : nodes) {
    double mass = 0;
    for (const int* e = m.tetsBegin(v); e != m.tetsEnd(v); ++e)
      mass += elementLumpedMass(volumeM3_[*e]);
    m.massM3[v] = mass;
    const std::uint8_t active = mass > 0 ? 1 : 0;
    if (m.active[v] && !active) orphans.push_back(v);
    m.active[v] = active;
  }

  // cooled faces of the removed tets: their nodes' robin terms are summed again
  std::vector<int> faceNodes;
  for (int e : removed) {
    auto it = std::lower_bound(m.cooledByTet.begin(), m.cooledByTet.end(), std::make_pair(e, -1));
    for (; it != m.cooledByTet.end() && it->first == e; ++it) {
      ++stats.droppedCooledFaces;
      --m.aliveCooled;
      for (int v : cooledFaces_[it->second].nodes) faceNodes.push_back(v);
    }
  }
  if (!faceNodes.empty()) {
    std::sort(faceNodes.begin(), faceNodes.end());
    faceNodes.erase(std::unique(faceNodes.begin(), faceNodes.end()), faceNodes.end());
    recomputeConvection(faceNodes);
  }

  // conduction (+ robin) and consistent mass entries among the removed tets' nodes
  stats.editedEntries = recomputeEntries(removed);

  stats.orphanedNodes = static_cast<int>(orphans.size());

  // the factors: modified in place (or, if CHOLMOD refuses, factored again at next use)
  modifyFactors(removed, orphans, stats);
  if (m.ratesBuilt) {
    const double limitBefore = m.stableDt;
    for (int v : nodes) m.setRowRate(v, params_.heatCapacityJ_m3K, params_.lumpedMass, true);
    m.updateExplicitLimit(alive_);
    stats.explicitLimitChanged = m.stableDt != limitBefore;
  }
  stats.solverChoiceDropped = m.cgDecidedDt > 0;
  m.cgDecidedDt = m.cgDecidedTheta = -1;
  stats.ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return stats;
}

// the cholesky factors follow the removal in place: A loses sum_e dA_e, each a PSD 4 x 4
// (its tet's conduction and cooled faces times theta, its mass times c rho / dt for the
// implicit matrix; its consistent mass for the mass matrix), split into <= 4 columns by
// its eigenvectors (downdate), after new orphan nodes get their 1 (update: A stays
// positive definite throughout)
void ThermalPhase::modifyFactors(const std::vector<int>& removed, const std::vector<int>& orphans,
                                 RemovalStats& stats) {
  Impl& m = *impl_;
  // a large batch: factored again at the next step (the analysis too: as a fresh build)
  if (4 * removed.size() + orphans.size() > static_cast<size_t>(kMaxFactorUpdateRank)) {
    if (m.factor && m.factorDt > 0) {
      m.factor.reset();
      m.factorAnalyzed = false;
      m.factorModified = false;
      m.factorDt = m.factorTheta = -1;
      stats.factorDropped = true;
    }
    if (!params_.lumpedMass) {
      m.massFactorStale = true;
      stats.massFactorDropped = true;
    }
    return;
  }
  const double lambda = params_.conductivityW_mK, h = params_.convectionW_m2K;
  FactorColumns unit;
  for (int v : orphans) unit.push_back({{v, 1.0}});
  // columns of the PSD delta on tet t: sqrt(mu_k) v_k
  auto addColumns = [](const Tet& t, const Eigen::Matrix4d& delta, FactorColumns& out) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(delta);
    const double top = eig.eigenvalues().maxCoeff();
    for (int k = 0; k < 4; ++k) {
      const double mu = eig.eigenvalues()[k];
      if (!(mu > 1e-15 * top)) continue;  // the conduction's constant mode, round-off
      std::vector<std::pair<int, double>> col;
      for (int a = 0; a < 4; ++a) col.emplace_back(t[a], std::sqrt(mu) * eig.eigenvectors()(a, k));
      out.push_back(std::move(col));
    }
  };
  auto consistentMass = [](double volume) {
    Eigen::Matrix4d me;
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) me(a, b) = elementMassEntry(volume, a == b);
    return me;
  };
  // implicit matrix c rho M / dt + theta K, factored for (factorDt, factorTheta)
  if (m.factor && m.factorDt > 0) {
    const double capacity = params_.heatCapacityJ_m3K / m.factorDt, theta = m.factorTheta;
    FactorColumns down;
    for (int e : removed) {
      Eigen::Matrix4d delta = theta * elementStiffness(lambda, volumeM3_[e], gradM_[e]);
      auto it = std::lower_bound(m.cooledByTet.begin(), m.cooledByTet.end(), std::make_pair(e, -1));
      for (; it != m.cooledByTet.end() && it->first == e; ++it) {
        const BoundaryFace& f = cooledFaces_[it->second];
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            delta(localIndex(tets_[e], f.nodes[i]), localIndex(tets_[e], f.nodes[j])) +=
                theta * faceCoupling(params_.lumpedMass, h, m.cooledAreaM2[it->second], i, j);
      }
      if (params_.lumpedMass)
        delta.diagonal().array() += capacity * elementLumpedMass(volumeM3_[e]);
      else
        delta += capacity * consistentMass(volumeM3_[e]);
      addColumns(tets_[e], delta, down);
    }
    stats.factorRank = static_cast<int>(down.size() + unit.size());
    if (m.factor->modify(true, unit) && m.factor->modify(false, down)) {
      stats.factorUpdated = true;
      m.factorModified = true;
    } else {  // analysed and factored again at the next step
      m.factor.reset();
      m.factorAnalyzed = false;
      m.factorModified = false;
      m.factorDt = m.factorTheta = -1;
      stats.factorDropped = true;
    }
  }
  // consistent mass (+1 on orphans)
  if (!params_.lumpedMass && m.massFactor && !m.massFactorStale) {
    FactorColumns down;
    for (int e : removed) addColumns(tets_[e], consistentMass(volumeM3_[e]), down);
    if (m.massFactor->modify(true, unit) && m.massFactor->modify(false, down)) {
      stats.massFactorUpdated = true;
    } else {
      m.massFactorStale = true;
      stats.massFactorDropped = true;
    }
  }
}

// convective load and column sums of `nodes` from their alive cooled faces, in face order
// (as built); the total load and the active flag follow
void ThermalPhase::recomputeConvection(const std::vector<int>& nodes) {
  Impl& m = *impl_;
  const double h = params_.convectionW_m2K;
  for (int v : nodes) {
    double load = 0, colSum = 0;
    for (const int* f = m.nodeCooled.begin(v); f != m.nodeCooled.end(v); ++f) {
      const BoundaryFace& face = cooledFaces_[*f];
      if (!alive_[face.tet]) continue;
      const double areaM2 = m.cooledAreaM2[*f];
      load += faceLoadW(h, params_.ambientTemperatureC, areaM2);
      const int j = localIndex(face.nodes, v);
      for (int i = 0; i < 3; ++i) colSum += faceCoupling(params_.lumpedMass, h, areaM2, i, j);
    }
    m.convectionLoadW[v] = load;
    m.convectionColSum[v] = colSum;
  }
  m.convectionLoadTotalW = m.convectionLoadW.sum();  // O(n), as built (same summation order)
  m.convectionActive = m.aliveCooled > 0;
}

// every entry (i, j) with i, j nodes of a removed tet is summed again over the alive tets
// holding both (tet order) plus the alive cooled faces holding both (face order): the
// values a fresh assembly gives, bitwise; entries no alive tet holds become exact zeros.
// then the diagonal and the gershgorin row sums of the touched rows. returns the count
int ThermalPhase::recomputeEntries(const std::vector<int>& removed) {
  Impl& m = *impl_;
  std::vector<std::pair<int, int>> entries;
  for (int e : removed)
    for (int a : tets_[e])
      for (int b : tets_[e]) entries.emplace_back(a, b);
  std::sort(entries.begin(), entries.end());
  entries.erase(std::unique(entries.begin(), entries.end()), entries.end());
  const double lambda = params_.conductivityW_mK;
  const double h = params_.convectionW_m2K;
  for (const auto& [i, j] : entries) {
    double conduction = 0, mass = 0;
    bool any = false;
    for (const int* it = m.tetsBegin(i); it != m.tetsEnd(i); ++it) {
      const Tet& t = tets_[*it];
      const int b = localIndex(t, j);
      if (b < 0) continue;
      const int a = localIndex(t, i);
      const double ke = elementStiffness(lambda, volumeM3_[*it], gradM_[*it])(a, b);
      const double me = elementMassEntry(volumeM3_[*it], i == j);
      conduction = any ? conduction + ke : ke;
      mass = any ? mass + me : me;
      any = true;
    }
    if (h > 0) {
      double robin = 0;
      bool anyFace = false;
      for (const int* f = m.nodeCooled.begin(i); f != m.nodeCooled.end(i); ++f) {
        const BoundaryFace& face = cooledFaces_[*f];
        const int b = localIndex(face.nodes, j);
        if (b < 0 || !alive_[face.tet]) continue;
        const double kij =
            faceCoupling(params_.lumpedMass, h, m.cooledAreaM2[*f], localIndex(face.nodes, i), b);
        if (kij == 0) continue;
        robin = anyFace ? robin + kij : kij;
        anyFace = true;
      }
      if (anyFace) conduction = conduction + robin;
    }
    entryRef(m.stiffness, j, i) = conduction;
    entryRef(m.stiffnessRows, i, j) = conduction;
    if (!params_.lumpedMass) entryRef(m.massConsistent, j, i) = mass;
  }
  // touched rows: diagonal and sum_j |K_ij| in row order (the zeros add nothing)
  int lastRow = -1;
  for (const auto& [i, j] : entries) {
    if (i == lastRow) continue;
    lastRow = i;
    m.stiffnessDiag[i] = entryRef(m.stiffnessRows, i, i);
    double absRow = 0;
    for (RowMatrix::InnerIterator it(m.stiffnessRows, i); it; ++it) absRow += std::abs(it.value());
    m.stiffnessAbsRow[i] = absRow;
  }
  return static_cast<int>(entries.size());
}

void ThermalPhase::Impl::factorMass() {
  SparseMatrix regular = massConsistent;
  for (int i = 0; i < static_cast<int>(active.size()); ++i)
    if (!active[i]) regular.coeffRef(i, i) = 1.0;
  massFactor = std::make_unique<Cholesky>();
  massFactor->analyzePattern(regular);
  massFactor->factorize(regular);
  ESIM_RUN_CHECK(massFactor->info() == Eigen::Success,
                 "thermal: the consistent mass matrix could not be factored");
  massFactorStale = false;
}

void ThermalPhase::Impl::solveMass(bool lumped, const Eigen::VectorXd& x,
                                   Eigen::VectorXd& y) const {
  const int n = static_cast<int>(massM3.size());
  if (lumped) {
    y.resize(n);
    for (int i = 0; i < n; ++i) y[i] = active[i] ? x[i] / massM3[i] : 0.0;
  } else {
    y = massFactor->solve(x);
    for (int i = 0; i < n; ++i)
      if (!active[i]) y[i] = 0.0;
  }
}

// energy bookkeeping: stored heat sum_i m_i H_i, of which latent sum_i m_i Lv vapour_i
// (Lv = lvJ_m3 [J/m^3]); the rest is sensible. both relative to the initial state
void ThermalPhase::Impl::storeEnergySplit(double lvJ_m3, ThermalState& s) const {
  const int n = static_cast<int>(massM3.size());
  double latent = 0, total = 0;
  for (int i = 0; i < n; ++i) {
    total += massM3[i] * s.enthalpyJ_m3[i];
    latent += massM3[i] * lvJ_m3 * s.vaporFraction[i];
  }
  s.latentJ = latent;
  s.sensibleJ = total - latent;
}

// ---- T(H) ----

namespace {

// the T(H) relation and the vapour fraction, with the constants precomputed
struct Derived {
  double crho, t0, tb, hb, lv;
  bool boiling;
  double temperature(double h) const {
    if (!boiling || h <= hb) return t0 + h / crho;
    if (h <= hb + lv) return tb;
    return tb + (h - hb - lv) / crho;
  }
  double vapor(double h) const {
    if (!boiling) return 0.0;
    if (lv <= 0) return h > hb ? 1.0 : 0.0;
    return std::clamp((h - hb) / lv, 0.0, 1.0);
  }
};

Derived derivedOf(const ThermalParams& p) {
  Derived d;
  d.crho = p.heatCapacityJ_m3K;
  d.t0 = p.initialTemperatureC;
  d.tb = p.boilingTemperatureC;
  d.hb = d.crho * (d.tb - d.t0);
  d.lv = p.waterFraction * p.densityKg_m3 * p.latentHeatJ_kg;
  d.boiling = p.boiling;
  return d;
}

}  // namespace

double ThermalPhase::temperatureOfEnthalpy(double h) const {
  return derivedOf(params_).temperature(h);
}

void ThermalPhase::initState(ThermalState& s) const {
  const int n = numNodes_;
  const size_t nt = tets_.size();
  s.temperatureC = Eigen::VectorXd::Constant(n, params_.initialTemperatureC);
  s.enthalpyJ_m3 = Eigen::VectorXd::Zero(n);
  s.vaporFraction = Eigen::VectorXd::Zero(n);
  s.vaporFractionTet.assign(nt, 0.0);
  s.damageOmega.assign(nt, 0.0);
  s.coagulationTet.assign(nt, 0.0);
  s.desiccatedTet.assign(nt, 0);
  s.timeS = 0;
  s.sensibleJ = s.latentJ = s.sourceJ = s.convectedJ = 0;
}

void ThermalPhase::setTemperature(ThermalState& s, const Eigen::VectorXd& temperatureC) const {
  ESIM_VERIFY(temperatureC.size() == numNodes_,
              "thermal setTemperature: " + std::to_string(temperatureC.size()) + " values for " +
                  std::to_string(numNodes_) + " nodes");
  if (s.enthalpyJ_m3.size() != numNodes_) initState(s);
  const Derived d = derivedOf(params_);
  for (int i = 0; i < numNodes_; ++i) {
    const double t = temperatureC[i];
    ESIM_VERIFY(std::isfinite(t) && t > -kKelvinOffset,
                "thermal setTemperature: node " + std::to_string(i) + " temperature " + fmt(t) +
                    " C is not a finite temperature above absolute zero");
    double h = d.crho * (t - d.t0);
    if (d.boiling && t > d.tb) h += d.lv;  // above boiling: dry
    s.enthalpyJ_m3[i] = h;
    s.temperatureC[i] = temperatureOfEnthalpy(h);
    s.vaporFraction[i] = d.vapor(h);
  }
  impl_->storeEnergySplit(d.lv, s);  // of the imposed field
  // per tet (the step updates these only around nodes whose vapour changes)
  const Eigen::VectorXd& vf = s.vaporFraction;
  for (size_t e = 0; e < tets_.size(); ++e) {
    const Tet& t = tets_[e];
    s.vaporFractionTet[e] = 0.25 * (vf[t[0]] + vf[t[1]] + vf[t[2]] + vf[t[3]]);
    if (alive_[e] && vf[t[0]] >= 1 && vf[t[1]] >= 1 && vf[t[2]] >= 1 && vf[t[3]] >= 1)
      s.desiccatedTet[e] = 1;
  }
}

double ThermalPhase::storedEnergyJ(const ThermalState& s) const {
  ESIM_VERIFY(s.enthalpyJ_m3.size() == numNodes_,
              "thermal storedEnergyJ: state has " + std::to_string(s.enthalpyJ_m3.size()) +
                  " nodes, the phase " + std::to_string(numNodes_));
  return impl_->massM3.dot(s.enthalpyJ_m3);
}

std::string ThermalPhase::lastSolverName() const { return impl_->lastSolver; }

// ---- explicit stability limit: element and gershgorin bounds ----
//
// element: x' K x = sum_e x_e' K_e x_e <= max_e rate_e sum_e x_e' c rho M_e x_e
// = max_e rate_e x' c rho M x (K_e with the robin terms of its cooled faces; M_e lumped or
// consistent), so lambda_max((c rho M)^-1 K) <= max_e rate_e. Without faces K_e 1 = 0 and
// c rho M_e = c rho V/4 I (lumped) or c rho V/20 I on 1-perp (consistent): rate_e = (4 or
// 20) lambda mu_e / c rho, mu_e = lambda_max(G' G) of the basis gradients G (3 x 3, closed
// form). Removing tets only drops terms of the max: a sorted list, O(1) to keep.
// gershgorin: lambda_max((c rho M_L)^-1 K) <= max_i sum_j |K_ij| / (c rho m_i), and
// M_c >= M_L / 5 (per element: V/20 (I + 1 1') >= V/20 I), so 5 times that for the
// consistent mass. Better than the element bound where a node's mass comes from many tets
// (slivers, graded zones); a max-tree over the nodes, O(log n) per touched node.
// dt <= 2 / min(both) is stable, with no margin.

double ThermalPhase::stableExplicitDtS() const {
  if (!impl_->ratesBuilt) elementRates();
  return impl_->stableDt;
}

void ThermalPhase::elementRates() const {
  Impl& m = *impl_;
  const double crho = params_.heatCapacityJ_m3K, lambda = params_.conductivityW_mK;
  const double massShare = params_.lumpedMass ? 4.0 : 20.0;  // V / (that) per node
  m.tetRate.assign(tets_.size(), 0.0);
  m.tetsByRate.clear();
  for (int e = 0; e < numTets(); ++e) {
    if (!alive_[e]) continue;
    const Eigen::Matrix3d gtg = gradM_[e].transpose() * gradM_[e];
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(gtg, Eigen::EigenvaluesOnly);
    m.tetRate[e] = massShare * lambda * eig.eigenvalues().maxCoeff() / crho;
    m.tetsByRate.push_back(e);
  }
  // tets with cooled faces: the 4 x 4 generalized problem with the robin terms
  const double h = params_.convectionW_m2K;
  for (size_t k = 0; h > 0 && k < m.cooledByTet.size();) {
    const int e = m.cooledByTet[k].first;
    const double volume = volumeM3_[e];
    Eigen::Matrix4d ke = elementStiffness(lambda, volume, gradM_[e]);
    for (; k < m.cooledByTet.size() && m.cooledByTet[k].first == e; ++k) {
      const BoundaryFace& f = cooledFaces_[m.cooledByTet[k].second];
      const double areaM2 = m.cooledAreaM2[m.cooledByTet[k].second];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          ke(localIndex(tets_[e], f.nodes[i]), localIndex(tets_[e], f.nodes[j])) +=
              faceCoupling(params_.lumpedMass, h, areaM2, i, j);
    }
    if (!alive_[e]) continue;
    Eigen::Matrix4d me = Eigen::Matrix4d::Identity() * (crho * volume / 4.0);
    if (!params_.lumpedMass)
      me = (crho * volume / 20.0) * (Eigen::Matrix4d::Ones() + Eigen::Matrix4d::Identity());
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::Matrix4d> eig(ke, me, Eigen::EigenvaluesOnly);
    m.tetRate[e] = std::max(m.tetRate[e], eig.eigenvalues().maxCoeff());
  }
  std::sort(m.tetsByRate.begin(), m.tetsByRate.end(), [&](int a, int b) {
    return m.tetRate[a] != m.tetRate[b] ? m.tetRate[a] > m.tetRate[b] : a < b;
  });
  m.fastest = 0;
  // gershgorin rates of every node, then the inner levels of the max-tree
  m.rowLeaf = 1;
  while (m.rowLeaf < numNodes_) m.rowLeaf *= 2;
  m.rowRate.assign(2 * static_cast<size_t>(m.rowLeaf), 0.0);
  for (int i = 0; i < numNodes_; ++i) m.setRowRate(i, crho, params_.lumpedMass, false);
  for (int k = m.rowLeaf - 1; k >= 1; --k)
    m.rowRate[k] = std::max(m.rowRate[2 * k], m.rowRate[2 * k + 1]);
  m.updateExplicitLimit(alive_);
  m.ratesBuilt = true;
}

void ThermalPhase::Impl::setRowRate(int i, double crho, bool lumped, bool propagate) {
  const double rate =
      active[i] ? (lumped ? 1.0 : 5.0) * stiffnessAbsRow[i] / (crho * massM3[i]) : 0.0;
  size_t k = static_cast<size_t>(rowLeaf) + i;
  rowRate[k] = rate;
  if (!propagate) return;
  for (k /= 2; k >= 1; k /= 2) rowRate[k] = std::max(rowRate[2 * k], rowRate[2 * k + 1]);
}

void ThermalPhase::Impl::updateExplicitLimit(const std::vector<std::uint8_t>& alive) {
  while (fastest < tetsByRate.size() && !alive[tetsByRate[fastest]]) ++fastest;
  const double element = fastest < tetsByRate.size() ? tetRate[tetsByRate[fastest]] : 0.0;
  const double rate = std::min(element, rowRate[1]);
  stableDt = rate > 0 ? 2.0 / rate : std::numeric_limits<double>::infinity();
}

// ---- the step ----
//
// step() in parts; they share one call's context through a Stepper (below):
//   assembleSource       nodal load F from the per-tet source
//   uniformEnthalpy      skip test: at rest nothing changes but time and damage
//   explicitSubsteps     theta = 0: H += h M^-1 (F - K T), sub-stepped below the limit
//   trBdf2Step           two implicitStage()s on one matrix (below)
//   implicitStep         theta = 1/2, 1:
//     chooseLinearSolver   cg or cholmod for this (dt, theta)
//     thetaLoad            G = F - (1 - theta) K T0, fixed over the step
//     boilingPredictor     explicit first guess of H (boiling, lumped mass)
//     chernoffIteration    chernoffRhs, solveLinear (solveCg or solveDirect), fluxUpdate,
//                          until T(H) settles
//   accumulateDamage     arrhenius integral over each (sub)step
//   updateVapor, Impl::storeEnergySplit, markDesiccated: the derived fields

namespace {

// theta of the theta scheme: 0 explicit, 1/2 crank-nicolson, 1 backward euler (and each of
// tr-bdf2's stages, written as backward euler steps)
double thetaOf(ThermalIntegrator integrator) {
  switch (integrator) {
    case ThermalIntegrator::Explicit:
      return 0.0;
    case ThermalIntegrator::BackwardEuler:
    case ThermalIntegrator::TrBdf2:
      return 1.0;
    case ThermalIntegrator::CrankNicolson:
      return 0.5;
  }
  return 0.0;
}

}  // namespace

// one call of step(): the phase's operators and mesh data, the caller's state, the stats
struct ThermalPhase::Impl::Stepper {
  Impl& m;
  const ThermalParams& p;
  const Derived d;
  const std::vector<Tet>& tets;
  const std::vector<std::uint8_t>& alive;
  const std::vector<double>& volumeM3;
  const int n;
  double dtS;    // the step of the linear system: the frame's, or tr-bdf2's stage step h
  double theta;  // of the theta scheme (1 in tr-bdf2's stages)
  ThermalState& s;
  StepStats stats{};
  double sourcePowerW = 0;  // set by assembleSource [W]
  bool anySource = false;   // ... some alive tet has a nonzero source

  void assembleSource(const std::vector<double>& sourceW_m3);
  void updateTemperature();
  bool uniformEnthalpy() const;
  void accumulateDamage(double h, const Eigen::VectorXd& t0, const Eigen::VectorXd& t1);
  double convectedPowerW(const Eigen::VectorXd& t) const;

  void explicitSubsteps(double limitS);

  void implicitStep();
  void trBdf2Step();
  void implicitStage();
  void chooseLinearSolver();
  void setChernoffDiagonal();
  bool solveCg(const Eigen::VectorXd& b, Eigen::VectorXd& x, Eigen::VectorXd& kx, double errorK);
  void solveDirect(const Eigen::VectorXd& b, Eigen::VectorXd& x, Eigen::VectorXd& kx);
  void solveLinear(const Eigen::VectorXd& b, Eigen::VectorXd& x, Eigen::VectorXd& kx,
                   double errorK);
  void thetaLoad();
  void boilingPredictor();
  void chernoffIteration();
  void chernoffRhs(bool pin, bool wasPinned);
  double fluxUpdate();

  void updateVapor();
  void markDesiccated();
};

bool ThermalPhase::nodeActive(int node) const {
  return node >= 0 && node < numNodes_ && impl_->active[node] != 0;
}

ThermalPhase::StepStats ThermalPhase::step(double dtS, const std::vector<double>& sourceW_m3,
                                           ThermalState& s,
                                           const std::vector<NodalSource>& nodalSources) {
  const int n = numNodes_;
  ESIM_VERIFY(std::isfinite(dtS) && dtS > 0,
              "thermal step: dt = " + fmt(dtS) + " s: must be > 0 and finite");
  ESIM_VERIFY(sourceW_m3.size() == tets_.size(),
              "thermal step: source has " + std::to_string(sourceW_m3.size()) +
                  " values, the mesh has " + std::to_string(tets_.size()) + " tets");
  ESIM_VERIFY(
      s.enthalpyJ_m3.size() == n && s.temperatureC.size() == n && s.vaporFraction.size() == n &&
          s.damageOmega.size() == tets_.size() && s.coagulationTet.size() == tets_.size() &&
          s.vaporFractionTet.size() == tets_.size() && s.desiccatedTet.size() == tets_.size(),
      "thermal step: the state does not match the mesh (call initState)");
  Impl::Stepper st{.m = *impl_,
                   .p = params_,
                   .d = derivedOf(params_),
                   .tets = tets_,
                   .alive = alive_,
                   .volumeM3 = volumeM3_,
                   .n = n,
                   .dtS = dtS,
                   .theta = thetaOf(params_.integrator),
                   .s = s};

  if (impl_->massFactorStale) impl_->factorMass();  // removeTets could not modify it
  st.assembleSource(sourceW_m3);
  for (const NodalSource& ns : nodalSources) {
    ESIM_VERIFY(nodeActive(ns.node) && std::isfinite(ns.powerW),
                "thermal step: nodal source on node " + std::to_string(ns.node) + " of " +
                    fmt(ns.powerW) + " W: the node must belong to an alive tet, the power finite");
    if (ns.powerW == 0) continue;
    impl_->load[ns.node] += ns.powerW;
    st.sourcePowerW += ns.powerW;
    st.anySource = true;
  }
  st.updateTemperature();  // from the primary unknown

  // skip: nothing can change but time and damage
  if (!st.anySource && !impl_->convectionActive && st.uniformEnthalpy()) {
    st.accumulateDamage(dtS, s.temperatureC, s.temperatureC);
    s.timeS += dtS;
    st.stats.skipped = true;
    return st.stats;
  }

  if (params_.integrator == ThermalIntegrator::Explicit)
    st.explicitSubsteps(stableExplicitDtS());
  else if (params_.integrator == ThermalIntegrator::TrBdf2)
    st.trBdf2Step();
  else
    st.implicitStep();

  // derived fields: vapour per node and tet, energy split, desiccation
  s.timeS += dtS;
  s.sourceJ += dtS * st.sourcePowerW;
  st.updateVapor();
  impl_->storeEnergySplit(st.d.lv, s);
  if (params_.boiling) st.markDesiccated();
  return st.stats;
}

// ---- step: shared parts ----

// nodal source load F_i = sum_e Q_e V_e / 4 [W]: P1 spreads a tet's heat evenly over its
// four nodes. also the total power, for the energy balance
void ThermalPhase::Impl::Stepper::assembleSource(const std::vector<double>& sourceW_m3) {
  m.load.setZero();
  sourcePowerW = 0;
  anySource = false;
  for (size_t e = 0; e < tets.size(); ++e) {
    if (!alive[e]) continue;
    const double q = sourceW_m3[e];
    ESIM_VERIFY(std::isfinite(q), "thermal step: source of tet " + std::to_string(e) + " is " +
                                      fmt(q) + " W/m^3 (must be finite)");
    if (q == 0) continue;
    anySource = true;
    const double powerW = q * volumeM3[e];
    sourcePowerW += powerW;
    for (int v : tets[e]) m.load[v] += 0.25 * powerW;
  }
}

// T = T(H) on every node: enthalpy is the primary unknown
void ThermalPhase::Impl::Stepper::updateTemperature() {
  Eigen::VectorXd& temp = s.temperatureC;
  const Eigen::VectorXd& enth = s.enthalpyJ_m3;
  for (int i = 0; i < n; ++i) temp[i] = d.temperature(enth[i]);
}

// same enthalpy on every active node? with no source and no convection that field is at
// rest (the rows of the conduction matrix sum to zero); orphan nodes exchange nothing
bool ThermalPhase::Impl::Stepper::uniformEnthalpy() const {
  const Eigen::VectorXd& enth = s.enthalpyJ_m3;
  bool uniform = true;
  double h0 = 0;
  bool first = true;
  for (int i = 0; i < n && uniform; ++i) {
    if (!m.active[i]) continue;
    if (first) {
      h0 = enth[i];
      first = false;
    } else if (enth[i] != h0)
      uniform = false;
  }
  return uniform;
}

// arrhenius damage over a (sub)step of length h: Omega += A exp(-Ea/(R T_K)) h, trapezoid
// rule on the tet mean temperature in kelvin at both ends; coagulation 1 - exp(-Omega)
void ThermalPhase::Impl::Stepper::accumulateDamage(double h, const Eigen::VectorXd& t0,
                                                   const Eigen::VectorXd& t1) {
  if (!p.damage) return;
  const double ea = p.arrheniusEa_J_mol / kGasConstantJ_molK;
  for (size_t e = 0; e < tets.size(); ++e) {
    if (!alive[e]) continue;
    const Tet& t = tets[e];
    const double m0 = 0.25 * (t0[t[0]] + t0[t[1]] + t0[t[2]] + t0[t[3]]) + kKelvinOffset;
    const double m1 = 0.25 * (t1[t[0]] + t1[t[1]] + t1[t[2]] + t1[t[3]]) + kKelvinOffset;
    s.damageOmega[e] += 0.5 * h * p.arrheniusA_s * (std::exp(-ea / m0) + std::exp(-ea / m1));
    s.coagulationTet[e] = -std::expm1(-s.damageOmega[e]);
  }
}

// heat lost through the cooled faces at temperature t [W]: h (T - T_amb) A
double ThermalPhase::Impl::Stepper::convectedPowerW(const Eigen::VectorXd& t) const {
  return m.convectionActive ? m.convectionColSum.dot(t) - m.convectionLoadTotalW : 0.0;
}

// ---- step: explicit ----

// theta = 0: H += h M^-1 (F - K T) per sub-step, h = dt / substeps at most the stability
// limit; above the limit without sub-stepping it is an error (the scheme would blow up)
void ThermalPhase::Impl::Stepper::explicitSubsteps(double limitS) {
  Eigen::VectorXd& temp = s.temperatureC;
  Eigen::VectorXd& enth = s.enthalpyJ_m3;
  int substeps = 1;
  if (dtS > limitS) {
    ESIM_VERIFY(p.allowSubstepping,
                "thermal explicit step: dt = " + fmt(dtS) + " s exceeds the stability limit " +
                    fmt(limitS) +
                    " s of this mesh; enable sub-stepping (allow_substepping) or use "
                    "backward-euler / crank-nicolson");
    const double need = std::ceil(dtS / limitS);  // a double: never overflows
    ESIM_RUN_CHECK(need <= p.maxSubsteps, explicitSubstepMessage(dtS, limitS, p.maxSubsteps));
    substeps = static_cast<int>(need);
  }
  const double h = dtS / substeps;
  for (int k = 0; k < substeps; ++k) {
    checkInterrupt();  // a frame of many sub-steps stops within one
    m.flux = m.load + m.convectionLoadW;
    m.flux.noalias() -= m.stiffnessRows * temp;
    s.convectedJ += h * convectedPowerW(temp);
    m.solveMass(p.lumpedMass, m.flux, m.work);
    enth += h * m.work;
    m.tempOld = temp;
    updateTemperature();
    accumulateDamage(h, m.tempOld, temp);
  }
  stats.substeps = substeps;
  stats.iterations = 0;
}

// ---- step: implicit theta scheme ----

// theta = 1 (backward euler) or 1/2 (crank-nicolson):
//   M (H1 - H0)/dt + theta K T(H1) + (1 - theta) K T(H0) = F,
// nonlinear in H1 once boiling is on: the chernoff iteration of the header
void ThermalPhase::Impl::Stepper::implicitStep() {
  chooseLinearSolver();
  thetaLoad();
  implicitStage();
  // convected heat by the same theta rule as the conduction
  if (m.convectionActive)
    s.convectedJ +=
        dtS * (theta * convectedPowerW(m.tempNew) + (1 - theta) * convectedPowerW(m.tempOld));
  accumulateDamage(dtS, m.tempOld, s.temperatureC);
  stats.substeps = 1;
}

// the nonlinear solve of one implicit step or stage, its load m.g set (thetaLoad, then
// adjusted by tr-bdf2): the predictor, then the chernoff iteration
void ThermalPhase::Impl::Stepper::implicitStage() {
  if (p.boiling && p.lumpedMass) boilingPredictor();
  chernoffIteration();
}

// tr-bdf2, gamma = 2 - sqrt 2, F the load (source and ambient), K with the robin terms:
//   stage 1, crank-nicolson over gamma dt: M (H_g - H_n)/(gamma dt) = F - K (T_n + T_g)/2,
//     i.e. times 2, a backward euler step of h = gamma dt/2 with the load 2F - K T_n;
//   stage 2, BDF2 on t_n, t_n + gamma dt, t_n + dt: with a = 1/(gamma (2 - gamma)) and
//     b = (1 - gamma)^2/(gamma (2 - gamma)) (a - b = 1), H* = a H_g - b H_n and
//     M (H_n+1 - H*)/h = F - K T_n+1, a backward euler step of the same h
//     ((1 - gamma)/(2 - gamma) dt = gamma dt/2 for this gamma): one matrix, factored once.
// Each stage balances energy exactly (flux form); over the step the source enters with
// weight (a gamma + (1 - gamma)/(2 - gamma)) dt = dt, and so does the convected heat below.
// Damage by the trapezoid rule over the two stages' real lengths, gamma dt and (1 - gamma) dt
void ThermalPhase::Impl::Stepper::trBdf2Step() {
  const double stepS = dtS;
  const double gamma = 2.0 - std::sqrt(2.0);
  const double a = 1.0 / (gamma * (2.0 - gamma)), b = (1.0 - gamma) * (1.0 - gamma) * a;
  dtS = 0.5 * gamma * stepS;
  theta = 1.0;
  chooseLinearSolver();
  // stage 1
  thetaLoad();                     // H_n, T_n, K T_n; g = F
  m.stageEnthalpyN = m.enthalpy0;  // (kept in the phase: no allocation a frame)
  m.stageTempN = m.tempOld;
  m.g = 2.0 * m.g - m.kTemp;
  implicitStage();
  const bool converged = stats.converged;  // (iterations add up in stats.iterations)
  const double convectedN = convectedPowerW(m.stageTempN);
  const double convectedG = convectedPowerW(m.tempNew);
  accumulateDamage(gamma * stepS, m.stageTempN, s.temperatureC);
  m.stageTempG = s.temperatureC;
  // stage 2, from H*
  s.enthalpyJ_m3 = a * s.enthalpyJ_m3 - b * m.stageEnthalpyN;
  updateTemperature();
  thetaLoad();  // H*, T(H*), K T(H*); g = F
  implicitStage();
  stats.converged = stats.converged && converged;
  if (m.convectionActive)
    s.convectedJ +=
        a * gamma * stepS * 0.5 * (convectedN + convectedG) + dtS * convectedPowerW(m.tempNew);
  accumulateDamage((1.0 - gamma) * stepS, m.stageTempG, s.temperatureC);
  stats.substeps = 2;
  dtS = stepS;
}

// decided once per (dt, theta). auto: cg when the jacobi-preconditioned A = diag(S) +
// theta K has a small condition number; K >= 0 bounds its spectrum below by min S_i/A_ii,
// gershgorin above by max (S_i + theta sum_j |K_ij|)/A_ii
void ThermalPhase::Impl::Stepper::chooseLinearSolver() {
  if (m.cgDecidedDt == dtS && m.cgDecidedTheta == theta) return;
  m.cgDecidedDt = dtS;
  m.cgDecidedTheta = theta;
  const double crho = d.crho;
  bool cg = p.lumpedMass && p.linearSolver != ThermalLinearSolver::Direct;
  if (cg && p.linearSolver == ThermalLinearSolver::Auto) {
    double lo = std::numeric_limits<double>::infinity(), hi = 0;
    for (int i = 0; i < n; ++i) {
      if (!m.active[i]) continue;
      const double si = crho * m.massM3[i] / dtS;
      const double di = si + theta * m.stiffnessDiag[i];
      lo = std::min(lo, si / di);
      hi = std::max(hi, (si + theta * m.stiffnessAbsRow[i]) / di);
    }
    cg = hi <= kCgMaxCondition * lo;
  }
  m.useCg = cg;
  setChernoffDiagonal();
}

// diag(S) = c rho M / dt (1 on orphan nodes, which keeps A invertible) and the jacobi
// preconditioner 1 / A_ii of A = diag(S) + theta K
void ThermalPhase::Impl::Stepper::setChernoffDiagonal() {
  const double crho = d.crho;
  for (int i = 0; i < n; ++i) {
    m.diagS[i] = m.active[i] ? crho * m.massM3[i] / dtS : 1.0;
    m.diagPrec[i] = 1.0 / (m.diagS[i] + theta * m.stiffnessDiag[i]);
  }
}

// A x = b by jacobi-cg, lumped mass: A = diag(S) + theta K; kx = K x on entry and on exit
// (tracked along the iteration, so that no product is spent on it). stops when the
// preconditioned residual (~ the error in kelvin, A being close to its diagonal) is below
// errorK; false after kCgMaxIterations
bool ThermalPhase::Impl::Stepper::solveCg(const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                          Eigen::VectorXd& kx, double errorK) {
  m.cgR = b - m.diagS.cwiseProduct(x) - theta * kx;
  m.cgZ = m.diagPrec.cwiseProduct(m.cgR);
  if (m.cgZ.cwiseAbs().maxCoeff() <= errorK) return true;
  m.cgP = m.cgZ;
  double rz = m.cgR.dot(m.cgZ);
  for (int it = 0; it < kCgMaxIterations; ++it) {
    m.cgKp.noalias() = m.stiffnessRows * m.cgP;
    m.cgAp = m.diagS.cwiseProduct(m.cgP) + theta * m.cgKp;
    const double alpha = rz / m.cgP.dot(m.cgAp);
    x += alpha * m.cgP;
    kx += alpha * m.cgKp;
    m.cgR -= alpha * m.cgAp;
    ++stats.cgIterations;
    m.cgZ = m.diagPrec.cwiseProduct(m.cgR);
    if (m.cgZ.cwiseAbs().maxCoeff() <= errorK) return true;
    const double rzNew = m.cgR.dot(m.cgZ);
    m.cgP = m.cgZ + (rzNew / rz) * m.cgP;
    rz = rzNew;
  }
  return false;
}

// A x = b by sparse cholesky, A = c rho M/dt + theta K (+1 on orphan nodes); kx = K x.
// A is factored once per (dt, theta), its pattern analysed once per operator build
void ThermalPhase::Impl::Stepper::solveDirect(const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                              Eigen::VectorXd& kx) {
  const double crho = d.crho;
  if (!m.factor || m.factorDt != dtS || m.factorTheta != theta) {
    SparseMatrix a = theta * m.stiffness;
    if (p.lumpedMass) {
      for (int i = 0; i < n; ++i) a.coeffRef(i, i) += m.active[i] ? crho * m.massM3[i] / dtS : 1.0;
    } else {
      a += (crho / dtS) * m.massConsistent;
      for (int i = 0; i < n; ++i)
        if (!m.active[i]) a.coeffRef(i, i) += 1.0;
    }
    a.makeCompressed();
    if (m.factorModified) {  // removeTets changed its pattern: analyse again
      m.factor.reset();
      m.factorAnalyzed = false;
      m.factorModified = false;
    }
    if (!m.factor) m.factor = std::make_unique<Cholesky>();
    if (!m.factorAnalyzed) {
      m.factor->analyzePattern(a);
      m.factorAnalyzed = true;
    }
    m.factor->factorize(a);
    ESIM_RUN_CHECK(m.factor->info() == Eigen::Success,
                   "thermal step: the implicit heat matrix could not be factored");
    m.factorDt = dtS;
    m.factorTheta = theta;
  }
  x = m.factor->solve(b);
  kx.noalias() = m.stiffnessRows * x;
}

// cg when chosen; if it does not converge, cholesky for this dt from then on
void ThermalPhase::Impl::Stepper::solveLinear(const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                              Eigen::VectorXd& kx, double errorK) {
  if (m.useCg) {
    m.lastSolver = "cg";
    if (solveCg(b, x, kx, errorK)) return;
    m.useCg = false;
  }
  m.lastSolver = "cholmod";
  solveDirect(b, x, kx);
}

// G = F + h T_amb load - (1 - theta) K T0: the part of the right-hand side fixed over the
// step. keeps H0, T0 and K T0; T0 is also the first guess of the linear solves
void ThermalPhase::Impl::Stepper::thetaLoad() {
  m.enthalpy0 = s.enthalpyJ_m3;
  m.tempOld = s.temperatureC;
  m.tempNew = s.temperatureC;
  m.kTemp.noalias() = m.stiffnessRows * s.temperatureC;
  m.g = m.load + m.convectionLoadW;
  if (theta < 1) m.g -= (1 - theta) * m.kTemp;
}

// start the iteration from the predictor H0 + dt M^-1 (G - theta K T0): a node that starts
// boiling in this step then starts near its plateau (one iteration fewer)
void ThermalPhase::Impl::Stepper::boilingPredictor() {
  Eigen::VectorXd& temp = s.temperatureC;
  Eigen::VectorXd& enth = s.enthalpyJ_m3;
  for (int i = 0; i < n; ++i) {
    if (!m.active[i]) continue;
    enth[i] = m.enthalpy0[i] + dtS * (m.g[i] - theta * m.kTemp[i]) / m.massM3[i];
    temp[i] = d.temperature(enth[i]);
  }
}

// chernoff iteration on T(H) (see the header): each iterate solves the linear problem's
// matrix for T_k+1 and updates H in flux form, until T(H_k+1) matches T_k+1 within
// nonlinearToleranceK. without boiling one iteration suffices
void ThermalPhase::Impl::Stepper::chernoffIteration() {
  stats.converged = false;
  double lastMismatchK = 0;  // of the previous iteration [K]
  const double cgFloorK = kCgRoundOff * (1.0 + m.tempOld.cwiseAbs().maxCoeff());
  bool pinnedLast = false;
  for (int it = 0; it < p.maxNonlinearIterations; ++it) {
    checkInterrupt();
    // with cg (no factorization to keep), the first iterations pin the plateau nodes at
    // the boiling temperature (newton-like): the phase set is then found in ~2 iterations
    // instead of the chernoff contraction's ~4; after kPinIterations the plain, always
    // convergent chernoff iteration takes over
    const bool pin = p.boiling && m.useCg && it < kPinIterations;
    chernoffRhs(pin, pinnedLast);
    pinnedLast = pin;
    // later solves need only an error well below what this iteration will leave (the
    // iteration contracts by ~theta dt lambda_max, < 1e-2 at frame steps)
    // (the first solve: 1e-3 of the tolerance)
    solveLinear(m.rhs, m.tempNew, m.kTemp,
                std::max(1e-3 * std::max(p.nonlinearToleranceK, lastMismatchK), cgFloorK));
    ++stats.iterations;
    const double mismatchK = fluxUpdate();
    if (mismatchK <= p.nonlinearToleranceK) {
      stats.converged = true;
      break;
    }
    lastMismatchK = mismatchK;
  }
  if (pinnedLast) setChernoffDiagonal();  // restore it for the next step
}

// rhs = G + M (C T(H_k) - (H_k - H0)) / dt with the relaxation capacity C = c rho
// (chernoff), or kPinCapacity c rho on the plateau nodes when pinning; C enters diag(S),
// which is rewritten while pinning and once after (wasPinned)
void ThermalPhase::Impl::Stepper::chernoffRhs(bool pin, bool wasPinned) {
  const Eigen::VectorXd& temp = s.temperatureC;
  const Eigen::VectorXd& enth = s.enthalpyJ_m3;
  const double crho = d.crho;
  if (pin || wasPinned) {
    for (int i = 0; i < n; ++i) {
      const bool inPlateau = pin && enth[i] > d.hb && enth[i] < d.hb + d.lv;
      const double c = inPlateau ? kPinCapacity * crho : crho;
      m.diagS[i] = m.active[i] ? c * m.massM3[i] / dtS : 1.0;
      m.diagPrec[i] = 1.0 / (m.diagS[i] + theta * m.stiffnessDiag[i]);
      m.work[i] = c * temp[i] - (enth[i] - m.enthalpy0[i]);
    }
  } else {
    for (int i = 0; i < n; ++i) m.work[i] = crho * temp[i] - (enth[i] - m.enthalpy0[i]);
  }
  if (p.lumpedMass)
    m.rhs = m.g + (m.massM3.cwiseProduct(m.work)) / dtS;
  else
    m.rhs = m.g + (m.massConsistent * m.work) / dtS;
}

// flux form H = H0 + dt M^-1 (G - theta K T_k+1): exact energy balance at every iterate
// (the columns of K sum to zero). returns max |T(H) - T_k+1| on the active nodes [K]
double ThermalPhase::Impl::Stepper::fluxUpdate() {
  Eigen::VectorXd& temp = s.temperatureC;
  Eigen::VectorXd& enth = s.enthalpyJ_m3;
  m.flux = m.g - theta * m.kTemp;
  m.solveMass(p.lumpedMass, m.flux, m.work);
  enth = m.enthalpy0 + dtS * m.work;
  double mismatchK = 0;
  for (int i = 0; i < n; ++i) {
    temp[i] = d.temperature(enth[i]);
    if (m.active[i]) mismatchK = std::max(mismatchK, std::abs(temp[i] - m.tempNew[i]));
  }
  return mismatchK;
}

// ---- step: derived fields ----

// vapour fraction per node; per tet (the mean of its nodes) only around the nodes whose
// fraction changed
void ThermalPhase::Impl::Stepper::updateVapor() {
  const Eigen::VectorXd& enth = s.enthalpyJ_m3;
  Eigen::VectorXd& vf = s.vaporFraction;
  for (int i = 0; i < n; ++i) {
    const double v = d.vapor(enth[i]);
    if (v != vf[i]) {
      vf[i] = v;
      for (const int* e = m.tetsBegin(i); e != m.tetsEnd(i); ++e) {
        const Tet& t = tets[*e];
        s.vaporFractionTet[*e] = 0.25 * (vf[t[0]] + vf[t[1]] + vf[t[2]] + vf[t[3]]);
      }
    }
  }
}

// a tet is desiccated once all four nodes are dry (sticky: re-condensation keeps it)
void ThermalPhase::Impl::Stepper::markDesiccated() {
  const Eigen::VectorXd& vf = s.vaporFraction;
  for (int i = 0; i < n; ++i) {
    if (vf[i] < 1) continue;
    for (const int* e = m.tetsBegin(i); e != m.tetsEnd(i); ++e) {
      const Tet& t = tets[*e];
      if (!s.desiccatedTet[*e] && vf[t[0]] >= 1 && vf[t[1]] >= 1 && vf[t[2]] >= 1 && vf[t[3]] >= 1)
        s.desiccatedTet[*e] = 1;
    }
  }
}

}  // namespace esim
