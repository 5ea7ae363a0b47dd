// cmd_run.cpp - `esim run SCENARIO`: simulate, render, encode, report.
//
// 1. Load and validate the scenario (+ --set overrides).
// 2. Build the mesh (slab generator or surface file + CGAL) and the phases the scene lists.
// 3. Open the renderer; only now create the output folder (as DIR.partial).
// 4. Frame loop: physics stages -> snapshot -> render -> encoder queue / PNG / hashes / VTU.
// 5. Close the video, write timing.csv, timing.json, trace.json, hashes.json,
//    scenario.yaml, summary.txt; rename DIR.partial to DIR.
// 6. Print the one-screen summary.
// Bad input (steps 1-3) exits 2 with nothing written. Ctrl-C stops after the current
// frame and still closes the video properly (the summary says "interrupted").
#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>

#include "render/image_hash.h"
#include "render/image_png.h"
#include "render/renderer.h"
#include "render/video_encoder.h"
#include "sim/core_error.h"
#include "sim/io/mesh_import.h"
#include "sim/io/scenario.h"
#include "sim/io/vtu.h"
#include "sim/mesh_slab.h"
#include "sim/simulation.h"
#include "tools/esim/command.h"
#include "tools/esim/run_report.h"

namespace esim::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::atomic<bool> gInterrupted{false};
extern "C" void onSignal(int) { gInterrupted = true; }

struct RunOptions {
  std::string scenario;
  std::string outDir;
  int frames = 0;        // 0: from the scenario
  int fieldsEvery = -1;  // -1: from the scenario
  std::vector<std::string> sets;
  bool noVideo = false;
  bool quiet = false;
};

// ---- scenario -> simulation ----
// above this the run's temperatures are outside what the model describes (no charring,
// no ablation): the summary and timing.json say so [C]
constexpr double kImplausibleTemperatureC = 300.0;

SimulationConfig makeConfig(const Scenario& s) {
  SimulationConfig c;
  c.phases.electric = s.has(Phase::Electric);
  c.phases.thermal = s.has(Phase::Thermal);
  c.phases.boiling = s.has(Phase::Boiling);
  c.phases.structural = s.has(Phase::Structural);
  c.phases.rupture = s.has(Phase::Rupture);
  c.frameDtS = 1.0 / s.time.fps;
  const auto& m = s.material;
  c.conductivityS_m = m.electricConductivitySPerM;
  c.toolVoltageV = s.tool.voltageV;
  c.contactDistanceM = s.tool.contactDistanceM;
  c.electrode.kind = s.tool.shape == "sphere" ? ElectrodeKind::Sphere : ElectrodeKind::Blade;
  c.electrode.radiusM = s.tool.radiusM;
  c.electrode.lengthM = s.tool.lengthM;
  c.electrode.widthM = s.tool.widthM;
  c.returnElectrode.centerM = s.returnElectrode.centerM;
  c.returnElectrode.normal = s.returnElectrode.normal;
  c.returnElectrode.radiusM = s.returnElectrode.radiusM;
  c.returnElectrode.toleranceM = s.returnElectrode.toleranceM;
  c.toolPath = makeToolPath(s);
  c.electricSolver.strategy = parseElectricStrategy(s.solvers.electricStrategy);
  c.electricSolver.pcgTolerance = s.solvers.electricTolerance;
  c.electricSolver.pcgMaxIterations = s.solvers.electricMaxIterations;
  c.electricSolver.denseMemoryLimitBytes = s.solvers.electricDenseMemoryLimitMb * 1048576.0;
  c.electricSolver.threads = s.solvers.electricThreads;
  c.prefetchUntilS = s.solvers.electricPrefetchPath ? s.time.durationS : 0.0;
  c.temperatureDependentConductivity = s.effects.temperatureDependentConductivity;
  c.conductivityTempCoeffPerK = m.conductivityTempCoeffPerK;
  c.desiccatedConductivityFactor = m.desiccatedConductivityFactor;
  ThermalParams& t = c.thermal;
  t.heatCapacityJ_m3K = m.heatCapacityJPerM3K;
  t.conductivityW_mK = m.thermalConductivityWPerMK;
  t.initialTemperatureC = m.initialTemperatureC;
  t.boiling = c.phases.boiling;
  t.boilingTemperatureC = m.boilingTemperatureC;
  t.waterFraction = m.waterFraction;
  t.densityKg_m3 = m.densityKgPerM3;
  t.latentHeatJ_kg = m.latentHeatJPerKg;
  t.integrator = parseThermalIntegrator(s.solvers.thermalIntegrator);
  t.lumpedMass = s.solvers.thermalMass == "lumped";
  t.allowSubstepping = s.solvers.thermalAllowSubstepping;
  t.convectionW_m2K = s.effects.surfaceCoolingHWPerM2K;
  t.ambientTemperatureC = s.effects.surfaceCoolingAmbientC;
  t.damage = s.effects.thermalDamage;
  t.arrheniusA_s = m.arrheniusAPerS;
  t.arrheniusEa_J_mol = m.arrheniusEaJPerMol;
  c.coolTopSurface = s.effects.surfaceCoolingHWPerM2K > 0;
  c.heatSource.enabled = s.heatSource.kind == "gaussian";
  c.heatSource.centerM = s.heatSource.centerM;
  c.heatSource.radiusM = s.heatSource.radiusM;
  c.heatSource.powerDensityW_m3 = s.heatSource.powerDensityWPerM3;
  c.hotSpot.enabled = s.initialHotSpot.enabled;
  c.hotSpot.centerM = s.initialHotSpot.centerM;
  c.hotSpot.radiusM = s.initialHotSpot.radiusM;
  c.hotSpot.temperatureC = s.initialHotSpot.temperatureC;
  c.structural.youngsModulusPa = m.youngsModulusPa;
  c.structural.poissonRatio = m.poissonRatio;
  c.criticalStressPa = m.criticalStressPa;
  c.vaporLiquidVolumeRatio = m.vaporLiquidVolumeRatio;
  c.maxVaporExpansion = m.maxVaporExpansion;
  c.clampBandM = s.effects.structuralClampBandM;
  c.backgroundRebuild = s.solvers.rebuildMode == "background";
  c.rebuildLagFrames = s.solvers.rebuildLagFrames;
  c.recomputeLagFrames = s.solvers.rebuildRecompute;
  return c;
}

