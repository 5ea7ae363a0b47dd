// cholmod_view.h - an Eigen sparse matrix seen by CHOLMOD without a copy (the electric
// solvers' and the structural phase's factorizations).
#pragma once

#include <cholmod.h>

#include "sim/fem_p1.h"

namespace esim {

// the lower triangle of a symmetric, compressed Eigen matrix as a CHOLMOD matrix; it points
// into `a`, which must outlive it and stay unchanged while CHOLMOD reads it
inline cholmod_sparse cholmodViewLower(const SparseMatrix& a) {
  cholmod_sparse s{};
  s.nrow = a.rows();
  s.ncol = a.cols();
  s.nzmax = a.nonZeros();
  s.p = const_cast<int*>(a.outerIndexPtr());
  s.i = const_cast<int*>(a.innerIndexPtr());
  s.x = const_cast<double*>(a.valuePtr());
  s.stype = -1;  // symmetric, lower triangle used
  s.itype = CHOLMOD_INT;
  s.xtype = CHOLMOD_REAL;
  s.dtype = CHOLMOD_DOUBLE;
  s.sorted = 1;
  s.packed = 1;
  return s;
}

}  // namespace esim
