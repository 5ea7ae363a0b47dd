// electric_solver.h - the electric potential with a moving tool: one interface,
// four strategies, the same discrete answer.
//
// Equation: P1 FEM for div(sigma grad V) = 0, i.e. K u = 0 at the free nodes,
// with u = 0 [V] at the grounded nodes (return electrode) and u = voltageV at the
// contact nodes (tool). K is the n x n stiffness of the whole mesh (conductivity
// [S/m] inside, entries [S]). Insulated (natural) boundary elsewhere.
//
// Node classes (fixed by setMatrix, then by each updateMatrix):
//   grounded  - the ids passed to setMatrix, held at 0 V;
//   floating  - nodes with no path to a grounded node through the nonzeros of K
//               (nodes with no alive element, islands cut off by removal): their
//               potential is undefined, so they are held at 0 V, carry no
//               current and are never part of a factorized matrix; a contact on a
//               floating node is ignored (it touches an isolated island);
//   free (f)  - all others. K_ff is SPD.
// Per frame the contact nodes c (subset of f) are held at voltageV, the others
// o = f \ c are solved.
//
// Strategies (and what setMatrix costs, i.e. when K changes: conductivity
// feedback, removed elements; updateMatrix: see below):
//   refactor      - the conventional method (paper eq. 6-7): K_ff with the
//                   contact rows/columns replaced by the identity (same pattern
//                   for every contact set, so the symbolic analysis is done once
//                   per setMatrix) is factorized numerically (CHOLMOD supernodal)
//                   again whenever the contact set changes. setMatrix: a new
//                   symbolic analysis; the next solve refactors. updateMatrix:
//                   new values in the kept pattern (no analysis); the next solve
//                   refactors.
//   dense-inverse - the paper's method (eq. 8-13): L = K_ff^-1 precomputed
//                   (n_f^2 * 8 bytes, refused above denseMemoryLimitBytes);
//                   per frame f_c = L_cc^-1 u_c, u_o = L_oc f_c (BLAS).
//                   setMatrix: the whole inverse is recomputed. updateMatrix: a
//                   Sherman-Morrison-Woodbury update of rank s (the rows of
//                   K_ff that changed), 2 n_f^2 s flops.
//   capacitance   - one CHOLMOD factorization of K_ff; per contact set the
//                   columns z_i = K_ff^-1 e_i of the contact nodes (cached across
//                   frames: a new contact node costs one solve, or one block
//                   solve for its patch of neighbouring surface nodes when
//                   setContactCandidates was given; least recently used columns
//                   are evicted above cacheMemoryLimitBytes), the small system
//                   Z_cc f = u_c, then u = Z f. setMatrix: a new factorization
//                   and the cache is emptied. updateMatrix: the supernodal
//                   factor is kept and a Woodbury term of rank s (the changed
//                   rows) is added to its solves (one block solve of s columns),
//                   folded into a numeric refactorization (kept ordering) when it
//                   grows; every cached column is corrected in place
//                   (z' = z - K'^-1 (K' - K) z, one BLAS-3 product, 2 n_f s flops
//                   a column) unless solving it again is cheaper.
//                   CapacitanceUpdate::Downdate modifies a simplicial LDL' factor
//                   instead (CHOLMOD rowdel, updown; 1.6-2.6x slower solves after).
//                   See electric_capacitance.cpp.
//   local         - not exact: the nodes within localMarginM of the contacts solved each
//                   frame with the potential elsewhere held from a full pcg solve
//                   refreshed on a thread every localRefreshFrames solves (see
//                   electric_local.cpp; its error measured in README "The potential
//                   solved around the tool, built"). setMatrix: an O(nnz) copy;
//                   updateMatrix told the changed nodes: its classes in place (FreeBase)
//                   and their columns copied; the full solver takes the matrix at its next
//                   refresh (a cut as pcg's update in place, told the changed nodes since
//                   it last took one).
//   downdate      - capacitance's algebra on one simplicial LDL' factor of K_ff kept
//                   exact through a cut: updateMatrix deletes the rows leaving the free
//                   set and applies the change by low-rank updates and downdates (the
//                   structural phase's kernels, ldl_updown.h), so no term grows and nothing
//                   is refactorized; a contact node's path up the elimination tree (its
//                   column's forward half, L^-1 e_j) is solved on first touch and kept
//                   until the next update, and a new contact set's potential is one backward
//                   solve (ldlSolveBackward). See electric_downdate.cpp.
//   pcg           - conjugate gradients on the reduced system, warm-started from
//                   the input potential, Jacobi or incomplete-Cholesky
//                   preconditioner, stopping at ||r|| <= pcgTolerance ||b||.
//                   setMatrix: only the matrix is replaced (the warm start stays);
//                   updateMatrix: the change in place (FreeBase), the preconditioner's
//                   aggregates kept.
// All strategies run with explicit thread counts (OpenBLAS set to `threads`,
// Eigen single-threaded) and are deterministic for a given input.
// Ownership: a solver owns copies of what it needs; K is not referenced after
// setMatrix or updateMatrix returns.
// Thread safety: none inside one solver (every call, solve included, mutates caches);
// distinct solvers may run on distinct threads.
//
// Matrix updates (issue #11, cutting): updateMatrix(K, grounded) gives the same
// potential as setMatrix(K, grounded) (to rounding: 1e-9 relative is tested, every
// strategy, any sequence of updates) at a cost set by the change, not the mesh:
//   - made for element removal: K is the stiffness assembled from the alive elements
//     after the cut (assembleStiffness; same pattern with explicit zeros or
//     recompressed, both accepted). The change is read from K itself: the entries that
//     differ from the current matrix (an O(nnz) comparison plus the node classes,
//     O(nnz) breadth-first search). Unchanged entries must be bitwise unchanged (a
//     fresh assembly gives that), otherwise they only count as changed rows. Given
//     changedNodes (every node whose column of K may differ from the last K: a cut's
//     removed elements' nodes), the FreeBase strategies (refactor, dense-inverse,
//     capacitance, downdate, pcg, local) read only those columns, their neighbours' and a
//     spanning forest's paths to the ground: O(the change), with the same result bit for bit
//     (FreeBase::diff; it takes the O(nnz) way where a change is not a removal);
//   - nodes may leave the free set (no alive element left, an island cut off from the
//     ground, a node newly grounded): they keep their index with an identity
//     row/column, so orderings and factor sizes stay those of the last setMatrix;
//   - it falls back to setMatrix (stats.fellBack, stats.fallbackReason) when a node
//     joins the free set (the grounded set shrank and the node still has elements, or
//     a floating island reconnects), when K_ff gains a nonzero outside the pattern of
//     the last setMatrix, when the change is too large for an update to pay (the
//     crossovers are in the strategy files) or when a factor modification fails
//     numerically (a non-positive pivot or a residual above 1e-10);
//   - throws Error on bad input exactly as setMatrix does (and then, like a failed
//     setMatrix, leaves the solver unusable until the next setMatrix); a failed
//     factorization in a fallback throws as setMatrix does;
//   - cost (esim bench electric --only-update, 5 tets removed, one core, shared
//     machine): capacitance 0.12-0.35 s vs 0.7-2.0 s for setMatrix at 50k nodes,
//     with ~340 cached columns corrected, and the next solve of a cached contact set
//     costs < 1 ms instead of solving its columns; refactor 7-24 ms (next solve
//     refactors as always); pcg 0.4-0.7 ms vs 14-15 ms for its old setMatrix at 50k
//     nodes (5-95 tets, README "The potential's two-level preconditioner");
//     dense-inverse 0.1 s vs 5 s at 8k nodes.
// Capacitance after a cut, in this order: updateMatrix(K, grounded);
// setContactCandidates(new surface nodes); prefetch(newly exposed nodes the tool may
// touch) - all outside the frame loop, so the frame's solve finds its columns cached.
// updateMatrix modifies the solver in place: a caller that keeps solving frames while
// a cut is processed on another thread needs its own solver for that (or must wait).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sim/fem_p1.h"