TetMesh buildMesh(const Scenario& s, double* seconds) {
  const auto t0 = Clock::now();
  TetMesh mesh;
  if (s.mesh.source == "slab") {
    mesh = makeSlab(makeSlabSpec(s));
  } else {
    const auto& f = s.mesh.file;
    const MeshingOptions o = makeMeshingOptions(s);  // sizes and refinement near the cut
    mesh = loadTetMesh(f.resolvedPath.empty() ? f.path : f.resolvedPath, o, f.scaleToM);
  }
  *seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return mesh;
}

RenderOptions makeRenderOptions(const Scenario& s) {
  RenderOptions r;
  r.width = s.look.width;
  r.height = s.look.height;
  r.look = s.look.style;
  for (int c = 0; c < 3; ++c) {
    r.eyeM[c] = static_cast<float>(s.camera.eyeM[c]);
    r.targetM[c] = static_cast<float>(s.camera.targetM[c]);
    r.up[c] = static_cast<float>(s.camera.up[c]);
  }
  r.fovDeg = static_cast<float>(s.camera.fovDeg);
  r.tMinC = static_cast<float>(s.look.tMinC);
  r.tMaxC = static_cast<float>(s.look.tMaxC);
  r.vMinV = static_cast<float>(s.look.vMinV);
  r.vMaxV = static_cast<float>(s.look.vMaxV != 0.0 ? s.look.vMaxV : s.tool.voltageV);  // 0: tool
  r.potentialLogScale = s.look.potentialScale == "log";
  r.colormap = s.look.colormap;
  r.showColorBar = s.look.colorBar;
  r.showTime = s.look.showTime;
  r.msaaSamples = s.look.msaa;
  r.shading = s.look.shading;
  return r;
}

void writeText(const fs::path& path, const std::string& text) {
  std::ofstream os(path, std::ios::binary);
  os << text;
  ESIM_VERIFY(os.good(), path.string() + ": write failed");
}

