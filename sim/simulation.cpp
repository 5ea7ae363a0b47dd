// simulation.cpp - the frame pipeline (see simulation.h).
#include "sim/simulation.h"

#include <algorithm>
#include <cmath>
#include <future>
#include <iterator>

#include "sim/core_error.h"
#include "sim/electric_phase.h"

namespace esim {

namespace {

constexpr double kRebuildPrefetchS = 1.0;         // scripted path prefetched after a rebuild [s]
constexpr double kMaxPrincipleToleranceK = 1e-3;  // round-off and obtuse-mesh margin [K]

constexpr const char* kStageNames[kStageCount] = {
    "move_tool", "find_contacts", "solve_potential", "heat",        "solve_stress", "rupture",
    "rebuild",   "snapshot",      "render",          "encode_wait", "write_labels"};

}  // namespace

const char* rebuildModeName(RebuildMode mode) {
  switch (mode) {
    case RebuildMode::Synchronous:
      return "synchronous";
    case RebuildMode::Background:
      return "background";
    case RebuildMode::Update:
      return "update";
  }
  return "?";
}

const char* stageName(Stage stage) { return kStageNames[static_cast<int>(stage)]; }

double FrameRecord::physicsMs() const {
  double sum = 0;
  for (int s = 0; s <= static_cast<int>(Stage::Snapshot); ++s) sum += ms[s];
  return sum;
}

StageTimer::~StageTimer() {
  const auto end = std::chrono::steady_clock::now();
  const int s = static_cast<int>(stage_);
  record_.ms[s] = std::chrono::duration<double, std::milli>(end - start_).count();
  record_.status[s] = skipped_ ? StageStatus::Skipped : StageStatus::Ran;
}

const SimulationConfig& defaultSimulationConfig() {
  static const SimulationConfig config;
  return config;
}

// ---- checks (the constructor's, also run by `esim validate`) ----

std::string phaseDependencyProblem(const PhaseSet& ph) {
  if (ph.boiling && !ph.thermal) return "'boiling' needs 'thermal'; add thermal";
  if (ph.structural && (!ph.thermal || !ph.boiling))
    return "'structural' needs 'thermal' and 'boiling' (its load is the expansion of heated "
           "and vaporized water); add them";
  if (ph.rupture && !ph.structural)
    return "'rupture' needs 'structural' (the stress that breaks elements); add structural";
  if (!ph.electric && !ph.thermal) return "no phase to simulate: list electric or thermal";
  return "";
}

void validateSimulationConfig(const SimulationConfig& config) {
  const PhaseSet& ph = config.phases;
  const std::string phaseProblem = phaseDependencyProblem(ph);
  ESIM_VERIFY(phaseProblem.empty(), "physics: " + phaseProblem);
  ESIM_VERIFY(config.frameDtS > 0 && std::isfinite(config.frameDtS),
              "time.fps: the frame step 1/fps must be positive and finite");
  if (ph.electric) {
    ESIM_VERIFY(config.conductivityS_m > 0 && std::isfinite(config.conductivityS_m),
                "material.electric_conductivity_s_per_m must be a positive finite number");
    ESIM_VERIFY(std::isfinite(config.toolVoltageV), "tool.voltage_v must be finite");
    validateToolPath(config.toolPath);
    validateElectricSolverOptions(config.electricSolver);
  }
  if (ph.thermal) {
    ThermalParams tp = config.thermal;
    tp.boiling = ph.boiling;
    validateThermalParams(tp);
  }
  if (ph.structural) {
    ESIM_VERIFY(config.clampBandM >= 0 && std::isfinite(config.clampBandM),
                "effects.structural_clamp_band_m must be >= 0");
    ESIM_VERIFY(config.criticalStressPa > 0 && std::isfinite(config.criticalStressPa),
                "material.critical_stress_pa must be > 0");
    ESIM_VERIFY(config.vaporLiquidVolumeRatio >= 1,
                "material.vapor_liquid_volume_ratio must be >= 1");
  }
}

namespace {

// the nodes the structural phase clamps: surface nodes within the clamp band of the lowest
std::vector<Support> clampedSupports(const TetMesh& mesh, const std::vector<int>& surfaceNodes,
                                     double clampBandM) {
  double zMin = mesh.nodes.front().z();
  for (const Vec3& p : mesh.nodes) zMin = std::min(zMin, p.z());
  std::vector<Support> supports;
  for (int v : surfaceNodes)
    if (mesh.nodes[v].z() <= zMin + clampBandM)
      for (int a = 0; a < 3; ++a) supports.push_back({v, a});
  return supports;
}

// median edge length of the tets [m]
double medianEdgeLengthM(const TetMesh& mesh) {
  std::vector<double> edges;
  edges.reserve(6 * mesh.tets.size());
  for (const Tet& t : mesh.tets)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) edges.push_back((mesh.nodes[t[a]] - mesh.nodes[t[b]]).norm());
  if (edges.empty()) return 0;
  std::nth_element(edges.begin(), edges.begin() + edges.size() / 2, edges.end());
  return edges[edges.size() / 2];
}

// the alive tet holding p (barycentric coordinates >= 0 within a round-off margin), or -1;
// a plain loop, only for frames where the tool has no contact, and none at all when p is
// outside the mesh's box (a tool in the air: the common case)
int aliveTetContaining(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                       const Eigen::AlignedBox3d& boundsM, const Vec3& p) {
  if (!boundsM.contains(p)) return -1;
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    const Tet& t = mesh.tets[e];
    const Vec3 c =
        0.25 * (mesh.nodes[t[0]] + mesh.nodes[t[1]] + mesh.nodes[t[2]] + mesh.nodes[t[3]]);
    bool inside = true;
    for (int a = 0; a < 4 && inside; ++a) inside = 0.25 + geo[e].grad.row(a).dot(p - c) >= -1e-9;
    if (inside) return e;
  }
  return -1;
}

std::string returnElectrodeMessage(const ReturnElectrode& r) {
  return "return_electrode: no mesh node lies on the return electrode disc (centre " +
         std::to_string(r.centerM.x()) + " " + std::to_string(r.centerM.y()) + " " +
         std::to_string(r.centerM.z()) + " m, radius " + std::to_string(r.radiusM) +
         " m); move it onto the tissue surface or enlarge radius_m/tolerance_m";
}

}  // namespace

