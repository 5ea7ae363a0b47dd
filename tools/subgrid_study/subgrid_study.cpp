// subgrid_study - the sub-grid contact model's error series (issue #13; README, "A coarse mesh
// that cuts"): runs a scenario (physics only, no rendering) with `--set`-style overrides and
// prints, per frame, the power, current, peak mesh temperature, removed tets and the sub-grid
// zone's state, then the metrics compared between a coarse run and a resolved one:
//   delivered energy [J]; peak mesh temperature [C]; first frame with a removal;
//   temperatures at fixed probes beside and below the path (P1 interpolation, end of run);
//   the groove: removed tets, their volume [mm^3], depth below the top [mm], largest centroid
//   offset from the path line [mm] and the extent of their centroids along it [mm].
// Usage: subgrid_study SCENARIO [key.path=value ...]
// The path is the straight segment from the first to the last keyframe.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "sim/core_error.h"
#include "sim/io/scenario.h"
#include "tools/app/accuracy_metrics.h"
#include "tools/app/run_config.h"

using namespace esim;

namespace {

// P1 interpolation of a nodal field at p, in the alive tet holding it (NAN outside)
double interpolate(const TetMesh& m, const std::vector<TetGeometry>& geo, const Eigen::VectorXd& f,
                   const Vec3& p) {
  for (int e = 0; e < m.numTets(); ++e) {
    if (!m.isAlive(e)) continue;
    const Tet& t = m.tets[e];
    const Vec3 c = 0.25 * (m.nodes[t[0]] + m.nodes[t[1]] + m.nodes[t[2]] + m.nodes[t[3]]);
    double l[4];
    bool inside = true;
    for (int a = 0; a < 4 && inside; ++a) {
      l[a] = 0.25 + geo[e].grad.row(a).dot(p - c);
      inside = l[a] >= -1e-9;
    }
    if (inside) return l[0] * f[t[0]] + l[1] * f[t[1]] + l[2] * f[t[2]] + l[3] * f[t[3]];
  }
  return NAN;
}

int run(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: subgrid_study SCENARIO [key.path=value ...]\n");
    return 2;
  }
  const Scenario s = loadScenario(argv[1], std::vector<std::string>(argv + 2, argv + argc));
  app::checkRunnable(s);
  Simulation sim(app::buildMesh(s), app::makeSimulationConfig(s));
  const Vec3 p0 = s.tool.path.front().positionM, p1 = s.tool.path.back().positionM;
  const double top = sim.model().boundsM.max().z();
  std::printf("# %s: %d nodes, %d tets, sub-grid contact %s (area_factor %g)\n", s.name.c_str(),
              sim.mesh().numNodes(), sim.mesh().numTets(),
              subgridModeName(sim.config().subgrid.mode), sim.config().subgrid.areaFactor);
  std::printf(
      "frame,t_s,power_w,current_a,max_mesh_c,removed_tets,subgrid,subgrid_w,zone_c,"
      "vapor_kg,pocket_pa\n");
  int firstRemoval = -1;
  for (int f = 0; f < frameCount(s); ++f) {
    const FrameRecord& r = sim.step();
    if (firstRemoval < 0 && sim.removedTets() > 0) firstRemoval = r.frame;
    std::printf("%d,%.4f,%.5f,%.6f,%.3f,%d,%d,%.4f,%.2f,%.3g,%.4g\n", r.frame, r.timeS, r.powerW,
                r.toolCurrentA, r.maxTemperatureC, sim.removedTets(), r.subgridActive ? 1 : 0,
                r.subgridPowerW, r.subgridZoneTemperatureC, r.subgridVaporKg,
                r.subgridPocketStressPa);
  }
  // the groove: the removed tets
  const TetMesh& m = sim.mesh();
  const auto& geo = *sim.model().geo;
  const app::RemovedExtents groove = app::removedTetExtents(m, geo, p0, p1, top);
  const int n = groove.tets;
  const double vol = groove.volumeM3, depth = groove.maxDepthM, off = groove.maxOffPathM,
               along0 = groove.alongMinM, along1 = groove.alongMaxM;
  // probes at the end: beside the middle of the path on the surface, beside its start, below it
  const Vec3 mid = 0.5 * (p0 + p1);
  const Vec3 probes[] = {Vec3(mid.x(), 0.003, top - 1e-5), Vec3(mid.x(), 0.005, top - 1e-5),
                         Vec3(mid.x(), 0.002, top - 0.002), Vec3(p0.x(), 0.003, top - 1e-5),
                         Vec3(mid.x(), 0.0, top - 0.006)};
  const Eigen::VectorXd temp = sim.temperatureC();
  std::printf("# probes (x, y, z mm -> C):");
  for (const Vec3& p : probes)
    std::printf(" (%.0f, %.0f, %.0f) %.3f", p.x() * 1e3, p.y() * 1e3, p.z() * 1e3,
                interpolate(m, geo, temp, p));
  std::printf(
      "\n# delivered %.4f J, peak mesh %.2f C, first removal frame %d, removed %d tets "
      "%.3f mm^3, depth %.3f mm, centroids <= %.3f mm off the path, along it %.2f .. "
      "%.2f mm\n",
      sim.energyDeliveredJ(), sim.maxTemperatureSeenC(), firstRemoval, n, vol * 1e9, depth * 1e3,
      n ? off * 1e3 : 0.0, n ? along0 * 1e3 : 0.0, n ? along1 * 1e3 : 0.0);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const Error& e) {
    std::fprintf(stderr, "subgrid_study: %s\n", e.what());
    return 2;
  }
}
