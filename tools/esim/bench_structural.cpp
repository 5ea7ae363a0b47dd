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
//    updated factor (median of --solves) and its difference from the rebuilt phase's.
// 5. Print a table; --csv writes nodes,dofs,factor_ms,solve_ms,rebuild5_ms,update5_ms,
//    convert_ms,update_refactorized,solve_updated_ms,update_vs_rebuild,max_von_mises_pa.
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
  std::string csv;
};

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

int benchStructural(const BenchStructuralOptions& opt) {
  ESIM_VERIFY(opt.solves >= 1, "--solves must be >= 1");
  const std::vector<int> sizes = app::parseNodeCounts(opt.sizes, "bench structural");
  std::unique_ptr<std::ofstream> csv;
  if (!opt.csv.empty()) {
    csv = std::make_unique<std::ofstream>(opt.csv);
    ESIM_VERIFY(csv->good(), "--csv: cannot write '" + opt.csv + "'");
    *csv << "nodes,dofs,factor_ms,solve_ms,rebuild5_ms,update5_ms,convert_ms,update_refactorized,"
            "solve_updated_ms,update_vs_rebuild,max_von_mises_pa\n";
  }
  std::printf(
      "esim bench structural: paper slab 100x100x10 mm, bottom clamped, Gaussian "
      "expansion (peak %.2f, radius 3 mm) under the top centre; %d solves; E 4.75e4 "
      "Pa, nu 0.4; one BLAS thread%s\n",
      opt.peakExpansion, opt.solves,
      opt.prepareForUpdates ? "; prepareForUpdates (factor_ms includes the conversion)" : "");
  std::printf("%8s %8s %10s %10s %12s %11s %11s %10s %13s %10s %12s\n", "nodes", "dofs",
              "factor_ms", "solve_ms", "rebuild5_ms", "update5_ms", "convert_ms", "refactored",
              "solve_upd_ms", "upd_vs_reb", "max_vm_Pa");
  for (const int nodes : sizes) {
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
    const double maxVm = *std::max_element(phase->vonMisesPa().begin(), phase->vonMisesPa().end());
    // 3. remove the 5 tets nearest the top centre and rebuild
    std::vector<int> order(mesh.numTets());
    for (int t = 0; t < mesh.numTets(); ++t) order[t] = t;
    std::partial_sort(order.begin(), order.begin() + 5, order.end(),
                      [&](int a, int b) { return dist[a] < dist[b]; });
    for (int k = 0; k < 5; ++k) mesh.alive[order[k]] = 0;
    t0 = std::chrono::steady_clock::now();
    const auto rebuilt = std::make_unique<StructuralPhase>(mesh, StructuralOptions{}, clamp);
    const double rebuildMs = msSince(t0);
    // 4. the same 5 tets removed from the first phase by an update
    t0 = std::chrono::steady_clock::now();
    const StructuralUpdateStats update =
        phase->removeTets({order[0], order[1], order[2], order[3], order[4]});
    const double updateMs = msSince(t0);
    std::vector<double> updatedSolveMs;
    for (int k = 0; k < opt.solves; ++k) {
      t0 = std::chrono::steady_clock::now();
      phase->solve(load);
      updatedSolveMs.push_back(msSince(t0));
    }
    std::sort(updatedSolveMs.begin(), updatedSolveMs.end());
    rebuilt->solve(load);
    const double difference = (phase->displacementM() - rebuilt->displacementM()).norm() /
                              rebuilt->displacementM().norm();
    const double solveUpdatedMs = updatedSolveMs[updatedSolveMs.size() / 2];
    const double convertMs = 1e3 * update.convertSeconds;
    std::printf("%8d %8d %10.1f %10.2f %12.1f %11.2f %11.2f %10s %13.2f %10.1e %12.1f\n",
                mesh.numNodes(), rebuilt->numFreeDofs(), factorMs, solveMs[solveMs.size() / 2],
                rebuildMs, updateMs, convertMs, update.refactorized ? "yes" : "no", solveUpdatedMs,
                difference, maxVm);
    std::fflush(stdout);
    if (csv)
      *csv << mesh.numNodes() << ',' << rebuilt->numFreeDofs() << ',' << factorMs << ','
           << solveMs[solveMs.size() / 2] << ',' << rebuildMs << ',' << updateMs << ',' << convertMs
           << ',' << (update.refactorized ? 1 : 0) << ',' << solveUpdatedMs << ',' << difference
           << ',' << maxVm << '\n';
  }
  if (csv) std::printf("wrote %s\n", opt.csv.c_str());
  return cli::kExitOk;
}

cli::Registrar registerBenchStructural(
    {"bench", "structural"},
    "Structural phase benchmark: factorization, solve, and rebuild or update after removing 5 "
    "tets",
    [](CLI::App& app) -> cli::Runner {
      auto opt = std::make_shared<BenchStructuralOptions>();
      app.add_option("--sizes", opt->sizes, "slab node counts, comma separated")
          ->capture_default_str();
      app.add_option("--solves", opt->solves, "timed solves per size")->capture_default_str();
      app.add_option("--peak-expansion", opt->peakExpansion,
                     "peak volumetric expansion dV/V of the load")
          ->capture_default_str();
      app.add_flag("--prepare-for-updates", opt->prepareForUpdates,
                   "StructuralOptions::prepareForUpdates for the phase of steps 1, 2 and 4 (the "
                   "factor converted to LDL' at construction: update5_ms is the steady state)");
      app.add_option("--csv", opt->csv,
                     "write nodes,dofs,factor_ms,solve_ms,rebuild5_ms,update5_ms,convert_ms,"
                     "update_refactorized,solve_updated_ms,update_vs_rebuild,max_von_mises_pa "
                     "to FILE");
      return [opt] { return benchStructural(*opt); };
    });

}  // namespace
}  // namespace esim