void checkExplicitBound(const ThermalPhase& thermal, const SimulationConfig& config) {
  const ThermalParams& p = config.thermal;
  if (p.integrator != ThermalIntegrator::Explicit) return;
  const double limitS = thermal.stableExplicitDtS();
  if (config.frameDtS <= limitS) return;
  ESIM_VERIFY(p.allowSubstepping,
              "solvers.thermal.allow_substepping is false and the frame step " +
                  std::to_string(config.frameDtS) + " s exceeds the explicit stability limit " +
                  std::to_string(limitS) +
                  " s of this mesh; use backward-euler or crank-nicolson, or a higher time.fps");
  ESIM_VERIFY(std::ceil(config.frameDtS / limitS) <= p.maxSubsteps,
              explicitSubstepMessage(config.frameDtS, limitS, p.maxSubsteps));
}

void validateSimulationMesh(const TetMesh& meshIn, const SimulationConfig& config) {
  TetMesh mesh = meshIn;
  if (mesh.alive.empty()) mesh.alive.assign(mesh.tets.size(), 1);
  validateMesh(mesh, "mesh");
  const std::vector<BoundaryFace> surface = boundaryFaces(mesh);
  const std::vector<int> surfaceNodes = boundaryNodes(mesh, surface);
  if (config.phases.electric)
    ESIM_VERIFY(!returnElectrodeNodes(mesh, surfaceNodes, config.returnElectrode).empty(),
                returnElectrodeMessage(config.returnElectrode));
  if (config.phases.electric && config.electricSolver.strategy == ElectricStrategy::DenseInverse) {
    const double nf = mesh.numNodes() -
                      static_cast<double>(
                          returnElectrodeNodes(mesh, surfaceNodes, config.returnElectrode).size());
    const double need = 8.0 * nf * nf;
    ESIM_VERIFY(need <= config.electricSolver.denseMemoryLimitBytes,
                "solvers.electric.strategy: dense-inverse needs " + std::to_string(need / 1e9) +
                    " GB for this mesh, above solvers.electric.dense_memory_limit_mb = " +
                    std::to_string(config.electricSolver.denseMemoryLimitBytes / 1048576.0) +
                    " MiB; use 'capacitance' (the same answer with sparse memory)");
  }
  if (config.phases.thermal && config.thermal.integrator == ThermalIntegrator::Explicit) {
    ThermalParams tp = config.thermal;
    tp.boiling = config.phases.boiling;
    checkExplicitBound(ThermalPhase(mesh, tetGeometry(mesh), tp), config);
  }
  if (config.phases.structural)
    ESIM_VERIFY(!clampedSupports(mesh, surfaceNodes, config.clampBandM).empty(),
                "effects.structural_clamp_band_m = " + std::to_string(config.clampBandM) +
                    " m: no surface node lies within it of the lowest node (nothing holds the "
                    "tissue)");
}

// ---- building ----

Simulation::Simulation(TetMesh mesh, SimulationConfig config) : config_(std::move(config)) {
  validateSimulationConfig(config_);
  if (mesh.alive.empty()) mesh.alive.assign(mesh.tets.size(), 1);
  validateMesh(mesh, "mesh");
  config_.thermal.boiling = config_.phases.boiling;
  buildInitialModel(std::move(mesh));
  initState();
}

// the parts of the model that no removal changes (geometry, initial surface, cooled
// faces, supports, prescribed source), then the topology-dependent parts (buildModel)
void Simulation::buildInitialModel(TetMesh mesh) {
  auto fixed = std::make_unique<SimModel>();
  SimModel& m = *fixed;
  m.geo = std::make_shared<const std::vector<TetGeometry>>(tetGeometry(mesh));
  const std::vector<BoundaryFace> surface = boundaryFaces(mesh);
  const std::vector<int> surfaceNodes = boundaryNodes(mesh, surface);
  auto initialFaces = std::make_shared<std::vector<std::array<int, 3>>>();
  for (const auto& f : surface) {
    std::array<int, 3> key{f.nodes[0], f.nodes[1], f.nodes[2]};
    std::sort(key.begin(), key.end());
    initialFaces->push_back(key);
  }
  std::sort(initialFaces->begin(), initialFaces->end());
  m.initialFaces = std::move(initialFaces);
  const PhaseSet& ph = config_.phases;
  if (ph.electric) {
    ESIM_VERIFY(!returnElectrodeNodes(mesh, surfaceNodes, config_.returnElectrode).empty(),
                returnElectrodeMessage(config_.returnElectrode));
  }
  if (ph.thermal && config_.coolTopSurface && config_.thermal.convectionW_m2K > 0) {
    for (const auto& f : surface) {
      const Vec3& a = mesh.nodes[f.nodes[0]];
      const Vec3 n = (mesh.nodes[f.nodes[1]] - a).cross(mesh.nodes[f.nodes[2]] - a);
      if (n.z() > 0.5 * n.norm()) m.cooledInitial.push_back(f);
    }
  }
  if (ph.thermal && !ph.electric) {
    m.prescribedSource.assign(mesh.numTets(), 0.0);  // zero without a source
    if (config_.heatSource.enabled) {
      const double r2 = config_.heatSource.radiusM * config_.heatSource.radiusM;
      for (int e = 0; e < mesh.numTets(); ++e) {
        Vec3 c = Vec3::Zero();
        for (int v : mesh.tets[e]) c += 0.25 * mesh.nodes[v];
        m.prescribedSource[e] = config_.heatSource.powerDensityW_m3 *
                                std::exp(-(c - config_.heatSource.centerM).squaredNorm() / r2);
      }
    }
  }
  if (ph.structural) {
    m.supports = clampedSupports(mesh, surfaceNodes, config_.clampBandM);
    ExpansionParams& x = m.expansion;
    x.waterFraction = config_.thermal.waterFraction;
    x.densityKg_m3 = config_.thermal.densityKg_m3;
    x.initialTemperatureC = config_.thermal.initialTemperatureC;
    x.boilingTemperatureC = config_.thermal.boilingTemperatureC;
    x.vaporLiquidVolumeRatio = config_.vaporLiquidVolumeRatio;
    x.maxExpansion = config_.maxVaporExpansion;
    pending_.assign(mesh.numTets(), 0);
  }
  if (ph.rupture && config_.rebuildMode == RebuildMode::Update) {
    m.faceNeighbours =
        std::make_shared<const std::vector<std::array<int, 4>>>(tetFaceNeighbours(mesh));
    if (ph.electric) m.nodeTets = std::make_shared<const Adjacency>(nodeTets(mesh));
  }
  m.medianEdgeM = medianEdgeLengthM(mesh);
  for (const Vec3& x : mesh.nodes) m.boundsM.extend(x);
  std::vector<std::uint8_t> alive = mesh.alive;
  m.mesh = std::move(mesh);
  model_ = std::move(fixed);
  const int prefetchTo =
      config_.prefetchUntilS > 0
          ? static_cast<int>(std::ceil(config_.prefetchUntilS / config_.frameDtS))
          : -1;
  try {
    model_ = buildModel(
        std::move(alive),
        std::vector<double>(ph.electric ? model_->mesh.numTets() : 0, config_.conductivityS_m), 0,
        prefetchTo);
  } catch (const Error& e) {
    if (std::string(e.what()).rfind("structural", 0) != 0) throw;
    throw RunError(std::string(e.what()) +
                   " (clamped: " + std::to_string(model_->supports.size() / 3) +
                   " bottom nodes within effects.structural_clamp_band_m = " +
                   std::to_string(config_.clampBandM) + " m of the lowest node)");
  }
  // the work of an explicit frame is bounded: refused up front, never a frame of minutes
  if (model_->thermal) checkExplicitBound(*model_->thermal, config_);
}

