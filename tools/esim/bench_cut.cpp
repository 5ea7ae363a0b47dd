// bench_cut.cpp - `esim bench cut`: the whole cut (electric, thermal, boiling, structural,
// rupture) per mesh size and rebuild strategy, measured side by side in one run: the physics
// per frame, and with --render the drawing of each frame apart.
//
// The scene is scenarios/slab_cut.yaml (a blade drawn 40 mm through a 60 x 30 x 10 mm slab,
// graded along the cut) with mesh.slab.nodes set to each --sizes entry, tool.voltage_v to
// --voltage and solvers.rebuild.mode to each strategy; --frames frames (default: the whole
// 4 s cut, 120 frames). Per (strategy, size): physics time per frame (median, p95, max,
// removal frames included), tets removed, rebuilds, the rebuild stage's median on the frames
// that removed tets, and the frames that waited for a background rebuild. --csv writes
// strategy,nodes,frames,median_ms,p95_ms,max_ms,removed_tets,rebuilds,rebuild_median_ms,waits
// when the bench ends (app::CsvOutput: an earlier FILE stays as it was until then). Every run's
// scenario is checked before the first run. --stages adds each stage's median / p95 / max, the
// parts of a removal in update mode, the structural update's work (CHOLMOD's entries of L
// walked times the columns passing them) and its rate, and the slowest frames. A benchmark,
// never a pass/fail test.
// --render draws every frame as `esim run` does (the scene's look and frame size; --set
// look.msaa=0 etc. change it): the snapshot stays in the physics time, as in esim run's
// timing.csv, the drawing is timed apart, and the table gains render_median_ms, render_p95_ms
// and the physics + render time per frame (interactive_median_ms, interactive_p95_ms: the
// quantity of the 30 Hz target). In update mode the structural update's thread runs on
// while the frame is drawn, as in esim run. Encoding (esim run's own thread) is left out.
// --repeat N runs the whole table N times, round after round (each round every size,
// strategy and method once, so that a machine's slow spell falls on all of them alike), adds
// a round column to the CSV, and ends with each row's range over the rounds: median and p95
// (lowest / median / highest round), their ratio to the same round's update row at that size
// and structural method (the side-by-side ratio, one per round) and whether every round removed the
// same tets in the same count (each strategy is deterministic: a difference is a finding, not
// noise).
// --structural and --electric list solver choices (solvers.structural.method,
// solvers.electric.strategy): every pair runs, and each run after the first is compared with
// the first: the tets removed by one of the two only, the frames before their removed sets
// first differ, and the largest relative difference of the Joule power over those frames
// (what an inexact method gives up, e.g. --electric pcg,local).
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "render/renderer.h"
#include "sim/core_error.h"
#include "sim/io/scenario.h"
#include "sim/message_text.h"
#include "sim/simulation.h"
#include "tools/app/bench_common.h"
#include "tools/app/run_config.h"
#include "tools/app/run_report.h"
#include "tools/esim/command.h"

