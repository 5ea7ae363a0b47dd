// subgrid_contact.cpp - the sub-grid contact model (see subgrid_contact.h).
#include "sim/subgrid_contact.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "sim/core_error.h"

namespace esim {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kSampleStepM = 5e-5;  // spacing of the blade's samples along its axis
}  // namespace

const char* subgridModeName(SubgridMode mode) {
  switch (mode) {
    case SubgridMode::Off:
      return "off";
    case SubgridMode::Auto:
      return "auto";
    case SubgridMode::On:
      return "on";
  }
  return "?";
}

// ---- geometry ----

std::vector<SurfaceSample> electrodeSurfaceSamples(const ElectrodeShape& shape) {
  std::vector<SurfaceSample> out;
  const double r = shape.radiusM;
  if (shape.kind == ElectrodeKind::Sphere) {
    const int n = 4000;
    const double golden = kPi * (3.0 - std::sqrt(5.0));
    const double area = 4 * kPi * r * r / n;
    for (int i = 0; i < n; ++i) {
      const double z = 1.0 - (2.0 * i + 1.0) / n;
      const double rho = std::sqrt(std::max(0.0, 1 - z * z));
      const double phi = golden * i;
      out.push_back({r * Vec3(rho * std::cos(phi), rho * std::sin(phi), z), area});
    }
    return out;
  }
  const double w = shape.widthM, len = shape.lengthM;
  // along the axis: midpoints of nz cells over [0, L]; across the width: nx cells
  const int nz = std::max(1, static_cast<int>(std::ceil(len / kSampleStepM)));
  const int nx = std::max(1, static_cast<int>(std::ceil(w / (4 * kSampleStepM))));
  const int nphi = 16;  // around a half-cylinder
  const double dz = len / nz, dx = w / nx, dphi = kPi / nphi;
  if (r > 0) {
    // the two faces y = +-r
    for (int k = 0; k < nz; ++k)
      for (int i = 0; i < nx; ++i) {
        const double x = -0.5 * w + (i + 0.5) * dx, z = (k + 0.5) * dz;
        out.push_back({Vec3(x, r, z), dx * dz});
        out.push_back({Vec3(x, -r, z), dx * dz});
      }
    // half-cylinders along the bottom (z = 0) and top (z = L) edges, along x
    for (int i = 0; i < nx; ++i)
      for (int j = 0; j < nphi; ++j) {
        const double x = -0.5 * w + (i + 0.5) * dx, phi = (j + 0.5) * dphi;
        // bottom: angle from +y through -z to -y; top: from +y through +z to -y
        out.push_back({Vec3(x, r * std::cos(phi), -r * std::sin(phi)), r * dphi * dx});
        out.push_back({Vec3(x, r * std::cos(phi), len + r * std::sin(phi)), r * dphi * dx});
      }
    // half-cylinders along the side edges x = +-w/2, along z
    for (int k = 0; k < nz; ++k)
      for (int j = 0; j < nphi; ++j) {
        const double z = (k + 0.5) * dz, phi = (j + 0.5) * dphi - 0.5 * kPi;  // -pi/2..pi/2
        const double c = std::cos(phi), s = std::sin(phi);
        out.push_back({Vec3(0.5 * w + r * c, r * s, z), r * dphi * dz});
        out.push_back({Vec3(-0.5 * w - r * c, r * s, z), r * dphi * dz});
      }
    // quarter-spheres at the four corners (x outward, z outward): midpoint rule in
    // (polar angle from the outward z, azimuth within the outward x half)
    const int nth = 16;
    for (int zs : {-1, 1})
      for (int xs : {-1, 1}) {
        const Vec3 corner(0.5 * w * xs, 0, zs < 0 ? 0.0 : len);
        for (int a = 0; a < nth; ++a)
          for (int b = 0; b < nphi; ++b) {
            const double th = (a + 0.5) * (0.5 * kPi / nth);  // from the z axis
            const double ph = (b + 0.5) * dphi - 0.5 * kPi;   // x half: -pi/2..pi/2
            const Vec3 d(xs * std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph),
                         zs * std::cos(th));
            out.push_back({corner + r * d, r * r * std::sin(th) * (0.5 * kPi / nth) * dphi});
          }
      }
  }
  return out;
}

