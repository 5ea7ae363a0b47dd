// cholmod_view.h - an Eigen sparse matrix seen by CHOLMOD without a copy, and a symbolic
// analysis with a given ordering (the electric solvers' and the structural phase's
// factorizations).
#pragma once

#include <cholmod.h>

#include <algorithm>
#include <new>

#include "sim/core_error.h"
#include "sim/fem_p1.h"

namespace esim {

// after a CHOLMOD call that failed for want of resources: memory that ran out is
// std::bad_alloc, as an allocation of ours would be (the run's "out of memory" with its
// remedy, exit 1); a factor beyond CHOLMOD's 32-bit indices (more than 2^31 entries) is a run
// error saying so; other failures are the caller's to name
inline void throwIfOutOfResources(const cholmod_common& c) {
  if (c.status == CHOLMOD_OUT_OF_MEMORY) throw std::bad_alloc();
  if (c.status == CHOLMOD_TOO_LARGE)
    throw RunError(
        "the mesh is too large for the direct solvers: the factor of its matrix would hold more "
        "than 2^31 entries, beyond CHOLMOD's 32-bit indices; use a smaller mesh");
}

// nrow x ncol column-major doubles at x (leading dimension nrow) as a CHOLMOD dense matrix, e.g.
// a right-hand side; it points into x, which must outlive it (CHOLMOD only reads a solve's B)
inline cholmod_dense cholmodViewDense(const double* x, size_t nrow, size_t ncol = 1) {
  cholmod_dense d{};
  d.nrow = nrow;
  d.ncol = ncol;
  d.nzmax = nrow * ncol;
  d.d = nrow;
  d.x = const_cast<double*>(x);
  d.xtype = CHOLMOD_REAL;
  d.dtype = CHOLMOD_DOUBLE;
  return d;
}

// ncol sparse columns of nrow rows (compressed: p[0..ncol] offsets into i, rows ascending in
// each column, and x, the values) as an unsymmetric CHOLMOD matrix, e.g. the columns of a
// low-rank update; it points into the arrays, which must outlive it
inline cholmod_sparse cholmodViewColumns(size_t nrow, size_t ncol, int* p, int* i, double* x) {
  cholmod_sparse s{};
  s.nrow = nrow;
  s.ncol = ncol;
  s.nzmax = std::max(1, p[ncol]);
  s.p = p;
  s.i = i;
  s.x = x;
  s.itype = CHOLMOD_INT;
  s.xtype = CHOLMOD_REAL;
  s.dtype = CHOLMOD_DOUBLE;
  s.sorted = 1;
  s.packed = 1;
  return s;
}

// the lower triangle of a symmetric, compressed Eigen matrix as a CHOLMOD matrix; it points
// into `a`, which must outlive it and stay unchanged while CHOLMOD reads it
inline cholmod_sparse cholmodViewLower(const SparseMatrix& a) {
  cholmod_sparse s =
      cholmodViewColumns(a.rows(), a.cols(), const_cast<int*>(a.outerIndexPtr()),
                         const_cast<int*>(a.innerIndexPtr()), const_cast<double*>(a.valuePtr()));
  s.stype = -1;  // symmetric, lower triangle used
  return s;
}

// a simplicial LDL' factor's arrays (columns sorted, the diagonal D(j) first), read only
struct SimplicialView {
  const int* p;
  const int* i;
  const int* nz;
  const double* x;
  explicit SimplicialView(const cholmod_factor* f)
      : p(static_cast<const int*>(f->p)),
        i(static_cast<const int*>(f->i)),
        nz(static_cast<const int*>(f->nz)),
        x(static_cast<const double*>(f->x)) {}
  int parent(int j) const { return nz[j] > 1 ? i[p[j] + 1] : -1; }  // elimination tree
  double diagonal(int j) const { return x[p[j]]; }                  // D(j)
};

// the symbolic analysis of `a` with the fill-reducing ordering `perm` (n entries; no AMD or
// METIS search): the common's ordering methods are set to CHOLMOD_GIVEN for the call and
// restored; nullptr when CHOLMOD fails (out of memory)
inline cholmod_factor* cholmodAnalyzeGiven(cholmod_sparse* a, int* perm, cholmod_common* c) {
  const int methods = c->nmethods, ordering = c->method[0].ordering;
  c->nmethods = 1;
  c->method[0].ordering = CHOLMOD_GIVEN;
  cholmod_factor* f = cholmod_analyze_p(a, perm, nullptr, 0, c);
  c->nmethods = methods;
  c->method[0].ordering = ordering;
  return f;
}

}  // namespace esim
