// structural.h - linear thermo-elastic P1 tetrahedra loaded by a volumetric eigenstrain:
// the stress that the expansion of the tissue's water (liquid, then vapour) causes.
//
// Small strain, isotropic linear elasticity (Young's modulus E [Pa], Poisson's ratio nu):
//   sigma = D (eps(u) - eps*),   eps* = (e_v / 3) I   per tet,
// e_v the tet's volumetric expansion (dV / V, the paper's Delta v_liq + Delta v_gas).
// P1 displacements (3 components per node, constant strain per tet); equilibrium
//   K u = f,   K = sum_e V_e B_e^T D B_e,   f = sum_e V_e B_e^T D eps*_e,
// with listed displacement components (Support) held at 0. The phase factorizes (CHOLMOD)
//   A = K on the free components, the identity on the held ones   (3n x 3n, all components)
// once at construction (supernodal LL'); every full solve() is a right-hand side (0 on the
// held components) and two triangular solves (a local one, see LocalSolveOptions, a
// correction on a region around the changed load). Once the factor is simplicial LDL' (after
// the first removal) the triangular solves are ldl_solve.h's, on solveThreads threads (esim
// bench structural at 8000 nodes, a solve with its stresses: 4.7 ms on two threads, 6.7 ms on
// one, 8.9 ms by CHOLMOD's cholmod_solve2; README, "The structural solve and update on two
// threads").
// Removed tets (alive == 0) contribute nothing, and neither do the tets of a floating island
// (a rigid piece: alive tets connected through shared faces, whose own supports leave a
// rigid motion free: cut loose, or hanging by an edge or a node): K holds the pieces the
// supports hold, so that it stays positive definite. A node without a tet in K is held at
// 0; a node an island shares with a held piece moves with that piece (an island hanging
// by an edge or a node does not clamp the tissue it hangs from). Islands carry no stress
// (free expansion: stress and von Mises 0); an island's own nodes follow the rigid motion of the
// nodes it hangs by (rigidFollowDisplacement, for the picture; 0 if none). The result
// equals a phase built on the mesh without the islands' tets, on the nodes and tets of the held
// pieces. Removal (removeTets) updates the factor instead of rebuilding it: the rows of the
// components it newly holds are deleted (identity rows, as cholmod_rowdel makes them, but all
// in one multiple-rank cholmod_updown by L's columns at those rows: deleteRows), then
// the removed tets' stiffness on the components still free is subtracted as a low-rank
// downdate (cholmod_updown; the stiffness of each cluster of removed tets sharing nodes is
// summed and split by an LDL' in L's row order (threshold pivoting), so a cluster costs its free
// dofs less its rigid motions in columns, not 6 per tet: 36 instead of 78 for 13 tets under the
// blade; L is converted to simplicial LDL' at the first removal after a factorization, O(nnz(L))
// once, or right after each factorization with StructuralOptions::prepareForUpdates). Its cost
// grows with the removed tets, the pieces they cut off and the columns of L below them, not with
// the mesh; when the estimate of that cost exceeds StructuralOptions::updateCostLimit times a
// refactorization's, or a downdate loses positive definiteness (a pivot D(j) <= 0), it
// refactorizes A instead. Either way the result equals a phase built afresh on the mesh
// with the same tets removed and the same supports (to round-off; see the tests).
// Measured (esim bench structural, paper slab, 5 tets under the top centre, 2 loaded
// cores): update 1.2 / 39 / 270 / 974 ms against a rebuild of 18 / 344 / 2940 / 10265 ms
// at 1k / 5k / 20k / 50k nodes, of which the one-off conversion to LDL' 0.4 / 17 / 148 /
// 587 ms; a simplicial factorization from the start would cost 2x (5k) to 5.7x (20k) the
// supernodal one, so the phase keeps the supernodal and converts at the first removal;
// solves with the LDL' factor then take ~1.3x as long (105 vs 83 ms at 20k nodes).
// A factor prepared for updates is ordered by METIS's nested dissection, whose shallower
// elimination tree shortens each update's paths (CHOLMOD's default takes AMD alone on small
// meshes). beginRemoval splits a removal into its bookkeeping (now, with its errors) and the
// factor's update (a function the caller may run on another thread: update mode runs it
// from the removal frame to the next structural solve).
// Pieces: per tet its piece; a removal searches only from the removed tets' neighbours
// (see splitPiece in structural.cpp), the pieces it cuts off and the supports they take.
// Per tet after solve(): Cauchy stress in Voigt order (xx, yy, zz, yz, xz, xy) [Pa]
// and its von Mises stress [Pa]. Displacement: 3 per node (x0, y0, z0, x1, ...) [m].
// The supports must remove the rigid motions (at least 6 independent components,
// e.g. a clamped face); otherwise the constructor throws esim::Error.
// Ownership: the phase copies the nodes, tets and alive flags it needs; the mesh may go
// away, and removeTets does not touch it (the caller keeps its alive flags in step).
// Threads: a phase is not thread-safe: solve() and removeTets() on one phase must not
// overlap; distinct phases are independent (each owns its CHOLMOD workspace). solve() may
// run half of its triangular solves on a thread it starts and joins (solveThreads). With
// LocalSolveOptions::refreshOnThread the phase runs full solves on a thread of its own (its
// own CHOLMOD workspace and copy of the state; it alone changes the whole factor while it
// runs: removeTets under the local method defers the factor's update to it).
// CHOLMOD runs with one OpenBLAS thread (set before each factorization and solve): on 2 shared
// cores more threads only spin (measured: simulation_test's background rebuild test went from 6.1 s
// to 0.7 s), and results do not depend on the thread count.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sim/mesh_tet.h"

