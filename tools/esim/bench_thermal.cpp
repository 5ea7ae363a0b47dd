// bench_thermal.cpp - `esim bench thermal`: time per 1/30 s frame of heat transfer.
//
// 1. For each slab size (--sizes, node counts): build the paper's slab and a Joule-like
//    source, a Gaussian hot spot (peak 5e8 W/m^3, radius 2 mm) under a tool that moves
//    along x on the top face at 5 mm/s.
// 2. Reference: Crank-Nicolson with --ref-substeps steps per frame on the same mesh.
// 3. For each integrator (explicit lumped, backward Euler, Crank-Nicolson; lumped mass):
//    time every frame's step; error = max over frames and nodes of |T - T_ref|.
// 4. A cut's topology change: after the frames, the 5 tets nearest the tool are removed in
//    place (ThermalPhase::removeTets, rm5_ms) and one more frame is timed (next_ms: it
//    makes the solver choice again); compare with setup_ms, a fresh build.
// 5. Print a table; optionally write CSV
//    integrator,nodes,dt_s,median_ms,p95_ms,max_abs_error_K.
// Boiling is on by default (the hot spot reaches 100 C after ~0.5 s), damage off.
// A benchmark, never a pass/fail test. BLAS runs on one thread.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <memory>
#include <sstream>

#include "sim/core_error.h"
#include "sim/fem_p1.h"
#include "sim/mesh_slab.h"
#include "sim/message_text.h"
#include "sim/thermal_step.h"
#include "tools/app/bench_common.h"
#include "tools/esim/command.h"

extern "C" void openblas_set_num_threads(int num_threads);

namespace esim {
namespace {

struct BenchThermalOptions {
  std::string sizes = "1013,20000,50000";
  int frames = 60;
  double fps = 30;
  int refSubsteps = 16;
  std::string solver = "auto";
  bool noBoiling = false;
  double nonlinearTolK = ThermalParams{}.nonlinearToleranceK;
  std::string csv;
};

// Joule-like source: Gaussian hot spot under the tool tip at time tS
void toolSource(const std::vector<Vec3>& centroids, double tS, double topZ,
                std::vector<double>& q) {
  const double peakW_m3 = 5e8, radiusM = 0.002;
  const Vec3 tip(-0.01 + 0.005 * tS, 0.0, topZ);
  for (size_t e = 0; e < centroids.size(); ++e) {
    const double r2 = (centroids[e] - tip).squaredNorm();
    q[e] = r2 > 36 * radiusM * radiusM ? 0.0 : peakW_m3 * std::exp(-r2 / (2 * radiusM * radiusM));
  }
}

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  const size_t i = std::min(v.size() - 1, static_cast<size_t>(std::ceil(p * v.size())) - 1);
  return v[i];
}

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// CPU time of this thread [ms]: less sensitive than wall time to other processes
double threadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * ts.tv_sec + 1e-6 * ts.tv_nsec;
}

