// scenario.cpp - the scenario schema (one table), YAML loader, validator and writer.
//
// Outline:
//   ---- schema ----     the table: key path, type, unit, range/choices, description and a
//                        reference to the Scenario member (defaults come from Scenario{})
//   ---- formatting ---- numbers and values as YAML text (shortest round-trip doubles)
//   ---- reader ----     YAML tree -> Scenario with file:line:col errors and suggestions
//   ---- checks ----     cross-field rules (phase dependencies, assets, camera, ...)
//   ---- public API ---- load/parse/toYaml/hash/reference/derived values
#include "sim/io/scenario.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <variant>

#include "sim/core_error.h"

namespace esim {

namespace {

namespace fs = std::filesystem;
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- schema ----

enum class Kind {
  Number,
  Integer,
  Bool,
  Choice,
  Text,
  Vector,
  IntTriple,
  Phases,
  Keyframes,
  Intervals
};

// an interval of allowed values; open ends exclude the bound
struct Range {
  double lo = -kInf, hi = kInf;
  bool loOpen = true, hiOpen = true;
  bool contains(double v) const {
    if (std::isnan(v)) return false;
    const bool okLo = loOpen ? v > lo : v >= lo;
    const bool okHi = hiOpen ? v < hi : v <= hi;
    return okLo && okHi;
  }
};
Range closed(double lo, double hi) { return {lo, hi, false, false}; }
Range positive(double hi) { return {0.0, hi, true, false}; }          // (0, hi]
Range openHi(double lo, double hi) { return {lo, hi, false, true}; }  // [lo, hi)

using NumberRef = double& (*)(Scenario&);
using IntRef = int& (*)(Scenario&);
using BoolRef = bool& (*)(Scenario&);
using StringRef = std::string& (*)(Scenario&);
using VecRef = Vec3& (*)(Scenario&);
using Int3Ref = std::array<int, 3>& (*)(Scenario&);
using PhasesRef = std::vector<Phase>& (*)(Scenario&);
using KeysRef = std::vector<ScenarioKeyframe>& (*)(Scenario&);
using IntervalsRef = std::vector<std::array<double, 2>>& (*)(Scenario&);
using Ref = std::variant<NumberRef, IntRef, BoolRef, StringRef, VecRef, Int3Ref, PhasesRef, KeysRef,
                         IntervalsRef>;

struct Field {
  std::string path;  // YAML key path
  Kind kind;
  std::string unit;  // SI symbol, "" when dimensionless
  Range range;       // numbers, integers, each vector component, interval ends
  std::vector<std::string> choices;
  std::string description;
  Ref ref;
  bool nonzero = false;  // vectors that must not be zero (directions)
};

// a captureless lambda giving the member as a function pointer
#define ESIM_REF(member) +[](Scenario& s) -> decltype(auto) { return (s.member); }

Field number(std::string path, NumberRef r, std::string unit, Range range, std::string desc) {
  return {std::move(path), Kind::Number, std::move(unit), range, {}, std::move(desc), r};
}
Field integer(std::string path, IntRef r, std::string unit, Range range, std::string desc) {
  return {std::move(path), Kind::Integer, std::move(unit), range, {}, std::move(desc), r};
}
Field boolean(std::string path, BoolRef r, std::string desc) {
  return {std::move(path), Kind::Bool, "", {}, {}, std::move(desc), r};
}
Field choice(std::string path, StringRef r, std::vector<std::string> choices, std::string desc) {
  return {std::move(path), Kind::Choice, "", {}, std::move(choices), std::move(desc), r};
}
Field text(std::string path, StringRef r, std::string desc) {
  return {std::move(path), Kind::Text, "", {}, {}, std::move(desc), r};
}
Field vector(std::string path, VecRef r, std::string unit, Range range, std::string desc,
             bool nonzero = false) {
  return {std::move(path), Kind::Vector, std::move(unit), range, {}, std::move(desc), r, nonzero};
}

const std::vector<std::string> kPhaseNames{"electric", "thermal", "boiling", "structural",
                                           "rupture"};

// the schema: the single source of truth for keys, types, units, ranges and descriptions.
// Defaults are the member initializers of Scenario (scenario.h). Groups are contiguous.
const std::vector<Field>& schema() {
  static const std::vector<Field> fields = [] {
    std::vector<Field> f;
    const Range anyPos = closed(-10.0, 10.0);
    f.push_back(text("name", ESIM_REF(name), "short name of the run, used in titles and reports"));
    f.push_back(text("description", ESIM_REF(description), "free text: what the scene shows"));
    // mesh
    f.push_back(choice("mesh.source", ESIM_REF(mesh.source), {"slab", "file"},
                       "slab: the box generator; file: a closed surface meshed with CGAL"));
    f.push_back(vector("mesh.slab.size_m", ESIM_REF(mesh.slab.sizeM), "m", positive(10.0),
                       "slab size Lx, Ly, Lz; x, y centred on 0, z from 0 (bottom) to Lz (top)"));
    f.push_back(integer("mesh.slab.nodes", ESIM_REF(mesh.slab.nodes), "", closed(8, 1e7),
                        "target node count (paper: 506, 643, 1013); ignored with nodes_per_axis"));
    f.push_back({"mesh.slab.nodes_per_axis",
                 Kind::IntTriple,
                 "",
                 closed(0, 1000),
                 {},
                 "explicit grid nodes px, py, pz (each >= 2); [0, 0, 0] = derive from nodes",
                 ESIM_REF(mesh.slab.nodesPerAxis)});
    f.push_back(boolean("mesh.slab.grading.enabled", ESIM_REF(mesh.slab.grading.enabled),
                        "refine the grid around a planned cut segment"));
    f.push_back(vector("mesh.slab.grading.from_m", ESIM_REF(mesh.slab.grading.fromM), "m", anyPos,
                       "planned cut segment start"));
    f.push_back(vector("mesh.slab.grading.to_m", ESIM_REF(mesh.slab.grading.toM), "m", anyPos,
                       "planned cut segment end"));
    f.push_back(number("mesh.slab.grading.ratio", ESIM_REF(mesh.slab.grading.ratio), "",
                       closed(1, 100), "coarse / fine spacing ratio"));
    f.push_back(number("mesh.slab.grading.width_m", ESIM_REF(mesh.slab.grading.widthM), "m",
                       positive(10.0), "half-width of the fine zone around the segment"));
    f.push_back(boolean("mesh.slab.grading.toward_top", ESIM_REF(mesh.slab.grading.towardTop),
                        "also refine the depth toward the top face"));
    f.push_back(text("mesh.file.path", ESIM_REF(mesh.file.path),
                     "surface file (OBJ, STL, PLY, OFF); relative to the scenario's folder, "
                     "then the repository root, then the working directory"));
    f.push_back(number("mesh.file.scale_to_m", ESIM_REF(mesh.file.scaleToM), "m", positive(1000.0),
                       "metres per file unit (0.001 for a file in mm)"));
    f.push_back(number("mesh.file.cell_size_m", ESIM_REF(mesh.file.cellSizeM), "m", positive(1.0),
                       "largest tetrahedron circumradius"));
    f.push_back(number("mesh.file.facet_size_m", ESIM_REF(mesh.file.facetSizeM), "m", positive(1.0),
                       "largest surface triangle circumradius"));
    f.push_back(number("mesh.file.facet_distance_m", ESIM_REF(mesh.file.facetDistanceM), "m",
                       positive(1.0), "largest distance between the mesh surface and the input"));
    f.push_back(number("mesh.file.facet_angle_deg", ESIM_REF(mesh.file.facetAngleDeg), "deg",
                       positive(30.0), "smallest surface triangle angle (CGAL guarantees <= 30)"));
    f.push_back(number("mesh.file.radius_edge_ratio", ESIM_REF(mesh.file.radiusEdgeRatio), "",
                       closed(2.0, 10.0), "largest tetrahedron circumradius / shortest edge"));
    f.push_back(boolean("mesh.file.refine.enabled", ESIM_REF(mesh.file.refine.enabled),
                        "make tets and surface facets finer around a planned cut segment"));
    f.push_back(vector("mesh.file.refine.from_m", ESIM_REF(mesh.file.refine.fromM), "m", anyPos,
                       "planned cut segment start (in the file's frame after scale_to_m)"));
    f.push_back(vector("mesh.file.refine.to_m", ESIM_REF(mesh.file.refine.toM), "m", anyPos,
                       "planned cut segment end"));
    f.push_back(number("mesh.file.refine.cell_size_m", ESIM_REF(mesh.file.refine.cellSizeM), "m",
                       positive(1.0),
                       "tet circumradius bound within width_m of the segment (<= cell_size_m); "
                       "facet size and distance shrink by the same factor"));
    f.push_back(number("mesh.file.refine.width_m", ESIM_REF(mesh.file.refine.widthM), "m",
                       positive(10.0),
                       "radius of the fine zone; sizes grow linearly back to the global ones "
                       "over another width_m"));
    // material
    f.push_back(number("material.heat_capacity_j_per_m3k", ESIM_REF(material.heatCapacityJPerM3K),
                       "J/(m^3 K)", positive(1e8),
                       "volumetric heat capacity c*rho (paper Table 1)"));
    f.push_back(number("material.thermal_conductivity_w_per_mk",
                       ESIM_REF(material.thermalConductivityWPerMK), "W/(m K)", positive(100.0),
                       "thermal conductivity lambda (paper Table 1)"));
    f.push_back(number("material.electric_conductivity_s_per_m",
                       ESIM_REF(material.electricConductivitySPerM), "S/m", positive(1e3),
                       "electric conductivity sigma at the initial temperature (paper Table 1)"));
    f.push_back(number("material.youngs_modulus_pa", ESIM_REF(material.youngsModulusPa), "Pa",
                       positive(1e12), "Young's modulus E (paper Table 1)"));
    f.push_back(number("material.poisson_ratio", ESIM_REF(material.poissonRatio), "",
                       openHi(0.0, 0.5), "Poisson's ratio nu (paper Table 1)"));
    f.push_back(number("material.critical_stress_pa", ESIM_REF(material.criticalStressPa), "Pa",
                       positive(1e12), "von Mises stress that breaks an element (paper Table 1)"));
    f.push_back(number("material.vapor_liquid_volume_ratio",
                       ESIM_REF(material.vaporLiquidVolumeRatio), "", closed(1.0, 1e4),
                       "volume of water vapour / liquid at boiling and 1 atm (steam tables: "
                       "1.673 / 0.001044); the trapped vapour's expansion loads the structural "
                       "phase"));
    f.push_back(number("material.max_vapor_expansion", ESIM_REF(material.maxVaporExpansion), "",
                       closed(0.0, 1e4),
                       "cap of the tissue's volumetric expansion dV/V (the vapour vents once the "
                       "tissue parts; see sim/structural.h for its effect on the cut)"));
    f.push_back(number("material.density_kg_per_m3", ESIM_REF(material.densityKgPerM3), "kg/m^3",
                       positive(1e5), "tissue density rho"));
    f.push_back(number("material.water_fraction", ESIM_REF(material.waterFraction), "",
                       closed(0.0, 1.0), "mass fraction of water"));
    f.push_back(number("material.latent_heat_j_per_kg", ESIM_REF(material.latentHeatJPerKg), "J/kg",
                       positive(1e8), "latent heat of vaporization of water"));
    f.push_back(number("material.boiling_temperature_c", ESIM_REF(material.boilingTemperatureC),
                       "C", closed(0.0, 300.0), "temperature at which tissue water boils"));
    f.push_back(number("material.initial_temperature_c", ESIM_REF(material.initialTemperatureC),
                       "C", closed(-50.0, 300.0), "uniform initial temperature"));
    f.push_back(number("material.conductivity_temp_coeff_per_k",
                       ESIM_REF(material.conductivityTempCoeffPerK), "1/K", closed(-1.0, 1.0),
                       "sigma(T) = sigma0 (1 + a (T - T0)) with effects."
                       "temperature_dependent_conductivity"));
    f.push_back(number("material.desiccated_conductivity_factor",
                       ESIM_REF(material.desiccatedConductivityFactor), "", positive(1.0),
                       "sigma multiplier of fully dried tissue"));
    f.push_back(number("material.arrhenius_a_per_s", ESIM_REF(material.arrheniusAPerS), "1/s",
                       {0.0, kInf, true, true}, "Arrhenius damage frequency factor A"));
    f.push_back(number("material.arrhenius_ea_j_per_mol", ESIM_REF(material.arrheniusEaJPerMol),
                       "J/mol", positive(1e7), "Arrhenius damage activation energy Ea"));
    // return electrode
    f.push_back(vector("return_electrode.center_m", ESIM_REF(returnElectrode.centerM), "m", anyPos,
                       "centre of the return electrode disc"));
    f.push_back(vector("return_electrode.normal", ESIM_REF(returnElectrode.normal), "",
                       closed(-1e3, 1e3), "outward normal of the disc (any length, not zero)",
                       true));
    f.push_back(number("return_electrode.radius_m", ESIM_REF(returnElectrode.radiusM), "m",
                       positive(10.0), "disc radius (paper: 40 mm)"));
    f.push_back(number("return_electrode.tolerance_m", ESIM_REF(returnElectrode.toleranceM), "m",
                       closed(0.0, 1.0), "boundary nodes this close to the disc are grounded"));
    // tool
    f.push_back(choice("tool.shape", ESIM_REF(tool.shape), {"blade", "sphere"},
                       "electrode shape: flat blade or ball tip"));
    f.push_back(number("tool.radius_m", ESIM_REF(tool.radiusM), "m", positive(0.1),
                       "ball radius, or the blade edge's half-thickness"));
    f.push_back(number("tool.length_m", ESIM_REF(tool.lengthM), "m", positive(1.0),
                       "length along the axis (drawn and used for contact)"));
    f.push_back(
        number("tool.width_m", ESIM_REF(tool.widthM), "m", positive(0.1), "blade width (local x)"));
    f.push_back(number("tool.voltage_v", ESIM_REF(tool.voltageV), "V", closed(0.0, 1e4),
                       "tool potential while the generator is on (paper: 72 V)"));
    f.push_back(number("tool.contact_distance_m", ESIM_REF(tool.contactDistanceM), "m",
                       closed(0.0, 0.1), "surface nodes this close to the tool are in contact"));
    f.push_back({"tool.path",
                 Kind::Keyframes,
                 "",
                 {},
                 {},
                 "keyframes {t_s, position_m, orientation_deg}: tip position linear, orientation "
                 "slerp, held before the first and after the last",
                 ESIM_REF(tool.path)});
    f.push_back({"tool.generator_on",
                 Kind::Intervals,
                 "s",
                 {0.0, kInf, false, false},
                 {},
                 "[on, off) intervals when the generator is on; [[0, .inf]] = always, [] = never",
                 ESIM_REF(tool.generatorOnS)});
    // physics
    f.push_back({"physics",
                 Kind::Phases,
                 "",
                 {},
                 kPhaseNames,
                 "the phases to simulate; only these are built",
                 ESIM_REF(physics)});
    // heat source and hot spot (thermal scenes without the electric phase)
    f.push_back(choice("heat_source.kind", ESIM_REF(heatSource.kind), {"none", "gaussian"},
                       "prescribed heat source, only for thermal without electric"));
    f.push_back(vector("heat_source.center_m", ESIM_REF(heatSource.centerM), "m", anyPos,
                       "centre of the Gaussian source"));
    f.push_back(number("heat_source.radius_m", ESIM_REF(heatSource.radiusM), "m", positive(10.0),
                       "1/e radius of the Gaussian: q = q0 exp(-r^2 / radius^2)"));
    f.push_back(number("heat_source.power_density_w_per_m3",
                       ESIM_REF(heatSource.powerDensityWPerM3), "W/m^3", closed(0.0, 1e15),
                       "peak power density q0 (on while the generator is on)"));
    f.push_back(boolean("initial_hot_spot.enabled", ESIM_REF(initialHotSpot.enabled),
                        "start with a ball of hot tissue"));
    f.push_back(vector("initial_hot_spot.center_m", ESIM_REF(initialHotSpot.centerM), "m", anyPos,
                       "centre of the hot ball"));
    f.push_back(number("initial_hot_spot.radius_m", ESIM_REF(initialHotSpot.radiusM), "m",
                       positive(10.0), "radius of the hot ball"));
    f.push_back(number("initial_hot_spot.temperature_c", ESIM_REF(initialHotSpot.temperatureC), "C",
                       closed(-50.0, 1000.0), "initial temperature inside the ball"));
    // effects
    f.push_back(boolean("effects.temperature_dependent_conductivity",
                        ESIM_REF(effects.temperatureDependentConductivity),
                        "sigma follows temperature and drying (needs electric and thermal)"));
    f.push_back(boolean("effects.thermal_damage", ESIM_REF(effects.thermalDamage),
                        "accumulate Arrhenius damage (coagulation; needs thermal)"));
    f.push_back(number("effects.surface_cooling.h_w_per_m2k",
                       ESIM_REF(effects.surfaceCoolingHWPerM2K), "W/(m^2 K)", closed(0.0, 1e6),
                       "convective cooling of the free surface (0 = insulated, paper)"));
    f.push_back(number("effects.surface_cooling.ambient_c",
                       ESIM_REF(effects.surfaceCoolingAmbientC), "C", closed(-50.0, 200.0),
                       "ambient temperature for surface cooling"));
    f.push_back(number("effects.structural_clamp_band_m", ESIM_REF(effects.structuralClampBandM),
                       "m", closed(0.0, 10.0),
                       "structural: the surface nodes within this height of the lowest node "
                       "are clamped (the tissue rests on the table)"));
    // solvers
    f.push_back(choice("solvers.electric.strategy", ESIM_REF(solvers.electricStrategy),
                       {"refactor", "dense-inverse", "capacitance", "pcg"},
                       "electric solver: refactor per contact change, the paper's dense inverse, "
                       "cached sparse columns, or warm-started CG"));
    f.push_back(number("solvers.electric.tolerance", ESIM_REF(solvers.electricTolerance), "",
                       {0.0, 1.0, true, true}, "relative residual for pcg"));
    f.push_back(integer("solvers.electric.max_iterations", ESIM_REF(solvers.electricMaxIterations),
                        "", closed(1, 1e7), "iteration cap for pcg"));
    f.push_back(integer("solvers.electric.dense_memory_limit_mb",
                        ESIM_REF(solvers.electricDenseMemoryLimitMb), "MB", closed(1, 1e7),
                        "dense-inverse refuses when n^2 * 8 bytes exceeds this"));
    f.push_back(integer("solvers.electric.threads", ESIM_REF(solvers.electricThreads), "",
                        closed(1, 256), "BLAS / solver threads (fixed for reproducibility)"));
    f.push_back(boolean("solvers.electric.prefetch_path", ESIM_REF(solvers.electricPrefetchPath),
                        "pre-processing: precompute the solver data (capacitance columns) of every "
                        "node the scripted tool path touches, so frames need none"));
    f.push_back(choice("solvers.thermal.integrator", ESIM_REF(solvers.thermalIntegrator),
                       {"explicit", "backward-euler", "crank-nicolson"},
                       "time integrator of the heat equation (explicit: lumped mass, sub-stepped "
                       "below its stability limit; see esim bench thermal)"));
    f.push_back(choice("solvers.thermal.mass", ESIM_REF(solvers.thermalMass),
                       {"lumped", "consistent"}, "heat capacity matrix"));
    f.push_back(boolean("solvers.thermal.allow_substepping",
                        ESIM_REF(solvers.thermalAllowSubstepping),
                        "split a frame into stable substeps when needed"));
    f.push_back(choice("solvers.rebuild.mode", ESIM_REF(solvers.rebuildMode),
                       {"synchronous", "background"},
                       "after rupture: build the new model in the frame that breaks tets, or on "
                       "a thread while frames go on with the old one (swapped in lag_frames "
                       "later, deterministically)"));
    f.push_back(integer("solvers.rebuild.lag_frames", ESIM_REF(solvers.rebuildLagFrames), "frames",
                        closed(0, 1000),
                        "background rebuild: frames between the rupture and the swap (the frame "
                        "loop waits there if the build is not done)"));
    f.push_back(boolean("solvers.rebuild.recompute", ESIM_REF(solvers.rebuildRecompute),
                        "background rebuild: compute the frames since the rupture again on the "
                        "new model at the swap (the paper's way; video frames already drawn "
                        "stay as they were)"));
    // time
    f.push_back(number("time.fps", ESIM_REF(time.fps), "1/s", positive(1000.0),
                       "frames per simulated second (one physics step per frame)"));
    f.push_back(number("time.duration_s", ESIM_REF(time.durationS), "s", positive(86400.0),
                       "simulated duration; frames = round(duration_s * fps)"));
    // camera
    f.push_back(vector("camera.eye_m", ESIM_REF(camera.eyeM), "m", closed(-100.0, 100.0),
                       "camera position"));
    f.push_back(vector("camera.target_m", ESIM_REF(camera.targetM), "m", closed(-100.0, 100.0),
                       "point looked at"));
    f.push_back(vector("camera.up", ESIM_REF(camera.up), "", closed(-1e3, 1e3),
                       "up direction (not along the view direction)", true));
    f.push_back(number("camera.fov_deg", ESIM_REF(camera.fovDeg), "deg", {0.0, 180.0, true, true},
                       "vertical field of view"));
    // look
    f.push_back(choice("look.style", ESIM_REF(look.style), {"temperature", "tissue", "potential"},
                       "temperature colour map with legend, realistic tissue, or the electric "
                       "potential on the surface with legend (needs the electric phase)"));
    f.push_back(choice("look.colormap", ESIM_REF(look.colormap), {"inferno", "viridis"},
                       "colour map of the temperature and potential styles"));
    f.push_back(number("look.t_min_c", ESIM_REF(look.tMinC), "C", closed(-50.0, 1000.0),
                       "temperature at the bottom of the colour map"));
    f.push_back(number("look.t_max_c", ESIM_REF(look.tMaxC), "C", closed(-50.0, 1000.0),
                       "temperature at the top of the colour map (> t_min_c)"));
    f.push_back(number("look.v_min_v", ESIM_REF(look.vMinV), "V", closed(-1e4, 1e4),
                       "potential at the bottom of the colour map (potential style)"));
    f.push_back(number("look.v_max_v", ESIM_REF(look.vMaxV), "V", closed(-1e4, 1e4),
                       "potential at the top of the colour map (potential style; 0 = "
                       "tool.voltage_v)"));
    f.push_back(choice("look.potential_scale", ESIM_REF(look.potentialScale), {"linear", "log"},
                       "colour map scale of the potential style (log needs v_min_v > 0; the "
                       "potential spans decades away from the tool)"));
    f.push_back(integer("look.width", ESIM_REF(look.width), "px", closed(16, 7680),
                        "frame width (even, for yuv420p video)"));
    f.push_back(integer("look.height", ESIM_REF(look.height), "px", closed(16, 4320),
                        "frame height (even, for yuv420p video)"));
    f.push_back(integer(
        "look.msaa", ESIM_REF(look.msaa), "samples", closed(0, 4),
        "multisample anti-aliasing: 0 (off: about half the render time on llvmpipe), 2 or 4 "
        "(llvmpipe: 2 costs as much as 4; see esim bench render)"));
    f.push_back(choice("look.shading", ESIM_REF(look.shading), {"pixel", "vertex"},
                       "lighting per vertex and interpolated (faster; highlights follow the "
                       "mesh, which shows on coarse curved meshes) or per pixel; colours are "
                       "per pixel either way"));
    f.push_back(boolean("look.color_bar", ESIM_REF(look.colorBar), "draw the colour bar legend"));
    f.push_back(boolean("look.show_time", ESIM_REF(look.showTime), "draw the simulated time"));
    // output
    f.push_back(boolean("output.video", ESIM_REF(output.video), "write video.mp4 (H.264)"));
    f.push_back(integer("output.crf", ESIM_REF(output.crf), "", closed(0, 51),
                        "H.264 constant rate factor (lower = better)"));
    f.push_back(choice("output.preset", ESIM_REF(output.preset),
                       {"ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow",
                        "slower", "veryslow"},
                       "x264 speed preset"));
    f.push_back(boolean("output.reproducible", ESIM_REF(output.reproducible),
                        "deterministic single-threaded encoding (same bytes every run)"));
    f.push_back(integer("output.png_every", ESIM_REF(output.pngEvery), "", closed(0, 1e6),
                        "write every Nth frame as frames/frame_NNNNN.png (0 = none)"));
    f.push_back(integer("output.fields_every", ESIM_REF(output.fieldsEvery), "", closed(0, 1e6),
                        "write every Nth frame as fields/frame_NNNNN.vtu (0 = none)"));
    f.push_back(boolean("output.hashes", ESIM_REF(output.hashes),
                        "write hashes.json (exact and perceptual hash per frame)"));
    return f;
  }();
  return fields;
}

#undef ESIM_REF

// keyframe sub-fields (entries of tool.path), used by the reader and the reference
struct KeyField {
  const char* name;
  Kind kind;  // Number or Vector
  const char* unit;
  Range range;
  bool required;
  const char* description;
};
const std::vector<KeyField>& keyframeSchema() {
  static const std::vector<KeyField> k{
      {"t_s", Kind::Number, "s", closed(0.0, 1e6), true,
       "time of the keyframe (strictly increasing)"},
      {"position_m", Kind::Vector, "m", closed(-10.0, 10.0), true, "tool tip position"},
      {"orientation_deg", Kind::Vector, "deg", closed(-720.0, 720.0), false,
       "[rx, ry, rz]: R = Rz Ry Rx about fixed axes; [0, 0, 0] = axis straight up (+z)"},
  };
  return k;
}

const Field* findField(const std::string& path) {
  for (const Field& f : schema())
    if (f.path == path) return &f;
  return nullptr;
}

// true when path is a proper prefix group of some field ("" is the root)
bool isGroup(const std::string& path) {
  if (path.empty()) return true;
  for (const Field& f : schema())
    if (f.path.size() > path.size() && f.path.compare(0, path.size(), path) == 0 &&
        f.path[path.size()] == '.')
      return true;
  return false;
}

// immediate child keys of a group, in schema order
std::vector<std::string> childKeys(const std::string& group) {
  std::vector<std::string> keys;
  const std::string prefix = group.empty() ? "" : group + ".";
  for (const Field& f : schema()) {
    if (f.path.compare(0, prefix.size(), prefix) != 0) continue;
    std::string rest = f.path.substr(prefix.size());
    rest = rest.substr(0, rest.find('.'));
    if (std::find(keys.begin(), keys.end(), rest) == keys.end()) keys.push_back(rest);
  }
  return keys;
}

std::string joinPath(const std::string& group, const std::string& key) {
  return group.empty() ? key : group + "." + key;
}

// ---- formatting ----

// shortest text that reads back to the same double; .inf for infinity
std::string formatNumber(double v) {
  if (std::isinf(v)) return v > 0 ? ".inf" : "-.inf";
  if (std::isnan(v)) return ".nan";
  // shortest round-trip digits; plain decimals for everyday magnitudes (0.0005, 3820000)
  const double mag = std::abs(v);
  const bool fixed = mag == 0.0 || (mag >= 1e-5 && mag < 1e9);
  char buf[400];
  auto res = std::to_chars(buf, buf + sizeof(buf), v,
                           fixed ? std::chars_format::fixed : std::chars_format::scientific);
  return std::string(buf, res.ptr);
}

std::string formatVector(const Vec3& v) {
  std::string out = "[";
  for (int i = 0; i < 3; ++i) {
    if (i > 0) out += ", ";
    out += formatNumber(v[i]);
  }
  return out + "]";
}

std::string quoteString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char b[8];
          std::snprintf(b, sizeof(b), "\\x%02x", static_cast<unsigned char>(c));
          out += b;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

std::string formatKeyframe(const ScenarioKeyframe& k) {
  return "{t_s: " + formatNumber(k.timeS) + ", position_m: " + formatVector(k.positionM) +
         ", orientation_deg: " + formatVector(k.orientationDeg) + "}";
}

// the value of a field as (flow) YAML text
std::string formatValue(const Field& f, const Scenario& constScenario) {
  // the refs take a mutable Scenario; nothing is written through them here
  Scenario& s = const_cast<Scenario&>(constScenario);
  switch (f.kind) {
    case Kind::Number:
      return formatNumber(std::get<NumberRef>(f.ref)(s));
    case Kind::Integer:
      return std::to_string(std::get<IntRef>(f.ref)(s));
    case Kind::Bool:
      return std::get<BoolRef>(f.ref)(s) ? "true" : "false";
    case Kind::Choice:
      return std::get<StringRef>(f.ref)(s);
    case Kind::Text:
      return quoteString(std::get<StringRef>(f.ref)(s));
    case Kind::Vector:
      return formatVector(std::get<VecRef>(f.ref)(s));
    case Kind::IntTriple: {
      const auto& a = std::get<Int3Ref>(f.ref)(s);
      return "[" + std::to_string(a[0]) + ", " + std::to_string(a[1]) + ", " +
             std::to_string(a[2]) + "]";
    }
    case Kind::Phases: {
      std::string out = "[";
      for (Phase p : std::get<PhasesRef>(f.ref)(s))
        out += (out.size() > 1 ? ", " : "") + std::string(phaseName(p));
      return out + "]";
    }
    case Kind::Keyframes: {
      std::string out = "[";
      for (const auto& k : std::get<KeysRef>(f.ref)(s))
        out += (out.size() > 1 ? ", " : "") + formatKeyframe(k);
      return out + "]";
    }
    case Kind::Intervals: {
      std::string out = "[";
      for (const auto& iv : std::get<IntervalsRef>(f.ref)(s))
        out += (out.size() > 1 ? ", " : "") + std::string("[") + formatNumber(iv[0]) + ", " +
               formatNumber(iv[1]) + "]";
      return out + "]";
    }
  }
  return "";
}

// a range bound: the shortest form (1e+08 rather than 100000000)
std::string formatBound(double v) {
  if (std::isinf(v)) return v > 0 ? ".inf" : "-.inf";
  char buf[64];
  auto res = std::to_chars(buf, buf + sizeof(buf), v);
  return std::string(buf, res.ptr);
}

std::string formatRange(const Range& r) {
  return std::string(r.loOpen ? "(" : "[") + formatBound(r.lo) + ", " + formatBound(r.hi) +
         (r.hiOpen ? ")" : "]");
}

// "in metres" etc. for messages
std::string unitPhrase(const std::string& unit) {
  static const std::map<std::string, std::string> words{
      {"m", "metres"},    {"s", "seconds"},         {"V", "volts"},   {"Pa", "pascals"},
      {"deg", "degrees"}, {"C", "degrees Celsius"}, {"px", "pixels"}, {"MB", "megabytes"}};
  if (unit.empty()) return "";
  auto it = words.find(unit);
  return " in " + (it != words.end() ? it->second : unit);
}

std::string kindName(Kind k) {
  switch (k) {
    case Kind::Number:
      return "number";
    case Kind::Integer:
      return "integer";
    case Kind::Bool:
      return "bool";
    case Kind::Choice:
      return "choice";
    case Kind::Text:
      return "string";
    case Kind::Vector:
      return "[x, y, z] numbers";
    case Kind::IntTriple:
      return "[px, py, pz] integers";
    case Kind::Phases:
      return "list of phases";
    case Kind::Keyframes:
      return "list of keyframes";
    case Kind::Intervals:
      return "list of [on, off]";
  }
  return "";
}

std::string allowedText(const Field& f) {
  std::string out;
  switch (f.kind) {
    case Kind::Number:
    case Kind::Integer:
    case Kind::Vector:
    case Kind::IntTriple:
      return formatRange(f.range);
    case Kind::Bool:
      return "true | false";
    case Kind::Choice:
    case Kind::Phases:
      for (const auto& c : f.choices) out += (out.empty() ? "" : " | ") + c;
      return out;
    case Kind::Text:
      return "any text";
    case Kind::Keyframes:
      return ">= 1 keyframe, t_s strictly increasing";
    case Kind::Intervals:
      return "0 <= on < off <= .inf, sorted, disjoint";
  }
  return out;
}

// ---- suggestions ----

size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diag = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

// the closest candidate within a typo's distance ("" if none); a candidate that extends
// the word (missing unit suffix, e.g. voltage -> voltage_v) also counts
std::string closestName(const std::string& word, const std::vector<std::string>& candidates) {
  std::string best;
  size_t bestDist = std::max<size_t>(2, word.size() / 3) + 1;
  for (const auto& c : candidates) {
    size_t d = editDistance(word, c);
    if (word.size() >= 3 && c.compare(0, word.size(), word) == 0) d = std::min<size_t>(d, 1);
    if (d < bestDist) {
      bestDist = d;
      best = c;
    }
  }
  return best;
}

std::string joinList(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& s : items) out += (out.empty() ? "" : ", ") + s;
  return out;
}

// ---- reader ----

class Reader {
 public:
  Reader(std::string source) : source_(std::move(source)) {}

