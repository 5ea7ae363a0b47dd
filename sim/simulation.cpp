// simulation.cpp - the frame pipeline (see simulation.h).
#include "sim/simulation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <future>
#include <iterator>
#include <limits>
#include <utility>

#include "sim/core_error.h"
#include "sim/electric_phase.h"
#include "sim/rupture_debris.h"

namespace esim {

namespace {

constexpr double kRebuildPrefetchS = 1.0;         // scripted path prefetched after a rebuild [s]
constexpr double kMaxPrincipleToleranceK = 1e-3;  // round-off and obtuse-mesh margin [K]

constexpr const char* kStageNames[kStageCount] = {
    "move_tool", "find_contacts", "solve_potential", "heat",        "solve_stress", "rupture",
    "rebuild",   "snapshot",      "render",          "encode_wait", "write_labels"};

}  // namespace

// this frame's contact as the sub-grid model sees it (solve stage -> heat stage)
struct Simulation::SubgridFrame {
  bool active = false;
  double innerM = 0, zoneM = 0, patchM = 0;  // a, r_z, a_p
  std::vector<int> nodes;                    // contact nodes
  std::vector<double> weights;               // their shares of the current
  std::vector<double> shellW;                // Joule power per zone shell
  double directW = 0;                        // power of r_z < r < a_p, to the nodes
  double residenceS = 0;                     // zone residence time (inf at rest)
  int vaporTet = -1;                         // alive tet holding the deepest point (-1: vent)
};

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
  if (config.subgrid.mode != SubgridMode::Off) {
    ESIM_VERIFY(config.contactNodes == ContactNodes::Surface,
                std::string("subgrid_contact.mode = ") + subgridModeName(config.subgrid.mode) +
                    " with tool.contact = volume: the sub-grid contact model is of a tool at "
                    "the tissue's surface (a flat contact under it); set one of them off or "
                    "to surface");
    ESIM_VERIFY(ph.electric && ph.thermal,
                std::string("subgrid_contact.mode = ") + subgridModeName(config.subgrid.mode) +
                    ": the sub-grid contact model needs the electric and thermal phases; add "
                    "them or set it off");
    ESIM_VERIFY(config.subgrid.areaFactor > 0 && std::isfinite(config.subgrid.areaFactor),
                "subgrid_contact.area_factor must be a positive finite number");
  }
  if (ph.structural) {
    ESIM_VERIFY(config.clampBandM >= 0 && std::isfinite(config.clampBandM),
                "effects.structural_clamp_band_m must be >= 0");
    ESIM_VERIFY(config.criticalStressPa > 0 && std::isfinite(config.criticalStressPa),
                "material.critical_stress_pa must be > 0");
    ESIM_VERIFY(config.criticalStressRadiusM >= 0 && std::isfinite(config.criticalStressRadiusM),
                "material.critical_stress_radius_m must be >= 0");
    ESIM_VERIFY(config.vaporLiquidVolumeRatio >= 1,
                "material.vapor_liquid_volume_ratio must be >= 1");
    ESIM_VERIFY(
        config.structural.volumetric == VolumetricStrain::element ||
            config.structural.solveMethod == StructuralSolveMethod::full,
        std::string("solvers.structural.volumetric = nodal with solvers.structural.method "
                    "= ") +
            (config.structural.solveMethod == StructuralSolveMethod::local ? "local" : "coarse") +
            ": the volumetric strain at the nodes works with the full method only; set "
            "the method to full or the volumetric strain to element");
  }
}

namespace {

// "" unless linear tets with the volumetric strain per tet would lock at this Poisson ratio
// (sim/structural.h, VolumetricStrain: von Mises 4 % too high at 0.48 in its test, 9 % at 0.49)
std::string lockingWarning(const SimulationConfig& config) {
  const double nu = config.structural.poissonRatio;
  if (!config.phases.structural || config.structural.volumetric != VolumetricStrain::element ||
      nu < kLockingPoissonRatio)
    return "";
  return "material.poisson_ratio = " + messageNumber(nu) +
         " with solvers.structural.volumetric: element: linear tets lock as the tissue nears "
         "incompressibility, so their von Mises stress is too high and more tets break (in "
         "sim/structural.h's test of an expanding inclusion: +4 % at 0.48, +9 % at 0.49, +60 % "
         "at 0.499); set solvers.structural.volumetric: nodal";
}

}  // namespace

