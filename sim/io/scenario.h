// scenario.h - a scenario: everything one run needs, read from scenarios/*.yaml.
//
// `Scenario` is plain data (no YAML types), every field defaulted to the seed paper's
// set-up (Table 1 materials, Table 2 boundary conditions: 72 V tool, 40 mm return disc,
// 100 x 100 x 10 mm slab of 1013 nodes). SI units, the unit is in each name.
// The schema (key path, type, default, unit, range or choices, description of every
// field) is one table in scenario_schema.cpp; the loader validates against it and
// `scenarioReferenceMarkdown()` renders it as docs/scenario-reference.md.
//
// Loading: parse YAML -> apply `--set key.path=value` overrides (values parsed as YAML)
// -> check every key, type and range -> cross-field checks (phase dependencies, tool
// path times, asset files). Any problem throws esim::Error naming
// `file:line:column: field.path: what is wrong; what is expected`.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <limits>
#include <string>
#include <vector>

#include "sim/io/mesh_import.h"
#include "sim/mesh_slab.h"
#include "sim/mesh_tet.h"
#include "sim/simulation.h"
#include "sim/tool_path.h"

namespace esim {

namespace scenario_detail {
// the core's defaults: the one source of the physical and solver defaults below
inline const SimulationConfig& core() { return defaultSimulationConfig(); }
}  // namespace scenario_detail

// choices held as enums from the load on (their names are in the schema, scenario_schema.cpp;
// the core's own enums where it has one: ElectrodeKind, ElectricStrategy, ThermalIntegrator,
// RebuildMode, StructuralSolveMethod)
enum class MeshSource { Slab, File };
enum class HeatSourceKind { None, Gaussian };
enum class ThermalMass { Lumped, Consistent };

// physics phases, in pipeline order
enum class Phase : int { Electric = 0, Thermal, Boiling, Structural, Rupture };

// ---- mesh ----
struct ScenarioGrading {
  bool enabled = false;
  Vec3 fromM{-0.04, 0.0, 0.01};  // planned cut start [m]
  Vec3 toM{0.04, 0.0, 0.01};     // planned cut end [m]
  double ratio = 4.0;            // coarse / fine spacing
  double widthM = 0.01;          // fine zone half-width [m]
  bool towardTop = true;         // also refine toward the top face
  bool operator==(const ScenarioGrading&) const = default;
};

struct ScenarioSlab {
  Vec3 sizeM{0.1, 0.1, 0.01};                // Lx, Ly, Lz [m]
  int nodes = 1013;                          // target node count
  std::array<int, 3> nodesPerAxis{0, 0, 0};  // explicit grid, zeros = from `nodes`
  ScenarioGrading grading;
  bool operator==(const ScenarioSlab&) const = default;
};

// local refinement of a surface-file mesh around the planned cut (MeshingOptions::Refinement)
struct ScenarioRefine {
  bool enabled = false;
  Vec3 fromM{-0.04, 0.0, 0.02};  // planned cut start [m]
  Vec3 toM{0.04, 0.0, 0.02};     // planned cut end [m]
  double cellSizeM = 0.001;      // tet size bound within width_m of the segment [m]
  double widthM = 0.005;         // fine-zone radius; sizes grow back over another width [m]
  bool operator==(const ScenarioRefine&) const = default;
};

struct ScenarioMeshFile {
  std::string path;                // as written (relative to the scenario or repo root)
  double scaleToM = 1.0;           // file units -> metres
  double cellSizeM = 0.004;        // max tet circumradius [m]
  double facetSizeM = 0.004;       // max surface triangle circumradius [m]
  double facetDistanceM = 0.0005;  // max surface approximation error [m]
  double facetAngleDeg = 25.0;     // min surface triangle angle [deg]
  double radiusEdgeRatio = 2.5;    // max tet circumradius / shortest edge
  ScenarioRefine refine;           // finer cells near the planned cut
  std::string resolvedPath;        // filled by the loader: the file found (not in YAML)
  bool operator==(const ScenarioMeshFile&) const = default;
};

struct ScenarioMesh {
  MeshSource source = MeshSource::Slab;  // slab | file
  ScenarioSlab slab;
  ScenarioMeshFile file;
  bool operator==(const ScenarioMesh&) const = default;
};

// ---- material (paper Table 1, porcine liver) ----
// The physical and solver defaults below are the core's (scenario_detail::core(), that is
// defaultSimulationConfig() in sim/simulation.h): one source, never a second literal.
struct ScenarioMaterial {
  // c*rho
  double heatCapacityJPerM3K = scenario_detail::core().thermal.heatCapacityJ_m3K;
  // lambda
  double thermalConductivityWPerMK = scenario_detail::core().thermal.conductivityW_mK;
  // sigma at 37 C
  double electricConductivitySPerM = scenario_detail::core().conductivityS_m;
  double youngsModulusPa = scenario_detail::core().structural.youngsModulusPa;
  double poissonRatio = scenario_detail::core().structural.poissonRatio;
  // von Mises breaking stress
  double criticalStressPa = scenario_detail::core().criticalStressPa;
  // radius of the average compared with it (0: each element's own)
  double criticalStressRadiusM = scenario_detail::core().criticalStressRadiusM;
  // pieces cut loose up to this volume are removed with the cut (0: kept)
  double debrisVolumeM3 = scenario_detail::core().debrisVolumeM3;
  // v_gas / v_liq of water at boiling, 1 atm
  double vaporLiquidVolumeRatio = scenario_detail::core().vaporLiquidVolumeRatio;
  // cap of the volumetric expansion (vapour vents)
  double maxVaporExpansion = scenario_detail::core().maxVaporExpansion;
  double densityKgPerM3 = scenario_detail::core().thermal.densityKg_m3;
  // mass fraction of water
  double waterFraction = scenario_detail::core().thermal.waterFraction;
  // vaporization of water
  double latentHeatJPerKg = scenario_detail::core().thermal.latentHeatJ_kg;
  double boilingTemperatureC = scenario_detail::core().thermal.boilingTemperatureC;
  double initialTemperatureC = scenario_detail::core().thermal.initialTemperatureC;
  // sigma(T) = sigma0 (1 + a (T - T0))
  double conductivityTempCoeffPerK = scenario_detail::core().conductivityTempCoeffPerK;
  // sigma multiplier once dried
  double desiccatedConductivityFactor = scenario_detail::core().desiccatedConductivityFactor;
  // damage frequency factor
  double arrheniusAPerS = scenario_detail::core().thermal.arrheniusA_s;
  // damage activation energy
  double arrheniusEaJPerMol = scenario_detail::core().thermal.arrheniusEa_J_mol;
  bool operator==(const ScenarioMaterial&) const = default;
};

struct ScenarioReturnElectrode {
  Vec3 centerM = scenario_detail::core().returnElectrode.centerM;
  // outward normal of the disc (normalized by the user of it)
  Vec3 normal = scenario_detail::core().returnElectrode.normal;
  double radiusM = scenario_detail::core().returnElectrode.radiusM;
  // boundary nodes within this distance of the disc plane
  double toleranceM = scenario_detail::core().returnElectrode.toleranceM;
  bool operator==(const ScenarioReturnElectrode&) const = default;
};

// ---- tool ----
struct ScenarioKeyframe {
  double timeS = 0.0;
  Vec3 positionM{0.0, 0.0, 0.0098};    // tip [m]
  Vec3 orientationDeg{0.0, 0.0, 0.0};  // [rx, ry, rz] fixed-axis XYZ (sim/tool_path.h)
  bool operator==(const ScenarioKeyframe&) const = default;
};

struct ScenarioTool {
  ElectrodeKind shape = scenario_detail::core().electrode.kind;  // blade | sphere
  // sphere radius / blade edge half-thickness
  double radiusM = scenario_detail::core().electrode.radiusM;
  double lengthM = scenario_detail::core().electrode.lengthM;
  // blade width
  double widthM = scenario_detail::core().electrode.widthM;
  double voltageV = scenario_detail::core().toolVoltageV;
  // nodes this close to the tool surface are in contact
  double contactDistanceM = scenario_detail::core().contactDistanceM;
  // the nodes it may touch: surface | volume
  ContactNodes contact = scenario_detail::core().contactNodes;
  std::vector<ScenarioKeyframe> path{ScenarioKeyframe{}};
  // the keyframes from a CSV file instead (a line t_s, x_m, y_m, z_m[, rx_deg, ry_deg,
  // rz_deg]); as written, resolved like mesh.file.path; `path` then holds what it read
  std::string pathFile;
  std::string pathFileResolved;  // absolute (set by loading; not a scenario key)
  // [on, off) intervals [s]; the default [[0, inf]] is always on; [] is never on
  std::vector<std::array<double, 2>> generatorOnS{{0.0, std::numeric_limits<double>::infinity()}};
  bool operator==(const ScenarioTool&) const = default;
};

// ---- heat source for thermal scenes without the electric phase ----
struct ScenarioHeatSource {
  HeatSourceKind kind = HeatSourceKind::None;  // none | gaussian
  Vec3 centerM = scenario_detail::core().heatSource.centerM;
  // Gaussian 1/e radius [m]
  double radiusM = scenario_detail::core().heatSource.radiusM;
  // peak q [W/m^3]
  double powerDensityWPerM3 = scenario_detail::core().heatSource.powerDensityW_m3;
  bool operator==(const ScenarioHeatSource&) const = default;
};

struct ScenarioHotSpot {
  bool enabled = false;
  Vec3 centerM = scenario_detail::core().hotSpot.centerM;
  double radiusM = scenario_detail::core().hotSpot.radiusM;
  // nodes within radius start at this temperature
  double temperatureC = scenario_detail::core().hotSpot.temperatureC;
  bool operator==(const ScenarioHotSpot&) const = default;
};

struct ScenarioEffects {
  bool temperatureDependentConductivity = false;
  bool thermalDamage = false;
  double surfaceCoolingHWPerM2K = 0.0;  // convective h on the free surface (0 = insulated)
  double surfaceCoolingAmbientC = scenario_detail::core().thermal.ambientTemperatureC;
  // clamp nodes this close to the lowest z (structural)
  double structuralClampBandM = scenario_detail::core().clampBandM;
  bool operator==(const ScenarioEffects&) const = default;
};

// the contact below the mesh's resolution (sim/subgrid_contact.h)
struct ScenarioSubgridContact {
  SubgridMode mode = scenario_detail::core().subgrid.mode;  // off | auto | on
  // kappa: effective / wetted contact area (calibrated)
  double areaFactor = scenario_detail::core().subgrid.areaFactor;
  bool operator==(const ScenarioSubgridContact&) const = default;
};

struct ScenarioSolvers {
  // refactor|dense-inverse|capacitance|pcg|local|downdate|auto
  ElectricStrategy electricStrategy = scenario_detail::core().electricSolver.strategy;
  // pcg relative residual
  double electricTolerance = scenario_detail::core().electricSolver.pcgTolerance;
  int electricMaxIterations = scenario_detail::core().electricSolver.pcgMaxIterations;
  // pcg's preconditioner: jacobi | ic | two-level
  PcgPreconditioner electricPreconditioner =
      scenario_detail::core().electricSolver.pcgPreconditioner;
  // dense-inverse refuses above this
  int electricDenseMemoryLimitMb =
      static_cast<int>(scenario_detail::core().electricSolver.denseMemoryLimitBytes / 1048576.0);
  // capacitance's column cache holds at most this (esim run cuts it when memory runs short)
  int electricCacheMemoryLimitMb =
      static_cast<int>(scenario_detail::core().electricSolver.cacheMemoryLimitBytes / 1048576.0);
  int electricThreads = scenario_detail::core().electricSolver.threads;
  // local: the region's radius around the contacts [m], the far field's refresh period
  double electricLocalMarginM = scenario_detail::core().electricSolver.localMarginM;
  int electricLocalRefreshFrames = scenario_detail::core().electricSolver.localRefreshFrames;
  bool electricPrefetchPath = true;  // precompute what the scripted tool path touches
  // explicit | backward-euler | crank-nicolson | tr-bdf2
  ThermalIntegrator thermalIntegrator = scenario_detail::core().thermal.integrator;
  // lumped | consistent
  ThermalMass thermalMass =
      scenario_detail::core().thermal.lumpedMass ? ThermalMass::Lumped : ThermalMass::Consistent;
  bool thermalAllowSubstepping = scenario_detail::core().thermal.allowSubstepping;
  int thermalMaxSubsteps = scenario_detail::core().thermal.maxSubsteps;  // explicit, per frame
  // full | local | coarse (sim/structural.h LocalSolveOptions)
  StructuralSolveMethod structuralMethod = scenario_detail::core().structural.solveMethod;
  // element | nodal (sim/structural.h VolumetricStrain)
  VolumetricStrain structuralVolumetric = scenario_detail::core().structural.volumetric;
  // local: the region is the nodes within this of the load change's box
  double structuralLocalMarginM = scenario_detail::core().structural.local.marginM;
  // local: the box grown by this when a region is built [m]
  double structuralLocalSlackM = scenario_detail::core().structural.local.slackM;
  // local: a larger region (fraction of the unknowns) is a full solve instead
  double structuralLocalMaxRegionFraction =
      scenario_detail::core().structural.local.maxRegionFraction;
  // local: a full solve (the new reference) at least every this many solves
  int structuralLocalRefreshEvery = scenario_detail::core().structural.local.refreshEvery;
  // local: that full solve on a thread of the phase, adopted refresh_every solves later
  bool structuralLocalRefreshOnThread = scenario_detail::core().structural.local.refreshOnThread;
  // coarse: the coarse grid's cell size, at most [m]
  double structuralCoarseSpacingM = scenario_detail::core().structural.local.coarseSpacingM;
  // coarse: the box holds the tets whose load changed by more than this times the largest
  double structuralCoarseLoadTolerance =
      scenario_detail::core().structural.local.coarseLoadTolerance;
  // coarse: the region's correction after the coarse solve (false: the coarse solve alone)
  bool structuralCoarseCorrection = scenario_detail::core().structural.local.coarseCorrection;
  // a removal's factor update by the vectorized kernel (else cholmod_updown)
  bool structuralVectorizedUpdate = scenario_detail::core().structural.vectorizedUpdate;
  // threads of an updated factor's triangular solves and of a removal's update (1 or 2, the
  // same bits either way; 0: CHOLMOD's solve)
  int structuralSolveThreads = scenario_detail::core().structural.solveThreads;
  // synchronous | background | update
  RebuildMode rebuildMode = scenario_detail::core().rebuildMode;
  // background: frames until the swap
  int rebuildLagFrames = scenario_detail::core().rebuildLagFrames;
  // background: the lag frames again, new model
  bool rebuildRecompute = scenario_detail::core().recomputeLagFrames;
  bool operator==(const ScenarioSolvers&) const = default;
};

struct ScenarioTime {
  double fps = 30.0;
  double durationS = 4.0;
  bool operator==(const ScenarioTime&) const = default;
};

struct ScenarioCamera {
  Vec3 eyeM{0.0, -0.13, 0.11};
  Vec3 targetM{0.0, 0.0, 0.005};
  Vec3 up{0.0, 0.0, 1.0};
  double fovDeg = 40.0;  // vertical field of view
  bool operator==(const ScenarioCamera&) const = default;
};

struct ScenarioLook {
  std::string style = "temperature";  // temperature | tissue | potential (needs electric)
  std::string colormap = "inferno";   // inferno | viridis
  double tMinC = 37.0;
  double tMaxC = 120.0;
  double vMinV = 0.0;                     // potential colour map range [V]
  double vMaxV = 0.0;                     // 0 = tool.voltageV
  std::string potentialScale = "linear";  // linear | log (log needs vMinV > 0)
  int width = 1280;
  int height = 720;
  int msaa = 4;                    // multisample anti-aliasing samples: 0 (off, fastest), 2 or 4
  std::string shading = "vertex";  // lighting "vertex" (interpolated, faster) or "pixel"
  bool colorBar = true;
  bool showTime = true;
  double displacementScale = 1.0;  // structural: drawn displacement / computed
  // appearance, for datasets that vary it (render/renderer.h, RenderOptions)
  int textureSeed = 0;                     // tissue style: the mottling's pattern
  Vec3 tissueTint{1.0, 1.0, 1.0};          // tissue style: its colours times this RGB
  Vec3 lightDirection{-0.45, 0.65, 0.60};  // key light, camera frame (right, up, back)
  double lightIntensity = 1.0;             // key and fill lights' strength
  int cutWallSmoothing = 3;                // passes over the cut walls' normals
  int cutWallDamageSmoothing = 0;          // passes over the cut walls' coagulation, desiccation
  bool operator==(const ScenarioLook&) const = default;
};

struct ScenarioOutput {
  bool video = true;
  int crf = 20;  // H.264 constant rate factor
  // x264 preset: veryfast, measured on slab_cut (120 frames, 1280x720, crf 20): the
  // encoder's thread 1.5-1.6 s against 3.3-4.0 s with medium, the PSNR against the frames'
  // PNGs 36.01 against 36.07 dB, the file 208 against 242 kB
  std::string preset = "veryfast";
  // "during": encoded beside the frame loop; "after": frames kept raw, encoded at the end
  std::string encode = "during";
  bool reproducible = true;  // single-threaded deterministic encode
  int pngEvery = 0;          // write every Nth frame as PNG (0 = none)
  int fieldsEvery = 0;       // write every Nth frame as VTU (0 = none)
  bool hashes = true;        // hashes.json
  bool operator==(const ScenarioOutput&) const = default;
};

struct Scenario {
  std::string name = "unnamed";
  std::string description;
  ScenarioMesh mesh;
  ScenarioMaterial material;
  ScenarioReturnElectrode returnElectrode;
  ScenarioTool tool;
  std::vector<Phase> physics{Phase::Electric, Phase::Thermal, Phase::Boiling};  // sorted
  ScenarioHeatSource heatSource;
  ScenarioHotSpot initialHotSpot;
  ScenarioEffects effects;
  ScenarioSubgridContact subgridContact;
  ScenarioSolvers solvers;
  ScenarioTime time;
  ScenarioCamera camera;
  ScenarioLook look;
  ScenarioOutput output;
  std::string sourceName;  // the file it came from (not in YAML; "" for defaults)

