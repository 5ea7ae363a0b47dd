// updown_study - what an exact rank-r change of the structural factor costs, three ways, on
// one factor (issue #11; README, "Not done yet"): the paper's slab (P1 elasticity, paper
// Table 1's E and nu, bottom face clamped), METIS-ordered as StructuralPhase orders it; the
// columns C are the element stiffnesses' 6 non-rigid eigenpairs of the r/6 tets nearest the
// middle of the top face (where a cut runs), scaled to keep A + C C' well conditioned.
//   updown:        cholmod_updown(A + C C') on the simplicial LDL' factor (what
//                  StructuralPhase::removeTets does);
//   block solve:   L^-1 P C with the supernodal factor and C dense (BLAS-3; the first half
//                  of a Woodbury term on a kept factor);
//   reach solves:  the same, one column at a time, only over each column's reach in L
//                  (cholmod_solve2 with Bset, simplicial factor);
//   vector:        A + C C' by ESim's AVX-512 kernel (sim/ldl_updown.h) on a copy of the
//                  simplicial factor (cholmod_updown where the CPU has no AVX-512).
// Each is the best of three. The study checks what it times: the reach solves equal the
// block solve (scaled by D^1/2: LDL' against LL'), the updated factor solves the updated
// matrix, and the kernel's factor equals cholmod_updown's (relative differences printed,
// exit 1 above 1e-8).
// Usage: updown_study [NODES ...] (default 1013 8000)
#include <cholmod.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "sim/fem_p1.h"
#include "sim/ldl_updown.h"
#include "sim/mesh_slab.h"
#include "sim/structural.h"

using namespace esim;

