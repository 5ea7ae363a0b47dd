// grid_operator_util.h - the test matrix of the LDL' kernels' tests (ldl_updown_test,
// ldl_solve_test): a 3-D grid operator, symmetric positive definite, as CHOLMOD's lower triangle.
#pragma once

#include <cholmod.h>

namespace esim::testing_util {

// (7-point stencil on k x k x k nodes + a diagonal shift) kron M, M = 1 (components 1) or a
// 3 x 3 SPD block (components 3: three unknowns a node, as the structural phase's); SPD since
// both factors are. Lower triangle, stype -1; the caller frees it.
inline cholmod_sparse* gridOperator(int k, int components, cholmod_common& cm) {
  const double m1[1][1] = {{1}};
  const double m3[3][3] = {{2, 0.5, 0.2}, {0.5, 2, 0.3}, {0.2, 0.3, 2}};
  const int c = components == 3 ? 3 : 1;
  const int nodes = k * k * k, n = c * nodes;
  cholmod_triplet* t = cholmod_allocate_triplet(n, n, 4 * c * c * nodes, -1, CHOLMOD_REAL, &cm);
  const auto add = [&](int u, int v, double s) {  // node block (u, v), u >= v
    for (int a = 0; a < c; ++a)
      for (int b = 0; b < c; ++b) {
        const int i = c * u + a, j = c * v + b;
        if (i < j) continue;
        static_cast<int*>(t->i)[t->nnz] = i;
        static_cast<int*>(t->j)[t->nnz] = j;
        static_cast<double*>(t->x)[t->nnz++] = s * (c == 3 ? m3[a][b] : m1[0][0]);
      }
  };
  for (int z = 0; z < k; ++z)
    for (int y = 0; y < k; ++y)
      for (int x = 0; x < k; ++x) {
        const int i = x + k * (y + k * z);
        add(i, i, 6.5 + 0.01 * (i % 7));
        if (x + 1 < k) add(i + 1, i, -1);
        if (y + 1 < k) add(i + k, i, -1);
        if (z + 1 < k) add(i + k * k, i, -1);
      }
  cholmod_sparse* a = cholmod_triplet_to_sparse(t, 0, &cm);
  cholmod_free_triplet(&t, &cm);
  return a;
}

}  // namespace esim::testing_util