WettedContact wettedContact(const std::vector<SurfaceSample>& samples, const ToolPose& pose,
                            const Vec3& planePointM, const Vec3& planeNormal, const Vec3& motion) {
  WettedContact c;
  const Vec3 n = planeNormal.normalized();
  const Eigen::Quaterniond q = pose.orientation.normalized();
  const double mlen = motion.norm();
  const Vec3 m = mlen > 0 ? Vec3(motion / mlen) : Vec3::Zero();
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  c.deepestM = pose.tipM;
  for (const SurfaceSample& s : samples) {
    const Vec3 p = pose.tipM + q * s.localM;
    const double depth = n.dot(planePointM - p);  // > 0 below the surface
    if (depth > c.depthM) {
      c.depthM = depth;
      c.deepestM = p;
    }
    if (depth <= 0) continue;
    c.areaM2 += s.areaM2;
    if (mlen > 0) {
      // along the motion, within the plane
      const double t = m.dot(p);
      lo = std::min(lo, t);
      hi = std::max(hi, t);
    }
  }
  if (c.areaM2 > 0 && mlen > 0) c.lengthAlongM = hi - lo;
  return c;
}

double pocketVonMisesPa(double youngsModulusPa, double poissonRatio, double expansion) {
  return youngsModulusPa * (expansion / 3.0) / (1.0 - poissonRatio);
}

double shellResistanceOhm(double sigmaS_m, double r1M, double r2M) {
  return (1.0 / r1M - 1.0 / r2M) / (2 * kPi * sigmaS_m);
}

// ---- the zone ----

std::vector<double> zoneRadii(double innerM, double outerM) {
  std::vector<double> r(kSubgridShells + 1);
  for (int k = 0; k <= kSubgridShells; ++k)
    r[k] = innerM * std::pow(outerM / innerM, static_cast<double>(k) / kSubgridShells);
  r[0] = innerM;
  r[kSubgridShells] = outerM;
  return r;
}

std::vector<double> zoneVolumes(const std::vector<double>& radii) {
  std::vector<double> v(radii.size() - 1);
  for (size_t k = 0; k + 1 < radii.size(); ++k)
    v[k] = 2 * kPi / 3 * (std::pow(radii[k + 1], 3) - std::pow(radii[k], 3));
  return v;
}

double zoneEnergyJ(const SubgridZone& zone) {
  if (!zone.present) return 0;
  const std::vector<double> v = zoneVolumes(zoneRadii(zone.innerM, zone.outerM));
  double e = 0;
  for (size_t k = 0; k < v.size(); ++k) e += v[k] * zone.enthalpyJ_m3[k];
  return e;
}

double zoneTemperatureC(const SubgridZoneParams& p, const SubgridZone& zone, int shell) {
  if (!zone.present) return p.initialTemperatureC;
  return p.initialTemperatureC + zone.enthalpyJ_m3[shell] / p.heatCapacityJ_m3K;
}

namespace {

// the sensible heat of tissue taken from a contact node: its enthalpy, capped at boiling
// (its vapour stays with the node) and never below the initial state's
double inflowEnthalpy(const SubgridZoneParams& p, double nodeEnthalpyJ_m3) {
  const double hb = p.boiling
                        ? p.heatCapacityJ_m3K * (p.boilingTemperatureC - p.initialTemperatureC)
                        : std::numeric_limits<double>::infinity();
  return std::min(nodeEnthalpyJ_m3, hb);
}

void checkCoupling(const ZoneCoupling& c) {
  ESIM_VERIFY(!c.weights.empty() && c.weights.size() == c.temperatureC.size() &&
                  c.weights.size() == c.enthalpyJ_m3.size(),
              "subgrid zone: one weight, temperature and enthalpy per contact node");
}

}  // namespace

