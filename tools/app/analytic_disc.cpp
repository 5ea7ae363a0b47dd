// analytic_disc.cpp - the disc electrode on a half-space (analytic_disc.h).
#include "tools/app/analytic_disc.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "sim/core_error.h"
#include "sim/electric_phase.h"
#include "sim/electric_solver.h"
#include "sim/fem_p1.h"
#include "sim/mesh_slab.h"

namespace esim::app {

double discPotential(double a, double v0, double rho, double d) {
  const double d1 = std::sqrt((rho - a) * (rho - a) + d * d);
  const double d2 = std::sqrt((rho + a) * (rho + a) + d * d);
  return 2 * v0 / M_PI * std::asin(std::min(1.0, 2 * a / (d1 + d2)));
}

DiscResult discResistance(int m, double a, double sigma) {
  ESIM_VERIFY(m >= 1, "discResistance: m must be >= 1");
  const auto t0 = std::chrono::steady_clock::now();
  const double L = 4 * a, v0 = 1.0;
  SlabSpec s;
  s.sizeM = Vec3(L, L, L);
  s.nodesPerAxis = {4 * m + 1, 4 * m + 1, 4 * m + 1};
  TetMesh mesh = makeSlab(s);
  // x, y in [0, L], top z = L; then bend the grid so that the square max(x, y) <= a
  // becomes the quarter disc rho <= a (its boundary nodes lie on the circle), blended
  // back to the straight grid at max(x, y) = 2a: the electrode is a polygon whose
  // area converges smoothly instead of a staircase of grid points
  for (auto& p : mesh.nodes) {
    p += Vec3(L / 2, L / 2, 0);
    const double sq = std::max(p.x(), p.y()), r = std::hypot(p.x(), p.y());
    if (r == 0 || sq >= 2 * a) continue;
    const double w = sq <= a ? 1.0 : (2 * a - sq) / a;
    const double scale = w * sq / r + (1 - w);
    p.x() *= scale;
    p.y() *= scale;
  }
  validateMesh(mesh, "disc electrode mesh");
  const auto geo = tetGeometry(mesh);
  const std::vector<double> sigmaTet(mesh.numTets(), sigma);
  const SparseMatrix K = assembleElectricStiffness(mesh, geo, sigmaTet);
  const int n = mesh.numNodes();
  const double eps = 1e-9 * a;
  Eigen::VectorXd u = Eigen::VectorXd::Zero(n);
  std::vector<int> kind(n, 0);  // 0 free, 1 electrode, 2 far boundary
  std::vector<int> electrode, far;
  for (int i = 0; i < n; ++i) {
    const Vec3& p = mesh.nodes[i];
    const double rho = std::hypot(p.x(), p.y());
    if (p.z() > L - eps && rho <= a + eps) {
      kind[i] = 1;
      u[i] = v0;
      electrode.push_back(i);
    } else if (p.x() > L - eps || p.y() > L - eps || p.z() < eps) {
      kind[i] = 2;
      u[i] = discPotential(a, v0, rho, L - p.z());
      far.push_back(i);
    }
  }
  // K_ff u_f = -K_fd u_d with the solver module's CHOLMOD factorization
  std::vector<int> idx(n, -1), freeIds;
  for (int i = 0; i < n; ++i)
    if (kind[i] == 0) {
      idx[i] = static_cast<int>(freeIds.size());
      freeIds.push_back(i);
    }
  const int nf = static_cast<int>(freeIds.size());
  std::vector<Eigen::Triplet<double>> t;
  Eigen::VectorXd b = Eigen::VectorXd::Zero(nf);
  for (int j = 0; j < n; ++j)
    for (SparseMatrix::InnerIterator it(K, j); it; ++it) {
      const int i = static_cast<int>(it.row());
      if (idx[i] < 0) continue;
      if (idx[j] >= 0)
        t.emplace_back(idx[i], idx[j], it.value());
      else
        b[idx[i]] -= it.value() * u[j];
    }
  SparseMatrix kff(nf, nf);
  kff.setFromTriplets(t.begin(), t.end());
  kff.makeCompressed();
  electric_detail::CholmodFactor factor;
  factor.analyze(kff);
  factor.factorize(kff, "disc electrode");
  Eigen::VectorXd x(nf);
  factor.solve(b.data(), x.data());
  for (int k = 0; k < nf; ++k) u[freeIds[k]] = x[k];
  // the current through the quarter disc, from the reactions
  const ElectricFields f = computeElectricFields(mesh, geo, sigmaTet, K, u, electrode, far, v0);
  DiscResult r;
  r.toolCurrentA = f.toolCurrentA;
  r.returnCurrentA = f.returnCurrentA;
  r.resistanceOhm = v0 / (4 * f.toolCurrentA);
  r.nodes = n;
  r.solveMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace esim::app