  // remembers an override so messages about its fields point at it
  void noteOverride(const std::string& path, const std::string& text) { overrides_[path] = text; }

  // where a field's value came from: "--set k=v", "file:line:col" or "file"
  std::string where(const std::string& path, const YAML::Mark& mark) const {
    for (const auto& [key, text] : overrides_)
      if (path == key || (path.size() > key.size() && path.compare(0, key.size(), key) == 0 &&
                          (path[key.size()] == '.' || path[key.size()] == '[')))
        return source_ + ": --set " + text;
    if (mark.is_null()) return source_;
    return source_ + ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
  }
  std::string where(const std::string& path) const {
    auto it = marks_.find(path);
    return where(path, it != marks_.end() ? it->second : YAML::Mark::null_mark());
  }

  [[noreturn]] void fail(const std::string& path, const YAML::Mark& mark,
                         const std::string& message) const {
    throw Error(where(path, mark) + ": " + message);
  }
  [[noreturn]] void fail(const std::string& path, const std::string& message) const {
    throw Error(where(path) + ": " + message);
  }

  // reads a mapping (the root or a group) into s
  void readGroup(const YAML::Node& node, const std::string& group, Scenario& s) {
    if (node.IsNull()) return;  // "effects:" with nothing under it keeps the defaults
    if (!node.IsMap())
      fail(group, node.Mark(),
           (group.empty() ? std::string("the scenario") : group) +
               ": expected a mapping with keys " + joinList(childKeys(group)) + ", got " +
               describe(node));
    std::set<std::string> seen;
    for (auto it = node.begin(); it != node.end(); ++it) {
      // copies: the iterator's -> yields a temporary proxy (nodes are shared handles)
      const YAML::Node keyNode = it->first;
      const YAML::Node value = it->second;
      if (!keyNode.IsScalar())
        fail(group, keyNode.Mark(),
             (group.empty() ? std::string("scenario") : group) + ": keys must be plain names");
      const std::string key = keyNode.Scalar();
      const std::string path = joinPath(group, key);
      if (!seen.insert(key).second) fail(path, keyNode.Mark(), path + ": duplicate key");
      const YAML::Mark mark = markOf(value, keyNode);
      marks_[path] = mark;
      if (const Field* f = findField(path)) {
        readField(*f, value, path, mark, s);
      } else if (isGroup(path)) {
        readGroup(value, path, s);
      } else {
        fail(path, keyNode.Mark(), unknownKeyMessage(group, key));
      }
    }
  }

