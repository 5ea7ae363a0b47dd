// electric_phase.cpp - fields, Joule power, currents and impedance (see electric_phase.h).
#include "sim/electric_phase.h"

#include <cmath>
#include <limits>
#include <string>

#include "sim/core_error.h"

namespace esim {

void validateConductivity(const TetMesh& mesh, const std::vector<double>& conductivityS_m) {
  ESIM_VERIFY(static_cast<int>(conductivityS_m.size()) == mesh.numTets(),
              "electric conductivity: expected one value per tet (" +
                  std::to_string(mesh.numTets()) + "), got " +
                  std::to_string(conductivityS_m.size()));
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    const double s = conductivityS_m[e];
    ESIM_VERIFY(std::isfinite(s) && s > 0, "electric conductivity: tet " + std::to_string(e) +
                                               " has sigma = " + std::to_string(s) +
                                               " S/m; expected a finite value > 0");
  }
}

SparseMatrix assembleElectricStiffness(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                                       const std::vector<double>& conductivityS_m) {
  validateConductivity(mesh, conductivityS_m);
  return assembleStiffness(mesh, geo, conductivityS_m);
}

ElectricTotals computeJoulePower(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                                 const std::vector<double>& conductivityS_m, const SparseMatrix& K,
                                 const Eigen::VectorXd& potentialV, const std::vector<int>& contact,
                                 const std::vector<int>& grounded, double toolVoltageV,
                                 std::vector<double>& joulePowerW_m3) {
  const int n = mesh.numNodes();
  ESIM_VERIFY(static_cast<int>(conductivityS_m.size()) == mesh.numTets() &&
                  static_cast<int>(geo.size()) == mesh.numTets(),
              "computeJoulePower: conductivity and geometry must have one entry per tet");
  ESIM_VERIFY(K.rows() == n && K.cols() == n,
              "computeJoulePower: K must be n x n with n the mesh's node count");
  ESIM_VERIFY(potentialV.size() == n, "computeJoulePower: potential must have one value per node");
  ESIM_VERIFY(potentialV.allFinite(), "computeJoulePower: potential is not finite");

  // ---- per tet ----
  ElectricTotals out;
  joulePowerW_m3.assign(mesh.numTets(), 0.0);
  double power = 0;
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    joulePowerW_m3[e] = conductivityS_m[e] * tetGradient(mesh, geo, e, potentialV).squaredNorm();
    power += joulePowerW_m3[e] * geo[e].volume;
  }
  out.powerW = power;

  // ---- reactions at the fixed nodes: (K u)_i = K.col(i) . u (K symmetric) ----
  for (int c : contact) {
    ESIM_VERIFY(c >= 0 && c < n, "computeJoulePower: contact id out of range");
    out.toolCurrentA += K.col(c).dot(potentialV);
  }
  for (int g : grounded) {
    ESIM_VERIFY(g >= 0 && g < n, "computeJoulePower: grounded id out of range");
    out.returnCurrentA -= K.col(g).dot(potentialV);
  }
  out.impedanceOhm = out.toolCurrentA > 0 ? toolVoltageV / out.toolCurrentA
                                          : std::numeric_limits<double>::infinity();
  return out;
}

ElectricFields computeElectricFields(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                                     const std::vector<double>& conductivityS_m,
                                     const SparseMatrix& K, const Eigen::VectorXd& potentialV,
                                     const std::vector<int>& contact,
                                     const std::vector<int>& grounded, double toolVoltageV) {
  validateConductivity(mesh, conductivityS_m);
  ElectricFields out;
  const ElectricTotals totals =
      computeJoulePower(mesh, geo, conductivityS_m, K, potentialV, contact, grounded, toolVoltageV,
                        out.joulePowerW_m3);
  out.potentialV = potentialV;
  out.toolCurrentA = totals.toolCurrentA;
  out.returnCurrentA = totals.returnCurrentA;
  out.powerW = totals.powerW;
  out.impedanceOhm = totals.impedanceOhm;
  out.fieldV_m.assign(mesh.numTets(), Vec3::Zero());
  out.currentDensityA_m2.assign(mesh.numTets(), Vec3::Zero());
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    const Vec3 grad = tetGradient(mesh, geo, e, potentialV);
    out.fieldV_m[e] = -grad;
    out.currentDensityA_m2[e] = -conductivityS_m[e] * grad;
  }
  return out;
}

}  // namespace esim
