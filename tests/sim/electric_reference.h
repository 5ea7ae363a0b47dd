// electric_reference.h - the independent reference the electric solvers' tests check against:
// an Eigen LDLT of the reduced system K_oo u_o = -K_oc u_c (o: the nodes reached from the
// ground through the nonzeros of K, neither grounded nor in contact). Nodes not reached
// (floating) are 0 V, as the solvers hold them; a contact on one is ignored.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>
#include <vector>

#include "sim/fem_p1.h"

namespace esim::test {

inline Eigen::VectorXd referenceSolve(const SparseMatrix& K, const std::vector<int>& grounded,
                                      const std::vector<int>& contact, double v) {
  const int n = static_cast<int>(K.rows());
  std::vector<int> reached(n, 0), queue(grounded);
  for (int g : grounded) reached[g] = 1;
  for (size_t h = 0; h < queue.size(); ++h)
    for (SparseMatrix::InnerIterator it(K, queue[h]); it; ++it)
      if (!reached[it.row()] && it.value() != 0) {
        reached[it.row()] = 1;
        queue.push_back(static_cast<int>(it.row()));
      }
  std::vector<int> fixed(n, -1);  // -1 unknown, 0 ground or not reached, 1 contact
  for (int i = 0; i < n; ++i)
    if (!reached[i]) fixed[i] = 0;
  for (int g : grounded) fixed[g] = 0;
  for (int c : contact)
    if (reached[c]) fixed[c] = 1;
  std::vector<int> idx(n, -1);
  int m = 0;
  for (int i = 0; i < n; ++i)
    if (fixed[i] < 0) idx[i] = m++;
  std::vector<Eigen::Triplet<double>> t;
  Eigen::VectorXd b = Eigen::VectorXd::Zero(m);
  for (int j = 0; j < n; ++j)
    for (SparseMatrix::InnerIterator it(K, j); it; ++it) {
      const int i = static_cast<int>(it.row());
      if (idx[i] < 0) continue;
      if (idx[j] >= 0)
        t.emplace_back(idx[i], idx[j], it.value());
      else if (fixed[j] == 1)
        b[idx[i]] -= it.value() * v;
    }
  SparseMatrix a(m, m);
  a.setFromTriplets(t.begin(), t.end());
  Eigen::SimplicialLDLT<SparseMatrix> ldlt(a);
  EXPECT_EQ(ldlt.info(), Eigen::Success);
  const Eigen::VectorXd x = ldlt.solve(b);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(n);
  for (int i = 0; i < n; ++i) u[i] = idx[i] >= 0 ? x[idx[i]] : (fixed[i] == 1 ? v : 0.0);
  return u;
}

// max |a - ref| / max |ref|
inline double relError(const Eigen::VectorXd& a, const Eigen::VectorXd& ref) {
  return (a - ref).cwiseAbs().maxCoeff() / std::max(ref.cwiseAbs().maxCoeff(), 1e-300);
}

}  // namespace esim::test
