// subgrid_contact.h - a sub-grid model of the electrode's contact for meshes coarser than it.
//
// Why: at the paper's resolution (1013 nodes, 5-6 mm between nodes) the contact rule holds
// whole element patches at the tool voltage. The real contact of the blade (an edge 1 mm
// thick, 3 mm wide, pressed a fraction of a millimetre in) is ~8 mm^2; the patch the mesh
// holds at 72 V is ~130 mm^2. The mesh then (a) misses most of the spreading resistance of
// the true contact: it draws ~20 W where a resolved mesh draws ~4 W, and (b) spreads that
// power over elements of ~30 mm^3, which stay a few kelvin above body temperature, whereas
// the resolved field puts it into a skin a fraction of a millimetre thick around the edge,
// which boils within 0.2-0.3 s (README, "A coarse mesh that cuts"). Nothing boils, nothing
// breaks.
//
// The model (subgrid_contact.mode off | auto | on):
//
// 1. The true contact. The electrode surface is sampled once (electrodeSurfaceSamples, ~0.05
//    mm apart along the blade). Each frame the intact tissue is taken locally flat: the plane
//    of the initial boundary face nearest to the tool tip (initial: the sub-grid groove the
//    blade cuts is assumed to follow the blade, so the coarse holes left by removed elements
//    do not change the contact). The wetted area A_w is the sampled electrode surface below
//    that plane (wettedContact); the current enters through an effective area kappa A_w.
//    kappa (subgrid_contact.area_factor) is the model's one calibrated parameter (below): the
//    current crowds onto the electrode's deepest part and ends, which a uniform current
//    density over A_w would miss.
// 2. Its spreading resistance. Near an electrode of area A the field is taken as that of the
//    hemisphere of the same area, radius a = sqrt(kappa A_w / (2 pi)) (REFERENCE.md case 3;
//    a disc of the same area is within 10 %): the resistance between the radii r1 < r2 is
//    R(r1, r2) = (1/r1 - 1/r2) / (2 pi sigma), the Joule power of that shell I^2 R(r1, r2)
//    (per unit radius it falls off as 1/r^2). The mesh already represents the spreading
//    beyond its contact patch, the contact nodes' share of the boundary (the dual area A_p,
//    a_p = sqrt(A_p / (2 pi))). What it misses is the series resistance
//        R_sg = R(a, a_p) = (1/a - 1/a_p) / (2 pi sigma)      (a_p > a)
//    between the true contact and the patch (sigma: the mean conductivity of the tets at the
//    contact). The contact nodes are one equipotential, so the problem is linear in their
//    potential: the mesh's solution u_1 (contact at V) draws I_1 through R_m = V / I_1; with
//    R_sg in series the patch is at s V, s = R_m / (R_m + R_sg): the potential, currents and
//    Joule power density are s u_1, s I_1 and s^2 q_1, and the sub-grid shell a < r < a_p
//    receives I^2 R_sg, I = s I_1. The power delivered is V I = s^2 P_1 + I^2 R_sg exactly.
//    Where the mesh resolves the contact (a_p -> a), R_sg -> 0 and the model vanishes.
// 3. The contact zone. The sub-grid shell a < r < r_z, r_z = min(a_p, 2 a) (half of the
//    spreading power of the true contact lies within 2 a), is a 1-D radial model: kShells
//    hemispherical shells (radii geometric from a to r_z), each with its own enthalpy
//    (heat capacity c rho V_k), water (w rho V_k) and Joule power P_k = I^2 R(r_k, r_k+1):
//        c rho V_k dT_k/dt = P_k + G_k-1 (T_k-1 - T_k) - G_k (T_k - T_k+1) - renewal,
//    G_k = 2 pi lambda / (1/rho_k - 1/rho_k+1) between the shells' mid radii rho_k (steady
//    conduction between hemispheres; the electrode side, r = a, insulated as in the paper's
//    Table 2), the outermost shell exchanging 2 pi lambda rho_N (T_N - T_i) with the contact
//    nodes i (a hemisphere in a half-space at their temperature). The zone moves with the
//    tool: at speed v tissue passes through it in the residence time tau = L / v, L the
//    wetted contact's length along the motion (each shell renewed at the rate 1/tau with
//    tissue at the contact nodes' state, solved exactly over a sub-step; the tissue it
//    releases carries its heat to them). The power of the shell r_z < r < a_p goes to the
//    contact nodes directly. Shared among the contact nodes by the current each carries
//    (the reactions (K u)_i), every exchange with the mesh is a nodal heat source
//    (ThermalPhase::step), in the frame it is computed (explicit coupling; the zone is
//    sub-stepped at its own stability limit).
// 4. Boiling and rupture. A shell that reaches the boiling temperature vaporises its water
//    (latent heat w rho L per unit volume) and holds at 100 C until it is dry, then heats
//    further (the dry tissue's heat capacity taken equal to the wet). Its vapour is trapped
//    where it forms, in the alive tet holding the electrode's deepest point: the structural
//    phase reads it as vaporised water of that tet (its fraction of the tet's water added to
//    the tet's vapour fraction: paper eq. 3). Spread over a 30 mm^3 element that expansion
//    stays below the critical stress; in the tissue it is a pocket of boiling tissue whose
//    expansion e_v (the structural phase's water expansion at the shell's vaporised fraction,
//    capped) loads the tissue around it like Eshelby's inclusion, with the wall stress
//    E e_v / (3 (1 - nu)) (REFERENCE.md case 8; pocketVonMisesPa). The rupture stage removes
//    a tet whose pocket's wall stress exceeds the paper's critical stress, as it removes a
//    tet whose own von Mises stress does: with Table 1's E, nu and critical stress, once
//    ~7e-4 of the boiling shell's water has vaporised. The groove is then one element wide
//    and deep: the resolution of the mesh. Where the tet at the tool has been removed
//    already the vapour vents (the tissue has parted): its latent heat leaves, like the
//    heat of removed tissue.
// 5. Energy. The zone's sensible heat sum_k V_k e_k and the latent heat of the trapped
//    vapour of alive tets are stored energy; vented vapour and the vapour of removed tets
//    leave with the tissue. The zone takes the tissue it heats from the contact nodes at
//    their own enthalpy and returns it with its own (when it forms, moves, changes size or
//    goes): delivered = mesh stored + zone stored - initial + convected + removed, exact to
//    round-off (tests/sim/subgrid_contact_test.cpp; tests/hard_cases' FrameChecker). The
//    zone duplicates the heat capacity of the tissue it covers (~4 mm^3 against ~100 mm^3 per
//    node at the paper's resolution): its tissue is both in the zone and in the mesh.
// 6. When: `on` in every frame whose tool is immersed in the tissue with a_p > a; `auto` only
//    where the patch is at least kAutoPatchRatio times the true contact (a_p >= 2 a: the
//    mesh misses at least half of the contact's spreading resistance): on at the paper's
//    5-6 mm cells, off at the 0.2-0.4 mm reference below (checked: no frame); `off` (the
//    default): the mesh alone, bitwise as before. A zone left by a frame without it returns
//    its heat to the mesh.
//
// Calibration of kappa (once, README "A coarse mesh that cuts"): against a resolved run of
// the same cut (the paper's slab graded to 0.37 x 0.18 x 0.21 mm along the path, 50 400
// nodes; 72 V, 0.3 s at rest then 10 mm/s), which starts cutting while the blade rests (first
// removal at 0.17 s; 0.20 s and 0.27 s at 0.13 mm and 0.25 mm on a smaller slab) and cuts
// along the whole path. kappa = 0.35 starts the coarse cut at rest too (0.27 s) and cuts
// all along; with kappa >= 0.40 the zone peaks just under 100 C at rest and the cut starts
// only once the blade moves; the energy-matched kappa ~ 0.6 never boils (86 C). The price is
// the energy: 26 % less than resolved (uniform current density over the effective area
// cannot carry both the resistance and the hot spot of the real blade). Not calibrated but
// reproduced: at 20.6 mm/s (paper_slab's speed) the resolved run (0.25 mm, smaller slab) and
// the coarse one both cut only where the blade rests, nothing along the path.
//
// Units SI; temperatures in C. The functions are pure; SubgridZone is plain data held in the
// simulation's state (a checkpoint copies it).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "sim/electrode.h"
#include "sim/mesh_tet.h"

