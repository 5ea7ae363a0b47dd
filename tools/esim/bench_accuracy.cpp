// bench_accuracy.cpp - `esim bench accuracy`: what accuracy costs in time, on one scene.
//
// 1. The scene: scenarios/slab_cut.yaml (a 200 V blade drawn through a 60 x 30 x 10 mm slab,
//    all five phases), the first --seconds of the cut. The baseline point: the mesh graded
//    along the cut (8000 nodes; --quick 2000), rebuild mode update, 30 fps.
// 2. The reference: the finest mesh (20 000 graded nodes; --quick 4000), the smallest step
//    (60 fps), the scene's solvers (electric `auto`: pcg at 1e-8 for a cut at this size, named
//    in accuracy.md; the explicit heat step sub-stepped below its stability limit; the
//    structural factor), the most exact image (per-pixel shading, 4x MSAA).
// 3. Each knob a user turns is swept alone from the baseline: mesh resolution (uniform and
//    graded, from the paper's 1013 nodes up), electric strategy and pcg tolerance, thermal
//    integrator and time step (fps), the structural solve (local, coarse, refactorize), the rebuild
//    strategy and lag, and the renderer's shading and MSAA.
// 4. Per point: physics and render time per frame (median, p95; the render every
//    --render-every frames, snapshot included) and, at the end time, the error against the
//    reference: delivered energy, temperature at fixed probe points, vaporised volume, the
//    cut (removed volume, groove width and depth, intersection over union of the removed
//    region on a common voxel grid: tools/app/accuracy_metrics.h), PSNR of the last frame.
// 5. Outputs in --out: accuracy.csv (one row per point with the command line that reruns it),
//    accuracy.md (the table, Pareto fronts marked, convergence orders of the mesh sweeps) and
//    accuracy_vs_time.png (tools/plot_accuracy.py; a warning without matplotlib).
// A benchmark: a table and a plot, never pass/fail (a point that fails is reported as such).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <sstream>

#include "render/image_hash.h"
#include "render/image_png.h"
#include "render/renderer.h"
#include "sim/core_error.h"
#include "sim/io/scenario.h"
#include "sim/message_text.h"
#include "sim/simulation.h"
#include "tools/app/accuracy_metrics.h"
#include "tools/app/analytic_disc.h"
#include "tools/app/bench_common.h"
#include "tools/app/plot_script.h"
#include "tools/app/run_config.h"
#include "tools/app/run_output.h"
#include "tools/esim/command.h"

namespace esim::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using app::GrooveShape;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInitialTemperatureC = 37.0;

// the scene when --scenario is not given (found from any working folder: benchScenarioPath)
constexpr const char* kDefaultScenario = "scenarios/slab_cut.yaml";

struct AccuracyOptions {
  bool quick = false;
  std::string out = "out/accuracy";
  std::string scenario = kDefaultScenario;
  std::string only;     // run the reference and these points only (names or knobs, a,b,c)
  double seconds = 0;   // simulated time (0: 2 s, --quick 0.6 s)
  int renderEvery = 0;  // 0: 5 (--quick 3)
  bool noPlot = false;
  std::vector<std::string> sets;  // --set KEY=VALUE: the scene's, for every point and the
                                  // reference (a point's own knob still wins)
};

// the --set options as a command line writes them
std::string setArgs(const AccuracyOptions& opt) {
  std::string out;
  for (const std::string& s : opt.sets) out += " --set " + s;
  return out;
}

// ---- the points ----

struct Point {
  std::string name, knob, value;
  std::vector<std::string> sets;                 // scenario overrides beyond the baseline's
  std::function<void(SimulationConfig&)> tweak;  // a knob the scenario has no key for
  std::string tweakNote;                         // what tweak does, for the table
  std::string mark;                              // "paper", "slab_cut" (a shipped set-up)
  bool baseline = false;  // the baseline point itself (each knob's series passes through it)
};

struct Sweep {
  std::vector<std::string> baseSets;  // the baseline point's overrides of the scene
  Point reference;
  std::vector<Point> points;
  int width = 640, height = 360;
  double voxelM = 1e-4;
};

std::string nodesSet(int n) { return "mesh.slab.nodes=" + std::to_string(n); }