  static std::string unknownKeyMessage(const std::string& group, const std::string& key) {
    const std::string path = joinPath(group, key);
    const std::vector<std::string> siblings = childKeys(group);
    const std::string near = closestName(key, siblings);
    if (!near.empty()) return path + ": unknown key; did you mean '" + near + "'?";
    // the same key in another section?
    for (const Field& f : schema()) {
      const std::string leaf = f.path.substr(f.path.rfind('.') + 1);
      if (leaf == key && f.path != path)
        return path + ": unknown key; did you mean '" + f.path + "'?";
    }
    return path + ": unknown key; expected one of " + joinList(siblings);
  }

  static std::string describe(const YAML::Node& n) {
    if (!n.IsDefined() || n.IsNull()) return "nothing";
    if (n.IsSequence()) return "a list";
    if (n.IsMap()) return "a mapping";
    return "'" + n.Scalar() + "'";
  }

  const std::map<std::string, YAML::Mark>& marks() const { return marks_; }

 private:
  // a null value has no useful mark: point at its key
  static YAML::Mark markOf(const YAML::Node& value, const YAML::Node& key) {
    if (value.IsNull() || value.Mark().is_null()) return key.Mark();
    return value.Mark();
  }

  double readNumber(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                    const std::string& unit, const Range& range) const {
    double v = 0;
    if (!n.IsScalar() || !YAML::convert<double>::decode(n, v) || std::isnan(v))
      fail(path, mark, path + ": expected a number" + unitPhrase(unit) + ", got " + describe(n));
    if (!range.contains(v))
      fail(path, mark, path + " = " + formatNumber(v) + " is outside " + formatRange(range));
    return v;
  }

