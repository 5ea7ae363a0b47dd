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

constexpr double kRebuildPrefetchS = 1.0;  // scripted path prefetched after a rebuild [s]

constexpr const char* kStageNames[kStageCount] = {
    "move_tool", "find_contacts", "solve_potential", "heat",   "solve_stress",
    "rupture",   "rebuild",       "snapshot",        "render", "encode_wait"};

}  // namespace

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

Simulation::Simulation(TetMesh mesh, SimulationConfig config)
    : mesh_(std::move(mesh)), config_(std::move(config)) {
  const PhaseSet& ph = config_.phases;
  ESIM_VERIFY(!ph.structural || (ph.thermal && ph.boiling),
              "physics: 'structural' needs 'thermal' and 'boiling' (its load is the water's "
              "expansion)");
  ESIM_VERIFY(!ph.rupture || ph.structural,
              "physics: 'rupture' needs 'structural' (the stress that breaks elements)");
  ESIM_VERIFY(ph.electric || ph.thermal, "physics: the scene lists no phase to simulate");
  ESIM_VERIFY(config_.frameDtS > 0 && std::isfinite(config_.frameDtS),
              "time: frame step must be positive (fps > 0)");
  if (mesh_.alive.empty()) mesh_.alive.assign(mesh_.tets.size(), 1);
  validateMesh(mesh_, "mesh");

  // ---- model: geometry and surface (shared by every phase) ----
  geo_ = tetGeometry(mesh_);
  surface_ = boundaryFaces(mesh_);
  surfaceNodes_ = boundaryNodes(mesh_, surface_);
  for (const auto& f : surface_) {
    std::array<int, 3> key{f.nodes[0], f.nodes[1], f.nodes[2]};
    std::sort(key.begin(), key.end());
    initialFaces_.push_back(key);
  }
  std::sort(initialFaces_.begin(), initialFaces_.end());
  buildSurfaceTopology();
  potential_ = Eigen::VectorXd::Zero(mesh_.numNodes());
  joule_.assign(mesh_.numTets(), 0.0);

  // ---- electric phase ----
  if (ph.electric) {
    ESIM_VERIFY(config_.conductivityS_m > 0 && std::isfinite(config_.conductivityS_m),
                "material.electric_conductivity_s_per_m must be a positive finite number");
    ESIM_VERIFY(std::isfinite(config_.toolVoltageV), "tool.voltage_v must be finite");
    validateToolPath(config_.toolPath);
    ground_ = returnElectrodeNodes(mesh_, surfaceNodes_, config_.returnElectrode);
    ESIM_VERIFY(!ground_.empty(),
                "return_electrode: no mesh node lies on the return electrode disc (centre " +
                    std::to_string(config_.returnElectrode.centerM.x()) + " " +
                    std::to_string(config_.returnElectrode.centerM.y()) + " " +
                    std::to_string(config_.returnElectrode.centerM.z()) + " m, radius " +
                    std::to_string(config_.returnElectrode.radiusM) +
                    " m); move it onto the tissue surface or enlarge radius_m/tolerance_m");
    contactFinder_ = ContactFinder(mesh_, surfaceNodes_);
    sigma_.assign(mesh_.numTets(), config_.conductivityS_m);
    sigmaAssembled_ = sigma_;
    stiffness_ = assembleStiffness(mesh_, geo_, sigma_);
    electric_ = makeElectricSolver(config_.electricSolver);
    electric_->setContactCandidates(surfaceNodes_);
    electric_->setMatrix(stiffness_, ground_);
    prefetchScriptedPath();
  }

  // ---- thermal phase ----
  if (ph.thermal) {
    ThermalParams tp = config_.thermal;
    tp.boiling = ph.boiling;
    validateThermalParams(tp, "material");
    std::vector<BoundaryFace> cooled;
    if (config_.coolTopSurface && tp.convectionW_m2K > 0) {
      for (const auto& f : surface_) {
        const Vec3& a = mesh_.nodes[f.nodes[0]];
        const Vec3 n = (mesh_.nodes[f.nodes[1]] - a).cross(mesh_.nodes[f.nodes[2]] - a);
        if (n.z() > 0.5 * n.norm()) cooled.push_back(f);
      }
    }
    config_.thermal = tp;
    cooled_ = cooled;
    thermal_ = std::make_unique<ThermalPhase>(mesh_, geo_, tp, cooled);
    thermal_->initState(thermalState_);
    if (config_.hotSpot.enabled) {
      Eigen::VectorXd t = thermalState_.temperatureC;
      for (int i = 0; i < mesh_.numNodes(); ++i)
        if ((mesh_.nodes[i] - config_.hotSpot.centerM).norm() <= config_.hotSpot.radiusM)
          t[i] = config_.hotSpot.temperatureC;
      thermal_->setTemperature(thermalState_, t);
    }
    if (!ph.electric) prescribedSource_.assign(mesh_.numTets(), 0.0);  // zero without a source
    if (!ph.electric && config_.heatSource.enabled) {
      const double r2 = config_.heatSource.radiusM * config_.heatSource.radiusM;
      for (int e = 0; e < mesh_.numTets(); ++e) {
        Vec3 c = Vec3::Zero();
        for (int v : mesh_.tets[e]) c += 0.25 * mesh_.nodes[v];
        prescribedSource_[e] = config_.heatSource.powerDensityW_m3 *
                               std::exp(-(c - config_.heatSource.centerM).squaredNorm() / r2);
      }
    }
    maxTemperatureC_ = thermalState_.temperatureC.maxCoeff();
  } else {
    maxTemperatureC_ = config_.thermal.initialTemperatureC;
  }

  // ---- structural phase: clamped at the bottom ----
  if (ph.structural) {
    ESIM_VERIFY(config_.clampBandM >= 0 && std::isfinite(config_.clampBandM),
                "effects.structural_clamp_band_m must be >= 0");
    ESIM_VERIFY(config_.criticalStressPa > 0 && std::isfinite(config_.criticalStressPa),
                "material.critical_stress_pa must be > 0");
    ESIM_VERIFY(config_.vaporLiquidVolumeRatio >= 1,
                "material.vapor_liquid_volume_ratio must be >= 1");
    double zMin = mesh_.nodes.front().z();
    for (const Vec3& p : mesh_.nodes) zMin = std::min(zMin, p.z());
    for (int v : surfaceNodes_)
      if (mesh_.nodes[v].z() <= zMin + config_.clampBandM)
        for (int a = 0; a < 3; ++a) supports_.push_back({v, a});
    expansion_.waterFraction = config_.thermal.waterFraction;
    expansion_.densityKg_m3 = config_.thermal.densityKg_m3;
    expansion_.initialTemperatureC = config_.thermal.initialTemperatureC;
    expansion_.boilingTemperatureC = config_.thermal.boilingTemperatureC;
    expansion_.vaporLiquidVolumeRatio = config_.vaporLiquidVolumeRatio;
    expansion_.maxExpansion = config_.maxVaporExpansion;
    eigenstrain_.assign(mesh_.numTets(), 0.0);
    try {
      structural_ = std::make_unique<StructuralPhase>(mesh_, config_.structural, supports_);
      pending_.assign(mesh_.numTets(), 0);
    } catch (const Error& e) {
      throw Error(std::string(e.what()) + " (clamped: " + std::to_string(supports_.size() / 3) +
                  " bottom nodes within effects.structural_clamp_band_m = " +
                  std::to_string(config_.clampBandM) + " m of the lowest node)");
    }
  }
}