struct cholmod_factor_struct;  // cholmod.h's cholmod_factor

namespace esim {

// Auto is not a solver: resolveElectricStrategy turns it into one for a mesh's size
enum class ElectricStrategy { Refactor, DenseInverse, Capacitance, Pcg, Local, Downdate, Auto };

enum class PcgPreconditioner { Jacobi, IncompleteCholesky, TwoLevel };

// how capacitance applies updateMatrix to its factor (see electric_capacitance.cpp)
enum class CapacitanceUpdate {
  Woodbury,  // keep the supernodal factor, add a low-rank Woodbury term to its solves
  Downdate   // modify a simplicial LDL' factor (CHOLMOD rowdel, updown): slower solves
};

// "refactor", "dense-inverse", "capacitance", "pcg", "local", "downdate", "auto"; throws Error
// listing the valid names
ElectricStrategy parseElectricStrategy(const std::string& name);

// the name parseElectricStrategy accepts
const char* electricStrategyName(ElectricStrategy strategy);

struct ElectricSolverOptions {
  ElectricStrategy strategy = ElectricStrategy::Capacitance;
  double pcgTolerance = 1e-8;  // relative residual ||b - A x|| / ||b||
  int pcgMaxIterations = 5000;
  // see electric_pcg.cpp: two-level measured 1.5x (8000 nodes) to 3.4x (27908) faster
  PcgPreconditioner pcgPreconditioner = PcgPreconditioner::TwoLevel;
  double denseMemoryLimitBytes = 2048.0 * 1048576.0;  // dense-inverse refuses above (2 GiB)
  double cacheMemoryLimitBytes = 1024.0 * 1048576.0;  // capacitance column cache cap (LRU eviction)
  int capacitancePatchNodes = 16;                     // capacitance: candidates solved together
  CapacitanceUpdate capacitanceUpdate = CapacitanceUpdate::Woodbury;  // capacitance updateMatrix
  // updateMatrix (capacitance, dense-inverse): ||K' Y - I||_F / sqrt(s) the updated factor or
  // inverse must reach on the s rows it changed (Y = K'^-1 I_:S); above it capacitance's
  // Woodbury term refines once, then refactorizes, and dense-inverse recomputes
  double updateResidual = 1e-10;
  int threads = 1;  // BLAS threads (CHOLMOD supernodal uses BLAS)
  // local (sim/electric_local.cpp): the region solved each frame, nodes within this distance
  // of a contact node [m]; the far field is held from a full solve (pcg) started every
  // localRefreshFrames solves with contact on a thread and adopted as many solves later
  double localMarginM = 0.006;
  int localRefreshFrames = 3;
  // local: also solve every frame fully (pcg at 1e-10, in the frame) and report the power's
  // error in ElectricSolveStats::powerError (a measurement for benchmarks: costs a full solve)
  bool localCheck = false;
};

// Checks the options; throws Error naming the scenario key (solvers.electric.*).
void validateElectricSolverOptions(const ElectricSolverOptions& options);

// The strategy that solves fastest for freeNodes unknowns (nodes off the return electrode):
// options.strategy unless it is Auto; then the paper's dense inverse up to
// kAutoDenseMaxFreeNodes (and within denseMemoryLimitBytes); above, capacitance, or, when the
// matrix changes in most frames (cuts: a removal updates it in the frame), downdate up to
// kAutoDowndateMaxFreeNodes and pcg above.
ElectricStrategy resolveElectricStrategy(const ElectricSolverOptions& options, double freeNodes,
                                         bool cuts = false);
// Measured on the cut, physics per frame (esim bench cut --strategy update --set
// solvers.electric.strategy=S, README "The cut"): at 1012 nodes (863 free) the dense
// inverse's update (one rank-s dgemm) gave a p95 of 1.9-2.4 ms against 2.4-3.9 ms for
// capacitance (five alternating pairs; its Woodbury term and factor adoption cost 1-4 ms
// there); at 1500, 2002 and 2976 nodes the dense inverse was ahead in median and p95 (2976:
// 3.5 / 9.3-9.8 ms against 3.7-4.0 / 11.2-12.2 ms); at 3996 nodes its update (2 n_f^2 s
// flops at every removal) made the median 16-17 ms against 9.5-9.8 ms. Since the structural
// update was vectorized (ldl_updown.h), capacitance's update of the large removals (a
// refactorization in the frame when its Woodbury term misses its check) set the p95 above
// that: pcg against capacitance (--strategy update --set solvers.electric.strategy=S, two
// alternating pairs each; the same tets removed): 3996 nodes (--frames 90) median 9.6-9.8
// against 8.1-8.4 ms, p95 10.9-11.1 against 30.5-32.0 ms; 5040 nodes 14.1-14.4 against
// 13.7-14.0 ms, p95 19.1-19.2 against 42.3-48.4 ms; 8000 nodes (--frames 60, one run each)
// 28.6 / 39.2 against 29.5 / 107 ms; liver_incision (esim run, video) 88 s against 114 s, peak
// memory 1.2 against 2.8 GB. So auto takes pcg above kAutoDenseMaxFreeNodes for a cut; scenes
// whose matrix stays (no rupture, or a rebuild mode that refactorizes) keep capacitance.
inline constexpr double kAutoDenseMaxFreeNodes = 3000;
// Downdate against pcg on the cut (esim bench cut --strategy update --electric pcg,downdate
// [--stages], side by side in one run; the same tets removed, the power within 2e-14): 3996
// nodes (3596 free, two rounds) median 4.2-4.5 against 5.0 ms, p95 7.6-7.8 against 7.8-8.2 ms;
// 8000 (7200 free; two rounds of 120 frames, one of 60) median 14.6-17.8 against 16.1-18.2 ms,
// p95 24.9-35.7 against 29.8-36.2 ms, the potential's median 1.7 against 6.1 ms; 12000 (60
// frames) median 35.6 either, p95 54.1 against 50.5 ms; 14040 (two rounds) median 36.2-39.4
// against 39.8-42.4 ms, p95 71-74 against 54-55 ms; 20130 median 72.7 against 80.3 ms, p95 162
// against 148 ms. Above ~10 000 free nodes the frames where the blade enters (20-30 contact
// nodes, each a new column after every removal, ~1 ms a column at 14k nodes) cost more than
// pcg's iterations: auto took downdate for a cut up to 9000 free nodes. Since the contacts'
// columns became paths up the elimination tree, solved in one pass, with one backward solve
// for the potential (electric_downdate.cpp; tools/contact_path_study, 24 contacts, the
// solver's own solve: 2.5 ms at 8000 nodes, 8.3 at 20 130, 13.7 at 26 928, against 15.0, 101
// and 100 ms for the columns in blocks of 4), downdate against pcg (esim bench cut --sizes
// 12000,14040,20000 --frames 60 --strategy update --electric pcg,downdate --repeat 2; the
// same tets removed): median 35.8-37.1 against 38.9-40.5 ms at 12 000 nodes, 38.2-38.8
// against 44.6-45.5 at 14 040, 66.3-67.9 against 73.4-75.5 at 20 130 (19 004 free); p95
// 60.0-60.2 against 49.8-63.0, 56.6-68.5 against 55.7-58.3, 109.8-122.8 against 113.7-152.7
// ms; the potential's median at 20 130 nodes 8.4-9.6 against 26.8-28.0 ms; 49 966 nodes
// (47 753 free; --sizes 50000 --frames 30, three rounds) median 221-265 against 283-326 ms, p95
// 533-601 against 560-623 ms, the potential's median 22 against 71 ms, the CPU 561 against 636
// ms a frame. liver_incision (27 908 nodes; esim run -q --set output.png_every=60, two
// alternating pairs): its frame loop 19.5 / 20.5 s against 21.2 / 21.4 s, the same 9822 tets
// removed, 66 MB more memory; its factor's updates cost more (37 against 26 ms a removal) than
// the potential gains (16-19 against 44-48 ms, median) only in part. 100 170 nodes (96 709
// free; esim bench cut --sizes 100000 --frames 20 --strategy update --electric pcg,downdate
// --stages, one run, 2026-12-07): median 1146 against 1238 ms, p95 3289 against 3418 ms, the
// potential's median 84 against 332 ms (its factor's update 118 against 57 ms a removal), the
// CPU 2741 against 2816 ms a frame, the same 3977 tets removed. 149 940 nodes (145 488 free;
// the same command at --sizes 150000, one run, 2026-12-07, a later session, pcg's update in
// place by then): median 2303 against 2392 ms, p95 6048 against 5965 ms, the potential's
// median 104 against 477 ms (its factor's update 195 against 2.5 ms a removal, p95 778
// against 4.4), the CPU 5194 against 5373 ms a frame, the same 5824 tets removed, a peak of
// 8.6 GB. 200 376 nodes (194 944 free; --sizes 200000, one run, the session after, 6 min
// 45 s, a peak of 12.7 GB): median 4809 against 5100 ms, p95 10 994 against 12 015 ms, the
// potential's median 214 against 922 ms (its factor's update 382 against 1.1 ms a removal),
// the CPU 10 081 against 10 199 ms a frame (the structural update 4.6 s a removal either
// way), the same 7646 tets removed. So auto takes downdate for a cut up to 200 000 free
// nodes (the largest measured rounded up, as 47 753 was to 50 000, 96 709 to 100 000 and
// 145 488 to 150 000; downdate's margin in CPU 2.7 % at 96 709 free nodes, 3.3 % at 145 488,
// 1.2 % at 194 944); pcg above, with less memory. 250 275 nodes (244 036 free; --sizes
// 250000, one run, the same session, 9 min 22 s, a peak of 17.4 GB): the CPU 13 273 against
// 13 334 ms a frame (0.5 %), median 4892 against 5161 ms, p95 16 048 against 15 726 ms, the
// potential's median 245 against 1107 ms, its factor's update 511 against 1.3 ms a removal,
// the same 9224 tets: a tie, so the crossing lies between the two sizes and the bound stays.
inline constexpr double kAutoDowndateMaxFreeNodes = 200000;

struct ElectricSolveStats {
  bool refactored = false;   // refactor: the matrix was factorized in this solve
  int newColumns = 0;        // capacitance, downdate: columns computed in this solve
  int iterations = 0;        // pcg: iterations
  double residual = 0;       // pcg: relative residual reached
  int regionNodes = 0;       // local: nodes solved in this frame (all free nodes in a full solve)
  double farFieldScale = 1;  // local: the held far field's scale (energy minimum) this frame
  // local with localCheck: u'Ku / u*'Ku* - 1 against a full solve u* of the same frame (the
  // Joule power's relative excess, >= 0 to the solves' tolerance); -1 when not measured
  double powerError = -1;
};

// what updateMatrix did
struct ElectricUpdateStats {
  bool fellBack = false;       // a full setMatrix was done instead
  std::string fallbackReason;  // why (empty when updated in place)
  int changedNodes = 0;        // free nodes whose row of K_ff changed (still free)
  int droppedNodes = 0;        // free nodes that left the free set (floating or grounded)
  int rank = 0;                // capacitance, dense-inverse, downdate: rank of the change applied
  bool adoptedFactor = false;  // capacitance: took the factor computed on a thread since the
                               // last update (of the matrix then; see electric_capacitance.cpp)
  bool refactored = false;     // capacitance: the factor was recomputed numerically (same
                               // ordering): the change or the Woodbury term was too large
                               // to pay, or the accuracy check after the update failed
  bool refined = false;        // capacitance, Woodbury: the term missed the accuracy check
                               // alone; its solves now take one refinement step each
  int columnsCorrected = 0;    // capacitance: cached columns kept, corrected on next use
  int columnsDropped = 0;      // capacitance: cached columns dropped (node left the free
                               // set, or correcting them would cost more than solving again);
                               // downdate: every column (an update drops them all)
};

class ElectricSolver {
 public:
  virtual ~ElectricSolver();
  // K: n x n stiffness of the whole mesh (conductivity inside); grounded: sorted ids
  // held at 0 V (at least one). Pre-processing. Throws Error on bad input.
  virtual void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) = 0;
  // K changed a little since the last setMatrix/updateMatrix (elements removed by a cut):
  // the same result as setMatrix(K, grounded) at the cost of the change (see "Matrix
  // updates" above). The default is setMatrix (stats.fellBack). Capacitance: afterwards
  // call setContactCandidates with the new surface (cache and patches are kept, the new
  // candidates get patches) and prefetch the newly exposed nodes the tool may touch, so
  // their columns are solved here and not in the frame loop.
  // changedNodes: sorted, every node whose column of K may differ from the K of the last
  // setMatrix/updateMatrix (a cut: the nodes of the removed elements; nodes that only joined or
  // left `grounded` need not be listed), or nullptr: any column may have changed. A list that
  // misses a changed column gives a wrong matrix: it is the caller's to keep.
  virtual ElectricUpdateStats updateMatrix(const SparseMatrix& K, const std::vector<int>& grounded,
                                           const std::vector<int>* changedNodes);
  ElectricUpdateStats updateMatrix(const SparseMatrix& K, const std::vector<int>& grounded) {
    return updateMatrix(K, grounded, nullptr);
  }
  // contact: sorted ids held at voltageV (disjoint from grounded, else Error "short
  // circuit"); potential: size n, in: warm start (pcg), out: the solution.
  // Empty contact -> potential 0 everywhere.
  virtual ElectricSolveStats solve(const std::vector<int>& contact, double voltageV,
                                   Eigen::VectorXd& potential) = 0;
  // precompute what solves for these contact nodes need (capacitance: their columns;
  // others: nothing). Lets a caller spend idle time on nodes the tool will touch.
  virtual void prefetch(const std::vector<int>& /*nodes*/) {}
  // the nodes the tool can touch (the surface nodes); capacitance groups them into
  // patches solved together (see electric_capacitance.cpp); others ignore it. Kept
  // across setMatrix, which rebuilds every patch; call again after the surface changes:
  // between setMatrix calls, candidates already in a patch keep it, new ones are grouped
  // into new patches and the column cache is kept.
  virtual void setContactCandidates(const std::vector<int>& /*nodes*/) {}
  // node positions [m], one per node of K (local: its region is a distance from the
  // contacts; the others ignore them). Call before the first solve.
  virtual void setNodePositions(const std::vector<Vec3>& /*positionsM*/) {}
  // bytes held by factorizations, inverses, caches
  virtual double memoryBytes() const = 0;
  // caps the cache of solved data (capacitance's columns) at `bytes` from now on (at least
  // one column), evicting the least recently used columns now; returns the bytes of columns
  // given back (0 for solvers without a cache). The results do not change, only the time
  // (columns evicted are solved again when the tool comes back).
  virtual double limitCache(double /*bytes*/) { return 0; }
  virtual const char* name() const = 0;
};

