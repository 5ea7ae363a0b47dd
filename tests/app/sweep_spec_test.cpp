// Sweep files (tools/app/sweep_spec.h): expansion (grid x draws, ids, values), determinism
// (same seed, same variants; pinned draws), the path transforms, jitter around the base,
// and located errors naming the sweep file's line and the key.
#include "tools/app/sweep_spec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

#include "sim/core_error.h"

namespace esim::app {
namespace {

namespace fs = std::filesystem;

const std::string kScenarios = std::string(ESIM_SOURCE_DIR) + "/scenarios";

// a sweep file's text parsed as if it lay in scenarios/sweeps/
SweepSpec spec(const std::string& text) {
  return parseSweepSpec(text, kScenarios + "/sweeps/test.yaml");
}

// the message of the Error that f throws ("" if none)
template <class F>
std::string errorOf(F f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// a sweep file that is not UTF-8 is refused where it is (its name reached the JSON
// manifest, whose writer threw: exit 4)
TEST(SweepSpec, TextThatIsNotUtf8IsRefusedWhereItIs) {
  const std::string message =
      errorOf([] { spec("name: \"t\xff\"\nbase: ../paper_slab_506.yaml\ndraws: 1\n"); });
  EXPECT_NE(message.find("sweeps/test.yaml:1:9: not UTF-8 text (byte 0xFF)"), std::string::npos)
      << message;
}

TEST(SweepSpec, ShippedSweepsExpandAndCheck) {
  for (const auto& entry : fs::directory_iterator(kScenarios + "/sweeps")) {
    if (entry.path().extension() != ".yaml") continue;
    const SweepSpec s = loadSweepSpec(entry.path().string());
    const auto vs = expandSweep(s);
    EXPECT_EQ(vs.size(), sweepVariantCount(s)) << entry.path();
    EXPECT_GE(vs.size(), 4u) << entry.path();
  }
  const auto cut = expandSweep(loadSweepSpec(kScenarios + "/sweeps/slab_cut_8.yaml"));
  ASSERT_EQ(cut.size(), 8u);
  std::set<std::string> distinct;
  for (const auto& v : cut) distinct.insert(scenarioToYaml(v.scenario));
  EXPECT_EQ(distinct.size(), 8u) << "every variant differs";
}

TEST(SweepSpec, GridTimesDrawsGridMajorWithIds) {
  const SweepSpec s = spec(
      "base: ../paper_slab_506.yaml\n"
      "grid:\n"
      "  tool.voltage_v: [60, 80, 100]\n"
      "  look.colormap: [inferno, viridis]\n"
      "draws: 2\n"
      "random:\n"
      "  camera.fov_deg: {uniform: [30, 50]}\n");
  EXPECT_EQ(sweepVariantCount(s), 12u);
  const auto vs = expandSweep(s, false);
  ASSERT_EQ(vs.size(), 12u);
  EXPECT_EQ(vs[0].id, "v0000");
  EXPECT_EQ(vs[11].id, "v0011");
  // the first key slowest, the draws innermost
  EXPECT_EQ(vs[0].values["tool.voltage_v"], 60);
  EXPECT_EQ(vs[0].values["look.colormap"], "inferno");
  EXPECT_EQ(vs[1].values["look.colormap"], "inferno");
  EXPECT_EQ(vs[2].values["look.colormap"], "viridis");
  EXPECT_EQ(vs[4].values["tool.voltage_v"], 80);
  EXPECT_EQ(vs[11].values["tool.voltage_v"], 100);
  for (const auto& v : vs) {
    EXPECT_EQ(v.scenario.tool.voltageV, v.values["tool.voltage_v"].get<double>());
    EXPECT_EQ(v.scenario.look.colormap, v.values["look.colormap"].get<std::string>());
    const double fov = v.values["camera.fov_deg"].get<double>();
    EXPECT_EQ(v.scenario.camera.fovDeg, fov);
    EXPECT_GE(fov, 30.0);
    EXPECT_LE(fov, 50.0);
  }
  EXPECT_EQ(variantId(7, 12345), "v00007");
}

TEST(SweepSpec, SameSeedSameVariantsOtherSeedOthers) {
  const std::string text =
      "base: ../paper_slab_506.yaml\n"
      "seed: 5\n"
      "draws: 3\n"
      "random:\n"
      "  tool.voltage_v: {uniform: [50, 90]}\n"
      "  solvers.electric.threads: {integer: [1, 4]}\n"
      "  look.style: {choice: [temperature, tissue]}\n"
      "  camera.eye_m: {jitter: [0.01, 0.01, 0.01]}\n";
  const auto a = expandSweep(spec(text), false);
  const auto b = expandSweep(spec(text), false);
  ASSERT_EQ(a.size(), 3u);
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].values, b[i].values);
    EXPECT_EQ(scenarioToYaml(a[i].scenario), scenarioToYaml(b[i].scenario));
  }
  const auto c = expandSweep(
      spec(text.substr(0, text.find("seed")) + "seed: 6" + text.substr(text.find("\ndraws"))),
      false);
  EXPECT_NE(a[0].values, c[0].values);
  // drawn numbers keep 6 significant digits
  const double v = a[0].values["tool.voltage_v"];
  EXPECT_EQ(v, roundDrawn(v));
  EXPECT_NE(a[0].values, a[1].values) << "each variant draws anew";
}

