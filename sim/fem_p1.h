// fem_p1.h - linear (P1) tetrahedral finite elements for scalar fields.
//
// For a tet with vertices p0..p3 the barycentric basis N_i has constant gradient
// grad N_i (rows of `grad`, [1/m]); volume V [m^3]. The scalar operator
//   K_ij = sum_e k_e V_e grad N_i . grad N_j
// discretises -div(k grad u) (k: S/m for the potential, W/(m K) for heat).
// Mass: consistent M_ij = c_e V_e (1 + delta_ij) / 20, lumped m_i = sum_e c_e V_e / 4.
// Removed tets (alive == 0) contribute nothing. Matrices are n x n over all nodes.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

#include "sim/mesh_tet.h"

namespace esim {

using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

struct TetGeometry {
  double volume = 0;                 // [m^3]
  Eigen::Matrix<double, 4, 3> grad;  // gradients of the 4 basis functions [1/m]
};

// geometry of every tet (removed tets included; they are just not assembled)
std::vector<TetGeometry> tetGeometry(const TetMesh& mesh);

// an n x n compressed matrix of the column pattern (outer, inner: CSC, rows ascending in each
// column), every value -0.0: the additive identity the assemblies scatter their element
// matrices onto, so that each entry is bitwise the sum setFromTriplets gave
SparseMatrix patternOfZeros(int n, const std::vector<int>& outer, const std::vector<int>& inner);

// stiffness K (n x n, symmetric) with coefficient coeff[e] per tet
SparseMatrix assembleStiffness(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                               const std::vector<double>& coeff);

// K from assembleStiffness, after the tets `removed` died (mesh.alive already 0 for them):
// each entry they touched summed again over the alive tets in assembleStiffness's order,
// so K is bitwise what a fresh assembly gives, with explicit zeros where no alive tet is
// left (the pattern is kept). Cost: the removed tets' entries times the tets at a node,
// not the mesh. nodeTets: node -> tets containing it, sorted (nodeTets of any earlier
// alive set: a superset of today's). Returns the number of entries summed again.
int removeFromStiffness(SparseMatrix& k, const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                        const std::vector<double>& coeff, const Adjacency& nodeTets,
                        const std::vector<int>& removed);

// consistent mass matrix with coefficient coeff[e] per tet
SparseMatrix assembleMass(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                          const std::vector<double>& coeff);

// lumped (row-sum) mass with coefficient coeff[e] per tet
Eigen::VectorXd lumpedMass(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                           const std::vector<double>& coeff);

// gradient of a nodal field in tet e (constant per tet)
inline Eigen::Vector3d tetGradient(const TetMesh& mesh, const std::vector<TetGeometry>& geo, int e,
                                   const Eigen::VectorXd& field) {
  const Tet& t = mesh.tets[e];
  return geo[e].grad.transpose() *
         Eigen::Vector4d(field[t[0]], field[t[1]], field[t[2]], field[t[3]]);
}

}  // namespace esim