  bool has(Phase p) const;
  bool operator==(const Scenario&) const = default;
};

// ---- loading ----

// reads, overrides (`key.path=value`, value parsed as YAML) and validates a scenario file;
// a folder or an unreadable file is an Error naming it. "-" is standard input (read once;
// named "<stdin>" in messages; relative asset paths from the working folder)
Scenario loadScenario(const std::string& path, const std::vector<std::string>& overrides = {});

// the bound on a scenario or sweep file read by readYamlText: /dev/zero or a wrong file (a
// video) given as the scenario was read until memory ran out
inline constexpr size_t kMaxYamlBytes = size_t{16} << 20;

// the whole of `in` into text, or false as soon as it holds more than maxBytes (an endless
// file: /dev/zero, /proc/kcore); a failed read throws Error "NAME: read failed" (run)
bool readAtMost(std::istream& in, const std::string& name, size_t maxBytes, std::string& text);

// the whole of `in` (a scenario or sweep file, standard input), at most kMaxYamlBytes: more
// throws Error "NAME: more than 16 MiB; a WHAT is a short YAML file (...)"
std::string readYamlText(std::istream& in, const std::string& name, const std::string& what);

// YAML is Unicode text: throws Error "WHERE[:LINE:COLUMN]: not UTF-8 text (byte 0xE9); ..." at
// the first byte of `text` that is not well-formed UTF-8 (a file saved as Latin-1). Left in a
// name, such a byte reached the run's JSON reports, whose writer threw at the end of the run
// (exit 4, every frame computed and only DIR.partial/ left). Throws "...: a control character
// (byte 0x00) that YAML does not allow in text; ..." at a C0 control other than tab, line feed
// and carriage return, or DEL (escapes such as "\x1e" in double quotes are taken)
void requireUtf8Text(const std::string& text, const std::string& where, bool lineAndColumn);

// "" when a text value (after its escapes are decoded) is UTF-8, else what is wrong with it:
// yaml-cpp decodes "\N" (U+0085) to the one byte 0x85, and a scenario (or sweep) holding it
// could not be written back and read again
std::string decodedTextProblem(const std::string& value);

// same from text; sourceName is used in messages and to resolve relative asset paths
Scenario parseScenario(const std::string& yamlText, const std::string& sourceName,
                       const std::vector<std::string>& overrides = {});

// the fully resolved scenario as YAML (every field, in schema order); parse(toYaml(s)) == s
std::string scenarioToYaml(const Scenario& scenario);

// a number as a scenario (and --set KEY=VALUE) writes it: the shortest text that reads back
// to the same double (std::to_string would give 0.000000 for 1e-7 and 309 digits for 1e308)
std::string scenarioNumber(double value);

// FNV-1a 64-bit hash of scenarioToYaml (stable across runs and machines)
std::uint64_t scenarioHash(const Scenario& scenario);

// the schema as a Markdown reference page (docs/scenario-reference.md)
std::string scenarioReferenceMarkdown();

// one schema row in printable form (what the reference page shows)
struct ScenarioFieldInfo {
  std::string path;  // YAML key path, e.g. "tool.voltage_v" ("tool.path[].t_s" for keyframes)
  std::string type;  // "number", "integer", "bool", "choice", "string", "vector", ...
  std::string defaultYaml;  // the default as YAML text, e.g. "72", "[0, 0, -1]"
  std::string unit;         // "V", "m", "" (dimensionless)
  std::string allowed;      // "[0, 1]", "(0, 0.1]", "blade | sphere"
  std::string description;  // one line
};

// every field of the schema, in schema order
std::vector<ScenarioFieldInfo> scenarioFields();

// ---- derived values for the runner ----

// number of frames: round(duration * fps), at least 1
int frameCount(const Scenario& scenario);

// the listed phases as the core's PhaseSet
PhaseSet phaseSet(const Scenario& scenario);

// phase names: "electric", "thermal", ...
const char* phaseName(Phase phase);

// the slab generator's spec (mesh.source == "slab")
SlabSpec makeSlabSpec(const Scenario& scenario);

// mesh.file.* as Mesh_3 options (sizes, refinement around the planned cut)
MeshingOptions makeMeshingOptions(const Scenario& scenario);

// keyframes with Euler degrees turned into quaternions, generator intervals in seconds
ToolPath makeToolPath(const Scenario& scenario);

// one-line summary: "120 frames, physics [electric, thermal], mesh slab 100x100x10 mm ..."
std::string scenarioSummary(const Scenario& scenario);

}  // namespace esim