// the draws are ours, from mt19937_64's raw output (which the standard pins): the same
// numbers with every standard library
TEST(SweepSpec, DrawsArePortable) {
  std::mt19937_64 ref;  // default seed 5489: the standard's 10000th output
  ref.discard(9999);
  EXPECT_EQ(ref(), 9981545732273789042ULL);
  EXPECT_EQ(splitmix64(0), 0xe220a8397b1dcdafULL);  // the reference splitmix64's first output
  std::mt19937_64 e = variantEngine(0, 0);
  std::mt19937_64 same(splitmix64(splitmix64(0)));
  EXPECT_EQ(e(), same());
  std::mt19937_64 u(1);
  const double x = drawUnit(u);
  std::mt19937_64 raw(1);
  EXPECT_EQ(x, static_cast<double>(raw() >> 11) / 9007199254740992.0);
  std::mt19937_64 g(3);
  int counts[3] = {0, 0, 0};
  for (int i = 0; i < 3000; ++i) ++counts[drawBelow(g, 3)];
  for (int c : counts) EXPECT_NEAR(c, 1000, 120);
  EXPECT_EQ(roundDrawn(123.456789), 123.457);
  EXPECT_EQ(roundDrawn(0.000123456789), 0.000123457);
}

TEST(SweepSpec, JitterIsAroundTheBaseValue) {
  const auto vs = expandSweep(spec("base: ../paper_slab_506.yaml\n"
                                   "set: {camera.eye_m: [0, -0.1, 0.1]}\n"
                                   "draws: 20\n"
                                   "random:\n"
                                   "  camera.eye_m: {jitter: [0.002, 0, 0.004]}\n"
                                   "  tool.voltage_v: {jitter: 5}\n"),
                              false);
  for (const auto& v : vs) {
    const Vec3& e = v.scenario.camera.eyeM;
    EXPECT_LE(std::fabs(e.x() - 0.0), 0.002 + 1e-12);
    EXPECT_EQ(e.y(), -0.1);
    EXPECT_LE(std::fabs(e.z() - 0.1), 0.004 + 1e-12);
    EXPECT_LE(std::fabs(v.scenario.tool.voltageV - 72.0), 5.0);
  }
}

