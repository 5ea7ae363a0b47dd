// simulation.h - one run of the physics: the fixed pipeline of named, timed stages.
//
// A Simulation owns its configuration, the model (SimModel: mesh, geometry, surface,
// operators and factorizations of one topology) and the state (SimState: time, tool pose,
// contacts, potential, thermal state, energies). step() advances one frame of
// config.frameDtS seconds:
//
//   moveTool -> findContacts -> solvePotential -> heat -> [solveStress -> rupture ->
//   rebuild] -> snapshot
//
// Only the phases the scene lists are built: an unlisted phase has no object, no
// matrix and no stage (its timing is "absent"). A listed stage with nothing to do this
// frame (generator off, no contact, zero source at rest) records "skipped".
// Structural: the tissue water's expansion (liquid + trapped vapour, structural.h) loads a
// linear elastic body clamped at its bottom (nodes within clampBandM of the lowest
// node); per-tet von Mises stress. Rupture: alive tets whose von Mises stress exceeds
// criticalStressPa are removed; rebuild (synchronous: applied in the same frame) then
// refreshes the surface, the contact candidates, the electric matrix and solver, the
// thermal operators and the structural factorization. Faces exposed by removal are cut
// walls in the snapshot.
// Units: SI (m, s, V, A, W, J), temperatures in degrees Celsius.
#pragma once

#include <array>
#include <chrono>
#include <future>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "sim/core_error.h"
#include "sim/electric_solver.h"
#include "sim/electrode.h"
#include "sim/fem_p1.h"
#include "sim/mesh_tet.h"
#include "sim/rupture_nonlocal.h"
#include "sim/snapshot.h"
#include "sim/structural.h"
#include "sim/subgrid_contact.h"
#include "sim/thermal_step.h"
#include "sim/tool_path.h"
#include "sim/two_threads.h"

namespace esim {

// ---- stages ----
enum class Stage : int {
  MoveTool = 0,
  FindContacts,
  SolvePotential,
  Heat,
  SolveStress,
  Rupture,
  Rebuild,
  Snapshot,
  Render,
  Encode,  // time the frame loop waited on the encoder queue (encoding itself is offline)
  Labels,  // esim run --labels: writing the label files (the label pass is in Render)
  kCount
};
constexpr int kStageCount = static_cast<int>(Stage::kCount);

// "move_tool", "find_contacts", ... (the column names of timing.csv)
const char* stageName(Stage stage);

enum class StageStatus : std::uint8_t { Absent = 0, Ran, Skipped };

// one row of the timing report
struct FrameRecord {
  int frame = 0;
  double timeS = 0;                               // simulated time at frame start [s]
  std::array<double, kStageCount> ms{};           // wall time per stage [ms]
  std::array<StageStatus, kStageCount> status{};  // absent / ran / skipped
  int contactNodes = 0;
  bool generatorOn = false;
  double toolCurrentA = 0;    // into the tissue at the tool [A]
  double returnCurrentA = 0;  // out at the return electrode [A]
  double powerW = 0;          // Joule power this frame [W]
  // electric strategy local with ElectricSolverOptions::localCheck: this frame's Joule power
  // over a full solve's of the same frame, minus 1 (>= 0); -1 when not measured
  double electricPowerError = -1;
  double maxTemperatureC = 0;  // after heat, over the nodes of alive tets (removed tissue left out)
  double maxVonMisesPa = 0;    // structural phase, over alive tets
  int removedTets = 0;         // by the rebuild swapped in this frame
  double rebuildWaitMs = 0;    // background rebuild: the frame loop waited for it
  // update mode, a removal frame: wall time of each part of the update [ms]
  std::array<double, 4> updatePartMs{};  // surface (and contacts), thermal, electric, structural
  double structuralUpdateMs = 0;         // update mode: the structural update joined in this frame,
                                  // run on a thread since the removal (its own wall time) [ms]
  double structuralUpdateWork = 0;  // ... its work: entries of L walked times the columns
                                    // passing them (StructuralUpdateStats::updateWork; 0 when
                                    // it refactorized instead)
  bool contactByTet = false;        // tool inside the tissue, no node within reach: the nearest
                                    // node of the tet holding the tip carried the current
  bool toolSwept = false;           // the tool moved more than an element: contacts along its path
  bool boilingUnconverged = false;  // the boiling iteration stopped at its iteration cap
  double maxPrincipleViolationK = 0;   // heat: how far T left its maximum-principle bounds
  bool subgridActive = false;          // the sub-grid contact model carried the contact
  double subgridPowerW = 0;            // ... Joule power of the sub-grid shell a < r < a_p [W]
  double subgridZoneTemperatureC = 0;  // ... its innermost shell at the end of the frame [C]
  double subgridVaporKg = 0;           // ... water its zone vaporised this frame [kg]
  double subgridPocketStressPa = 0;    // ... wall stress of the vapour pocket it fed [Pa]
  double physicsMs() const;            // sum of the simulation stages [ms]
};

// times one stage into a record (monotonic clock)
class StageTimer {
 public:
  StageTimer(FrameRecord& record, Stage stage)
      : record_(record), stage_(stage), start_(std::chrono::steady_clock::now()) {}
  ~StageTimer();
  void skip() { skipped_ = true; }

