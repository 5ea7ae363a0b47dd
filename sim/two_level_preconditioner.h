// A two-level preconditioner for conjugate gradients on a P1 Laplacian (the electric
// potential's reduced system): l1-Jacobi smoothing on the fine level, and a coarse
// correction on aggregates of nodes, solved exactly.
//
// Jacobi-preconditioned CG needs O(1/h) iterations: its residual's smooth part (the far
// field, which shifts with each frame's contact set and the current through it) decays one
// element a sweep. The coarse level removes that part in one step. Its space Z holds one
// piecewise-constant column per aggregate, a connected group of nodes, taken greedily from
// the matrix graph ("unsmoothed aggregation", Vanek, Mandel and Brezina 1996). Each
// aggregation pass groups a node with its neighbours (about 10-15 nodes); a second pass
// groups the first pass's aggregates the same way. The coarse matrix E = Z' A Z is sparse
// and factored by a sparse LDL'.
//
// One application, z = M^-1 r, is the balancing Neumann-Neumann form (Mandel 1993; Tang,
// Nabben, Vuik and Erlangga 2009 compare it with deflation):
//   M^-1 = P' S P + Q,   Q = Z E^-1 Z',   P = I - A Q,   S = diag(1 / sum_j |a_ij|)
// computed as w = E^-1 Z' r, t = S (r - (A Z) w), v = E^-1 (A Z)' t, z = t + Z (w - v):
// two coarse solves and two products with the sparse n x m matrix A Z (about a third of
// A's entries), no product with A itself. M is symmetric positive definite for any SPD A
// and S (CG stays CG); l1-Jacobi (Baker, Falgout, Kolev and Yang 2011) needs no damping
// factor whatever the mesh's angles. The coarse level takes the smooth part of the error,
// so the iterations barely grow as the mesh is refined. Measured on slab_cut against a
// symmetric V-cycle (Jacobi, coarse, Jacobi: two products with A), the same coarse space:
// 55 against 40 iterations, 7.6 against 9.2 ms a solve.
// pcg runs it in its deflated form, A-DEF2 (applyDeflated, one coarse solve and one product
// with (A Z)' an application), from deflate's start: there every residual CG makes has
// Z' r = 0, where the two forms are the same operator, so the iterates are BNN's to rounding
// (Tang et al. 2009, the equivalence of BNN and A-DEF2 for that start). Measured on the graded
// slab_cut mesh, a blade's contacts moving 0.33 mm a frame, 20 frames warm-started (a
// throw-away harness, since removed): 35.6 iterations either way at 49 966 nodes, 24.2 against
// 32.9 ms a solve; 13.6 iterations, 1.31 against 1.60 ms at 8000. (A smoothed-aggregation
// multigrid V-cycle measured in the same harness halved the iterations, 18.2, but took
// 35.5 ms a solve and 180 ms to build, which a cut would pay after every removal.)
//
// Rows excluded from the coarse space (the contact nodes, whose rows of A are the identity)
// are left to the smoother. The aggregates depend on the matrix's graph only; setMatrix is
// called again after a cut (the pattern changed), compute for every new set of excluded
// rows (the coarse matrix's assembly and factorization, O(nnz(A)) plus a small sparse LDL').
// Deterministic (no threads, fixed order). Not thread-safe: one cycle's scratch is a member.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <vector>

#include "sim/fem_p1.h"

namespace esim {

class TwoLevelPreconditioner {
 public:
  // aggregates of the graph of K (n x n, symmetric pattern, both triangles stored),
  // `passes` aggregation passes (1: ~10-15 nodes each, 2: ~100-200); throws Error for
  // passes outside [1, 3]. The graph of the last call again costs one comparison. compute
  // must follow either way.
  void setGraph(const SparseMatrix& K, int passes);

  // smoother and coarse matrix of A (the pattern of setGraph's K, both triangles), the rows
  // `excluded` (ascending or not) out of the coarse space; throws Error when the coarse
  // matrix cannot be factored (A not positive definite)
  void compute(const SparseMatrix& A, const std::vector<int>& excluded);

  // z = M^-1 r (r of size n)
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const;

  // The cheaper form of the same preconditioner (A-DEF2, Tang et al. 2009): one coarse solve
  // and one product with (A Z)' an application,
  //   z = S r + Z E^-1 (Z' r - (A Z)' S r)   (M^-1 = P' S + Q),
  // equal to apply's P' S P r + Q r on every residual with Z' r = 0, which conjugate
  // gradients keep (A P' = P A) once they start from deflate's x. Not symmetric off that
  // subspace, so only for CG started by deflate.
  void applyDeflated(const Eigen::VectorXd& r, Eigen::VectorXd& z) const;
  // x += Q (b - A x): the start whose residual has no coarse component (Z' r = 0); A is
  // compute's matrix
  void deflate(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) const;

  int numAggregates() const { return numAggregates_; }
  // aggregate of each row (setGraph's), -1 for none
  const std::vector<int>& aggregateOf() const { return aggregateOf_; }
  bool ready() const { return ready_; }
  // bytes held (aggregates, A Z, the coarse matrix and its factor, scratch)
  double memoryBytes() const;

 private:
  std::vector<int> graphOuter_, graphInner_;  // setGraph's graph (a repeat is skipped)
  int passes_ = 0;
  std::vector<int> aggregateOf_;  // setGraph's aggregates
  std::vector<int> coarseOf_;     // compute's: aggregateOf_ with excluded rows -1
  int numAggregates_ = 0;
  Eigen::VectorXd smoother_;          // 1 / sum_j |a_ij|
  std::vector<int> azOuter_, azRow_;  // A Z (n x m) by columns: setGraph's pattern
  std::vector<double> azValue_;       // and compute's values
  SparseMatrix e_;                    // E = Z' A Z, lower triangle
  std::vector<int> azSlot_, eSlot_;   // per entry of A: its place in az_ and e_ (-1: upper)
  std::vector<int> eDiagonal_;        // place of E(a, a)
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::AMDOrdering<int>> coarse_;
  mutable Eigen::VectorXd coarseRhs_, coarseW_, coarseSolution_;        // scratch of apply
  void restrictToCoarse(const Eigen::VectorXd& r) const;                // coarseRhs_ = Z' r
  void subtractAzTransposed(const Eigen::VectorXd& z) const;            // coarseRhs_ -= (A Z)' z
  void prolongAdd(const Eigen::VectorXd& w, Eigen::VectorXd& z) const;  // z += Z w
  bool ready_ = false;
};

}  // namespace esim