void Simulation::computeEigenstrain() {
  const Eigen::VectorXd& t = thermalState_.temperatureC;
  for (int e = 0; e < mesh_.numTets(); ++e) {
    if (!mesh_.isAlive(e)) {
      eigenstrain_[e] = 0;
      continue;
    }
    const Tet& tet = mesh_.tets[e];
    const double te = 0.25 * (t[tet[0]] + t[tet[1]] + t[tet[2]] + t[tet[3]]);
    const double x =
        thermalState_.vaporFractionTet.empty() ? 0.0 : thermalState_.vaporFractionTet[e];
    eigenstrain_[e] = volumetricExpansion(expansion_, te, x);
  }
}

// everything the removal of tets invalidates, built for a given alive set from the
// immutable model only (nodes, tets, geometry, configuration, supports), so that it can
// run on another thread while frames go on with the current structures
struct Simulation::Rebuilt {
  std::vector<std::uint8_t> alive;
  std::vector<int> removed;  // the tets this rebuild removes
  std::vector<BoundaryFace> surface;
  std::vector<int> surfaceNodes, ground;
  ContactFinder contactFinder;
  std::vector<double> sigma;  // the conductivities K was assembled with
  SparseMatrix stiffness;
  std::unique_ptr<ElectricSolver> electric;
  std::unique_ptr<ThermalPhase> thermal;
  std::unique_ptr<StructuralPhase> structural;
  double buildMs = 0;
};

