// run_config_test.cpp - the scenario -> configuration mapping (tools/app/run_config.cpp):
// one source for every default (the core's), and `esim validate`'s checks equal to the
// run's set-up.
#include "tools/app/run_config.h"

#include <gtest/gtest.h>

#include "sim/core_error.h"
#include "sim/io/scenario.h"

namespace esim::app {
namespace {

Scenario defaults() { return parseScenario("name: defaults\n", "defaults.yaml"); }

std::string schemaDefault(const std::string& path) {
  for (const ScenarioFieldInfo& f : scenarioFields())
    if (f.path == path) return f.defaultYaml;
  ADD_FAILURE() << "no schema field " << path;
  return "";
}

// the two defaults that had drifted apart: read through the scenario and through the core
TEST(RunConfig, ThermalIntegratorDefaultIsOne) {
  const SimulationConfig& core = defaultSimulationConfig();
  EXPECT_EQ(core.thermal.integrator, ThermalParams{}.integrator);
  EXPECT_EQ(makeSimulationConfig(defaults()).thermal.integrator, core.thermal.integrator);
  EXPECT_EQ(schemaDefault("solvers.thermal.integrator"),
            thermalIntegratorName(ThermalParams{}.integrator));
  EXPECT_EQ(ThermalParams{}.integrator, ThermalIntegrator::Explicit);  // README: the default
}

TEST(RunConfig, DenseMemoryLimitDefaultIsOne) {
  const double core = ElectricSolverOptions{}.denseMemoryLimitBytes;
  EXPECT_EQ(defaultSimulationConfig().electricSolver.denseMemoryLimitBytes, core);
  EXPECT_EQ(makeSimulationConfig(defaults()).electricSolver.denseMemoryLimitBytes, core);
  EXPECT_EQ(schemaDefault("solvers.electric.dense_memory_limit_mb"), "2048");
  EXPECT_EQ(core, 2048.0 * 1048576.0);
}

TEST(RunConfig, ElectricCacheLimitIsAKeyInMegabytes) {
  EXPECT_EQ(schemaDefault("solvers.electric.cache_memory_limit_mb"), "1024");
  EXPECT_EQ(ElectricSolverOptions{}.cacheMemoryLimitBytes, 1024.0 * 1048576.0);
  Scenario s = defaults();
  s.solvers.electricCacheMemoryLimitMb = 64;
  EXPECT_EQ(makeSimulationConfig(s).electricSolver.cacheMemoryLimitBytes, 64.0 * 1048576.0);
}

// every mapped field of a default scenario equals the core's default
TEST(RunConfig, EveryDefaultComesFromTheCore) {
  const SimulationConfig& d = defaultSimulationConfig();
  const SimulationConfig c = makeSimulationConfig(defaults());
  EXPECT_EQ(c.conductivityS_m, d.conductivityS_m);
  EXPECT_EQ(c.toolVoltageV, d.toolVoltageV);
  EXPECT_EQ(c.contactDistanceM, d.contactDistanceM);
  EXPECT_EQ(c.electrode.radiusM, d.electrode.radiusM);
  EXPECT_EQ(c.electrode.lengthM, d.electrode.lengthM);
  EXPECT_EQ(c.electrode.widthM, d.electrode.widthM);
  EXPECT_EQ(c.returnElectrode.centerM, d.returnElectrode.centerM);
  EXPECT_EQ(c.returnElectrode.normal, d.returnElectrode.normal);
  EXPECT_EQ(c.returnElectrode.radiusM, d.returnElectrode.radiusM);
  EXPECT_EQ(c.returnElectrode.toleranceM, d.returnElectrode.toleranceM);
  EXPECT_EQ(c.electricSolver.strategy, d.electricSolver.strategy);
  EXPECT_EQ(c.electricSolver.pcgTolerance, d.electricSolver.pcgTolerance);
  EXPECT_EQ(c.electricSolver.pcgMaxIterations, d.electricSolver.pcgMaxIterations);
  EXPECT_EQ(c.electricSolver.pcgPreconditioner, d.electricSolver.pcgPreconditioner);
  EXPECT_EQ(c.electricSolver.threads, d.electricSolver.threads);
  EXPECT_EQ(c.electricSolver.cacheMemoryLimitBytes, d.electricSolver.cacheMemoryLimitBytes);
  EXPECT_EQ(c.conductivityTempCoeffPerK, d.conductivityTempCoeffPerK);
  EXPECT_EQ(c.desiccatedConductivityFactor, d.desiccatedConductivityFactor);
  const ThermalParams &t = c.thermal, &dt = d.thermal;
  EXPECT_EQ(t.heatCapacityJ_m3K, dt.heatCapacityJ_m3K);
  EXPECT_EQ(t.conductivityW_mK, dt.conductivityW_mK);
  EXPECT_EQ(t.initialTemperatureC, dt.initialTemperatureC);
  EXPECT_EQ(t.boilingTemperatureC, dt.boilingTemperatureC);
  EXPECT_EQ(t.waterFraction, dt.waterFraction);
  EXPECT_EQ(t.densityKg_m3, dt.densityKg_m3);
  EXPECT_EQ(t.latentHeatJ_kg, dt.latentHeatJ_kg);
  EXPECT_EQ(t.lumpedMass, dt.lumpedMass);
  EXPECT_EQ(t.allowSubstepping, dt.allowSubstepping);
  EXPECT_EQ(t.maxSubsteps, dt.maxSubsteps);
  EXPECT_EQ(t.ambientTemperatureC, dt.ambientTemperatureC);
  EXPECT_EQ(t.arrheniusA_s, dt.arrheniusA_s);
  EXPECT_EQ(t.arrheniusEa_J_mol, dt.arrheniusEa_J_mol);
  EXPECT_EQ(c.heatSource.centerM, d.heatSource.centerM);
  EXPECT_EQ(c.heatSource.radiusM, d.heatSource.radiusM);
  EXPECT_EQ(c.heatSource.powerDensityW_m3, d.heatSource.powerDensityW_m3);
  EXPECT_EQ(c.hotSpot.temperatureC, d.hotSpot.temperatureC);
  EXPECT_EQ(c.structural.youngsModulusPa, d.structural.youngsModulusPa);
  EXPECT_EQ(c.structural.poissonRatio, d.structural.poissonRatio);
  EXPECT_EQ(c.criticalStressPa, d.criticalStressPa);
  EXPECT_EQ(c.vaporLiquidVolumeRatio, d.vaporLiquidVolumeRatio);
  EXPECT_EQ(c.vaporLiquidVolumeRatio, ExpansionParams{}.vaporLiquidVolumeRatio);
  EXPECT_EQ(c.maxVaporExpansion, ExpansionParams{}.maxExpansion);
  EXPECT_EQ(c.clampBandM, d.clampBandM);
  EXPECT_EQ(c.rebuildMode, d.rebuildMode);
  EXPECT_EQ(c.rebuildLagFrames, d.rebuildLagFrames);
  EXPECT_EQ(c.recomputeLagFrames, d.recomputeLagFrames);
  EXPECT_EQ(c.structural.solveMethod, d.structural.solveMethod);
  EXPECT_EQ(c.structural.local.marginM, d.structural.local.marginM);
  EXPECT_EQ(c.structural.local.slackM, d.structural.local.slackM);
  EXPECT_EQ(c.structural.local.maxRegionFraction, d.structural.local.maxRegionFraction);
  EXPECT_EQ(c.structural.local.refreshEvery, d.structural.local.refreshEvery);
  EXPECT_EQ(c.structural.local.refreshOnThread, d.structural.local.refreshOnThread);
  EXPECT_EQ(c.structural.local.coarseSpacingM, d.structural.local.coarseSpacingM);
  EXPECT_EQ(c.structural.local.coarseLoadTolerance, d.structural.local.coarseLoadTolerance);
  EXPECT_EQ(c.structural.local.coarseCorrection, d.structural.local.coarseCorrection);
  EXPECT_EQ(c.structural.vectorizedUpdate, d.structural.vectorizedUpdate);
}

// the appearance keys reach the renderer's options, and their defaults are the renderer's
TEST(RunConfig, AppearanceKeysReachTheRenderer) {
  const RenderOptions d, c = makeRenderOptions(defaults());
  EXPECT_EQ(c.textureSeed, d.textureSeed);
  EXPECT_EQ(c.tissueTint, d.tissueTint);
  EXPECT_EQ(c.keyLightCamera, d.keyLightCamera);
  EXPECT_EQ(c.lightIntensity, d.lightIntensity);
  EXPECT_EQ(c.cutWallNormalPasses, d.cutWallNormalPasses);
  EXPECT_EQ(c.cutWallDamagePasses, d.cutWallDamagePasses);
  Scenario s = defaults();
  s.look.textureSeed = 123456789;
  s.look.tissueTint = {0.9, 1.1, 0.8};
  s.look.lightDirection = {1, 2, 3};
  s.look.lightIntensity = 1.5;
  s.look.cutWallSmoothing = 7;
  s.look.cutWallDamageSmoothing = 5;
  const RenderOptions r = makeRenderOptions(s);
  EXPECT_EQ(r.textureSeed, 123456789u);
  EXPECT_EQ(r.tissueTint, (std::array<float, 3>{0.9f, 1.1f, 0.8f}));
  EXPECT_EQ(r.keyLightCamera, (std::array<float, 3>{1, 2, 3}));
  EXPECT_EQ(r.lightIntensity, 1.5f);
  EXPECT_EQ(r.cutWallNormalPasses, 7);
  EXPECT_EQ(r.cutWallDamagePasses, 5);
  // the schema's range is the renderer's: its largest value renders, one more is refused
  for (const char* key : {"cut_wall_smoothing", "cut_wall_damage_smoothing"}) {
    EXPECT_NO_THROW(parseScenario(
        "name: w\nlook:\n  " + std::string(key) + ": " + std::to_string(kMaxCutWallPasses) + "\n",
        "w.yaml"))
        << key;
    EXPECT_THROW(parseScenario("name: w\nlook:\n  " + std::string(key) + ": " +
                                   std::to_string(kMaxCutWallPasses + 1) + "\n",
                               "w.yaml"),
                 Error)
        << key;
  }
}

// solvers.electric.preconditioner reaches pcg's options; the default is two-level
TEST(RunConfig, PcgPreconditionerKeyReachesTheSolver) {
  const auto preconditioner = [](const std::string& name) {
    return makeSimulationConfig(
               parseScenario("name: p\nsolvers:\n  electric:\n    preconditioner: " + name + "\n",
                             "p.yaml"))
        .electricSolver.pcgPreconditioner;
  };
  EXPECT_EQ(preconditioner("jacobi"), PcgPreconditioner::Jacobi);
  EXPECT_EQ(preconditioner("ic"), PcgPreconditioner::IncompleteCholesky);
  EXPECT_EQ(preconditioner("two-level"), PcgPreconditioner::TwoLevel);
  EXPECT_EQ(
      makeSimulationConfig(parseScenario("name: d\n", "d.yaml")).electricSolver.pcgPreconditioner,
      PcgPreconditioner::TwoLevel);
  try {
    preconditioner("multigrid");
    ADD_FAILURE() << "accepted preconditioner: multigrid";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input);
    const std::string what = e.what();
    EXPECT_NE(what.find("p.yaml"), std::string::npos) << what;
    EXPECT_NE(what.find("solvers.electric.preconditioner"), std::string::npos) << what;
    EXPECT_NE(what.find("two-level"), std::string::npos) << what;
  }
}

// solvers.structural.*: the local solve's keys reach the structural phase's options
TEST(RunConfig, StructuralLocalSolveKeysReachThePhase) {
  const Scenario s = parseScenario(
      "name: local\nsolvers:\n  structural:\n    method: local\n    local_margin_m: 0.004\n"
      "    local_refresh_every: 7\n    local_refresh_on_thread: true\n"
      "    local_slack_m: 0.002\n    local_max_region_fraction: 0.8\n"
      "    vectorized_update: false\n    solve_threads: 1\n",
      "local.yaml");
  const SimulationConfig c = makeSimulationConfig(s);
  EXPECT_EQ(c.structural.solveMethod, StructuralSolveMethod::local);
  EXPECT_EQ(c.structural.local.marginM, 0.004);
  EXPECT_EQ(c.structural.local.refreshEvery, 7);
  EXPECT_TRUE(c.structural.local.refreshOnThread);
  EXPECT_EQ(c.structural.local.slackM, 0.002);
  EXPECT_EQ(c.structural.local.maxRegionFraction, 0.8);
  EXPECT_FALSE(c.structural.vectorizedUpdate);
  EXPECT_EQ(c.structural.solveThreads, 1);
  EXPECT_EQ(makeSimulationConfig(parseScenario("name: d\n", "d.yaml")).structural.solveThreads, 2);
  EXPECT_TRUE(
      makeSimulationConfig(parseScenario("name: d\n", "d.yaml")).structural.vectorizedUpdate);
  try {
    parseScenario("name: bad\nsolvers:\n  structural:\n    method: nearby\n", "bad.yaml");
    ADD_FAILURE() << "accepted method: nearby";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input);
    const std::string what = e.what();
    EXPECT_NE(what.find("bad.yaml:4"), std::string::npos) << what;
    EXPECT_NE(what.find("solvers.structural.method"), std::string::npos) << what;
    EXPECT_NE(what.find("full"), std::string::npos) << what;
  }
  try {
    parseScenario("name: bad\nsolvers:\n  structural:\n    local_max_region_fraction: 0\n",
                  "bad.yaml");
    ADD_FAILURE() << "accepted local_max_region_fraction: 0";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input);
    const std::string what = e.what();
    EXPECT_NE(what.find("bad.yaml:4"), std::string::npos) << what;
    EXPECT_NE(what.find("solvers.structural.local_max_region_fraction"), std::string::npos) << what;
  }
}