namespace {

constexpr double kYoungsModulusPa = 4.75e4;  // paper Table 1
constexpr double kPoissonRatio = 0.4;        // paper Table 1
constexpr double kColumnScale = 1e-3;        // C C' against the element stiffness

double seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

using Matrix12 = Eigen::Matrix<double, 12, 12>;

// P1 elasticity stiffness of tet e (12 x 12, node-major x, y, z), as StructuralPhase's
Matrix12 elementStiffness(const TetGeometry& g) {
  return elasticTetStiffness(g, kYoungsModulusPa, kPoissonRatio);
}

// the worst relative residuals over a study
struct Checks {
  double reachVsBlock = 0;    // max |Y_reach - D^1/2 Y_block| / max |Y_reach|
  double updated = 0;         // ||(A + sum C C') x - b|| / ||b|| with the updated factor
  double vectorVsUpdown = 0;  // max |L_vector - L_updown| / max |L_updown|
};

// returns the checks
Checks study(int targetNodes) {
  Checks checks;
  SlabSpec spec;
  spec.targetNodes = targetNodes;
  const TetMesh mesh = makeSlab(spec);
  const std::vector<TetGeometry> geo = tetGeometry(mesh);
  const int nodes = static_cast<int>(mesh.nodes.size());
  double zMin = 1e300, zMax = -1e300;
  for (const Vec3& p : mesh.nodes) {
    zMin = std::min(zMin, p.z());
    zMax = std::max(zMax, p.z());
  }
  std::vector<int> dof(3 * nodes, -1);  // clamped: -1
  int n = 0;
  for (int i = 0; i < nodes; ++i)
    if (mesh.nodes[i].z() > zMin + 1e-9)
      for (int a = 0; a < 3; ++a) dof[3 * i + a] = n++;
  const auto dofOf = [&](int tet, int a) { return dof[3 * mesh.tets[tet][a / 3] + a % 3]; };

  cholmod_common c;
  cholmod_start(&c);
  c.supernodal = CHOLMOD_SUPERNODAL;
  c.nmethods = 1;
  c.method[0].ordering = CHOLMOD_METIS;
  cholmod_triplet* t = cholmod_allocate_triplet(n, n, 78 * mesh.tets.size(), -1, CHOLMOD_REAL, &c);
  for (int e = 0; e < mesh.numTets(); ++e) {
    const Matrix12 k = elementStiffness(geo[e]);
    for (int a = 0; a < 12; ++a)
      for (int b = 0; b < 12; ++b) {
        const int i = dofOf(e, a), j = dofOf(e, b);
        if (i < 0 || j < 0 || i < j) continue;
        static_cast<int*>(t->i)[t->nnz] = i;
        static_cast<int*>(t->j)[t->nnz] = j;
        static_cast<double*>(t->x)[t->nnz++] = k(a, b);
      }
  }
  cholmod_sparse* a = cholmod_triplet_to_sparse(t, 0, &c);
  // A (both triangles) and every update added to it, for the residual check
  Eigen::SparseMatrix<double> current(n, n);
  {
    std::vector<Eigen::Triplet<double>> entries;
    for (size_t q = 0; q < t->nnz; ++q) {
      const int i = static_cast<int*>(t->i)[q], j = static_cast<int*>(t->j)[q];
      const double v = static_cast<double*>(t->x)[q];
      entries.emplace_back(i, j, v);
      if (i != j) entries.emplace_back(j, i, v);
    }
    current.setFromTriplets(entries.begin(), entries.end());
  }
  cholmod_factor* super = cholmod_analyze(a, &c);
  const double t0 = seconds();
  cholmod_factorize(a, super, &c);
  std::printf("%d nodes, %d unknowns: nnz(L) %.3g, factorization %.0f ms\n", nodes, n, c.lnz,
              1e3 * (seconds() - t0));
  cholmod_factor* simplicial = cholmod_copy_factor(super, &c);
  cholmod_change_factor(CHOLMOD_REAL, 0, 0, 1, 1, simplicial, &c);  // simplicial LDL'
  // the reach solves use A's factor, as the block solve does; `simplicial` takes the updates
  cholmod_factor* original = cholmod_copy_factor(simplicial, &c);
  cholmod_factor* vec = cholmod_copy_factor(simplicial, &c);
  LdlUpdownWork work;

  std::vector<std::pair<double, int>> byDistance;  // tets by centroid distance to the top middle
  for (int e = 0; e < mesh.numTets(); ++e) {
    Vec3 m = Vec3::Zero();
    for (int v : mesh.tets[e]) m += mesh.nodes[v] / 4;
    byDistance.push_back({(m - Vec3(0, 0, zMax)).norm(), e});
  }
  std::sort(byDistance.begin(), byDistance.end());

  std::printf("%6s %12s %15s %15s %12s %10s\n", "rank", "updown ms", "block solve ms",
              "reach solves ms", "reach rows", "vector ms");
  for (int r : {6, 24, 72, 144}) {
    // C in A's row order, then in L's (P C)
    cholmod_sparse* cols = cholmod_allocate_sparse(n, r, 12 * r, 1, 1, 0, CHOLMOD_REAL, &c);
    int nz = 0;
    for (int k = 0; k < r; ++k) {
      const int e = byDistance[k / 6].second;
      const Eigen::SelfAdjointEigenSolver<Matrix12> eig(elementStiffness(geo[e]));
      const int mode = 11 - k % 6;  // the 6 largest: the non-rigid ones
      std::vector<std::pair<int, double>> entries;
      for (int q = 0; q < 12; ++q)
        if (dofOf(e, q) >= 0)
          entries.push_back({dofOf(e, q), kColumnScale * std::sqrt(eig.eigenvalues()[mode]) *
                                              eig.eigenvectors()(q, mode)});
      std::sort(entries.begin(), entries.end());
      static_cast<int*>(cols->p)[k] = nz;
      for (const auto& [row, value] : entries) {
        static_cast<int*>(cols->i)[nz] = row;
        static_cast<double*>(cols->x)[nz++] = value;
      }
    }
    static_cast<int*>(cols->p)[r] = nz;
    cholmod_sparse* permuted =
        cholmod_submatrix(cols, static_cast<int*>(super->Perm), n, nullptr, -1, 1, 1, &c);
    cholmod_dense* dense = cholmod_sparse_to_dense(cols, &c);
    Eigen::SparseMatrix<double> colsEigen(n, r);
    {
      std::vector<Eigen::Triplet<double>> entries;
      for (int k = 0; k < r; ++k)
        for (int q = static_cast<int*>(cols->p)[k]; q < static_cast<int*>(cols->p)[k + 1]; ++q)
          entries.emplace_back(static_cast<int*>(cols->i)[q], k, static_cast<double*>(cols->x)[q]);
      colsEigen.setFromTriplets(entries.begin(), entries.end());
    }
    const Eigen::SparseMatrix<double> cct = colsEigen * colsEigen.transpose();
    Eigen::MatrixXd yBlock(n, r), yReach = Eigen::MatrixXd::Zero(n, r);

    double block = 1e300, reach = 1e300, updown = 1e300, vector = 1e300;
    long reachRows = 0;
    for (int rep = 0; rep < 3; ++rep) {
      double s = seconds();
      cholmod_dense* pc = cholmod_solve(CHOLMOD_P, super, dense, &c);
      cholmod_dense* y = cholmod_solve(CHOLMOD_L, super, pc, &c);
      block = std::min(block, seconds() - s);
      if (rep == 0) std::memcpy(yBlock.data(), y->x, sizeof(double) * n * r);
      cholmod_free_dense(&pc, &c);
      cholmod_free_dense(&y, &c);

      cholmod_dense *x = nullptr, *work1 = nullptr, *work2 = nullptr;
      cholmod_sparse* xSet = nullptr;
      cholmod_dense* bColumn = cholmod_zeros(n, 1, CHOLMOD_REAL, &c);
      cholmod_sparse* bSet = cholmod_allocate_sparse(n, 1, 12, 1, 1, 0, CHOLMOD_PATTERN, &c);
      const int* pp = static_cast<int*>(permuted->p);
      const int* pi = static_cast<int*>(permuted->i);
      const double* px = static_cast<double*>(permuted->x);
      double* bx = static_cast<double*>(bColumn->x);
      reachRows = 0;
      s = seconds();
      for (int k = 0; k < r; ++k) {
        int m = 0;
        for (int q = pp[k]; q < pp[k + 1]; ++q) {
          bx[pi[q]] = px[q];
          static_cast<int*>(bSet->i)[m++] = pi[q];
        }
        static_cast<int*>(bSet->p)[1] = m;
        cholmod_solve2(CHOLMOD_L, original, bColumn, bSet, &x, &xSet, &work1, &work2, &c);
        reachRows += static_cast<int*>(xSet->p)[1];
        if (rep == 0)
          for (int q = 0; q < static_cast<int*>(xSet->p)[1]; ++q) {
            const int row = static_cast<int*>(xSet->i)[q];
            yReach(row, k) = static_cast<double*>(x->x)[row];
          }
        for (int q = pp[k]; q < pp[k + 1]; ++q) bx[pi[q]] = 0;
      }
      reach = std::min(reach, seconds() - s);
      cholmod_free_dense(&x, &c);
      cholmod_free_dense(&work1, &c);
      cholmod_free_dense(&work2, &c);
      cholmod_free_sparse(&xSet, &c);
      cholmod_free_dense(&bColumn, &c);
      cholmod_free_sparse(&bSet, &c);

      if (rep == 0) {  // L_s = L_u D^1/2: Y_block = D^-1/2 Y_reach
        const int* lp = static_cast<int*>(original->p);
        const double* lx = static_cast<double*>(original->x);
        for (int row = 0; row < n; ++row) yBlock.row(row) *= std::sqrt(lx[lp[row]]);
        checks.reachVsBlock =
            std::max(checks.reachVsBlock,
                     (yReach - yBlock).cwiseAbs().maxCoeff() / yReach.cwiseAbs().maxCoeff());
      }

      s = seconds();
      cholmod_updown(1, permuted, simplicial, &c);  // an update: the factor stays definite
      updown = std::min(updown, seconds() - s);
      s = seconds();
      ldlUpdown(true, *permuted, *vec, work, c);
      vector = std::min(vector, seconds() - s);
      current += cct;
    }
    // the updated factor solves the updated matrix
    cholmod_dense* b = cholmod_ones(n, 1, CHOLMOD_REAL, &c);
    cholmod_dense* x = cholmod_solve(CHOLMOD_A, simplicial, b, &c);
    const Eigen::Map<const Eigen::VectorXd> xv(static_cast<double*>(x->x), n);
    checks.updated = std::max(checks.updated, (current * xv - Eigen::VectorXd::Ones(n)).norm() /
                                                  std::sqrt(static_cast<double>(n)));
    cholmod_free_dense(&x, &c);
    cholmod_free_dense(&b, &c);
    double differ = 0, largest = 0;
    for (size_t q = 0; q < simplicial->nzmax; ++q) {
      differ = std::max(differ, std::abs(static_cast<double*>(simplicial->x)[q] -
                                         static_cast<double*>(vec->x)[q]));
      largest = std::max(largest, std::abs(static_cast<double*>(simplicial->x)[q]));
    }
    checks.vectorVsUpdown = std::max(checks.vectorVsUpdown, differ / largest);
    std::printf("%6d %12.2f %15.2f %15.2f %12ld %10.2f\n", r, 1e3 * updown, 1e3 * block,
                1e3 * reach, reachRows / r, 1e3 * vector);
    cholmod_free_dense(&dense, &c);
    cholmod_free_sparse(&permuted, &c);
    cholmod_free_sparse(&cols, &c);
  }
  cholmod_free_factor(&simplicial, &c);
  cholmod_free_factor(&original, &c);
  cholmod_free_factor(&vec, &c);
  cholmod_free_factor(&super, &c);
  cholmod_free_sparse(&a, &c);
  cholmod_free_triplet(&t, &c);
  cholmod_finish(&c);
  std::printf(
      "checks: reach solves against the block solve %.1e, updated factor's residual %.1e, "
      "vector against updown %.1e\n",
      checks.reachVsBlock, checks.updated, checks.vectorVsUpdown);
  return checks;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes;
  for (int i = 1; i < argc; ++i) {
    char* end = nullptr;
    const long v = std::strtol(argv[i], &end, 10);
    if (*end != '\0' || v < 100 || v > 200000) {
      std::fprintf(stderr, "updown_study: '%s': expected a node count in [100, 200000]\n", argv[i]);
      return 2;
    }
    sizes.push_back(static_cast<int>(v));
  }
  if (sizes.empty()) sizes = {1013, 8000};
  for (int nodes : sizes) {
    const Checks checks = study(nodes);
    if (!(checks.reachVsBlock <= 1e-8 && checks.updated <= 1e-8 && checks.vectorVsUpdown <= 1e-8)) {
      std::fprintf(stderr, "updown_study: %d nodes: the methods disagree (see the checks)\n",
                   nodes);
      return 1;
    }
  }
  return 0;
}
