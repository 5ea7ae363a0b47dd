// Tests for sim/simulation.cpp: the frame pipeline builds only the listed phases,
// skips idle stages, conserves current and energy, and is deterministic.
#include "sim/simulation.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <memory>
#include <set>
#include <tuple>

#include "sim/core_error.h"
#include "sim/mesh_slab.h"
#include "sim/structural.h"

namespace esim {
namespace {

SlabSpec smallSlabSpec() {
  SlabSpec s;
  s.sizeM = Vec3(0.06, 0.06, 0.01);
  s.nodesPerAxis = {25, 25, 5};
  return s;
}

TetMesh smallSlab() { return makeSlab(smallSlabSpec()); }

// smallSlab's box and nodes, 4x finer within 4 mm of the blade's path and toward the top
TetMesh gradedSlab() {
  SlabSpec s = smallSlabSpec();
  s.grading.enabled = true;
  s.grading.cutFrom = Vec3(-0.015, 0, 0.01);
  s.grading.cutTo = Vec3(0.015, 0, 0.01);
  s.grading.widthM = 0.004;
  return makeSlab(s);
}

// a blade pressed 0.2 mm into the top face, moving along x
SimulationConfig cutConfig(bool thermal) {
  SimulationConfig c;
  c.phases.electric = true;
  c.phases.thermal = thermal;
  c.phases.boiling = thermal;
  c.returnElectrode.radiusM = 0.025;
  ToolKeyframe a, b;
  a.timeS = 0;
  a.positionM = Vec3(-0.015, 0, 0.0098);
  b.timeS = 0.5;
  b.positionM = Vec3(0.015, 0, 0.0098);
  c.toolPath.keys = {a, b};
  c.toolPath.generatorOnS = {{0.0, 10.0}};
  c.thermal.boiling = thermal;
  return c;
}

// the cut of the update-mode tests: every phase, the blade at 400 V along 2 s
SimulationConfig fullCutConfig(RebuildMode mode) {
  SimulationConfig c = cutConfig(true);
  c.phases.structural = c.phases.rupture = true;
  c.toolVoltageV = 400;
  c.toolPath.keys[1].timeS = 2.0;
  c.rebuildMode = mode;
  return c;
}

// |a - b| / |b|
double relDiff(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return (a - b).norm() / std::max(b.norm(), 1e-300);
}

// two runs of one cut (the update mode against the synchronous rebuild): the same alive set,
// and the same temperature, potential and von Mises stress to 1e-9
void expectTheSameCut(const Simulation& upd, const Simulation& sync) {
  EXPECT_EQ(sync.mesh().alive, upd.mesh().alive);
  EXPECT_LT(relDiff(upd.temperatureC(), sync.temperatureC()), 1e-9);
  EXPECT_LT(relDiff(upd.potentialV(), sync.potentialV()), 1e-9);
  const std::vector<double>& a = *upd.vonMisesPa();
  const std::vector<double>& b = *sync.vonMisesPa();
  EXPECT_LT(relDiff(Eigen::Map<const Eigen::VectorXd>(a.data(), a.size()),
                    Eigen::Map<const Eigen::VectorXd>(b.data(), b.size())),
            1e-9);
}

// the tets each of `frames` steps removed
std::vector<int> removedPerStep(Simulation& sim, int frames) {
  std::vector<int> out;
  for (int f = 0; f < frames; ++f) out.push_back(sim.step().removedTets);
  return out;
}

TEST(Simulation, ElectricOnlyBuildsNoThermalStage) {
  Simulation sim(smallSlab(), cutConfig(false));
  const FrameRecord& r = sim.step();
  EXPECT_EQ(r.status[static_cast<int>(Stage::MoveTool)], StageStatus::Ran);
  EXPECT_EQ(r.status[static_cast<int>(Stage::FindContacts)], StageStatus::Ran);
  EXPECT_EQ(r.status[static_cast<int>(Stage::SolvePotential)], StageStatus::Ran);
  EXPECT_EQ(r.status[static_cast<int>(Stage::Heat)], StageStatus::Absent);
  EXPECT_EQ(r.status[static_cast<int>(Stage::SolveStress)], StageStatus::Absent);
  EXPECT_EQ(sim.thermalState(), nullptr);
  EXPECT_GT(r.contactNodes, 0);
  EXPECT_GT(r.powerW, 0.0);
}

// the default electric strategy, auto, is resolved once from the initial mesh: the paper's
// dense inverse on a small slab, capacitance on a larger one; an explicit one is kept
TEST(Simulation, AutoElectricStrategyFollowsTheMeshSize) {
  SlabSpec small;
  small.sizeM = Vec3(0.06, 0.06, 0.01);
  small.nodesPerAxis = {10, 10, 5};
  EXPECT_EQ(Simulation(makeSlab(small), cutConfig(false)).electricSolverName(), "dense-inverse");
  SlabSpec large = small;
  large.nodesPerAxis = {30, 30, 5};  // 4500 nodes, ~490 on the return electrode
  EXPECT_EQ(Simulation(makeSlab(large), cutConfig(false)).electricSolverName(), "capacitance");
  SimulationConfig pcg = cutConfig(false);
  pcg.electricSolver.strategy = ElectricStrategy::Pcg;
  EXPECT_EQ(Simulation(makeSlab(small), pcg).electricSolverName(), "pcg");
  // the same potential either way
  SimulationConfig cap = cutConfig(false);
  cap.electricSolver.strategy = ElectricStrategy::Capacitance;
  Simulation a(makeSlab(small), cutConfig(false)), b(makeSlab(small), cap);
  const double ia = a.step().toolCurrentA, ib = b.step().toolCurrentA;
  EXPECT_GT(ia, 0.0);
  EXPECT_NEAR(ia, ib, 1e-12 * ib);
}

TEST(Simulation, CurrentIsConservedAndPowerIsVoltageTimesCurrent) {
  Simulation sim(smallSlab(), cutConfig(false));
  for (int f = 0; f < 5; ++f) {
    const FrameRecord& r = sim.step();
    ASSERT_GT(r.toolCurrentA, 0.0);
    EXPECT_NEAR(r.returnCurrentA, r.toolCurrentA, 1e-9 * r.toolCurrentA);
    EXPECT_NEAR(r.powerW, 72.0 * r.toolCurrentA, 1e-9 * r.powerW);
  }
}

TEST(Simulation, GeneratorOffSkipsContactAndPotential) {
  SimulationConfig c = cutConfig(true);
  c.toolPath.generatorOnS = {{0.1, 0.2}};
  Simulation sim(smallSlab(), c);
  const FrameRecord& r = sim.step();  // t = 0: off
  EXPECT_FALSE(r.generatorOn);
  EXPECT_EQ(r.status[static_cast<int>(Stage::FindContacts)], StageStatus::Skipped);
  EXPECT_EQ(r.status[static_cast<int>(Stage::SolvePotential)], StageStatus::Skipped);
  EXPECT_EQ(r.status[static_cast<int>(Stage::Heat)], StageStatus::Skipped);  // at rest, no source
  EXPECT_EQ(r.powerW, 0.0);
  sim.step();
  sim.step();
  sim.step();  // t = 0.1: on
  EXPECT_TRUE(sim.lastRecord().generatorOn);
  EXPECT_EQ(sim.lastRecord().status[static_cast<int>(Stage::Heat)], StageStatus::Ran);
}

TEST(Simulation, CoupledRunConservesEnergy) {
  // heat stored (sensible + latent) equals the Joule energy delivered
  SimulationConfig c = cutConfig(true);
  c.toolVoltageV = 400;  // hot enough to boil within a second
  c.toolPath.keys[1].positionM = c.toolPath.keys[0].positionM;  // held still
  Simulation sim(smallSlab(), c);
  for (int f = 0; f < 90 && sim.thermalState()->latentJ == 0; ++f) sim.step();
  for (int f = 0; f < 5; ++f) sim.step();
  const ThermalState* t = sim.thermalState();
  ASSERT_NE(t, nullptr);
  EXPECT_GT(sim.maxTemperatureSeenC(), 100.0 - 1e-9);
  EXPECT_GT(t->latentJ, 0.0);
  EXPECT_NEAR(t->sourceJ, sim.energyDeliveredJ(), 1e-10 * sim.energyDeliveredJ());
  EXPECT_NEAR(t->sensibleJ + t->latentJ, sim.energyDeliveredJ(), 1e-8 * sim.energyDeliveredJ());
}

TEST(Simulation, SameScenarioTwiceIsBitIdentical) {
  Simulation a(smallSlab(), cutConfig(true)), b(smallSlab(), cutConfig(true));
  for (int f = 0; f < 6; ++f) {
    a.step();
    b.step();
  }
  const Eigen::VectorXd ta = a.temperatureC(), tb = b.temperatureC();
  ASSERT_EQ(ta.size(), tb.size());
  for (int i = 0; i < ta.size(); ++i) ASSERT_EQ(ta[i], tb[i]) << "node " << i;
  EXPECT_EQ(a.contactNodes(), b.contactNodes());
}

TEST(Simulation, ThermalOnlySceneWithPrescribedSource) {
  SimulationConfig c;
  c.phases.thermal = true;
  c.heatSource.enabled = true;
  c.heatSource.centerM = Vec3(0, 0, 0.01);
  c.heatSource.radiusM = 0.003;
  c.heatSource.powerDensityW_m3 = 2e8;
  Simulation sim(smallSlab(), c);
  const FrameRecord& r = sim.step();
  EXPECT_EQ(r.status[static_cast<int>(Stage::SolvePotential)], StageStatus::Absent);
  EXPECT_EQ(r.status[static_cast<int>(Stage::MoveTool)], StageStatus::Absent);
  EXPECT_GT(sim.maxTemperatureSeenC(), 37.0);
  const SurfaceSnapshot snap = sim.snapshot();
  EXPECT_FALSE(snap.tool.present);
  EXPECT_EQ(snap.temperatureC.size(), static_cast<size_t>(snap.numVertices()));
}

TEST(Simulation, SnapshotIsTheClosedSurface) {
  Simulation sim(smallSlab(), cutConfig(true));
  sim.step();
  const SurfaceSnapshot s = sim.snapshot();
  EXPECT_EQ(s.numTriangles(), static_cast<int>(boundaryFaces(sim.mesh()).size()));
  EXPECT_TRUE(s.tool.present);
  EXPECT_NEAR(s.tool.tipM[0], -0.015, 1e-6);
  EXPECT_EQ(sim.lastRecord().status[static_cast<int>(Stage::Snapshot)], StageStatus::Ran);
  // every vertex index in range
  for (auto v : s.triangles) ASSERT_LT(static_cast<int>(v), s.numVertices());
}

TEST(Simulation, TemperatureDependentConductivityScalesTheCurrent) {
  // a uniform 20 K rise multiplies sigma by (1 + 0.02 * 20) = 1.4 everywhere; the potential
  // is unchanged (Laplace is homogeneous in sigma) and the current scales by exactly 1.4
  SimulationConfig base = cutConfig(true);
  base.phases.boiling = false;
  base.thermal.boiling = false;
  base.hotSpot.enabled = true;
  base.hotSpot.centerM = Vec3(0, 0, 0);
  base.hotSpot.radiusM = 1.0;  // the whole slab
  base.hotSpot.temperatureC = 57.0;
  SimulationConfig hot = base;
  hot.temperatureDependentConductivity = true;
  Simulation a(smallSlab(), base), b(smallSlab(), hot);
  const double ia = a.step().toolCurrentA;
  const double ib = b.step().toolCurrentA;
  EXPECT_NEAR(ib / ia, 1.4, 1e-9);
  EXPECT_LT((a.potentialV() - b.potentialV()).cwiseAbs().maxCoeff(), 1e-9);
  for (double s : b.conductivityS_m()) EXPECT_NEAR(s, 0.144 * 1.4, 1e-12);
}

TEST(Simulation, BadInputMessages) {
  SimulationConfig c = cutConfig(false);
  c.phases.structural = true;
  try {
    Simulation sim(smallSlab(), c);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'structural' needs 'thermal' and 'boiling'"),
              std::string::npos);
  }
  c = cutConfig(true);
  c.phases.rupture = true;
  try {
    Simulation sim(smallSlab(), c);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'rupture' needs 'structural'"), std::string::npos);
  }
  c = cutConfig(false);
  c.returnElectrode.centerM = Vec3(0, 0, -0.05);  // below the slab: touches nothing
  try {
    Simulation sim(smallSlab(), c);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("return_electrode: no mesh node lies on the return"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace esim

namespace esim {
namespace {

// thermal scene with a Gaussian source under the top face that boils the water within
// a few frames; structural (and rupture) on top
SimulationConfig boilingSpot(bool rupture) {
  SimulationConfig c;
  c.phases.thermal = c.phases.boiling = c.phases.structural = true;
  c.phases.rupture = rupture;
  c.thermal.boiling = true;
  c.heatSource.enabled = true;
  c.heatSource.centerM = Vec3(0, 0, 0.01);
  c.heatSource.radiusM = 0.003;
  c.heatSource.powerDensityW_m3 = 3e9;
  return c;
}

TEST(Simulation, StructuralStressRisesWhereTheWaterBoils) {
  Simulation sim(smallSlab(), boilingSpot(false));
  double vmBeforeBoiling = 0, vmAfter = 0;
  for (int f = 0; f < 40; ++f) {
    const FrameRecord& r = sim.step();
    EXPECT_EQ(r.status[static_cast<int>(Stage::SolveStress)], StageStatus::Ran);
    EXPECT_EQ(r.status[static_cast<int>(Stage::Rupture)], StageStatus::Absent);
    const auto& x = sim.thermalState()->vaporFractionTet;
    const bool boiling = *std::max_element(x.begin(), x.end()) > 0;
    (boiling ? vmAfter : vmBeforeBoiling) = r.maxVonMisesPa;
  }
  // liquid expansion alone: below 1 kPa (../shared/REFERENCE.md: ~0.8 kPa); vapour: far above
  EXPECT_GT(vmBeforeBoiling, 0.0);
  EXPECT_LT(vmBeforeBoiling, 1.5e3);
  EXPECT_GT(vmAfter, 2.45e4);
  EXPECT_EQ(sim.removedTets(), 0);
}

// the clamp band holds one corner of a tilted slab: the body can turn about it. The
// structural phase's message names the clamp and its key, and it is bad input (nothing ran)
TEST(Simulation, AClampThatHoldsNothingIsRefusedAtItsKey) {
  TetMesh mesh = smallSlab();
  const Eigen::Matrix3d tilt =
      (Eigen::AngleAxisd(0.2, Vec3::UnitX()) * Eigen::AngleAxisd(0.3, Vec3::UnitY()))
          .toRotationMatrix();
  for (Vec3& p : mesh.nodes) p = tilt * p;
  SimulationConfig c = boilingSpot(false);
  c.clampBandM = 0;
  try {
    Simulation sim(mesh, c);
    FAIL() << "built";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input) << e.what();
    EXPECT_EQ(std::string(e.what()),
              "structural: the supports leave the body free to translate or rotate; hold at "
              "least 6 independent displacement components, e.g. by clamping a face (clamped: 1 "
              "bottom node within effects.structural_clamp_band_m = 0 m of the lowest node)");
  }
  // a band wide enough for the lowest edge's nodes holds it
  c.clampBandM = 0.002;
  Simulation sim(mesh, c);
  EXPECT_TRUE(std::isfinite(sim.step().maxVonMisesPa));
}

TEST(Simulation, RuptureRemovesBoilingTissueAndRebuildsTheSurface) {
  auto run = [](Simulation& sim) {
    for (int f = 0; f < 40; ++f) sim.step();
  };
  Simulation sim(smallSlab(), boilingSpot(true));
  const int facesBefore = static_cast<int>(boundaryFaces(sim.mesh()).size());
  int rebuilt = 0;
  for (int f = 0; f < 40; ++f) {
    const FrameRecord& r = sim.step();
    if (r.removedTets > 0) {
      ++rebuilt;
      EXPECT_EQ(r.status[static_cast<int>(Stage::Rebuild)], StageStatus::Ran);
    } else {
      EXPECT_EQ(r.status[static_cast<int>(Stage::Rebuild)], StageStatus::Skipped);
    }
  }
  ASSERT_GT(sim.removedTets(), 0);
  EXPECT_GT(rebuilt, 0);
  EXPECT_EQ(sim.mesh().numAlive(), sim.mesh().numTets() - sim.removedTets());
  // removed where the water boiled: near the source, never at the clamped bottom
  for (int e = 0; e < sim.mesh().numTets(); ++e) {
    if (sim.mesh().isAlive(e)) continue;
    Vec3 c = Vec3::Zero();
    for (int v : sim.mesh().tets[e]) c += 0.25 * sim.mesh().nodes[v];
    EXPECT_LT((c - Vec3(0, 0, 0.01)).norm(), 0.01);
  }
  // the snapshot is the new surface: the crater's faces are cut walls
  const SurfaceSnapshot snap = sim.snapshot();
  EXPECT_EQ(snap.numTriangles(), static_cast<int>(boundaryFaces(sim.mesh()).size()));
  EXPECT_NE(snap.numTriangles(), facesBefore);
  int walls = 0;
  for (float w : snap.cutWall) walls += w > 0 ? 1 : 0;
  EXPECT_GT(walls, 0);
  for (auto v : snap.triangles) ASSERT_LT(static_cast<int>(v), snap.numVertices());
  // deterministic: the same removals again
  Simulation again(smallSlab(), boilingSpot(true));
  run(again);
  EXPECT_EQ(again.mesh().alive, sim.mesh().alive);
}

// a cut wall is a face of the surface that was not on the initial one: the snapshot's flags
// against that definition by the faces' nodes, on a slab whose mesh comes with dead tets (a
// step in one corner, as a .vtu's alive flags give: its faces are the initial surface, not
// cut walls), in both ways a removal is taken
TEST(Simulation, CutWallsAreTheFacesNotOnTheInitialSurface) {
  for (RebuildMode mode : {RebuildMode::Update, RebuildMode::Synchronous}) {
    SCOPED_TRACE(rebuildModeName(mode));
    TetMesh mesh = smallSlab();
    mesh.alive.assign(mesh.tets.size(), 1);
    int dead = 0;
    for (int e = 0; e < mesh.numTets(); ++e) {
      Vec3 c = Vec3::Zero();
      for (int v : mesh.tets[e]) c += 0.25 * mesh.nodes[v];
      if (c.x() > 0.015 && c.z() > 0.005) mesh.alive[e] = 0, ++dead;
    }
    ASSERT_GT(dead, 0);
    auto key = [](const BoundaryFace& f) {
      std::array<int, 3> k{f.nodes[0], f.nodes[1], f.nodes[2]};
      std::sort(k.begin(), k.end());
      return k;
    };
    std::set<std::array<int, 3>> initial;
    for (const BoundaryFace& f : boundaryFaces(mesh)) initial.insert(key(f));
    SimulationConfig c = boilingSpot(true);
    c.rebuildMode = mode;
    Simulation sim(mesh, c);
    auto expectWalls = [&](const SurfaceSnapshot& snap) -> long {
      std::vector<float> want(snap.numVertices(), 0.0f);
      const std::vector<BoundaryFace> faces = boundaryFaces(sim.mesh());
      EXPECT_EQ(snap.numTriangles(), static_cast<int>(faces.size()));
      if (snap.numTriangles() != static_cast<int>(faces.size())) return -1;
      for (size_t i = 0; i < faces.size(); ++i)
        if (!initial.count(key(faces[i])))
          for (int k = 0; k < 3; ++k) want[snap.triangles[3 * i + k]] = 1.0f;
      EXPECT_EQ(snap.cutWall, want);
      return std::count(want.begin(), want.end(), 1.0f);
    };
    EXPECT_EQ(expectWalls(sim.snapshot()), 0);  // the step's faces are no cut walls
    for (int f = 0; f < 40; ++f) sim.step();
    ASSERT_GT(sim.removedTets(), 0);
    EXPECT_GT(expectWalls(sim.snapshot()), 0);
  }
}

// nodes whose every tet broke keep the temperature they had then: the frame's maximum is the
// tissue's (the nodes of alive tets), and an orphan hotter than the tissue left is no breach
// of the maximum principle in the frames after the generator stops
TEST(Simulation, RemovedTissueLeavesTheReportedTemperature) {
  SimulationConfig c = fullCutConfig(RebuildMode::Update);
  c.toolPath.generatorOnS = {{0.0, 1.0}};
  Simulation sim(smallSlab(), c);
  const TetMesh& mesh = sim.mesh();
  int unheatedWithHotterOrphan = 0;
  for (int f = 0; f < 45; ++f) {
    const FrameRecord r = sim.step();
    std::vector<std::uint8_t> active(mesh.nodes.size(), 0);
    for (int e = 0; e < mesh.numTets(); ++e)
      if (mesh.isAlive(e))
        for (int v : mesh.tets[e]) active[v] = 1;
    const Eigen::VectorXd& t = sim.thermalState()->temperatureC;
    double tissue = -1e300, orphan = -1e300;
    for (int i = 0; i < t.size(); ++i) {
      if (active[i])
        tissue = std::max(tissue, t[i]);
      else
        orphan = std::max(orphan, t[i]);
    }
    // the record was taken before this frame's removal: compare the frames without one
    if (r.removedTets == 0) {
      EXPECT_DOUBLE_EQ(r.maxTemperatureC, tissue) << "frame " << f;
    }
    if (r.powerW == 0 && orphan > tissue + 1) ++unheatedWithHotterOrphan;
    EXPECT_EQ(r.maxPrincipleViolationK, 0.0) << "frame " << f;
  }
  ASSERT_GT(sim.removedTets(), 0);
  EXPECT_GT(unheatedWithHotterOrphan, 0);  // the case arose
}

TEST(Simulation, CutWithTheElectricPhaseConservesCurrentAfterRemoval) {
  SimulationConfig c = cutConfig(true);
  c.phases.structural = c.phases.rupture = true;
  c.toolVoltageV = 400;
  c.toolPath.keys[1].timeS = 2.0;  // slow: 15 mm/s
  Simulation sim(smallSlab(), c);
  int frames = 0;
  while (sim.removedTets() == 0 && frames < 60) {
    sim.step();
    ++frames;
  }
  ASSERT_GT(sim.removedTets(), 0) << "no rupture within 2 s at 400 V";
  for (int f = 0; f < 5; ++f) {
    const FrameRecord& r = sim.step();
    if (r.contactNodes == 0) continue;
    EXPECT_NEAR(r.toolCurrentA, r.returnCurrentA, 1e-9 * std::abs(r.toolCurrentA));
    EXPECT_NEAR(r.powerW, c.toolVoltageV * r.toolCurrentA, 1e-9 * r.powerW);
  }
}

// solvers.structural.volumetric: nodal (sim/structural.h, VolumetricStrain): a removal
// refactorizes, so update mode still cuts like the synchronous rebuild; a Poisson's ratio at
// which tets lock warns unless the volumetric strain is at the nodes; nodal is refused with a
// local method, naming both keys
TEST(Simulation, NodalVolumetricStrainInUpdateModeCutsLikeTheSynchronousRebuild) {
  auto config = [](RebuildMode mode, VolumetricStrain v, double nu) {
    SimulationConfig c = fullCutConfig(mode);
    c.structural.volumetric = v;
    c.structural.poissonRatio = nu;
    return c;
  };
  auto run = [&](RebuildMode mode) {
    auto sim =
        std::make_unique<Simulation>(smallSlab(), config(mode, VolumetricStrain::nodal, 0.49));
    std::vector<int> removedPerFrame = removedPerStep(*sim, 45);
    return std::make_pair(std::move(sim), removedPerFrame);
  };
  const auto [sync, syncRemoved] = run(RebuildMode::Synchronous);
  const auto [upd, updRemoved] = run(RebuildMode::Update);
  ASSERT_GT(sync->removedTets(), 0) << "the scene does not cut";
  EXPECT_EQ(syncRemoved, updRemoved);
  expectTheSameCut(*upd, *sync);
  EXPECT_EQ(upd->structuralRefactorizations(), 0);  // every removal an update
  {  // updates refused (their cost over a refactorization's at any size): each one counted
    SimulationConfig c = config(RebuildMode::Update, VolumetricStrain::nodal, 0.49);
    c.structural.updateCostLimit = 0;
    Simulation refactor(smallSlab(), c);
    EXPECT_EQ(removedPerStep(refactor, 45), updRemoved);
    EXPECT_EQ(refactor.structuralRefactorizations(), refactor.rebuilds());
  }
  const auto lockingWarnings = [](const Simulation& sim) {
    std::vector<std::string> out;
    for (const std::string& w : sim.warnings())
      if (w.find("lock") != std::string::npos) out.push_back(w);
    return out;
  };
  EXPECT_TRUE(lockingWarnings(*upd).empty());
  const Simulation locked(smallSlab(),
                          config(RebuildMode::Update, VolumetricStrain::element, 0.49));
  ASSERT_EQ(lockingWarnings(locked).size(), 1u);
  EXPECT_EQ(lockingWarnings(locked)[0].rfind(
                "material.poisson_ratio = 0.49 with solvers.structural.volumetric: element: "
                "linear tets lock",
                0),
            0u)
      << lockingWarnings(locked)[0];
  EXPECT_TRUE(lockingWarnings(Simulation(smallSlab(), config(RebuildMode::Update,
                                                             VolumetricStrain::element, 0.47)))
                  .empty());
  SimulationConfig local = config(RebuildMode::Update, VolumetricStrain::nodal, 0.49);
  local.structural.solveMethod = StructuralSolveMethod::local;
  try {
    validateSimulationConfig(local);
    FAIL() << "nodal with the local method accepted";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "solvers.structural.volumetric = nodal with solvers.structural.method = local: "
                 "the volumetric strain at the nodes works with the full method only; set the "
                 "method to full or the volumetric strain to element");
  }
}

// solvers.rebuild.mode: update edits the model in place in the frame the tets break; over a
// whole cut (electric, thermal, boiling, structural, rupture) it removes the same tets in
// the same frames as the synchronous rebuild, with the same fields to 1e-9
TEST(Simulation, UpdateModeCutsLikeTheSynchronousRebuild) {
  auto run = [](RebuildMode mode) {
    SimulationConfig c = fullCutConfig(mode);
    c.prefetchUntilS = 2.0;  // update: the exposed surface's columns on a thread (joined)
    auto sim = std::make_unique<Simulation>(smallSlab(), c);
    std::vector<int> removedPerFrame = removedPerStep(*sim, 45);
    return std::make_pair(std::move(sim), removedPerFrame);
  };
  const auto [sync, syncRemoved] = run(RebuildMode::Synchronous);
  const auto [upd, updRemoved] = run(RebuildMode::Update);
  ASSERT_GT(sync->removedTets(), 0) << "the scene does not cut";
  EXPECT_GT(sync->rebuilds(), 1);
  EXPECT_EQ(syncRemoved, updRemoved);
  expectTheSameCut(*upd, *sync);
  // the surfaces are the same faces in the same order (removeFromBoundary)
  const SurfaceSnapshot sa = upd->snapshot(), sb = sync->snapshot();
  EXPECT_EQ(sa.triangles, sb.triangles);
}

// solvers.electric.strategy: downdate (one factor edited through every removal: rows deleted,
// rank-one updates and downdates) cuts like a synchronous rebuild that factorizes the potential's
// matrix afresh at every contact change (refactor): the same tets in the same frames, the same
// fields to 1e-9
TEST(Simulation, TheDowndatePotentialCutsLikeAFreshFactorizationEveryFrame) {
  auto run = [](RebuildMode mode, ElectricStrategy strategy) {
    SimulationConfig c = fullCutConfig(mode);
    c.electricSolver.strategy = strategy;
    auto sim = std::make_unique<Simulation>(smallSlab(), c);
    std::vector<int> removedPerFrame = removedPerStep(*sim, 45);
    return std::make_pair(std::move(sim), removedPerFrame);
  };
  const auto [fresh, freshRemoved] = run(RebuildMode::Synchronous, ElectricStrategy::Refactor);
  const auto [upd, updRemoved] = run(RebuildMode::Update, ElectricStrategy::Downdate);
  ASSERT_GT(fresh->rebuilds(), 1) << "the scene does not cut";
  EXPECT_EQ(freshRemoved, updRemoved);
  expectTheSameCut(*upd, *fresh);
}

// the face-connected pieces of the alive tets: per piece, its volume [m^3] and whether a node of
// it lies within the clamp band of the lowest node (held by a support)
struct AlivePiece {
  double volumeM3 = 0;
  bool supported = false;  // a node in the clamp band
  int tets = 0;
};
// the face-connected pieces of the alive tets; pieceOfTet: each tet's (-1 removed)
std::vector<AlivePiece> alivePieces(const TetMesh& m, double clampBandM,
                                    std::vector<int>* pieceOfTet = nullptr) {
  const auto geo = tetGeometry(m);
  double zMin = INFINITY;
  for (const Vec3& p : m.nodes) zMin = std::min(zMin, p.z());
  int count = 0;
  const std::vector<int> pieceOf = tetPieces(m, &count);
  std::vector<AlivePiece> pieces(count);
  for (int t = 0; t < m.numTets(); ++t) {
    if (pieceOf[t] < 0) continue;
    pieces[pieceOf[t]].volumeM3 += geo[t].volume;
    ++pieces[pieceOf[t]].tets;
    for (int v : m.tets[t]) pieces[pieceOf[t]].supported |= m.nodes[v].z() <= zMin + clampBandM;
  }
  if (pieceOfTet) *pieceOfTet = pieceOf;
  return pieces;
}

// material.debris_volume_m3 (sim/rupture_debris.h) in the frame loop: a cut whose removals
// leave pieces hanging by an edge or a node (here up to 100 mm^3: a few of this slab's tets)
// removes them with the tets that broke. Afterwards no unsupported piece of at most that
// volume is left (with debris off, they are: the structural phase holds them in place), and
// the update mode removes the same tets in the same frames as the synchronous rebuild, with
// the same fields
TEST(Simulation, DebrisCutLooseGoesWithTheCutInEveryRebuildMode) {
  const double maxV = 1e-7;
  auto run = [maxV](RebuildMode mode, double debrisM3) {
    SimulationConfig c = fullCutConfig(mode);
    c.debrisVolumeM3 = debrisM3;
    auto sim = std::make_unique<Simulation>(gradedSlab(), c);
    std::vector<int> removedPerFrame = removedPerStep(*sim, 45);
    return std::make_pair(std::move(sim), removedPerFrame);
  };
  auto smallFloating = [maxV](const Simulation& sim) {
    int n = 0;
    for (const AlivePiece& p : alivePieces(sim.mesh(), sim.config().clampBandM))
      n += !p.supported && p.volumeM3 <= maxV ? 1 : 0;
    return n;
  };
  const auto [kept, keptRemoved] = run(RebuildMode::Update, 0);
  EXPECT_EQ(kept->debrisTets(), 0);
  EXPECT_GT(smallFloating(*kept), 0) << "the cut leaves no piece loose: nothing to test";
  // the pieces kept leave the structural phase's K: the nodes they share with the tissue (a
  // supported piece) move with it; no node of the tissue is held at 0 but the clamp's
  {
    const TetMesh& m = kept->mesh();
    const double band = kept->config().clampBandM;
    double zMin = INFINITY;
    for (const Vec3& p : m.nodes) zMin = std::min(zMin, p.z());
    std::vector<int> pieceOf;
    const std::vector<AlivePiece> pieces = alivePieces(m, band, &pieceOf);
    std::vector<std::uint8_t> inTissue(m.numNodes(), 0), inLoose(m.numNodes(), 0);
    for (int t = 0; t < m.numTets(); ++t)
      if (pieceOf[t] >= 0)
        for (int v : m.tets[t]) (pieces[pieceOf[t]].supported ? inTissue : inLoose)[v] = 1;
    int shared = 0, heldInTissue = 0;
    const Eigen::VectorXd& u = kept->state().displacementM;
    for (int v = 0; v < m.numNodes(); ++v) {
      shared += inTissue[v] && inLoose[v];
      heldInTissue += inTissue[v] && m.nodes[v].z() > zMin + band && u.segment<3>(3 * v).isZero(0);
    }
    EXPECT_GT(shared, 0) << "no loose piece hangs from the tissue: nothing to test";
    EXPECT_EQ(heldInTissue, 0);
    // the run's count of loose pieces and their tets: the pieces off the clamp band
    int loose = 0, looseTets = 0;
    for (const AlivePiece& p : pieces) {
      loose += !p.supported;
      looseTets += p.supported ? 0 : p.tets;
    }
    EXPECT_GT(loose, 0);
    EXPECT_EQ(kept->loosePieces(), loose);
    EXPECT_EQ(kept->looseTets(), looseTets);
    // each loose piece is drawn moved rigidly with what it hangs by (placeIslands): its own
    // nodes (in no tissue tet) keep their distances; some pieces turn, not only translate
    std::vector<std::vector<int>> own(pieces.size());
    for (int t = 0; t < m.numTets(); ++t)
      if (pieceOf[t] >= 0 && !pieces[pieceOf[t]].supported)
        for (int v : m.tets[t])
          if (!inTissue[v]) own[pieceOf[t]].push_back(v);
    double worstM = 0;
    int turned = 0;
    for (std::vector<int>& o : own) {
      std::sort(o.begin(), o.end());
      o.erase(std::unique(o.begin(), o.end()), o.end());
      bool translatedOnly = true;
      for (size_t i = 0; i < o.size(); ++i)
        for (size_t j = 0; j < i; ++j) {
          const Vec3 rest = m.nodes[o[i]] - m.nodes[o[j]];
          const Vec3 du = u.segment<3>(3 * o[i]) - u.segment<3>(3 * o[j]);
          worstM = std::max(worstM, std::abs((rest + du).norm() - rest.norm()));
          translatedOnly = translatedOnly && du.norm() < 1e-12;
        }
      turned += !translatedOnly;
    }
    EXPECT_LT(worstM, 1e-15);
    EXPECT_GT(turned, 0) << "no loose piece turns: the rotation is not tested";
    std::printf(
        "debris kept: %d tissue nodes shared with loose pieces, %d held, %d pieces turned\n",
        shared, heldInTissue, turned);
  }
  const auto [sync, syncRemoved] = run(RebuildMode::Synchronous, maxV);
  const auto [upd, updRemoved] = run(RebuildMode::Update, maxV);
  EXPECT_GT(upd->debrisTets(), 0);
  EXPECT_LT(upd->debrisTets(), upd->removedTets());
  EXPECT_EQ(smallFloating(*upd), 0);
  EXPECT_EQ(upd->loosePieces(), 0);
  EXPECT_EQ(upd->looseTets(), 0);
  EXPECT_EQ(sync->debrisTets(), upd->debrisTets());
  EXPECT_EQ(syncRemoved, updRemoved);
  expectTheSameCut(*upd, *sync);
  // in the background the debris is counted with its rebuild, when it swaps in
  const auto [bg, bgRemoved] = run(RebuildMode::Background, maxV);
  EXPECT_GT(bg->debrisTets(), 0);
  EXPECT_LT(bg->debrisTets(), bg->removedTets());
  std::printf("removed %d tets, %d of them debris (debris kept: %d removed, %d pieces loose)\n",
              upd->removedTets(), upd->debrisTets(), kept->removedTets(), smallFloating(*kept));
}

// material.critical_stress_radius_m: the nonlocal criterion (sim/rupture_nonlocal.h) in the
// frame loop. A radius below every distance between centroids is the paper's criterion to the
// bit; a wider one removes fewer tets in this scene (the averaged peak is lower), the update
// mode still the same tets in the same frames as the synchronous rebuild
TEST(Simulation, NonlocalCriticalStressInTheFrameLoop) {
  auto run = [](RebuildMode mode, double radiusM) {
    SimulationConfig c = fullCutConfig(mode);
    c.criticalStressRadiusM = radiusM;
    auto sim = std::make_unique<Simulation>(smallSlab(), c);
    std::vector<int> removedPerFrame = removedPerStep(*sim, 45);
    return std::make_pair(std::move(sim), removedPerFrame);
  };
  const auto [local, localRemoved] = run(RebuildMode::Update, 0);
  const auto [tiny, tinyRemoved] = run(RebuildMode::Update, 1e-6);
  ASSERT_GT(local->removedTets(), 0) << "the scene does not cut";
  EXPECT_EQ(tinyRemoved, localRemoved);
  EXPECT_EQ(tiny->mesh().alive, local->mesh().alive);
  const auto [sync, syncRemoved] = run(RebuildMode::Synchronous, 0.004);
  const auto [upd, updRemoved] = run(RebuildMode::Update, 0.004);
  EXPECT_GT(upd->removedTets(), 0);
  EXPECT_LT(upd->removedTets(), local->removedTets());
  EXPECT_EQ(syncRemoved, updRemoved);
  EXPECT_EQ(sync->mesh().alive, upd->mesh().alive);
  std::printf("removed: local %d, nonlocal 4 mm %d\n", local->removedTets(), upd->removedTets());
}

// solvers.structural.solve_threads: the structural solves and a removal's updates on one thread
// or two give the same cut to the bit (ldl_solve.h and ldl_updown.h run the same arithmetic
// either way): the same tets in the same frames, the same stresses and temperatures
TEST(Simulation, StructuralThreadsGiveTheSameCutToTheBit) {
  auto run = [](int threads) {
    SimulationConfig c = fullCutConfig(RebuildMode::Update);
    c.structural.solveThreads = threads;
    auto sim = std::make_unique<Simulation>(smallSlab(), c);
    std::vector<int> removedPerFrame = removedPerStep(*sim, 45);
    return std::make_pair(std::move(sim), removedPerFrame);
  };
  const auto [one, oneRemoved] = run(1);
  const auto [two, twoRemoved] = run(2);
  ASSERT_GT(one->removedTets(), 0) << "the scene does not cut";
  EXPECT_EQ(oneRemoved, twoRemoved);
  EXPECT_EQ(one->mesh().alive, two->mesh().alive);
  EXPECT_EQ(*one->vonMisesPa(), *two->vonMisesPa());
  EXPECT_EQ(one->temperatureC(), two->temperatureC());
}

// the electric column cache capped in the middle of a cut (esim run gives memory back when
// its cgroup runs short): the cut removes the same tets in the same frames, the fields stay
// within round-off of an uncapped twin, and a cap in a background rebuild waits for its job
TEST(Simulation, AnElectricCacheCappedMidCutCutsTheSame) {
  auto run = [](RebuildMode mode, bool cap) {
    SimulationConfig c = fullCutConfig(mode);
    c.electricSolver.strategy = ElectricStrategy::Capacitance;
    c.prefetchUntilS = 2.0;
    auto sim = std::make_unique<Simulation>(smallSlab(), c);
    std::vector<int> removedPerFrame;
    double freed = 0;
    for (int f = 0; f < 45; ++f) {
      removedPerFrame.push_back(sim->step().removedTets);
      if (cap && f % 10 == 9) freed += sim->limitElectricCache(8.0 * 4 * sim->mesh().numNodes());
    }
    return std::make_tuple(std::move(sim), removedPerFrame, freed);
  };
  for (RebuildMode mode : {RebuildMode::Update, RebuildMode::Background}) {
    SCOPED_TRACE(rebuildModeName(mode));
    const auto [whole, wholeRemoved, none] = run(mode, false);
    const auto [capped, cappedRemoved, freed] = run(mode, true);
    ASSERT_GT(whole->removedTets(), 0) << "the scene does not cut";
    EXPECT_EQ(none, 0.0);
    EXPECT_GT(freed, 0.0);
    EXPECT_DOUBLE_EQ(capped->config().electricSolver.cacheMemoryLimitBytes,
                     8.0 * 4 * capped->mesh().numNodes());
    EXPECT_EQ(cappedRemoved, wholeRemoved);
    EXPECT_LT(relDiff(capped->potentialV(), whole->potentialV()), 1e-12);
    EXPECT_LT(relDiff(capped->temperatureC(), whole->temperatureC()), 1e-12);
  }
}

// solvers.structural.method: local through the whole cut (update mode): the removed set
// and the stress stay close to the full solve's (the local solve holds the far field of
// its last full solve; see LocalSolveOptions)
// the local method on the cut in update mode, its refresh in the frame or on its thread
// (where removals defer the whole factor's update to that thread: the run is then also
// compared with a twin, bit for bit)
// (coarse: the coarse method, a 5 mm grid and a 6 mm region, in place of the local one)
void expectLocalCutsLikeTheFullOne(bool refreshOnThread,
                                   StructuralSolveMethod kind = StructuralSolveMethod::local) {
  auto make = [&](StructuralSolveMethod method) {
    SimulationConfig c = fullCutConfig(RebuildMode::Update);
    c.structural.solveMethod = method;
    c.structural.local.marginM = 0.006;
    c.structural.local.refreshEvery = 10;
    c.structural.local.refreshOnThread = refreshOnThread;
    return std::make_unique<Simulation>(smallSlab(), c);
  };
  auto full = make(StructuralSolveMethod::full), local = make(kind);
  auto twin = refreshOnThread ? make(kind) : nullptr;
  // the two side by side: the stress error of each local solve while the alive sets agree
  int localSolves = 0;
  double worst = 0;
  for (int f = 0; f < 45; ++f) {
    full->step();
    local->step();
    if (twin) {
      twin->step();
      ASSERT_EQ(*twin->vonMisesPa(), *local->vonMisesPa()) << "frame " << f;
    }
    if (!local->model().structural->lastSolveStats().local) continue;
    ++localSolves;
    if (full->mesh().alive != local->mesh().alive) continue;
    double num = 0, den = 0;
    const std::vector<double>& a = *local->vonMisesPa();
    const std::vector<double>& b = *full->vonMisesPa();
    for (size_t e = 0; e < a.size(); ++e) {
      num += (a[e] - b[e]) * (a[e] - b[e]);
      den += b[e] * b[e];
    }
    worst = std::max(worst, std::sqrt(num / std::max(den, 1e-300)));
  }
  EXPECT_GT(localSolves, 10) << "the local method fell back to full solves";
  ASSERT_GT(full->removedTets(), 20) << "the scene does not cut";
  int differ = 0;
  for (size_t e = 0; e < full->mesh().alive.size(); ++e)
    differ += full->mesh().alive[e] != local->mesh().alive[e];
  std::printf(
      "%s vs full: %d local solves, worst von Mises error %.3g, %d of %d removed "
      "tets differ\n",
      kind == StructuralSolveMethod::local ? "local" : "coarse", localSolves, worst, differ,
      full->removedTets());
  EXPECT_GT(worst, 0.0) << "no local solve was compared";
  // the relative L2 error of von Mises over all tets; the coarse method's far field is the
  // coarse grid's (measured 0.175; 0.04 for the local one), its removals the same here
  EXPECT_LT(worst, kind == StructuralSolveMethod::local ? 0.05 : 0.25);
  EXPECT_LE(differ, full->removedTets() / 10);
}

TEST(Simulation, LocalStructuralSolveCutsLikeTheFullOne) { expectLocalCutsLikeTheFullOne(false); }

TEST(Simulation, CoarseStructuralSolveCutsLikeTheFullOne) {
  expectLocalCutsLikeTheFullOne(false, StructuralSolveMethod::coarse);
}

// ThreadSanitizer runs this one (ctest --preset tsan: UpdateMode)
TEST(Simulation, UpdateModeLocalSolveWithItsRefreshOnAThreadCutsLikeTheFullOne) {
  expectLocalCutsLikeTheFullOne(true);
}

// background rebuild: the new structures are built on a thread and swapped in exactly
// rebuildLagFrames frames after the rupture, whatever the thread's speed
TEST(Simulation, BackgroundRebuildSwapsInAtAFixedFrameAndIsDeterministic) {
  auto run = [](int lag, bool background, std::vector<int>* ruptureFrames,
                std::vector<int>* swapFrames) {
    SimulationConfig c = boilingSpot(true);
    c.rebuildMode = background ? RebuildMode::Background : RebuildMode::Synchronous;
    c.rebuildLagFrames = lag;
    SlabSpec spec;  // a quarter of smallSlab() at the same spacing: 845 nodes
    spec.sizeM = Vec3(0.03, 0.03, 0.01);
    spec.nodesPerAxis = {13, 13, 5};
    auto sim = std::make_unique<Simulation>(makeSlab(spec), c);
    for (int f = 0; f < 30; ++f) {
      const FrameRecord& r = sim->step();
      if (ruptureFrames && r.status[static_cast<int>(Stage::Rupture)] == StageStatus::Ran)
        ruptureFrames->push_back(f);
      if (swapFrames && r.removedTets > 0) swapFrames->push_back(f);
    }
    return sim;
  };
  std::vector<int> ruptures, swaps;
  const auto a = run(4, true, &ruptures, &swaps);
  ASSERT_FALSE(swaps.empty());
  ASSERT_FALSE(ruptures.empty());
  EXPECT_EQ(swaps.front(), ruptures.front() + 4);  // the first rebuild swaps in at f + lag
  for (size_t k = 1; k < swaps.size(); ++k) EXPECT_GE(swaps[k] - swaps[k - 1], 4);
  EXPECT_EQ(a->rebuilds(), static_cast<int>(swaps.size()));
  // the same run again: the same removals and temperatures, bit for bit
  const auto b = run(4, true, nullptr, nullptr);
  EXPECT_EQ(a->mesh().alive, b->mesh().alive);
  EXPECT_EQ((a->temperatureC() - b->temperatureC()).cwiseAbs().maxCoeff(), 0.0);
  // lag 0 on a thread is the synchronous rebuild
  const auto sync = run(0, false, nullptr, nullptr);
  const auto zero = run(0, true, nullptr, nullptr);
  EXPECT_EQ(sync->mesh().alive, zero->mesh().alive);
  EXPECT_EQ((sync->temperatureC() - zero->temperatureC()).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(sync->removedTets(), 0);
}

// background rebuild with the lag frames recomputed: up to the swap it is the synchronous
// run, bit for bit, as long as no other tet breaks during the lag
TEST(Simulation, RecomputedLagFramesMatchTheSynchronousRun) {
  SlabSpec spec;
  spec.sizeM = Vec3(0.03, 0.03, 0.01);
  spec.nodesPerAxis = {13, 13, 5};
  auto make = [&](bool background, int lag) {
    SimulationConfig c = boilingSpot(true);
    c.rebuildMode = background ? RebuildMode::Background : RebuildMode::Synchronous;
    c.rebuildLagFrames = lag;
    c.recomputeLagFrames = true;
    return std::make_unique<Simulation>(makeSlab(spec), c);
  };
  // the synchronous run's first two removal frames
  auto sync = make(false, 0);
  std::vector<int> removals;
  for (int f = 0; f < 40 && removals.size() < 2; ++f)
    if (sync->step().removedTets > 0) removals.push_back(f);
  ASSERT_EQ(removals.size(), 2u);
  const int lag = removals[1] - removals[0] - 1;
  ASSERT_GE(lag, 1) << "removals in consecutive frames: no lag to test";
  auto bg = make(true, lag);
  auto ref = make(false, 0);
  for (int f = 0; f <= removals[0] + lag; ++f) {
    const FrameRecord& r = bg->step();
    ref->step();
    if (f == removals[0] + lag) {
      EXPECT_GT(r.removedTets, 0);  // the swap frame
    }
  }
  EXPECT_EQ(bg->recomputedFrames(), lag);
  EXPECT_EQ(bg->mesh().alive, ref->mesh().alive);
  EXPECT_EQ((bg->temperatureC() - ref->temperatureC()).cwiseAbs().maxCoeff(), 0.0);
}

// ---- guards: a tool the contact rule would lose, bounded work, prescribed energy ----

namespace guards {

// a sphere electrode held at p, generator on
SimulationConfig sphereAt(const Vec3& p) {
  SimulationConfig c = cutConfig(false);
  c.electrode.kind = ElectrodeKind::Sphere;
  ToolKeyframe k;
  k.positionM = p;
  c.toolPath.keys = {k};
  return c;
}

TEST(SimulationGuards, ABuriedElectrodeDeliversCurrentAndSaysHow) {
  // 2 mm below the top face of a 2.5 mm grid: no node within 0.8 mm of the ball
  Simulation sim(smallSlab(), sphereAt(Vec3(0.0013, 0.0013, 0.006)));
  const FrameRecord& r = sim.step();
  EXPECT_TRUE(r.contactByTet);
  EXPECT_EQ(r.contactNodes, 1);
  EXPECT_GT(r.powerW, 0.0);
  EXPECT_NEAR(r.returnCurrentA, r.toolCurrentA, 1e-9 * r.toolCurrentA);
  ASSERT_EQ(sim.warnings().size(), 2u);  // the set-up's depth (below), then the fallback
  EXPECT_EQ(sim.warnings()[0].rfind("the tool reaches 4.5 mm under the tissue's surface", 0), 0u)
      << sim.warnings()[0];
  EXPECT_NE(sim.warnings()[1].find("tool.contact_distance_m"), std::string::npos);
  // above the tissue: no contact, no fallback
  Simulation air(smallSlab(), sphereAt(Vec3(0.0013, 0.0013, 0.02)));
  EXPECT_EQ(air.step().contactNodes, 0);
  ASSERT_EQ(air.warnings().size(), 1u);
  EXPECT_NE(air.warnings()[0].find("touched the tissue in none"), std::string::npos);
}

// Contact is found among the surface's nodes: a tool deeper than its contact distance
// touches the tissue only where it enters it (liver_cut's blade ran 3.4-3.7 mm deep). The
// set-up says so, with the depth and when; a tip 0.2 mm in, a sphere resting on the face, or
// a blade going down to the contact distance and 1 mm more, say nothing.
TEST(SimulationGuards, AToolDeeperThanItsContactDistanceIsNamedAtSetUp) {
  SimulationConfig deep = cutConfig(false);
  deep.toolPath.keys[1].positionM.z() = 0.006;  // down to 4 mm under the top face at 0.5 s
  Simulation sim(smallSlab(), deep);
  ASSERT_EQ(sim.warnings().size(), 1u);
  EXPECT_EQ(sim.warnings()[0],
            "the tool reaches 4.0 mm under the tissue's surface at t = 0.50 s (tool.path; the "
            "surface as it is at the start): contact is found among the surface's nodes, so a "
            "tool deeper than tool.contact_distance_m (0.8 mm) touches the tissue only where it "
            "enters it; keep the tool within that of the surface, or set tool.contact: volume for "
            "a tool inside the tissue");
  deep.contactNodes = ContactNodes::Volume;  // then it touches the tissue along its depth
  EXPECT_TRUE(Simulation(smallSlab(), deep).warnings().empty());
  EXPECT_TRUE(Simulation(smallSlab(), cutConfig(false)).warnings().empty());
  EXPECT_TRUE(Simulation(smallSlab(), sphereAt(Vec3(0, 0, 0.0103))).warnings().empty());
  SimulationConfig edge = cutConfig(false);
  edge.toolPath.keys[1].positionM.z() = 0.0083;  // 1.7 mm: under 0.8 + 1 mm
  EXPECT_TRUE(Simulation(smallSlab(), edge).warnings().empty());
  // a blade nearly flat, its tip 0.2 mm in and its heel down: turned 95 deg about x, its width
  // along x, its 20 mm axis along -y and 5 deg down, so its far end is 20 sin 5 deg = 1.74 mm
  // lower (1.94 mm deep); the tip alone said nothing
  SimulationConfig flat = cutConfig(false);
  for (ToolKeyframe& k : flat.toolPath.keys) {
    k.positionM = Vec3(0, 0.01, 0.0098);
    k.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(95 * M_PI / 180, Vec3::UnitX()));
  }
  const Simulation heel(smallSlab(), flat);
  ASSERT_EQ(heel.warnings().size(), 1u);
  EXPECT_EQ(heel.warnings()[0].rfind("the tool reaches 1.9 mm under the tissue's surface with its "
                                     "blade 20.0 mm from the tip at t = 0.00 s (tool.path;",
                                     0),
            0u)
      << heel.warnings()[0];
  for (ToolKeyframe& k : flat.toolPath.keys)  // turned 85 deg: the heel rises, no warning
    k.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(85 * M_PI / 180, Vec3::UnitX()));
  EXPECT_TRUE(Simulation(smallSlab(), flat).warnings().empty());
}

}  // namespace guards

// ---- tool.contact: volume, a tool inside the tissue ----

namespace volume_contact {

// A plate held inside the tissue: the blade turned flat (local y, its thickness, along world
// z; its axis along -y), 80 x 80 mm, its mid-plane on the node layer z = 5 mm of the 60 x 60 x
// 10 mm slab, the whole bottom face on the return electrode. With every node of that layer
// at V the field below is that of a parallel-plate capacitor, phi = V z / h (h = 5 mm), and
// above it phi = V: both lie in the P1 space, so the discrete current is exactly
// sigma V A / h and the power sigma V^2 A / h.
SimulationConfig buriedPlate(ContactNodes rule) {
  SimulationConfig c;
  c.phases.electric = true;
  c.contactNodes = rule;
  c.returnElectrode.radiusM = 0.05;  // the whole bottom face (half diagonal 42.4 mm)
  c.electrode.kind = ElectrodeKind::Blade;
  c.electrode.widthM = 0.08;
  c.electrode.lengthM = 0.08;
  ToolKeyframe k;
  k.positionM = Vec3(0, 0.04, 0.005);
  k.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Vec3::UnitX()));
  c.toolPath.keys = {k};
  c.toolPath.generatorOnS = {{0.0, 10.0}};
  return c;
}

TEST(VolumeContact, APlateInsideTheTissueDrawsTheParallelPlateCurrent) {
  const double sigma = SimulationConfig{}.conductivityS_m, volts = SimulationConfig{}.toolVoltageV;
  const double area = 0.06 * 0.06, h = 0.005;
  for (ElectricStrategy s : {ElectricStrategy::DenseInverse, ElectricStrategy::Capacitance,
                             ElectricStrategy::Refactor, ElectricStrategy::Pcg}) {
    SimulationConfig c = buriedPlate(ContactNodes::Volume);
    c.electricSolver.strategy = s;
    c.electricSolver.pcgTolerance = 1e-12;
    Simulation sim(smallSlab(), c);
    const FrameRecord& r = sim.step();
    EXPECT_EQ(r.contactNodes, 25 * 25) << "strategy " << static_cast<int>(s);
    EXPECT_FALSE(r.contactByTet);
    EXPECT_NEAR(r.toolCurrentA, sigma * volts * area / h, 1e-9 * sigma * volts * area / h);
    EXPECT_NEAR(r.powerW, sigma * volts * volts * area / h, 1e-9 * r.powerW);
    EXPECT_NEAR(r.returnCurrentA, r.toolCurrentA, 1e-9 * r.toolCurrentA);
    for (int v = 0; v < sim.mesh().numNodes(); ++v) {
      const double z = sim.mesh().nodes[v].z();
      EXPECT_NEAR(sim.potentialV()[v], z < h ? volts * z / h : volts, 1e-9 * volts) << v;
    }
    EXPECT_TRUE(sim.warnings().empty()) << sim.warnings()[0];
  }
  // the paper's rule holds only the layer's nodes on the side faces: far less current
  Simulation surface(smallSlab(), buriedPlate(ContactNodes::Surface));
  const FrameRecord& r = surface.step();
  EXPECT_EQ(r.contactNodes, 4 * 24);
  EXPECT_LT(r.powerW, 0.9 * sigma * volts * volts * area / h);
}

// a ball of 2.5 mm radius half sunk into the top face (its centre 2.5 mm under it, off the
// grid's lines): it reaches nodes of the top face and of the two layers under it
SimulationConfig sphereAtDepth() {
  SimulationConfig c = buriedPlate(ContactNodes::Surface);
  c.electrode.kind = ElectrodeKind::Sphere;
  c.electrode.radiusM = 0.0025;
  c.toolPath.keys[0].positionM = Vec3(0.0013, 0.0007, 0.0075);
  c.toolPath.keys[0].orientation = Eigen::Quaterniond::Identity();
  return c;
}

// the contact set is every node of an alive tet within the contact distance (brute force over
// the nodes); the surface rule's is the part of it on the surface
TEST(VolumeContact, TheContactsAreTheNodesWithinReach) {
  SimulationConfig c = sphereAtDepth();
  std::vector<size_t> counts;
  for (ContactNodes rule : {ContactNodes::Volume, ContactNodes::Surface}) {
    c.contactNodes = rule;
    Simulation sim(smallSlab(), c);
    sim.step();
    const TetMesh& mesh = sim.mesh();
    const std::vector<int> candidates =
        rule == ContactNodes::Volume ? aliveNodes(mesh) : sim.model().surfaceNodes;
    std::vector<int> expected;
    for (int v : candidates)
      if (electrodeDistance(c.electrode, sim.state().pose, mesh.nodes[v]) <= c.contactDistanceM)
        expected.push_back(v);
    ASSERT_FALSE(expected.empty());
    EXPECT_EQ(sim.contactNodes(), expected);
    counts.push_back(expected.size());
  }
  EXPECT_GT(counts[0], counts[1]) << "the ball reaches no node under the surface";
}

// a blade drawn 2 mm deep through the slab (its edge reaches the node layer 2.5 mm under the
// top face) at 400 V: the update mode removes the same tets in the same frames as the
// synchronous rebuild, with the same fields to 1e-9, and every frame's contacts are nodes of
// the tets alive when it began (a node whose last tet broke is no longer touched)
TEST(VolumeContact, UpdateModeCutsLikeTheSynchronousRebuild) {
  auto run = [](RebuildMode mode) {
    SimulationConfig c = fullCutConfig(mode);
    c.contactNodes = ContactNodes::Volume;
    for (ToolKeyframe& k : c.toolPath.keys) k.positionM.z() = 0.008;
    auto sim = std::make_unique<Simulation>(smallSlab(), c);
    std::vector<int> removed;
    int interior = 0;
    for (int f = 0; f < 45; ++f) {
      const std::vector<int> alive = aliveNodes(sim->mesh());
      const std::vector<int> surface = sim->model().surfaceNodes;
      removed.push_back(sim->step().removedTets);
      for (int v : sim->contactNodes()) {
        EXPECT_TRUE(std::binary_search(alive.begin(), alive.end(), v)) << "frame " << f;
        interior += !std::binary_search(surface.begin(), surface.end(), v);
      }
    }
    EXPECT_GT(interior, 0) << "no node under the surface was touched";
    return std::make_pair(std::move(sim), removed);
  };
  const auto [sync, syncRemoved] = run(RebuildMode::Synchronous);
  const auto [upd, updRemoved] = run(RebuildMode::Update);
  ASSERT_GT(sync->removedTets(), 0) << "the scene does not cut";
  EXPECT_EQ(syncRemoved, updRemoved);
  expectTheSameCut(*upd, *sync);
}

}  // namespace volume_contact

namespace guards {

// a second body in the mesh, off the return electrode: named at set-up (it carries no current
// whatever the tool does); one body, or both on the pad, say nothing
TEST(SimulationGuards, APieceOffTheReturnElectrodeIsNamed) {
  const TetMesh one = smallSlab();
  TetMesh two = one;
  for (const Vec3& p : one.nodes) two.nodes.push_back(p + Vec3(0.1, 0, 0));
  const int n = one.numNodes();
  for (const Tet& t : one.tets) two.tets.push_back({t[0] + n, t[1] + n, t[2] + n, t[3] + n});
  two.alive.assign(two.tets.size(), 1);
  Simulation sim(two, cutConfig(false));
  const FrameRecord& r = sim.step();
  EXPECT_GT(r.contactNodes, 0);
  EXPECT_NEAR(r.returnCurrentA, r.toolCurrentA, 1e-9 * r.toolCurrentA);
  ASSERT_EQ(sim.warnings().size(), 1u);
  EXPECT_EQ(sim.warnings()[0],
            "the mesh is 2 separate pieces, and 1 of them has no node on the return electrode "
            "(the first: 3125 nodes, from [70.0, -30.0, 0.0] to [130.0, 30.0, 10.0] mm): no "
            "current flows in it, and a tool touching it delivers none (one body per mesh file, "
            "or a return_electrode disc that reaches each piece)");
  SimulationConfig wide = cutConfig(false);
  wide.returnElectrode.centerM = Vec3(0.05, 0, 0);
  wide.returnElectrode.radiusM = 0.1;
  Simulation both(two, wide);
  both.step();
  EXPECT_TRUE(both.warnings().empty()) << both.warnings()[0];
  Simulation single(one, cutConfig(false));
  single.step();
  EXPECT_TRUE(single.warnings().empty()) << single.warnings()[0];
}

TEST(SimulationGuards, AToolThatNeverTouchesTheTissueSaysHowCloseItCame) {
  // the ball (radius 0.5 mm) 10 mm above a node of the slab's top face (z = 10 mm)
  SimulationConfig c = sphereAt(Vec3(0, 0, 0.02));
  c.toolPath.keys.push_back(c.toolPath.keys[0]);
  c.toolPath.keys[1].timeS = 0.1;  // then down 2 mm a frame (less than an element)
  c.toolPath.keys[1].positionM.z() = 0.014;
  Simulation sim(smallSlab(), c);
  for (int f = 0; f < 3; ++f) EXPECT_EQ(sim.step().contactNodes, 0);
  ASSERT_EQ(sim.warnings().size(), 1u);
  const std::string w = sim.warnings()[0];
  EXPECT_NE(w.find("none of the frames with the generator on (3)"), std::string::npos) << w;
  // frame 2 (t = 1/15 s) is the closest, at 16 mm: 16 - 10 - 0.5 = 5.5 mm
  EXPECT_NE(w.find("closest approach to a surface node was 5.50 mm (t = 0.067 s)"),
            std::string::npos)
      << w;
  EXPECT_NE(w.find("z [0.0000, 0.0100] m"), std::string::npos) << w;
  // the generator off throughout: that is the reason given
  c.toolPath.generatorOnS.clear();
  Simulation off(smallSlab(), c);
  off.step();
  ASSERT_EQ(off.warnings().size(), 1u);
  EXPECT_EQ(off.warnings()[0],
            "the generator was off in every frame (1; tool.generator_on): no current flowed");
  // a tool that touches in one frame of many: no warning
  c = sphereAt(Vec3(0, 0, 0.02));
  c.toolPath.keys.push_back(c.toolPath.keys[0]);
  c.toolPath.keys[1].timeS = 0.1;
  c.toolPath.keys[1].positionM.z() = 0.0098;
  Simulation touch(smallSlab(), c);
  int touched = 0;
  for (int f = 0; f < 4; ++f) touched += touch.step().contactNodes > 0;
  EXPECT_EQ(touched, 1);  // frame 3 only (t = 0.1 s)
  EXPECT_TRUE(touch.warnings().empty());
}

TEST(SimulationGuards, AToolCrossingTheTissueInOneFrameKeepsItsContacts) {
  // the blade sweeps 30 mm in one frame (1/30 s): the frame's end pose alone is beyond the
  // slab, its path crosses it
  SimulationConfig c = cutConfig(false);
  c.toolPath.keys[0].positionM = Vec3(-0.015, 0, 0.0098);
  c.toolPath.keys[1].positionM = Vec3(0.045, 0, 0.0098);
  c.toolPath.keys[1].timeS = 1.0 / 30.0;
  Simulation sim(smallSlab(), c);
  sim.step();
  const FrameRecord& r = sim.step();  // from x = 15 mm to 45 mm: off the slab at its end
  EXPECT_TRUE(r.toolSwept);
  EXPECT_GT(r.contactNodes, 0);
  EXPECT_GT(r.powerW, 0.0);
  EXPECT_EQ(sim.warnings().size(), 1u);
}

TEST(SimulationGuards, ExplicitSubstepsAreBoundedUpFront) {
  // a thin slab with a tiny heat capacity: the explicit limit is ~1e-8 s, a frame needs
  // millions of sub-steps (an int overflow before): refused with the remedy
  SimulationConfig c = sphereAt(Vec3(0, 0, 0.0098));
  c.phases.thermal = true;
  c.thermal.heatCapacityJ_m3K = 1.0;
  try {
    Simulation sim(smallSlab(), c);
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input);
    const std::string m = e.what();
    EXPECT_NE(m.find("solvers.thermal.max_substeps"), std::string::npos) << m;
    EXPECT_NE(m.find("backward-euler"), std::string::npos) << m;
  }
  c.thermal.integrator = ThermalIntegrator::BackwardEuler;  // the remedy runs
  Simulation sim(smallSlab(), c);
  const FrameRecord& r = sim.step();
  EXPECT_TRUE(std::isfinite(r.maxTemperatureC));
}

TEST(SimulationGuards, APrescribedSourceCountsAsDeliveredEnergy) {
  SimulationConfig c = boilingSpot(false);
  c.phases.boiling = c.phases.structural = false;
  c.thermal.boiling = false;
  c.heatSource.powerDensityW_m3 = 1e8;
  Simulation sim(smallSlab(), c);
  for (int f = 0; f < 5; ++f) EXPECT_GT(sim.step().powerW, 0.0);
  const ThermalState& t = *sim.thermalState();
  EXPECT_GT(sim.energyDeliveredJ(), 0.0);
  EXPECT_NEAR(sim.energyDeliveredJ(), t.sourceJ, 1e-12 * t.sourceJ);
}

TEST(SimulationGuards, VonMisesSurvivesTheRebuildFrame) {
  Simulation sim(smallSlab(), boilingSpot(true));
  bool seen = false;
  for (int f = 0; f < 40 && !seen; ++f) {
    const FrameRecord& r = sim.step();
    if (r.removedTets == 0) continue;
    seen = true;
    const std::vector<double>& vm = *sim.vonMisesPa();
    EXPECT_EQ(*std::max_element(vm.begin(), vm.end()), r.maxVonMisesPa);
    EXPECT_GT(r.maxVonMisesPa, 2.45e4);
  }
  EXPECT_TRUE(seen);
}

// a stop asked from outside (the front end's signal flag) ends the frame at its next check
// with Interrupted, a Run error; with no flag installed nothing ever interrupts
TEST(SimulationGuards, AStopFlagInterruptsTheFrame) {
  Simulation sim(smallSlab(), cutConfig(true));
  sim.step();
  std::atomic<bool> stop{true};
  setInterruptFlag(&stop);
  try {
    sim.step();
    ADD_FAILURE() << "no interruption";
  } catch (const Interrupted& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Run);
  }
  EXPECT_EQ(sim.frame(), 1) << "an interrupted frame does not count";
  stop = false;
  EXPECT_NO_THROW(sim.step());
  setInterruptFlag(nullptr);
  stop = true;
  EXPECT_NO_THROW(sim.step());
}

