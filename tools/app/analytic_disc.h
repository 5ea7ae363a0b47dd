// analytic_disc.h - the disc electrode on a half-space, the electric phase's analytic case
// (`esim bench accuracy` and tests/sim/electric_phase_test.cpp).
//
// A disc of radius a at potential v0 on the insulated surface of a half-space of
// conductivity sigma draws I = 4 sigma a v0: R = 1 / (4 sigma a) [ohm]; its potential at
// radius rho and depth d is (2 v0 / pi) asin(2a / (d1 + d2)), d1,2 = sqrt((rho -+ a)^2 + d^2).
// The discrete case: a quarter domain [0, 4a]^3 (symmetry planes x = 0 and y = 0 insulated
// like the surface), h = a / m, the grid bent so the electrode's edge nodes lie on the
// circle, the exact potential imposed on the far faces: what is left is discretization
// error, O(h) in the current (the r^-1/2 edge singularity limits P1).
#pragma once

namespace esim::app {

// exact potential of the disc (radius a, potential v0) at radius rho and depth d [V]
double discPotential(double aM, double v0, double rhoM, double depthM);

struct DiscResult {
  double resistanceOhm = 0;   // of the whole disc: v0 / (4 I_quarter)
  double toolCurrentA = 0;    // through the quarter disc
  double returnCurrentA = 0;  // out through the far faces (equal to round-off)
  int nodes = 0;
  double solveMs = 0;  // assembly + factorization + solve
};

// the discrete disc at h = a / m (m >= 1), sigma [S/m]
DiscResult discResistance(int m, double aM, double sigmaS_m);

}  // namespace esim::app