// interactive (physics + render) time statistics
StageStats stageStatsInteractive(const std::vector<FrameRecord>& records) {
  std::vector<double> ms;
  for (const auto& r : records) ms.push_back(interactiveMs(r));
  return seriesStats(ms);
}

// fields of the phases the scene has, as VTU (see README: fields for inspection)
void writeFields(const std::string& path, const Simulation& sim) {
  const TetMesh& m = sim.mesh();
  std::vector<VtuField> point, cell;
  std::vector<double> bc(m.numNodes(), 0.0);
  if (sim.hasElectric()) {
    point.push_back(
        {"potential", 1,
         std::vector<double>(sim.potentialV().data(), sim.potentialV().data() + m.numNodes())});
    for (int v : sim.contactNodes()) bc[v] = 1;
    for (int v : sim.groundNodes()) bc[v] = 2;
    point.push_back({"bc", 1, bc});
    cell.push_back({"conductivity", 1, sim.conductivityS_m()});
    cell.push_back({"joule_power", 1, sim.joulePowerW_m3()});
  }
  if (const ThermalState* t = sim.thermalState()) {
    point.push_back(
        {"temperature", 1,
         std::vector<double>(t->temperatureC.data(), t->temperatureC.data() + m.numNodes())});
    if (!t->vaporFractionTet.empty()) cell.push_back({"vapor_fraction", 1, t->vaporFractionTet});
    if (!t->coagulationTet.empty()) cell.push_back({"coagulation", 1, t->coagulationTet});
  }
  if (const std::vector<double>* vm = sim.vonMisesPa()) cell.push_back({"von_mises", 1, *vm});
  std::vector<double> alive(m.numTets());
  for (int e = 0; e < m.numTets(); ++e) alive[e] = m.isAlive(e) ? 1.0 : 0.0;
  cell.push_back({"alive", 1, alive});
  writeVtu(path, m, point, cell);
}

// peak resident memory of this process so far [MB]
double peakRssMb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;  // ru_maxrss is in kB on Linux
}

// ---- progress ----
class Progress {
 public:
  Progress(int total, bool quiet) : total_(total), quiet_(quiet), tty_(isatty(2) != 0) {}
  void update(int done, double simTimeS) {
    if (quiet_) return;
    const double wall = std::chrono::duration<double>(Clock::now() - start_).count();
    const double fps = wall > 0 ? done / wall : 0;
    const double eta = fps > 0 ? (total_ - done) / fps : 0;
    if (tty_) {
      const int width = 30, fill = total_ ? width * done / total_ : width;
      std::fprintf(stderr, "\r[%s%s] %d/%d frames  t=%.2f s  %.1f fps  ETA %.0f s ",
                   std::string(fill, '#').c_str(), std::string(width - fill, '-').c_str(), done,
                   total_, simTimeS, fps, eta);
      if (done == total_) std::fprintf(stderr, "\n");
    } else if (wall - lastLine_ >= 5.0 || done == total_) {
      lastLine_ = wall;
      std::fprintf(stderr, "esim: %d/%d frames, t=%.2f s, %.1f fps, ETA %.0f s\n", done, total_,
                   simTimeS, fps, eta);
    }
  }

 private:
  int total_;
  bool quiet_, tty_;
  Clock::time_point start_ = Clock::now();
  double lastLine_ = -1e9;
};