namespace esim {
namespace {

// the scene when --scenario is not given (found from any working folder: benchScenarioPath)
constexpr const char* kDefaultScenario = "scenarios/slab_cut.yaml";

struct BenchCutOptions {
  std::string sizes = "1013,8000,20000,50000";
  std::string strategy = "all";
  std::string scenario = kDefaultScenario;
  double voltageV = 200;
  int frames = 0;  // 0: the scenario's duration
  std::string csv;
  bool stages = false;              // per-stage median / p95 / max under each row
  bool render = false;              // draw every frame, timed apart
  std::string structural = "full";  // solvers.structural.method values, comma separated
  std::string electric;             // solvers.electric.strategy values (empty: the scene's)
  bool electricCheck = false;       // local: each frame's power against a full solve
  double paceHz = 0;  // > 0: each frame starts on its tick of a loop at this rate (as a
                      // haptic or display loop runs), not right after the last one
  std::vector<std::string> overrides;  // --set KEY=VALUE, after the bench's own
  int repeat = 1;                      // rounds of the whole table
};

// one row of the table (a size, strategy and method in one round): what --repeat sums up
struct CutRow {
  std::string label, strategy, method;
  int nodes = 0;
  double medianMs = 0, p95Ms = 0;
  std::vector<std::uint8_t> alive;  // the removed set (its zeros), compared between rounds
  int removed() const { return static_cast<int>(std::count(alive.begin(), alive.end(), 0)); }
};

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

// one run's solver choice: a structural method and an electric strategy ("": the scene's)
struct Variant {
  std::string method, electric;
  std::string name() const { return electric.empty() ? method : method + "+" + electric; }
};

// the scenario values of one run: the bench's own, then --set
std::vector<std::string> runSets(const BenchCutOptions& opt, int nodes, const std::string& strategy,
                                 const Variant& variant) {
  std::vector<std::string> sets = {
      "mesh.slab.nodes=" + std::to_string(nodes), "tool.voltage_v=" + scenarioNumber(opt.voltageV),
      "solvers.rebuild.mode=" + strategy, "solvers.structural.method=" + variant.method,
      "physics=[electric,thermal,boiling,structural,rupture]"};
  if (!variant.electric.empty()) sets.push_back("solvers.electric.strategy=" + variant.electric);
  sets.insert(sets.end(), opt.overrides.begin(), opt.overrides.end());
  return sets;
}

// --repeat: each row's range over the rounds, its ratio to the update row of the same size
// in the same round, and whether the rounds removed the same tets
void printRounds(const std::vector<std::vector<CutRow>>& rounds) {
  const size_t rows = rounds.front().size();
  const auto range = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    char text[96];
    std::snprintf(text, sizeof text, "%.2f / %.2f / %.2f", v.front(), v[v.size() / 2], v.back());
    return std::string(text);
  };
  std::printf(
      "over %zu rounds (each value: lowest / median / highest round; x update: the ratio to the "
      "update row of the same size in the same round)\n",
      rounds.size());
  int width = 12;  // the labels' column
  for (const CutRow& row : rounds.front())
    width = std::max(width, static_cast<int>(row.label.size()));
  std::printf("%-*s %7s %26s %26s %22s %22s  %s\n", width, "strategy", "nodes", "median_ms",
              "p95_ms", "median x update", "p95 x update", "removed");
  for (size_t k = 0; k < rows; ++k) {
    std::vector<double> med, p95, medRatio, p95Ratio;
    bool same = true;
    std::string counts;
    for (const std::vector<CutRow>& round : rounds) {
      const CutRow& row = round[k];
      med.push_back(row.medianMs);
      p95.push_back(row.p95Ms);
      same = same && row.alive == rounds.front()[k].alive;
      counts += (counts.empty() ? "" : ", ") + std::to_string(row.removed());
      for (const CutRow& other : round)
        if (other.nodes == row.nodes && other.strategy == "update" && other.method == row.method &&
            other.medianMs > 0 && other.p95Ms > 0) {
          medRatio.push_back(row.medianMs / other.medianMs);
          p95Ratio.push_back(row.p95Ms / other.p95Ms);
        }
    }
    const CutRow& first = rounds.front()[k];
    std::printf("%-*s %7d %26s %26s %22s %22s  %s\n", width, first.label.c_str(), first.nodes,
                range(med).c_str(), range(p95).c_str(),
                medRatio.size() == rounds.size() ? range(medRatio).c_str() : "-",
                p95Ratio.size() == rounds.size() ? range(p95Ratio).c_str() : "-",
                same ? (std::to_string(first.removed()) + " tets, the same in every round").c_str()
                     : ("DIFFERENT sets between rounds: " + counts + " tets").c_str());
  }
}

int benchCut(const BenchCutOptions& opt) {
  const std::vector<int> sizes = app::parseNodeCounts(opt.sizes, "bench cut");
  std::vector<std::string> strategies =
      opt.strategy == "all" ? std::vector<std::string>{"synchronous", "background", "update"}
                            : app::splitList(opt.strategy);
  ESIM_VERIFY(!strategies.empty(),
              "--strategy is empty; expected synchronous, background, update (comma separated) or "
              "all");
  for (const std::string& s : strategies)
    ESIM_VERIFY(
        s == "synchronous" || s == "background" || s == "update",
        "--strategy: " + quoteInMessage(s) + " is not synchronous, background, update or all");
  ESIM_VERIFY(opt.frames >= 0, "--frames must be >= 0");
  ESIM_VERIFY(opt.paceHz >= 0 && opt.paceHz <= 1e4, "--pace must be in 0..10000 Hz");
  ESIM_VERIFY(
      opt.repeat >= 1 && opt.repeat <= 100,
      "--repeat must be in 1..100 (rounds of the whole table), got " + std::to_string(opt.repeat));
  const std::vector<std::string> methods = app::splitList(opt.structural);
  ESIM_VERIFY(!methods.empty(),
              "--structural is empty; expected full, local or coarse (comma separated)");
  for (const std::string& m : methods)
    ESIM_VERIFY(m == "full" || m == "local" || m == "coarse",
                "--structural: " + quoteInMessage(m) +
                    " is not full, local or coarse (solvers.structural.method)");
  std::vector<std::string> electrics = app::splitList(opt.electric);
  if (electrics.empty()) electrics.push_back("");
  for (const std::string& e : electrics)
    if (!e.empty()) {
      try {
        parseElectricStrategy(e);
      } catch (const Error& err) {
        throw Error("--electric: " + std::string(err.what()));
      }
    }
  // every structural method with every electric strategy; the first is the reference the
  // others' removed sets and powers are compared with
  std::vector<Variant> variants;
  for (const std::string& m : methods)
    for (const std::string& e : electrics) variants.push_back({m, e});
  // every run's scenario checked before the first run (its mesh is built when it runs); the
  // first one's look serves --render
  std::optional<Scenario> first;
  for (const int nodes : sizes)
    for (const std::string& strategy : strategies)
      for (const Variant& variant : variants) {
        Scenario sc = loadScenario(opt.scenario, runSets(opt, nodes, strategy, variant));
        if (!first) first = std::move(sc);
      }
  // --render: one renderer for every run (the look is the same: --set applies to all), made
  // before the first run, so that a scene it cannot draw fails before anything runs
  std::unique_ptr<Renderer> renderer;
  const double displacementScale = first->look.displacementScale;
  if (opt.render) renderer = std::make_unique<Renderer>(app::makeRenderOptions(*first));
  app::CsvOutput csv(opt.csv, std::string("strategy,nodes,frames,median_ms,p95_ms,max_ms,"
                                          "removed_tets,rebuilds,rebuild_median_ms,waits") +
                                  (opt.render ? ",render_median_ms,render_p95_ms,"
                                                "interactive_median_ms,interactive_p95_ms"
                                              : "") +
                                  (opt.repeat > 1 ? ",round" : ""));
  const int structuralThreads = first->solvers.structuralSolveThreads;
  const std::string threadsNote =
      structuralThreads == 0 ? "1 (CHOLMOD's solve)" : std::to_string(structuralThreads);
  if (renderer)
    std::printf(
        "esim bench cut: %s at %s V, physics per frame, then each frame drawn at %dx%d "
        "(render and physics + render apart), one BLAS thread, structural solve and update on "
        "%s\n",
        opt.scenario.c_str(), scenarioNumber(opt.voltageV).c_str(), renderer->options().width,
        renderer->options().height, threadsNote.c_str());
  else
    std::printf(
        "esim bench cut: %s at %s V, physics per frame (no rendering), one BLAS thread, "
        "structural solve and update on %s\n",
        opt.scenario.c_str(), scenarioNumber(opt.voltageV).c_str(), threadsNote.c_str());
  std::printf("%-12s %7s %6s %10s %9s %9s %8s %8s %11s %6s", "strategy", "nodes", "frames",
              "median_ms", "p95_ms", "max_ms", "removed", "rebuilds", "rebuild_med", "waits");
  if (renderer)
    std::printf(" %10s %10s %15s %15s", "render_med", "render_p95", "interactive_med",
                "interactive_p95");
  std::printf("\n");
  std::vector<std::vector<CutRow>> rounds(opt.repeat);
  for (int round = 0; round < opt.repeat; ++round)
    for (const int nodes : sizes)
      for (const std::string& strategy : strategies) {
        // the reference run's (the first variant's) removed set and power, frame by frame
        std::vector<std::vector<std::uint8_t>> referenceAlive;
        std::vector<double> referencePowerW;
        for (const Variant& variant : variants) {
          const std::string method = variant.name();
          const bool reference = &variant == &variants.front();
          const Scenario sc = loadScenario(opt.scenario, runSets(opt, nodes, strategy, variant));
          SimulationConfig config = app::makeSimulationConfig(sc);
          config.electricSolver.localCheck = opt.electricCheck;
          Simulation sim(app::buildMesh(sc), config);
          const int frames =
              opt.frames > 0 ? opt.frames
                             : std::max(1, static_cast<int>(sc.time.durationS * sc.time.fps + 0.5));
          std::vector<double> ms, rebuildMs, renderMs, frameMs;
          std::vector<std::string> frameLines;  // --stages: what each frame spent, for the slowest
          std::array<std::vector<double>, kStageCount> stageMs;
          std::array<std::vector<double>, 4> partMs;   // update mode: the parts of a removal
          std::vector<double> structuralWork, workMs;  // ... the structural updates' work, time
          int waits = 0;
          std::vector<double> powerErrors;  // --electric-check: local's, frame by frame
          // against the reference: the frames before the removed sets first differ, and the
          // largest relative difference of the Joule power over those frames
          int sameFrames = 0;
          bool diverged = false;
          double powerDiff = 0;
          // --pace: frame f starts at its tick; a frame that overruns its tick makes the loop
          // skip the ticks it covered (a real-time loop drops them), and counts as late
          int late = 0;
          const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
              std::chrono::duration<double>(opt.paceHz > 0 ? 1.0 / opt.paceHz : 0.0));
          auto next = std::chrono::steady_clock::now();
          const auto loopStart = next;
          const double cpuStartS = app::processCpuSeconds();  // --stages: the CPU the frames cost
          for (int f = 0; f < frames; ++f) {
            if (opt.paceHz > 0) {
              std::this_thread::sleep_until(next);
              next += period;
            }
            const FrameRecord& r = sim.step();
            if (renderer) {  // the snapshot is timed into r's Snapshot stage (physics), as in run
              const SurfaceSnapshot snap = sim.snapshot(displacementScale);
              const auto t0 = std::chrono::steady_clock::now();
              renderer->render(snap);
              renderMs.push_back(
                  std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                      .count());
              frameMs.push_back(r.physicsMs() + renderMs.back());
            }
            if (opt.paceHz > 0 && std::chrono::steady_clock::now() > next) {
              ++late;
              while (next < std::chrono::steady_clock::now()) next += period;
            }
            ms.push_back(r.physicsMs());
            if (r.electricPowerError >= 0) powerErrors.push_back(r.electricPowerError);
            if (reference) {
              referenceAlive.push_back(sim.mesh().alive);
              referencePowerW.push_back(r.powerW);
            } else if (!diverged && f < static_cast<int>(referenceAlive.size())) {
              if (referencePowerW[f] > 0)
                powerDiff = std::max(powerDiff,
                                     std::abs(r.powerW - referencePowerW[f]) / referencePowerW[f]);
              if (sim.mesh().alive == referenceAlive[f])
                ++sameFrames;
              else
                diverged = true;
            }
            for (int s = 0; s < kStageCount; ++s)
              if (r.status[s] == StageStatus::Ran) stageMs[s].push_back(r.ms[s]);
            if (r.removedTets > 0) rebuildMs.push_back(r.ms[static_cast<int>(Stage::Rebuild)]);
            if (r.removedTets > 0 && strategy == "update")
              for (int k = 0; k < 3; ++k) partMs[k].push_back(r.updatePartMs[k]);
            if (r.structuralUpdateMs > 0) {
              partMs[3].push_back(r.structuralUpdateMs);
              if (r.structuralUpdateWork > 0) {
                structuralWork.push_back(r.structuralUpdateWork);
                workMs.push_back(r.structuralUpdateMs);
              }
            }
            if (r.rebuildWaitMs > 1.0) ++waits;
            if (opt.stages) {
              char line[256];
              int len = std::snprintf(line, sizeof line, "frame %4d %8.3f ms, %3d tets removed:", f,
                                      r.physicsMs(), r.removedTets);
              for (int s = 0; s < kStageCount; ++s)
                if (r.status[s] == StageStatus::Ran && r.ms[s] >= 0.1 * r.physicsMs() && len < 200)
                  len += std::snprintf(line + len, sizeof line - len, " %s %.3f",
                                       stageName(static_cast<Stage>(s)), r.ms[s]);
              frameLines.push_back(line);
            }
          }
          const double cpuMsPerFrame = 1e3 * (app::processCpuSeconds() - cpuStartS) / frames;
          const double busyCpus =
              1e-3 * cpuMsPerFrame * frames /
              std::chrono::duration<double>(std::chrono::steady_clock::now() - loopStart).count();
          const double med = quantile(ms, 0.5), p95 = quantile(ms, 0.95),
                       mx = *std::max_element(ms.begin(), ms.end()),
                       rmed = quantile(rebuildMs, 0.5);
          // removed-set difference against the reference run: tets removed by one only
          const std::vector<std::uint8_t>& alive = sim.mesh().alive;
          int differ = -1;
          if (!reference && !referenceAlive.empty() &&
              referenceAlive.back().size() == alive.size()) {
            differ = 0;
            for (size_t e = 0; e < alive.size(); ++e)
              differ += (alive[e] != referenceAlive.back()[e]);
          }
          std::string label = variants.size() > 1 ? strategy + "/" + method : strategy;
          if (opt.paceHz > 0) label += "@" + messageNumber(opt.paceHz) + "Hz";
          rounds[round].push_back(
              {label, strategy, method, sim.mesh().numNodes(), med, p95, alive});
          if (opt.repeat > 1 && rounds[round].size() == 1)
            std::printf("round %d of %d\n", round + 1, opt.repeat);
          std::printf("%-12s %7d %6d %10.2f %9.2f %9.2f %8d %8d %11.2f %6d", label.c_str(),
                      sim.mesh().numNodes(), frames, med, p95, mx, sim.removedTets(),
                      sim.rebuilds(), rmed, waits);
          if (renderer)
            std::printf(" %10.2f %10.2f %15.2f %15.2f", quantile(renderMs, 0.5),
                        quantile(renderMs, 0.95), quantile(frameMs, 0.5), quantile(frameMs, 0.95));
          if (differ >= 0)
            std::printf(
                "  (%d tets removed by one of %s/%s only; the same removed set in the first %d "
                "frames, the power within %.2e of %s's there)",
                differ, variants.front().name().c_str(), method.c_str(), sameFrames, powerDiff,
                variants.front().name().c_str());
          if (opt.paceHz > 0) std::printf("  (%d frames ended after their tick)", late);
          // which solver the scene's electric strategy (auto: by the mesh's size) took
          if (const std::string electric = sim.electricSolverName(); !electric.empty())
            std::printf("  electric %s", electric.c_str());
          std::printf("\n");
          if (!powerErrors.empty())
            std::printf(
                "  power error    against a full solve of the same frame (--electric-check): "
                "median %.2e, p95 %.2e, max %.2e over %zu frames (%zu of them full solves)\n",
                quantile(powerErrors, 0.5), quantile(powerErrors, 0.95),
                *std::max_element(powerErrors.begin(), powerErrors.end()), powerErrors.size(),
                static_cast<size_t>(std::count(powerErrors.begin(), powerErrors.end(), 0.0)));
          if (opt.stages)  // the whole process's (every thread's) CPU over the frames
            std::printf(
                "  cpu            %.2f ms a frame, all threads; %.2f of %d CPUs busy (no "
                "frame below %.2f ms on average here)\n",
                cpuMsPerFrame, busyCpus, app::usableCpus(), cpuMsPerFrame / app::usableCpus());
          if (opt.stages)
            for (int s = 0; s < kStageCount; ++s)
              if (!stageMs[s].empty())
                std::printf("  %-14s ran %4zu  median %8.3f  p95 %8.3f  max %8.3f ms\n",
                            stageName(static_cast<Stage>(s)), stageMs[s].size(),
                            quantile(stageMs[s], 0.5), quantile(stageMs[s], 0.95),
                            *std::max_element(stageMs[s].begin(), stageMs[s].end()));
          if (opt.stages && !partMs[0].empty()) {
            static const char* const kParts[4] = {"surface", "thermal", "electric", "structural*"};
            for (int k = 0; k < 4; ++k)
              if (!partMs[k].empty())
                std::printf("    update %-10s %4zu  median %8.3f  p95 %8.3f  max %8.3f ms\n",
                            kParts[k], partMs[k].size(), quantile(partMs[k], 0.5),
                            quantile(partMs[k], 0.95),
                            *std::max_element(partMs[k].begin(), partMs[k].end()));
            std::printf("    (* on a thread from the removal to the next structural solve)\n");
            double work = 0, seconds = 0;
            for (size_t k = 0; k < structuralWork.size(); ++k) {
              work += structuralWork[k];
              seconds += workMs[k] * 1e-3;
            }
            if (work > 0)
              std::printf(
                  "    structural* work (entries of L walked x columns passing; updates that "
                  "refactorized left out): median %.3g a removal, %.3g a second of their wall "
                  "time\n",
                  quantile(structuralWork, 0.5), work / seconds);
          }
          if (opt.stages) {  // the slowest frames (what lies above the p95)
            std::vector<int> order(frames);
            for (int f = 0; f < frames; ++f) order[f] = f;
            std::sort(order.begin(), order.end(), [&](int a, int b) { return ms[a] > ms[b]; });
            const int shown = std::min(frames, std::max(3, frames / 20 + 1));
            std::printf("  the %d slowest frames (stages over 10 %% of the frame):\n", shown);
            for (int k = 0; k < shown; ++k) std::printf("    %s\n", frameLines[order[k]].c_str());
          }
          std::fflush(stdout);
          if (csv) {
            csv.out() << label << ',' << sim.mesh().numNodes() << ',' << frames << ',' << med << ','
                      << p95 << ',' << mx << ',' << sim.removedTets() << ',' << sim.rebuilds()
                      << ',' << rmed << ',' << waits;
            if (renderer)
              csv.out() << ',' << quantile(renderMs, 0.5) << ',' << quantile(renderMs, 0.95) << ','
                        << quantile(frameMs, 0.5) << ',' << quantile(frameMs, 0.95);
            if (opt.repeat > 1) csv.out() << ',' << round + 1;
            csv.out() << '\n';
          }
        }
      }
  if (opt.repeat > 1) printRounds(rounds);
  if (csv) {
    csv.commit();
    std::printf("wrote %s\n", printablePath(opt.csv).c_str());
  }
  return cli::kExitOk;
}