ZoneStepResult stepZone(const SubgridZoneParams& p, SubgridZone& zone,
                        const std::vector<double>& powerW, const ZoneCoupling& coupling,
                        double residenceS, double dtS) {
  checkCoupling(coupling);
  ESIM_VERIFY(zone.present, "subgrid zone: stepZone on an absent zone");
  const int n = static_cast<int>(zone.enthalpyJ_m3.size());
  ESIM_VERIFY(static_cast<int>(powerW.size()) == n, "subgrid zone: one power per shell");
  ESIM_VERIFY(dtS > 0 && std::isfinite(dtS), "subgrid zone: dt must be > 0");
  const int nc = static_cast<int>(coupling.weights.size());
  ZoneStepResult res;
  res.toNodesJ.assign(nc, 0.0);
  const std::vector<double> r = zoneRadii(zone.innerM, zone.outerM);
  const std::vector<double> vol = zoneVolumes(r);
  std::vector<double> mid(n), g(n);  // mid radii; g[k]: conductance k -> k+1 (k = n-1: out)
  for (int k = 0; k < n; ++k) mid[k] = std::sqrt(r[k] * r[k + 1]);
  const double lambda = p.conductivityW_mK, crho = p.heatCapacityJ_m3K;
  for (int k = 0; k + 1 < n; ++k) g[k] = 2 * kPi * lambda / (1.0 / mid[k] - 1.0 / mid[k + 1]);
  g[n - 1] = 2 * kPi * lambda * mid[n - 1];
  // explicit stability: each shell keeps a non-negative weight on its own temperature
  double hmax = dtS;
  for (int k = 0; k < n; ++k) {
    const double gsum = g[k] + (k > 0 ? g[k - 1] : 0.0);
    hmax = std::min(hmax, 0.5 * crho * vol[k] / gsum);
  }
  const bool moving = std::isfinite(residenceS) && residenceS > 0;
  if (moving) hmax = std::min(hmax, kMaxAdvectedFraction * residenceS);
  const int steps = std::max(1, static_cast<int>(std::ceil(dtS / hmax)));
  const double h = dtS / steps;
  res.substeps = steps;
  double tMesh = 0, eIn = 0;
  std::vector<double> eInNode(nc);
  for (int i = 0; i < nc; ++i) {
    tMesh += coupling.weights[i] * coupling.temperatureC[i];
    eInNode[i] = inflowEnthalpy(p, coupling.enthalpyJ_m3[i]);
    eIn += coupling.weights[i] * eInNode[i];
  }
  const double hb = crho * (p.boilingTemperatureC - p.initialTemperatureC);
  std::vector<double> flux(n);
  std::vector<double>& e = zone.enthalpyJ_m3;
  for (int step = 0; step < steps; ++step) {
    // conduction (antisymmetric between shells: exact); the outer shell to each node
    for (int k = 0; k + 1 < n; ++k) flux[k] = g[k] * (e[k] - e[k + 1]) / crho * h;
    const double tOuter = p.initialTemperatureC + e[n - 1] / crho;
    double outJ = 0;
    for (int i = 0; i < nc; ++i) {
      const double q = coupling.weights[i] * g[n - 1] * (tOuter - coupling.temperatureC[i]) * h;
      res.toNodesJ[i] += q;
      outJ += q;
    }
    for (int k = 0; k < n; ++k) {
      double dE = powerW[k] * h;  // Joule heat and conduction over the sub-step [J]
      if (k > 0) dE += flux[k - 1];
      dE -= k + 1 < n ? flux[k] : outJ;
      res.inputJ += powerW[k] * h;
      if (!moving) {
        e[k] += dE / vol[k];
        continue;
      }
      // renewal at the rate 1/tau with tissue at eIn, the heating q = dE / (V h) held over
      // the sub-step: de/dt = q + (eIn - e) / tau solved exactly; the tissue released carries
      // its heat (the integral of e) to the nodes, the tissue taken in comes from them
      // (in forms that stay accurate for tau >> h: x = h / tau, 1 - exp(-x) and
      // x - (1 - exp(-x)) without cancellation)
      const double q = dE / (vol[k] * h), x = h / residenceS;
      const double renewed = -std::expm1(-x);  // 1 - exp(-x)
      const double lag = x < 1e-4 ? x * x * (0.5 - x / 6 + x * x / 24) : x - renewed;
      const double drive = q * residenceS + eIn - e[k];        // steady state - e
      const double outJ2 = vol[k] * (e[k] * x + drive * lag);  // V / tau * integral of e
      for (int i = 0; i < nc; ++i)
        res.toNodesJ[i] += coupling.weights[i] * (outJ2 - vol[k] * eInNode[i] * x);
      e[k] += drive * renewed;
      zone.water[k] += (1 - zone.water[k]) * renewed;
    }
    // boiling: heat above the plateau vaporises the water left
    if (p.boiling) {
      for (int k = 0; k < n; ++k) {
        if (e[k] <= hb || zone.water[k] <= 0) continue;
        const double dw =
            p.latentJ_m3 > 0 ? std::min(zone.water[k], (e[k] - hb) / p.latentJ_m3) : zone.water[k];
        e[k] -= dw * p.latentJ_m3;
        zone.water[k] -= dw;
        res.vaporKg += dw * p.waterKg_m3 * vol[k];
        res.maxVaporFraction = std::max(res.maxVaporFraction, 1.0 - zone.water[k]);
      }
    }
  }
  (void)tMesh;
  zone.weights = coupling.weights;  // the shares a release uses (the caller keeps the nodes)
  return res;
}