  int readInteger(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                  const std::string& unit, const Range& range) const {
    double v = 0;
    if (!n.IsScalar() || !YAML::convert<double>::decode(n, v) || !std::isfinite(v) ||
        v != std::floor(v))
      fail(path, mark, path + ": expected an integer" + unitPhrase(unit) + ", got " + describe(n));
    if (!range.contains(v))
      fail(path, mark, path + " = " + formatNumber(v) + " is outside " + formatRange(range));
    return static_cast<int>(v);
  }

  Vec3 readVector(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                  const std::string& unit, const Range& range, bool nonzero) const {
    if (!n.IsSequence() || n.size() != 3)
      fail(path, mark,
           path + ": expected a list of 3 numbers" + unitPhrase(unit) + " [x, y, z], got " +
               (n.IsSequence() ? "a list of " + std::to_string(n.size()) : describe(n)));
    Vec3 v;
    for (int i = 0; i < 3; ++i) {
      const std::string item = path + "[" + std::to_string(i) + "]";
      v[i] = readNumber(n[i], item, n[i].Mark(), unit, range);
    }
    if (nonzero && v.norm() == 0.0) fail(path, mark, path + ": must not be the zero vector");
    return v;
  }

  std::string readScalarText(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                             const std::string& expected) const {
    if (n.IsNull()) return "";
    if (!n.IsScalar()) fail(path, mark, path + ": expected " + expected + ", got " + describe(n));
    return n.Scalar();
  }

