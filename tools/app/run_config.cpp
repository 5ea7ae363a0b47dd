// run_config.cpp - scenario -> mesh, SimulationConfig, RenderOptions (see run_config.h).
#include "tools/app/run_config.h"

#include <cmath>
#include <cstdio>

#include "render/video_encoder.h"
#include "sim/core_error.h"
#include "sim/io/mesh_import.h"
#include "sim/mesh_slab.h"

namespace esim::app {

namespace {

void mapElectric(const Scenario& s, SimulationConfig& c) {
  const ScenarioMaterial& m = s.material;
  c.conductivityS_m = m.electricConductivitySPerM;
  c.toolVoltageV = s.tool.voltageV;
  c.contactDistanceM = s.tool.contactDistanceM;
  c.contactNodes = s.tool.contact;
  c.electrode.kind = s.tool.shape;
  c.electrode.radiusM = s.tool.radiusM;
  c.electrode.lengthM = s.tool.lengthM;
  c.electrode.widthM = s.tool.widthM;
  c.returnElectrode.centerM = s.returnElectrode.centerM;
  c.returnElectrode.normal = s.returnElectrode.normal;
  c.returnElectrode.radiusM = s.returnElectrode.radiusM;
  c.returnElectrode.toleranceM = s.returnElectrode.toleranceM;
  c.toolPath = makeToolPath(s);
  c.electricSolver.strategy = s.solvers.electricStrategy;
  c.electricSolver.pcgTolerance = s.solvers.electricTolerance;
  c.electricSolver.pcgMaxIterations = s.solvers.electricMaxIterations;
  c.electricSolver.pcgPreconditioner = s.solvers.electricPreconditioner;
  c.electricSolver.denseMemoryLimitBytes = s.solvers.electricDenseMemoryLimitMb * 1048576.0;
  c.electricSolver.cacheMemoryLimitBytes = s.solvers.electricCacheMemoryLimitMb * 1048576.0;
  c.electricSolver.threads = s.solvers.electricThreads;
  c.electricSolver.localMarginM = s.solvers.electricLocalMarginM;
  c.electricSolver.localRefreshFrames = s.solvers.electricLocalRefreshFrames;
  c.prefetchUntilS = s.solvers.electricPrefetchPath ? s.time.durationS : 0.0;
  c.temperatureDependentConductivity = s.effects.temperatureDependentConductivity;
  c.conductivityTempCoeffPerK = m.conductivityTempCoeffPerK;
  c.desiccatedConductivityFactor = m.desiccatedConductivityFactor;
  c.subgrid.mode = s.subgridContact.mode;
  c.subgrid.areaFactor = s.subgridContact.areaFactor;
}

void mapThermal(const Scenario& s, SimulationConfig& c) {
  const ScenarioMaterial& m = s.material;
  ThermalParams& t = c.thermal;
  t.heatCapacityJ_m3K = m.heatCapacityJPerM3K;
  t.conductivityW_mK = m.thermalConductivityWPerMK;
  t.initialTemperatureC = m.initialTemperatureC;
  t.boiling = c.phases.boiling;
  t.boilingTemperatureC = m.boilingTemperatureC;
  t.waterFraction = m.waterFraction;
  t.densityKg_m3 = m.densityKgPerM3;
  t.latentHeatJ_kg = m.latentHeatJPerKg;
  t.integrator = s.solvers.thermalIntegrator;
  t.lumpedMass = s.solvers.thermalMass == ThermalMass::Lumped;
  t.allowSubstepping = s.solvers.thermalAllowSubstepping;
  t.maxSubsteps = s.solvers.thermalMaxSubsteps;
  t.convectionW_m2K = s.effects.surfaceCoolingHWPerM2K;
  t.ambientTemperatureC = s.effects.surfaceCoolingAmbientC;
  t.damage = s.effects.thermalDamage;
  t.arrheniusA_s = m.arrheniusAPerS;
  t.arrheniusEa_J_mol = m.arrheniusEaJPerMol;
  c.coolTopSurface = s.effects.surfaceCoolingHWPerM2K > 0;
  c.heatSource.enabled = s.heatSource.kind == HeatSourceKind::Gaussian;
  c.heatSource.centerM = s.heatSource.centerM;
  c.heatSource.radiusM = s.heatSource.radiusM;
  c.heatSource.powerDensityW_m3 = s.heatSource.powerDensityWPerM3;
  c.hotSpot.enabled = s.initialHotSpot.enabled;
  c.hotSpot.centerM = s.initialHotSpot.centerM;
  c.hotSpot.radiusM = s.initialHotSpot.radiusM;
  c.hotSpot.temperatureC = s.initialHotSpot.temperatureC;
}

void mapStructural(const Scenario& s, SimulationConfig& c) {
  const ScenarioMaterial& m = s.material;
  c.structural.youngsModulusPa = m.youngsModulusPa;
  c.structural.poissonRatio = m.poissonRatio;
  c.criticalStressPa = m.criticalStressPa;
  c.criticalStressRadiusM = m.criticalStressRadiusM;
  c.debrisVolumeM3 = m.debrisVolumeM3;
  c.vaporLiquidVolumeRatio = m.vaporLiquidVolumeRatio;
  c.maxVaporExpansion = m.maxVaporExpansion;
  c.clampBandM = s.effects.structuralClampBandM;
  c.structural.solveMethod = s.solvers.structuralMethod;
  c.structural.volumetric = s.solvers.structuralVolumetric;
  c.structural.local.marginM = s.solvers.structuralLocalMarginM;
  c.structural.local.slackM = s.solvers.structuralLocalSlackM;
  c.structural.local.maxRegionFraction = s.solvers.structuralLocalMaxRegionFraction;
  c.structural.local.refreshEvery = s.solvers.structuralLocalRefreshEvery;
  c.structural.local.refreshOnThread = s.solvers.structuralLocalRefreshOnThread;
  c.structural.local.coarseSpacingM = s.solvers.structuralCoarseSpacingM;
  c.structural.local.coarseCorrection = s.solvers.structuralCoarseCorrection;
  c.structural.local.coarseLoadTolerance = s.solvers.structuralCoarseLoadTolerance;
  c.structural.vectorizedUpdate = s.solvers.structuralVectorizedUpdate;
  c.structural.solveThreads = s.solvers.structuralSolveThreads;
  c.rebuildMode = s.solvers.rebuildMode;
  c.rebuildLagFrames = s.solvers.rebuildLagFrames;
  c.recomputeLagFrames = s.solvers.rebuildRecompute;
}

}  // namespace

SimulationConfig makeSimulationConfig(const Scenario& s) {
  SimulationConfig c;
  c.phases = phaseSet(s);
  c.frameDtS = 1.0 / s.time.fps;
  mapElectric(s, c);
  mapThermal(s, c);
  mapStructural(s, c);
  return c;
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
  r.textureSeed = static_cast<std::uint32_t>(s.look.textureSeed);
  for (int c = 0; c < 3; ++c) {
    r.tissueTint[c] = static_cast<float>(s.look.tissueTint[c]);
    r.keyLightCamera[c] = static_cast<float>(s.look.lightDirection[c]);
  }
  r.lightIntensity = static_cast<float>(s.look.lightIntensity);
  r.cutWallNormalPasses = s.look.cutWallSmoothing;
  r.cutWallDamagePasses = s.look.cutWallDamageSmoothing;
  return r;
}

TetMesh buildMesh(const Scenario& s) {
  if (s.mesh.source == MeshSource::Slab) return makeSlab(makeSlabSpec(s));
  const ScenarioMeshFile& f = s.mesh.file;
  const MeshingOptions o = makeMeshingOptions(s);  // sizes and refinement near the cut
  return loadTetMesh(f.resolvedPath.empty() ? f.path : f.resolvedPath, o, f.scaleToM);
}

void checkRunnable(const Scenario& s, bool withMesh, bool noVideo) {
  // the checks of the core and the renderer name fields, not files: named here
  try {
    const SimulationConfig config = makeSimulationConfig(s);
    validateSimulationConfig(config);
    if (s.output.video || s.output.pngEvery > 0 || s.output.hashes)
      validateRenderOptions(makeRenderOptions(s));
    if (s.output.video && !noVideo) validateVideoRate(s.time.fps);
    if (withMesh && s.mesh.source == MeshSource::Slab) validateSimulationMesh(buildMesh(s), config);
    if (withMesh && s.mesh.source == MeshSource::File) {  // all but Mesh_3 itself
      const ScenarioMeshFile& f = s.mesh.file;
      checkTetMeshSource(f.resolvedPath.empty() ? f.path : f.resolvedPath, makeMeshingOptions(s),
                         f.scaleToM);
    }
  } catch (const Error& e) {
    rethrowNamingScenario(e, s);
  }
}

void rethrowNamingScenario(const Error& error, const Scenario& scenario) {
  const std::string what = error.what();
  if (error.kind() != ErrorKind::Input || scenario.sourceName.empty() ||
      what.rfind(scenario.sourceName, 0) == 0)
    throw;
  throw Error(scenario.sourceName + ": " + what, error.kind());
}

}  // namespace esim::app