void Simulation::initState() {
  SimState& s = state_;
  const int n = model_->mesh.numNodes(), nt = model_->mesh.numTets();
  s.potentialV = Eigen::VectorXd::Zero(n);
  s.joulePowerW_m3.assign(nt, 0.0);
  if (model_->electric) s.conductivityS_m.assign(nt, config_.conductivityS_m);
  s.maxTemperatureC = config_.thermal.initialTemperatureC;
  if (model_->thermal) {
    model_->thermal->initState(s.thermal);
    if (config_.hotSpot.enabled) {
      Eigen::VectorXd t = s.thermal.temperatureC;
      for (int i = 0; i < n; ++i)
        if ((model_->mesh.nodes[i] - config_.hotSpot.centerM).norm() <= config_.hotSpot.radiusM)
          t[i] = config_.hotSpot.temperatureC;
      model_->thermal->setTemperature(s.thermal, t);
    }
    s.maxTemperatureC = s.thermal.temperatureC.maxCoeff();
    lowestC_ = s.thermal.temperatureC.minCoeff();
  }
  if (model_->structural) {
    s.eigenstrain.assign(nt, 0.0);
    s.vonMisesPa.assign(nt, 0.0);
    s.displacementM = Eigen::VectorXd::Zero(3 * n);
  }
}

void Simulation::computeEigenstrain() {
  const TetMesh& mesh = model_->mesh;
  const ThermalState& th = state_.thermal;
  const Eigen::VectorXd& t = th.temperatureC;
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) {
      state_.eigenstrain[e] = 0;
      continue;
    }
    const Tet& tet = mesh.tets[e];
    const double te = 0.25 * (t[tet[0]] + t[tet[1]] + t[tet[2]] + t[tet[3]]);
    const double x = th.vaporFractionTet.empty() ? 0.0 : th.vaporFractionTet[e];
    state_.eigenstrain[e] = volumetricExpansion(model_->expansion, te, x);
  }
}

namespace {

// surface vertex numbering, triangles and cut walls of the snapshot: fixed until the
// topology changes
void buildSnapshotTopology(SimModel& m) {
  m.surfaceVertexOf.assign(m.mesh.numNodes(), -1);
  m.surfacePositionsM.clear();
  for (int v : m.surfaceNodes) {
    m.surfaceVertexOf[v] = static_cast<int>(m.surfacePositionsM.size() / 3);
    for (int c = 0; c < 3; ++c)
      m.surfacePositionsM.push_back(static_cast<float>(m.mesh.nodes[v][c]));
  }
  m.surfaceTriangles.clear();
  m.surfaceTriangles.reserve(m.surface.size() * 3);
  for (const auto& f : m.surface)
    for (int v : f.nodes)
      m.surfaceTriangles.push_back(static_cast<std::uint32_t>(m.surfaceVertexOf[v]));
  // cut walls: vertices of faces that were inside the initial tissue
  m.surfaceCutWall.assign(m.surfacePositionsM.size() / 3, 0.0f);
  for (const auto& f : m.surface) {
    std::array<int, 3> key{f.nodes[0], f.nodes[1], f.nodes[2]};
    std::sort(key.begin(), key.end());
    if (std::binary_search(m.initialFaces->begin(), m.initialFaces->end(), key)) continue;
    for (int v : f.nodes) m.surfaceCutWall[m.surfaceVertexOf[v]] = 1.0f;
  }
}

}  // namespace