namespace esim {

// ---- the load: expansion of the tissue's water (paper eq. 3) ----
// e_v = Delta v_liq + Delta v_gas per unit tissue volume, with phi = w rho / rho_w(T0) the
// water volume fraction:
//   Delta v_liq = phi (rho_w(T0) / rho_w(min(T, Tb)) - 1)   thermal expansion of the liquid
//                 (rho_w from the steam-table densities at 20..100 C, piecewise linear,
//                 held outside that range: +3.6 % from 37 to 100 C);
//   Delta v_gas = phi x (v_gas / v_liq - 1)                  the vaporised fraction x of
//                 the water at atmospheric pressure (v_gas / v_liq = 1602 at 100 C).
// The vapour is assumed trapped where it forms, so a vaporised fraction of ~7e-4 already
// gives e_v ~ 0.93, the expansion at which a laterally constrained layer with the paper's
// E, nu reaches its critical stress: tissue parts where boiling starts. e_v is capped at
// maxExpansion: once the tissue parts the vapour vents, and an uncapped e_v (x = 0.05 in
// one frame gives e_v = 67) loads the neighbours far beyond what a vented pocket can,
// widening the cut by whole elements. Measured on scenarios/slab_cut.yaml (8000 nodes,
// 60 frames): uncapped, 1399 tets removed in 13 frames (a crater); cap 3 (the default),
// 1014 tets in 37 frames (a groove along the blade); cap 1, none (peak von Mises
// 23.5 kPa, just under the critical 24.5 kPa, as the boiling tets sit at the free surface).
struct ExpansionParams {
  double waterFraction = 0.78;           // w, mass fraction of water
  double densityKg_m3 = 1060;            // tissue density rho [kg/m^3]
  double initialTemperatureC = 37;       // T0, the stress-free state [C]
  double boilingTemperatureC = 100;      // Tb [C]
  double vaporLiquidVolumeRatio = 1602;  // v_gas / v_liq at Tb and 1 atm (1.673 / 0.001044)
  double maxExpansion = 3.0;             // cap of e_v: the vapour vents once the tissue parts
};

// liquid water density [kg/m^3] at temperatureC (20..100 C table, held outside)
double waterDensityKg_m3(double temperatureC);

// volumetric expansion e_v of tissue at temperatureC with vaporised water fraction x
double volumetricExpansion(const ExpansionParams& params, double temperatureC,
                           double vaporFraction);

// ---- the volumetric part of the stiffness ----
// P1 tets lock as the material nears incompressibility: a tet's constant strain must keep its
// volume, and the mesh has fewer ways to move isochorically than it has tets, so the solution
// is too stiff and its deviatoric stress, the one von Mises measures, spurious. Measured
// (StructuralVolumetric.EshelbyInclusionHasTheAnalyticStress: a spherical inclusion expanded
// in a 24 mm cube of 9261 nodes, the mean von Mises stress of the tets 1.5 to 2.5 radii out
// over the analytic 6 mu D / r^3): element 1.009 / 1.015 / 1.094 / 1.597 at nu = 0.4 / 0.45 /
// 0.49 / 0.499; nodal 1.010 / 1.008 / 1.009 / 1.033.
// nodal: the volumetric strain is averaged at the nodes (the average nodal pressure tet of
// Bonet & Burton 1998): with V_n = sum_{e at n} V_e / 4 and the mean dilatation at a node
// theta_n(u) = sum_{e at n} (V_e / 4) div_e(u) / V_n,
//   K = sum_e V_e B_e^T D_dev B_e + sum_n K_b V_n grad(theta_n) grad(theta_n)^T,
//   f = sum_n K_b V_n theta*_n grad(theta_n),   theta*_n = sum_{e at n} (V_e / 4) e_v,e / V_n,
// and the stress of a tet D_dev B_e u_e + K_b (theta - theta*)_e (1,1,1,0,0,0), the bracket
// averaged over its 4 nodes. One constraint a node instead of one a tet: no locking. K then
// couples the nodes two rings apart (a larger factor: README, "Near-incompressible tissue"),
// and a removal changes the volumetric term of each node of the removed tets: removeTets
// adds the new terms (an update by sqrt(K_b V_n) g_n over the tets left, first, so that the
// factor stays positive definite) and downdates the old ones with the tets' deviatoric
// stiffness; rows deleted for held nodes reach two rings (rowPattern). A removal that frees
// rows again refactorizes. Not with the local or coarse solve methods (refused). The eigenstrain is
// averaged at the nodes too, so a sharp change of e_v (the boiling front) is spread over one ring
// of nodes: at nu = 0.4 the peak von Mises at the inclusion's surface is lower than element's (498
// against 682 Pa in the test above, analytic 792 Pa just outside the interface).
enum class VolumetricStrain {
  element,  // per tet (the paper's, and P1's usual form)
  nodal,    // averaged at the nodes (see above)
};
// from this Poisson's ratio on, a simulation with the volumetric strain per tet warns of
// locking (+4 % von Mises in the test above at 0.48, +2.7 % at 0.47)
constexpr double kLockingPoissonRatio = 0.48;

// ---- how solve() finds the displacement ----
enum class StructuralSolveMethod {
  full,    // K u = f over the whole body with the factor of A (the default)
  local,   // a correction of the last full solve on a region around the changed load
  coarse,  // a coarse Galerkin solve on a grid, then a correction on a region (see below)
};

// The local solve. The phase keeps a reference, (e_ref, u_ref): the load and displacement
// of its last full solve (or adopted refresh, see refreshOnThread). For a load e_v it
// solves only on U, the free components of the nodes within marginM of the box around the
// tets whose load changed since,
//   K_UU d_U = r_U,   r = f(e_v) - K u_ref = -sum_e V_e B_e^T sigma_e(u_ref, e_v),
//   u = u_ref + d   (d = 0 outside U),
// the Galerkin solution with u held at u_ref outside U: exact (to round-off) when U holds
// every free component; its energy-norm error never grows when U grows (nested spaces).
// What it drops is the response outside U to the load change since the reference, which
// decays slowly on the clamped slab (see the measurements below): the error grows with
// that change, so keep the reference fresh (refreshEvery) rather than the margin wide.
// The box: the alive tets whose |e_v - e_ref| exceeds loadTolerance times the largest
// change, the removed tets and the nodes held (u_ref set to 0) since the reference. The
// region (U, the alive tets touching it, CHOLMOD's factor of K_UU, ordered as the whole
// factor) is built around that box grown by slackM, and reused while the box stays inside
// it (a moving load pays a region factorization every slackM or so of travel).
// Removals under the local method: the next local solve updates the region's factor (kept
// simplicial LDL': the rows of the dofs held since deleted, as identity rows, and a
// downdate by the removed tets' stiffness on U, as the whole factor's update), or builds the
// region again when that update would cost more than a factorization; a removal outside the
// region's box rebuilds the region.
// With refreshOnThread, removeTets also leaves the whole factor as it is: it catches up in
// one update over every removal since its last one (a batched cholmod_updown) at the next
// refresh, on its thread (which starts from
// a copy of the alive set and the held dofs, so the frame goes on removing tets meanwhile;
// at its adoption the reference is set to 0 on the dofs held since and those removals widen
// the next box), or at the next full solve, in the frame.
// A full solve (the new reference) is done instead at the first
// solve, after setSolveMethod(full, ...), every refreshEvery solves (unless
// refreshOnThread), and when U would hold more than maxRegionFraction of the free
// components. The stress of a tet outside U's tets is D B_e u_ref - K_b e_v: its elastic
// part is kept per tet (48 bytes a tet; twice with refreshOnThread).
// Measured (esim bench structural --local: paper slab, Gaussian expansion of radius 3 mm
// scaled to a peak von Mises of 1.5 x 24.5 kPa, 40 frames, slack 5 mm, 2 loaded cores;
// growing: its peak ramps from 0.6 to 1; moving: 0.5 mm a frame along x), at 50k nodes
// (133k unknowns), full solve 150-160 ms (median). Refresh every 30 solves in the frame,
// margin 5 / 10 / 20 mm: median 18 / 30 / 63 ms growing, 21 / 32 / 62 ms moving; mean
// (a 0.4-1.8 s region build every ~10 frames moving, once growing, and the refreshes
// included) 36 / 50 / 108 and 67 / 107 / 224 ms; max |vm - vm_full| 155 / 83 / 28 Pa and
// 911 / 304 / 93 Pa; relative L2 over all tets 3.0 / 1.9 / 0.8 % and 6.8 / 4.1 / 1.6 %;
// tets on the other side of 24.5 kPa 1 / 1 / 0 and 2 / 1 / 0 (of 76-78 above it). With
// refreshOnThread, refreshEvery 10, margin 5 / 10 mm: median 36 / 41 and 25 / 36 ms (the
// thread competes for the 2 cores), max error 102 / 54 and 774 / 236 Pa, same set
// differences. At 20k nodes (full 43 ms): median 4-17 ms; at 5k (full 4.5 ms): 0.7-1.9 ms.
struct LocalSolveOptions {
  double marginM = 0.01;           // the region: nodes within this of the box [m]
  double slackM = 0.005;           // the box grown by this when a region is built [m]
  double loadTolerance = 1e-3;     // tets whose change exceeds this times the largest span
                                   // the box (in [0, 1))
  int refreshEvery = 30;           // a full solve at least every this many solves (0: never
                                   // but the first, and regions too large)
  double maxRegionFraction = 0.5;  // more of the free components than this: a full solve
  // the refresh on a thread of the phase instead of in the frame: a local solve starts a
  // full solve of its load on the thread (first applying the removals since the last one
  // to the whole factor), adopted as the reference (joined, waiting if unfinished) at the
  // refreshEvery-th solve after it, which starts the next one; so the reference is at most
  // 2 refreshEvery - 1 solves old, and the results do not depend on the thread's timing.
  // removeTets does not wait for it; setSolveMethod and a full solve in the frame join it
  // and drop its solve (refreshEvery 0: no refresh)
  bool refreshOnThread = false;
  // ---- the coarse method (StructuralSolveMethod::coarse) ----
  // Every solve: u_0 = P_h K_c^-1 P_h' f on the coarse space of structural_coarse.h (a grid of
  // cells of at most coarseSpacingM over the mesh's box, or automatic), then, with
  // coarseCorrection, the region's correction as above with u_0 for u_ref (one step of a
  // two-level multiplicative Schwarz method; its energy-norm error is at most the coarse
  // solve's). The box: the alive tets whose e_v changed by more than coarseLoadTolerance times
  // the largest change since the last solve, the removed tets and the nodes held
  // since (where the tool heats and cuts); the region is kept while that box stays inside the
  // one it was built around (a frame with no change keeps it). No full solve is done: removals
  // update K_c (structural_coarse.h) and the region's factor, and leave the whole factor as it
  // is (it catches up at the next full solve: a region holding more than maxRegionFraction of
  // the free components, or setSolveMethod(full)). marginM, slackM and maxRegionFraction as
  // above; loadTolerance, refreshEvery and refreshOnThread are not used.
  // Measured (esim bench cut --strategy update --structural full,coarse, README "The coarse
  // method in the frame loop"): at 50k nodes, margin 3 mm, slack 1 mm, solve_stress median 64
  // against 206 ms for the full solve, p95 1084 against 404 ms (9 region builds of 16 000-26 000
  // unknowns in 30 frames, 0.5-1.05 s each, in the frame), 2997 against 2975 tets removed; at
  // 8000 nodes slower than the full solve (median 17.6 against 8.3 ms).
  // the coarse grid's cell size, at most, along each axis [m]; 0: automatic, a grid of at most
  // CoarseSpace::kAutoGridNodes (300) nodes over the mesh's box (slab_cut: 5 mm, 273 nodes)
  double coarseSpacingM = 0;
  // the box: tets whose e_v changed by more than this times the largest change (in [0, 1));
  // the default takes the tets that start to boil (e_v jumps by ~1), not those warming
  double coarseLoadTolerance = 0.05;
  bool coarseCorrection = true;  // false: the coarse solve alone (what the region buys)
};

// what the last solve() did
struct StructuralSolveStats {
  bool local = false;               // a local solve (else a full one, the new reference)
  bool regionBuilt = false;         // ... that built and factorized a region
  bool regionUpdated = false;       // ... that updated its region's factor for removals in it
  bool regionRefactorized = false;  // ... by building it again (the update would cost more)
  int regionDofs = 0;               // unknowns of the local solve (0: no load change)
  int regionTets = 0;               // tets whose stress the correction changes
  double regionFactorSeconds = 0;   // assembly and factorization of K_UU, or its update
  double coarseFactorSeconds = 0;   // coarse method: K_c's build or numeric refactorization
  bool refreshAdopted = false;      // refreshOnThread: a refresh became the reference ...
  bool refreshStarted = false;      // ... a refresh of this load started
  int solveThreads = 0;             // threads of its triangular solves by ldl_solve.h (1 or 2;
                                    // 0: CHOLMOD's solve, the factor not simplicial LDL')
  double seconds = 0;               // wall time of the call (waits for the thread included)
};

// ---- the phase ----
struct StructuralOptions {
  double youngsModulusPa = 4.75e4;                          // E (paper Table 1)
  double poissonRatio = 0.4;                                // nu in [0, 0.5) (paper Table 1)
  VolumetricStrain volumetric = VolumetricStrain::element;  // see VolumetricStrain
  // removeTets updates the factor while its estimated cost is at most this times a
  // refactorization's, else refactorizes (1: the cheaper; 0: always refactorize; a large
  // value: update unless a downdate fails)
  double updateCostLimit = 1.0;
  // convert the factor to simplicial LDL' right after each factorization (the constructor's
  // and a fallback refactorization's) instead of at the first removal after it: a simulation
  // that removes tets in its frame loop pays the conversion at set-up (solves are then ~1.3x
  // slower from the start; results equal to round-off)
  bool prepareForUpdates = false;
  // a removal's updates of the simplicial factor (the downdate by its stiffness, the rows
  // deleted) by the AVX-512 kernel of ldl_updown.h where the machine has it, else (false, or
  // no AVX-512) by CHOLMOD's cholmod_updown: the same arithmetic, equal to round-off
  bool vectorizedUpdate = true;
  // the triangular solves of a simplicial LDL' factor (the whole one once updated, the local
  // method's region) by ldl_solve.h, the per-tet stresses, and a removal's update (ldl_updown.h's
  // passes pipelined) on this many threads (1 or 2; the same bits either way), or 0: the
  // solves by CHOLMOD's cholmod_solve2, the rest on one thread (the comparison). A supernodal
  // factor, before its first update, is solved by CHOLMOD.
  int solveThreads = 2;
  StructuralSolveMethod solveMethod = StructuralSolveMethod::full;  // see LocalSolveOptions
  LocalSolveOptions local;
  // what made the supports, in the caller's words (e.g. the scenario key of a clamp):
  // appended in parentheses to the errors about them (no piece held, a factor not positive
  // definite), so that the phase's message names the cause; empty: nothing appended
  std::string supportsNote;
};

// what one removeTets call did
struct StructuralUpdateStats {
  int tetsRemoved = 0;          // newly removed (ids of removed tets and repeats are skipped)
  int dofsHeld = 0;             // components newly held: rows deleted from L
  int tetsIntoIslands = 0;      // alive tets of the pieces it made islands: out of K with it
  int rank = 0;                 // columns of the downdate C (<= 6 per removed tet)
  int groupsSplit = 0;          // clusters of removed tets whose columns went by parts (too
                                // many dofs, or a summed column that would fill in L)
  long vectorColumns = 0;       // columns (of C and of the rows deleted) by ldl_updown.h's kernel
  long choleskyColumns = 0;     // ... and by cholmod_updown
  int piecesCutOff = 0;         // pieces split off the ones the removed tets belonged to
  double updateWork = 0;        // entries of L the update walks, times the columns passing
  double updateCost = 0;        // estimated cost of the update / a refactorization's
  bool refactorized = false;    // fell back to a full refactorization
  bool deferred = false;        // local method, refresh on a thread: the factor's update waits
                                // for the next refresh or full solve (see LocalSolveOptions)
  bool downdateFailed = false;  // ... because the update lost positive definiteness
  double convertSeconds = 0;    // supernodal LL' to simplicial LDL' (first update after a
                                // factorization; 0 with StructuralOptions::prepareForUpdates)
  double seconds = 0;           // wall time of the call
};

// one displacement component held at 0
struct Support {
  int node = 0;
  int axis = 0;  // 0 x, 1 y, 2 z
};

using VoigtStress = std::array<double, 6>;  // xx, yy, zz, yz, xz, xy [Pa]

// von Mises stress of a Voigt stress [Pa]
double vonMises(const VoigtStress& s);

// How an island (a piece out of K, whose rigid motion K leaves free) is drawn: the rigid
// motion that carries its anchors (the nodes it hangs by, at rest positions anchorRestM) by
// their displacements anchorDispM (3 x a), applied to the rest positions restM (3 x m);
// returns their displacements [m], (R - I)(x - c) + d with c the anchors' centroid and d
// their mean displacement. R: three anchors or more, not on a line, the least-squares
// rotation (Eigen::umeyama without scaling); two, or anchors on a line (the second principal
// extent under kRigidFollowLineRatio of the first), the smallest rotation that turns the
// line through the two outermost anchors (a rotation about that line is not determined);
// one: I, a translation; none: 0 (a piece cut loose stays where it was).
constexpr double kRigidFollowLineRatio = 0.05;
Eigen::Matrix3Xd rigidFollowDisplacement(const Eigen::Matrix3Xd& anchorRestM,
                                         const Eigen::Matrix3Xd& anchorDispM,
                                         const Eigen::Matrix3Xd& restM);

struct TetGeometry;
// P1 elasticity stiffness of one tet, V_e B_e^T D B_e [N/m] (12 x 12, node-major x, y, z
// components): what StructuralPhase assembles, for studies that assemble K themselves
Eigen::Matrix<double, 12, 12> elasticTetStiffness(const TetGeometry& g, double youngsModulusPa,
                                                  double poissonRatio);
// K of the alive tets (alive[t] != 0) on the free dofs, lower triangle, column-major, dof
// 3 v + axis of node v; a held dof (held[dof] != 0) has only a 1 on its diagonal. The pattern
// first (each node's alive tets' nodes), then each tet's elementStiffness(t) scattered in
// ascending tet order onto -0.0, the additive identity: every entry is summed left to right
// from its first tet's term, bitwise what Eigen's setFromTriplets gave for the triplets
// emitted tet by tet (as fem_p1.h's assembleStiffness does for P1), without the 78 triplets a
// tet (50 MB at 8000 nodes) and their sort. Measured in README, "Structural phase".
// With rowOfDof (per dof of the body: its row in the result, ascending in the dof, or -1 for a
// dof left out; held dofs left out), the result is numRows x numRows, K restricted to those
// dofs: a region's K_UU, alive naming the tets that touch the region.
Eigen::SparseMatrix<double, Eigen::ColMajor, int> assembleElasticLower(
    int numNodes, const std::vector<Tet>& tets, const std::uint8_t* alive, const std::uint8_t* held,
    const std::function<Eigen::Matrix<double, 12, 12>(int)>& elementStiffness,
    const int* rowOfDof = nullptr, int numRows = 0);
// the strain of one tet (xx, yy, zz, 2yz, 2xz, 2xy) from its 4 nodes' displacements [m]
// (3 each, x y z), as StructuralPhase's stresses take it
std::array<double, 6> tetStrain(const TetGeometry& g, const std::array<const double*, 4>& u);

class StructuralPhase {
 public:
  // assembles and factorizes K; throws esim::Error on bad options, supports or a
  // singular K (supports that leave a rigid motion free)
  StructuralPhase(const TetMesh& mesh, const StructuralOptions& options,
                  const std::vector<Support>& supports);
  ~StructuralPhase();
  StructuralPhase(const StructuralPhase&) = delete;
  StructuralPhase& operator=(const StructuralPhase&) = delete;