  void readField(const Field& f, const YAML::Node& n, const std::string& path,
                 const YAML::Mark& mark, Scenario& s) {
    switch (f.kind) {
      case Kind::Number:
        std::get<NumberRef>(f.ref)(s) = readNumber(n, path, mark, f.unit, f.range);
        return;
      case Kind::Integer:
        std::get<IntRef>(f.ref)(s) = readInteger(n, path, mark, f.unit, f.range);
        return;
      case Kind::Bool: {
        bool b = false;
        if (!n.IsScalar() || !YAML::convert<bool>::decode(n, b))
          fail(path, mark, path + ": expected true or false, got " + describe(n));
        std::get<BoolRef>(f.ref)(s) = b;
        return;
      }
      case Kind::Choice: {
        const std::string v = n.IsScalar() ? n.Scalar() : "";
        if (!n.IsScalar() || std::find(f.choices.begin(), f.choices.end(), v) == f.choices.end()) {
          const std::string near = n.IsScalar() ? closestName(v, f.choices) : "";
          fail(path, mark,
               path + ": unknown value " + describe(n) +
                   (near.empty() ? "" : "; did you mean '" + near + "'?") + " expected one of " +
                   joinList(f.choices));
        }
        std::get<StringRef>(f.ref)(s) = v;
        return;
      }
      case Kind::Text:
        std::get<StringRef>(f.ref)(s) = readScalarText(n, path, mark, "a string");
        return;
      case Kind::Vector:
        std::get<VecRef>(f.ref)(s) = readVector(n, path, mark, f.unit, f.range, f.nonzero);
        return;
      case Kind::IntTriple: {
        if (!n.IsSequence() || n.size() != 3)
          fail(path, mark, path + ": expected a list of 3 integers, got " + describe(n));
        auto& a = std::get<Int3Ref>(f.ref)(s);
        for (int i = 0; i < 3; ++i)
          a[i] =
              readInteger(n[i], path + "[" + std::to_string(i) + "]", n[i].Mark(), f.unit, f.range);
        return;
      }
      case Kind::Phases:
        readPhases(f, n, path, mark, std::get<PhasesRef>(f.ref)(s));
        return;
      case Kind::Keyframes:
        readKeyframes(n, path, mark, std::get<KeysRef>(f.ref)(s));
        return;
      case Kind::Intervals:
        readIntervals(f, n, path, mark, std::get<IntervalsRef>(f.ref)(s));
        return;
    }
  }

  void readPhases(const Field& f, const YAML::Node& n, const std::string& path,
                  const YAML::Mark& mark, std::vector<Phase>& out) const {
    if (n.IsNull()) {
      out.clear();
      return;
    }
    if (!n.IsSequence())
      fail(path, mark,
           path + ": expected a list of phases [" + joinList(f.choices) + "], got " + describe(n));
    std::vector<Phase> phases;
    for (size_t i = 0; i < n.size(); ++i) {
      const std::string item = path + "[" + std::to_string(i) + "]";
      const std::string name = n[i].IsScalar() ? n[i].Scalar() : "";
      auto it = std::find(f.choices.begin(), f.choices.end(), name);
      if (it == f.choices.end()) {
        const std::string near = n[i].IsScalar() ? closestName(name, f.choices) : "";
        fail(item, n[i].Mark(),
             item + ": unknown phase " + describe(n[i]) +
                 (near.empty() ? "" : "; did you mean '" + near + "'?") + " expected one of " +
                 joinList(f.choices));
      }
      const Phase p = static_cast<Phase>(it - f.choices.begin());
      if (std::find(phases.begin(), phases.end(), p) != phases.end())
        fail(item, n[i].Mark(), item + ": phase '" + name + "' is listed twice");
      phases.push_back(p);
    }
    std::sort(phases.begin(), phases.end());
    out = phases;
  }

