// structural_coarse.h - the coarse space of the structural phase's coarse solve method
// (StructuralSolveMethod::coarse, see structural.h): trilinear (Q1) displacements on a
// uniform grid of hexahedral cells over the mesh's bounding box, interpolated to the fine
// nodes, and the Galerkin coarse stiffness
//   K_c = P_h' K P_h   (3 m x 3 m, m grid nodes),
// P the interpolation (fine node i in cell c at local coordinates (x, y, z) in [0, 1]^3
// gets u_i = sum_k w_k u_c[k], w_k the 8 trilinear weights, per component), P_h the same
// with the rows of held fine components zeroed (the coarse functions vanish where the
// fine ones are held). The coarse solution u = P_h K_c^-1 P_h' f is the best fit to the
// fine solution in the energy norm among the coarse functions (Galerkin); a grid of half
// the spacing (cells split in 8) holds the coarser grid's functions, so its energy error
// is no larger (a test checks it).
// Grid nodes none of whose cells holds a free fine node span nothing (their column of
// P_h is 0): they are identity rows of the factorized matrix and solve to 0. Columns
// that are dependent on the fine nodes (a cell the mesh barely enters, or emptied by a
// cut: a trilinear function zero at its few free nodes) make K_c singular in directions P_h
// maps to 0; the factorized matrix is K_c + eps diag(K_c) (eps = kRegularization, x100 until
// CHOLMOD finds it positive definite), and kRefinementSteps steps of iterative refinement
// against K_c take the regularization out of P_h u (but in directions P_h maps to ~0).
// Removals keep K_c up to date by each tet's contribution P_e' K_e P_e (3 x the distinct
// grid nodes of its 4 nodes' cells, squared): subtracted for a removed tet, subtracted and
// added back under the new mask for a tet at a node newly held; the numeric factorization
// is then redone (the analysis is kept: the pattern only loses entries).
// Not thread-safe (its CHOLMOD workspace is a member); deterministic.
#pragma once

#include <cholmod.h>

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "sim/fem_p1.h"
#include "sim/mesh_tet.h"

namespace esim {

class CoarseSpace {
 public:
  // the grid over the bounding box of `nodes`, cells of at most spacingM along each axis
  // (at least one cell per axis); spacingM 0: the finest spacing of 0.97^k times the box's
  // longest side whose grid has at most kAutoGridNodes nodes. Throws esim::Error on a
  // spacing < 0 or a grid of more than kMaxGridNodes nodes (name a larger spacing)
  CoarseSpace(const std::vector<Vec3>& nodes, double spacingM);
  ~CoarseSpace();
  CoarseSpace(const CoarseSpace&) = delete;
  CoarseSpace& operator=(const CoarseSpace&) = delete;

  static constexpr int kMaxGridNodes = 300000;
  // the automatic grid's size: K_c's numeric refactorization at each removal costs 6-19 ms
  // with slab_cut's 273 grid nodes (5 mm) at 50k nodes, 37-47 ms with 1155 (3 mm) at 8000; a
  // 5 mm grid over the liver's box (~11 000 nodes) took 1.2-1.4 s a removal
  static constexpr int kAutoGridNodes = 300;
  static constexpr double kRegularization = 1e-6;  // relative to the diagonal (x100 if needed)
  static constexpr int kRefinementSteps = 3;

  // K_c = P_h' K P_h, K given as the lower triangle of the stiffness over all 3n fine dofs
  // (entries of held dofs ignored), held per fine dof (1: held at 0); analysis and
  // factorization. Throws esim::RunError when CHOLMOD fails
  void build(const SparseMatrix& lowerK, const std::uint8_t* held);
  // K_c += sign P_e' K_e P_e for a tet's 4 nodes and its 12 x 12 stiffness K_e (node-major
  // x, y, z), the fine dofs for which heldAt(dof) is true taken as held; the factorization is
  // redone at the next solve
  template <class Held>
  void addTet(const Tet& tet, const Eigen::Matrix<double, 12, 12>& ke, double sign,
              const Held& heldAt);
  // u = P_h K_c^-1 P_h' f (3n fine dofs each; u 0 on the held ones)
  void solve(const Eigen::VectorXd& f, const std::uint8_t* held, Eigen::VectorXd& u);

  bool needsFactorization() const { return dirty_; }  // K_c changed since it was factorized
  int numGridNodes() const { return gridNodes_; }
  const std::array<int, 3>& cells() const { return cells_; }
  double spacingM() const { return spacing_; }  // the cells' size bound (given or automatic) [m]
  double lastFactorSeconds() const { return factorSeconds_; }  // of the last factorization [s]

 private:
  void addEntry(int row, int col, double value);  // lower triangle, row >= col, in the pattern
  void factorize();
  void solveFactor(const Eigen::VectorXd& b);

  std::array<int, 3> cells_{};
  double spacing_ = 0;
  int gridNodes_ = 0;
  // per fine node: its 8 grid nodes and trilinear weights
  std::vector<std::array<int, 8>> gridOf_;
  std::vector<std::array<double, 8>> weightOf_;
  SparseMatrix kc_;            // K_c, lower triangle (3 m x 3 m)
  std::vector<double> diag0_;  // its diagonal at build(): what "spans nothing" is against
  SparseMatrix work_;          // the matrix factorized (dead rows identity, regularized)
  std::vector<std::uint8_t> dead_;
  std::vector<double> regularization_;  // added to work_'s diagonal
  bool dirty_ = true;                   // kc_ changed since the factorization
  cholmod_common common_;
  cholmod_factor* factor_ = nullptr;
  cholmod_dense *x_ = nullptr, *y_ = nullptr, *e_ = nullptr;
  Eigen::VectorXd fc_, uc_;
  double factorSeconds_ = 0;
};

template <class Held>
void CoarseSpace::addTet(const Tet& tet, const Eigen::Matrix<double, 12, 12>& ke, double sign,
                         const Held& heldAt) {
  // the distinct grid nodes of the tet's nodes, and P_e (12 x 3 k) by them
  std::array<int, 32> grid;
  int k = 0;
  std::array<std::array<int, 8>, 4> slot;
  for (int i = 0; i < 4; ++i)
    for (int c = 0; c < 8; ++c) {
      const int g = gridOf_[tet[i]][c];
      int s = 0;
      while (s < k && grid[s] != g) ++s;
      if (s == k) grid[k++] = g;
      slot[i][c] = s;
    }
  Eigen::Matrix<double, 12, 96> p = Eigen::Matrix<double, 12, 96>::Zero();
  for (int i = 0; i < 4; ++i)
    for (int a = 0; a < 3; ++a) {
      if (heldAt(3 * tet[i] + a)) continue;
      for (int c = 0; c < 8; ++c) p(3 * i + a, 3 * slot[i][c] + a) += weightOf_[tet[i]][c];
    }
  const Eigen::MatrixXd kp = ke * p.leftCols(3 * k);
  const Eigen::MatrixXd pkp = p.leftCols(3 * k).transpose() * kp;
  for (int s = 0; s < k; ++s)
    for (int a = 0; a < 3; ++a)
      for (int r = 0; r < k; ++r)
        for (int b = 0; b < 3; ++b) {
          const int row = 3 * grid[r] + b, col = 3 * grid[s] + a;
          if (row >= col && pkp(3 * r + b, 3 * s + a) != 0)
            addEntry(row, col, sign * pkp(3 * r + b, 3 * s + a));
        }
  dirty_ = true;
}

}  // namespace esim