std::vector<std::string> configWarnings(const SimulationConfig& config) {
  std::vector<std::string> out;
  if (std::string w = lockingWarning(config); !w.empty()) out.push_back(std::move(w));
  return out;
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

// "" unless the tool's path goes deeper under the tissue's surface (as it is at the start)
// than its contact distance and 1 mm more while contact is found among the surface's nodes
// (tool.contact: surface): such a tool touches the tissue only where it enters it
// (liver_cut's path ran 3.4-3.7 mm deep, its comment said 0.4 mm). The sphere's deepest
// point, or 9 points of the blade's mid-plane (its corners, the middles of its edges and its
// centre: under a flat surface the deepest point of the rectangle is a corner, so a blade
// laid flat or tilted heel down is seen, not only its tip), at 61 times over the path's span.
std::string toolDepthWarning(const TetMesh& mesh, const std::vector<BoundaryFace>& surface,
                             const SimulationConfig& config) {
  const ToolPath& path = config.toolPath;
  if (path.keys.empty() || surface.empty() || config.contactNodes == ContactNodes::Volume)
    return "";
  const ElectrodeShape& shape = config.electrode;
  std::vector<Vec3> points{Vec3::Zero()};  // local; the tip first (a tie keeps it)
  if (shape.kind == ElectrodeKind::Blade)
    for (double z : {0.0, 0.5, 1.0})
      for (double x : {0.0, -0.5, 0.5})  // (ties keep the centre line)
        if (x != 0 || z != 0) points.emplace_back(x * shape.widthM, 0, z * shape.lengthM);
  const double t0 = path.keys.front().timeS, t1 = path.keys.back().timeS;
  const int samples = t1 > t0 ? 61 : 1;
  double deepestM = 0, atS = t0;
  Vec3 where = Vec3::Zero();
  for (int k = 0; k < samples; ++k) {
    const double t = samples > 1 ? t0 + (t1 - t0) * k / (samples - 1) : t0;
    const Vec3 tip = path.positionAt(t);
    const Eigen::Quaterniond turn = path.orientationAt(t);
    for (const Vec3& local : points) {
      const double d = signedDistanceToSurface(mesh, surface, tip + turn * local);
      const double depth = shape.kind == ElectrodeKind::Sphere ? shape.radiusM - d : -d;
      if (depth > deepestM + 1e-9) {  // (1 nm: rounding does not move the time named)
        deepestM = depth;
        atS = t;
        where = local;
      }
    }
  }
  if (deepestM <= config.contactDistanceM + 0.001) return "";
  char b[220];
  int n = std::snprintf(b, sizeof b, "the tool reaches %.1f mm under the tissue's surface",
                        deepestM * 1e3);
  if (where != Vec3::Zero())
    n += std::snprintf(b + n, sizeof b - n, " with its blade %.1f mm from the tip%s",
                       where.z() * 1e3, where.x() != 0 ? " at a side edge" : "");
  std::snprintf(b + n, sizeof b - n, " at t = %.2f s", atS);
  return std::string(b) + " (tool.path; the surface as it is at the start): contact is found " +
         "among the surface's nodes, so a tool deeper than tool.contact_distance_m (" +
         messageNumber(config.contactDistanceM * 1e3) +
         " mm) touches the tissue only where it enters it; keep the tool within that of the "
         "surface, or set tool.contact: volume for a tool inside the tissue";
}

// "" when every piece of the mesh has a node on the return electrode; else what the pieces
// without one are (a second body in a mesh file, a fragment): no current flows in them
std::string unreturnedPiecesWarning(const TetMesh& mesh, const std::vector<int>& groundNodes) {
  int count = 0;
  const std::vector<int> piece = nodePieces(mesh, &count);
  std::vector<std::uint8_t> grounded(count, 0);
  for (int v : groundNodes)
    if (piece[v] >= 0) grounded[piece[v]] = 1;
  std::vector<int> nodes(count, 0);
  std::vector<Eigen::AlignedBox3d> box(count);
  for (int v = 0; v < mesh.numNodes(); ++v)
    if (piece[v] >= 0 && !grounded[piece[v]]) {
      ++nodes[piece[v]];
      box[piece[v]].extend(mesh.nodes[v]);
    }
  int loose = 0, first = -1;
  for (int p = 0; p < count; ++p)
    if (!grounded[p]) {
      ++loose;
      if (first < 0) first = p;
    }
  if (loose == 0) return "";
  const auto mm = [](const Vec3& p) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "[%.1f, %.1f, %.1f]", 1e3 * p.x(), 1e3 * p.y(), 1e3 * p.z());
    return std::string(buf);
  };
  return "the mesh is " + std::to_string(count) + " separate pieces, and " + std::to_string(loose) +
         (loose == 1 ? " of them has" : " of them have") +
         " no node on the return electrode (the first: " + std::to_string(nodes[first]) +
         " nodes, from " + mm(box[first].min()) + " to " + mm(box[first].max()) +
         " mm): no current flows in it, and a tool touching it delivers none (one body per "
         "mesh file, or a return_electrode disc that reaches each piece)";
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
  return "return_electrode: no mesh node lies on the return electrode disc (centre [" +
         messageNumber(r.centerM.x()) + ", " + messageNumber(r.centerM.y()) + ", " +
         messageNumber(r.centerM.z()) + "] m, radius " + messageNumber(r.radiusM) +
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
  const double ground =
      config.phases.electric
          ? static_cast<double>(
                returnElectrodeNodes(mesh, surfaceNodes, config.returnElectrode).size())
          : 0.0;
  if (config.phases.electric)
    ESIM_VERIFY(ground > 0, returnElectrodeMessage(config.returnElectrode));
  const double nf = mesh.numNodes() - ground;
  if (config.phases.electric &&
      resolveElectricStrategy(config.electricSolver, nf) == ElectricStrategy::DenseInverse) {
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
                "effects.structural_clamp_band_m = " + messageNumber(config.clampBandM) +
                    " m: no surface node lies within it of the lowest node (nothing holds the "
                    "tissue)");
  // the nonlocal criterion's bound on a frame's work (its constructor refuses)
  if (config.phases.rupture && config.criticalStressRadiusM > 0)
    NonlocalStress(mesh, tetGeometry(mesh), config.criticalStressRadiusM);
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
  // a face of the initial surface belongs to one alive tet, and only that tet can hold it
  // on any later surface (tets never come back): flags by (tet, local face) say the same as
  // the face's nodes would
  auto initialFaces = std::make_shared<std::vector<std::uint8_t>>(4 * mesh.tets.size(), 0);
  for (const auto& f : surface) (*initialFaces)[boundaryFaceIndex(mesh, f)] = 1;
  m.initialFaces = std::move(initialFaces);
  const PhaseSet& ph = config_.phases;
  if (ph.electric) {
    const std::vector<int> groundNodes =
        returnElectrodeNodes(mesh, surfaceNodes, config_.returnElectrode);
    const size_t ground = groundNodes.size();
    ESIM_VERIFY(ground > 0, returnElectrodeMessage(config_.returnElectrode));
    piecesWarning_ = unreturnedPiecesWarning(mesh, groundNodes);
    depthWarning_ = toolDepthWarning(mesh, surface, config_);
    // auto: one strategy for the whole run, from the initial mesh (a rebuild keeps it)
    config_.electricSolver.strategy = resolveElectricStrategy(
        config_.electricSolver, static_cast<double>(mesh.numNodes() - ground),
        ph.rupture && config_.rebuildMode == RebuildMode::Update);
    // only capacitance caches what the tool will touch: the others get no scripted contacts
    if (config_.electricSolver.strategy != ElectricStrategy::Capacitance)
      config_.prefetchUntilS = 0;
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
  if (ph.rupture && (config_.rebuildMode == RebuildMode::Update || config_.debrisVolumeM3 > 0))
    m.faceNeighbours =
        std::make_shared<const std::vector<std::array<int, 4>>>(tetFaceNeighbours(mesh));
  if (ph.rupture && config_.rebuildMode == RebuildMode::Update)
    m.nodeTets = std::make_shared<const Adjacency>(nodeTets(mesh));
  if (config_.subgrid.mode != SubgridMode::Off) {
    auto faces = std::make_shared<std::vector<SimModel::SurfaceFace>>();
    for (const auto& f : surface) {
      SimModel::SurfaceFace sf{
          mesh.nodes[f.nodes[0]], mesh.nodes[f.nodes[1]], mesh.nodes[f.nodes[2]], Vec3::Zero(), {}};
      const Vec3 n = (sf.b - sf.a).cross(sf.c - sf.a);
      if (!(n.norm() > 0)) continue;  // a degenerate face has no plane
      sf.normal = n.normalized();
      sf.box.extend(sf.a);
      sf.box.extend(sf.b);
      sf.box.extend(sf.c);
      faces->push_back(sf);
    }
    m.initialSurface = std::move(faces);
    electrodeSamples_ = electrodeSurfaceSamples(config_.electrode);
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
  model_ = buildModel(
      std::move(alive),
      std::vector<double>(ph.electric ? model_->mesh.numTets() : 0, config_.conductivityS_m), 0,
      prefetchTo, true);
  // the work of an explicit frame is bounded: refused up front, never a frame of minutes
  if (model_->thermal) checkExplicitBound(*model_->thermal, config_);
  if (ph.rupture && config_.criticalStressRadiusM > 0)
    nonlocal_ =
        std::make_unique<NonlocalStress>(model_->mesh, *model_->geo, config_.criticalStressRadiusM);
  if (ph.rupture && config_.debrisVolumeM3 > 0) {
    debrisSupported_.assign(model_->mesh.numNodes(), 0);
    for (const Support& s : model_->supports) debrisSupported_[s.node] = 1;
  }
}

// the pieces removing `broken` cuts loose, small enough to be debris, join it (pending
// like the tets that broke); returns how many tets they hold
int Simulation::addDebris(std::vector<int>& broken) {
  if (config_.debrisVolumeM3 <= 0) return 0;
  const SimModel& m = *model_;
  std::vector<int> debris = debrisCutLoose(m.mesh, *m.faceNeighbours, *m.geo, debrisSupported_,
                                           broken, config_.debrisVolumeM3);
  for (int e : debris) pending_[e] = 1;
  broken.insert(broken.end(), debris.begin(), debris.end());
  return static_cast<int>(debris.size());
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
  if (config_.subgrid.mode != SubgridMode::Off) {
    s.trappedVaporKg.assign(nt, 0.0);
    s.pocketStressPa.assign(nt, 0.0);
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
    double x = th.vaporFractionTet.empty() ? 0.0 : th.vaporFractionTet[e];
    // the sub-grid contact zone's vapour, trapped in this tet: a fraction of its water
    if (!state_.trappedVaporKg.empty() && state_.trappedVaporKg[e] > 0) {
      const double waterKg =
          config_.thermal.waterFraction * config_.thermal.densityKg_m3 * (*model_->geo)[e].volume;
      x = waterKg > 0 ? std::min(1.0, x + state_.trappedVaporKg[e] / waterKg) : 1.0;
    }
    state_.eigenstrain[e] = volumetricExpansion(model_->expansion, te, x);
  }
}

namespace {

// the nodes the tool may touch (tool.contact): the surface's, or those of the alive tets
// (volumeNodes is filled exactly for the volume rule)
const std::vector<int>& contactCandidates(const SimModel& m) {
  return m.volumeNodes.empty() ? m.surfaceNodes : m.volumeNodes;
}

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
    if ((*m.initialFaces)[boundaryFaceIndex(m.mesh, f)]) continue;
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
                                                 int prefetchTo, bool concurrent) const {
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
  m.initialSurface = base.initialSurface;
  m.surface = boundaryFaces(m.mesh);
  m.surfaceNodes = boundaryNodes(m.mesh, m.surface);
  if (config_.phases.electric && config_.contactNodes == ContactNodes::Volume)
    m.volumeNodes = aliveNodes(m.mesh);
  buildSnapshotTopology(m);
  checkInterrupt();  // between the phases' builds: a stop waits for one factorization at most
  // concurrent: the structural phase is built on a thread of its own meanwhile (it reads the
  // mesh and supports only and owns its CHOLMOD workspace: the same arithmetic, the same
  // model); an error of the others comes first, as when it was built last. Not in a
  // background rebuild, whose job already shares the 2 cores with the frame loop. Measured
  // (each against the sequential build, one binary after the other): liver_incision's setup
  // 11.1 / 13.7 -> 6.7 / 6.5 s (two pairs, timing.json setup_s), slab_cut's 1.81 / 1.47 ->
  // 1.25 / 1.17 s; esim bench cut --sizes 8000 --frames 30 --strategy synchronous, rebuild
  // median 1451 -> 959 ms
  std::future<std::unique_ptr<StructuralPhase>> structural;
  if (config_.phases.structural) {
    StructuralOptions so = config_.structural;
    // update mode: the factor's conversion for low-rank updates is paid here, not in a frame
    so.prepareForUpdates = config_.phases.rupture && config_.rebuildMode == RebuildMode::Update;
    // its errors about the supports name the clamp that made them
    const size_t clamped = m.supports.size() / 3;
    so.supportsNote =
        "clamped: " + std::to_string(clamped) + (clamped == 1 ? " bottom node" : " bottom nodes") +
        " within effects.structural_clamp_band_m = " + messageNumber(config_.clampBandM) +
        " m of the lowest node";
    structural = std::async(concurrent ? std::launch::async : std::launch::deferred, [&m, so] {
      return std::make_unique<StructuralPhase>(m.mesh, so, m.supports);
    });
  }
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
    m.contactFinder = ContactFinder(m.mesh, contactCandidates(m));
    m.sigmaAssembled = std::move(sigma);
    m.stiffness = assembleStiffness(m.mesh, *m.geo, m.sigmaAssembled);
    m.electric = makeElectricSolver(config_.electricSolver);
    m.electric->setContactCandidates(contactCandidates(m));
    m.electric->setNodePositions(m.mesh.nodes);
    m.electric->setMatrix(m.stiffness, m.ground);
    if (prefetchTo >= prefetchFrom)
      m.electric->prefetch(scriptedContacts(m.contactFinder, m.ground, prefetchFrom, prefetchTo));
  }
  if (structural.valid()) m.structural = structural.get();
  checkInterrupt();
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
                                                   int prefetchTo, bool concurrent) const {
  try {
    return buildModel(std::move(alive), std::move(sigma), first, prefetchTo, concurrent);
  } catch (const Error& e) {
    throwRebuildError(e, first - 1);
  }
}