// solvers.structural.coarse_*: the coarse method's keys reach the structural phase's options
TEST(RunConfig, StructuralCoarseSolveKeysReachThePhase) {
  const Scenario s = parseScenario(
      "name: coarse\nsolvers:\n  structural:\n    method: coarse\n"
      "    coarse_spacing_m: 0.004\n    coarse_load_tolerance: 0.2\n"
      "    coarse_correction: false\n",
      "coarse.yaml");
  const SimulationConfig c = makeSimulationConfig(s);
  EXPECT_EQ(c.structural.solveMethod, StructuralSolveMethod::coarse);
  EXPECT_EQ(c.structural.local.coarseSpacingM, 0.004);
  EXPECT_EQ(c.structural.local.coarseLoadTolerance, 0.2);
  EXPECT_FALSE(c.structural.local.coarseCorrection);
}

void expectRefused(const Scenario& s, const std::string& part) {
  try {
    checkRunnable(s);
    ADD_FAILURE() << "accepted; expected an error with '" << part << "'";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input);
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

// rules that only the core checked passed `esim validate` and failed at `esim run`
TEST(RunConfig, ValidateRunsTheSetUpChecks) {
  EXPECT_NO_THROW(checkRunnable(defaults()));
  // boiling below the initial temperature (the core's rule), named by its scenario key
  expectRefused(parseScenario("material: {boiling_temperature_c: 30}\n", "b.yaml"),
                "material.boiling_temperature_c");
  // a return electrode off the tissue (needs the mesh)
  expectRefused(parseScenario("return_electrode: {center_m: [0, 0, 0.5]}\n", "r.yaml"),
                "return_electrode");
  // the dense inverse above its memory limit (needs the mesh's size)
  expectRefused(parseScenario("solvers: {electric: {strategy: dense-inverse, "
                              "dense_memory_limit_mb: 1}}\n",
                              "d.yaml"),
                "solvers.electric.dense_memory_limit_mb");
  // a nonlocal radius of the body's size (needs the mesh's tets; the cut's physics on)
  expectRefused(parseScenario("physics: [electric, thermal, boiling, structural, rupture]\n"
                              "material: {critical_stress_radius_m: 0.05}\n"
                              "mesh: {slab: {nodes: 8000}}\n",
                              "n.yaml"),
                "material.critical_stress_radius_m = 0.05 m: a frame's average could visit");
}

TEST(RunConfig, ChecksAreTheConstructorsChecks) {
  // the same rule refuses the configuration in the core's constructor, by the same key
  SimulationConfig c = makeSimulationConfig(defaults());
  c.thermal.boilingTemperatureC = 30;
  try {
    Simulation sim(buildMesh(defaults()), c);
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("material.boiling_temperature_c"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace esim::app
