// bench_structural.cpp - `esim bench structural`: what the structural phase and a rebuild
// after rupture cost per mesh size, side by side with the throw-away prototype's floor
// (../shared/REFERENCE.md: pre-factored solve 0.58 / 7.9 / 47 / 145 ms at 2.5k / 13k / 52k /
// 136k unknowns; refactor after removing 5 elements 18 / 196 / 1720 / 6130 ms at 1k / 5k /
// 20k / 50k nodes).
//
// 1. For each slab size (--sizes, node counts; the paper's 100x100x10 mm slab): clamp the
//    bottom face, build StructuralPhase (assembly + CHOLMOD factorization, timed).
// 2. Load: a Gaussian volumetric expansion under the top centre (peak --peak-expansion,
//    radius 3 mm), --solves solves timed (median), the load scaled a little each time.
// 3. Remove the 5 alive tets nearest the top centre and build the phase again (the
//    rebuild a rupture triggers), timed.
// 4. Remove the same 5 tets from the phase of step 1 with removeTets (the factor updated,
//    the first update converting it to simplicial LDL', unless --prepare-for-updates built
//    the phase with the conversion done), timed; then a solve with the
//    updated factor (median of --solves; ldl_solve.h on two threads, the default: solve_upd;
//    on one: upd_1t; CHOLMOD's cholmod_solve2 of the same factor: upd_chol, taken in turn)
//    and its difference from the rebuilt phase's.
// 5. Print a table; --csv writes nodes,dofs,factor_ms,solve_ms,rebuild5_ms,update5_ms,
//    convert_ms,update_refactorized,solve_updated_ms,update_vs_rebuild,max_von_mises_pa,
//    solve_updated_1thread_ms,solve_updated_cholmod_ms,volumetric.
// --volumetric element,nodal: steps 1-4 for each form of the volumetric strain
// (StructuralOptions::volumetric: per tet, or at the nodes, which does not lock), a row each,
// side by side per size: what the form that does not lock costs.
// With --local, instead: the local solve (StructuralSolveMethod::local) against the full
// one, frame by frame, on two loads scaled so that the peak von Mises is --overload times
// the critical stress (SimulationConfig's default):
//   growing: the Gaussian under the top centre, its peak ramping from 0.6 to 1 of that;
//   moving:  the Gaussian's centre moving along x by --step-mm a frame (a cut), from
//            -frames * step / 2.
// Per size, a full phase solves every frame (its von Mises is the truth) and one local
// phase per --margins-mm (its first solve full, the reference; refreshed every
// --refresh solves, in the frame or with --refresh-on-thread on the phase's thread); table
// per scene and margin: solve ms (median, mean, max; region factorizations and full
// refreshes included), fulls (full solves in the frame), builds (region factorizations),
// the region's largest count of unknowns, max |vm - vm_full|,
// relative L2 of vm - vm_full over all tets, and the tets on different sides of the
// critical stress (max over frames; above: the full solve's count at the last frame).
// A benchmark, never a pass/fail test. BLAS runs on one thread (as in the phase).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>

#include "sim/core_error.h"
#include "sim/mesh_slab.h"
#include "sim/message_text.h"
#include "sim/simulation.h"
#include "sim/structural.h"
#include "tools/app/bench_common.h"
#include "tools/esim/command.h"