TEST(SweepSpec, PathTransformsMoveTurnAndSpeedTheToolAndThePlannedCut) {
  const auto base = loadScenario(kScenarios + "/slab_cut.yaml");
  const auto vs = expandSweep(spec("base: ../slab_cut.yaml\n"
                                   "set:\n"
                                   "  path.offset_m: [0, 0.002, 0]\n"
                                   "  path.angle_deg: 90\n"
                                   "  path.speed: 2\n"),
                              false);
  ASSERT_EQ(vs.size(), 1u);
  const Scenario& s = vs[0].scenario;
  ASSERT_EQ(s.tool.path.size(), base.tool.path.size());
  // slab_cut: (-0.02, 0) -> (0.02, 0) over 4 s; turned 90 degrees about (0, 0), moved 2 mm
  // in y, twice as fast
  EXPECT_NEAR(s.tool.path[0].positionM.x(), 0.0, 1e-9);
  EXPECT_NEAR(s.tool.path[0].positionM.y(), -0.02 + 0.002, 1e-9);
  EXPECT_NEAR(s.tool.path[1].positionM.y(), 0.02 + 0.002, 1e-9);
  EXPECT_NEAR(s.tool.path[1].positionM.z(), base.tool.path[1].positionM.z(), 1e-12);
  EXPECT_DOUBLE_EQ(s.tool.path[1].timeS, base.tool.path[1].timeS / 2);
  EXPECT_DOUBLE_EQ(s.tool.path[0].orientationDeg.z(), 90.0);
  // the graded zone follows
  EXPECT_NEAR(s.mesh.slab.grading.fromM.x(), 0.0, 1e-9);
  EXPECT_NEAR(s.mesh.slab.grading.fromM.y(), -0.025 + 0.002, 1e-9);
  EXPECT_TRUE(vs[0].values.empty()) << "set: values are the same for all, not recorded";
}

TEST(SweepSpec, RunOptionsAndName) {
  const SweepSpec s = spec("name: mine\nbase: ../paper_slab_506.yaml\nrun_options: [--labels]\n");
  EXPECT_EQ(s.name, "mine");
  EXPECT_EQ(s.runOptions, std::vector<std::string>{"--labels"});
  EXPECT_EQ(spec("base: ../paper_slab_506.yaml\n").name, "test");
  EXPECT_EQ(sweepVariantCount(spec("base: ../paper_slab_506.yaml\n")), 1u);
}