  // displacement and stresses for one volumetric eigenstrain per tet (numTets()
  // entries, removed tets ignored), by the solve method (full, or local: see
  // LocalSolveOptions); throws esim::Error on a size mismatch or NaN, or after a removal
  // that left no piece held
  void solve(const std::vector<double>& volumetricEigenstrain);

  // changes the solve method and its options (validated as the constructor does; nothing
  // changed if they are refused); the reference of a local solve is kept, its region dropped;
  // the coarse method's grid and K_c are built now
  void setSolveMethod(StructuralSolveMethod method, const LocalSolveOptions& local);
  const StructuralSolveStats& lastSolveStats() const;  // of the last solve()
  // changes StructuralOptions::solveThreads (0, 1 or 2; else esim::Error)
  void setSolveThreads(int threads);

  // Removes tets (mesh tet ids; ids already removed and repeats are skipped) and updates
  // the factor (see the header comment): afterwards the phase is the one a constructor
  // would build on the mesh with these tets removed too (under the local method with its
  // refresh on a thread the factor's update is deferred: see LocalSolveOptions). Throws
  // esim::Error (Input kind)
  // on an id out of range (nothing changed); when no piece is held by the supports any
  // more, it throws the constructor's esim::Error, "structural: no piece of the body is
  // held by the supports (StructuralOptions::supportsNote)" (Input kind, as the
  // constructor: the caller says whether a removal made it), and the phase is dead: every later
  // solve or removeTets throws it again; esim::RunError if CHOLMOD runs out of memory or a
  // refactorization fails.
  StructuralUpdateStats removeTets(const std::vector<int>& tets);
  // removeTets in two parts: this call does the bookkeeping (alive set, pieces, held
  // dofs) and throws what removeTets throws for it; the function returned updates
  // the factor (CHOLMOD's work, and its RunErrors) and returns the stats. It may run on
  // another thread; until it has returned, no other call may be made on the phase.
  // removeTets(t) is beginRemoval(t)().
  std::function<StructuralUpdateStats()> beginRemoval(const std::vector<int>& tets);

  const Eigen::VectorXd& displacementM() const;      // 3 per node [m]
  const std::vector<VoigtStress>& stressPa() const;  // per tet (0 for removed tets)
  const std::vector<double>& vonMisesPa() const;     // per tet (0 for removed tets)
  int numFreeDofs() const;                           // unknowns of K u = f
  int numFloatingIslands() const;                    // unsupported pieces (out of K)
  int numIslandTets() const;                         // their alive tets
  double factorizationSeconds() const;  // wall time of the constructor's factorization [s]
                                        // (with the conversion if prepareForUpdates, and the
                                        // coarse method's K_c and its factorization)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace esim