namespace esim {
namespace {

struct BenchStructuralOptions {
  std::string sizes = "1013,5000,20000";
  int solves = 20;
  double peakExpansion = 0.5;
  bool prepareForUpdates = false;
  std::string volumetric = "element";
  std::string csv;
  // --local
  bool local = false;
  int frames = 40;
  double stepMm = 0.5;
  double overload = 1.5;
  std::string marginsMm = "5,10,15";
  double slackMm = LocalSolveOptions{}.slackM * 1e3;
  int refresh = LocalSolveOptions{}.refreshEvery;
  bool refreshOnThread = false;
};

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// the slab of `nodes` nodes, clamped at the bottom
struct BenchSlab {
  SlabSpec spec;
  TetMesh mesh;
  std::vector<Support> clamp;
  std::vector<Vec3> centroids;
};

BenchSlab benchSlab(int nodes) {
  BenchSlab b;
  b.spec.targetNodes = nodes;
  b.mesh = makeSlab(b.spec);
  b.mesh.alive.assign(b.mesh.tets.size(), 1);
  for (int v = 0; v < b.mesh.numNodes(); ++v)
    if (b.mesh.nodes[v].z() < 1e-9)
      for (int a = 0; a < 3; ++a) b.clamp.push_back({v, a});
  for (const Tet& t : b.mesh.tets) {
    Vec3 c = Vec3::Zero();
    for (int v : t) c += 0.25 * b.mesh.nodes[v];
    b.centroids.push_back(c);
  }
  return b;
}

// peak * exp(-|c - centre|^2 / r^2) per tet, r = 3 mm
std::vector<double> gaussianLoad(const BenchSlab& b, const Vec3& centre, double peak) {
  std::vector<double> ev(b.centroids.size());
  for (size_t t = 0; t < ev.size(); ++t)
    ev[t] = peak * std::exp(-(b.centroids[t] - centre).squaredNorm() / (0.003 * 0.003));
  return ev;
}

struct Timing {
  double median = 0, mean = 0, max = 0;
};

Timing timing(std::vector<double> ms) {
  std::sort(ms.begin(), ms.end());
  Timing t;
  t.median = ms[ms.size() / 2];
  t.max = ms.back();
  for (double v : ms) t.mean += v / static_cast<double>(ms.size());
  return t;
}

int benchLocal(const BenchStructuralOptions& opt) {
  ESIM_VERIFY(opt.frames >= 2, "--frames must be >= 2");
  ESIM_VERIFY(opt.overload > 0, "--overload must be > 0");
  const std::vector<int> sizes = app::parseNodeCounts(opt.sizes, "bench structural");
  const std::vector<double> margins =
      app::parseNumberList(opt.marginsMm, "--margins-mm", 0, 1000, "5,10,15");
  const double critical = defaultSimulationConfig().criticalStressPa;
  std::printf(
      "esim bench structural --local: paper slab, bottom clamped, Gaussian expansion (radius "
      "3 mm) scaled to a peak von Mises of %.2f x %.0f Pa; %d frames; moving: %.2f mm a frame "
      "along x; slack %.1f mm, full refresh every %d solves%s; one BLAS thread\n",
      opt.overload, critical, opt.frames, opt.stepMm, opt.slackMm, opt.refresh,
      opt.refreshOnThread ? " on a thread (fulls: the frame's own)" : "");
  std::printf("%8s %8s %7s %9s %9s %9s %9s %6s %7s %9s %10s %12s %10s %8s %6s\n", "nodes", "scene",
              "method", "margin_mm", "med_ms", "mean_ms", "max_ms", "fulls", "builds", "build_ms",
              "region_dofs", "vm_maxerr_Pa", "vm_rel_l2", "set_diff", "above");
  for (const int nodes : sizes) {
    const BenchSlab b = benchSlab(nodes);
    const double top = b.spec.sizeM.z();
    StructuralPhase full(b.mesh, StructuralOptions{}, b.clamp);
    StructuralPhase local(b.mesh, StructuralOptions{}, b.clamp);
    // the load that brings the peak von Mises to overload x critical (the response is linear)
    full.solve(gaussianLoad(b, Vec3(0, 0, top), 1.0));
    const double unitPeak = *std::max_element(full.vonMisesPa().begin(), full.vonMisesPa().end());
    const double peak = opt.overload * critical / unitPeak;
    for (const char* scene : {"growing", "moving"}) {
      const bool moving = std::string(scene) == "moving";
      auto loadAt = [&](int k) {
        if (moving)
          return gaussianLoad(b, Vec3(1e-3 * opt.stepMm * (k - opt.frames / 2.0), 0, top), peak);
        return gaussianLoad(b, Vec3(0, 0, top), peak * (0.6 + 0.4 * k / (opt.frames - 1.0)));
      };
      // the truth: a full solve every frame
      std::vector<std::vector<double>> truth;
      std::vector<double> fullMs;
      for (int k = 0; k < opt.frames; ++k) {
        const std::vector<double> ev = loadAt(k);
        const auto t0 = std::chrono::steady_clock::now();
        full.solve(ev);
        fullMs.push_back(msSince(t0));
        truth.push_back(full.vonMisesPa());
      }
      int above = 0;
      for (double vm : truth.back()) above += vm >= critical;
      const Timing ft = timing(fullMs);
      std::printf("%8d %8s %7s %9s %9.2f %9.2f %9.2f %6d %7d %9s %10d %12s %10s %8s %6d\n",
                  b.mesh.numNodes(), scene, "full", "-", ft.median, ft.mean, ft.max, opt.frames, 0,
                  "-", full.numFreeDofs(), "-", "-", "-", above);
      std::fflush(stdout);
      for (double marginMm : margins) {
        LocalSolveOptions lo;
        lo.marginM = 1e-3 * marginMm;
        lo.slackM = 1e-3 * opt.slackMm;
        lo.refreshEvery = opt.refresh;
        lo.refreshOnThread = opt.refreshOnThread;
        local.setSolveMethod(StructuralSolveMethod::full, lo);  // drops the reference
        local.setSolveMethod(StructuralSolveMethod::local, lo);
        std::vector<double> ms, buildMs;
        int fulls = 0, builds = 0, regionDofs = 0, setDiff = 0;
        double maxErr = 0, relL2 = 0;
        for (int k = 0; k < opt.frames; ++k) {
          const std::vector<double> ev = loadAt(k);
          const auto t0 = std::chrono::steady_clock::now();
          local.solve(ev);
          ms.push_back(msSince(t0));
          const StructuralSolveStats& st = local.lastSolveStats();
          fulls += !st.local;
          builds += st.regionBuilt;
          if (st.regionBuilt) buildMs.push_back(1e3 * st.regionFactorSeconds);
          regionDofs = std::max(regionDofs, st.regionDofs);
          double err2 = 0, norm2 = 0;
          int diff = 0;
          for (size_t t = 0; t < truth[k].size(); ++t) {
            const double want = truth[k][t], got = local.vonMisesPa()[t];
            maxErr = std::max(maxErr, std::abs(got - want));
            err2 += (got - want) * (got - want);
            norm2 += want * want;
            diff += (got >= critical) != (want >= critical);
          }
          relL2 = std::max(relL2, std::sqrt(err2 / norm2));
          setDiff = std::max(setDiff, diff);
        }
        const Timing lt = timing(ms);
        char buildMedian[32] = "-";  // the region builds' median [ms]
        if (!buildMs.empty())
          std::snprintf(buildMedian, sizeof buildMedian, "%.2f", timing(buildMs).median);
        std::printf("%8d %8s %7s %9.1f %9.2f %9.2f %9.2f %6d %7d %9s %10d %12.1f %10.1e %8d %6d\n",
                    b.mesh.numNodes(), scene, "local", marginMm, lt.median, lt.mean, lt.max, fulls,
                    builds, buildMedian, regionDofs, maxErr, relL2, setDiff, above);
        std::fflush(stdout);
      }
    }
  }
  return cli::kExitOk;
}

int benchStructural(const BenchStructuralOptions& opt) {
  if (opt.local) return benchLocal(opt);
  ESIM_VERIFY(opt.solves >= 1, "--solves must be >= 1");
  const std::vector<int> sizes = app::parseNodeCounts(opt.sizes, "bench structural");
  std::vector<VolumetricStrain> forms;
  for (const std::string& f : app::splitList(opt.volumetric)) {
    ESIM_VERIFY(f == "element" || f == "nodal",
                "bench structural: --volumetric: " + quoteInMessage(f) +
                    " is not a form of the volumetric strain; expected element, nodal or both "
                    "(element,nodal)");
    forms.push_back(f == "nodal" ? VolumetricStrain::nodal : VolumetricStrain::element);
  }
  ESIM_VERIFY(!forms.empty(), "bench structural: --volumetric: none given");
  app::CsvOutput csv(opt.csv,
                     "nodes,dofs,factor_ms,solve_ms,rebuild5_ms,update5_ms,convert_ms,"
                     "update_refactorized,solve_updated_ms,update_vs_rebuild,max_von_mises_pa,"
                     "solve_updated_1thread_ms,solve_updated_cholmod_ms,volumetric");
  std::printf(
      "esim bench structural: paper slab 100x100x10 mm, bottom clamped, Gaussian "
      "expansion (peak %.2f, radius 3 mm) under the top centre; %d solves; E 4.75e4 "
      "Pa, nu 0.4; one BLAS thread%s\n",
      opt.peakExpansion, opt.solves,
      opt.prepareForUpdates ? "; prepareForUpdates (factor_ms includes the conversion)" : "");
  std::printf("%8s %8s %10s %10s %12s %11s %11s %10s %13s %10s %10s %10s %12s %10s\n", "nodes",
              "dofs", "factor_ms", "solve_ms", "rebuild5_ms", "update5_ms", "convert_ms",
              "refactored", "solve_upd_ms", "upd_1t_ms", "upd_chol_ms", "upd_vs_reb", "max_vm_Pa",
              "volumetric");
  for (const int nodes : sizes)
    for (const VolumetricStrain form : forms) {
      const char* formName = form == VolumetricStrain::nodal ? "nodal" : "element";
      SlabSpec spec;
      spec.targetNodes = nodes;
      TetMesh mesh = makeSlab(spec);
      mesh.alive.assign(mesh.tets.size(), 1);
      std::vector<Support> clamp;
      for (int v = 0; v < mesh.numNodes(); ++v)
        if (mesh.nodes[v].z() < 1e-9)
          for (int a = 0; a < 3; ++a) clamp.push_back({v, a});
      const Vec3 centre(0, 0, spec.sizeM.z());
      std::vector<double> ev(mesh.numTets()), dist(mesh.numTets());
      for (int t = 0; t < mesh.numTets(); ++t) {
        Vec3 c = Vec3::Zero();
        for (int v : mesh.tets[t]) c += 0.25 * mesh.nodes[v];
        dist[t] = (c - centre).norm();
        ev[t] = opt.peakExpansion * std::exp(-dist[t] * dist[t] / (0.003 * 0.003));
      }
      // 1. assembly + factorization
      auto t0 = std::chrono::steady_clock::now();
      StructuralOptions firstOptions;
      firstOptions.prepareForUpdates = opt.prepareForUpdates;
      firstOptions.volumetric = form;
      StructuralOptions rebuildOptions;
      rebuildOptions.volumetric = form;
      auto phase = std::make_unique<StructuralPhase>(mesh, firstOptions, clamp);
      const double factorMs = msSince(t0);
      // 2. solves
      std::vector<double> solveMs;
      std::vector<double> load = ev;
      for (int k = 0; k < opt.solves; ++k) {
        for (double& e : load) e *= 1.001;
        t0 = std::chrono::steady_clock::now();
        phase->solve(load);
        solveMs.push_back(msSince(t0));
      }
      std::sort(solveMs.begin(), solveMs.end());
      const double maxVm =
          *std::max_element(phase->vonMisesPa().begin(), phase->vonMisesPa().end());
      // 3. remove the 5 tets nearest the top centre and rebuild
      std::vector<int> order(mesh.numTets());
      for (int t = 0; t < mesh.numTets(); ++t) order[t] = t;
      std::partial_sort(order.begin(), order.begin() + 5, order.end(),
                        [&](int a, int b) { return dist[a] < dist[b]; });
      for (int k = 0; k < 5; ++k) mesh.alive[order[k]] = 0;
      t0 = std::chrono::steady_clock::now();
      const auto rebuilt = std::make_unique<StructuralPhase>(mesh, rebuildOptions, clamp);
      const double rebuildMs = msSince(t0);
      // 4. the same 5 tets removed from the first phase by an update
      t0 = std::chrono::steady_clock::now();
      const StructuralUpdateStats update =
          phase->removeTets({order[0], order[1], order[2], order[3], order[4]});
      const double updateMs = msSince(t0);
      // the updated (simplicial) factor's solves: CHOLMOD's, ldl_solve.h's on 1 and 2 threads,
      // interleaved (one solve of each in turn: the machine's load shared alike)
      std::vector<double> updatedMs[3];
      for (int k = 0; k < opt.solves; ++k)
        for (int threads : {0, 1, 2}) {
          phase->setSolveThreads(threads);
          t0 = std::chrono::steady_clock::now();
          phase->solve(load);
          updatedMs[threads].push_back(msSince(t0));
        }
      for (auto& v : updatedMs) std::sort(v.begin(), v.end());
      const auto median = [](const std::vector<double>& v) { return v[v.size() / 2]; };
      rebuilt->solve(load);
      const double difference = (phase->displacementM() - rebuilt->displacementM()).norm() /
                                rebuilt->displacementM().norm();
      const double solveUpdatedMs = median(updatedMs[2]);
      const double convertMs = 1e3 * update.convertSeconds;
      std::printf(
          "%8d %8d %10.1f %10.2f %12.1f %11.2f %11.2f %10s %13.2f %10.2f %10.2f %10.1e %12.1f "
          "%10s\n",
          mesh.numNodes(), rebuilt->numFreeDofs(), factorMs, solveMs[solveMs.size() / 2], rebuildMs,
          updateMs, convertMs, update.refactorized ? "yes" : "no", solveUpdatedMs,
          median(updatedMs[1]), median(updatedMs[0]), difference, maxVm, formName);
      std::fflush(stdout);
      if (csv)
        csv.out() << mesh.numNodes() << ',' << rebuilt->numFreeDofs() << ',' << factorMs << ','
                  << solveMs[solveMs.size() / 2] << ',' << rebuildMs << ',' << updateMs << ','
                  << convertMs << ',' << (update.refactorized ? 1 : 0) << ',' << solveUpdatedMs
                  << ',' << difference << ',' << maxVm << ',' << median(updatedMs[1]) << ','
                  << median(updatedMs[0]) << ',' << formName << '\n';
    }
  if (csv) {
    csv.commit();
    std::printf("wrote %s\n", printablePath(opt.csv).c_str());
  }
  return cli::kExitOk;
}

cli::Registrar registerBenchStructural(
    {"bench", "structural"},
    "Structural phase benchmark: factorization, solve, and rebuild or update after removing 5 "
    "tets",
    [](CLI::App& app) -> cli::Runner {
      auto opt = std::make_shared<BenchStructuralOptions>();
      // what only one of the two benches reads (the other would silently ignore it)
      std::vector<const CLI::Option*> fullOnly, localOnly;
      app.add_option("--sizes", opt->sizes, "slab node counts, comma separated")
          ->capture_default_str();
      fullOnly.push_back(
          app.add_option("--solves", opt->solves, "timed solves per size")->capture_default_str());
      fullOnly.push_back(app.add_option("--peak-expansion", opt->peakExpansion,
                                        "peak volumetric expansion dV/V of the load")
                             ->capture_default_str());
      fullOnly.push_back(
          app.add_option("--volumetric", opt->volumetric,
                         "the volumetric strain per tet (element), at the nodes (nodal: no "
                         "locking), or both side by side (element,nodal)")
              ->capture_default_str());
      fullOnly.push_back(app.add_flag(
          "--prepare-for-updates", opt->prepareForUpdates,
          "StructuralOptions::prepareForUpdates for the phase of steps 1, 2 and 4 (the "
          "factor converted to LDL' at construction: update5_ms is the steady state)"));
      app.add_flag("--local", opt->local,
                   "instead: the local solve against the full one on a growing and a moving "
                   "load (errors of von Mises, tets on the other side of the critical stress)");
      localOnly.push_back(app.add_option("--frames", opt->frames, "--local: frames per scene")
                              ->capture_default_str());
      localOnly.push_back(
          app.add_option("--step-mm", opt->stepMm, "--local: the moving load's step a frame [mm]")
              ->capture_default_str());
      localOnly.push_back(
          app.add_option("--overload", opt->overload,
                         "--local: the load's peak von Mises over the critical stress")
              ->capture_default_str());
      localOnly.push_back(
          app.add_option("--margins-mm", opt->marginsMm,
                         "--local: LocalSolveOptions::marginM values [mm], comma separated")
              ->capture_default_str());
      localOnly.push_back(
          app.add_option("--slack-mm", opt->slackMm, "--local: LocalSolveOptions::slackM [mm]")
              ->capture_default_str());
      localOnly.push_back(
          app.add_option("--refresh", opt->refresh, "--local: LocalSolveOptions::refreshEvery")
              ->capture_default_str());
      localOnly.push_back(app.add_flag("--refresh-on-thread", opt->refreshOnThread,
                                       "--local: LocalSolveOptions::refreshOnThread"));
      fullOnly.push_back(
          app.add_option("--csv", opt->csv,
                         "write nodes,dofs,factor_ms,solve_ms,rebuild5_ms,update5_ms,convert_ms,"
                         "update_refactorized,solve_updated_ms,update_vs_rebuild,max_von_mises_pa,"
                         "solve_updated_1thread_ms,solve_updated_cholmod_ms,volumetric to FILE"));
      return [opt, fullOnly, localOnly] {
        if (opt->local)
          cli::refuseGiven(fullOnly, "bench structural", "is not an option of --local");
        else
          cli::refuseGiven(localOnly, "bench structural", "is an option of --local only");
        return benchStructural(*opt);
      };
    });

}  // namespace
}  // namespace esim
