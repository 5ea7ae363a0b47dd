// subgrid_contact_test.cpp - the sub-grid contact model (sim/subgrid_contact.h) against
// analytic results: wetted areas of a ball and a blade, the telescoping shell resistances,
// the zone's lumped heating rate P / (c rho V) before boiling, the boiling plateau at 100 C
// for w rho L / q, the well-mixed steady state q tau of a moving zone, energy to round-off;
// then in a simulation on a small inline slab: P = V I with the sub-grid shell in series, the
// energy balance every frame (hard_case.h's FrameChecker, 1e-9) through boiling and rupture,
// and `auto` identical to `off` where the mesh resolves the contact.
#include "sim/subgrid_contact.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numeric>

#include "sim/mesh_slab.h"
#include "sim/simulation.h"
#include "tests/hard_cases/hard_case.h"

namespace esim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();

double areaBelow(const std::vector<SurfaceSample>& s, const ToolPose& pose, double surfaceZ,
                 WettedContact* out = nullptr, Vec3 motion = Vec3::Zero()) {
  const WettedContact c = wettedContact(s, pose, Vec3(0, 0, surfaceZ), Vec3::UnitZ(), motion);
  if (out) *out = c;
  return c.areaM2;
}

TEST(SubgridContact, WettedAreaOfABallIsItsSphericalCap) {
  ElectrodeShape ball;
  ball.kind = ElectrodeKind::Sphere;
  ball.radiusM = 0.001;
  const auto samples = electrodeSurfaceSamples(ball);
  const double r = ball.radiusM;
  double total = 0;
  for (const auto& s : samples) total += s.areaM2;
  EXPECT_NEAR(total, 4 * kPi * r * r, 1e-12 * total);
  ToolPose pose;
  for (double depth : {0.25 * r, 0.5 * r, r, 1.5 * r}) {          // centre below the surface by ...
    pose.tipM = Vec3(0, 0, -depth + r);                           // ... surface at z = r
    const double cap = 2 * kPi * r * std::min(2 * r, r + depth);  // zone below the plane
    WettedContact c;
    EXPECT_NEAR(areaBelow(samples, pose, r, &c), cap, 2e-3 * cap) << depth;
    EXPECT_NEAR(c.depthM, depth + r, 2e-3 * r);
  }
}

TEST(SubgridContact, WettedAreaOfABladePressedIn) {
  ElectrodeShape blade;  // 0.5 mm edge radius, 3 mm wide, 20 mm long: the paper scene's
  const double r = blade.radiusM, w = blade.widthM;
  const auto samples = electrodeSurfaceSamples(blade);
  ToolPose pose;
  for (double s : {0.0, 0.2e-3, 1e-3}) {  // tip edge below the surface z = 0 by s
    pose.tipM = Vec3(0, 0, -s);
    // bottom half-cylinder + two corner quarter-spheres, then the faces and side edges
    const double area = kPi * r * (w + 2 * r) + 2 * s * (w + kPi * r);
    WettedContact c;
    EXPECT_NEAR(areaBelow(samples, pose, 0.0, &c, Vec3(1, 0, 0)), area, 5e-3 * area) << s;
    EXPECT_NEAR(c.depthM, s + r, 2e-3 * r);
    EXPECT_NEAR(c.lengthAlongM, w + 2 * r, 0.02 * r);  // along x: edge to edge
  }
  pose.tipM = Vec3(0, 0, 0.6e-3);  // above the surface by more than r: dry
  EXPECT_EQ(areaBelow(samples, pose, 0.0), 0.0);
}

TEST(SubgridContact, ShellResistancesAddUpToTheSpreadingResistance) {
  const double sigma = 0.144, a = 1e-3, rz = 2e-3;
  const auto radii = zoneRadii(a, rz);
  ASSERT_EQ(static_cast<int>(radii.size()), kSubgridShells + 1);
  double sum = 0;
  for (int k = 0; k < kSubgridShells; ++k) sum += shellResistanceOhm(sigma, radii[k], radii[k + 1]);
  EXPECT_NEAR(sum, shellResistanceOhm(sigma, a, rz), 1e-12 * sum);
  // a hemisphere of radius a against infinity: 1 / (2 pi sigma a) (REFERENCE.md case 3)
  EXPECT_NEAR(shellResistanceOhm(sigma, a, kInf), 1 / (2 * kPi * sigma * a), 1e-9);
  const auto v = zoneVolumes(radii);
  EXPECT_NEAR(std::accumulate(v.begin(), v.end(), 0.0), 2 * kPi / 3 * (rz * rz * rz - a * a * a),
              1e-22);
}