// an error of a rebuild or an update after the rupture of frame ruptureFrame: a run that
// cannot go on (internal checks and interruptions pass as they are)
void Simulation::throwRebuildError(const Error& e, int ruptureFrame) const {
  if (e.kind() == ErrorKind::Internal || dynamic_cast<const Interrupted*>(&e)) throw;
  std::string what = e.what();
  if (what.rfind("rupture: ", 0) == 0) what.erase(0, 9);  // said once, with the frame
  throw RunError("rupture, frame " + std::to_string(ruptureFrame) + ": " + what);
}

// solvers.rebuild.mode: update. The model edited in place in the frame the tets break:
// the alive set, the surface (removeFromBoundary: local), the snapshot topology, the
// return electrode and the contact finder (over the surface), and each phase's removal
// update. Its errors are a rebuild's.
void Simulation::updateModel(const std::vector<int>& broken, FrameRecord& rec) {
  const auto t0 = std::chrono::steady_clock::now();
  SimModel& m = *model_;
  joinPrefetch();
  joinStructural();
  auto part = [&rec, tp = t0](int k) mutable {  // closes part k of rec.updatePartMs
    const auto now = std::chrono::steady_clock::now();
    rec.updatePartMs[k] = std::chrono::duration<double, std::milli>(now - tp).count();
    tp = now;
  };
  try {
    for (int e : broken) m.mesh.alive[e] = 0;
    ESIM_RUN_CHECK(m.mesh.numAlive() > 0, "rupture: every element of the tissue has been removed");
    if (m.structural) {  // the factor's update on a thread, joined by the next structural
      structuralJobFrame_ = state_.frame;  // solve (see the header); its pieces here
      auto job = std::make_shared<std::packaged_task<StructuralUpdateStats()>>(
          m.structural->beginRemoval(broken));
      structuralJob_ = job->get_future();
      structuralRun_ = runOnHelper([job] { (*job)(); });
      if (!structuralRun_.running()) (*job)();  // no thread to be had: here
    }
    removeFromBoundary(m.mesh, *m.faceNeighbours, broken, m.surface);
    const BoundaryNodeChange moved =
        updateBoundaryNodes(m.mesh, *m.faceNeighbours, *m.nodeTets, broken, m.surfaceNodes);
    buildSnapshotTopology(m);
    part(0);
    if (m.thermal) m.thermal->removeTets(broken);
    part(1);
    if (m.electric) {
      // the return electrode and the contact finder edited by the nodes that left or joined
      // the surface (returnElectrodeNodes of the new surface, the finder of the new surface)
      std::vector<int> ground,
          onPad = returnElectrodeNodes(m.mesh, moved.joined, config_.returnElectrode);
      std::set_difference(m.ground.begin(), m.ground.end(), moved.left.begin(), moved.left.end(),
                          std::back_inserter(ground));
      ground.insert(ground.end(), onPad.begin(), onPad.end());
      std::sort(ground.begin(), ground.end());
      ESIM_RUN_CHECK(!ground.empty(),
                     "rupture: the cut removed all the tissue on the return electrode");
      m.ground = std::move(ground);
      if (config_.contactNodes == ContactNodes::Volume) {
        // the candidates are the nodes of alive tets: those whose last tet broke leave
        const std::vector<int> gone = nodesWithoutAliveTets(m.mesh, *m.nodeTets, broken);
        std::vector<int> kept;
        std::set_difference(m.volumeNodes.begin(), m.volumeNodes.end(), gone.begin(), gone.end(),
                            std::back_inserter(kept));
        m.volumeNodes = std::move(kept);
        m.contactFinder.update(m.mesh, gone, {});
      } else {
        m.contactFinder.update(m.mesh, moved.left, moved.joined);
      }
      // the entries of the removed tets summed again (bitwise a fresh assembly; the others
      // untouched: what updateMatrix reads the change from), then the solver's low-rank
      // update, then the new candidates (the capacitance cache is kept; new surface nodes
      // get their columns on first touch)
      removeFromStiffness(m.stiffness, m.mesh, *m.geo, m.sigmaAssembled, *m.nodeTets, broken);
      // only the removed tets' nodes have columns that changed: the solver reads those
      // (FreeBase::diff), not the whole matrix
      const std::vector<int> changed = nodesOfTets(m.mesh, broken);
      m.electric->updateMatrix(m.stiffness, m.ground, &changed);
      m.electric->setContactCandidates(contactCandidates(m));
      // the columns the scripted tool will need on the new surface in the next second, on a
      // thread while the frame is drawn (the next solve joins it): not solved on first touch
      if (config_.prefetchUntilS > 0) {
        const int first = state_.frame + 1;
        const int last =
            std::min(static_cast<int>(std::ceil(config_.prefetchUntilS / config_.frameDtS)),
                     first + static_cast<int>(std::ceil(kRebuildPrefetchS / config_.frameDtS)));
        std::vector<int> nodes = scriptedContacts(m.contactFinder, m.ground, first, last);
        if (!nodes.empty())
          prefetchJob_ =
              std::async(std::launch::async, [solver = m.electric.get(), nodes = std::move(nodes)] {
                deprioritizeThisThread();
                solver->prefetch(nodes);
              });
      }
    }
    part(2);
  } catch (const Error& e) {
    // the alive set is edited already: the run's summary counts what it shows
    removedTets_ += static_cast<int>(broken.size());
    rebuildBuildMs_ +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    ++rebuilds_;
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
  int debris = 0;  // of which cut loose as debris
};

void Simulation::swapIn(std::unique_ptr<Rebuilt> r, FrameRecord& rec) {
  for (int e : r->removed) pending_[e] = 0;
  removedTets_ += static_cast<int>(r->removed.size());
  rec.removedTets = static_cast<int>(r->removed.size());
  debrisTets_ += r->debris;
  rebuildBuildMs_ += r->model->buildMs;
  model_ = std::move(r->model);
  ++rebuilds_;
}

void Simulation::startRebuild(const std::vector<int>& broken, int debris) {
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
    ready_->model = rebuildModel(std::move(alive), std::move(sigma), first, prefetchTo, true);
    ready_->removed = broken;
    ready_->debris = debris;
    swapFrame_ = state_.frame;
    return;
  }
  if (config_.recomputeLagFrames && config_.rebuildLagFrames > 0) {
    checkpoint_ = std::make_unique<SimState>(state_);
    checkpoint_->frame = state_.frame + 1;  // the first frame to compute again
  }
  // a pure function of the fixed parts of the model and these copies: the result does not
  // depend on when the thread runs, and it is swapped in at a fixed frame
  job_ = std::async(std::launch::async, [this, alive = std::move(alive), broken, debris,
                                         sigma = std::move(sigma), first, prefetchTo]() mutable {
    auto r = std::make_unique<Rebuilt>();
    // (on the job's thread, beside the frame loop: the phases one after the other)
    r->model = rebuildModel(std::move(alive), std::move(sigma), first, prefetchTo, false);
    r->removed = std::move(broken);
    r->debris = debris;
    return r;
  });
  swapFrame_ = state_.frame + config_.rebuildLagFrames;
}