TEST(SimulationGuards, AnUndershootOfTheIntegratorIsWarned) {
  // a 90 C ball in a 37 C body, no source, no sink, 10 s steps: Crank-Nicolson with
  // consistent mass undershoots (below 37 C); backward Euler with lumped mass does not
  auto run = [](ThermalIntegrator integrator, bool lumped) {
    SimulationConfig c;
    c.phases.thermal = true;
    c.frameDtS = 10.0;
    c.thermal.integrator = integrator;
    c.thermal.lumpedMass = lumped;
    c.hotSpot.enabled = true;
    c.hotSpot.centerM = Vec3(0, 0, 0.01);
    c.hotSpot.radiusM = 0.004;
    Simulation sim(smallSlab(), c);
    double lowest = 1e9;
    for (int f = 0; f < 4; ++f) {
      sim.step();
      lowest = std::min(lowest, sim.thermalState()->temperatureC.minCoeff());
    }
    return std::make_pair(lowest, sim.warnings());
  };
  const auto [cnLow, cnWarnings] = run(ThermalIntegrator::CrankNicolson, false);
  EXPECT_LT(cnLow, 37.0 - 1e-3);
  ASSERT_EQ(cnWarnings.size(), 1u);
  EXPECT_NE(cnWarnings[0].find("maximum principle"), std::string::npos) << cnWarnings[0];
  EXPECT_NE(cnWarnings[0].find("backward-euler"), std::string::npos) << cnWarnings[0];
  const auto [beLow, beWarnings] = run(ThermalIntegrator::BackwardEuler, true);
  EXPECT_GE(beLow, 37.0 - 1e-9);
  EXPECT_TRUE(beWarnings.empty());
}

}  // namespace guards