std::vector<double> resizeZone(const SubgridZoneParams& p, SubgridZone& zone, double innerM,
                               double outerM, const ZoneCoupling& coupling) {
  checkCoupling(coupling);
  ESIM_VERIFY(innerM > 0 && outerM > innerM && std::isfinite(outerM),
              "subgrid zone: radii must satisfy 0 < inner < outer");
  const int nc = static_cast<int>(coupling.weights.size());
  std::vector<double> toNodes(nc, 0.0);
  const std::vector<double> vNew = zoneVolumes(zoneRadii(innerM, outerM));
  if (!zone.present) {
    // tissue joins the zone from the contact nodes, at their (sensible) state
    zone.present = true;
    zone.enthalpyJ_m3.assign(kSubgridShells, 0.0);
    zone.water.assign(kSubgridShells, 1.0);
    double vTotal = 0;
    for (double v : vNew) vTotal += v;
    double eIn = 0;
    for (int i = 0; i < nc; ++i) {
      const double ei = inflowEnthalpy(p, coupling.enthalpyJ_m3[i]);
      eIn += coupling.weights[i] * ei;
      toNodes[i] -= coupling.weights[i] * vTotal * ei;
    }
    zone.enthalpyJ_m3.assign(kSubgridShells, eIn);
  } else if (innerM != zone.innerM || outerM != zone.outerM) {
    // a shell that shrinks gives tissue back at its own state; one that grows takes tissue
    // from the contact nodes at theirs (mixed in)
    const std::vector<double> vOld = zoneVolumes(zoneRadii(zone.innerM, zone.outerM));
    for (int k = 0; k < kSubgridShells; ++k) {
      const double dv = vOld[k] - vNew[k];
      if (dv >= 0) {
        for (int i = 0; i < nc; ++i) toNodes[i] += coupling.weights[i] * dv * zone.enthalpyJ_m3[k];
        continue;
      }
      double eIn = 0;
      for (int i = 0; i < nc; ++i) {
        const double ei = inflowEnthalpy(p, coupling.enthalpyJ_m3[i]);
        eIn += coupling.weights[i] * ei;
        toNodes[i] += coupling.weights[i] * dv * ei;  // dv < 0: taken from the node
      }
      zone.enthalpyJ_m3[k] = (vOld[k] * zone.enthalpyJ_m3[k] - dv * eIn) / vNew[k];
      zone.water[k] = (vOld[k] * zone.water[k] - dv) / vNew[k];
    }
  }
  zone.innerM = innerM;
  zone.outerM = outerM;
  return toNodes;
}

std::vector<double> releaseZone(SubgridZone& zone) {
  std::vector<double> toNodes(zone.weights.size(), 0.0);
  if (zone.present) {
    const double e = zoneEnergyJ(zone);
    for (size_t i = 0; i < zone.weights.size(); ++i) toNodes[i] = zone.weights[i] * e;
  }
  zone.present = false;
  zone.enthalpyJ_m3.clear();
  zone.water.clear();
  zone.innerM = zone.outerM = 0;
  return toNodes;
}

}  // namespace esim