TEST(SweepSpec, ErrorsNameTheSweepFileLineAndKey) {
  const std::string file = kScenarios + "/sweeps/test.yaml";
  struct Case {
    std::string text, expect;
  };
  const std::vector<Case> cases{
      {"base: ../paper_slab_506.yaml\ngird: {tool.voltage_v: [1]}\n",
       file + ":2:1: gird: unknown key; did you mean 'grid'?"},
      // a scenario where the sweep file was expected: said so, not "mesh: unknown key"
      {"name: cut\nmesh:\n  source: slab\n",
       file + ":2:1: mesh: a scenario key at the top of a sweep file: this looks like a "
              "scenario, not a sweep file"},
      // yaml-cpp decodes "\N" to a byte that is not UTF-8 (it reached the JSON manifest)
      {"name: \"cut\\N\"\nbase: ../paper_slab_506.yaml\n",
       file + ":1:7: name: the text is not UTF-8 once its escapes are decoded (byte 0x85 at "
              "byte 4"},
      {"base: ../paper_slab_506.yaml\ngrid:\n  tool.voltag_v: [60]\n",
       file + ":3:3: grid.tool.voltag_v: unknown scenario key; did you mean 'tool.voltage_v'?"},
      {"base: ../paper_slab_506.yaml\ngrid:\n  tool.voltage_v: [60, 20000]\n",
       file + ":3:24: tool.voltage_v: variant v0001 {\"tool.voltage_v\":20000}: "},
      {"base: ../paper_slab_506.yaml\nrandom:\n  tool.voltage_v: {uniform: [20000, 30000]}\n",
       file + ":3:29: tool.voltage_v: variant v0000"},
      {"base: ../paper_slab_506.yaml\nrandom:\n  tool.voltage_v: {uniform: [90, 50]}\n",
       file + ":3:29: random.tool.voltage_v.uniform: lo 90 is above hi 50"},
      // a draw over the whole range of doubles was inf: on a path key, yaml-cpp's "bad
      // conversion" (exit 4)
      {"base: ../paper_slab_506.yaml\nrandom: {path.angle_deg: {uniform: [-1e308, 1e308]}}\n",
       file + ":2:36: random.path.angle_deg.uniform: hi - lo must be a finite number, got "
              "-1e+308 to 1e+308"},
      {"base: ../paper_slab_506.yaml\nrandom:\n  tool.voltage_v: {gauss: [1, 2]}\n",
       file + ":3:20: random.tool.voltage_v: unknown distribution 'gauss'"},
      {"base: ../paper_slab_506.yaml\nset: {path.speed: 0}\n",
       file + ":2:19: set.path.speed = 0 is outside (0, 100]"},
      {"base: ../paper_slab_506.yaml\ndraws: 3\n",
       file + ":2:8: draws: 3 draws without random: keys would make identical variants"},
      {"base: ../paper_slab_506.yaml\nrun_options: [-o, x]\n",
       file + ":2:15: run_options: -o is the sweep's to give"},
      {"base: ../nowhere.yaml\n", file + ":1:7: base: "},
      {"grid: {tool.voltage_v: [1]}\n", file + ": base: missing"},
      {"base: ../paper_slab_506.yaml\nset: {tool.voltage_v: 60}\ngrid: {tool.voltage_v: [1]}\n",
       file + ":3:8: tool.voltage_v: also given at " + file + ":2:7"},
      {"base: ../paper_slab_506.yaml\ngrid: {tool.path.offset: [1]}\n",
       file + ":2:8: grid.tool.path.offset: unknown scenario key"},
      // a repeated value ran the same variants twice
      {"base: ../paper_slab_506.yaml\ngrid: {tool.voltage_v: [60, 80, 6e1]}\n",
       file + ":2:33: grid.tool.voltage_v[2] = 6e1 repeats grid.tool.voltage_v[0]; give each "
              "value once"},
      {"base: ../paper_slab_506.yaml\ngrid: {look.style: [tissue, tissue]}\n",
       file + ":2:29: grid.look.style[1] = tissue repeats grid.look.style[0]"},
      {"base: ../paper_slab_506.yaml\nrandom: {look.style: {jitter: 1}}\n",
       file + ":2:10: random.look.style: jitter needs a number or a vector"},
      // the file's text is quoted where it is not short printable text (found by fuzz_sweep's
      // check that a rejection's message is printable: a CR, a tab, a long name were echoed)
      {"base: ../paper_slab_506.yaml\n\"gi\\rd\": {tool.voltage_v: [1]}\n",
       file + ":2:1: 'gi\\x0Dd': unknown key; did you mean 'grid'?"},
      {"base: ../paper_slab_506.yaml\ngrid: {\"tool.volt\\tage_v\": [1]}\n",
       file + ":2:8: 'grid.tool.volt\\x09age_v': unknown scenario key"},
      {"base: ../paper_slab_506.yaml\nrandom:\n  tool.voltage_v: {" + std::string(80, 'g') +
           ": [1, 2]}\n",
       file + ":3:20: random.tool.voltage_v: unknown distribution '" + std::string(60, 'g') +
           " ...' (80 characters)"},
      {"base: ../paper_slab_506.yaml\nset: {tool.voltage_v: " + std::string(100, '1') + "}\n",
       file + ":2:23: tool.voltage_v: variant v0000 (no values): "},
  };
  for (const auto& c : cases) {
    const std::string msg = errorOf([&] { expandSweep(spec(c.text), false); });
    EXPECT_EQ(msg.rfind(c.expect, 0), 0u)
        << "sweep:\n"
        << c.text << "\ngave: " << msg << "\nexpected it to start with: " << c.expect;
  }
  // the scenario's own message follows, with the value at fault
  const std::string range = errorOf([&] {
    expandSweep(spec("base: ../paper_slab_506.yaml\ngrid:\n  tool.voltage_v: [60, 20000]\n"),
                false);
  });
  EXPECT_NE(range.find("tool.voltage_v = 20000 is outside [0, 10000]"), std::string::npos) << range;
}

}  // namespace
}  // namespace esim::app