  void readKeyframes(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                     std::vector<ScenarioKeyframe>& out) const {
    if (!n.IsSequence() || n.size() == 0)
      fail(path, mark,
           path +
               ": expected a list of at least one keyframe {t_s, position_m, "
               "orientation_deg}, got " +
               (n.IsSequence() ? std::string("an empty list") : describe(n)));
    std::vector<std::string> names;
    for (const auto& k : keyframeSchema()) names.push_back(k.name);
    std::vector<ScenarioKeyframe> keys;
    for (size_t i = 0; i < n.size(); ++i) {
      const std::string item = path + "[" + std::to_string(i) + "]";
      const YAML::Node& kn = n[i];
      if (!kn.IsMap())
        fail(item, kn.Mark(),
             item +
                 ": expected a keyframe {t_s, position_m, orientation_deg}, "
                 "got " +
                 describe(kn));
      ScenarioKeyframe key;
      std::set<std::string> seen;
      YAML::Mark timeMark = kn.Mark();
      for (auto it = kn.begin(); it != kn.end(); ++it) {
        const YAML::Node keyNode = it->first, value = it->second;  // copies of the proxy
        const std::string name = keyNode.IsScalar() ? keyNode.Scalar() : "?";
        const std::string sub = item + "." + name;
        if (!seen.insert(name).second) fail(sub, keyNode.Mark(), sub + ": duplicate key");
        const YAML::Mark vm = markOf(value, keyNode);
        if (name == "t_s") {
          key.timeS = readNumber(value, sub, vm, "s", keyframeSchema()[0].range);
          timeMark = vm;
        } else if (name == "position_m") {
          key.positionM = readVector(value, sub, vm, "m", keyframeSchema()[1].range, false);
        } else if (name == "orientation_deg") {
          key.orientationDeg = readVector(value, sub, vm, "deg", keyframeSchema()[2].range, false);
        } else {
          const std::string near = closestName(name, names);
          fail(sub, keyNode.Mark(),
               sub + ": unknown key; " +
                   (near.empty() ? "expected one of " + joinList(names)
                                 : "did you mean '" + near + "'?"));
        }
      }
      for (const auto& k : keyframeSchema())
        if (k.required && !seen.count(k.name))
          fail(item, kn.Mark(), item + ": missing '" + k.name + "' (" + k.description + ")");
      if (i > 0 && !(key.timeS > keys.back().timeS))
        fail(item + ".t_s", timeMark,
             item + ".t_s = " + formatNumber(key.timeS) + " is not after " + path + "[" +
                 std::to_string(i - 1) + "].t_s = " + formatNumber(keys.back().timeS) +
                 "; keyframe times must strictly increase");
      keys.push_back(key);
    }
    out = keys;
  }

  void readIntervals(const Field& f, const YAML::Node& n, const std::string& path,
                     const YAML::Mark& mark, std::vector<std::array<double, 2>>& out) const {
    if (n.IsNull()) {
      out.clear();
      return;
    }
    if (!n.IsSequence())
      fail(path, mark,
           path + ": expected a list of [on, off] intervals in seconds, got " + describe(n));
    std::vector<std::array<double, 2>> intervals;
    for (size_t i = 0; i < n.size(); ++i) {
      const std::string item = path + "[" + std::to_string(i) + "]";
      const YAML::Node& in = n[i];
      if (!in.IsSequence() || in.size() != 2)
        fail(item, in.Mark(), item + ": expected [on, off] in seconds, got " + describe(in));
      const double on =
          readNumber(in[0], item + "[0]", in[0].Mark(), "s", {0.0, kInf, false, true});
      const double off = readNumber(in[1], item + "[1]", in[1].Mark(), "s", f.range);
      if (!(off > on))
        fail(item, in.Mark(),
             item + ": off time " + formatNumber(off) + " s must be after on time " +
                 formatNumber(on) + " s");
      if (!intervals.empty() && on < intervals.back()[1])
        fail(item, in.Mark(),
             item + ": starts at " + formatNumber(on) + " s, before the previous interval ends (" +
                 formatNumber(intervals.back()[1]) + " s); intervals must be sorted and disjoint");
      intervals.push_back({on, off});
    }
    out = intervals;
  }