Simulation::~Simulation() {
  if (job_.valid()) job_.wait();                      // the job reads model_
  if (prefetchJob_.valid()) prefetchJob_.wait();      // and this one the electric solver
  if (structuralJob_.valid()) structuralJob_.wait();  // and this one the structural phase
  structuralRun_.wait();
}

void Simulation::waitStructural() const {
  if (!structuralJob_.valid()) return;
  try {
    structuralJobStats_ = structuralJob_.get();
    structuralRefactorizations_ += structuralJobStats_.refactorized ? 1 : 0;
  } catch (...) {
    structuralError_ = std::current_exception();
  }
  structuralRun_.wait();  // the helper free again (it set the result as its last step)
}

// the structural update in flight joined; its error is the rupture's (throwRebuildError)
void Simulation::joinStructural() {
  if (structuralJob_.valid()) {
    while (structuralJob_.wait_for(std::chrono::milliseconds(20)) != std::future_status::ready)
      checkInterrupt();  // (the update runs on to its end, as a CHOLMOD call cannot be
                         // stopped; whoever destroys the simulation waits for it)
    waitStructural();
    record_.structuralUpdateMs = structuralJobStats_.seconds * 1e3;
    record_.structuralUpdateWork =
        structuralJobStats_.refactorized ? 0.0 : structuralJobStats_.updateWork;
  }
  if (!structuralError_) return;
  const std::exception_ptr error = std::exchange(structuralError_, nullptr);
  try {
    std::rethrow_exception(error);
  } catch (const Error& e) {
    throwRebuildError(e, structuralJobFrame_);
  }
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

double Simulation::limitElectricCache(double bytes) {
  joinPrefetch();
  // a background rebuild's job reads config_ (its model keeps the cap it was built with)
  if (job_.valid()) job_.wait();
  config_.electricSolver.cacheMemoryLimitBytes = bytes;
  return model_->electric ? model_->electric->limitCache(bytes) : 0.0;
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
  if (rec.generatorOn) ++framesGeneratorOn_;
  if (rec.contactNodes > 0) ++framesInContact_;
  if (rec.toolSwept) ++framesToolSwept_;
  if (rec.subgridActive) ++framesSubgrid_;
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
  if (subgridFrame_) subgridFrame_->active = false;

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
      rec.electricPowerError =
          m.electric->solve(st.contacts, config_.toolVoltageV, st.potentialV).powerError;
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
      if (config_.subgrid.mode != SubgridMode::Off && m.thermal)
        subgridContact(totals.toolCurrentA, power_w, rec);
    }
  }
  rec.powerW = power_w;
  st.energyJ += power_w * dt;

  // ---- 4. heat: Joule (or prescribed) source, conduction, boiling ----
  checkInterrupt();
  if (m.thermal) {
    StageTimer timer(rec, Stage::Heat);
    const double sourceBeforeJ = st.thermal.sourceJ;

    const double highBeforeC = tissueTemperatureRangeC().second;
    std::vector<ThermalPhase::NodalSource> nodal;
    if (config_.subgrid.mode != SubgridMode::Off) subgridHeat(nodal, rec);
    const auto stats =
        m.thermal->step(dt, m.electric ? st.joulePowerW_m3 : m.prescribedSource, st.thermal, nodal);
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
    const auto [lowC, highC] = tissueTemperatureRangeC();
    checkMaximumPrinciple(highBeforeC, lowC, highC, st.thermal.sourceJ > sourceBeforeJ, rec);
    rec.maxTemperatureC = highC;
    st.maxTemperatureC = std::max(st.maxTemperatureC, rec.maxTemperatureC);
  } else {
    rec.maxTemperatureC = config_.thermal.initialTemperatureC;
  }

  // ---- 5. stress from the water's expansion ----
  checkInterrupt();
  if (m.structural) {
    StageTimer timer(rec, Stage::SolveStress);
    joinStructural();  // a removal's update in flight (update mode): its wait counts here
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
  const std::vector<double>& pocket = state_.pocketStressPa;  // sub-grid vapour pockets
  // the nonlocal criterion: the averaged stress's tets (ascending), then the pockets'
  std::vector<int> averaged;
  if (nonlocal_ && !vm.empty()) averaged = nonlocal_->broken(mesh, vm, config_.criticalStressPa);
  auto over = averaged.begin();
  for (int e = 0; e < mesh.numTets(); ++e) {
    bool stress = false;
    if (!nonlocal_) {
      stress = !vm.empty() && vm[e] > config_.criticalStressPa;
    } else if (over != averaged.end() && *over == e) {
      stress = true;
      ++over;
    }
    if (mesh.isAlive(e) && !pending_[e] &&
        (stress || (!pocket.empty() && pocket[e] > config_.criticalStressPa))) {
      queued_.push_back(e);
      pending_[e] = 1;
    }
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
      debrisTets_ += addDebris(broken);  // counted as the removal is (a failed one too)
      updateModel(broken, rec);
    }
    return;
  }
  bool worked = false;
  if (swapFrame_ < 0 && !queued_.empty()) {  // nothing in flight: start with the queue
    std::vector<int> broken;
    broken.swap(queued_);  // they stay pending until swapIn
    const int debris = addDebris(broken);
    startRebuild(broken, debris);
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
  rec.subgridActive = redo.subgridActive;
  rec.subgridPowerW = redo.subgridPowerW;
  rec.subgridZoneTemperatureC = redo.subgridZoneTemperatureC;
  rec.subgridVaporKg = redo.subgridVaporKg;
  rec.subgridPocketStressPa = redo.subgridPocketStressPa;
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
  const auto point = [](const Vec3& p) {
    return "(" + messageNumber(p.x()) + ", " + messageNumber(p.y()) + ", " + messageNumber(p.z()) +
           ") m";
  };
  for (int v : contacts)
    ESIM_RUN_CHECK(!std::binary_search(m.ground.begin(), m.ground.end(), v),
                   "find_contacts, frame " + std::to_string(st.frame) +
                       ": short circuit: the tool touches node " + std::to_string(v) +
                       " on the return electrode, at " + point(m.mesh.nodes[v]) + " (tool tip at " +
                       point(st.pose.tipM) +
                       ", tool.contact_distance_m = " + messageNumber(config_.contactDistanceM) +
                       " m): the tool went through the tissue, or its contact distance reaches "
                       "across it");
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

// the coldest and hottest nodes of the tissue left. A node whose last tet broke (removed
// tissue) keeps the temperature it had then and no longer conducts: left in, it was reported
// as the tissue's maximum for the rest of the run (slab_cut at 2000 V: 1360 C in every frame
// after the removal). The maximum principle is checked on the same nodes. With no tissue
// left, the initial temperature (as with no thermal phase).
std::pair<double, double> Simulation::tissueTemperatureRangeC() const {
  const Eigen::VectorXd& t = state_.thermal.temperatureC;
  double low = std::numeric_limits<double>::infinity(), high = -low;
  for (int i = 0; i < static_cast<int>(t.size()); ++i)
    if (model_->thermal->nodeActive(i)) {
      low = std::min(low, t[i]);
      high = std::max(high, t[i]);
    }
  if (low > high) return {config_.thermal.initialTemperatureC, config_.thermal.initialTemperatureC};
  return {low, high};
}

// The discrete maximum principle: sources are >= 0 and the only sink is convection to the
// ambient temperature, so no node may ever fall below min(initial T, ambient), nor, in a frame
// without a source, rise above max(T before, ambient). Crank-Nicolson and consistent mass
// can break it at large steps (undershoot); recorded with its size and warned, with the
// remedy (backward Euler with lumped mass keeps it on non-obtuse meshes).
void Simulation::checkMaximumPrinciple(double highBeforeC, double lowC, double highC, bool heated,
                                       FrameRecord& rec) {
  const bool cooled = config_.thermal.convectionW_m2K > 0 && !model_->cooledInitial.empty();
  const double ambient = config_.thermal.ambientTemperatureC;
  // the lower bound holds over the whole run: the initial minimum (or the ambient), never
  // lowered by an earlier frame's undershoot (a slow drift adds up)
  const double lo = cooled ? std::min(lowestC_, ambient) : lowestC_;
  const double hi = cooled ? std::max(highBeforeC, ambient) : highBeforeC;
  double violation = std::max(0.0, lo - lowC);
  if (!heated) violation = std::max(violation, highC - hi);
  if (violation <= kMaxPrincipleToleranceK) return;
  rec.maxPrincipleViolationK = violation;
  ++framesMaxPrinciple_;
  worstMaxPrincipleK_ = std::max(worstMaxPrincipleK_, violation);
}

// a scene whose tool never touched the tissue ran without current: say so, with the tool's
// closest approach to the surface nodes over the frames with the generator on
std::string Simulation::noContactWarning() const {
  if (!model_->electric || state_.frame == 0 || framesInContact_ > 0) return "";
  if (framesGeneratorOn_ == 0)
    return "the generator was off in every frame (" + std::to_string(state_.frame) +
           "; tool.generator_on): no current flowed";
  const SimModel& m = *model_;
  double closestM = INFINITY, atS = 0;
  for (int f = 0; f < state_.frame; ++f) {
    const double t = f * config_.frameDtS;
    if (!config_.toolPath.generatorOnAt(t)) continue;
    const ToolPose pose = config_.toolPath.poseAt(t);
    for (int v : m.surfaceNodes) {
      const double d = electrodeDistance(config_.electrode, pose, m.mesh.nodes[v]);
      if (d < closestM) closestM = d, atS = t;
    }
  }
  Eigen::AlignedBox3d box;
  for (int v : m.surfaceNodes) box.extend(m.mesh.nodes[v]);
  char w[400];
  std::snprintf(w, sizeof w,
                "the tool touched the tissue in none of the frames with the generator on (%d): no "
                "current flowed. Its closest approach to a surface node was %.2f mm (t = %.3f s), "
                "beyond tool.contact_distance_m = %.2f mm; the tissue spans x [%.4f, %.4f], y "
                "[%.4f, %.4f], z [%.4f, %.4f] m: check tool.path",
                framesGeneratorOn_, closestM * 1e3, atS, config_.contactDistanceM * 1e3,
                box.min().x(), box.max().x(), box.min().y(), box.max().y(), box.min().z(),
                box.max().z());
  return w;
}

std::vector<std::string> Simulation::warnings() const {
  std::vector<std::string> w;
  const auto frames = [](int n) { return std::to_string(n) + (n == 1 ? " frame" : " frames"); };
  if (!piecesWarning_.empty()) w.push_back(piecesWarning_);
  if (!depthWarning_.empty()) w.push_back(depthWarning_);
  for (std::string& c : configWarnings(config_)) w.push_back(std::move(c));
  if (std::string nc = noContactWarning(); !nc.empty()) w.push_back(std::move(nc));
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
  if (framesSubgrid_ > 0)
    w.push_back(frames(framesSubgrid_) +
                ": the mesh was coarser than the tool's contact; the sub-grid contact model "
                "(subgrid_contact.mode) added the contact's spreading resistance and heated its "
                "calibrated contact zone (sim/subgrid_contact.h; resolve the contact to do "
                "without it)");
  if (framesBoilingUnconverged_ > 0)
    w.push_back(frames(framesBoilingUnconverged_) +
                ": the boiling iteration stopped at its iteration cap before its tolerance "
                "(use a smaller frame step: a higher time.fps)");
  return w;
}

// ---- the sub-grid contact (sim/subgrid_contact.h) ----

namespace {

// closest point of triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5)
Vec3 closestOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double den = 1.0 / (va + vb + vc);
  return a + ab * (vb * den) + ac * (vc * den);
}

}  // namespace