Sweep makeSweep(const AccuracyOptions& opt) {
  Sweep s;
  const int base = opt.quick ? 2000 : 8000;
  s.baseSets = {nodesSet(base), "solvers.rebuild.mode=update",
                "physics=[electric,thermal,boiling,structural,rupture]"};
  if (opt.quick) {
    s.width = 320;
    s.height = 180;
    s.voxelM = 2e-4;
  }
  s.reference = {
      "reference",
      "reference",
      "",
      {nodesSet(opt.quick ? 4000 : 20000), "time.fps=60", "look.shading=pixel", "look.msaa=4"},
      {},
      "",
      ""};
  auto add = [&](std::string knob, std::string value, std::vector<std::string> sets,
                 std::string mark = "") {
    std::string name = knob + ":" + value;
    s.points.push_back({name, knob, value, std::move(sets), {}, "", std::move(mark)});
  };
  // mesh: graded along the cut (the shipped slab_cut's mesh) and uniform (the paper's kind)
  const std::vector<int> graded =
      opt.quick ? std::vector<int>{1013, 2000} : std::vector<int>{1013, 2000, 4000, 8000, 14000};
  const std::vector<int> uniform =
      opt.quick ? std::vector<int>{1013, 2000} : std::vector<int>{1013, 4000, 8000, 16000};
  // the baseline is the shipped slab_cut's set-up (graded 8000 nodes, updated in place)
  for (int n : graded) {
    add("mesh_graded", std::to_string(n), {nodesSet(n)}, n == base && !opt.quick ? "slab_cut" : "");
    s.points.back().baseline = n == base;
  }
  for (int n : uniform)
    add("mesh_uniform", std::to_string(n), {nodesSet(n), "mesh.slab.grading.enabled=false"},
        n == 1013 ? "paper" : "");
  // electric: the baseline is the scene's `auto` (pcg for a cut at 8000 nodes)
  if (!opt.quick) add("electric", "refactor", {"solvers.electric.strategy=refactor"});
  for (const char* tol : opt.quick ? std::vector<const char*>{"1e-4"}
                                   : std::vector<const char*>{"1e-2", "1e-4", "1e-6", "1e-8"})
    add("electric", std::string("pcg_") + tol,
        {"solvers.electric.strategy=pcg", std::string("solvers.electric.tolerance=") + tol});
  // thermal: integrator (baseline explicit, sub-stepped) and the frame step
  add("thermal", "backward-euler", {"solvers.thermal.integrator=backward-euler"});
  if (!opt.quick) add("thermal", "crank-nicolson", {"solvers.thermal.integrator=crank-nicolson"});
  if (!opt.quick) add("thermal", "tr-bdf2", {"solvers.thermal.integrator=tr-bdf2"});
  add("time_step", "15fps", {"time.fps=15"});
  if (!opt.quick) add("time_step", "60fps", {"time.fps=60"});
  // rebuild after rupture (baseline: update in place)
  if (!opt.quick) add("rebuild", "synchronous", {"solvers.rebuild.mode=synchronous"});
  add("rebuild", "background_lag3",
      {"solvers.rebuild.mode=background", "solvers.rebuild.lag_frames=3"});
  if (!opt.quick)
    add("rebuild", "background_lag10",
        {"solvers.rebuild.mode=background", "solvers.rebuild.lag_frames=10"});
  // the structural solve (no scenario key yet: set on the configuration)
  s.points.push_back(
      {"structural:local",
       "structural",
       "local",
       {},
       [](SimulationConfig& c) { c.structural.solveMethod = StructuralSolveMethod::local; },
       "StructuralOptions::solveMethod = local",
       ""});
  if (!opt.quick) add("structural", "coarse", {"solvers.structural.method=coarse"});
  if (!opt.quick)
    s.points.push_back({"structural:refactorize",
                        "structural",
                        "refactorize",
                        {},
                        [](SimulationConfig& c) { c.structural.updateCostLimit = 0; },
                        "StructuralOptions::updateCostLimit = 0 (refactorize on removal)",
                        ""});
  // the renderer (the physics is the baseline's; the baseline look is the scene's: vertex
  // shading, 4x MSAA)
  for (const char* shading : {"vertex", "pixel"})
    for (int msaa : opt.quick ? std::vector<int>{0, 4} : std::vector<int>{0, 2, 4}) {
      if (std::string(shading) == "vertex" && msaa == 4) continue;  // the baseline
      if (opt.quick && std::string(shading) == "pixel" && msaa == 0) continue;
      add("render", std::string(shading) + "_msaa" + std::to_string(msaa),
          {std::string("look.shading=") + shading, "look.msaa=" + std::to_string(msaa)});
    }
  return s;
}

// ---- one run ----

