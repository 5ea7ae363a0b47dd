// scenario_schema.cpp - the scenario schema: one table, a Field per YAML key.
//
// Each row gives the key path, type, SI unit, allowed range or choices, a one-line
// description (rendered into docs/scenario-reference.md) and a reference to the Scenario
// member it fills; defaults are Scenario's member initializers (scenario.h). Adding a
// key to scenarios means adding a member to Scenario and a row here. The keyframe
// sub-table (entries of tool.path) and the lookups by key path follow the table.
#include "sim/io/scenario_schema.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "sim/electric_solver.h"

namespace esim::scenario_detail {

namespace {

Range closed(double lo, double hi) { return {lo, hi, false, false}; }
Range positive(double hi) { return {0.0, hi, true, false}; }          // (0, hi]
Range openHi(double lo, double hi) { return {lo, hi, false, true}; }  // [lo, hi)

// a captureless lambda giving the member as a function pointer
#define ESIM_REF(member) +[](Scenario& s) -> decltype(auto) { return (s.member); }
// an enum member, read and written as the index of its name in the field's choices
#define ESIM_ENUM_REF(member)                                                      \
  EnumRef {                                                                        \
    +[](const Scenario& s) { return static_cast<int>(s.member); },                 \
        +[](Scenario& s, int v) { s.member = static_cast<decltype(s.member)>(v); } \
  }

Field number(std::string path, NumberRef r, std::string unit, Range range, std::string desc) {
  return {std::move(path), Kind::Number, std::move(unit), range, {}, std::move(desc), r};
}
Field integer(std::string path, IntRef r, std::string unit, Range range, std::string desc) {
  return {std::move(path), Kind::Integer, std::move(unit), range, {}, std::move(desc), r};
}
Field boolean(std::string path, BoolRef r, std::string desc) {
  return {std::move(path), Kind::Bool, "", {}, {}, std::move(desc), r};
}
Field choice(std::string path, EnumRef r, std::vector<std::string> choices, std::string desc) {
  return {std::move(path), Kind::Choice, "", {}, std::move(choices), std::move(desc), r};
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

}  // namespace

// the schema: the single source of truth for keys, types, units, ranges and descriptions.
// Defaults are the member initializers of Scenario (scenario.h). Groups are contiguous.
const std::vector<Field>& schema() {
  static const std::vector<Field> fields = [] {
    std::vector<Field> f;
    const Range anyPos = closed(-10.0, 10.0);
    f.push_back(text("name", ESIM_REF(name), "short name of the run, used in titles and reports"));
    f.push_back(text("description", ESIM_REF(description), "free text: what the scene shows"));
    // mesh
    f.push_back(choice("mesh.source", ESIM_ENUM_REF(mesh.source), {"slab", "file"},
                       "slab: the box generator; file: a closed surface meshed with CGAL"));
    f.push_back(vector("mesh.slab.size_m", ESIM_REF(mesh.slab.sizeM), "m", positive(10.0),
                       "slab size Lx, Ly, Lz; x, y centred on 0, z from 0 (bottom) to Lz (top)"));
    f.push_back(integer("mesh.slab.nodes", ESIM_REF(mesh.slab.nodes), "", closed(8, 1e7),
                        "target node count (paper: 506, 643, 1013); ignored with nodes_per_axis; "
                        "the grid holds at most 2e7 tets (6 a cell)"));
    f.push_back({"mesh.slab.nodes_per_axis",
                 Kind::IntTriple,
                 "",
                 closed(0, 1000),
                 {},
                 "explicit grid nodes px, py, pz (each >= 2; at most 2e7 tets, 6 a cell); "
                 "[0, 0, 0] = derive from nodes",
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
    f.push_back(number("material.critical_stress_radius_m",
                       ESIM_REF(material.criticalStressRadiusM), "m", closed(0.0, 0.05),
                       "0: an element breaks when its own von Mises stress passes "
                       "critical_stress_pa (the paper); > 0: when the stress averaged over the "
                       "elements within this radius does (nonlocal: the cut's shape stops "
                       "following the mesh once elements are smaller; sim/rupture_nonlocal.h)"));
    f.push_back(number("material.debris_volume_m3", ESIM_REF(material.debrisVolumeM3), "m^3",
                       closed(0.0, 1e-3),
                       "pieces of tissue a removal cuts loose (sharing no face with the rest "
                       "and held by no support) up to this volume are removed with it, as "
                       "fragments the vapour carries off; 0: they stay, stress-free and out of "
                       "the stiffness (the paper; sim/rupture_debris.h)"));
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
    f.push_back(choice("tool.shape", ESIM_ENUM_REF(tool.shape), {"blade", "sphere"},
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
                       closed(0.0, 0.1), "nodes this close to the tool are in contact"));
    f.push_back(choice("tool.contact", ESIM_ENUM_REF(tool.contact), {"surface", "volume"},
                       "the nodes the tool may touch: the tissue's surface (the paper: a tool "
                       "at the surface) or its whole volume (a tool pushed into the tissue, a "
                       "needle, a buried ball)"));
    f.push_back({"tool.path",
                 Kind::Keyframes,
                 "",
                 {},
                 {},
                 "keyframes {t_s, position_m, orientation_deg}: tip position linear, orientation "
                 "slerp, held before the first and after the last",
                 ESIM_REF(tool.path)});
    f.push_back(text("tool.path_file", ESIM_REF(tool.pathFile),
                     "CSV of keyframes instead of tool.path, one a line: t_s, x_m, y_m, z_m and "
                     "optionally rx_deg, ry_deg, rz_deg (a first line of these names, blank "
                     "lines and lines starting with # are skipped); found like mesh.file.path"));
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
    f.push_back(choice("heat_source.kind", ESIM_ENUM_REF(heatSource.kind), {"none", "gaussian"},
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
    // sub-grid contact
    f.push_back(choice("subgrid_contact.mode", ESIM_ENUM_REF(subgridContact.mode),
                       {"off", "auto", "on"},
                       "sub-grid model of a tool contact smaller than the mesh resolves "
                       "(sim/subgrid_contact.h): its spreading resistance in series with the "
                       "mesh, a contact zone that heats and boils, its vapour trapped in the "
                       "tet at the tool (whose pocket's wall stress can break it); auto = only "
                       "in frames where the contact nodes' patch is at least twice the true "
                       "contact's radius (needs electric and thermal)"));
    f.push_back(number("subgrid_contact.area_factor", ESIM_REF(subgridContact.areaFactor), "",
                       positive(10.0),
                       "kappa: the share of the electrode's wetted area that carries the "
                       "current (the model's one calibrated parameter; README, 'A coarse mesh "
                       "that cuts')"));
    // solvers
    f.push_back(
        choice("solvers.electric.strategy", ESIM_ENUM_REF(solvers.electricStrategy),
               {"refactor", "dense-inverse", "capacitance", "pcg", "local", "downdate", "auto"},
               "electric solver: refactor per contact change, the paper's dense inverse, "
               "cached sparse columns, warm-started CG, local (not exact: the nodes "
               "near the tool solved, the far field held from a pcg solve refreshed on "
               "a thread; README 'The potential solved around the tool, built'), "
               "downdate (one LDL' factor kept exact through a cut by low-rank "
               "downdates, each contact's path up its elimination tree solved on first "
               "touch), or auto: the dense inverse up to " +
                   std::to_string(std::lround(kAutoDenseMaxFreeNodes)) +
                   " nodes off the return electrode; above, for a cut in rebuild mode "
                   "update, downdate up to " +
                   std::to_string(std::lround(kAutoDowndateMaxFreeNodes)) +
                   " and pcg beyond, capacitance otherwise (the faster, measured: README "
                   "'The cut')"));
    f.push_back(number("solvers.electric.local_margin_m", ESIM_REF(solvers.electricLocalMarginM),
                       "m", positive(10.0),
                       "local: the nodes within this distance of a contact node are solved each "
                       "frame"));
    f.push_back(integer("solvers.electric.local_refresh_frames",
                        ESIM_REF(solvers.electricLocalRefreshFrames), "", closed(1, 1e6),
                        "local: a full solve of the far field starts on a thread every this "
                        "many frames with contact and is used from as many frames later"));
    f.push_back(number("solvers.electric.tolerance", ESIM_REF(solvers.electricTolerance), "",
                       {0.0, 1.0, true, true}, "relative residual for pcg"));
    f.push_back(integer("solvers.electric.max_iterations", ESIM_REF(solvers.electricMaxIterations),
                        "", closed(1, 1e7), "iteration cap for pcg"));
    f.push_back(choice("solvers.electric.preconditioner",
                       ESIM_ENUM_REF(solvers.electricPreconditioner), {"jacobi", "ic", "two-level"},
                       "pcg's preconditioner: Jacobi, incomplete Cholesky, or two-level "
                       "(l1-Jacobi and a coarse level on aggregates of nodes: iterations that "
                       "barely grow with the mesh; README, 'The potential's two-level "
                       "preconditioner')"));
    f.push_back(integer("solvers.electric.dense_memory_limit_mb",
                        ESIM_REF(solvers.electricDenseMemoryLimitMb), "MB", closed(1, 1e7),
                        "dense-inverse refuses when n^2 * 8 bytes exceeds this"));
    f.push_back(integer("solvers.electric.cache_memory_limit_mb",
                        ESIM_REF(solvers.electricCacheMemoryLimitMb), "MB", closed(1, 1e7),
                        "capacitance keeps at most this of solved columns, the least recently "
                        "used evicted (esim run halves it when memory runs short); the results "
                        "do not depend on it (after a cut: to round-off), only the time"));
    f.push_back(integer("solvers.electric.threads", ESIM_REF(solvers.electricThreads), "",
                        closed(1, 256), "BLAS / solver threads (fixed for reproducibility)"));
    f.push_back(boolean("solvers.electric.prefetch_path", ESIM_REF(solvers.electricPrefetchPath),
                        "pre-processing: precompute the solver data (capacitance columns) of every "
                        "node the scripted tool path touches, so frames need none"));
    f.push_back(choice("solvers.thermal.integrator", ESIM_ENUM_REF(solvers.thermalIntegrator),
                       {"explicit", "backward-euler", "crank-nicolson", "tr-bdf2"},
                       "time integrator of the heat equation (explicit: lumped mass, sub-stepped "
                       "below its stability limit; tr-bdf2: second order, L-stable, two solves a "
                       "step; see esim bench thermal)"));
    f.push_back(choice("solvers.thermal.mass", ESIM_ENUM_REF(solvers.thermalMass),
                       {"lumped", "consistent"}, "heat capacity matrix"));
    f.push_back(boolean("solvers.thermal.allow_substepping",
                        ESIM_REF(solvers.thermalAllowSubstepping),
                        "split a frame into stable substeps when needed"));
    f.push_back(integer("solvers.thermal.max_substeps", ESIM_REF(solvers.thermalMaxSubsteps), "",
                        closed(1, 1e6),
                        "explicit: a frame needing more sub-steps is refused before the run "
                        "(the work of a frame is bounded; use an implicit integrator)"));
    f.push_back(choice("solvers.structural.method", ESIM_ENUM_REF(solvers.structuralMethod),
                       {"full", "local", "coarse"},
                       "structural: each frame's displacement from the whole body's factor; or "
                       "(local) as a correction of the last full solve on a region around the "
                       "tets whose load changed (the far field held; a full solve refreshes it "
                       "every local_refresh_every solves); or (coarse) a Galerkin solve on a grid "
                       "of coarse_spacing_m cells, then the same correction on a region around "
                       "the load's change since the last frame (no full solve; see README for "
                       "the stress error each costs)"));
    f.push_back(choice("solvers.structural.volumetric", ESIM_ENUM_REF(solvers.structuralVolumetric),
                       {"element", "nodal"},
                       "structural: the volumetric strain per tet (the paper's; linear tets lock "
                       "as material.poisson_ratio nears 0.5: von Mises 4 % too high at 0.48, "
                       "9 % at 0.49, 60 % at 0.499 in sim/structural.h's test) or averaged at "
                       "the nodes (no locking; a factor ~3x larger, ~3x the structural stage's "
                       "time on slab_cut; full method only; README 'Near-incompressible "
                       "tissue')"));
    f.push_back(number("solvers.structural.local_margin_m",
                       ESIM_REF(solvers.structuralLocalMarginM), "m", positive(10.0),
                       "local: the region is every node within this of the box around the "
                       "changed load"));
    f.push_back(number("solvers.structural.local_slack_m", ESIM_REF(solvers.structuralLocalSlackM),
                       "m", closed(0, 10.0),
                       "local: the box is grown by this when a region is built, which is kept "
                       "while the changed load stays inside (a region built every this much of "
                       "travel)"));
    f.push_back(number("solvers.structural.local_max_region_fraction",
                       ESIM_REF(solvers.structuralLocalMaxRegionFraction), "", positive(1.0),
                       "local: a region holding more than this fraction of the unknowns is a "
                       "full solve instead"));
    f.push_back(integer("solvers.structural.local_refresh_every",
                        ESIM_REF(solvers.structuralLocalRefreshEvery), "solves", closed(0, 1e6),
                        "local: a full solve at least every this many solves (0: only the "
                        "first)"));
    f.push_back(boolean("solvers.structural.local_refresh_on_thread",
                        ESIM_REF(solvers.structuralLocalRefreshOnThread),
                        "local: run that full solve on a thread of its own, adopted "
                        "local_refresh_every solves later (deterministic), instead of in the "
                        "frame"));
    f.push_back(number("solvers.structural.coarse_spacing_m",
                       ESIM_REF(solvers.structuralCoarseSpacingM), "m", closed(0, 10.0),
                       "coarse: the grid over the mesh's box has cells of at most this size along "
                       "each axis (0: automatic, a grid of at most 300 nodes; a grid of more than "
                       "300 000 nodes is refused)"));
    f.push_back(number("solvers.structural.coarse_load_tolerance",
                       ESIM_REF(solvers.structuralCoarseLoadTolerance), "", closed(0, 0.999),
                       "coarse: the region is built around the tets whose load (e_v) changed since "
                       "the last frame by more than this times the largest change (0.05: the "
                       "tets that start to boil, not those warming)"));
    f.push_back(boolean("solvers.structural.coarse_correction",
                        ESIM_REF(solvers.structuralCoarseCorrection),
                        "coarse: correct the coarse solve on the region (local_margin_m, "
                        "local_slack_m, local_max_region_fraction); false: the coarse solve "
                        "alone, to measure what the region buys"));
    f.push_back(boolean("solvers.structural.vectorized_update",
                        ESIM_REF(solvers.structuralVectorizedUpdate),
                        "update mode: a removal's update of the structural factor by ESim's "
                        "AVX-512 kernel where the CPU has it (else, or false: CHOLMOD's "
                        "cholmod_updown, scalar code); the same result to round-off, 2-4x "
                        "faster (README, \"The cut with the model updated in place\")"));
    f.push_back(integer("solvers.structural.solve_threads",
                        ESIM_REF(solvers.structuralSolveThreads), "threads", closed(0, 2),
                        "the structural solve's two triangular solves, once its factor is "
                        "updated (simplicial LDL'), split over this many threads by the "
                        "elimination tree, and a removal's update pipelined over them (the same "
                        "bits with 1 or 2); 0: the solves by CHOLMOD's own, the rest on one "
                        "thread, for comparison (README, \"The structural solve and update on "
                        "two threads\")"));
    f.push_back(choice("solvers.rebuild.mode", ESIM_ENUM_REF(solvers.rebuildMode),
                       {"synchronous", "background", "update"},
                       "after rupture: build the new model in the frame that breaks tets, or on "
                       "a thread while frames go on with the old one (swapped in lag_frames "
                       "later, deterministically), or edit the model in place in the frame "
                       "that breaks tets (low-rank updates of the factorizations, local edits "
                       "of the operators and the surface)"));
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
    f.push_back(number("camera.fov_deg", ESIM_REF(camera.fovDeg), "deg", {1.0, 170.0, true, true},
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
    f.push_back(number("look.displacement_scale", ESIM_REF(look.displacementScale), "",
                       closed(0.0, 1e4),
                       "structural: the surface is drawn displaced by this times the computed "
                       "displacement (1 = as computed, 0 = undeformed, more to show it)"));
    f.push_back(integer("look.texture_seed", ESIM_REF(look.textureSeed), "", closed(0, 1e9),
                        "tissue style: the pattern of the tissue's mottling (0 = the default "
                        "one; another value gives another, the same every run)"));
    f.push_back(vector("look.tissue_tint", ESIM_REF(look.tissueTint), "", closed(0.0, 2.0),
                       "tissue style: the tissue's colours (every state: fresh, cut wall, "
                       "coagulated, dried) times this red, green, blue factor (1 = as is)"));
    f.push_back(vector("look.light_direction", ESIM_REF(look.lightDirection), "", closed(-1e3, 1e3),
                       "where the key light comes from, in the camera's frame (right, up, "
                       "towards the viewer; any length); it casts the electrode's shadow. The "
                       "fill light stays on the other side",
                       true));
    f.push_back(number("look.light_intensity", ESIM_REF(look.lightIntensity), "", closed(0.0, 4.0),
                       "strength of the key and fill lights and their highlights (1 = as is; "
                       "the ambient light stays)"));
    // (at most render/renderer.h's kMaxCutWallPasses: RunConfig's test checks)
    f.push_back(integer("look.cut_wall_smoothing", ESIM_REF(look.cutWallSmoothing), "passes",
                        closed(0, 20),
                        "the cut walls' shading: passes that average their normals over "
                        "neighbouring vertices, so the stair steps removed tets leave are lit "
                        "as one wall and its rim stays a crease (0: each vertex's own faces; "
                        "the steps then show as lit and dark teeth along a groove); the "
                        "geometry drawn is the same"));
    f.push_back(integer("look.cut_wall_damage_smoothing", ESIM_REF(look.cutWallDamageSmoothing),
                        "passes", closed(0, 20),
                        "the cut walls' colour: passes that average the coagulation and "
                        "desiccation drawn at their vertices over neighbouring vertices, so "
                        "the damage of the tets under a groove's floor is drawn as a band, "
                        "its peaks paler (0: each vertex's own, the mean of the tets under "
                        "its faces: whitened teeth along the floor); display only, but the "
                        "labels (esim run --labels) follow the colours drawn: fewer pixels "
                        "reach the coagulated class (liver_incision, 90 frames: 2302 against "
                        "7893 with 3 passes)"));
    // output
    f.push_back(boolean("output.video", ESIM_REF(output.video), "write video.mp4 (H.264)"));
    f.push_back(integer("output.crf", ESIM_REF(output.crf), "", closed(0, 51),
                        "H.264 constant rate factor (lower = better)"));
    f.push_back(choice("output.preset", ESIM_REF(output.preset),
                       {"ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow",
                        "slower", "veryslow"},
                       "x264 speed preset (veryfast: on slab_cut less than half medium's "
                       "encoding time for a PSNR 0.06 dB lower and a smaller file; README, "
                       "\"Rendering\")"));
    f.push_back(choice("output.encode", ESIM_REF(output.encode), {"during", "after"},
                       "when the video is encoded: during the run, on a thread beside the "
                       "frame loop (memory bounded; a killed run leaves the frames encoded so "
                       "far in video.mp4.partial, which plays), or after its last frame (the "
                       "frames kept raw in video.mp4.frames.partial, look.width x look.height "
                       "x 3 bytes each, checked against the disk's free space at the start: "
                       "the frame loop has the encoder's CPU, the same video bytes, the "
                       "encoding's time added at the end; a killed run leaves no video; "
                       "README, \"The video encoded after the frame loop\")"));
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
#undef ESIM_ENUM_REF

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

std::string choiceText(const Field& f, const Scenario& s) {
  if (const EnumRef* e = std::get_if<EnumRef>(&f.ref)) return f.choices.at(e->get(s));
  return std::get<StringRef>(f.ref)(const_cast<Scenario&>(s));
}

void setChoice(const Field& f, Scenario& s, const std::string& name) {
  if (const EnumRef* e = std::get_if<EnumRef>(&f.ref)) {
    const auto it = std::find(f.choices.begin(), f.choices.end(), name);
    e->set(s, static_cast<int>(it - f.choices.begin()));
    return;
  }
  std::get<StringRef>(f.ref)(s) = name;
}

}  // namespace esim::scenario_detail