 private:
  FrameRecord& record_;
  Stage stage_;
  std::chrono::steady_clock::time_point start_;
  bool skipped_ = false;
};

// ---- configuration ----
struct PhaseSet {
  bool electric = false, thermal = false, boiling = false, structural = false, rupture = false;
};

// a prescribed heat source for thermal scenes without the electric phase
struct HeatSourceSpec {
  bool enabled = false;
  Vec3 centerM{0, 0, 0.01};
  double radiusM = 0.003;         // Gaussian 1/e radius [m]
  double powerDensityW_m3 = 1e8;  // peak [W/m^3]
};

struct HotSpotSpec {
  bool enabled = false;
  Vec3 centerM{0, 0, 0.01};
  double radiusM = 0.003;
  double temperatureC = 90;
};

// after rupture: build the new model in the frame that breaks tets, or on a thread while
// frames go on with the old one, or edit the model in place in the frame that breaks tets
// (each phase's removal update: its cost follows the removed tets, not the mesh)
enum class RebuildMode { Synchronous, Background, Update };

// "synchronous", "background", "update" (the scenario's solvers.rebuild.mode)
const char* rebuildModeName(RebuildMode mode);

struct SimulationConfig {
  PhaseSet phases;
  double frameDtS = 1.0 / 30.0;  // simulated time per frame [s]

  // electric
  double conductivityS_m = 0.144;  // sigma at the initial temperature [S/m]
  double toolVoltageV = 72;
  double contactDistanceM = 0.0008;
  // the contact rule's candidates: the surface's nodes (the paper), or every node of the
  // alive tets (a tool inside the tissue is held at its voltage along all of its length)
  ContactNodes contactNodes = ContactNodes::Surface;
  ElectrodeShape electrode;
  ReturnElectrode returnElectrode;
  ToolPath toolPath;
  // auto: the dense inverse on small meshes, capacitance above (resolveElectricStrategy)
  ElectricSolverOptions electricSolver{.strategy = ElectricStrategy::Auto};
  // pre-processing: the solver precomputes what the scripted tool path will touch in
  // [0, prefetchUntilS] (capacitance: the columns of those nodes), so that frames need no
  // new column; 0 disables it (a live, unscripted tool)
  double prefetchUntilS = 0;
  // effect: sigma(T) = sigma0 (1 + a (T - T0)) up to boiling, x factor once desiccated
  bool temperatureDependentConductivity = false;
  double conductivityTempCoeffPerK = 0.02;
  double desiccatedConductivityFactor = 0.01;
  double conductivityRefreshTolerance = 0.02;  // refresh K when some sigma moved this much (rel.)

  // thermal
  ThermalParams thermal;
  HeatSourceSpec heatSource;
  HotSpotSpec hotSpot;
  bool coolTopSurface = false;  // convective faces: the boundary faces facing up (+z)

  // structural and rupture
  StructuralOptions structural;                                              // E, nu
  double vaporLiquidVolumeRatio = ExpansionParams{}.vaporLiquidVolumeRatio;  // v_gas / v_liq
  double maxVaporExpansion = ExpansionParams{}.maxExpansion;  // cap of dV/V (structural.h)
  double clampBandM = 1e-4;          // clamp the nodes this close to the lowest z [m]
  double criticalStressPa = 2.45e4;  // von Mises stress that breaks a tet (paper)
  // > 0: the criterion compares the von Mises stress averaged within this radius [m]
  // (sim/rupture_nonlocal.h); 0: each tet's own (the paper)
  double criticalStressRadiusM = 0;
  // > 0: pieces a removal cuts loose (no face with the rest, no support) up to this volume
  // [m^3] are removed with it (sim/rupture_debris.h); 0: kept, out of the stiffness (the paper)
  double debrisVolumeM3 = 1e-8;
  RebuildMode rebuildMode = RebuildMode::Update;  // or rebuilt in the frame, or on a thread ...
  int rebuildLagFrames = 3;                       // ... swapped in this many frames after rupture
  bool recomputeLagFrames = true;                 // ... then the lag frames again on the new model

