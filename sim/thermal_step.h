// thermal_step.h - heat conduction with Joule source, boiling (latent heat) and damage.
//
// Solves, on the P1 tet mesh, the enthalpy form of the heat equation (paper eq. 2)
//   dH/dt = div(lambda grad T) + Q,     T = T(H),
// with H [J/m^3] the volumetric enthalpy relative to the initial state (T0, all water
// liquid), Q [W/m^3] a per-tet source given by the caller (Joule heat sigma |grad V|^2
// or a prescribed source), lambda [W/(m K)] the conductivity and c rho [J/(K m^3)] the
// volumetric heat capacity. Boundaries are insulated, except `cooledFaces`, which lose
// h (T - T_ambient) [W/m^2] (Robin condition). Temperatures are in degrees Celsius.
//
// T(H), with Hb = c rho (Tb - T0) and Lv = w rho L (latent heat of the tissue water):
//   H <= Hb:            T = T0 + H / (c rho)             (liquid, sensible heat)
//   Hb < H <= Hb + Lv:  T = Tb                           (boiling plateau, vapour fraction
//                                                         (H - Hb)/Lv)
//   H > Hb + Lv:        T = Tb + (H - Hb - Lv)/(c rho)   (dry: desiccated)
// Without boiling, T = T0 + H/(c rho) everywhere. Vaporisation is reversible in this
// model (a node that cools re-condenses); the per-tet `desiccatedTet` flag is sticky.
//
// Discretisation: M dH/dt + K T = F, M the (lumped or consistent) P1 mass [m^3], K the
// P1 stiffness (lambda) plus the convective face matrix (h) [W/K], F the nodal source
// plus h T_ambient face load [W]. Theta scheme, theta = 0 (explicit), 1/2 (Crank-
// Nicolson), 1 (backward Euler):
//   M (H1 - H0)/dt + theta K T(H1) + (1 - theta) K T(H0) = F.
// The nonlinear T(H) is handled by a Chernoff-type iteration (Nochetto-Verdi relaxation
// with the maximal slope 1/(c rho) of T(H)):
//   (c rho M/dt + theta K) T_k+1 = G - M (H_k - H0)/dt + c rho M T(H_k)/dt,
//   H_k+1 = H0 + dt M^-1 (G - theta K T_k+1),       G = F - (1 - theta) K T(H0),
// whose matrix is the linear problem's matrix (pre-factored once per dt, or solved by
// Jacobi-CG when it is well conditioned). The flux form of the H update makes the energy
// balance exact at every iterate: sum_i m_i (H1 - H0)_i = dt (source - convected power),
// because the columns of the conduction matrix sum to zero. Without boiling one
// iteration suffices. With CG (nothing to re-factor) the iteration starts from the
// explicit predictor and, for its first iterations, uses a Newton-like relaxation
// capacity 1e8 c rho on the nodes inside the plateau (pinning them at Tb), which finds
// the boiling set in ~1-2 iterations; the plain Chernoff iteration (globally convergent,
// contraction ~theta dt lambda_max < 1e-2 at frame steps) then takes over if needed.
// CG stops when its preconditioned residual (~ the temperature error) is below 1e-3 of
// the nonlinear tolerance.
// Explicit: the stability limit dt <= 2 / lambda_max((c rho M)^-1 K) is enforced by
// sub-stepping, or an Error, with lambda_max bounded by the smaller of two rigorous bounds
// (no margin): the elements' own, max_e lambda_max(K_e, c rho M_e) (K_e with its cooled
// faces' Robin terms), and Gershgorin's, max_i sum_j |K_ij| / (c rho m_i) (lumped; x5 for
// the consistent mass, M_c >= M_L / 5). On the shipped slabs (1k-50k nodes, graded or not)
// the limit is 0.74-0.99 of 2 / lambda_max (the Lanczos estimate with a 5 % margin used
// before: 0.95), 1 sub-step per 1/30 s frame either way; O(tets log tets) to build, and
// removeTets keeps it in O(log n) per touched node.
// Damage (optional): Arrhenius Omega += A exp(-Ea/(R T_K)) dt per tet, T_K the tet's mean
// temperature in kelvin (trapezoid rule over each (sub)step); coagulation 1 - exp(-Omega).
//
// Skipped steps: a step with zero source, no active convection and a uniform enthalpy
// field (e.g. the whole body at rest at 37 C) changes nothing but the time and the damage
// integral; it does no solve and returns StepStats.skipped = true.
//
// Ownership: ThermalPhase copies what it needs from the mesh (tets, alive flags, volumes,
// and for removeTets and the explicit limit the basis gradients and per-tet rates: ~110
// bytes per tet) and owns its operators and factorizations; ThermalState is plain data
// owned by the caller. Enthalpy is the primary unknown: `temperatureC` is derived from it
// at every step; to impose a temperature field use ThermalPhase::setTemperature.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sim/fem_p1.h"
#include "sim/mesh_tet.h"