  std::string source_;
  std::map<std::string, std::string> overrides_;
  std::map<std::string, YAML::Mark> marks_;
};

// ---- overrides ----

// sets root[k1][k2]...[kn] = value, creating mappings on the way
void setPath(YAML::Node node, const std::vector<std::string>& keys, size_t i,
             const YAML::Node& value) {
  if (i + 1 == keys.size()) {
    node[keys[i]] = value;
    return;
  }
  YAML::Node child = node[keys[i]];
  if (!child.IsMap()) {
    node[keys[i]] = YAML::Node(YAML::NodeType::Map);
    child = node[keys[i]];
  }
  setPath(child, keys, i + 1, value);
}

void applyOverride(YAML::Node& root, const std::string& text, const std::string& source,
                   Reader& reader) {
  const std::string where = source + ": --set " + text + ": ";
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw Error(where + "expected key.path=value, e.g. tool.voltage_v=60");
  std::string key = text.substr(0, eq);
  key.erase(0, key.find_first_not_of(" \t"));
  key.erase(key.find_last_not_of(" \t") + 1);
  const std::string valueText = text.substr(eq + 1);
  // each step of the path must be a group, the last a field or a group
  std::vector<std::string> keys;
  std::string group;
  std::stringstream ss(key);
  for (std::string k; std::getline(ss, k, '.');) {
    const std::string path = joinPath(group, k);
    if (k.empty() || (!findField(path) && !isGroup(path)))
      throw Error(where + Reader::unknownKeyMessage(group, k));
    if (findField(path) && path != key) throw Error(where + path + " is a value, not a group");
    keys.push_back(k);
    group = path;
  }
  YAML::Node value;
  try {
    value = YAML::Load(valueText);
  } catch (const YAML::Exception& e) {
    throw Error(where + "malformed value: " + e.msg);
  }
  if (!root.IsMap()) root = YAML::Node(YAML::NodeType::Map);
  setPath(root, keys, 0, value);
  reader.noteOverride(key, text);
}

// ---- checks ----

std::string phaseList(const Scenario& s) {
  std::string out;
  for (Phase p : s.physics) out += (out.empty() ? "" : ", ") + std::string(phaseName(p));
  return "[" + out + "]";
}

// mesh.file.path resolved: the scenario's folder, the nearest ancestor holding assets/
// (the repository root), then the working directory
std::string resolveAsset(const std::string& path, const std::string& sourceName,
                         const Reader& reader) {
  const fs::path p(path);
  std::vector<fs::path> tried;
  if (p.is_absolute()) {
    tried.push_back(p);
  } else {
    const fs::path dir = fs::path(sourceName).parent_path();
    tried.push_back(dir / p);
    std::error_code ec;
    fs::path up = fs::absolute(dir.empty() ? fs::path(".") : dir, ec).lexically_normal();
    while (!ec && !up.empty()) {
      std::error_code statError;  // a missing assets/ is no error
      if (fs::is_directory(up / "assets", statError)) {
        tried.push_back(up / p);
        break;
      }
      if (up == up.parent_path()) break;
      up = up.parent_path();
    }
    tried.push_back(fs::current_path(ec) / p);
  }
  std::vector<std::string> names;
  for (const auto& t : tried) {
    std::error_code ec;
    const fs::path full = fs::absolute(t, ec).lexically_normal();
    if (fs::is_regular_file(full, ec)) return full.string();
    const std::string n = full.string();
    if (std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  }
  reader.fail("mesh.file.path",
              "mesh.file.path: file '" + path + "' not found; tried " + joinList(names));
}

void checkScenario(Scenario& s, const Reader& r) {
  // phase dependencies
  const bool electric = s.has(Phase::Electric), thermal = s.has(Phase::Thermal);
  if (s.has(Phase::Boiling) && !thermal)
    r.fail("physics", "physics " + phaseList(s) + ": 'boiling' needs 'thermal'; add thermal");
  if (s.has(Phase::Structural) && (!thermal || !s.has(Phase::Boiling)))
    r.fail("physics", "physics " + phaseList(s) +
                          ": 'structural' needs 'thermal' and 'boiling' (its load is the "
                          "expansion of heated and vaporized water); add them");
  if (s.has(Phase::Rupture) && !s.has(Phase::Structural))
    r.fail("physics", "physics " + phaseList(s) +
                          ": 'rupture' needs 'structural' (the stress that breaks elements); "
                          "add structural");
  if (thermal && !electric && s.heatSource.kind == "none" && !s.initialHotSpot.enabled)
    r.fail("physics", "physics " + phaseList(s) +
                          ": 'thermal' without 'electric' has no heat; add electric, or set "
                          "heat_source.kind: gaussian or initial_hot_spot.enabled: true");
  if (s.heatSource.kind != "none" && (!thermal || electric))
    r.fail("heat_source.kind", "heat_source.kind = " + s.heatSource.kind +
                                   " is used only when physics has thermal without electric "
                                   "(physics " +
                                   phaseList(s) + "); set heat_source.kind: none");
  if (s.initialHotSpot.enabled && !thermal)
    r.fail("initial_hot_spot.enabled",
           "initial_hot_spot.enabled needs the thermal phase (physics " + phaseList(s) + ")");
  // effects need their phases
  if (s.effects.temperatureDependentConductivity && !(electric && thermal))
    r.fail("effects.temperature_dependent_conductivity",
           "effects.temperature_dependent_conductivity needs electric and thermal (physics " +
               phaseList(s) + ")");
  if (s.effects.thermalDamage && !thermal)
    r.fail("effects.thermal_damage",
           "effects.thermal_damage needs thermal (physics " + phaseList(s) + ")");
  if (s.effects.surfaceCoolingHWPerM2K > 0 && !thermal)
    r.fail("effects.surface_cooling.h_w_per_m2k",
           "effects.surface_cooling.h_w_per_m2k > 0 needs thermal (physics " + phaseList(s) + ")");
  // mesh
  const auto& npa = s.mesh.slab.nodesPerAxis;
  const bool allZero = npa[0] == 0 && npa[1] == 0 && npa[2] == 0;
  if (!allZero && (npa[0] < 2 || npa[1] < 2 || npa[2] < 2))
    r.fail("mesh.slab.nodes_per_axis",
           "mesh.slab.nodes_per_axis: each entry must be >= 2, or all 0 to derive the grid "
           "from mesh.slab.nodes");
  if (s.mesh.slab.grading.enabled && s.mesh.slab.grading.fromM == s.mesh.slab.grading.toM)
    r.fail("mesh.slab.grading.to_m",
           "mesh.slab.grading.to_m equals from_m; the planned cut needs two distinct ends");
  const ScenarioRefine& refine = s.mesh.file.refine;
  if (refine.enabled && refine.fromM == refine.toM)
    r.fail("mesh.file.refine.to_m",
           "mesh.file.refine.to_m equals from_m; the planned cut needs two distinct ends");
  if (refine.enabled && refine.cellSizeM > s.mesh.file.cellSizeM)
    r.fail("mesh.file.refine.cell_size_m",
           "mesh.file.refine.cell_size_m = " + formatNumber(refine.cellSizeM) +
               " m is larger than mesh.file.cell_size_m = " + formatNumber(s.mesh.file.cellSizeM) +
               " m; the refined cells must be at most the global size");
  if (s.mesh.source == "file") {
    if (s.mesh.file.path.empty())
      r.fail("mesh.source", "mesh.source = file needs mesh.file.path (a surface file)");
    s.mesh.file.resolvedPath = resolveAsset(s.mesh.file.path, s.sourceName, r);
  }
  // time
  if (std::lround(s.time.durationS * s.time.fps) < 1)
    r.fail("time.duration_s",
           "time.duration_s * time.fps = " + formatNumber(s.time.durationS * s.time.fps) +
               " gives no frame; at least one frame is needed");
  // camera
  const Vec3 view = s.camera.targetM - s.camera.eyeM;
  if (view.norm() == 0.0)
    r.fail("camera.target_m", "camera.target_m equals camera.eye_m; the camera needs a direction");
  if (view.normalized().cross(s.camera.up.normalized()).norm() < 1e-6)
    r.fail("camera.up", "camera.up is parallel to the view direction (target_m - eye_m)");
  // look
  if (!(s.look.tMaxC > s.look.tMinC))
    r.fail("look.t_max_c", "look.t_max_c = " + formatNumber(s.look.tMaxC) +
                               " must be above look.t_min_c = " + formatNumber(s.look.tMinC));
  if (s.look.style == "potential" && !electric)
    r.fail("look.style", "look.style = potential needs the electric phase (physics " +
                             phaseList(s) + "); add electric, or use temperature or tissue");
  const double vMaxV = s.look.vMaxV != 0.0 ? s.look.vMaxV : s.tool.voltageV;
  if ((s.look.style == "potential" || s.look.vMaxV != 0.0) && !(vMaxV > s.look.vMinV))
    r.fail(s.look.vMaxV != 0.0 ? "look.v_max_v" : "look.v_min_v",
           "look.v_max_v = " + formatNumber(vMaxV) +
               (s.look.vMaxV != 0.0 ? "" : " (0 = tool.voltage_v)") +
               " must be above look.v_min_v = " + formatNumber(s.look.vMinV));
  if (s.look.potentialScale == "log" && !(s.look.vMinV > 0.0))
    r.fail("look.v_min_v", "look.v_min_v = " + formatNumber(s.look.vMinV) +
                               " must be above 0 with look.potential_scale = log");
  if (s.look.width % 2 != 0)
    r.fail("look.width",
           "look.width = " + std::to_string(s.look.width) + " must be even (yuv420p video)");
  if (s.look.height % 2 != 0)
    r.fail("look.height",
           "look.height = " + std::to_string(s.look.height) + " must be even (yuv420p video)");
  if (s.look.msaa == 1 || s.look.msaa == 3)
    r.fail("look.msaa", "look.msaa = " + std::to_string(s.look.msaa) + " must be 0, 2 or 4");
}

}  // namespace

// ---- public API ----

bool Scenario::has(Phase p) const {
  return std::find(physics.begin(), physics.end(), p) != physics.end();
}

const char* phaseName(Phase phase) {
  switch (phase) {
    case Phase::Electric:
      return "electric";
    case Phase::Thermal:
      return "thermal";
    case Phase::Boiling:
      return "boiling";
    case Phase::Structural:
      return "structural";
    case Phase::Rupture:
      return "rupture";
  }
  return "?";
}

Scenario parseScenario(const std::string& yamlText, const std::string& sourceName,
                       const std::vector<std::string>& overrides) {
  // 1. parse
  YAML::Node root;
  try {
    root = YAML::Load(yamlText);
  } catch (const YAML::ParserException& e) {
    throw Error(sourceName + ":" + std::to_string(e.mark.line + 1) + ":" +
                std::to_string(e.mark.column + 1) + ": malformed YAML: " + e.msg);
  } catch (const YAML::Exception& e) {
    throw Error(sourceName + ": malformed YAML: " + e.msg);
  }
  // 2. overrides
  Reader reader(sourceName);
  for (const auto& text : overrides) applyOverride(root, text, sourceName, reader);
  // 3. keys, types, ranges
  Scenario s;
  s.sourceName = sourceName;
  try {
    reader.readGroup(root, "", s);
  } catch (const YAML::Exception& e) {  // defensive: yaml-cpp errors not caught above
    throw Error(sourceName + ": " + e.msg);
  }
  // 4. cross-field rules
  checkScenario(s, reader);
  return s;
}

Scenario loadScenario(const std::string& path, const std::vector<std::string>& overrides) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open the scenario file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return parseScenario(buffer.str(), path, overrides);
}

std::string scenarioToYaml(const Scenario& s) {
  std::string out = "# ESim scenario, fully resolved (every field explicit)\n";
  std::vector<std::string> open;  // current group path components
  for (const Field& f : schema()) {
    std::vector<std::string> parts;
    std::stringstream ss(f.path);
    for (std::string k; std::getline(ss, k, '.');) parts.push_back(k);
    size_t common = 0;
    while (common < open.size() && common + 1 < parts.size() && open[common] == parts[common])
      ++common;
    open.resize(common);
    for (size_t i = common; i + 1 < parts.size(); ++i) {
      out += std::string(2 * i, ' ') + parts[i] + ":\n";
      open.push_back(parts[i]);
    }
    const std::string indent(2 * (parts.size() - 1), ' ');
    if (f.kind == Kind::Keyframes) {
      out += indent + parts.back() + ":\n";
      for (const auto& k : s.tool.path) out += indent + "  - " + formatKeyframe(k) + "\n";
    } else {
      out += indent + parts.back() + ": " + formatValue(f, s) + "\n";
    }
  }
  return out;
}