  // the contact below the mesh's resolution (sim/subgrid_contact.h)
  SubgridContactOptions subgrid;
};

// The phases' dependencies, the one rule the scenario loader and the constructor both use:
// boiling needs thermal; structural needs thermal and boiling (its load is the water's
// expansion); rupture needs structural; at least one of electric and thermal. Returns ""
// when met, else what is missing and what to add.
std::string phaseDependencyProblem(const PhaseSet& phases);

// The core's defaults (like MuJoCo's mj_defaultOption): the one source of every default
// of the scenario schema (sim/io/scenario.h reads its member defaults from here).
const SimulationConfig& defaultSimulationConfig();

// Checks the configuration alone (phases and their dependencies, frame step, materials,
// tool path, solver options); throws Error naming the scenario key. The constructor runs
// it; `esim validate` runs it too, so that a valid scenario never fails at set-up.
void validateSimulationConfig(const SimulationConfig& config);

// The warnings that follow from the configuration alone, before any mesh (today: linear tets
// with the volumetric strain per tet at a Poisson's ratio where they lock, sim/structural.h
// VolumetricStrain). Simulation::warnings() lists them; `esim validate` prints them.
std::vector<std::string> configWarnings(const SimulationConfig& config);

// The explicit integrator's bound: a frame step above the mesh's stability limit needs
// sub-stepping, and at most thermal.maxSubsteps sub-steps; else an Input error with the
// remedy. The constructor runs it, and validateSimulationMesh.
void checkExplicitBound(const ThermalPhase& thermal, const SimulationConfig& config);

// Checks what the configuration needs of the mesh: a valid mesh, nodes on the return
// electrode (electric), nodes in the clamp band (structural), the explicit bound (thermal),
// the dense inverse's memory, the nonlocal criterion's work bound (rupture). `esim validate`
// runs it; the constructor makes the same checks.
void validateSimulationMesh(const TetMesh& mesh, const SimulationConfig& config);

// ---- model and state ----

// The model of one topology (one alive set): mesh, geometry, surface, contact candidates
// and every phase's operators and factorizations. Built by the constructor and again by
// each rebuild after rupture (a new SimModel, never an edit the solvers could miss);
// read-only between builds, except the electric matrix, which sigma(T) refreshes.
struct SimModel {
  TetMesh mesh;  // nodes, tets and the alive set this model is built for
  std::shared_ptr<const std::vector<TetGeometry>> geo;  // per tet (all tets; shared by builds)
  // per tet * 4 + local face (boundaryFaceIndex): 1 on the initial surface (a face of the
  // surface that is not is a cut wall)
  std::shared_ptr<const std::vector<std::uint8_t>> initialFaces;
  std::vector<BoundaryFace> surface;  // boundary faces of the alive tets
  // per tet, the tet across each face (tetFaceNeighbours; rebuild mode update only)
  std::shared_ptr<const std::vector<std::array<int, 4>>> faceNeighbours;
  // node -> tets of the initial alive set (nodeTets; rebuild mode update only)
  std::shared_ptr<const Adjacency> nodeTets;
  std::vector<int> surfaceNodes;  // sorted
  std::vector<int> ground;        // return-electrode nodes (electric)
  // tool.contact volume: every node of an alive tet (sorted; electric); empty otherwise
  std::vector<int> volumeNodes;
  ContactFinder contactFinder;  // over the contact candidates: surfaceNodes or volumeNodes
  // the snapshot's surface: fixed until the topology changes
  std::vector<int> surfaceVertexOf;             // node -> snapshot vertex (-1 inside)
  std::vector<float> surfacePositionsM;         // snapshot vertex positions [m]
  std::vector<std::uint32_t> surfaceTriangles;  // snapshot triangles
  std::vector<float> surfaceCutWall;            // snapshot vertex: 1 on a cut wall
  // electric phase (null when not listed)
  std::unique_ptr<ElectricSolver> electric;
  SparseMatrix stiffness;              // K assembled with sigmaAssembled
  std::vector<double> sigmaAssembled;  // per tet [S/m]
  // thermal phase (null when not listed)
  std::unique_ptr<ThermalPhase> thermal;
  std::vector<BoundaryFace> cooledInitial;  // convective faces of the initial surface
  std::vector<double> prescribedSource;     // thermal without electric: per tet [W/m^3]
  // structural phase (null when not listed)
  std::unique_ptr<StructuralPhase> structural;
  std::vector<Support> supports;
  ExpansionParams expansion;
  // sub-grid contact: the initial boundary faces (the intact tissue's surface), as planes
  struct SurfaceFace {
    Vec3 a, b, c, normal;  // corners [m] and outward unit normal
    Eigen::AlignedBox3d box;
  };
  std::shared_ptr<const std::vector<SurfaceFace>> initialSurface;
  double medianEdgeM = 0;       // median edge length of the initial mesh [m] (a fast tool's scale)
  Eigen::AlignedBox3d boundsM;  // box of the initial mesh's nodes [m]
  double buildMs = 0;           // wall time of the build [ms]
};

// The sub-grid contact model's energy account (all [J], since the start): with the thermal
// state's, delivered = mesh source - toMesh + input, and mesh stored + sub-grid stored =
// initial + delivered - convected - removed (with tets) - vented.
struct SubgridEnergy {
  double inputJ = 0;   // Joule heat of the sub-grid shell (in the energy delivered)
  double toMeshJ = 0;  // heat the model gave the mesh as nodal sources (in its sourceJ)
  double ventedJ = 0;  // latent heat of vapour formed where the tissue had parted, and heat
                       // of a zone whose nodes were all removed
  double storedJ = 0;  // zone + trapped vapour of alive tets, after the heat stage
};

// The state: everything a frame changes. A checkpoint is a copy of it.
struct SimState {
  int frame = 0;     // frames done
  double timeS = 0;  // simulated time [s]
  ToolPose pose;
  bool generatorOn = false;
  std::vector<int> contacts;            // sorted nodes touching the tool
  Eigen::VectorXd potentialV;           // per node [V]
  std::vector<double> joulePowerW_m3;   // per tet [W/m^3]
  std::vector<double> conductivityS_m;  // per tet: sigma(T) [S/m]
  ThermalState thermal;                 // enthalpy, temperature, vapour, damage
  std::vector<double> eigenstrain;      // per tet: volumetric expansion (structural load)
  std::vector<double> vonMisesPa;       // per tet: of the last structural solve [Pa]
  Eigen::VectorXd displacementM;        // 3 per node: of the last structural solve [m]
  double energyJ = 0;                   // Joule energy delivered so far [J]
  double maxTemperatureC = 0;           // highest temperature seen so far [C]
  // sub-grid contact (sim/subgrid_contact.h)
  SubgridZone subgridZone;
  std::vector<double> trappedVaporKg;  // per tet: water the zone vaporised in it [kg]
  std::vector<double> pocketStressPa;  // per tet: von Mises at the wall of that vapour pocket
  SubgridEnergy subgridEnergy;
};

// ---- the simulation ----
class Simulation {
 public:
  // Builds the listed phases on the mesh (validated here). Throws Error on bad input
  // (no return-electrode node, unimplemented phase, bad parameters).
  Simulation(TetMesh mesh, SimulationConfig config);
  ~Simulation();