SubgridZoneParams Simulation::subgridZoneParams() const {
  const ThermalParams& t = config_.thermal;
  SubgridZoneParams p;
  p.heatCapacityJ_m3K = t.heatCapacityJ_m3K;
  p.conductivityW_mK = t.conductivityW_mK;
  p.initialTemperatureC = t.initialTemperatureC;
  p.boiling = config_.phases.boiling;
  p.boilingTemperatureC = t.boilingTemperatureC;
  p.waterKg_m3 = t.waterFraction * t.densityKg_m3;
  p.latentJ_m3 = p.waterKg_m3 * t.latentHeatJ_kg;
  return p;
}

double Simulation::subgridStoredEnergyJ() const {
  double e = zoneEnergyJ(state_.subgridZone);
  const std::vector<double>& trapped = state_.trappedVaporKg;
  double kg = 0;
  for (size_t t = 0; t < trapped.size(); ++t)
    if (trapped[t] > 0 && model_->mesh.isAlive(static_cast<int>(t))) kg += trapped[t];
  return e + kg * config_.thermal.latentHeatJ_kg;
}

// Solve stage, after the mesh's solve with the contact nodes at V (current I_1): the true
// contact (immersion in the intact tissue, wetted area, radius a), the mesh's contact patch
// (a_p), and when the model applies this frame the series resistance R(a, a_p): potential,
// currents and Joule power scaled (s, s, s^2), powerW the power delivered V I.
void Simulation::subgridContact(double toolCurrentA, double& powerW, FrameRecord& rec) {
  SimModel& m = *model_;
  SimState& st = state_;
  if (!subgridFrame_) subgridFrame_ = std::make_unique<SubgridFrame>();
  SubgridFrame& f = *subgridFrame_;
  f.active = false;
  const double v = config_.toolVoltageV;
  if (!(toolCurrentA > 0) || v == 0 || st.contacts.empty()) return;
  // the intact tissue's surface at the tool: the nearest initial boundary face to the tip
  const Vec3 tip = st.pose.tipM;
  double best = std::numeric_limits<double>::infinity();
  Vec3 planePoint = Vec3::Zero(), planeNormal = Vec3::UnitZ();
  for (const SimModel::SurfaceFace& sf : *m.initialSurface) {
    if (sf.box.squaredExteriorDistance(tip) >= best) continue;
    const Vec3 q = closestOnTriangle(tip, sf.a, sf.b, sf.c);
    const double d2 = (q - tip).squaredNorm();
    if (d2 < best) best = d2, planePoint = q, planeNormal = sf.normal;
  }
  if (!std::isfinite(best)) return;
  const double dt = config_.frameDtS;
  const Vec3 motion =
      st.frame > 0 ? Vec3(tip - config_.toolPath.poseAt(st.timeS - dt).tipM) : Vec3::Zero();
  const WettedContact wet =
      wettedContact(electrodeSamples_, st.pose, planePoint, planeNormal, motion);
  if (!(wet.areaM2 > 0)) return;  // touching by the contact distance only: not immersed
  constexpr double kTwoPi = 2 * 3.14159265358979323846;
  const double a = std::sqrt(config_.subgrid.areaFactor * wet.areaM2 / kTwoPi);
  // the patch: the contact nodes' share of the current surface
  const int n = m.mesh.numNodes();
  if (static_cast<int>(contactMark_.size()) != n) contactMark_.assign(n, 0);
  for (int c : st.contacts) contactMark_[c] = 1;
  double patchArea = 0;
  for (const BoundaryFace& face : m.surface) {
    int k = 0;
    for (int v3 : face.nodes) k += contactMark_[v3];
    if (k == 0) continue;
    const Vec3& p0 = m.mesh.nodes[face.nodes[0]];
    patchArea += k / 3.0 * 0.5 *
                 (m.mesh.nodes[face.nodes[1]] - p0).cross(m.mesh.nodes[face.nodes[2]] - p0).norm();
  }
  const double ap = std::sqrt(patchArea / kTwoPi);
  const SubgridMode mode = config_.subgrid.mode;
  const bool applies = ap > a && (mode == SubgridMode::On ||
                                  (mode == SubgridMode::Auto && ap >= kAutoPatchRatio * a));
  if (!applies) {
    for (int c : st.contacts) contactMark_[c] = 0;
    return;
  }
  // the tets at the contact: their conductivity, and the one holding the deepest point
  double sigmaSum = 0;
  int sigmaCount = 0;
  f.vaporTet = -1;
  const auto& geo = *m.geo;
  for (int e = 0; e < m.mesh.numTets(); ++e) {
    if (!m.mesh.isAlive(e)) continue;
    const Tet& t = m.mesh.tets[e];
    if (!(contactMark_[t[0]] | contactMark_[t[1]] | contactMark_[t[2]] | contactMark_[t[3]]))
      continue;
    sigmaSum += m.sigmaAssembled[e];
    ++sigmaCount;
    if (f.vaporTet >= 0) continue;
    const Vec3 c =
        0.25 * (m.mesh.nodes[t[0]] + m.mesh.nodes[t[1]] + m.mesh.nodes[t[2]] + m.mesh.nodes[t[3]]);
    bool inside = true;
    for (int k = 0; k < 4 && inside; ++k)
      inside = 0.25 + geo[e].grad.row(k).dot(wet.deepestM - c) >= -1e-9;
    if (inside) f.vaporTet = e;
  }
  for (int c : st.contacts) contactMark_[c] = 0;
  const double sigma = sigmaCount > 0 ? sigmaSum / sigmaCount : config_.conductivityS_m;
  // the contact nodes' shares of the current: their reactions (K u)_i
  f.nodes = st.contacts;
  f.weights.assign(f.nodes.size(), 0.0);
  double wsum = 0;
  for (size_t i = 0; i < f.nodes.size(); ++i) {
    const double r = m.stiffness.col(f.nodes[i]).dot(st.potentialV);
    f.weights[i] = std::max(r, 0.0);
    wsum += f.weights[i];
  }
  for (double& w : f.weights) w = wsum > 0 ? w / wsum : 1.0 / f.nodes.size();
  // the series resistance, and the mesh's solution scaled to it
  const double rMesh = v / toolCurrentA;
  const double rSub = shellResistanceOhm(sigma, a, ap);
  const double scale = rMesh / (rMesh + rSub);
  st.potentialV *= scale;
  for (double& q : st.joulePowerW_m3) q *= scale * scale;
  rec.toolCurrentA *= scale;
  rec.returnCurrentA *= scale;
  const double current = scale * toolCurrentA;
  f.innerM = a;
  f.patchM = ap;
  f.zoneM = std::min(ap, kZoneRadiusFactor * a);
  const std::vector<double> radii = zoneRadii(f.innerM, f.zoneM);
  f.shellW.resize(kSubgridShells);
  double subW = 0;
  for (int k = 0; k < kSubgridShells; ++k) {
    f.shellW[k] = current * current * shellResistanceOhm(sigma, radii[k], radii[k + 1]);
    subW += f.shellW[k];
  }
  f.directW = f.zoneM < ap ? current * current * shellResistanceOhm(sigma, f.zoneM, ap) : 0.0;
  subW += f.directW;
  // (a tool at rest may move by round-off between keyframes: below 1 nm per frame it rests)
  const double speed = motion.norm() > 1e-9 ? motion.norm() / dt : 0.0;
  f.residenceS = speed > 0 && wet.lengthAlongM > 0 ? wet.lengthAlongM / speed
                                                   : std::numeric_limits<double>::infinity();
  powerW = scale * scale * powerW + subW;
  f.active = true;
  rec.subgridActive = true;
  rec.subgridPowerW = subW;
}