std::uint64_t scenarioHash(const Scenario& s) {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a 64
  for (unsigned char c : scenarioToYaml(s)) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

std::vector<ScenarioFieldInfo> scenarioFields() {
  const Scenario defaults;
  std::vector<ScenarioFieldInfo> out;
  for (const Field& f : schema()) {
    out.push_back({f.path, kindName(f.kind), formatValue(f, defaults), f.unit, allowedText(f),
                   f.description});
    if (f.kind == Kind::Keyframes) {
      const ScenarioKeyframe k;
      for (const auto& kf : keyframeSchema()) {
        const std::string def = kf.kind == Kind::Number ? formatNumber(k.timeS)
                                : std::string(kf.name) == "position_m"
                                    ? formatVector(k.positionM)
                                    : formatVector(k.orientationDeg);
        out.push_back({f.path + "[]." + kf.name, kindName(kf.kind),
                       kf.required ? "(required)" : def, kf.unit, formatRange(kf.range),
                       kf.description});
      }
    }
  }
  return out;
}

std::string scenarioReferenceMarkdown() {
  std::string md;
  md +=
      "# Scenario reference\n\n"
      "<!-- generated by `esim validate --reference` from the schema in sim/io/scenario.cpp; "
      "do not edit by hand -->\n\n"
      "A scenario (`scenarios/*.yaml`) describes one run. Every field is optional: a missing "
      "field takes the default below (the seed paper's set-up: Table 1 materials, 72 V tool, "
      "40 mm return disc, 100 x 100 x 10 mm slab of 1013 nodes). Units are SI and appear in "
      "the key names (`_m`, `_s`, `_v`, `_c` for degrees Celsius, ...).\n\n"
      "- Unknown keys, wrong types and out-of-range values are errors that name the file, "
      "line and column (`scenarios/x.yaml:12:5: tool.contact_distnce: unknown key; did you "
      "mean 'contact_distance_m'?`).\n"
      "- `esim validate FILE... [--set key.path=value ...]` checks files; `esim run` accepts "
      "the same `--set` overrides. Values are parsed as YAML: `--set tool.voltage_v=60`, "
      "`--set physics=[electric]`, `--set mesh.slab.grading.enabled=true`. An override is "
      "checked like the file (unknown keys are errors).\n"
      "- Ranges: `[a, b]` includes the bounds, `(a, b)` excludes them; for vectors the range "
      "applies to each component.\n"
      "- **Tool orientation**: `orientation_deg: [rx, ry, rz]` rotates the tool about the "
      "fixed world axes x, then y, then z: R = Rz(rz) Ry(ry) Rx(rx). The tool's local +z is "
      "its axis from the tip to the handle, local x the blade width; `[0, 0, 0]` points the "
      "axis straight up (+z). `[30, 0, 0]` tilts the handle toward -y. Between keyframes the "
      "tip moves linearly and the orientation follows a slerp; before the first and after "
      "the last keyframe the pose is held.\n"
      "- **Generator**: `generator_on` lists `[on, off)` intervals in seconds; the default "
      "`[[0, .inf]]` is always on, `[]` never on.\n"
      "- **Phases**: `physics` lists what is simulated; a phase not listed is never built. "
      "Dependencies: `boiling` needs `thermal`; `structural` needs `thermal` and `boiling`; "
      "`rupture` needs `structural`; `thermal` without `electric` needs a heat source "
      "(`heat_source.kind: gaussian`) or `initial_hot_spot.enabled: true`. Effects need "
      "their phases (`temperature_dependent_conductivity`: electric and thermal; "
      "`thermal_damage` and surface cooling: thermal).\n"
      "- **Mesh files**: `mesh.file.path` is looked up relative to the scenario's folder, "
      "then the repository root (the nearest folder above the scenario that holds "
      "`assets/`), then the working directory; the error lists the paths tried.\n"
      "- Frames: `round(time.duration_s * time.fps)`; frame k shows simulated time k / fps.\n"
      "- Each run writes the fully resolved scenario (every field explicit) into its output "
      "folder, so that the run can be repeated exactly.\n";
  std::string section;
  for (const auto& f : scenarioFields()) {
    const std::string top = f.path.substr(0, f.path.find_first_of(".["));
    const std::string head = (top == "name" || top == "description") ? "general" : top;
    if (head != section) {
      section = head;
      md += "\n## " + section +
            "\n\n| key | type | default | unit | allowed | description |\n"
            "|---|---|---|---|---|---|\n";
    }
    auto cell = [](std::string v) {
      std::string out;
      for (char c : v) out += (c == '|') ? std::string("\\|") : std::string(1, c);
      return out;
    };
    md += "| `" + f.path + "` | " + cell(f.type) + " | `" + cell(f.defaultYaml) + "` | " +
          cell(f.unit) + " | " + cell(f.allowed) + " | " + cell(f.description) + " |\n";
  }
  return md;
}

int frameCount(const Scenario& s) {
  return std::max(1, static_cast<int>(std::lround(s.time.durationS * s.time.fps)));
}

SlabSpec makeSlabSpec(const Scenario& s) {
  SlabSpec spec;
  spec.sizeM = s.mesh.slab.sizeM;
  spec.targetNodes = s.mesh.slab.nodes;
  spec.nodesPerAxis = s.mesh.slab.nodesPerAxis;
  const ScenarioGrading& g = s.mesh.slab.grading;
  spec.grading.enabled = g.enabled;
  spec.grading.cutFrom = g.fromM;
  spec.grading.cutTo = g.toM;
  spec.grading.ratio = g.ratio;
  spec.grading.widthM = g.widthM;
  spec.grading.towardTop = g.towardTop;
  return spec;
}

MeshingOptions makeMeshingOptions(const Scenario& s) {
  const ScenarioMeshFile& f = s.mesh.file;
  MeshingOptions o;
  o.cellSizeM = f.cellSizeM;
  o.facetSizeM = f.facetSizeM;
  o.facetDistanceM = f.facetDistanceM;
  o.facetAngleDeg = f.facetAngleDeg;
  o.cellRadiusEdgeRatio = f.radiusEdgeRatio;
  o.refinement.enabled = f.refine.enabled;
  o.refinement.fromM = f.refine.fromM;
  o.refinement.toM = f.refine.toM;
  o.refinement.cellSizeM = f.refine.cellSizeM;
  o.refinement.widthM = f.refine.widthM;
  return o;
}

ToolPath makeToolPath(const Scenario& s) {
  ToolPath path;
  for (const auto& k : s.tool.path)
    path.keys.push_back({k.timeS, k.positionM, eulerXyzDegToQuaternion(k.orientationDeg)});
  for (const auto& iv : s.tool.generatorOnS) path.generatorOnS.emplace_back(iv[0], iv[1]);
  validateToolPath(path);
  return path;
}

std::string scenarioSummary(const Scenario& s) {
  std::ostringstream out;
  out << frameCount(s) << " frames (" << formatNumber(s.time.durationS) << " s at "
      << formatNumber(s.time.fps) << " fps), physics " << phaseList(s) << ", mesh ";
  if (s.mesh.source == "slab") {
    const auto& sz = s.mesh.slab.sizeM;
    out << "slab " << formatNumber(sz.x() * 1e3) << "x" << formatNumber(sz.y() * 1e3) << "x"
        << formatNumber(sz.z() * 1e3) << " mm, ";
    const auto& n = s.mesh.slab.nodesPerAxis;
    if (n[0] > 0)
      out << n[0] << "x" << n[1] << "x" << n[2] << " nodes";
    else
      out << "~" << s.mesh.slab.nodes << " nodes";
    if (s.mesh.slab.grading.enabled) out << " graded x" << formatNumber(s.mesh.slab.grading.ratio);
  } else {
    out << "file " << s.mesh.file.path << " (cell " << formatNumber(s.mesh.file.cellSizeM * 1e3)
        << " mm";
    if (s.mesh.file.refine.enabled)
      out << ", " << formatNumber(s.mesh.file.refine.cellSizeM * 1e3) << " mm near the cut";
    out << ")";
  }
  out << ", tool " << s.tool.shape << " " << formatNumber(s.tool.voltageV) << " V, "
      << s.tool.path.size() << " keyframe" << (s.tool.path.size() == 1 ? "" : "s") << ", look "
      << s.look.style;
  return out.str();
}

}  // namespace esim
