// validate_cli_test.cpp - `esim validate` end to end: every shipped scenario passes with
// exit 0; a warning of the configuration leaves a file valid; bad files and bad overrides
// print file:line:col messages and exit 2;
// `--reference` prints the committed docs/scenario-reference.md.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/tools/cli_test_util.h"

namespace {

namespace fs = std::filesystem;
const fs::path kRoot = ESIM_SOURCE_DIR;

struct Result {
  int exitCode = -1;
  std::string output;  // stdout and stderr
};

Result runEsim(const std::string& args) {
  const std::string cmd = std::string("\"") + ESIM_EXE + "\" " + args + " 2>&1";
  Result r;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return r;
  char buf[4096];
  size_t n = 0;
  while ((n = fread(buf, 1, sizeof buf, pipe)) > 0) r.output.append(buf, n);
  const int status = pclose(pipe);
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

TEST(ValidateCli, EveryShippedScenarioIsOk) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(kRoot / "scenarios"))
    if (e.path().extension() == ".yaml") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  ASSERT_GE(files.size(), 7u);
  std::string args = "validate";
  for (const auto& f : files) args += " \"" + f.string() + "\"";
  const Result r = runEsim(args);
  EXPECT_EQ(r.exitCode, 0) << r.output;
  for (const auto& f : files)
    EXPECT_NE(r.output.find("ok " + f.string() + ": "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("120 frames (4 s at 30 fps), physics [electric, thermal, boiling]"),
            std::string::npos)
      << r.output;
}

// what the run would warn of from the configuration alone is printed, and the file stays
// valid: linear tets locking at nu = 0.49 (sim/structural.h, VolumetricStrain); not with the
// volumetric strain at the nodes, nor without the structural phase
TEST(ValidateCli, AWarningOfTheConfigurationLeavesTheFileValid) {
  const std::string cut = "\"" + (kRoot / "scenarios/slab_cut.yaml").string() + "\"";
  const Result locked = runEsim("validate " + cut + " --set material.poisson_ratio=0.49");
  EXPECT_EQ(locked.exitCode, 0) << locked.output;
  EXPECT_NE(locked.output.find("ok "), std::string::npos) << locked.output;
  EXPECT_NE(locked.output.find("warning: " + (kRoot / "scenarios/slab_cut.yaml").string() +
                               ": material.poisson_ratio = 0.49 with "
                               "solvers.structural.volumetric: element: linear tets lock"),
            std::string::npos)
      << locked.output;
  for (const std::string& fine :
       {std::string(" --set material.poisson_ratio=0.49 --set solvers.structural.volumetric=nodal"),
        std::string(" --set material.poisson_ratio=0.49 --set physics=[electric,thermal,boiling]"),
        std::string()}) {
    const Result r = runEsim("validate " + cut + fine);
    EXPECT_EQ(r.exitCode, 0) << r.output;
    EXPECT_EQ(r.output.find("warning"), std::string::npos) << fine << ": " << r.output;
  }
}

TEST(ValidateCli, BadInputExitsTwoWithTheMessage) {
  const fs::path bad = fs::temp_directory_path() / "esim_validate_cli_bad.yaml";
  std::ofstream(bad) << "name: bad\ntool:\n  contact_distnce: 0.001\n";
  const fs::path good = kRoot / "scenarios/paper_slab.yaml";
  const Result r = runEsim("validate \"" + good.string() + "\" \"" + bad.string() + "\"");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("ok " + good.string()), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("error: " + bad.string() +
                          ":3:3: tool.contact_distnce: unknown key; did you mean "
                          "'contact_distance_m'?"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("1 of 2 scenarios invalid"), std::string::npos) << r.output;
  fs::remove(bad);

  const Result o = runEsim("validate \"" + good.string() + "\" --set physics=[electric,rupture]");
  EXPECT_EQ(o.exitCode, 2) << o.output;
  EXPECT_NE(o.output.find("--set physics=[electric,rupture]: physics [electric, rupture]: "
                          "'rupture' needs 'structural'"),
            std::string::npos)
      << o.output;

  // a slab past the scene's tet bound is refused at once (a 1e7-node slab ran 287 s until the
  // kernel killed it)
  const Result big = runEsim("validate \"" + good.string() + "\" --set mesh.slab.nodes=10000000");
  EXPECT_EQ(big.exitCode, 2) << big.output;
  EXPECT_NE(big.output.find("--set mesh.slab.nodes=10000000: mesh.slab.nodes gives a grid of 457 "
                            "x 456 x 48 nodes, 58509360 tetrahedra; at most 20000000"),
            std::string::npos)
      << big.output;
  const Result axes = runEsim("validate \"" + good.string() +
                              "\" --set \"mesh.slab.nodes_per_axis=[1000,1000,30]\"");
  EXPECT_EQ(axes.exitCode, 2) << axes.output;
  EXPECT_NE(axes.output.find("mesh.slab.nodes_per_axis gives a grid of 1000 x 1000 x 30 nodes"),
            std::string::npos)
      << axes.output;

  // what only the run's set-up checks (here the mesh) find names the file too
  const Result pad =
      runEsim("validate \"" + good.string() + "\" --set \"return_electrode.center_m=[0,0,-0.5]\"");
  EXPECT_EQ(pad.exitCode, 2) << pad.output;
  EXPECT_NE(pad.output.find("error: " + good.string() +
                            ": return_electrode: no mesh node lies on the return electrode disc"),
            std::string::npos)
      << pad.output;
  // the schema's range is the renderer's (validate said ok to a field of view run refused)
  const Result fov = runEsim("validate \"" + good.string() + "\" --set camera.fov_deg=175");
  EXPECT_EQ(fov.exitCode, 2) << fov.output;
  EXPECT_NE(fov.output.find(good.string() +
                            ": --set camera.fov_deg=175: camera.fov_deg = 175 is outside (1, 170)"),
            std::string::npos)
      << fov.output;

  const Result set = runEsim("validate \"" + good.string() + "\" --set tool.voltage_v=60");
  EXPECT_EQ(set.exitCode, 0) << set.output;
  EXPECT_NE(set.output.find("tool blade 60 V"), std::string::npos) << set.output;

  const Result missing = runEsim("validate /nonexistent/x.yaml");
  EXPECT_EQ(missing.exitCode, 2) << missing.output;
  EXPECT_NE(missing.output.find("/nonexistent/x.yaml: cannot open"), std::string::npos);

  // a folder was read as an empty scenario and said "ok"
  const Result folder = runEsim("validate \"" + (kRoot / "scenarios").string() + "\"");
  EXPECT_EQ(folder.exitCode, 2) << folder.output;
  EXPECT_NE(folder.output.find("scenarios: is a folder; expected a scenario file"),
            std::string::npos)
      << folder.output;
  // a mesh given for a scenario: its text was quoted whole (263 kB for the liver)
  const Result mesh = runEsim("validate \"" + (kRoot / "assets/liver.obj").string() + "\"");
  EXPECT_EQ(mesh.exitCode, 2) << mesh.output;
  EXPECT_NE(mesh.output.find("the scenario: expected a mapping with keys"), std::string::npos)
      << mesh.output.substr(0, 1000);
  EXPECT_NE(mesh.output.find(" characters)"), std::string::npos) << mesh.output.substr(0, 1000);
  EXPECT_LT(mesh.output.size(), 1000u);
}

// A file mesh in millimetres (a 100 mm cube read as 100 m): validate said "ok" and esim run
// refused it at set-up; validate now runs every check of the file mesh but Mesh_3 itself
TEST(ValidateCli, ASurfaceInMillimetresIsRefusedAsTheRunRefusesIt) {
  const fs::path dir = fs::temp_directory_path() / "esim_validate_cli_mm";
  fs::create_directories(dir);
  std::ofstream obj(dir / "cube_mm.obj");
  for (int v = 0; v < 8; ++v)
    obj << "v " << (v & 1) * 100 << " " << (v >> 1 & 1) * 100 << " " << (v >> 2 & 1) * 100 << "\n";
  // 12 outward triangles (1-based)
  obj << "f 1 3 2\nf 2 3 4\nf 5 6 7\nf 6 8 7\nf 1 2 5\nf 2 6 5\nf 3 7 4\nf 4 7 8\n"
         "f 1 5 3\nf 3 5 7\nf 2 4 6\nf 4 8 6\n";
  obj.close();
  std::ofstream(dir / "mm.yaml") << "mesh:\n  source: file\n  file:\n    path: cube_mm.obj\n";
  std::ofstream(dir / "m.yaml")
      << "mesh:\n  source: file\n  file:\n    path: cube_mm.obj\n    scale_to_m: 0.001\n";
  const Result mm = runEsim("validate \"" + (dir / "mm.yaml").string() + "\"");
  EXPECT_EQ(mm.exitCode, 2) << mm.output;
  EXPECT_NE(
      mm.output.find("error: " + (dir / "mm.yaml").string() + ": " +
                     (dir / "cube_mm.obj").string() + ": cell size 0.004 m would give about "),
      std::string::npos)
      << mm.output;
  EXPECT_NE(mm.output.find("for an enclosed volume of 1e+06 m^3; check the units (the surface "
                           "must be in metres)"),
            std::string::npos)
      << mm.output;
  // the same surface scaled to metres validates
  const Result m = runEsim("validate \"" + (dir / "m.yaml").string() + "\"");
  EXPECT_EQ(m.exitCode, 0) << m.output;
  fs::remove_all(dir);
}

// "-" is standard input, read once, named <stdin> (it said "-: cannot open the scenario
// file"); a bench that loads its scene per size gets the same scene each time
TEST(ValidateCli, AScenarioFromStandardInput) {
  using esim::cli_test::shell;
  const std::string exe = std::string(ESIM_EXE);
  esim::cli_test::Result r = shell("cat scenarios/paper_slab.yaml | " + exe + " validate -");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.output.rfind("ok <stdin>: 120 frames (4 s at 30 fps)", 0), 0u) << r.output;
  r = shell("printf 'time: {fps: 0}\\n' | " + exe + " validate -");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("error: <stdin>:1:13: time.fps = 0 is outside (0, 1000]"),
            std::string::npos)
      << r.output;
  r = shell("cat scenarios/slab_cut.yaml | " + exe +
            " bench cut --scenario - --sizes 27,400 --frames 2 --strategy update");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("update           405      2"), std::string::npos) << r.output;
}

TEST(ValidateCli, ReferenceIsTheCommittedPage) {
  const Result r = runEsim("validate --reference");
  EXPECT_EQ(r.exitCode, 0);
  std::ifstream in(kRoot / "docs/scenario-reference.md");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(r.output, text.str());
}

}  // namespace