int benchThermal(const BenchThermalOptions& opt) {
  // 1. options
  const std::vector<int> sizes = app::parseNodeCounts(opt.sizes, "bench thermal");
  ESIM_VERIFY(opt.frames >= 1, "--frames must be >= 1");
  ESIM_VERIFY(opt.fps > 0, "--fps must be > 0");
  ESIM_VERIFY(opt.refSubsteps >= 2, "--ref-substeps must be >= 2");
  ESIM_VERIFY(opt.nonlinearTolK > 0, "--nonlinear-tol must be > 0");
  ThermalLinearSolver solver = ThermalLinearSolver::Auto;
  if (opt.solver == "direct")
    solver = ThermalLinearSolver::Direct;
  else if (opt.solver == "cg")
    solver = ThermalLinearSolver::Cg;
  else
    ESIM_VERIFY(opt.solver == "auto",
                "--solver " + quoteInMessage(opt.solver) + ": expected auto, direct or cg");
  openblas_set_num_threads(1);
  const double dt = 1.0 / opt.fps;

  app::CsvOutput csv(opt.csv, "integrator,nodes,dt_s,median_ms,p95_ms,max_abs_error_K");
  std::printf(
      "esim bench thermal: %d frames of %.4f s, boiling %s, hot spot 5e8 W/m^3 r 2 mm "
      "moving 5 mm/s; reference CN x%d sub-steps; solver %s; boiling tolerance %.0e K; "
      "1 thread\n",
      opt.frames, dt, opt.noBoiling ? "off" : "on", opt.refSubsteps, opt.solver.c_str(),
      opt.nonlinearTolK);
  std::printf("%-15s %7s %8s %9s %9s %9s %9s %9s %6s %6s %6s %-8s %10s %7s %8s %8s\n", "integrator",
              "nodes", "tets", "setup_ms", "median_ms", "p95_ms", "max_ms", "cpu_med", "subst",
              "iters", "cg_its", "solver", "max_err_K", "Tmax_C", "rm5_ms", "next_ms");

  for (int target : sizes) {
    // 2. mesh and source
    SlabSpec spec;
    spec.targetNodes = target;
    const TetMesh mesh = makeSlab(spec);
    const auto geo = tetGeometry(mesh);
    const double topZ = spec.sizeM.z();
    std::vector<Vec3> centroids(mesh.tets.size());
    for (int e = 0; e < mesh.numTets(); ++e) {
      centroids[e].setZero();
      for (int v : mesh.tets[e]) centroids[e] += 0.25 * mesh.nodes[v];
    }
    std::vector<double> source(mesh.tets.size());
    ThermalParams base;
    base.boiling = !opt.noBoiling;
    base.linearSolver = solver;
    base.nonlinearToleranceK = opt.nonlinearTolK;

    // 3. reference trajectory
    std::vector<Eigen::VectorXd> reference;
    {
      ThermalParams p = base;
      p.integrator = ThermalIntegrator::CrankNicolson;
      ThermalPhase phase(mesh, geo, p);
      ThermalState s;
      phase.initState(s);
      const double h = dt / opt.refSubsteps;
      for (int f = 0; f < opt.frames; ++f) {
        for (int k = 0; k < opt.refSubsteps; ++k) {
          toolSource(centroids, s.timeS + 0.5 * h, topZ, source);
          phase.step(h, source, s);
        }
        reference.push_back(s.temperatureC);
      }
    }
    double explicitLimit = 0;

    // 4. the integrators, timed per frame (the reference uses the source at mid-step too)
    for (ThermalIntegrator integrator :
         {ThermalIntegrator::Explicit, ThermalIntegrator::BackwardEuler,
          ThermalIntegrator::CrankNicolson, ThermalIntegrator::TrBdf2}) {
      ThermalParams p = base;
      p.integrator = integrator;
      const auto t0 = Clock::now();
      ThermalPhase phase(mesh, geo, p);
      if (integrator == ThermalIntegrator::Explicit) explicitLimit = phase.stableExplicitDtS();
      const double setupMs = msSince(t0);
      ThermalState s;
      phase.initState(s);
      std::vector<double> frameMs, frameCpuMs;
      double maxErr = 0;
      long substeps = 0, iterations = 0, cgIterations = 0;
      for (int f = 0; f < opt.frames; ++f) {
        toolSource(centroids, s.timeS + 0.5 * dt, topZ, source);
        const double c1 = threadCpuMs();
        const auto t1 = Clock::now();
        const auto stats = phase.step(dt, source, s);
        frameMs.push_back(msSince(t1));
        frameCpuMs.push_back(threadCpuMs() - c1);
        substeps += stats.substeps;
        iterations += stats.iterations;
        cgIterations += stats.cgIterations;
        maxErr = std::max(maxErr, (s.temperatureC - reference[f]).cwiseAbs().maxCoeff());
      }
      const double med = percentile(frameMs, 0.5), p95 = percentile(frameMs, 0.95);
      const double mx = *std::max_element(frameMs.begin(), frameMs.end());
      const double cpuMed = percentile(frameCpuMs, 0.5);
      const std::string name = thermalIntegratorName(integrator);
      const double tMaxC = s.temperatureC.maxCoeff();
      const std::string solverName =
          integrator == ThermalIntegrator::Explicit ? "-" : phase.lastSolverName();
      // the cut: the 5 alive tets nearest the tool, removed in place, then one more frame
      const Vec3 tip(-0.01 + 0.005 * s.timeS, 0.0, topZ);
      std::vector<std::pair<double, int>> byDistance;
      for (int e = 0; e < mesh.numTets(); ++e)
        byDistance.push_back({(centroids[e] - tip).squaredNorm(), e});
      std::partial_sort(byDistance.begin(), byDistance.begin() + 5, byDistance.end());
      std::vector<int> cut;
      for (int i = 0; i < 5; ++i) cut.push_back(byDistance[i].second);
      const double removeMs = phase.removeTets(cut).ms;
      toolSource(centroids, s.timeS + 0.5 * dt, topZ, source);
      const auto t2 = Clock::now();
      phase.step(dt, source, s);
      const double nextMs = msSince(t2);
      std::printf(
          "%-15s %7d %8d %9.2f %9.3f %9.3f %9.3f %9.3f %6.2f %6.2f %6.2f %-8s %10.3e %7.2f %8.4f "
          "%8.3f\n",
          name.c_str(), mesh.numNodes(), mesh.numTets(), setupMs, med, p95, mx, cpuMed,
          double(substeps) / opt.frames, double(iterations) / opt.frames,
          double(cgIterations) / opt.frames, solverName.c_str(), maxErr, tMaxC, removeMs, nextMs);
      if (csv)
        csv.out() << name << "," << mesh.numNodes() << "," << dt << "," << med << "," << p95 << ","
                  << maxErr << "\n";
    }
    std::printf("%-15s %7d explicit stability limit %.3f s (%.0f frames)\n", "", mesh.numNodes(),
                explicitLimit, explicitLimit / dt);
  }
  if (csv) {
    csv.commit();
    std::printf("wrote %s\n", printablePath(opt.csv).c_str());
  }
  return cli::kExitOk;
}

cli::Registrar registerBenchThermal(
    {"bench", "thermal"}, "Thermal integrator benchmark: time per frame and error vs a fine dt",
    [](CLI::App& app) -> cli::Runner {
      auto opt = std::make_shared<BenchThermalOptions>();
      app.add_option("--sizes", opt->sizes, "slab node counts, comma separated")
          ->capture_default_str();
      app.add_option("--frames", opt->frames, "frames per run")->capture_default_str();
      app.add_option("--fps", opt->fps, "frames per simulated second")->capture_default_str();
      app.add_option("--ref-substeps", opt->refSubsteps,
                     "Crank-Nicolson sub-steps per frame of the reference")
          ->capture_default_str();
      app.add_option("--solver", opt->solver, "implicit linear solver: auto, direct, cg")
          ->capture_default_str();
      app.add_flag("--no-boiling", opt->noBoiling, "switch the latent heat off");
      app.add_option("--nonlinear-tol", opt->nonlinearTolK,
                     "boiling iteration tolerance [K] (ThermalParams::nonlinearToleranceK)")
          ->capture_default_str();
      app.add_option("--csv", opt->csv,
                     "write integrator,nodes,dt_s,median_ms,p95_ms,"
                     "max_abs_error_K to FILE");
      return [opt] { return benchThermal(*opt); };
    });

}  // namespace
}  // namespace esim