int runScenario(const RunOptions& opt) {
  // ---- 1. scenario ----
  Scenario sc = loadScenario(opt.scenario, opt.sets);
  int frames = opt.frames > 0 ? opt.frames : frameCount(sc);
  const int fields_every = opt.fieldsEvery >= 0 ? opt.fieldsEvery : sc.output.fieldsEvery;
  const bool video = sc.output.video && !opt.noVideo;
  const fs::path out = opt.outDir.empty() ? fs::path("out") / sc.name : fs::path(opt.outDir);

  // ---- 2. mesh and physics ----
  double mesh_s = 0;
  TetMesh mesh = buildMesh(sc, &mesh_s);
  const int nodes = mesh.numNodes(), tets = mesh.numTets();
  const auto build_t0 = Clock::now();
  Simulation sim(std::move(mesh), makeConfig(sc));
  const double setup_s = std::chrono::duration<double>(Clock::now() - build_t0).count();
  const double rss_after_setup_mb = peakRssMb();

  // ---- 3. renderer, then the output folder ----
  const bool need_render = video || sc.output.pngEvery > 0 || sc.output.hashes;
  std::unique_ptr<Renderer> renderer;
  if (need_render) renderer = std::make_unique<Renderer>(makeRenderOptions(sc));
  const fs::path partial = out.string() + ".partial";
  fs::remove_all(partial);
  fs::create_directories(partial);
  // from here on, a failure removes the half-written folder before it propagates
  struct PartialGuard {
    fs::path dir;
    bool armed = true;
    ~PartialGuard() {
      if (!armed) return;
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } guard{partial};
  std::unique_ptr<VideoEncoder> encoder;
  if (video) {
    VideoEncoder::Options vo;
    vo.path = (partial / "video.mp4").string();
    vo.width = sc.look.width;
    vo.height = sc.look.height;
    vo.fps = static_cast<int>(std::lround(sc.time.fps));
    vo.crf = sc.output.crf;
    vo.preset = sc.output.preset;
    vo.reproducible = sc.output.reproducible;
    encoder = std::make_unique<VideoEncoder>();
    encoder->open(vo);
  }
  if (sc.output.pngEvery > 0) fs::create_directories(partial / "frames");
  if (fields_every > 0) fs::create_directories(partial / "fields");

  // ---- 4. frame loop ----
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  std::vector<FrameRecord> records;
  std::vector<double> frame_start_us;
  nlohmann::json frame_hashes = nlohmann::json::array();
  FrameHashSequence all_hash;
  Progress progress(frames, opt.quiet);
  const auto loop_t0 = Clock::now();
  double peak_power_w = 0;
  for (int f = 0; f < frames && !gInterrupted; ++f) {
    frame_start_us.push_back(
        std::chrono::duration<double, std::micro>(Clock::now() - loop_t0).count());
    sim.step();
    SurfaceSnapshot snap;
    if (renderer) snap = sim.snapshot();
    FrameRecord rec = sim.lastRecord();
    peak_power_w = std::max(peak_power_w, rec.powerW);
    if (renderer) {
      const std::vector<std::uint8_t>* rgb = nullptr;
      {
        StageTimer timer(rec, Stage::Render);
        rgb = &renderer->render(snap);
      }
      const std::uint64_t h = hashFrame(*rgb);
      all_hash.add(h);
      frame_hashes.push_back(
          {{"frame", f},
           {"xxh3", hashToHex(h)},
           {"dhash", hashToHex(perceptualHash(*rgb, sc.look.width, sc.look.height))}});
      if (sc.output.pngEvery > 0 && f % sc.output.pngEvery == 0) {
        std::ostringstream name;
        name << "frame_" << std::setw(5) << std::setfill('0') << f << ".png";
        writePng((partial / "frames" / name.str()).string(), *rgb, sc.look.width, sc.look.height);
      }
      if (encoder) {
        StageTimer timer(rec, Stage::Encode);
        encoder->push(*rgb);
      }
    }
    if (fields_every > 0 && f % fields_every == 0) {
      std::ostringstream name;
      name << "frame_" << std::setw(5) << std::setfill('0') << f << ".vtu";
      writeFields((partial / "fields" / name.str()).string(), sim);
    }
    records.push_back(rec);
    progress.update(f + 1, sim.timeS());
  }
  const double loop_s = std::chrono::duration<double>(Clock::now() - loop_t0).count();

  // ---- 5. close the video and write the reports ----
  double encode_s = 0;
  std::string encoder_codec;
  if (encoder) {
    encoder->close();
    encode_s = encoder->encodeSeconds();
    encoder_codec = encoder->codecName();
  }
  const std::uint64_t total_hash = all_hash.combined();
  const int frames_done = static_cast<int>(records.size());
  const Eigen::VectorXd temp = sim.temperatureC();

  nlohmann::json extra;
  extra["scenario"] = sc.name;
  extra["scenario_hash"] = hashToHex(scenarioHash(sc));
  extra["interrupted"] = gInterrupted.load();
  extra["mesh"] = {{"nodes", nodes}, {"tets", tets}, {"build_s", mesh_s}};
  extra["setup_s"] = setup_s;
  extra["peak_rss_mb"] = peakRssMb();
  extra["peak_rss_after_setup_mb"] = rss_after_setup_mb;
  extra["frame_loop_s"] = loop_s;
  extra["offline"] = {{"encode_s", encode_s},
                      {"codec", encoder_codec},
                      {"note", "libav encoding on its own thread, not in the 30 Hz budget"}};
  extra["machine"] = machineInfo();
  extra["threads"] = {{"blas", sc.solvers.electricThreads},
                      {"encoder", sc.output.reproducible ? 1 : 0}};
  extra["electric_solver"] = sim.electricSolverName();
  extra["build"] = {{"compiler", __VERSION__}, {"esim", "0.1.0"}};
  extra["electric_memory_mb"] = sim.electricMemoryBytes() / 1048576.0;
  // results a demanding user should not take at face value
  std::vector<std::string> warnings;
  if (sim.maxTemperatureSeenC() > kImplausibleTemperatureC) {
    char w[400];
    std::snprintf(w, sizeof w,
                  "the tissue reached %.0f C: above ~%.0f C it chars and ablates, which the model "
                  "does not include; lower tool.voltage_v, or enable "
                  "effects.temperature_dependent_conductivity (drying cuts the current) or the "
                  "structural and rupture phases (boiling tissue is removed)",
                  sim.maxTemperatureSeenC(), kImplausibleTemperatureC);
    warnings.push_back(w);
  }
  extra["warnings"] = warnings;
  if (sim.config().phases.structural)
    extra["structural"] = {
        {"removed_tets", sim.removedTets()},
        {"alive_tets", sim.mesh().numAlive()},
        {"rebuild_mode", sc.solvers.rebuildMode},
        {"rebuild_lag_frames", sc.solvers.rebuildLagFrames},
        {"rebuilds", sim.rebuilds()},
        {"rebuilds_late", sim.rebuildsLate()},
        {"rebuild_build_ms_mean", sim.rebuilds() > 0 ? sim.rebuildBuildMs() / sim.rebuilds() : 0.0},
        {"rebuild_wait_ms_max", sim.maxRebuildWaitMs()},
        {"recomputed_frames", sim.recomputedFrames()}};
  if (renderer) {
    extra["renderer"] = {{"gl_renderer", renderer->glRenderer()},
                         {"gl_version", renderer->glVersion()},
                         {"platform", renderer->glPlatform()}};
  }
  const nlohmann::json timing = timingJson(records, extra);
  writeText(partial / "timing.json", timing.dump(2) + "\n");
  writeText(partial / "timing.csv", timingCsv(records));
  writeText(partial / "trace.json", chromeTrace(records, frame_start_us).dump() + "\n");
  writeText(partial / "scenario.yaml", scenarioToYaml(sc));
  if (renderer && sc.output.hashes) {
    nlohmann::json hj;
    hj["frames"] = frame_hashes;
    hj["all_frames_xxh3"] = hashToHex(total_hash);
    hj["hash_definition"] =
        "xxh3-64 (seed 0) of the raw RGB24 bytes, top row first; all_frames: xxh3-64 of the "
        "frame hashes as little-endian uint64; dhash: 64-bit difference hash (render/image_hash.h)";
    hj["width"] = sc.look.width;
    hj["height"] = sc.look.height;
    hj["renderer"] = extra["renderer"];
    hj["libraries"] = VideoEncoder::libraryVersions();
    hj["png_every"] = sc.output.pngEvery;
    hj["scenario_hash"] = extra["scenario_hash"];
    writeText(partial / "hashes.json", hj.dump(2) + "\n");
  }

  // ---- 6. summary ----
  std::ostringstream sum;
  sum << std::fixed;
  sum.precision(2);
  sum << "esim run " << sc.name << (gInterrupted ? "  (INTERRUPTED)" : "") << "\n";
  sum << "  mesh        " << nodes << " nodes, " << tets << " tets (built in " << mesh_s
      << " s), setup " << setup_s << " s\n";
  sum << "  frames      " << frames_done << " of " << frames << ", simulated " << sim.timeS()
      << " s at " << sc.time.fps << " fps, wall " << loop_s << " s\n";
  sum << "  stage          median ms     p95 ms   skipped\n";
  for (int s = 0; s < kStageCount; ++s) {
    const StageStats st = stageStats(records, static_cast<Stage>(s));
    if (st.ran + st.skipped == 0) continue;
    char line[160];
    std::snprintf(line, sizeof line, "  %-14s %10.3f %10.3f %9d\n",
                  stageName(static_cast<Stage>(s)), st.p50Ms, st.p95Ms, st.skipped);
    sum << line;
  }
  const StageStats inter = stageStatsInteractive(records);
  char line[200];
  std::snprintf(line, sizeof line,
                "  interactive    %10.3f %10.3f   (physics+render; %d of %d frames over 33.3 ms)\n",
                inter.p50Ms, inter.p95Ms, timing["frames_over_budget"].get<int>(), frames_done);
  sum << line;
  sum << "  encode        " << encode_s << " s offline (own thread)\n";
  sum << "  memory        peak " << peakRssMb() << " MB resident (" << rss_after_setup_mb
      << " MB after setup)\n";
  sum.precision(1);
  sum << "  temperature   max " << sim.maxTemperatureSeenC() << " C (now " << temp.maxCoeff()
      << " C)\n";
  for (const std::string& w : warnings) sum << "  WARNING       " << w << "\n";
  sum.precision(3);
  sum << "  energy        " << sim.energyDeliveredJ() << " J delivered, peak power " << peak_power_w
      << " W\n";
  if (sim.config().phases.structural) {
    double peakVm = 0;
    for (const FrameRecord& r : records) peakVm = std::max(peakVm, r.maxVonMisesPa);
    sum << "  structural    peak von Mises " << peakVm << " Pa; " << sim.removedTets()
        << " tets removed in " << sim.rebuilds() << " frames (" << sim.mesh().numAlive() << " of "
        << sim.mesh().numTets() << " alive)\n";
    if (sim.config().phases.rupture && sim.rebuilds() > 0) {
      sum << "  rebuild       " << sim.rebuilds() << " rebuilds, "
          << (sim.config().backgroundRebuild
                  ? "background, swapped in " + std::to_string(sim.config().rebuildLagFrames) +
                        " frames after the rupture"
                  : std::string("synchronous"))
          << "; build " << sim.rebuildBuildMs() / sim.rebuilds() << " ms mean";
      if (sim.config().backgroundRebuild)
        sum << "; lag missed " << sim.rebuildsLate() << " times (longest wait "
            << sim.maxRebuildWaitMs() << " ms); " << sim.recomputedFrames() << " frames recomputed";
      sum << "\n";
    }
  }
  if (encoder) encoder.reset();
  fs::remove_all(out);
  fs::rename(partial, out);
  guard.armed = false;
  sum << "  outputs       " << out.string() << "/ {" << (video ? "video.mp4, " : "")
      << "timing.csv, timing.json, trace.json, scenario.yaml"
      << (renderer && sc.output.hashes ? ", hashes.json" : "")
      << (sc.output.pngEvery > 0 ? ", frames/" : "") << (fields_every > 0 ? ", fields/" : "")
      << "}\n";
  writeText(out / "summary.txt", sum.str());
  std::cout << sum.str();
  return gInterrupted ? kExitFailure : kExitOk;
}

Registrar reg({"run"}, "Run a scenario: simulate, render, encode, report",
              [](CLI::App& app) -> Runner {
                auto opt = std::make_shared<RunOptions>();
                app.add_option("scenario", opt->scenario, "scenario YAML file")->required();
                app.add_option("-o,--out", opt->outDir, "output folder (default out/<name>)");
                app.add_option("--frames", opt->frames,
                               "number of frames (default: duration x fps)")
                    ->check(CLI::PositiveNumber);
                app.add_option("--fields", opt->fieldsEvery,
                               "write every Nth frame's fields as VTU (0: none)")
                    ->check(CLI::NonNegativeNumber);
                app.add_option("--set", opt->sets, "override a scenario field: key.path=value");
                app.add_flag("--no-video", opt->noVideo, "skip video encoding");
                app.add_flag("-q,--quiet", opt->quiet, "no progress output");
                return [opt] { return runScenario(*opt); };
              });

}  // namespace
}  // namespace esim::cli