// A model for the given alive set, built from the parts no removal changes (model_'s
// nodes, tets, geometry, initial faces, cooled faces, supports) and the configuration
// only, so that it can run on another thread while frames go on with model_ (which the
// frame loop changes only in its electric matrix, not read here). The electric columns of
// the scripted contacts in frames [prefetchFrom, prefetchTo] are prefetched (none when
// prefetchTo < prefetchFrom).
std::unique_ptr<SimModel> Simulation::buildModel(std::vector<std::uint8_t> alive,
                                                 std::vector<double> sigma, int prefetchFrom,
                                                 int prefetchTo) const {
  const auto t0 = std::chrono::steady_clock::now();
  const SimModel& base = *model_;
  auto out = std::make_unique<SimModel>();
  SimModel& m = *out;
  m.mesh.nodes = base.mesh.nodes;
  m.mesh.tets = base.mesh.tets;
  m.mesh.alive = std::move(alive);
  ESIM_RUN_CHECK(m.mesh.numAlive() > 0, "rupture: every element of the tissue has been removed");
  m.geo = base.geo;
  m.initialFaces = base.initialFaces;
  m.cooledInitial = base.cooledInitial;
  m.prescribedSource = base.prescribedSource;
  m.supports = base.supports;
  m.expansion = base.expansion;
  m.medianEdgeM = base.medianEdgeM;
  m.boundsM = base.boundsM;
  m.faceNeighbours = base.faceNeighbours;
  m.nodeTets = base.nodeTets;
  m.surface = boundaryFaces(m.mesh);
  m.surfaceNodes = boundaryNodes(m.mesh, m.surface);
  buildSnapshotTopology(m);
  checkInterrupt();  // between the phases' builds: a stop waits for one factorization at most
  if (config_.phases.thermal) {
    std::vector<BoundaryFace> cooled;
    for (const BoundaryFace& f : m.cooledInitial)
      if (m.mesh.isAlive(f.tet)) cooled.push_back(f);
    m.thermal = std::make_unique<ThermalPhase>(m.mesh, *m.geo, config_.thermal, cooled);
    if (config_.thermal.integrator == ThermalIntegrator::Explicit)
      m.thermal->stableExplicitDtS();  // computed here, not in the next frame
  }
  checkInterrupt();
  if (config_.phases.electric) {
    m.ground = returnElectrodeNodes(m.mesh, m.surfaceNodes, config_.returnElectrode);
    ESIM_RUN_CHECK(!m.ground.empty(),
                   "rupture: the cut removed all the tissue on the return electrode");
    m.contactFinder = ContactFinder(m.mesh, m.surfaceNodes);
    m.sigmaAssembled = std::move(sigma);
    m.stiffness = assembleStiffness(m.mesh, *m.geo, m.sigmaAssembled);
    m.electric = makeElectricSolver(config_.electricSolver);
    m.electric->setContactCandidates(m.surfaceNodes);
    m.electric->setMatrix(m.stiffness, m.ground);
    if (prefetchTo >= prefetchFrom)
      m.electric->prefetch(scriptedContacts(m.contactFinder, m.ground, prefetchFrom, prefetchTo));
  }
  checkInterrupt();
  if (config_.phases.structural) {
    StructuralOptions so = config_.structural;
    // update mode: the factor's conversion for low-rank updates is paid here, not in a frame
    so.prepareForUpdates = config_.phases.rupture && config_.rebuildMode == RebuildMode::Update;
    m.structural = std::make_unique<StructuralPhase>(m.mesh, so, m.supports);
  }
  m.buildMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

// ---- rebuild after rupture ----

// buildModel for the alive set left by a rupture (at frame first - 1): whatever stops it (no
// tissue left on the return electrode or held by the clamps, a factorization) is a run that
// cannot go on, never bad input
std::unique_ptr<SimModel> Simulation::rebuildModel(std::vector<std::uint8_t> alive,
                                                   std::vector<double> sigma, int first,
                                                   int prefetchTo) const {
  try {
    return buildModel(std::move(alive), std::move(sigma), first, prefetchTo);
  } catch (const Error& e) {
    throwRebuildError(e, first - 1);
  }
}

// an error of a rebuild or an update after the rupture of frame ruptureFrame: a run that
// cannot go on (internal checks and interruptions pass as they are)
void Simulation::throwRebuildError(const Error& e, int ruptureFrame) const {
  if (e.kind() == ErrorKind::Internal || dynamic_cast<const Interrupted*>(&e)) throw;
  const std::string what = e.what();
  std::string context = "rupture, frame " + std::to_string(ruptureFrame) + ": ";
  if (what.find("supports") != std::string::npos)
    context +=
        "the cut removed all the tissue held by the clamps "
        "(effects.structural_clamp_band_m): ";
  throw RunError(context + what);
}

// solvers.rebuild.mode: update. The model edited in place in the frame the tets break:
// the alive set, the surface (removeFromBoundary: local), the snapshot topology, the
// return electrode and the contact finder (over the surface), and each phase's removal
// update. Its errors are a rebuild's.
void Simulation::updateModel(const std::vector<int>& broken, FrameRecord& rec) {
  const auto t0 = std::chrono::steady_clock::now();
  SimModel& m = *model_;
  joinPrefetch();
  try {
    for (int e : broken) m.mesh.alive[e] = 0;
    ESIM_RUN_CHECK(m.mesh.numAlive() > 0, "rupture: every element of the tissue has been removed");
    removeFromBoundary(m.mesh, *m.faceNeighbours, broken, m.surface);
    m.surfaceNodes = boundaryNodes(m.mesh, m.surface);
    buildSnapshotTopology(m);
    if (m.thermal) m.thermal->removeTets(broken);
    if (m.electric) {
      std::vector<int> ground =
          returnElectrodeNodes(m.mesh, m.surfaceNodes, config_.returnElectrode);
      ESIM_RUN_CHECK(!ground.empty(),
                     "rupture: the cut removed all the tissue on the return electrode");
      m.ground = std::move(ground);
      m.contactFinder = ContactFinder(m.mesh, m.surfaceNodes);
      // the entries of the removed tets summed again (bitwise a fresh assembly; the others
      // untouched: what updateMatrix reads the change from), then the solver's low-rank
      // update, then the new candidates (the capacitance cache is kept; new surface nodes
      // get their columns on first touch)
      removeFromStiffness(m.stiffness, m.mesh, *m.geo, m.sigmaAssembled, *m.nodeTets, broken);
      m.electric->updateMatrix(m.stiffness, m.ground);
      m.electric->setContactCandidates(m.surfaceNodes);
      // the columns the scripted tool will need on the new surface in the next second, on a
      // thread while the frame is drawn (the next solve joins it): not solved on first touch
      if (config_.prefetchUntilS > 0) {
        const int first = state_.frame + 1;
        const int last =
            std::min(static_cast<int>(std::ceil(config_.prefetchUntilS / config_.frameDtS)),
                     first + static_cast<int>(std::ceil(kRebuildPrefetchS / config_.frameDtS)));
        std::vector<int> nodes = scriptedContacts(m.contactFinder, m.ground, first, last);
        if (!nodes.empty())
          prefetchJob_ = std::async(
              std::launch::async,
              [solver = m.electric.get(), nodes = std::move(nodes)] { solver->prefetch(nodes); });
      }
    }
    if (m.structural) m.structural->removeTets(broken);
  } catch (const Error& e) {
    throwRebuildError(e, state_.frame);
  }
  for (int e : broken) pending_[e] = 0;
  removedTets_ += static_cast<int>(broken.size());
  rec.removedTets = static_cast<int>(broken.size());
  m.buildMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  rebuildBuildMs_ += m.buildMs;
  ++rebuilds_;
}

// a model built for a new alive set, and the tets it removes
struct Simulation::Rebuilt {
  std::unique_ptr<SimModel> model;
  std::vector<int> removed;
};

void Simulation::swapIn(std::unique_ptr<Rebuilt> r, FrameRecord& rec) {
  for (int e : r->removed) pending_[e] = 0;
  removedTets_ += static_cast<int>(r->removed.size());
  rec.removedTets = static_cast<int>(r->removed.size());
  rebuildBuildMs_ += r->model->buildMs;
  model_ = std::move(r->model);
  ++rebuilds_;
}

void Simulation::startRebuild(const std::vector<int>& broken) {
  std::vector<std::uint8_t> alive = model_->mesh.alive;
  for (int e : broken) alive[e] = 0;
  std::vector<double> sigma = model_->electric ? model_->sigmaAssembled : std::vector<double>{};
  // the columns the script will need on the new model: from its first frame with
  // recomputation to kRebuildPrefetchS after the swap (later contacts get theirs when they
  // come); built with the model, off the frame loop in background mode
  const int first = state_.frame + 1;
  int prefetchTo = -1;
  if (config_.prefetchUntilS > 0) {
    const int last = static_cast<int>(std::ceil(config_.prefetchUntilS / config_.frameDtS));
    prefetchTo =
        std::min(last, first + config_.rebuildLagFrames +
                           static_cast<int>(std::ceil(kRebuildPrefetchS / config_.frameDtS)));
  }
  if (config_.rebuildMode == RebuildMode::Synchronous) {
    ready_ = std::make_unique<Rebuilt>();
    ready_->model = rebuildModel(std::move(alive), std::move(sigma), first, prefetchTo);
    ready_->removed = broken;
    swapFrame_ = state_.frame;
    return;
  }
  if (config_.recomputeLagFrames && config_.rebuildLagFrames > 0) {
    checkpoint_ = std::make_unique<SimState>(state_);
    checkpoint_->frame = state_.frame + 1;  // the first frame to compute again
  }
  // a pure function of the fixed parts of the model and these copies: the result does not
  // depend on when the thread runs, and it is swapped in at a fixed frame
  job_ = std::async(std::launch::async, [this, alive = std::move(alive), broken,
                                         sigma = std::move(sigma), first, prefetchTo]() mutable {
    auto r = std::make_unique<Rebuilt>();
    r->model = rebuildModel(std::move(alive), std::move(sigma), first, prefetchTo);
    r->removed = std::move(broken);
    return r;
  });
  swapFrame_ = state_.frame + config_.rebuildLagFrames;
}

Simulation::~Simulation() {
  if (job_.valid()) job_.wait();                  // the job reads model_
  if (prefetchJob_.valid()) prefetchJob_.wait();  // and this one the electric solver
}

// the prefetch job's end (its error, an interruption included, is this caller's)
void Simulation::joinPrefetch() const {
  if (!prefetchJob_.valid()) return;
  while (prefetchJob_.wait_for(std::chrono::milliseconds(20)) != std::future_status::ready)
    checkInterrupt();  // the job stops at its next check too
  prefetchJob_.get();
}

Eigen::VectorXd Simulation::temperatureC() const {
  if (model_->thermal) return state_.thermal.temperatureC;
  return Eigen::VectorXd::Constant(model_->mesh.numNodes(), config_.thermal.initialTemperatureC);
}

double Simulation::electricMemoryBytes() const {
  joinPrefetch();
  return model_->electric ? model_->electric->memoryBytes() : 0.0;
}

std::string Simulation::electricSolverName() const {
  return model_->electric ? model_->electric->name() : "";
}

// the union of the contact sets the script produces in frames [fromFrame, toFrame] on the
// surface `finder` was built for, without the grounded nodes (sorted)
std::vector<int> Simulation::scriptedContacts(const ContactFinder& finder,
                                              const std::vector<int>& ground, int fromFrame,
                                              int toFrame) const {
  std::vector<int> nodes;
  for (int f = fromFrame; f <= toFrame; ++f) {
    const double t = f * config_.frameDtS;
    if (!config_.toolPath.generatorOnAt(t)) continue;
    const auto c =
        finder.find(config_.electrode, config_.toolPath.poseAt(t), config_.contactDistanceM);
    nodes.insert(nodes.end(), c.begin(), c.end());
  }
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  std::vector<int> notGround;
  std::set_difference(nodes.begin(), nodes.end(), ground.begin(), ground.end(),
                      std::back_inserter(notGround));
  return notGround;
}

// ---- the frame ----

void Simulation::refreshConductivity() {
  // sigma(T) per tet from the mean nodal temperature; refresh K when it moved enough
  SimModel& m = *model_;
  SimState& st = state_;
  const double t0 = config_.thermal.initialTemperatureC;
  const double tb = config_.thermal.boilingTemperatureC;
  double max_rel = 0;
  for (int e = 0; e < m.mesh.numTets(); ++e) {
    if (!m.mesh.isAlive(e)) continue;
    double t = 0;
    for (int v : m.mesh.tets[e]) t += 0.25 * st.thermal.temperatureC[v];
    t = std::min(t, tb);
    double s = config_.conductivityS_m * (1.0 + config_.conductivityTempCoeffPerK * (t - t0));
    if (!st.thermal.desiccatedTet.empty() && st.thermal.desiccatedTet[e])
      s *= config_.desiccatedConductivityFactor;
    st.conductivityS_m[e] = std::max(s, 1e-6 * config_.conductivityS_m);
    max_rel = std::max(max_rel,
                       std::abs(st.conductivityS_m[e] - m.sigmaAssembled[e]) / m.sigmaAssembled[e]);
  }
  if (max_rel > config_.conductivityRefreshTolerance) {
    m.sigmaAssembled = st.conductivityS_m;
    m.stiffness = assembleStiffness(m.mesh, *m.geo, m.sigmaAssembled);
    m.electric->setMatrix(m.stiffness, m.ground);
  }
}

const FrameRecord& Simulation::step() {
  FrameRecord& rec = record_;
  rec = FrameRecord{};
  advance(rec);
  if (rec.contactByTet) ++framesContactByTet_;
  if (rec.toolSwept) ++framesToolSwept_;
  if (config_.phases.rupture) ruptureAndRebuild(rec);
  ++state_.frame;
  state_.timeS = state_.frame * config_.frameDtS;
  return rec;
}

// stages 1-5 of frame state_.frame (at time state_.timeS): the physics on the current model
void Simulation::advance(FrameRecord& rec) {
  SimModel& m = *model_;
  SimState& st = state_;
  rec.frame = st.frame;
  rec.timeS = st.timeS;
  const double dt = config_.frameDtS;

  // ---- 1. move the tool ----
  if (m.electric) {
    StageTimer timer(rec, Stage::MoveTool);
    st.pose = config_.toolPath.poseAt(st.timeS);
    st.generatorOn = config_.toolPath.generatorOnAt(st.timeS);
  }
  rec.generatorOn = st.generatorOn;

  // ---- 2. contacts ----
  checkInterrupt();  // between the stages (a stop inside one: see core_error.h)
  if (m.electric) {
    StageTimer timer(rec, Stage::FindContacts);
    if (st.generatorOn) {
      st.contacts = findContacts(rec);
    } else {
      st.contacts.clear();
      timer.skip();
    }
  }
  rec.contactNodes = static_cast<int>(st.contacts.size());

  // ---- 3. potential and Joule heat ----
  double power_w = 0;
  if (m.electric) {
    StageTimer timer(rec, Stage::SolvePotential);
    if (st.contacts.empty()) {
      st.potentialV.setZero();
      std::fill(st.joulePowerW_m3.begin(), st.joulePowerW_m3.end(), 0.0);
      timer.skip();
    } else {
      joinPrefetch();  // the wait for a removal's prefetch, if any, counts here
      if (m.thermal && config_.temperatureDependentConductivity) refreshConductivity();
      m.electric->solve(st.contacts, config_.toolVoltageV, st.potentialV);
      // Joule power density (into the state's buffer, reused) and currents with the
      // assembled sigma
      const ElectricTotals totals =
          computeJoulePower(m.mesh, *m.geo, m.sigmaAssembled, m.stiffness, st.potentialV,
                            st.contacts, m.ground, config_.toolVoltageV, st.joulePowerW_m3);
      checkFinite(Stage::SolvePotential, "potential", st.potentialV.data(),
                  static_cast<int>(st.potentialV.size()), "V");
      power_w = totals.powerW;
      rec.toolCurrentA = totals.toolCurrentA;
      rec.returnCurrentA = totals.returnCurrentA;
    }
  }
  rec.powerW = power_w;
  st.energyJ += power_w * dt;

  // ---- 4. heat: Joule (or prescribed) source, conduction, boiling ----
  checkInterrupt();
  if (m.thermal) {
    StageTimer timer(rec, Stage::Heat);
    const double sourceBeforeJ = st.thermal.sourceJ;

    const double highBeforeC = st.thermal.temperatureC.maxCoeff();
    const auto stats =
        m.thermal->step(dt, m.electric ? st.joulePowerW_m3 : m.prescribedSource, st.thermal);
    if (stats.skipped) timer.skip();
    if (!stats.converged) {
      rec.boilingUnconverged = true;
      ++framesBoilingUnconverged_;
    }
    checkFinite(Stage::Heat, "temperature", st.thermal.temperatureC.data(),
                static_cast<int>(st.thermal.temperatureC.size()), "C");
    if (!m.electric) {  // a prescribed source: its heat is the energy delivered
      rec.powerW = (st.thermal.sourceJ - sourceBeforeJ) / dt;
      st.energyJ += st.thermal.sourceJ - sourceBeforeJ;
    }
    checkMaximumPrinciple(highBeforeC, st.thermal.sourceJ > sourceBeforeJ, rec);
    rec.maxTemperatureC = st.thermal.temperatureC.maxCoeff();
    st.maxTemperatureC = std::max(st.maxTemperatureC, rec.maxTemperatureC);
  } else {
    rec.maxTemperatureC = config_.thermal.initialTemperatureC;
  }

  // ---- 5. stress from the water's expansion ----
  checkInterrupt();
  if (m.structural) {
    StageTimer timer(rec, Stage::SolveStress);
    computeEigenstrain();
    if (std::all_of(st.eigenstrain.begin(), st.eigenstrain.end(),
                    [](double v) { return v == 0; })) {
      timer.skip();  // at rest: no load, and the last stresses are zero too
    } else {
      m.structural->solve(st.eigenstrain);
      st.vonMisesPa = m.structural->vonMisesPa();
      st.displacementM = m.structural->displacementM();
      checkFinite(Stage::SolveStress, "von Mises stress", st.vonMisesPa.data(),
                  static_cast<int>(st.vonMisesPa.size()), "Pa");
    }
    const std::vector<double>& vm = st.vonMisesPa;
    rec.maxVonMisesPa = vm.empty() ? 0.0 : *std::max_element(vm.begin(), vm.end());
  }
}

// tets over the critical stress that no rebuild is removing yet join the queue
void Simulation::detectRupture(FrameRecord& rec) {
  StageTimer timer(rec, Stage::Rupture);
  const TetMesh& mesh = model_->mesh;
  const std::vector<double>& vm = state_.vonMisesPa;
  for (int e = 0; e < mesh.numTets(); ++e)
    if (mesh.isAlive(e) && !pending_[e] && vm[e] > config_.criticalStressPa) {
      queued_.push_back(e);
      pending_[e] = 1;
    }
  if (queued_.empty()) timer.skip();
}

// 6. rupture; 7. rebuild: synchronous (built and swapped in now), or built on a thread and
// swapped in config_.rebuildLagFrames frames later; frames meanwhile use the old model,
// and tets that break meanwhile wait for the next rebuild. With recomputeLagFrames the
// frames since the rupture are then computed again on the new model (from a checkpoint,
// a copy of the state, taken when the rebuild started), so that only the timing of later
// ruptures differs from a synchronous run.
void Simulation::ruptureAndRebuild(FrameRecord& rec) {
  detectRupture(rec);
  StageTimer timer(rec, Stage::Rebuild);
  if (config_.rebuildMode == RebuildMode::Update) {
    if (queued_.empty()) {
      timer.skip();
    } else {
      std::vector<int> broken;
      broken.swap(queued_);
      updateModel(broken, rec);
    }
    return;
  }
  bool worked = false;
  if (swapFrame_ < 0 && !queued_.empty()) {  // nothing in flight: start with the queue
    std::vector<int> broken;
    broken.swap(queued_);  // they stay pending until swapIn
    startRebuild(broken);
    worked = true;
  }
  if (swapFrame_ >= 0 && state_.frame >= swapFrame_) {  // due: wait if needed, swap in
    if (!ready_) {
      const auto w0 = std::chrono::steady_clock::now();
      // a stop asked meanwhile is honoured while waiting (the job stops at its next check)
      while (job_.wait_for(std::chrono::milliseconds(20)) != std::future_status::ready)
        checkInterrupt();
      ready_ = job_.get();
      rec.rebuildWaitMs =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - w0).count();
      rebuildWaitMs_ = std::max(rebuildWaitMs_, rec.rebuildWaitMs);
      if (rec.rebuildWaitMs > 1.0) ++rebuildsLate_;
    }
    swapIn(std::move(ready_), rec);
    swapFrame_ = -1;
    if (checkpoint_) recomputeSinceCheckpoint(rec);
    worked = true;
  }
  if (!worked) timer.skip();
}