// Heat stage, before the mesh's step: the zone formed, resized, advanced or released; its
// exchanges with the mesh and the direct share of the sub-grid power as nodal sources; its
// vapour trapped in the tet at the deepest point or vented.
void Simulation::subgridHeat(std::vector<ThermalPhase::NodalSource>& sources, FrameRecord& rec) {
  SimState& st = state_;
  const ThermalPhase& thermal = *model_->thermal;
  const double dt = config_.frameDtS;
  const SubgridZoneParams p = subgridZoneParams();
  SubgridZone& zone = st.subgridZone;
  SubgridEnergy& acc = st.subgridEnergy;
  std::vector<double> toNodes;  // [J], per zone node
  std::vector<int> nodes;
  if (subgridFrame_ && subgridFrame_->active) {
    const SubgridFrame& f = *subgridFrame_;
    nodes = f.nodes;
    ZoneCoupling c;
    c.weights = f.weights;
    for (int v : nodes) {
      c.temperatureC.push_back(st.thermal.temperatureC[v]);
      c.enthalpyJ_m3.push_back(st.thermal.enthalpyJ_m3[v]);
    }
    toNodes = resizeZone(p, zone, f.innerM, f.zoneM, c);
    const ZoneStepResult r = stepZone(p, zone, f.shellW, c, f.residenceS, dt);
    for (size_t i = 0; i < nodes.size(); ++i)
      toNodes[i] += r.toNodesJ[i] + f.weights[i] * f.directW * dt;
    zone.nodes = nodes;
    zone.weights = f.weights;
    acc.inputJ += r.inputJ + f.directW * dt;
    const double latentJ = r.vaporKg * config_.thermal.latentHeatJ_kg;
    if (f.vaporTet >= 0) {
      st.trappedVaporKg[f.vaporTet] += r.vaporKg;
      // the pocket it forms: an inclusion expanding by the boiling tissue's e_v (the
      // structural phase's water expansion, capped) whose wall stress breaks the tissue
      if (model_->structural && r.vaporKg > 0) {
        const double ev = volumetricExpansion(
            model_->expansion, config_.thermal.boilingTemperatureC, r.maxVaporFraction);
        double& pocket = st.pocketStressPa[f.vaporTet];
        pocket = std::max(pocket, pocketVonMisesPa(config_.structural.youngsModulusPa,
                                                   config_.structural.poissonRatio, ev));
        rec.subgridPocketStressPa = pocket;
      }
    } else {
      acc.ventedJ += latentJ;
    }
    rec.subgridVaporKg = r.vaporKg;
    rec.subgridZoneTemperatureC = zoneTemperatureC(p, zone);
  } else if (zone.present) {
    // the zone goes (the tool left, or the mesh resolves the contact): its heat to the nodes
    // it last exchanged with, those that still belong to the tissue
    nodes = zone.nodes;
    std::vector<double> weights = zone.weights;
    double kept = 0;
    for (size_t i = 0; i < nodes.size(); ++i) {
      if (!thermal.nodeActive(nodes[i])) weights[i] = 0;
      kept += weights[i];
    }
    const double heatJ = zoneEnergyJ(zone);
    releaseZone(zone);
    toNodes.assign(nodes.size(), 0.0);
    if (kept > 0) {
      for (size_t i = 0; i < nodes.size(); ++i) toNodes[i] = heatJ * weights[i] / kept;
    } else {
      acc.ventedJ += heatJ;  // its tissue was removed: the heat left with it
    }
  }
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (toNodes[i] == 0) continue;
    sources.push_back({nodes[i], toNodes[i] / dt});
    acc.toMeshJ += toNodes[i];
  }
  acc.storedJ = subgridStoredEnergyJ();
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