std::unique_ptr<ElectricSolver> makeElectricSolver(const ElectricSolverOptions& options);

// sets the OpenBLAS thread count (CHOLMOD supernodal and dense BLAS calls)
void setBlasThreads(int threads);
// lowers the calling thread's scheduling priority (Linux nice +10; elsewhere nothing): for
// work done ahead of need (column prefetch, the next factor), so that on few cores it yields
// to the frame loop and to the structural update the next frame waits for (measured, bench
// cut --sizes 1013 --strategy update, four alternating pairs: p95 4.5-5.6 ms against
// 5.5-5.8 ms without)
void deprioritizeThisThread();

// ---- shared internals of the strategies (sim/electric_solver.cpp) ----
namespace electric_detail {

// the node classes of one (K, grounded) pair, see the header comment
struct NodeClasses {
  int n = 0;
  std::vector<int> freeNodes;            // sorted node ids of the free nodes
  std::vector<int> freeIndex;            // node -> index in freeNodes, -1 if not free
  std::vector<std::uint8_t> isGrounded;  // per node
  std::vector<int> grounded;             // the grounded ids, sorted

  // throws Error for a non-square K, a non-finite entry, empty/unsorted/out-of-range grounded;
  // towardGround (optional): per node the node its breadth-first search from the grounded
  // nodes reached it from (-1: grounded or not reached), a spanning forest of the free nodes
  void build(const SparseMatrix& K, const std::vector<int>& grounded,
             std::vector<int>* towardGround = nullptr);
  // checks contact (sorted, in range, not grounded) and returns the free indices of
  // its free nodes (floating ones dropped), ascending
  std::vector<int> contactFreeIndices(const std::vector<int>& contact) const;
  int numFree() const { return static_cast<int>(freeNodes.size()); }
};

// Forgets the node classes (NodeClasses or CurrentClasses) if setMatrix throws, so that a
// failed setMatrix leaves the solver unusable ("setMatrix must be called before solve")
// instead of half-built.
template <class Classes>
class ResetOnThrow {
 public:
  explicit ResetOnThrow(Classes& classes)
      : classes_(classes), exceptions_(std::uncaught_exceptions()) {}
  ~ResetOnThrow() {
    if (std::uncaught_exceptions() > exceptions_) classes_ = Classes{};
  }