  // advances one frame and returns its record (stage times, currents, max temperature).
  // Throws RunError when the run cannot go on, Interrupted (core_error.h) when the stop
  // flag is set: the frame is then left halfway (its record and counters are not kept)
  const FrameRecord& step();

  // the surface of the alive tets with per-vertex state, for the renderer (timed into the
  // last record's Snapshot stage); with the structural phase its vertices are displaced by
  // displacementScale times the last displacement (1: as computed; more to show it)
  SurfaceSnapshot snapshot(double displacementScale = 1.0);

  // ---- read access ----
  const SimModel& model() const {  // (after the structural update in flight, if any)
    waitStructural();
    return *model_;
  }
  const SimState& state() const { return state_; }
  const FrameRecord& lastRecord() const { return record_; }  // of the last step (+ snapshot)
  const TetMesh& mesh() const { return model_->mesh; }
  const SimulationConfig& config() const { return config_; }
  int frame() const { return state_.frame; }
  double timeS() const { return state_.timeS; }
  const std::vector<int>& groundNodes() const { return model_->ground; }
  const std::vector<int>& contactNodes() const { return state_.contacts; }
  const Eigen::VectorXd& potentialV() const { return state_.potentialV; }
  const std::vector<double>& joulePowerW_m3() const { return state_.joulePowerW_m3; }
  const std::vector<double>& conductivityS_m() const { return state_.conductivityS_m; }
  const ThermalState* thermalState() const { return model_->thermal ? &state_.thermal : nullptr; }
  Eigen::VectorXd temperatureC() const;  // per node (initial value without thermal)
  double energyDeliveredJ() const { return state_.energyJ; }  // integral of Joule power [J]
  double maxTemperatureSeenC() const { return state_.maxTemperatureC; }
  // sub-grid contact: its energy account, and what it stores now (zone + trapped vapour of
  // the alive tets) [J]
  const SubgridEnergy& subgridEnergy() const { return state_.subgridEnergy; }
  double subgridStoredEnergyJ() const;
  const SubgridZone& subgridZone() const { return state_.subgridZone; }
  SubgridZoneParams subgridZoneParams() const;
  double electricMemoryBytes() const;
  // caps the electric solver's cache (capacitance's columns) at `bytes`, now and in models
  // rebuilt later, after the prefetch under way; returns the bytes given back (0: nothing
  // to give). The fields do not change, only the time (see ElectricSolver::limitCache)
  double limitElectricCache(double bytes);
  std::string electricSolverName() const;
  bool hasElectric() const { return model_->electric != nullptr; }
  const std::vector<double>* vonMisesPa() const {
    return model_->structural ? &state_.vonMisesPa : nullptr;
  }
  // what a demanding user should know about the run so far (a buried or fast tool, an
  // unconverged boiling iteration), one sentence each with the frames and the remedy
  std::vector<std::string> warnings() const;
  int removedTets() const { return removedTets_; }  // by rupture since the start
  int debrisTets() const { return debrisTets_; }  // of which cut loose as debris (rupture_debris.h)
  // pieces of alive tets the supports do not hold (loose, left by a cut: larger than the
  // debris volume, or with debris kept), out of the structural phase's stiffness, and their
  // tets; 0 without the structural phase
  int loosePieces() const {
    return model_->structural ? model_->structural->numFloatingIslands() : 0;
  }
  int looseTets() const { return model_->structural ? model_->structural->numIslandTets() : 0; }
  int rebuilds() const { return rebuilds_; }                 // swapped in so far
  int rebuildsLate() const { return rebuildsLate_; }         // background: the frame loop waited
  double rebuildBuildMs() const { return rebuildBuildMs_; }  // sum over rebuilds
  double maxRebuildWaitMs() const { return rebuildWaitMs_; }
  int recomputedFrames() const { return recomputedFrames_; }
  // update mode: removals whose structural update refactorized the factor instead (its
  // estimate passed a refactorization's, or a downdate lost positive definiteness)
  int structuralRefactorizations() const { return structuralRefactorizations_; }

