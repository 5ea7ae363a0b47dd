// electric_phase.h - quantities derived from a solved potential.
//
// Given the P1 potential u [V] (nodal), per tet e with conductivity sigma_e [S/m]:
//   E_e = -grad u             field [V/m]
//   J_e = sigma_e E_e         current density [A/m^2]
//   q_e = sigma_e |grad u|^2  Joule power density [W/m^3] (0 for removed tets)
// Currents are the nodal reactions r = K u at the fixed nodes (exact for the
// discrete problem): toolCurrentA = sum_{contact} r_i (into the tissue),
// returnCurrentA = -sum_{grounded} r_i (out of the tissue); they balance up to the
// solver's residual. powerW = sum_e q_e V_e = u^T K u = V_tool * toolCurrentA when
// the return electrode is at 0 V. impedanceOhm = V_tool / toolCurrentA (+inf when
// no current flows, e.g. no contact).
// ElectricFields owns its arrays.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "sim/fem_p1.h"

namespace esim {

struct ElectricFields {
  Eigen::VectorXd potentialV;            // per node [V]
  std::vector<double> joulePowerW_m3;    // per tet, sigma |grad V|^2, 0 for removed
  std::vector<Vec3> fieldV_m;            // per tet, E = -grad V (0 for removed)
  std::vector<Vec3> currentDensityA_m2;  // per tet, J = sigma E (0 for removed)
  double toolCurrentA = 0;               // into the tissue at the contact nodes
  double returnCurrentA = 0;             // out of the tissue at the grounded nodes
  double powerW = 0;                     // total Joule power [W]
  double impedanceOhm = 0;               // V_tool / toolCurrentA (+inf without current)
};

// checks a per-tet conductivity: one value per tet, finite and > 0 on alive tets;
// throws Error naming the first bad tet
void validateConductivity(const TetMesh& mesh, const std::vector<double>& conductivityS_m);

// K of div(sigma grad V) after validateConductivity
SparseMatrix assembleElectricStiffness(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                                       const std::vector<double>& conductivityS_m);

struct ElectricTotals {
  double toolCurrentA = 0;    // into the tissue at the contact nodes [A]
  double returnCurrentA = 0;  // out of the tissue at the grounded nodes [A]
  double powerW = 0;          // total Joule power [W]
  double impedanceOhm = 0;    // V_tool / toolCurrentA (+inf without current)
};

// The per-frame part: Joule power density per tet into joulePowerW_m3 (resized to the
// tet count; its storage is reused across frames) and the totals. The currents are the
// reactions (K u)_i at the fixed nodes only, row i taken as column i of the symmetric K,
// so no full product is formed. sigma is assumed validated (assembleElectricStiffness).
ElectricTotals computeJoulePower(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                                 const std::vector<double>& conductivityS_m, const SparseMatrix& K,
                                 const Eigen::VectorXd& potentialV, const std::vector<int>& contact,
                                 const std::vector<int>& grounded, double toolVoltageV,
                                 std::vector<double>& joulePowerW_m3);

// the derived fields of a solved potential (see the header comment); contact and
// grounded are the sorted node sets the solve used, toolVoltageV the contact voltage
ElectricFields computeElectricFields(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                                     const std::vector<double>& conductivityS_m,
                                     const SparseMatrix& K, const Eigen::VectorXd& potentialV,
                                     const std::vector<int>& contact,
                                     const std::vector<int>& grounded, double toolVoltageV);

}  // namespace esim