SubgridZoneParams liver() {
  SubgridZoneParams p;
  p.waterKg_m3 = 0.78 * 1060;
  p.latentJ_m3 = p.waterKg_m3 * 2.256e6;
  return p;
}

ZoneCoupling oneNode(double temperatureC, double enthalpyJ_m3) {
  return {{1.0}, {temperatureC}, {enthalpyJ_m3}};
}

// shells heated with the same power density q while the node follows the zone: no
// conduction, T = T0 + q t / (c rho) before boiling; the plateau for w rho L / q; then dry
TEST(SubgridContact, ZoneHeatsAtPOverCRhoVThenBoilsForWRhoLOverQ) {
  const SubgridZoneParams p = liver();
  SubgridZone zone;
  const double a = 1e-3, rz = 2e-3, q = 2e9;  // [W/m^3]
  resizeZone(p, zone, a, rz, oneNode(37, 0));
  const auto vol = zoneVolumes(zoneRadii(a, rz));
  std::vector<double> power;
  for (double v : vol) power.push_back(q * v);
  const double dt = 1e-4;  // below the zone's explicit limit: one sub-step per call
  const double crho = p.heatCapacityJ_m3K, hb = crho * 63.0;
  double t = 0, vapor = 0, input = 0, toNodes = 0;
  const double e0 = zoneEnergyJ(zone);
  double plateauStart = -1, plateauEnd = -1;
  for (int i = 0; i < 12000; ++i) {
    const double tz = zoneTemperatureC(p, zone, kSubgridShells - 1);
    const auto r = stepZone(p, zone, power, oneNode(tz, crho * (tz - 37)), kInf, dt);
    ASSERT_EQ(r.substeps, 1);
    t += dt;
    vapor += r.vaporKg;
    input += r.inputJ;
    toNodes += r.toNodesJ[0];
    const double tc = zoneTemperatureC(p, zone);
    if (plateauStart < 0) {
      if (zone.water[0] < 1)
        plateauStart = t;
      else
        ASSERT_NEAR(tc, 37 + q * t / crho, 1e-9) << "t = " << t;
    }
    if (plateauStart >= 0 && plateauEnd < 0) {
      if (zone.water[0] > 0)
        ASSERT_NEAR(tc, 100.0, 1e-9) << "on the plateau, t = " << t;
      else
        plateauEnd = t;
    }
  }
  EXPECT_NEAR(plateauStart, hb / q, 1.01 * dt);
  EXPECT_NEAR(plateauEnd - plateauStart, p.latentJ_m3 / q, 2.01 * dt);
  const double vTotal = std::accumulate(vol.begin(), vol.end(), 0.0);
  EXPECT_NEAR(vapor, p.waterKg_m3 * vTotal, 1e-12);  // all the water, once
  EXPECT_GT(zoneTemperatureC(p, zone), 100.0);       // dry: heating again
  EXPECT_EQ(toNodes, 0.0);                           // no conduction: equal temperatures
  // energy: input = stored + given + latent, to round-off
  const double latent = vapor / p.waterKg_m3 * p.latentJ_m3;
  EXPECT_NEAR(input, zoneEnergyJ(zone) - e0 + toNodes + latent, 1e-12 * input);
}

// a moving zone with no conduction (lambda 0): each shell renewed at 1/tau, so it tends to
// the well-mixed steady state e = q tau; with conduction the energy identity still holds
TEST(SubgridContact, MovingZoneTendsToTheWellMixedSteadyState) {
  SubgridZoneParams p = liver();
  p.conductivityW_mK = 0;
  p.boiling = false;
  SubgridZone zone;
  const double a = 1e-3, rz = 2e-3, q = 1e8, tau = 0.2;
  resizeZone(p, zone, a, rz, oneNode(37, 0));
  const auto vol = zoneVolumes(zoneRadii(a, rz));
  std::vector<double> power;
  for (double v : vol) power.push_back(q * v);
  for (int i = 0; i < 300; ++i) stepZone(p, zone, power, oneNode(37, 0), tau, 1.0 / 30);
  for (int k = 0; k < kSubgridShells; ++k)
    EXPECT_NEAR(zone.enthalpyJ_m3[k], q * tau, 1e-9 * q * tau) << "shell " << k;

  p = liver();
  SubgridZone z2;
  const ZoneCoupling two{{0.25, 0.75}, {40, 45}, {3.82e6 * 3, 3.82e6 * 8}};
  const auto formed = resizeZone(p, z2, a, rz, two);
  double e = zoneEnergyJ(z2), given = formed[0] + formed[1];
  EXPECT_NEAR(e, -given, 1e-15);  // the zone's tissue came from the nodes
  double input = 0, latent = 0;
  for (int i = 0; i < 200; ++i) {
    std::vector<double> pw(kSubgridShells, 20.0);
    const auto r = stepZone(p, z2, pw, two, 0.15, 1.0 / 30);
    input += r.inputJ;
    given += r.toNodesJ[0] + r.toNodesJ[1];
    latent += r.vaporKg / p.waterKg_m3 * p.latentJ_m3;
  }
  const auto grown = resizeZone(p, z2, 1.2e-3, 2.6e-3, two);  // the contact grows
  given += grown[0] + grown[1];
  const auto back = releaseZone(z2);
  given += back[0] + back[1];
  EXPECT_FALSE(z2.present);
  EXPECT_GT(latent, 0.0);
  EXPECT_NEAR(input, given + latent, 1e-12 * input);  // all of it went somewhere
  (void)e;
}