cli::Registrar registerBenchCut(
    {"bench", "cut"},
    "The whole cut per mesh size and rebuild strategy (synchronous, background, update)",
    [](CLI::App& app) -> cli::Runner {
      auto opt = std::make_shared<BenchCutOptions>();
      app.add_option("--sizes", opt->sizes, "slab node counts, comma separated")
          ->capture_default_str();
      app.add_option("--strategy", opt->strategy, "synchronous, background, update or all")
          ->capture_default_str();
      app.add_option("--scenario", opt->scenario, "the cut scene")->capture_default_str();
      app.add_option("--voltage", opt->voltageV, "tool voltage [V]")->capture_default_str();
      app.add_option("--frames", opt->frames, "frames per run (0: the scene's duration)")
          ->capture_default_str();
      app.add_option("--csv", opt->csv, "write the table to FILE");
      app.add_option("--pace", opt->paceHz,
                     "HZ: start each frame on its tick of a loop at this rate, as a haptic "
                     "(300) or display (30) loop does (a removal's structural update then "
                     "also runs in the idle rest of its frame); 0: back to back")
          ->capture_default_str();
      app.add_option("--structural", opt->structural,
                     "solvers.structural.method values, comma separated (full,local,coarse: "
                     "each later run's removed set compared with the first's)")
          ->capture_default_str();
      app.add_option("--electric", opt->electric,
                     "solvers.electric.strategy values, comma separated (e.g. pcg,local: each "
                     "later one's removed set and power compared with the first's; empty: the "
                     "scene's)")
          ->capture_default_str();
      app.add_flag("--electric-check", opt->electricCheck,
                   "electric strategy local: solve every frame fully as well (in the frame: its "
                   "times include it) and print the Joule power's error against it");
      app.add_option("--repeat", opt->repeat,
                     "N: the whole table N times, round after round, then each row's range over "
                     "the rounds, its ratio to the same round's update row, and whether every "
                     "round removed the same tets (CSV: a round column)")
          ->capture_default_str();
      app.add_flag("--stages", opt->stages, "per-stage median, p95 and max under each row");
      app.add_flag("--render", opt->render,
                   "draw every frame as esim run does (the scene's look and size), timed apart: "
                   "render and physics + render columns");
      app.add_option("--set", opt->overrides,
                     "KEY=VALUE: a scenario value for every run, as esim run's --set (e.g. "
                     "solvers.structural.local_margin_m=0.004)");
      return [opt] {
        BenchCutOptions o = *opt;
        o.scenario = app::benchScenarioPath(o.scenario, kDefaultScenario);
        return benchCut(o);
      };
    });

}  // namespace
}  // namespace esim