void Simulation::recomputeSinceCheckpoint(FrameRecord& rec) {
  // ruptures seen on the old model during the lag are forgotten: the recomputation finds
  // its own
  for (int e : queued_) pending_[e] = 0;
  queued_.clear();
  const int now = state_.frame;
  state_ = std::move(*checkpoint_);
  checkpoint_.reset();
  const int first = state_.frame;
  FrameRecord redo;
  for (int k = first; k <= now; ++k) {
    checkInterrupt();
    state_.frame = k;
    state_.timeS = k * config_.frameDtS;
    redo = FrameRecord{};
    advance(redo);
    detectRupture(redo);
  }
  state_.frame = now;
  state_.timeS = now * config_.frameDtS;
  // the frame's physics as recomputed
  rec.contactNodes = redo.contactNodes;
  rec.toolCurrentA = redo.toolCurrentA;
  rec.returnCurrentA = redo.returnCurrentA;
  rec.powerW = redo.powerW;
  rec.maxTemperatureC = redo.maxTemperatureC;
  rec.maxVonMisesPa = redo.maxVonMisesPa;
  recomputedFrames_ += now - first + 1;
}

// ---- contacts and guards ----

// The tool's contacts this frame: the surface nodes within tool.contact_distance_m of it;
// along its path since the last frame when it moved more than the median element edge (a
// fast tool crosses nodes between frames; the union of the contacts at poses half an edge
// apart); and, when no node is within reach but the tip is inside the tissue (a blade
// pressed into a coarse mesh, a buried electrode), the nearest node of the tet holding the
// tip, so that the current never vanishes without a word.
std::vector<int> Simulation::findContacts(FrameRecord& rec) const {
  const SimModel& m = *model_;
  const SimState& st = state_;
  std::vector<int> contacts =
      m.contactFinder.find(config_.electrode, st.pose, config_.contactDistanceM);
  const double dt = config_.frameDtS;
  if (st.frame > 0 && m.medianEdgeM > 0) {
    const Vec3 from = config_.toolPath.poseAt(st.timeS - dt).tipM;
    const double moved = (st.pose.tipM - from).norm();
    if (moved > m.medianEdgeM) {
      rec.toolSwept = true;
      const int samples = std::min(256, static_cast<int>(std::ceil(2.0 * moved / m.medianEdgeM)));
      for (int k = 1; k < samples; ++k) {
        const double t = st.timeS - dt + dt * k / samples;
        if (!config_.toolPath.generatorOnAt(t)) continue;
        const auto c = m.contactFinder.find(config_.electrode, config_.toolPath.poseAt(t),
                                            config_.contactDistanceM);
        contacts.insert(contacts.end(), c.begin(), c.end());
      }
      std::sort(contacts.begin(), contacts.end());
      contacts.erase(std::unique(contacts.begin(), contacts.end()), contacts.end());
    }
  }
  for (int v : contacts)
    ESIM_RUN_CHECK(!std::binary_search(m.ground.begin(), m.ground.end(), v),
                   "find_contacts, frame " + std::to_string(st.frame) +
                       ": short circuit: the tool touches node " + std::to_string(v) +
                       " on the return electrode (it went through the tissue)");
  if (!contacts.empty()) return contacts;
  const int tet = aliveTetContaining(m.mesh, *m.geo, m.boundsM, st.pose.tipM);
  if (tet < 0) return contacts;
  int best = -1;
  double bestD = 0;
  for (int v : m.mesh.tets[tet]) {
    if (std::binary_search(m.ground.begin(), m.ground.end(), v)) continue;
    const double d = (m.mesh.nodes[v] - st.pose.tipM).norm();
    if (best < 0 || d < bestD) best = v, bestD = d;
  }
  ESIM_RUN_CHECK(best >= 0, "find_contacts, frame " + std::to_string(st.frame) +
                                ": the tool tip is in a tet whose nodes all lie on the return "
                                "electrode (a short circuit)");
  rec.contactByTet = true;
  return {best};
}