// the pocket the zone's vapour forms is an inclusion: its wall stress E e_v / (3 (1 - nu))
// (REFERENCE.md case 8) passes the paper's critical stress once ~7e-4 of its water boiled
TEST(SubgridContact, AVapourPocketBreaksTheTissueOnceAFractionOfAPermilleBoiled) {
  const double e = 4.75e4, nu = 0.4, critical = 2.45e4;
  EXPECT_NEAR(pocketVonMisesPa(e, nu, 0.9), e * 0.3 / 0.6, 1e-9);
  ExpansionParams x;  // the structural phase's water expansion, capped at 3
  const auto wall = [&](double vapor) {
    return pocketVonMisesPa(e, nu, volumetricExpansion(x, 100.0, vapor));
  };
  EXPECT_LT(wall(0.0), 0.1 * critical);  // liquid expansion alone: far below
  EXPECT_LT(wall(5e-4), critical);
  EXPECT_GT(wall(1e-3), critical);
  EXPECT_NEAR(wall(1.0), e * 1.0 / (1 - nu), 1e-9);  // the cap: e_v = 3, eps* = 1
}

// ---- in a simulation ----

// a 12 x 12 x 6 mm slab on a grounded bottom, cells of 3 mm x 3 mm x 2 mm: a 0.5 mm ball
// pressed into the top is far smaller than the contact patch (4 nodes)
SimulationConfig ballConfig(SubgridMode mode, bool cut) {
  SimulationConfig c;
  c.phases = {true, true, true, cut, cut};
  c.toolVoltageV = 60;
  c.electrode.kind = ElectrodeKind::Sphere;
  c.electrode.radiusM = 5e-4;
  c.contactDistanceM = 2.3e-3;
  c.returnElectrode.radiusM = 1.0;
  ToolPath path;
  path.keys.push_back({0.0, Vec3(0.0003, 0.0002, 0.006), Eigen::Quaterniond::Identity()});
  path.keys.push_back({0.5, Vec3(0.0003, 0.0002, 0.006), Eigen::Quaterniond::Identity()});
  path.keys.push_back({1.5, Vec3(0.0023, 0.0002, 0.006), Eigen::Quaterniond::Identity()});
  path.generatorOnS = {{0.0, kInf}};
  c.toolPath = path;
  c.subgrid.mode = mode;
  c.subgrid.areaFactor = 1.0;
  c.electricSolver.strategy = ElectricStrategy::Refactor;
  return c;
}

TetMesh smallSlab(int nx = 5, int nz = 4) {
  SlabSpec spec;
  spec.sizeM = Vec3(0.012, 0.012, 0.006);
  spec.nodesPerAxis = {nx, nx, nz};
  return makeSlab(spec);
}