namespace esim {

// TrBdf2: a crank-nicolson stage over gamma dt then a BDF2 stage (gamma = 2 - sqrt 2, both on
// one matrix c rho M/h + K, h = gamma dt/2): second order and L-stable, so the stiff modes a
// sharp heat source excites are damped where crank-nicolson carries them with factor -1
// (README, "Thermal integrators")
enum class ThermalIntegrator { Explicit, BackwardEuler, CrankNicolson, TrBdf2 };

// "explicit", "backward-euler", "crank-nicolson", "tr-bdf2"; throws Error listing the valid
// names
ThermalIntegrator parseThermalIntegrator(const std::string& name);

// the name parseThermalIntegrator accepts
std::string thermalIntegratorName(ThermalIntegrator integrator);

// Linear solver of the implicit integrators. Auto: Jacobi-CG when the lumped-mass system
// is well conditioned (a Gershgorin bound on its condition number <= 4, true for frame
// steps on tissue meshes), else a pre-factored sparse Cholesky (CHOLMOD). Consistent mass
// always uses Cholesky.
enum class ThermalLinearSolver { Auto, Direct, Cg };

struct ThermalParams {
  double heatCapacityJ_m3K = 3.82e6;  // c rho [J/(K m^3)] (paper Table 1)
  double conductivityW_mK = 0.502;    // lambda [W/(m K)] (paper Table 1)
  double initialTemperatureC = 37;    // initial and body temperature [C]

  bool boiling = false;              // latent heat of the tissue water at boilingTemperatureC
  double boilingTemperatureC = 100;  // [C]
  double waterFraction = 0.78;       // water mass fraction w (liver) [0..1]
  double densityKg_m3 = 1060;        // tissue density rho [kg/m^3]
  double latentHeatJ_kg = 2.256e6;   // L [J/kg]

  ThermalIntegrator integrator = ThermalIntegrator::Explicit;  // lumped mass, sub-stepped
  bool lumpedMass = true;        // lumped (row-sum) or consistent P1 mass
  bool allowSubstepping = true;  // explicit: sub-step below the stability limit
  // explicit: a frame needing more sub-steps than this is refused (the work of a frame is
  // bounded; the remedy is an implicit integrator or a higher frame rate)
  int maxSubsteps = 1000;
  ThermalLinearSolver linearSolver = ThermalLinearSolver::Auto;
  double nonlinearToleranceK = 1e-9;  // boiling iteration: max |T_k - T(H_k)| [K]
  int maxNonlinearIterations = 100;

  double convectionW_m2K = 0;       // h on `cooledFaces` [W/(m^2 K)]
  double ambientTemperatureC = 20;  // [C]