// a stage's field must be finite: else the run stops, naming the stage, frame, entry, value
void Simulation::checkFinite(Stage stage, const char* what, const double* values, int count,
                             const char* unit) const {
  for (int i = 0; i < count; ++i) {
    if (std::isfinite(values[i])) continue;
    const bool perTet = stage == Stage::SolveStress;
    throw RunError(std::string(stageName(stage)) + ", frame " + std::to_string(state_.frame) +
                   ": the " + what + " of " + (perTet ? "tet " : "node ") + std::to_string(i) +
                   " is " + std::to_string(values[i]) + " " + unit +
                   " (the solve diverged; see the hard cases in README)");
  }
}

// The discrete maximum principle: sources are >= 0 and the only sink is convection to the
// ambient temperature, so no node may ever fall below min(initial T, ambient), nor, in a frame
// without a source, rise above max(T before, ambient). Crank-Nicolson and consistent mass
// can break it at large steps (undershoot); recorded with its size and warned, with the
// remedy (backward Euler with lumped mass keeps it on non-obtuse meshes).
void Simulation::checkMaximumPrinciple(double highBeforeC, bool heated, FrameRecord& rec) {
  const Eigen::VectorXd& t = state_.thermal.temperatureC;
  const bool cooled = config_.thermal.convectionW_m2K > 0 && !model_->cooledInitial.empty();
  const double ambient = config_.thermal.ambientTemperatureC;
  // the lower bound holds over the whole run: the initial minimum (or the ambient), never
  // lowered by an earlier frame's undershoot (a slow drift adds up)
  const double lo = cooled ? std::min(lowestC_, ambient) : lowestC_;
  const double hi = cooled ? std::max(highBeforeC, ambient) : highBeforeC;
  double violation = std::max(0.0, lo - t.minCoeff());
  if (!heated) violation = std::max(violation, t.maxCoeff() - hi);
  if (violation <= kMaxPrincipleToleranceK) return;
  rec.maxPrincipleViolationK = violation;
  ++framesMaxPrinciple_;
  worstMaxPrincipleK_ = std::max(worstMaxPrincipleK_, violation);
}