TEST(SubgridContactSimulation, TheSeriesResistanceScalesTheMeshSolution) {
  Simulation off(smallSlab(), ballConfig(SubgridMode::Off, false));
  Simulation on(smallSlab(), ballConfig(SubgridMode::On, false));
  const FrameRecord r0 = off.step();
  const FrameRecord r1 = on.step();
  ASSERT_TRUE(r1.subgridActive);
  ASSERT_FALSE(r0.subgridActive);
  ASSERT_EQ(on.contactNodes(), off.contactNodes());
  ASSERT_GE(on.contactNodes().size(), 1u);
  const double s = r1.toolCurrentA / r0.toolCurrentA;  // the scale of the mesh's solution
  EXPECT_LT(s, 0.7);                                   // the ball's resistance dominates
  EXPECT_GT(s, 0.0);
  EXPECT_NEAR((on.potentialV() - s * off.potentialV()).cwiseAbs().maxCoeff(), 0.0, 1e-12);
  // delivered = V I = the mesh's Joule power (s^2 of the unscaled) + the sub-grid shell's
  EXPECT_NEAR(r1.powerW, 60 * r1.toolCurrentA, 1e-9 * r1.powerW);
  EXPECT_NEAR(r1.powerW, s * s * r0.powerW + r1.subgridPowerW, 1e-9 * r1.powerW);
  // the sub-grid shell: I^2 (1/a - 1/a_p) / (2 pi sigma) with a = r (a hemisphere pressed
  // to its equator has the wetted area 2 pi r^2) and R_m + R_sg = V / I
  const double rsg = r1.subgridPowerW / (r1.toolCurrentA * r1.toolCurrentA);
  EXPECT_NEAR(60 / r0.toolCurrentA + rsg, 60 / r1.toolCurrentA, 1e-9 * 60 / r1.toolCurrentA);
  EXPECT_LT(rsg, 1 / (2 * kPi * 0.144 * 5e-4));
  EXPECT_GT(rsg, 0.5 / (2 * kPi * 0.144 * 5e-4));
}

TEST(SubgridContactSimulation, EnergyIsConservedThroughBoilingAndRupture) {
  Simulation sim(smallSlab(), ballConfig(SubgridMode::On, true));
  hard::Invariants inv;
  inv.potentialBounds = true;
  hard::FrameChecker check(sim, inv);
  double vapor = 0, hottest = 0;
  for (int f = 0; f < 45 && check.ok(); ++f) {
    const FrameRecord& r = check.step();
    EXPECT_TRUE(r.subgridActive) << f;
    vapor += r.subgridVaporKg;
    hottest = std::max(hottest, r.subgridZoneTemperatureC);
  }
  EXPECT_GT(vapor, 0.0);  // the zone boiled ...
  EXPECT_GE(hottest, 100.0 - 1e-9);
  EXPECT_GT(sim.removedTets(), 0);  // ... and its vapour broke the tet at the ball
  EXPECT_LT(check.worstEnergyRel(), 1e-9);
  const auto w = sim.warnings();
  EXPECT_TRUE(std::any_of(w.begin(), w.end(), [](const std::string& s) {
    return s.find("sub-grid contact") != std::string::npos;
  }));
}

// where the mesh resolves the contact, `auto` never applies: bitwise the run without it
TEST(SubgridContactSimulation, AutoIsOffWhereTheMeshResolvesTheContact) {
  SimulationConfig c = ballConfig(SubgridMode::Auto, false);
  c.contactDistanceM = 1e-4;
  c.electrode.radiusM = 2e-3;  // a 2 mm ball on 1 mm cells: ~20 contact nodes
  for (auto& k : c.toolPath.keys) k.positionM.z() = 0.0065;
  SimulationConfig o = c;
  o.subgrid.mode = SubgridMode::Off;
  Simulation a(smallSlab(13, 7), c), b(smallSlab(13, 7), o);
  for (int f = 0; f < 10; ++f) {
    const FrameRecord& ra = a.step();
    b.step();
    EXPECT_FALSE(ra.subgridActive);
    ASSERT_GT(ra.contactNodes, 4);
  }
  EXPECT_EQ(a.energyDeliveredJ(), b.energyDeliveredJ());
  EXPECT_EQ(a.thermalState()->enthalpyJ_m3, b.thermalState()->enthalpyJ_m3);
  EXPECT_EQ(a.subgridStoredEnergyJ(), 0.0);
}

// the model is of a flat contact under a tool at the surface: not with tool.contact volume
TEST(SubgridContactSimulation, IsNotForAToolInsideTheTissue) {
  SimulationConfig c = ballConfig(SubgridMode::On, false);
  c.contactNodes = ContactNodes::Volume;
  try {
    Simulation sim(smallSlab(), c);
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "subgrid_contact.mode = on with tool.contact = volume: the sub-grid contact model is "
              "of a tool at the tissue's surface (a flat contact under it); set one of them off "
              "or to surface");
  }
}

TEST(SubgridContactSimulation, NeedsTheElectricAndThermalPhases) {
  SimulationConfig c = ballConfig(SubgridMode::Auto, false);
  c.phases.thermal = c.phases.boiling = false;
  try {
    Simulation sim(smallSlab(), c);
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("subgrid_contact.mode"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace esim