struct RunResult {
  std::string error;           // "" = ran
  std::string electricSolver;  // the strategy solver.electric.strategy resolved to
  int nodes = 0, tets = 0, frames = 0;
  double fps = 30, setupS = 0;
  double physicsMedianMs = 0, physicsP95Ms = 0, renderMedianMs = 0, renderP95Ms = 0;
  std::array<double, kStageCount> stageMeanMs{};  // per physics stage, mean over all frames
  double energyJ = 0, vaporM3 = 0, maxTemperatureC = 0;
  std::vector<double> probeC;
  GrooveShape groove;
  std::vector<std::uint8_t> removed;
  std::vector<std::uint8_t> lastImage;
  double psnrRenderDb = kNaN;  // the last frame against the same frame drawn with the
                               // reference look (per-pixel shading, 4x MSAA): render only
  double wallS = 0;
};

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const size_t lo = static_cast<size_t>(pos), hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - lo) * (v[hi] - v[lo]);
}

// the probes: beside the groove near the top, deeper beside it, and under the cut line, at
// a third and two thirds of the way the blade travels in the simulated time
std::vector<Vec3> probePoints(const Scenario& sc, double seconds) {
  const Vec3 from = sc.tool.path.front().positionM;
  const Vec3 to = sc.tool.path.back().positionM;
  const double total = sc.tool.path.back().timeS - sc.tool.path.front().timeS;
  const Vec3 end = from + (to - from) * std::min(1.0, seconds / total);
  std::vector<Vec3> p;
  for (double f : {1.0 / 3, 2.0 / 3}) {
    const double x = from.x() + f * (end.x() - from.x());
    p.push_back({x, 0.0025, 0.0095});
    p.push_back({x, -0.004, 0.008});
    p.push_back({x, 0.0, 0.004});
  }
  return p;
}

app::VoxelGrid voxelGrid(const Scenario& sc, double voxelM) {
  const Vec3 size = sc.mesh.slab.sizeM;
  app::VoxelGrid g;
  // the slab's length, a 12 mm band across the cut line, the whole depth
  g.boxM = Eigen::AlignedBox3d(Vec3(-size.x() / 2, -0.006, 0), Vec3(size.x() / 2, 0.006, size.z()));
  const Vec3 ext = g.boxM.max() - g.boxM.min();
  for (int a = 0; a < 3; ++a)
    g.cells[a] = std::max(1, static_cast<int>(std::lround(ext[a] / voxelM)));
  return g;
}

std::vector<std::string> allSets(const Sweep& sw, const Point& p, double seconds) {
  std::vector<std::string> sets = sw.baseSets;
  sets.push_back("time.duration_s=" + scenarioNumber(seconds));
  sets.insert(sets.end(), p.sets.begin(), p.sets.end());
  return sets;
}

RunResult runPoint(const AccuracyOptions& opt, const Sweep& sw, const Point& p, double seconds,
                   int renderEvery) {
  RunResult r;
  const auto wall0 = Clock::now();
  try {
    const Scenario sc = loadScenario(opt.scenario, allSets(sw, p, seconds));
    SimulationConfig config = app::makeSimulationConfig(sc);
    if (p.tweak) p.tweak(config);
    const auto t0 = Clock::now();
    Simulation sim(app::buildMesh(sc), config);
    r.setupS = std::chrono::duration<double>(Clock::now() - t0).count();
    r.nodes = sim.mesh().numNodes();
    r.electricSolver = sim.electricSolverName();
    r.tets = sim.mesh().numTets();
    r.fps = sc.time.fps;
    r.frames = frameCount(sc);
    RenderOptions ro = app::makeRenderOptions(sc);
    ro.width = sw.width;
    ro.height = sw.height;
    Renderer renderer(ro);
    RenderOptions exact = ro;  // the reference look, for the render-only error
    exact.shading = "pixel";
    exact.msaaSamples = 4;
    std::vector<double> physicsMs, renderMs;
    for (int f = 0; f < r.frames; ++f) {
      const FrameRecord& rec = sim.step();
      physicsMs.push_back(rec.physicsMs());
      for (int st = 0; st <= static_cast<int>(Stage::Snapshot); ++st)
        r.stageMeanMs[st] += rec.ms[st] / r.frames;
      if (f % renderEvery == 0 || f == r.frames - 1) {
        const auto t1 = Clock::now();
        const SurfaceSnapshot snap = sim.snapshot(sc.look.displacementScale);
        const std::vector<std::uint8_t>& rgb = renderer.render(snap);
        renderMs.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t1).count());
        if (f == r.frames - 1) {
          r.lastImage = rgb;
          Renderer exactRenderer(exact);
          const std::vector<std::uint8_t>& best = exactRenderer.render(snap);
          r.psnrRenderDb = compareImages(r.lastImage, best, sw.width, sw.height).psnrDb;
        }
      }
    }
    r.physicsMedianMs = quantile(physicsMs, 0.5);
    r.physicsP95Ms = quantile(physicsMs, 0.95);
    r.renderMedianMs = quantile(renderMs, 0.5);
    r.renderP95Ms = quantile(renderMs, 0.95);
    // ---- the end state ----
    const TetMesh& mesh = sim.mesh();
    r.energyJ = sim.energyDeliveredJ();
    r.maxTemperatureC = sim.maxTemperatureSeenC();
    const Eigen::VectorXd t = sim.temperatureC();
    for (const app::ProbeLocation& loc : app::locateProbes(mesh, probePoints(sc, seconds)))
      r.probeC.push_back(app::sampleNodal(mesh, t, loc));
    if (const ThermalState* ts = sim.thermalState())
      r.vaporM3 = app::volumeIntegral(mesh, ts->vaporFractionTet);
    const app::VoxelGrid grid = voxelGrid(sc, sw.voxelM);
    r.removed = app::removedVoxels(mesh, grid);
    r.groove = app::grooveShape(mesh, grid, r.removed, sc.mesh.slab.sizeM.z());
  } catch (const Error& e) {
    r.error = e.what();
  }
  r.wallS = std::chrono::duration<double>(Clock::now() - wall0).count();
  return r;
}