 private:
  Classes& classes_;
  int exceptions_;
};

// K restricted to the free nodes (both triangles), compressed
SparseMatrix restrictToFree(const SparseMatrix& K, const NodeClasses& classes);

// ---- the base index space of updateMatrix ----
// Base indices are the free indices of the last setMatrix. A node that leaves the free
// set later keeps its base index with an identity row and column (value 1 on the
// diagonal, 0 elsewhere), so the base matrix keeps its size and pattern.

// The classes now, in the base index space: edited in place by each update, so that a
// change costs what it changes (a compact numbering of the free nodes now would be renumbered
// whole when one leaves)
struct CurrentClasses {
  int n = 0;
  std::vector<int> freeIndex;            // node -> its base index while free, -1 otherwise
  std::vector<std::uint8_t> isGrounded;  // per node
  std::vector<int> grounded;             // the grounded ids, sorted
  int freeCount = 0;                     // free nodes now
  int numFree() const { return freeCount; }
};

// the difference between a new (K, grounded) and a FreeBase's current matrix
struct BaseChange {
  std::vector<int> grounded;                  // the new grounded ids, sorted
  std::vector<int> groundJoined, groundLeft;  // nodes joining / leaving the ground, ascending
  std::vector<int> positions;  // the base matrix's entries (storage positions) whose bits change
  std::vector<double> values;  // ... their new values
  std::vector<int> dropped;    // base indices leaving the free set now (floating or grounded),
                               // ascending
  std::vector<int> touched;    // base indices staying free whose row changes, ascending
  SparseMatrix delta;          // new - current base matrix (both triangles, changed entries)
  std::string fallback;        // non-empty: cannot be applied in place (why)
  bool empty() const { return dropped.empty() && delta.nonZeros() == 0; }
};

struct FreeBase {
  NodeClasses base;                  // classes at the last setMatrix
  CurrentClasses current;            // classes now (free nodes: a subset of base's)
  SparseMatrix matrix;               // current K_ff in base indices (both triangles)
  std::vector<std::uint8_t> active;  // base index -> still free
  // the spanning forest of the last set (NodeClasses::build's towardGround), its paths mended
  // by diff where a removal broke them: only a guide, diff checks every path it follows
  // against K; and diff's scratch (per node: its class in this diff, the last walk through
  // it; per base index: a position in a column)
  mutable std::vector<int> towardGround, mark, walked, position;
  mutable int epoch = 0, walks = 0;