  bool damage = false;                 // Arrhenius coagulation (liver)
  double arrheniusA_s = 7.39e39;       // frequency factor A [1/s]
  double arrheniusEa_J_mol = 2.577e5;  // activation energy Ea [J/mol]
};

// Checks the parameters; throws Error "<scenario key> = <value>: must be ..." naming the
// first bad field by the scenario key it comes from (material.heat_capacity_j_per_m3k, ...).
void validateThermalParams(const ThermalParams& params);

// the refusal of an explicit frame step that needs more than maxSubsteps sub-steps, with
// the remedy (an implicit integrator, a higher time.fps)
std::string explicitSubstepMessage(double dtS, double limitS, int maxSubsteps);

// Per-node and per-tet thermal state (plain data, owned by the caller).
struct ThermalState {
  Eigen::VectorXd temperatureC;             // per node [C] (derived from the enthalpy)
  Eigen::VectorXd enthalpyJ_m3;             // per node [J/m^3], relative to the initial state
  Eigen::VectorXd vaporFraction;            // per node, vaporised fraction of the water 0..1
  std::vector<double> vaporFractionTet;     // per tet: mean of its nodes 0..1
  std::vector<double> damageOmega;          // per tet: Arrhenius damage integral Omega
  std::vector<double> coagulationTet;       // per tet: 1 - exp(-Omega)
  std::vector<std::uint8_t> desiccatedTet;  // per tet: 1 once all its nodes were dry (sticky)
  double timeS = 0;                         // simulated time [s]
  double sensibleJ = 0;                     // stored sensible heat, relative to T0 [J]
  double latentJ = 0;                       // stored latent heat (vaporised water) [J]
  double sourceJ = 0;                       // integral of the source power over time [J]
  double convectedJ = 0;                    // heat lost through the cooled faces [J]
};

class ThermalPhase {
 public:
  // Builds the operators of the alive tets. `cooledFaces` (boundary faces, e.g. the top
  // surface) exchange heat with the ambient when params.convectionW_m2K > 0.
  ThermalPhase(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
               const ThermalParams& params, const std::vector<BoundaryFace>& cooledFaces = {});
  ~ThermalPhase();
  ThermalPhase(ThermalPhase&&) noexcept;
  ThermalPhase& operator=(ThermalPhase&&) noexcept;

  // uniform initial temperature, no water vaporised, no damage, time 0
  void initState(ThermalState& state) const;

  // imposes a nodal temperature field [C]: liquid up to the boiling temperature, dry above
  void setTemperature(ThermalState& state, const Eigen::VectorXd& temperatureC) const;

  struct StepStats {
    int substeps = 0;       // explicit sub-steps (1 for implicit, 2 for tr-bdf2's stages)
    int iterations = 0;     // linear solves (boiling iterations; CG iterations not counted)
    bool skipped = false;   // nothing to do: zero source, uniform field (see header)
    bool converged = true;  // boiling iteration reached nonlinearToleranceK
    int cgIterations = 0;   // total CG iterations (0 with a direct solver)
  };

  // a heat source on one node [W] (constant over the step), added to the load of the tets'
  // source; it counts in sourceJ like them
  struct NodalSource {
    int node = 0;
    double powerW = 0;
  };

  // Advances the state by dtS [s] with the per-tet source sourceW_m3 [W/m^3] (size
  // numTets; removed tets ignored) and the nodal sources (on nodes of alive tets: see
  // nodeActive; any sign). Throws Error on bad input or, for the explicit integrator without
  // sub-stepping, on a dt above the stability limit.
  StepStats step(double dtS, const std::vector<double>& sourceW_m3, ThermalState& state,
                 const std::vector<NodalSource>& nodalSources = {});

  // the node belongs to an alive tet (it has heat capacity and exchanges heat)
  bool nodeActive(int node) const;

  // What removeTets did (for the caller's timing row and logs).
  struct RemovalStats {
    int removedTets = 0;                // tets newly removed (ids already removed are ignored)
    int orphanedNodes = 0;              // nodes left without an alive tet by this call
    int droppedCooledFaces = 0;         // cooled faces of the removed tets
    int editedEntries = 0;              // conduction matrix entries recomputed (pattern kept)
    bool factorUpdated = false;         // implicit Cholesky modified in place (cholmod_updown)
    int factorRank = 0;                 // ... by this many rank-1 terms (<= 4 per tet + orphans)
    bool massFactorUpdated = false;     // consistent mass Cholesky modified in place
    bool factorDropped = false;         // factored again at the next step instead (see below)
    bool massFactorDropped = false;     // the same for the mass
    bool explicitLimitChanged = false;  // explicit limit changed (up or down)
    bool solverChoiceDropped = false;   // Auto cg/cholmod: decided again next step
    double ms = 0;                      // wall time of the call [ms]
  };