// ---- errors against the reference ----

struct Errors {
  double energy = kNaN, probeK = kNaN, probe = kNaN, vapor = kNaN, removedVolume = kNaN,
         width = kNaN, depth = kNaN, iou = kNaN, psnrDb = kNaN, psnrRenderDb = kNaN;
};

double relative(double v, double ref) {
  return ref != 0 ? std::abs(v - ref) / std::abs(ref) : (v == 0 ? 0.0 : kNaN);
}

Errors errorsOf(const RunResult& r, const RunResult& ref) {
  Errors e;
  if (!r.error.empty()) return e;
  e.energy = relative(r.energyJ, ref.energyJ);
  double sq = 0, refSq = 0;
  int n = 0;
  for (size_t i = 0; i < r.probeC.size() && i < ref.probeC.size(); ++i) {
    if (!std::isfinite(r.probeC[i]) || !std::isfinite(ref.probeC[i])) continue;
    sq += (r.probeC[i] - ref.probeC[i]) * (r.probeC[i] - ref.probeC[i]);
    refSq += (ref.probeC[i] - kInitialTemperatureC) * (ref.probeC[i] - kInitialTemperatureC);
    ++n;
  }
  if (n > 0) {
    e.probeK = std::sqrt(sq / n);
    e.probe = refSq > 0 ? std::sqrt(sq / refSq) : kNaN;
  }
  e.vapor = relative(r.vaporM3, ref.vaporM3);
  e.removedVolume = relative(r.groove.removedVolumeM3, ref.groove.removedVolumeM3);
  e.width = relative(r.groove.widthM, ref.groove.widthM);
  e.depth = relative(r.groove.depthM, ref.groove.depthM);
  e.iou = app::intersectionOverUnion(r.removed, ref.removed);
  if (r.lastImage.size() == ref.lastImage.size() && !r.lastImage.empty())
    e.psnrDb =
        compareImages(r.lastImage, ref.lastImage, 1, static_cast<int>(r.lastImage.size() / 3))
            .psnrDb;
  e.psnrRenderDb = r.psnrRenderDb;
  return e;
}

// ---- outputs ----