TEST(Simulation, SnapshotShowsTheDisplacementScaled) {
  Simulation sim(smallSlab(), boilingSpot(false));
  for (int f = 0; f < 30; ++f) sim.step();
  const SurfaceSnapshot rest = sim.snapshot(0.0);
  const SurfaceSnapshot real = sim.snapshot(1.0);
  const SurfaceSnapshot shown = sim.snapshot(20.0);
  ASSERT_EQ(rest.positionsM.size(), real.positionsM.size());
  const Eigen::VectorXd& u = sim.state().displacementM;
  const std::vector<int>& vertexOf = sim.model().surfaceVertexOf;
  double largest = 0;
  for (int v = 0; v < sim.mesh().numNodes(); ++v) {
    if (vertexOf[v] < 0) continue;
    for (int c = 0; c < 3; ++c) {
      const int i = 3 * vertexOf[v] + c;
      EXPECT_EQ(rest.positionsM[i], static_cast<float>(sim.mesh().nodes[v][c]));
      EXPECT_NEAR(real.positionsM[i] - rest.positionsM[i], u[3 * v + c], 1e-9);
      EXPECT_NEAR(shown.positionsM[i] - rest.positionsM[i], 20.0 * u[3 * v + c], 1e-8);
      largest = std::max(largest, std::abs(u[3 * v + c]));
    }
  }
  EXPECT_GT(largest, 1e-6);  // the boiling spot swells the top by micrometres or more
}

}  // namespace
}  // namespace esim