  // Topology change in place: marks `tets` (ids into the mesh's tet array; duplicates and
  // tets already removed are ignored) removed and edits the operators locally, so that
  // every later step() equals that of a ThermalPhase freshly built on the mesh with these
  // tets dead and the cooled faces of dead tets dropped: the operators, the explicit limit
  // and the Auto solver choice bitwise (explicit and CG results are then bitwise the
  // same), the Cholesky results to round-off. The matrix patterns are kept (entries of
  // removed couplings hold exact zeros).
  // Cost, for k tets: O(k x local degree) for the entries, lumped/consistent mass and
  // Robin terms around the removed tets' nodes, O(log n) per touched node for the explicit
  // limit, an O(n) sum when a cooled face goes; the Cholesky factors (implicit Direct
  // path, consistent mass) are modified in place by a rank <= 4k update/downdate (CHOLMOD,
  // cost set by the factor columns it reaches; the first one per factor also converts it
  // to simplicial LDL', O(nnz(L))); a later change of dt then analyses and factors anew.
  // Above ~100 tets per call (rank 400; measured break-even ~500 at 8k and 50k nodes) the
  // factors are instead dropped and factored at the next step, as after a fresh build.
  // The Auto solver choice, O(n), is made again at the next step, as after a fresh build.
  // The ThermalState is not touched and keeps its size: orphan nodes (no alive tet left)
  // keep their enthalpy and temperature, have zero mass and exchange nothing, as in a
  // fresh build. Throws Error, before changing anything, on an id out of range; if CHOLMOD
  // refuses a modification the factor is dropped and built again at the next step
  // (stats.factorDropped), never an error. Not thread-safe: no other call on this phase
  // (const ones included) may run concurrently.
  RemovalStats removeTets(const std::vector<int>& tets);

  // Topology changed (tets removed; same node and tet arrays): rebuilds the operators and
  // drops the factorizations; the state is kept (removeTets does the same locally). Nodes left
  // without an alive tet keep their enthalpy but no longer exchange heat or count in the energy
  // (the heat of removed tissue leaves with it). Cooled faces of removed tets are dropped; newly
  // exposed faces are not cooled.
  void rebuild(const TetMesh& mesh, const std::vector<TetGeometry>& geo);

  // explicit stability limit of this mesh [s] (the bounds of the header; built with the
  // phase for the explicit integrator, else on the first call: O(tets log tets), which
  // writes the phase's cache, so that first call must not race other calls)
  double stableExplicitDtS() const;

  // sensible + latent heat stored in the alive tissue, relative to the initial state [J]
  double storedEnergyJ(const ThermalState& state) const;

  // temperature [C] of an enthalpy [J/m^3] (the T(H) relation above)
  double temperatureOfEnthalpy(double enthalpyJ_m3) const;

  // which linear solver the implicit integrator used in its last step ("cg", "cholmod")
  std::string lastSolverName() const;

  const ThermalParams& params() const { return params_; }
  int numNodes() const { return numNodes_; }
  int numTets() const { return static_cast<int>(tets_.size()); }

 private:
  struct Impl;
  void buildOperators(const TetMesh& mesh, const std::vector<TetGeometry>& geo);
  int recomputeEntries(const std::vector<int>& removed);
  void elementRates() const;
  void recomputeConvection(const std::vector<int>& nodes);
  void modifyFactors(const std::vector<int>& removed, const std::vector<int>& orphans,
                     RemovalStats& stats);

  ThermalParams params_;
  int numNodes_ = 0;
  std::vector<Tet> tets_;
  std::vector<std::uint8_t> alive_;
  std::vector<double> volumeM3_;
  std::vector<Eigen::Matrix<double, 4, 3>> gradM_;  // basis gradients per tet [1/m]
  std::vector<BoundaryFace> cooledFaces_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace esim