std::unique_ptr<Simulation::Rebuilt> Simulation::buildRebuilt(std::vector<std::uint8_t> alive,
                                                              std::vector<int> removed,
                                                              std::vector<double> sigma,
                                                              int firstFrame) const {
  const auto t0 = std::chrono::steady_clock::now();
  auto r = std::make_unique<Rebuilt>();
  TetMesh mesh;
  mesh.nodes = mesh_.nodes;
  mesh.tets = mesh_.tets;
  mesh.alive = alive;
  ESIM_VERIFY(mesh.numAlive() > 0, "rupture: every element of the tissue has been removed");
  r->surface = boundaryFaces(mesh);
  r->surfaceNodes = boundaryNodes(mesh, r->surface);
  if (thermal_) {
    std::vector<BoundaryFace> cooled;
    for (const BoundaryFace& f : cooled_)
      if (mesh.isAlive(f.tet)) cooled.push_back(f);
    r->thermal = std::make_unique<ThermalPhase>(mesh, geo_, config_.thermal, cooled);
    if (config_.thermal.integrator == ThermalIntegrator::Explicit)
      r->thermal->stableExplicitDtS();  // computed here, not in the next frame
  }
  if (electric_) {
    r->ground = returnElectrodeNodes(mesh, r->surfaceNodes, config_.returnElectrode);
    ESIM_VERIFY(!r->ground.empty(),
                "rupture: the cut removed all the tissue on the return electrode");
    r->contactFinder = ContactFinder(mesh, r->surfaceNodes);
    r->stiffness = assembleStiffness(mesh, geo_, sigma);
    r->electric = makeElectricSolver(config_.electricSolver);
    r->electric->setContactCandidates(r->surfaceNodes);
    r->electric->setMatrix(r->stiffness, r->ground);
    // the columns the script will need on the new model (from firstFrame, its first frame
    // with recomputation, to kRebuildPrefetchS after the swap; later contacts get theirs
    // when they come): built here, off the frame loop in background mode
    if (config_.prefetchUntilS > 0) {
      const int last = static_cast<int>(std::ceil(config_.prefetchUntilS / config_.frameDtS));
      const int to =
          std::min(last, firstFrame + config_.rebuildLagFrames +
                             static_cast<int>(std::ceil(kRebuildPrefetchS / config_.frameDtS)));
      r->electric->prefetch(scriptedContacts(r->contactFinder, r->ground, firstFrame, to));
    }
  }
  if (structural_)
    r->structural = std::make_unique<StructuralPhase>(mesh, config_.structural, supports_);
  r->alive = std::move(alive);
  r->removed = std::move(removed);
  r->sigma = std::move(sigma);
  r->buildMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

void Simulation::swapIn(std::unique_ptr<Rebuilt> r, FrameRecord& rec) {
  mesh_.alive = std::move(r->alive);
  for (int e : r->removed) pending_[e] = 0;
  removedTets_ += static_cast<int>(r->removed.size());
  rec.removedTets = static_cast<int>(r->removed.size());
  surface_ = std::move(r->surface);
  surfaceNodes_ = std::move(r->surfaceNodes);
  buildSurfaceTopology();
  if (thermal_) thermal_ = std::move(r->thermal);
  if (electric_) {
    ground_ = std::move(r->ground);
    contactFinder_ = std::move(r->contactFinder);
    stiffness_ = std::move(r->stiffness);
    sigmaAssembled_ = std::move(r->sigma);
    electric_ = std::move(r->electric);
  }
  if (structural_) structural_ = std::move(r->structural);
  ++rebuilds_;
  rebuildBuildMs_ += r->buildMs;
}

void Simulation::startRebuild(const std::vector<int>& broken) {
  std::vector<std::uint8_t> alive = mesh_.alive;
  for (int e : broken) alive[e] = 0;
  std::vector<double> sigma = electric_ ? sigmaAssembled_ : std::vector<double>{};
  if (!config_.backgroundRebuild) {
    ready_ = buildRebuilt(std::move(alive), broken, std::move(sigma), frame_ + 1);
    swapFrame_ = frame_;
    return;
  }
  if (config_.recomputeLagFrames && config_.rebuildLagFrames > 0) takeCheckpoint();
  // a pure function of the immutable model and these copies: the result does not depend
  // on when the thread runs, and it is swapped in at a fixed frame
  job_ = std::async(std::launch::async, [this, alive = std::move(alive), broken,
                                         sigma = std::move(sigma), first = frame_ + 1]() mutable {
    return buildRebuilt(std::move(alive), std::move(broken), std::move(sigma), first);
  });
  swapFrame_ = frame_ + config_.rebuildLagFrames;
}

Simulation::~Simulation() = default;

Eigen::VectorXd Simulation::temperatureC() const {
  if (thermal_) return thermalState_.temperatureC;
  return Eigen::VectorXd::Constant(mesh_.numNodes(), config_.thermal.initialTemperatureC);
}

double Simulation::electricMemoryBytes() const {
  return electric_ ? electric_->memoryBytes() : 0.0;
}

std::string Simulation::electricSolverName() const { return electric_ ? electric_->name() : ""; }

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

void Simulation::prefetchScriptedPath() {
  if (config_.prefetchUntilS <= 0) return;
  const int frames = static_cast<int>(std::ceil(config_.prefetchUntilS / config_.frameDtS));
  electric_->prefetch(scriptedContacts(contactFinder_, ground_, 0, frames));
}

void Simulation::refreshConductivity(FrameRecord& /*record*/) {
  // sigma(T) per tet from the mean nodal temperature; refresh K when it moved enough
  const double t0 = config_.thermal.initialTemperatureC;
  const double tb = config_.thermal.boilingTemperatureC;
  double max_rel = 0;
  for (int e = 0; e < mesh_.numTets(); ++e) {
    if (!mesh_.isAlive(e)) continue;
    double t = 0;
    for (int v : mesh_.tets[e]) t += 0.25 * thermalState_.temperatureC[v];
    t = std::min(t, tb);
    double s = config_.conductivityS_m * (1.0 + config_.conductivityTempCoeffPerK * (t - t0));
    if (!thermalState_.desiccatedTet.empty() && thermalState_.desiccatedTet[e])
      s *= config_.desiccatedConductivityFactor;
    sigma_[e] = std::max(s, 1e-6 * config_.conductivityS_m);
    max_rel = std::max(max_rel, std::abs(sigma_[e] - sigmaAssembled_[e]) / sigmaAssembled_[e]);
  }
  if (max_rel > config_.conductivityRefreshTolerance) {
    sigmaAssembled_ = sigma_;
    stiffness_ = assembleStiffness(mesh_, geo_, sigmaAssembled_);
    electric_->setMatrix(stiffness_, ground_);
  }
}

const FrameRecord& Simulation::step() {
  FrameRecord& rec = record_;
  rec = FrameRecord{};
  advance(rec);
  if (config_.phases.rupture) ruptureAndRebuild(rec);
  ++frame_;
  timeS_ = frame_ * config_.frameDtS;
  return rec;
}

// stages 1-5 of frame frame_ (at time timeS_): the physics on the current model
void Simulation::advance(FrameRecord& rec) {
  rec.frame = frame_;
  rec.timeS = timeS_;
  const double dt = config_.frameDtS;

  // ---- 1. move the tool ----
  if (electric_) {
    StageTimer timer(rec, Stage::MoveTool);
    pose_ = config_.toolPath.poseAt(timeS_);
    generatorOn_ = config_.toolPath.generatorOnAt(timeS_);
  }
  rec.generatorOn = generatorOn_;

  // ---- 2. contacts ----
  if (electric_) {
    StageTimer timer(rec, Stage::FindContacts);
    if (generatorOn_) {
      contacts_ = contactFinder_.find(config_.electrode, pose_, config_.contactDistanceM);
    } else {
      contacts_.clear();
      timer.skip();
    }
  }
  rec.contactNodes = static_cast<int>(contacts_.size());

  // ---- 3. potential and Joule heat ----
  double power_w = 0;
  if (electric_) {
    StageTimer timer(rec, Stage::SolvePotential);
    if (contacts_.empty()) {
      potential_.setZero();
      std::fill(joule_.begin(), joule_.end(), 0.0);
      timer.skip();
    } else {
      if (thermal_ && config_.temperatureDependentConductivity) refreshConductivity(rec);
      electric_->solve(contacts_, config_.toolVoltageV, potential_);
      // Joule power density (into joule_, reused) and currents with the assembled sigma
      const ElectricTotals totals =
          computeJoulePower(mesh_, geo_, sigmaAssembled_, stiffness_, potential_, contacts_,
                            ground_, config_.toolVoltageV, joule_);
      power_w = totals.powerW;
      rec.toolCurrentA = totals.toolCurrentA;
      rec.returnCurrentA = totals.returnCurrentA;
    }
  }
  rec.powerW = power_w;
  energyJ_ += power_w * dt;

  // ---- 4. heat: Joule (or prescribed) source, conduction, boiling ----
  if (thermal_) {
    StageTimer timer(rec, Stage::Heat);
    const auto stats = thermal_->step(dt, electric_ ? joule_ : prescribedSource_, thermalState_);
    if (stats.skipped) timer.skip();
    rec.maxTemperatureC = thermalState_.temperatureC.maxCoeff();
    maxTemperatureC_ = std::max(maxTemperatureC_, rec.maxTemperatureC);
  } else {
    rec.maxTemperatureC = config_.thermal.initialTemperatureC;
  }

  // ---- 5. stress from the water's expansion ----
  if (structural_) {
    StageTimer timer(rec, Stage::SolveStress);
    computeEigenstrain();
    if (std::all_of(eigenstrain_.begin(), eigenstrain_.end(), [](double v) { return v == 0; })) {
      timer.skip();  // at rest: no load, and the last stresses are zero too
    } else {
      structural_->solve(eigenstrain_);
    }
    const std::vector<double>& vm = structural_->vonMisesPa();
    rec.maxVonMisesPa = vm.empty() ? 0.0 : *std::max_element(vm.begin(), vm.end());
  }
}

// tets over the critical stress that no rebuild is removing yet join the queue
void Simulation::detectRupture(FrameRecord& rec) {
  StageTimer timer(rec, Stage::Rupture);
  const std::vector<double>& vm = structural_->vonMisesPa();
  for (int e = 0; e < mesh_.numTets(); ++e)
    if (mesh_.isAlive(e) && !pending_[e] && vm[e] > config_.criticalStressPa) {
      queued_.push_back(e);
      pending_[e] = 1;
    }
  if (queued_.empty()) timer.skip();
}

// 6. rupture; 7. rebuild: synchronous (built and swapped in now), or built on a thread and
// swapped in config_.rebuildLagFrames frames later; frames meanwhile use the old model,
// and tets that break meanwhile wait for the next rebuild. With recomputeLagFrames the
// frames since the rupture are then computed again on the new model (from a checkpoint
// taken when the rebuild started), so that only the timing of later ruptures differs from
// a synchronous run.
void Simulation::ruptureAndRebuild(FrameRecord& rec) {
  detectRupture(rec);
  StageTimer timer(rec, Stage::Rebuild);
  bool worked = false;
  if (swapFrame_ < 0 && !queued_.empty()) {  // nothing in flight: start with the queue
    std::vector<int> broken;
    broken.swap(queued_);  // they stay pending until swapIn
    startRebuild(broken);
    worked = true;
  }
  if (swapFrame_ >= 0 && frame_ >= swapFrame_) {  // due: wait if needed, swap in
    if (!ready_) {
      const auto w0 = std::chrono::steady_clock::now();
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

struct Simulation::Checkpoint {
  int nextFrame = 0;
  ThermalState thermal;
  Eigen::VectorXd potential;
  std::vector<double> joule, sigma;
  std::vector<int> contacts;
  ToolPose pose;
  bool generatorOn = false;
  double energyJ = 0;
};

void Simulation::takeCheckpoint() {
  checkpoint_ = std::make_unique<Checkpoint>();
  Checkpoint& c = *checkpoint_;
  c.nextFrame = frame_ + 1;
  c.thermal = thermalState_;
  c.potential = potential_;
  c.joule = joule_;
  c.sigma = sigma_;
  c.contacts = contacts_;
  c.pose = pose_;
  c.generatorOn = generatorOn_;
  c.energyJ = energyJ_;
}

void Simulation::recomputeSinceCheckpoint(FrameRecord& rec) {
  std::unique_ptr<Checkpoint> c = std::move(checkpoint_);
  // ruptures seen on the old model during the lag are forgotten: the recomputation finds
  // its own
  for (int e : queued_) pending_[e] = 0;
  queued_.clear();
  thermalState_ = std::move(c->thermal);
  potential_ = std::move(c->potential);
  joule_ = std::move(c->joule);
  sigma_ = std::move(c->sigma);
  contacts_ = std::move(c->contacts);
  pose_ = c->pose;
  generatorOn_ = c->generatorOn;
  energyJ_ = c->energyJ;
  const int now = frame_;
  FrameRecord redo;
  for (int k = c->nextFrame; k <= now; ++k) {
    frame_ = k;
    timeS_ = k * config_.frameDtS;
    redo = FrameRecord{};
    advance(redo);
    detectRupture(redo);
  }
  frame_ = now;
  timeS_ = now * config_.frameDtS;
  // the frame's physics as recomputed
  rec.contactNodes = redo.contactNodes;
  rec.toolCurrentA = redo.toolCurrentA;
  rec.returnCurrentA = redo.returnCurrentA;
  rec.powerW = redo.powerW;
  rec.maxTemperatureC = redo.maxTemperatureC;
  rec.maxVonMisesPa = redo.maxVonMisesPa;
  recomputedFrames_ += now - c->nextFrame + 1;
}

void Simulation::buildSurfaceTopology() {
  // surface vertex numbering and triangles: fixed until the topology changes
  surfaceVertexOf_.assign(mesh_.numNodes(), -1);
  surfacePositionsM_.clear();
  for (int v : surfaceNodes_) {
    surfaceVertexOf_[v] = static_cast<int>(surfacePositionsM_.size() / 3);
    for (int c = 0; c < 3; ++c) surfacePositionsM_.push_back(static_cast<float>(mesh_.nodes[v][c]));
  }
  surfaceTriangles_.clear();
  surfaceTriangles_.reserve(surface_.size() * 3);
  for (const auto& f : surface_)
    for (int v : f.nodes)
      surfaceTriangles_.push_back(static_cast<std::uint32_t>(surfaceVertexOf_[v]));
  // cut walls: vertices of faces that were inside the initial tissue
  surfaceCutWall_.assign(surfacePositionsM_.size() / 3, 0.0f);
  for (const auto& f : surface_) {
    std::array<int, 3> key{f.nodes[0], f.nodes[1], f.nodes[2]};
    std::sort(key.begin(), key.end());
    if (std::binary_search(initialFaces_.begin(), initialFaces_.end(), key)) continue;
    for (int v : f.nodes) surfaceCutWall_[surfaceVertexOf_[v]] = 1.0f;
  }
}

SurfaceSnapshot Simulation::snapshot() {
  StageTimer timer(record_, Stage::Snapshot);
  SurfaceSnapshot snap;
  snap.frame = record_.frame;
  snap.timeS = timeS_;
  const std::vector<int>& vertex_of = surfaceVertexOf_;
  snap.positionsM = surfacePositionsM_;
  snap.triangles = surfaceTriangles_;
  const int nv = snap.numVertices();
  snap.temperatureC.assign(nv, static_cast<float>(config_.thermal.initialTemperatureC));
  snap.coagulation.assign(nv, 0.0f);
  snap.desiccation.assign(nv, 0.0f);
  snap.cutWall = surfaceCutWall_;
  if (thermal_) {
    std::vector<float> coag_sum(nv, 0.0f), count(nv, 0.0f);
    for (const auto& f : surface_) {
      const float c = thermalState_.coagulationTet.empty()
                          ? 0.0f
                          : static_cast<float>(thermalState_.coagulationTet[f.tet]);
      for (int v : f.nodes) {
        coag_sum[vertex_of[v]] += c;
        count[vertex_of[v]] += 1;
      }
    }
    for (int v : surfaceNodes_) {
      const int i = vertex_of[v];
      snap.temperatureC[i] = static_cast<float>(thermalState_.temperatureC[v]);
      snap.desiccation[i] = static_cast<float>(thermalState_.vaporFraction[v]);
      snap.coagulation[i] = count[i] > 0 ? coag_sum[i] / count[i] : 0.0f;
    }
  }
  if (electric_) {
    snap.potentialV.resize(nv);
    for (int v : surfaceNodes_) snap.potentialV[vertex_of[v]] = static_cast<float>(potential_[v]);
    ToolSnapshot& t = snap.tool;
    t.present = true;
    t.generatorOn = generatorOn_;
    t.kind = config_.electrode.kind;
    for (int c = 0; c < 3; ++c) t.tipM[c] = static_cast<float>(pose_.tipM[c]);
    const Eigen::Quaterniond q = pose_.orientation.normalized();
    t.orientationWxyz = {static_cast<float>(q.w()), static_cast<float>(q.x()),
                         static_cast<float>(q.y()), static_cast<float>(q.z())};
    t.radiusM = static_cast<float>(config_.electrode.radiusM);
    t.lengthM = static_cast<float>(config_.electrode.lengthM);
    t.widthM = static_cast<float>(config_.electrode.widthM);
  }
  return snap;
}

}  // namespace esim