std::vector<std::string> Simulation::warnings() const {
  std::vector<std::string> w;
  const auto frames = [](int n) { return std::to_string(n) + (n == 1 ? " frame" : " frames"); };
  if (framesContactByTet_ > 0)
    w.push_back(frames(framesContactByTet_) +
                ": the tool was inside the tissue with no node within tool.contact_distance_m; "
                "the nearest node of the tet holding its tip carried the current (the mesh is "
                "coarse at the tool: refine it there, or raise tool.contact_distance_m)");
  if (framesToolSwept_ > 0)
    w.push_back(frames(framesToolSwept_) + ": the tool moved more than an element (" +
                std::to_string(model_->medianEdgeM * 1e3) +
                " mm) in one frame; the contacts along its path were taken together (raise "
                "time.fps, or slow the tool)");
  if (framesMaxPrinciple_ > 0)
    w.push_back(frames(framesMaxPrinciple_) + ": the temperature left the bounds of the maximum " +
                "principle by up to " + std::to_string(worstMaxPrincipleK_) +
                " K (an undershoot or overshoot of the time integrator: use "
                "solvers.thermal.integrator backward-euler with solvers.thermal.mass lumped, or "
                "a higher time.fps)");
  if (framesBoilingUnconverged_ > 0)
    w.push_back(frames(framesBoilingUnconverged_) +
                ": the boiling iteration stopped at its iteration cap before its tolerance "
                "(use a smaller frame step: a higher time.fps)");
  return w;
}