std::string quoteCsv(const std::string& s) {
  if (s.find_first_of(",\"") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string num(double v, int precision = 4) {
  if (!std::isfinite(v)) return std::isinf(v) ? "inf" : "";
  std::ostringstream os;
  os << std::setprecision(precision) << v;
  return os.str();
}

std::string rerunCommand(const AccuracyOptions& opt, const Point& p) {
  return std::string("esim bench accuracy") + (opt.quick ? " --quick" : "") +
         (opt.seconds > 0 ? " --seconds " + num(opt.seconds) : "") + setArgs(opt) + " --only " +
         p.name;
}

std::string runCommand(const AccuracyOptions& opt, const Sweep& sw, const Point& p,
                       double seconds) {
  if (p.tweak) return "";  // no scenario key for it
  std::string cmd = "esim run " + opt.scenario + " --no-video";
  for (const std::string& s : allSets(sw, p, seconds)) cmd += " --set " + s;
  return cmd;
}

// log-spaced resolution of a mesh of n nodes in the slab: h ~ n^(-1/3)
double meshH(int nodes) { return std::cbrt(1.0 / nodes); }

int benchAccuracy(const AccuracyOptions& opt) {
  // ---- 1. the sweep ----
  ESIM_VERIFY(
      std::isfinite(opt.seconds),
      "--seconds: expected a number in [0, 4] (0: the default), got " + messageNumber(opt.seconds));
  const double seconds = opt.seconds > 0 ? opt.seconds : (opt.quick ? 0.6 : 2.0);
  const int renderEvery = opt.renderEvery > 0 ? opt.renderEvery : (opt.quick ? 3 : 5);
  ESIM_VERIFY(seconds <= 4.0, "--seconds: the cut lasts 4 s (got " + num(seconds) + ")");
  Sweep sw = makeSweep(opt);
  sw.baseSets.insert(sw.baseSets.begin(), opt.sets.begin(), opt.sets.end());
  if (!opt.only.empty()) {
    std::string names;
    for (const Point& p : sw.points) names += " " + p.name;
    std::vector<Point> kept;
    const std::vector<std::string> wanted = app::splitList(opt.only);
    ESIM_VERIFY(!wanted.empty(), "--only " + quoteInMessage(opt.only) +
                                     ": expected point names or knobs, comma separated (e.g. "
                                     "mesh_graded,electric:pcg_1e-2)");
    for (const std::string& want : wanted) {
      const size_t before = kept.size();
      for (const Point& p : sw.points)
        if (p.name == want || p.knob == want) kept.push_back(p);
      ESIM_VERIFY(kept.size() > before,
                  "--only: no point or knob " + quoteInMessage(want) + "; the points are:" + names);
    }
    sw.points = kept;
  }
  // the scene as the reference runs it, checked before the folder is made (a bad scenario
  // was "the reference run failed", exit 1, after the folder was made); the --set values
  // alone first (a value the points' own knobs override was never read: 'abc' passed)
  (void)loadScenario(opt.scenario, opt.sets);
  (void)loadScenario(opt.scenario, allSets(sw, sw.reference, seconds));
  app::FolderLock outLock;
  app::createOutputFolder(opt.out, "--out", outLock);
  std::printf(
      "esim bench accuracy%s%s: %s, %.2f s of the cut, %zu points + the reference, "
      "images %dx%d every %d frames\n",
      opt.quick ? " --quick" : "", setArgs(opt).c_str(), opt.scenario.c_str(), seconds,
      sw.points.size(), sw.width, sw.height, renderEvery);
  // ---- 2. the reference ----
  const RunResult ref = runPoint(opt, sw, sw.reference, seconds, renderEvery);
  ESIM_RUN_CHECK(ref.error.empty(), "the reference run failed: " + ref.error);
  std::printf(
      "reference: %d nodes, %d frames at %.0f fps, %.1f s wall; energy %.3f J, removed "
      "%.1f mm^3, groove %.2f x %.2f mm\n",
      ref.nodes, ref.frames, ref.fps, ref.wallS, ref.energyJ, ref.groove.removedVolumeM3 * 1e9,
      ref.groove.widthM * 1e3, ref.groove.depthM * 1e3);
  if (!ref.lastImage.empty())
    writePng((fs::path(opt.out) / "reference_last_frame.png").string(), ref.lastImage, sw.width,
             sw.height);
  // ---- 3. the points ----
  std::printf("%-28s %6s %9s %9s %9s %9s %8s %8s %8s %7s %7s\n", "point", "nodes", "phys_ms",
              "p95_ms", "render_ms", "energy_e", "probe_K", "depth_e", "width_e", "IoU", "PSNR");
  std::vector<RunResult> results;
  std::vector<Errors> errors;
  for (const Point& p : sw.points) {
    results.push_back(runPoint(opt, sw, p, seconds, renderEvery));
    errors.push_back(errorsOf(results.back(), ref));
    const RunResult& r = results.back();
    const Errors& e = errors.back();
    if (!r.error.empty()) {
      std::printf("%-28s FAILED: %s\n", p.name.c_str(), r.error.c_str());
      continue;
    }
    std::printf("%-28s %6d %9.2f %9.2f %9.2f %9.4f %8.2f %8.4f %8.4f %7.3f %7.1f\n", p.name.c_str(),
                r.nodes, r.physicsMedianMs, r.physicsP95Ms, r.renderMedianMs, e.energy, e.probeK,
                e.depth, e.width, e.iou, e.psnrDb);
    std::fflush(stdout);
  }
  // ---- 4. Pareto fronts: physics + render median per frame against the cut's errors ----
  std::vector<double> cost, depthErr, iouErr, energyErr;
  for (size_t i = 0; i < results.size(); ++i) {
    const bool ok = results[i].error.empty();
    cost.push_back(ok ? results[i].physicsMedianMs + results[i].renderMedianMs : kNaN);
    depthErr.push_back(errors[i].depth);
    iouErr.push_back(1 - errors[i].iou);
    energyErr.push_back(errors[i].energy);
  }
  auto onFront = [&](const std::vector<double>& err) {
    std::vector<bool> on(results.size(), false);
    for (int i : app::paretoFront(cost, err)) on[i] = true;
    return on;
  };
  const std::vector<bool> frontDepth = onFront(depthErr), frontIou = onFront(iouErr),
                          frontEnergy = onFront(energyErr);
  // ---- 5. accuracy.csv ----
  const fs::path csvPath = fs::path(opt.out) / "accuracy.csv";
  std::ostringstream csv;  // (each file written whole, or not at all: writeFileAtomic)
  csv << "name,knob,value,mark,baseline,nodes,tets,frames,fps,setup_s,physics_median_ms,physics_"
         "p95_ms,"
         "render_median_ms,render_p95_ms,frame_ms,energy_j,energy_err,probe_rms_k,probe_err,"
         "vapor_mm3,vapor_err,removed_mm3,removed_err,width_mm,width_err,depth_mm,depth_err,iou,"
         "psnr_db,psnr_render_db,mean_potential_ms,mean_heat_ms,mean_stress_ms,mean_removal_ms,"
         "pareto_depth,pareto_iou,pareto_energy,note,error,rerun,run_"
         "command\n";
  auto row = [&](const Point& p, const RunResult& r, const Errors& e, bool fd, bool fi, bool fe) {
    csv << quoteCsv(p.name) << ',' << p.knob << ',' << quoteCsv(p.value) << ',' << p.mark << ','
        << p.baseline << ',' << r.nodes << ',' << r.tets << ',' << r.frames << ',' << num(r.fps)
        << ',' << num(r.setupS) << ',' << num(r.physicsMedianMs) << ',' << num(r.physicsP95Ms)
        << ',' << num(r.renderMedianMs) << ',' << num(r.renderP95Ms) << ','
        << num(r.physicsMedianMs + r.renderMedianMs) << ',' << num(r.energyJ, 6) << ','
        << num(e.energy) << ',' << num(e.probeK) << ',' << num(e.probe) << ','
        << num(r.vaporM3 * 1e9) << ',' << num(e.vapor) << ',' << num(r.groove.removedVolumeM3 * 1e9)
        << ',' << num(e.removedVolume) << ',' << num(r.groove.widthM * 1e3) << ',' << num(e.width)
        << ',' << num(r.groove.depthM * 1e3) << ',' << num(e.depth) << ',' << num(e.iou) << ','
        << num(e.psnrDb) << ',' << num(e.psnrRenderDb) << ','
        << num(r.stageMeanMs[static_cast<int>(Stage::SolvePotential)]) << ','
        << num(r.stageMeanMs[static_cast<int>(Stage::Heat)]) << ','
        << num(r.stageMeanMs[static_cast<int>(Stage::SolveStress)]) << ','
        << num(r.stageMeanMs[static_cast<int>(Stage::Rupture)] +
               r.stageMeanMs[static_cast<int>(Stage::Rebuild)])
        << ',' << fd << ',' << fi << ',' << fe << ',' << quoteCsv(p.tweakNote) << ','
        << quoteCsv(r.error) << ',' << quoteCsv(rerunCommand(opt, p)) << ','
        << quoteCsv(runCommand(opt, sw, p, seconds)) << '\n';
  };
  Errors refErr;
  refErr.energy = refErr.probeK = refErr.probe = refErr.vapor = refErr.removedVolume =
      refErr.width = refErr.depth = 0;
  refErr.iou = 1;
  refErr.psnrDb = refErr.psnrRenderDb = std::numeric_limits<double>::infinity();
  row(sw.reference, ref, refErr, false, false, false);
  for (size_t i = 0; i < results.size(); ++i)
    row(sw.points[i], results[i], errors[i], frontDepth[i], frontIou[i], frontEnergy[i]);
  app::writeFileAtomic(csvPath, csv.str());
  // ---- 6. accuracy.md ----
  const fs::path mdPath = fs::path(opt.out) / "accuracy.md";
  std::ostringstream md;
  md << "`esim bench accuracy" << (opt.quick ? " --quick" : "") << setArgs(opt)
     << "`: " << opt.scenario << ", " << num(seconds) << " s of the cut; reference " << ref.nodes
     << " nodes (graded), " << num(ref.fps) << " fps, electric solver " << ref.electricSolver
     << ", pixel shading + 4x MSAA: energy " << num(ref.energyJ) << " J, removed "
     << num(ref.groove.removedVolumeM3 * 1e9) << " mm^3, groove " << num(ref.groove.widthM * 1e3)
     << " mm wide, " << num(ref.groove.depthM * 1e3)
     << " mm deep. Errors are relative to the reference "
     << "(probe: RMS over " << ref.probeC.size() << " probes in K); ms are per frame (physics "
     << "median / p95, render = snapshot + draw at " << sw.width << "x" << sw.height
     << "). Pareto front (physics + render median against the error): D depth, I IoU, E "
        "energy.\n\n";
  md << "| point | nodes | physics ms (p95) | render ms | energy err | probe K | vapour err | "
        "removed err | width err | depth err | IoU | PSNR dB (render only) | front |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (size_t i = 0; i < results.size(); ++i) {
    const Point& p = sw.points[i];
    const RunResult& r = results[i];
    const Errors& e = errors[i];
    if (!r.error.empty()) {
      md << "| " << p.name << " | failed: " << r.error << " |||||||||||\n";
      continue;
    }
    auto pct = [](double v) { return std::isfinite(v) ? num(100 * v, 3) + " %" : "-"; };
    md << "| " << p.name << (p.mark.empty() ? "" : " (" + p.mark + ")")
       << (p.baseline ? " (baseline)" : "") << " | " << r.nodes << " | "
       << num(r.physicsMedianMs, 3) << " (" << num(r.physicsP95Ms, 3) << ") | "
       << num(r.renderMedianMs, 3) << " | " << pct(e.energy) << " | " << num(e.probeK, 3) << " | "
       << pct(e.vapor) << " | " << pct(e.removedVolume) << " | " << pct(e.width) << " | "
       << pct(e.depth) << " | " << num(e.iou, 3) << " | " << num(e.psnrDb, 3) << " ("
       << num(e.psnrRenderDb, 3) << ") | " << (frontDepth[i] ? "D" : "") << (frontIou[i] ? "I" : "")
       << (frontEnergy[i] ? "E" : "") << " |\n";
  }
  md << "\nWhere the physics time goes in the mesh sweeps: mean ms per frame of each stage over "
        "all "
        "frames (removal = rupture + rebuild, its frames included):\n\n| point | nodes | "
        "potential | heat | stress | removal | physics mean |\n|---|---|---|---|---|---|---|\n";
  for (size_t i = 0; i < results.size(); ++i) {
    const RunResult& r = results[i];
    if (!r.error.empty() || sw.points[i].knob.rfind("mesh_", 0) != 0) continue;
    double total = 0;
    for (double v : r.stageMeanMs) total += v;
    auto at = [&](Stage st) { return num(r.stageMeanMs[static_cast<int>(st)], 3); };
    md << "| " << sw.points[i].name << " | " << r.nodes << " | " << at(Stage::SolvePotential)
       << " | " << at(Stage::Heat) << " | " << at(Stage::SolveStress) << " | "
       << num(r.stageMeanMs[static_cast<int>(Stage::Rupture)] +
                  r.stageMeanMs[static_cast<int>(Stage::Rebuild)],
              3)
       << " | " << num(total, 3) << " |\n";
  }
  // convergence orders of the mesh sweeps (h ~ nodes^(-1/3)) between successive sizes
  md << "\nObserved order of the mesh sweeps, log(e1/e2) / log(h1/h2) with h ~ nodes^(-1/3), "
        "between successive sizes:\n\n| sweep | nodes | energy | probe | removed volume | "
        "depth | 1 - IoU |\n|---|---|---|---|---|---|---|\n";
  for (const char* knob : {"mesh_graded", "mesh_uniform"}) {
    int prev = -1;
    for (size_t i = 0; i < results.size(); ++i) {
      if (sw.points[i].knob != knob || !results[i].error.empty()) continue;
      if (prev >= 0) {
        const double h1 = meshH(results[prev].nodes), h2 = meshH(results[i].nodes);
        auto order = [&](double e1, double e2) {
          return num(app::convergenceOrder(h1, e1, h2, e2), 2);
        };
        md << "| " << knob << " | " << results[prev].nodes << " -> " << results[i].nodes << " | "
           << order(errors[prev].energy, errors[i].energy) << " | "
           << order(errors[prev].probeK, errors[i].probeK) << " | "
           << order(errors[prev].removedVolume, errors[i].removedVolume) << " | "
           << order(errors[prev].depth, errors[i].depth) << " | "
           << order(1 - errors[prev].iou, 1 - errors[i].iou) << " |\n";
      }
      prev = static_cast<int>(i);
    }
  }
  // ---- the analytic case: the disc electrode's resistance, 1 / (4 sigma a) ----
  {
    const double a = 0.002, sigma = 0.144, exact = 1 / (4 * sigma * a);
    md << "\nThe analytic case: a disc electrode (a = 2 mm) on a half-space, R = 1 / (4 sigma a) = "
       << num(exact)
       << " ohm (tools/app/analytic_disc.h), h = a / m:\n\n| m | nodes | R ohm | "
          "error | order | ms (assembly + factorization + solve) |\n|---|---|---|---|---|---|\n";
    std::ostringstream dcsv;
    dcsv << "m,h_m,nodes,resistance_ohm,exact_ohm,error,order,ms\n";
    double prevErr = kNaN;
    int prevM = 0;
    for (int m : opt.quick ? std::vector<int>{2, 3, 4} : std::vector<int>{2, 3, 4, 6, 8}) {
      const app::DiscResult d = app::discResistance(m, a, sigma);
      const double err = relative(d.resistanceOhm, exact);
      const double order = prevM > 0 ? app::convergenceOrder(a / prevM, prevErr, a / m, err) : kNaN;
      md << "| " << m << " | " << d.nodes << " | " << num(d.resistanceOhm, 6) << " | "
         << num(100 * err, 3) << " % | " << num(order, 3) << " | " << num(d.solveMs, 3) << " |\n";
      dcsv << m << ',' << num(a / m) << ',' << d.nodes << ',' << num(d.resistanceOhm, 8) << ','
           << num(exact, 8) << ',' << num(err) << ',' << num(order) << ',' << num(d.solveMs)
           << '\n';
      std::printf(
          "disc electrode h = a/%d: %d nodes, R %.4f ohm (exact %.4f), error %.3f %%, "
          "order %s, %.0f ms\n",
          m, d.nodes, d.resistanceOhm, exact, 100 * err, num(order, 3).c_str(), d.solveMs);
      prevErr = err;
      prevM = m;
    }
    app::writeFileAtomic(fs::path(opt.out) / "analytic_disc.csv", dcsv.str());
  }
  md << "\nRerun a row: the `rerun` column of accuracy.csv (`esim bench accuracy --only NAME`); "
        "the `run_command` column is the same physics as an `esim run`.\n";
  app::writeFileAtomic(mdPath, md.str());
  std::printf("wrote %s, %s\n", printablePath(csvPath.string()).c_str(),
              printablePath(mdPath.string()).c_str());
  // ---- 7. accuracy_vs_time.png ----
  if (!opt.noPlot) {
    const fs::path png = fs::path(opt.out) / "accuracy_vs_time.png";
    const app::PlotResult pr =
        app::runPlotScript("plot_accuracy.py", {csvPath.string(), "-o", png.string()});
    if (pr.status == app::PlotStatus::Written)
      std::printf("wrote %s\n", printablePath(png.string()).c_str());
    else
      std::cerr << "esim: warning: no accuracy_vs_time.png: " << printableMessage(pr.message)
                << "\n";
  }
  return kExitOk;
}

Registrar reg({"bench", "accuracy"},
              "What accuracy costs in time: the slab cut swept over mesh, solvers, time step, "
              "rebuild and renderer, errors against a reference run",
              [](CLI::App& app) -> Runner {
                auto opt = std::make_shared<AccuracyOptions>();
                app.add_flag("--quick", opt->quick,
                             "the CI sweep: smaller meshes, 0.6 s of the cut (under 2 minutes)");
                app.add_option("--out", opt->out, "output folder")->capture_default_str();
                app.add_option("--scenario", opt->scenario, "the cut scene")->capture_default_str();
                app.add_option("--only", opt->only,
                               "run the reference and these points only: names or knobs, comma "
                               "separated (e.g. mesh_graded,electric:pcg_1e-2)");
                app.add_option("--seconds", opt->seconds,
                               "simulated seconds of the cut (0: the default, 2, --quick 0.6)")
                    ->check(CLI::Range(0.0, 4.0));
                app.add_option("--render-every", opt->renderEvery,
                               "render every Nth frame (0: the default, 5, --quick 3)")
                    ->check(CLI::Range(0, 1000));
                app.add_flag("--no-plot", opt->noPlot, "no accuracy_vs_time.png");
                app.add_option("--set", opt->sets,
                               "KEY=VALUE: a scenario value for every point and the reference, "
                               "as esim run's --set (a point's own knob wins; e.g. "
                               "material.critical_stress_radius_m=0.00075)");
                return [opt] {
                  AccuracyOptions o = *opt;
                  o.scenario = app::benchScenarioPath(o.scenario, kDefaultScenario);
                  return benchAccuracy(o);
                };
              });

}  // namespace
}  // namespace esim::cli