namespace esim {

enum class SubgridMode { Off, Auto, On };

// "off", "auto", "on" (the scenario's subgrid_contact.mode)
const char* subgridModeName(SubgridMode mode);

struct SubgridContactOptions {
  SubgridMode mode = SubgridMode::Off;
  // kappa: effective / wetted contact area (calibrated, see the header comment)
  double areaFactor = 0.35;
};

constexpr int kSubgridShells = 8;             // radial shells of the contact zone
constexpr double kZoneRadiusFactor = 2.0;     // r_z = min(a_p, 2 a)
constexpr double kAutoPatchRatio = 2.0;       // auto: on where a_p >= 2 a
constexpr double kMaxAdvectedFraction = 0.2;  // a sub-step renews at most this of a shell

// ---- geometry of the true contact ----

struct SurfaceSample {
  Vec3 localM;        // point on the electrode surface, tool coordinates [m]
  double areaM2 = 0;  // surface area it stands for [m^2]
};

// The electrode's surface as points with areas (sum = its area): a sphere by a Fibonacci
// lattice, a blade (the points within radiusM of its rectangle) by its two faces, the four
// half-cylinders along its edges and the four quarter-spheres at its corners, ~0.05 mm apart
// along the axis (midpoint rule).
std::vector<SurfaceSample> electrodeSurfaceSamples(const ElectrodeShape& shape);

struct WettedContact {
  double areaM2 = 0;        // electrode surface below the tissue plane [m^2]
  double lengthAlongM = 0;  // extent of the wetted surface along the motion [m]
  double depthM = 0;        // depth of the deepest electrode point below the plane [m]
  Vec3 deepestM{0, 0, 0};   // that point [m]
};

// The part of the electrode (samples at pose) below the plane through planePointM with the
// tissue's outward normal planeNormal: area, extent along `motion` (any length; 0 = none)
// and the deepest point.
WettedContact wettedContact(const std::vector<SurfaceSample>& samples, const ToolPose& pose,
                            const Vec3& planePointM, const Vec3& planeNormal, const Vec3& motion);

// R(r1, r2) = (1/r1 - 1/r2) / (2 pi sigma): the hemispherical shell r1 < r < r2 [Ohm]
double shellResistanceOhm(double sigmaS_m, double r1M, double r2M);

// ---- the contact zone ----

struct SubgridZoneParams {
  double heatCapacityJ_m3K = 3.82e6;  // c rho
  double conductivityW_mK = 0.502;    // lambda
  double initialTemperatureC = 37;    // T0 (enthalpies are relative to it)
  bool boiling = true;
  double boilingTemperatureC = 100;
  double latentJ_m3 = 0;  // w rho L: latent heat of the tissue water per volume [J/m^3]
  double waterKg_m3 = 0;  // w rho: water per volume [kg/m^3]
};

// the zone's state: plain data (in SimState)
struct SubgridZone {
  bool present = false;
  double innerM = 0, outerM = 0;     // a and r_z [m]
  std::vector<double> enthalpyJ_m3;  // per shell: sensible heat relative to T0 [J/m^3]
  std::vector<double> water;         // per shell: liquid water left, of the initial 0..1
  std::vector<int> nodes;            // contact nodes it exchanges with (last frame; kept by
                                     // the caller)
  std::vector<double> weights;       // their shares (sum 1; set by stepZone)
};

// shell radii r_0 = a .. r_N = r_z (geometric)
std::vector<double> zoneRadii(double innerM, double outerM);
// hemispherical shell volumes (2 pi / 3)(r_k+1^3 - r_k^3)
std::vector<double> zoneVolumes(const std::vector<double>& radii);
// sensible heat stored in the zone [J]
double zoneEnergyJ(const SubgridZone& zone);
// temperature of the innermost shell (the hottest) [C]
double zoneTemperatureC(const SubgridZoneParams& p, const SubgridZone& zone, int shell = 0);

// what the zone's neighbours look like this frame: the contact nodes' shares, temperatures
// and enthalpies (the zone's inflow takes their sensible heat, capped at boiling)
struct ZoneCoupling {
  std::vector<double> weights;       // sum 1
  std::vector<double> temperatureC;  // per contact node
  std::vector<double> enthalpyJ_m3;  // per contact node (mesh enthalpy)
};

struct ZoneStepResult {
  std::vector<double> toNodesJ;  // heat given to each contact node (< 0: taken) [J]
  double inputJ = 0;             // Joule heat of the shells [J]
  double vaporKg = 0;            // water vaporised [kg]
  double maxVaporFraction = 0;   // largest vaporised fraction of a shell's water [0..1]
  int substeps = 0;
};

// The von Mises stress at the wall of a pocket of tissue with the volumetric expansion e_v
// inside an elastic body (Eshelby's spherical inclusion, REFERENCE.md case 8: interface
// von Mises E eps* / (1 - nu), eps* = e_v / 3) [Pa].
double pocketVonMisesPa(double youngsModulusPa, double poissonRatio, double expansion);

// Advances the zone by dtS with the shell powers powerW (one per shell, constant over the
// step), the coupling to the contact nodes and the residence time (infinity: a tool at rest).
// Energy: inputJ = change of zoneEnergyJ + sum(toNodesJ) + vaporKg * L exactly (to round-off).
ZoneStepResult stepZone(const SubgridZoneParams& p, SubgridZone& zone,
                        const std::vector<double>& powerW, const ZoneCoupling& coupling,
                        double residenceS, double dtS);

// The zone with new radii (created when absent): shells keep their state by index; the heat
// of tissue it gives back (it shrinks) or takes in (it grows, or forms: at the contact
// nodes' sensible enthalpy) is returned per contact node (> 0: given to the node) [J].
std::vector<double> resizeZone(const SubgridZoneParams& p, SubgridZone& zone, double innerM,
                               double outerM, const ZoneCoupling& coupling);

// The zone goes: its heat to its nodes (zone.nodes, zone.weights) [J], the zone cleared.
std::vector<double> releaseZone(SubgridZone& zone);

}  // namespace esim