// ---- the snapshot ----

SurfaceSnapshot Simulation::snapshot(double displacementScale) {
  StageTimer timer(record_, Stage::Snapshot);
  const SimModel& m = *model_;
  const SimState& st = state_;
  SurfaceSnapshot snap;
  snap.frame = record_.frame;
  snap.timeS = st.timeS;
  const std::vector<int>& vertex_of = m.surfaceVertexOf;
  snap.positionsM = m.surfacePositionsM;
  if (m.structural && displacementScale != 0 && st.displacementM.size() > 0) {
    for (int v : m.surfaceNodes)
      for (int c = 0; c < 3; ++c)
        snap.positionsM[3 * vertex_of[v] + c] +=
            static_cast<float>(displacementScale * st.displacementM[3 * v + c]);
  }
  snap.triangles = m.surfaceTriangles;
  const int nv = snap.numVertices();
  snap.temperatureC.assign(nv, static_cast<float>(config_.thermal.initialTemperatureC));
  snap.coagulation.assign(nv, 0.0f);
  snap.desiccation.assign(nv, 0.0f);
  snap.cutWall = m.surfaceCutWall;
  if (m.thermal) {
    std::vector<float> coag_sum(nv, 0.0f), count(nv, 0.0f);
    for (const auto& f : m.surface) {
      const float c = st.thermal.coagulationTet.empty()
                          ? 0.0f
                          : static_cast<float>(st.thermal.coagulationTet[f.tet]);
      for (int v : f.nodes) {
        coag_sum[vertex_of[v]] += c;
        count[vertex_of[v]] += 1;
      }
    }
    for (int v : m.surfaceNodes) {
      const int i = vertex_of[v];
      snap.temperatureC[i] = static_cast<float>(st.thermal.temperatureC[v]);
      snap.desiccation[i] = static_cast<float>(st.thermal.vaporFraction[v]);
      snap.coagulation[i] = count[i] > 0 ? coag_sum[i] / count[i] : 0.0f;
    }
  }
  if (m.electric) {
    snap.potentialV.resize(nv);
    for (int v : m.surfaceNodes)
      snap.potentialV[vertex_of[v]] = static_cast<float>(st.potentialV[v]);
    ToolSnapshot& t = snap.tool;
    t.present = true;
    t.generatorOn = st.generatorOn;
    t.kind = config_.electrode.kind;
    for (int c = 0; c < 3; ++c) t.tipM[c] = static_cast<float>(st.pose.tipM[c]);
    const Eigen::Quaterniond q = st.pose.orientation.normalized();
    t.orientationWxyz = {static_cast<float>(q.w()), static_cast<float>(q.x()),
                         static_cast<float>(q.y()), static_cast<float>(q.z())};
    t.radiusM = static_cast<float>(config_.electrode.radiusM);
    t.lengthM = static_cast<float>(config_.electrode.lengthM);
    t.widthM = static_cast<float>(config_.electrode.widthM);
  }
  return snap;
}

}  // namespace esim