  // setMatrix: classes and K_ff (throws Error on bad input)
  void set(const SparseMatrix& K, const std::vector<int>& grounded);
  // the change to (K, grounded); throws Error on bad input. changed == nullptr: O(nnz(K) +
  // nnz(matrix)). Else (sorted, see ElectricSolver::updateMatrix) the same change from the
  // columns of the changed nodes and their neighbours, the ground's change, and the forest
  // (towardGround) checked from the changed nodes: O(the change x the forest's depth), but
  // for the delta's column index, sized to the base (one O(m) pass: finishChange); the
  // O(nnz) way when a changed column joins a node outside the free set
  // to the rest, a node leaving the ground keeps an element, or the search grows past a
  // quarter of nnz(K). apply: O(the change) (current is edited in place)
  BaseChange diff(const SparseMatrix& K, const std::vector<int>& grounded,
                  const std::vector<int>* changed = nullptr) const;
  BaseChange diffAll(const SparseMatrix& K, const std::vector<int>& grounded) const;
  // diff from the changed nodes; false: the O(nnz) way is needed (ch is then undefined)
  bool diffNear(const SparseMatrix& K, const std::vector<int>& grounded,
                const std::vector<int>& changed, BaseChange& ch) const;
  // the new values of the base matrix's column j; stays(b): base index b stays free
  template <class Stays>
  void newColumn(const SparseMatrix& K, int j, const Stays& stays, std::vector<double>& column,
                 std::string& fallback) const;
  static void finishChange(int m, std::vector<Eigen::Triplet<double>>& delta,
                           std::vector<int>& touched, BaseChange& ch);
  // adopts a change without a fallback reason
  void apply(const BaseChange& change);
  // the base indices of contact's free nodes now (ascending; floating ones dropped); checks
  // contact as NodeClasses::contactFreeIndices does
  std::vector<int> contactBaseIndices(const std::vector<int>& contact) const;
  // ... and, when none of the contact is free (empty, or only floating nodes), the solve's whole
  // answer: potential set to 0 (size n). An internal error before the first set.
  std::vector<int> contactsOrZero(const std::vector<int>& contact,
                                  Eigen::VectorXd& potential) const;
  // scatterPotential for base values (nodes no longer free: 0)
  void scatter(const Eigen::VectorXd& baseValues, const std::vector<int>& contactBase,
               double voltageV, Eigen::VectorXd& potential) const;
  int size() const { return base.numFree(); }
  // ||K' Y - I_:rows||_F / sqrt(s), K' the current matrix: the relative residual of Y as the
  // solutions of the s unit right-hand sides on `rows` (the check after updateMatrix)
  double identityResidual(const std::vector<int>& rows, const Eigen::MatrixXd& y) const;
};

// u = Z_:c f with Z_cc f = (voltageV, ..., voltageV): the potential on the free (base) indices
// from the columns z[k] = K_ff^-1 e_cf[k] of the contact nodes cf (nf entries each); throws
// Error naming `what` when Z_cc is not positive definite
void combineColumns(const std::vector<const double*>& z, const std::vector<int>& cf,
                    double voltageV, int nf, const char* what, Eigen::VectorXd& u);

// The update of a strategy whose own part is the matrix's change alone (refactor, pcg): the
// change to (K, grounded) into `change`; where it cannot be taken in place, setMatrix() and
// the stats say why (fellBack); else adopted by `free`, with its counts
ElectricUpdateStats updateFreeBase(FreeBase& free, const SparseMatrix& K,
                                   const std::vector<int>& grounded,
                                   const std::vector<int>* changedNodes, BaseChange& change,
                                   const std::function<void()>& setMatrix);

// scatters free values into a full-size potential (fixed and floating nodes: 0,
// contact: voltage)
void scatterPotential(const NodeClasses& classes, const Eigen::VectorXd& freeValues,
                      const std::vector<int>& contactFree, double voltageV,
                      Eigen::VectorXd& potential);

// A_ff with the rows/columns of `contactFree` replaced by the identity (pattern kept,
// values rewritten in place from Kff), and the right-hand side b (b_c = V, b_o =
// -K_oc V). `A` must have Kff's pattern.
void dirichletSystem(const SparseMatrix& Kff, const std::vector<int>& contactFree, double voltageV,
                     SparseMatrix& A, Eigen::VectorXd& b);

// RAII supernodal LL^T factorization with CHOLMOD (int indices, double)
class CholmodFactor {
 public:
  CholmodFactor();
  ~CholmodFactor();
  CholmodFactor(const CholmodFactor&) = delete;
  CholmodFactor& operator=(const CholmodFactor&) = delete;
  // symbolic analysis (fill-reducing ordering) of a symmetric matrix (lower part used)
  void analyze(const SparseMatrix& A);
  // ... with a given fill-reducing ordering (ordering() of a factor of a matrix with A's
  // pattern): no ordering is computed, the same factor comes out (empty: as above)
  void analyze(const SparseMatrix& A, const std::vector<int>& ordering);
  // the fill-reducing permutation of the analysis (empty before one)
  std::vector<int> ordering() const;
  // numeric factorization; throws Error naming `what` if A is not positive definite
  void factorize(const SparseMatrix& A, const char* what);
  // x = A^-1 b for `ncols` column-major right-hand sides of length n
  void solve(const double* b, double* x, int ncols = 1);
  // x = P' L'^-1 D^-1 y (simplicial LDL' only): the backward half of a solve, y = L^-1 P b given
  // in L's row order (ldlSolveBackward; one thread)
  void solveBackward(const double* y, double* x);
  int size() const;
  double memoryBytes() const;
  bool factorized() const { return factorized_; }
  // ---- in-place modification (CHOLMOD Modify; the factor becomes simplicial LDL') ----
  // converts a supernodal LL' factor to simplicial LDL' (O(nnz(L)), no refactorization)
  void toSimplicial();
  bool isSupernodal() const;
  // A -> A with row and column i (an index of A, not of the permuted L) set to e_i
  void deleteRow(int i);
  // A -> A + C C^T (update) or A - C C^T (downdate); C: n x r, rows are indices of A (the
  // vectorized kernel of ldl_updown.h for the columns that do not fill in L)
  void updateDowndate(bool update, const SparseMatrix& C);
  // A -> A with the rows and columns `indices` (of A) set to the identity, in one update
  // (ldlTakeRows); A: the matrix factorized (its pattern: where L's rows may hold entries, so
  // only while no update has filled in L: capacitance's Downdate mode, whose eigenvector columns
  // do, deletes its rows one by one with deleteRow). False, the factor unchanged, when a pivot
  // of those rows is not positive.
  bool deleteRows(const std::vector<int>& indices, const SparseMatrix& A);
  // simplicial LDL': every pivot D_jj finite and > 0
  bool pivotsPositive() const;
  // stored entries of L (a solve costs about 4 flops per entry per right-hand side)
  double factorEntries() const;
  // the CHOLMOD factor itself, to read (e.g. a simplicial one's L, D and Perm through
  // cholmod_view.h's SimplicialView); an internal error before an analysis
  const cholmod_factor_struct& cholmod() const;
  // flops of one numeric factorization (from the symbolic analysis)
  double factorizeFlops() const { return factorizeFlops_; }
  void swap(CholmodFactor& other);  // exchanges the two factors (and their workspaces)

 private:
  struct Impl;
  Impl* impl_;
  bool factorized_ = false;
  double factorizeFlops_ = 0;
};

// the strategies (one file each)
std::unique_ptr<ElectricSolver> makeRefactorSolver(const ElectricSolverOptions& options);
std::unique_ptr<ElectricSolver> makeDenseInverseSolver(const ElectricSolverOptions& options);
std::unique_ptr<ElectricSolver> makeCapacitanceSolver(const ElectricSolverOptions& options);
std::unique_ptr<ElectricSolver> makePcgSolver(const ElectricSolverOptions& options);
std::unique_ptr<ElectricSolver> makeLocalSolver(const ElectricSolverOptions& options);
std::unique_ptr<ElectricSolver> makeDowndateSolver(const ElectricSolverOptions& options);

}  // namespace electric_detail
}  // namespace esim
