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
  mutable Eigen::VectorXd coarseRhs_, coarseW_, coarseSolution_;  // scratch of apply
  bool ready_ = false;
};

}  // namespace esim