 private:
  struct Rebuilt;
  void buildInitialModel(TetMesh mesh);
  // concurrent: the structural phase on a thread of its own while the others are built
  std::unique_ptr<SimModel> buildModel(std::vector<std::uint8_t> alive, std::vector<double> sigma,
                                       int prefetchFrom, int prefetchTo, bool concurrent) const;
  void initState();
  std::unique_ptr<SimModel> rebuildModel(std::vector<std::uint8_t> alive, std::vector<double> sigma,
                                         int first, int prefetchTo, bool concurrent) const;
  std::vector<int> findContacts(FrameRecord& record) const;
  void checkFinite(Stage stage, const char* what, const double* values, int count,
                   const char* unit) const;
  // lowC, highC: the tissue's range after the step (tissueTemperatureRangeC)
  void checkMaximumPrinciple(double highBeforeC, double lowC, double highC, bool heated,
                             FrameRecord& record);
  std::pair<double, double> tissueTemperatureRangeC() const;  // min, max on alive tets' nodes
  std::string noContactWarning() const;  // the tool never touched the tissue ("" if it did)
  void refreshConductivity();
  void computeEigenstrain();
  struct SubgridFrame;
  void subgridContact(double toolCurrentA, double& powerW, FrameRecord& record);
  void subgridHeat(std::vector<ThermalPhase::NodalSource>& sources, FrameRecord& record);
  std::vector<int> scriptedContacts(const ContactFinder& finder, const std::vector<int>& ground,
                                    int fromFrame, int toFrame) const;
  void startRebuild(const std::vector<int>& broken, int debris);
  void advance(FrameRecord& record);
  void detectRupture(FrameRecord& record);
  void ruptureAndRebuild(FrameRecord& record);
  void recomputeSinceCheckpoint(FrameRecord& record);
  void swapIn(std::unique_ptr<Rebuilt> rebuilt, FrameRecord& record);
  void updateModel(const std::vector<int>& broken, FrameRecord& record);
  int addDebris(std::vector<int>& broken);
  [[noreturn]] void throwRebuildError(const Error& e, int ruptureFrame) const;

