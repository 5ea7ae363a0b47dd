// structural.h - linear thermo-elastic P1 tetrahedra loaded by a volumetric eigenstrain:
// the stress that the expansion of the tissue's water (liquid, then vapour) causes.
//
// Small strain, isotropic linear elasticity (Young's modulus E [Pa], Poisson's ratio nu):
//   sigma = D (eps(u) - eps*),   eps* = (e_v / 3) I   per tet,
// e_v the tet's volumetric expansion (dV / V, the paper's Delta v_liq + Delta v_gas).
// P1 displacements (3 components per node, constant strain per tet); equilibrium
//   K u = f,   K = sum_e V_e B_e^T D B_e,   f = sum_e V_e B_e^T D eps*_e,
// with listed displacement components (Support) held at 0. K depends on the mesh,
// E, nu and the supports only: it is factorized once (CHOLMOD) at construction and
// every solve() is a right-hand side and two triangular solves.
// Removed tets (alive == 0) contribute nothing; a node left without an alive tet is
// held at 0 so that K stays positive definite.
// Per tet after solve(): Cauchy stress in Voigt order (xx, yy, zz, yz, xz, xy) [Pa]
// and its von Mises stress [Pa]. Displacement: 3 per node (x0, y0, z0, x1, ...) [m].
// The supports must remove the rigid motions (at least 6 independent components,
// e.g. a clamped face); otherwise the constructor throws esim::Error.
#pragma once

#include <Eigen/Core>
#include <array>
#include <memory>
#include <vector>

#include "sim/mesh_tet.h"

namespace esim {

struct StructuralOptions {
  double youngsModulusPa = 4.75e4;  // E (paper Table 1)
  double poissonRatio = 0.4;        // nu in [0, 0.5) (paper Table 1)
};

// one displacement component held at 0
struct Support {
  int node = 0;
  int axis = 0;  // 0 x, 1 y, 2 z
};

using VoigtStress = std::array<double, 6>;  // xx, yy, zz, yz, xz, xy [Pa]

// von Mises stress of a Voigt stress [Pa]
double vonMises(const VoigtStress& s);

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
  // entries, removed tets ignored); throws esim::Error on a size mismatch or NaN
  void solve(const std::vector<double>& volumetricEigenstrain);

  const Eigen::VectorXd& displacementM() const;      // 3 per node [m]
  const std::vector<VoigtStress>& stressPa() const;  // per tet (0 for removed tets)
  const std::vector<double>& vonMisesPa() const;     // per tet (0 for removed tets)
  int numFreeDofs() const;                           // unknowns of K u = f
  double factorizationSeconds() const;               // wall time of the constructor's factorization

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace esim