  SimulationConfig config_;
  std::unique_ptr<SimModel> model_;
  std::unique_ptr<NonlocalStress> nonlocal_;  // criticalStressRadiusM > 0, rupture on
  SimState state_;
  FrameRecord record_;

  // rupture and rebuild
  std::vector<std::uint8_t> pending_;          // per tet: broken, waiting for (or in) a rebuild
  std::vector<int> queued_;                    // broken since the rebuild in flight started
  std::future<std::unique_ptr<Rebuilt>> job_;  // the rebuild in flight (background)
  // update mode: the electric columns of the surface a removal exposed, computed on a thread
  // between the removal frame and the next solve (joined first by whatever uses the solver)
  mutable std::future<void> prefetchJob_;
  void joinPrefetch() const;
  // update mode: the structural phase's removal update (its factor's rowdel / updown), on a thread
  // from the removal frame's rupture to the next structural solve, while the other phases' updates
  // and the next frame's contacts, potential and heat run (the same arithmetic as in the frame
  // loop: the result does not depend on the timing) (on a kept helper thread: sim/two_threads.h)
  mutable std::future<StructuralUpdateStats> structuralJob_;
  mutable HelperRun structuralRun_;  // the helper running it (waited for with it)
  mutable std::exception_ptr structuralError_;
  mutable StructuralUpdateStats structuralJobStats_;  // of the last one joined
  int structuralJobFrame_ = -1;           // the removal frame (its errors are that rupture's)
  void waitStructural() const;            // joins; keeps its error for joinStructural
  void joinStructural();                  // joins, and throws its error as the rupture's
  std::unique_ptr<Rebuilt> ready_;        // synchronous rebuild, or the job's result
  int swapFrame_ = -1;                    // frame at which the rebuild in flight swaps in
  std::unique_ptr<SimState> checkpoint_;  // state when the rebuild in flight started
  int recomputedFrames_ = 0;              // frames computed again after swaps
  int framesContactByTet_ = 0, framesToolSwept_ = 0, framesBoilingUnconverged_ = 0;
  std::string piecesWarning_;   // set-up: pieces of the mesh with no return-electrode node
  std::string depthWarning_;    // set-up: the tool's path deeper than its contact distance
  int framesMaxPrinciple_ = 0;  // frames whose temperature left its bounds
  int framesSubgrid_ = 0;       // frames the sub-grid contact model carried the contact
  // electric: frames with the generator on, and with the tool in contact
  int framesGeneratorOn_ = 0, framesInContact_ = 0;
  std::vector<SurfaceSample> electrodeSamples_;  // sub-grid contact: the electrode's surface
  std::unique_ptr<SubgridFrame> subgridFrame_;   // ... this frame's contact (solve -> heat)
  std::vector<std::uint8_t> contactMark_;        // ... scratch: per node, in contact
  double worstMaxPrincipleK_ = 0;                // by how much at most [K]
  double lowestC_ = 0;  // the initial minimum temperature: the lower bound [C]
  int removedTets_ = 0;
  int debrisTets_ = 0;                          // of which removed as debris
  std::vector<std::uint8_t> debrisSupported_;   // per node: held by a support (debris only)
  int rebuilds_ = 0, rebuildsLate_ = 0;         // swapped in; of which had to wait > 1 ms
  mutable int structuralRefactorizations_ = 0;  // update mode: see structuralRefactorizations()
  double rebuildBuildMs_ = 0;                   // sum of the rebuilds' build times
  double rebuildWaitMs_ = 0;                    // longest wait for a background rebuild
};

}  // namespace esim
