// `esim run` end to end: every shipped scenario runs (short), outputs are complete, the
// fields hold only the phases the scene has, idle stages say "skipped", and bad input
// exits 2 with nothing written.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "render/image_hash.h"
#include "render/image_png.h"
#include "render/labels.h"
#include "sim/io/vtu.h"
#include "tests/tools/cli_test_util.h"

namespace {

namespace fs = std::filesystem;
using esim::cli_test::onOneCpu;
using esim::cli_test::readFile;
using esim::cli_test::Result;
using esim::cli_test::shell;

Result esimRun(const std::string& args) { return shell(std::string(ESIM_EXE) + " run " + args); }

fs::path tempOut(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("esim_run_test_" + name);
  fs::remove_all(p);
  return p;
}

const char* kSmall = " --set look.width=160 --set look.height=90 -q";

// the frames ffprobe decodes from a video (-1 when it cannot read it)
int videoFrames(const fs::path& video) {
  const Result r = shell(
      "ffprobe -v error -count_frames -select_streams v:0 -show_entries "
      "stream=nb_read_frames -of csv=p=0 " +
      video.string());
  return r.exitCode == 0 && !r.output.empty() ? std::atoi(r.output.c_str()) : -1;
}

// a run that failed after `frames` frames: never renamed as complete, its DIR.partial with
// timing.json saying so, and a playable video of those frames; DIR.partial removed after
void expectFailedWithFramesKept(const fs::path& out, int frames, const std::string& output) {
  const fs::path partial = out.string() + ".partial";
  EXPECT_FALSE(fs::exists(out));
  ASSERT_TRUE(fs::exists(partial / "timing.json")) << output;
  const auto timing = nlohmann::json::parse(readFile(partial / "timing.json"));
  EXPECT_FALSE(timing["complete"].get<bool>());
  EXPECT_EQ(timing["frames"].get<int>(), frames);
  EXPECT_EQ(videoFrames(partial / "video.mp4"), frames);
  fs::remove_all(partial);
}

TEST(RunCli, EveryShippedScenarioRuns) {
  for (const auto& entry : fs::directory_iterator(fs::path(ESIM_SOURCE_DIR) / "scenarios")) {
    if (entry.path().extension() != ".yaml") continue;
    const std::string name = entry.path().stem().string();
    const fs::path out = tempOut(name);
    const Result r = esimRun("scenarios/" + name + ".yaml --frames 3 --set output.video=false" +
                             std::string(kSmall) + " -o " + out.string());
    ASSERT_EQ(r.exitCode, 0) << name << ":\n" << r.output;
    for (const char* f :
         {"timing.csv", "timing.json", "trace.json", "scenario.yaml", "hashes.json", "summary.txt"})
      EXPECT_TRUE(fs::exists(out / f)) << name << " lacks " << f;
    const auto timing = nlohmann::json::parse(readFile(out / "timing.json"));
    EXPECT_EQ(timing["frames"], 3) << name;
    EXPECT_FALSE(fs::exists(out.string() + ".partial"));
    fs::remove_all(out);
  }
}

TEST(RunCli, VideoAndSummary) {
  const fs::path out = tempOut("video");
  const Result r = esimRun("scenarios/paper_slab.yaml --frames 15" + std::string(kSmall) + " -o " +
                           out.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  ASSERT_TRUE(fs::exists(out / "video.mp4"));
  EXPECT_GT(fs::file_size(out / "video.mp4"), 1000u);
  // what was written while the run went is gone: the fragmented video, the rows streamed
  for (const char* name : {"video.mp4.partial", "video.mp4.regular.partial", "timing.csv.partial"})
    EXPECT_FALSE(fs::exists(out / name)) << name;
  EXPECT_NE(r.output.find("frames      15 of 15"), std::string::npos) << r.output;
  // the solver the default (auto) took for the paper's 1026 nodes, in the summary and report
  EXPECT_NE(r.output.find("electric    dense-inverse (solvers.electric.strategy auto)"),
            std::string::npos)
      << r.output;
  const auto timing = nlohmann::json::parse(readFile(out / "timing.json"));
  EXPECT_EQ(timing["electric_solver"], "dense-inverse");
  // esim turns transparent huge pages off for itself (tools/app/memory_room.h)
  EXPECT_EQ(timing["machine"]["transparent_huge_pages"], "disabled (PR_SET_THP_DISABLE)");
  EXPECT_NE(r.output.find("energy"), std::string::npos);
  EXPECT_NE(r.output.find("over 33.3 ms"), std::string::npos);
  fs::remove_all(out);
}

// a run whose tissue goes far past what the model describes says so (summary and
// timing.json); a normal run has no warning
TEST(RunCli, ImplausibleTemperaturesAreFlagged) {
  const fs::path hot = tempOut("hot"), normal = tempOut("normal");
  const Result h = esimRun(
      "scenarios/paper_slab.yaml --frames 10 --no-video --set "
      "tool.voltage_v=10000 --set output.hashes=false -q -o " +
      hot.string());
  ASSERT_EQ(h.exitCode, 0) << h.output;
  EXPECT_NE(h.output.find("WARNING       the tissue reached"), std::string::npos) << h.output;
  const auto th = nlohmann::json::parse(readFile(hot / "timing.json"));
  ASSERT_EQ(th["warnings"].size(), 1u);
  EXPECT_NE(th["warnings"][0].get<std::string>().find("chars and ablates"), std::string::npos);
  // the remedies: a lower voltage, and only what the scene does not do yet
  EXPECT_NE(h.output.find("does not include; lower tool.voltage_v, or enable "
                          "effects.temperature_dependent_conductivity (drying cuts the current) "
                          "or the structural and rupture phases (boiling tissue is removed)\n"),
            std::string::npos)
      << h.output;
  for (const auto& [sets, remedies] : std::vector<std::pair<std::string, std::string>>{
           {"",
            "; lower tool.voltage_v, or enable effects.temperature_dependent_conductivity "
            "(drying cuts the current)\n"},
           {" --set effects.temperature_dependent_conductivity=true",
            "; lower tool.voltage_v\n"}}) {
    fs::remove_all(hot);
    const Result c = esimRun(
        "scenarios/paper_slab.yaml --frames 10 --no-video --set tool.voltage_v=10000 --set "
        "physics=[electric,thermal,boiling,structural,rupture] --set output.hashes=false -q -o " +
        hot.string() + sets);
    ASSERT_EQ(c.exitCode, 0) << c.output;
    EXPECT_NE(c.output.find("chars and ablates, which the model does not include" + remedies),
              std::string::npos)
        << sets << "\n"
        << c.output;
  }
  const Result n = esimRun(
      "scenarios/paper_slab.yaml --frames 10 --no-video --set "
      "output.hashes=false -q -o " +
      normal.string());
  ASSERT_EQ(n.exitCode, 0) << n.output;
  EXPECT_EQ(n.output.find("WARNING"), std::string::npos);
  EXPECT_TRUE(nlohmann::json::parse(readFile(normal / "timing.json"))["warnings"].empty());
  fs::remove_all(hot);
  fs::remove_all(normal);
}

TEST(RunCli, FieldsHoldOnlyThePhasesOfTheScene) {
  const fs::path full = tempOut("fields_full");
  Result r = esimRun("scenarios/paper_slab.yaml --frames 2 --fields 1 --no-video" +
                     std::string(kSmall) + " -o " + full.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const esim::VtuData d = esim::readVtu((full / "fields" / "frame_00001.vtu").string());
  for (const char* f : {"potential", "temperature", "bc"})
    EXPECT_NE(d.findPointField(f), nullptr) << f;
  for (const char* f : {"conductivity", "joule_power", "vapor_fraction", "alive"})
    EXPECT_NE(d.findCellField(f), nullptr) << f;
  EXPECT_EQ(d.findPointField("displacement"), nullptr);  // no structural phase
  EXPECT_EQ(d.findCellField("expansion"), nullptr);
  EXPECT_EQ(d.findCellField("von_mises"), nullptr);
  // bc: some tool contacts (1) and return-electrode nodes (2)
  int tool = 0, ground = 0;
  for (double v : d.findPointField("bc")->values) {
    tool += v == 1;
    ground += v == 2;
  }
  EXPECT_GT(tool, 0);
  EXPECT_GT(ground, 0);
  // potential between 0 and 72 V
  for (double v : d.findPointField("potential")->values) {
    EXPECT_GE(v, -1e-9);
    EXPECT_LE(v, 72 + 1e-9);
  }
  fs::remove_all(full);

  const fs::path eo = tempOut("fields_electric");
  r = esimRun("scenarios/electric_only.yaml --frames 1 --fields 1 --no-video" +
              std::string(kSmall) + " -o " + eo.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const esim::VtuData e = esim::readVtu((eo / "fields" / "frame_00000.vtu").string());
  EXPECT_NE(e.findPointField("potential"), nullptr);
  EXPECT_EQ(e.findPointField("temperature"), nullptr);  // thermal not listed: not built
  EXPECT_EQ(e.findCellField("vapor_fraction"), nullptr);
  // timing.csv has no heat column at all
  const std::string csv = readFile(eo / "timing.csv");
  EXPECT_EQ(csv.find("heat_ms"), std::string::npos) << csv.substr(0, 200);
  EXPECT_NE(csv.find("solve_potential_ms"), std::string::npos);
  fs::remove_all(eo);
}

// on a frame where tets break and a synchronous rebuild swaps in a new model, the VTU's
// von_mises is the frame's stress on the tets still alive (it was all zeros while
// timing.csv said 62 kPa): positive, at most the critical stress (everything above broke
// and is no longer written), and near it next to the cut
TEST(RunCli, FieldsOfARebuildFrameHoldItsStress) {
  const double criticalPa = 24500;  // material.critical_stress_pa, set below
  const fs::path out = tempOut("fields_rebuild");
  const Result r = esimRun(
      "scenarios/slab_cut.yaml --set solvers.rebuild.mode=synchronous --frames 5 --fields 1 "
      "--set material.critical_stress_pa=24500 --no-video -q -o " +
      out.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  // the frames' rows of timing.csv: max_von_mises_pa and removed_tets are the last columns
  std::istringstream csv(readFile(out / "timing.csv"));
  std::string line;
  std::getline(csv, line);
  ASSERT_NE(line.find("max_von_mises_pa,removed_tets"), std::string::npos) << line;
  int checked = 0;
  while (std::getline(csv, line)) {
    const int frame = std::atoi(line.c_str());
    const size_t last = line.rfind(','), before = line.rfind(',', last - 1);
    const double maxVm = std::atof(line.c_str() + before + 1);
    const int removed = std::atoi(line.c_str() + last + 1);
    if (removed == 0) continue;
    EXPECT_GT(maxVm, criticalPa);  // what broke
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d.vtu", frame);
    const esim::VtuData d = esim::readVtu((out / "fields" / name).string());
    const esim::VtuField* vm = d.findCellField("von_mises");
    ASSERT_NE(vm, nullptr);
    const double vtuMax = *std::max_element(vm->values.begin(), vm->values.end());
    EXPECT_LE(vtuMax, criticalPa) << name;
    EXPECT_GT(vtuMax, 0.5 * criticalPa) << name;
    // the displacement: 3 per point, 0 on the clamped base (z = 0), the top pushed up where
    // the water boils (~1 mm where the expansion reaches its cap of 3 under the blade; the
    // slab is 10 mm thick), finite everywhere
    const esim::VtuField* u = d.findPointField("displacement");
    ASSERT_NE(u, nullptr);
    ASSERT_EQ(u->components, 3);
    ASSERT_EQ(u->values.size(), 3 * d.points.size());
    double maxUp = 0;
    for (size_t p = 0; p < d.points.size(); ++p) {
      for (int a = 0; a < 3; ++a) ASSERT_TRUE(std::isfinite(u->values[3 * p + a]));
      if (d.points[p].z() < 1e-12) {
        for (int a = 0; a < 3; ++a) EXPECT_EQ(u->values[3 * p + a], 0.0) << name << " point " << p;
      }
      maxUp = std::max(maxUp, u->values[3 * p + 2]);
    }
    EXPECT_GT(maxUp, 1e-6) << name;
    EXPECT_LT(maxUp, 5e-3) << name;
    // the expansion: per cell, where the water boils over the 3 % of liquid expansion
    const esim::VtuField* ev = d.findCellField("expansion");
    ASSERT_NE(ev, nullptr);
    ASSERT_EQ(ev->values.size(), d.tets.size());
    EXPECT_GT(*std::max_element(ev->values.begin(), ev->values.end()), 0.0301) << name;
    EXPECT_GE(*std::min_element(ev->values.begin(), ev->values.end()), 0.0) << name;
    ++checked;
  }
  EXPECT_GT(checked, 0) << "no frame removed tets: the scene no longer cuts in 5 frames";
  fs::remove_all(out);
}

TEST(RunCli, IdleStagesAreSkipped) {
  // coagulation_spot: the generator is off before 0.5 s
  const fs::path out = tempOut("skipped");
  const Result r = esimRun("scenarios/coagulation_spot.yaml --frames 3 --no-video" +
                           std::string(kSmall) + " -o " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const std::string csv = readFile(out / "timing.csv");
  std::istringstream lines(csv);
  std::string header, row;
  std::getline(lines, header);
  std::getline(lines, row);
  EXPECT_NE(header.find("find_contacts_ms,solve_potential_ms,heat_ms"), std::string::npos)
      << header;
  EXPECT_NE(row.find("skipped,skipped,skipped"), std::string::npos) << row;
  const auto timing = nlohmann::json::parse(readFile(out / "timing.json"));
  EXPECT_EQ(timing["stages"]["solve_potential"]["frames_skipped"], 3);
  fs::remove_all(out);
}

TEST(RunCli, BadInputExitsTwoAndWritesNothing) {
  const fs::path out = tempOut("bad");
  const fs::path bad_yaml = fs::temp_directory_path() / "esim_run_test_bad.yaml";
  std::ofstream(bad_yaml) << "name: x\ntool: {voltage_v: [1, 2\n";
  struct Case {
    std::string args, expect;
  } cases[] = {
      {bad_yaml.string(), "esim_run_test_bad.yaml:"},
      {"scenarios/paper_slab.yaml --set tool.voltage_v=abc", "tool.voltage_v"},
      {"scenarios/paper_slab.yaml --set physics=[electric,magic]", "magic"},
      {"scenarios/nope.yaml", "nope.yaml"},
      // found only once the mesh is built: named by the scenario file still
      {"scenarios/paper_slab.yaml --set return_electrode.center_m=[0,0,-0.5]",
       "scenarios/paper_slab.yaml: return_electrode: no mesh node lies on the return electrode "
       "disc"},
      {"scenarios/paper_slab.yaml --set solvers.electric.strategy=dense-inverse "
       "--set mesh.slab.nodes=60000 --set solvers.electric.dense_memory_limit_mb=100",
       "capacitance"},
      {"scenarios/slab_cut.yaml --set solvers.structural.method=coarse "
       "--set solvers.structural.coarse_spacing_m=1e-5",
       "scenarios/slab_cut.yaml: structural: a coarse grid (solvers.structural.coarse_spacing_m) "
       "of spacing 1e-05 m"},
  };
  for (const auto& c : cases) {
    const Result r = esimRun(c.args + " -q -o " + out.string());
    EXPECT_EQ(r.exitCode, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << "\n" << r.output;
    EXPECT_FALSE(fs::exists(out)) << c.args;
    EXPECT_FALSE(fs::exists(out.string() + ".partial")) << c.args;
  }
  fs::remove(bad_yaml);
}

// ---- outputs that never destroy; errors of each kind with their exit codes ----

TEST(RunCli, OutputNeverReplacesWhatTheRunDidNotCreate) {
  const fs::path root = tempOut("user_files");
  fs::create_directories(root / "mine");
  std::ofstream(root / "mine" / "thesis.tex") << "user data\n";
  std::ofstream(root / "notes.txt") << "user data\n";
  const std::string args = "scenarios/paper_slab.yaml --frames 2 --no-video" + std::string(kSmall);
  for (const std::string target : {"mine", "notes.txt"}) {
    const Result r = esimRun(args + " --overwrite -o " + (root / target).string());
    EXPECT_EQ(r.exitCode, 2) << r.output;
  }
  EXPECT_EQ(readFile(root / "mine" / "thesis.tex"), "user data\n");
  EXPECT_EQ(readFile(root / "notes.txt"), "user data\n");
  EXPECT_FALSE(fs::exists(root / "mine.partial"));
  // the working folder (the source tree here): refused, nothing touched
  const Result dot = esimRun(args + " --overwrite -o .");
  EXPECT_EQ(dot.exitCode, 2) << dot.output;
  EXPECT_NE(dot.output.find("not an ESim run"), std::string::npos) << dot.output;
  EXPECT_TRUE(fs::exists(fs::path(ESIM_SOURCE_DIR) / "CMakeLists.txt"));
  // an earlier run: only with --overwrite
  const fs::path run = root / "run";
  ASSERT_EQ(esimRun(args + " -o " + run.string()).exitCode, 0);
  const std::string first = readFile(run / "summary.txt");
  const Result again = esimRun(args + " -o " + run.string());
  EXPECT_EQ(again.exitCode, 2) << again.output;
  EXPECT_NE(again.output.find("--overwrite"), std::string::npos) << again.output;
  EXPECT_EQ(readFile(run / "summary.txt"), first);
  EXPECT_EQ(esimRun(args + " --overwrite -o " + run.string()).exitCode, 0);
  fs::remove_all(root);
}

// a run into tempOut(name) (its earlier .partial removed first) that must fail: exit 1
Result failingRun(const std::string& name, const std::string& args) {
  const fs::path out = tempOut(name);
  fs::remove_all(out.string() + ".partial");
  const Result r = esimRun(args + " -o " + out.string());
  EXPECT_EQ(r.exitCode, 1) << r.output;
  return r;
}

// two runs started together into one folder: one writes it, the other is refused (exit 2),
// whichever comes second; the folder is the first's, its video whole (both used to write
// the same DIR.partial/: the run that completed committed a video without its moov atom,
// the other failed at its end)
TEST(RunCli, TwoRunsIntoOneFolderAtOnceOneIsRefused) {
  const fs::path out = tempOut("twice");
  fs::remove_all(out.string() + ".partial");
  const std::string run = std::string(ESIM_EXE) +
                          " run scenarios/paper_slab.yaml --frames 20 -q --set look.width=160 "
                          "--set look.height=90 -o " +
                          out.string();
  const Result r =
      shell("(" + run + "; echo \"exit=$?\") & (" + run + "; echo \"exit=$?\") & wait");
  const auto count = [&](const std::string& part) {
    int n = 0;
    for (size_t at = r.output.find(part); at != std::string::npos; at = r.output.find(part, at + 1))
      ++n;
    return n;
  };
  EXPECT_EQ(count("exit=0"), 1) << r.output;
  EXPECT_EQ(count("exit=2"), 1) << r.output;
  EXPECT_EQ(count("another esim run is writing this folder") +
                count("holds an earlier ESim run; add --overwrite"),
            1)
      << r.output;
  EXPECT_FALSE(fs::exists(out.string() + ".partial"));
  EXPECT_EQ(videoFrames(out / "video.mp4"), 20);
  fs::remove_all(out);
}

TEST(RunCli, AFailedRunExitsOneAndKeepsItsFramesMarkedPartial) {
  const fs::path out = tempOut("failed");
  // pcg capped at 2 iterations cannot reach 1e-12: the first solve fails
  const Result r = failingRun(
      "failed",
      "scenarios/paper_slab.yaml --frames 4 --no-video --set solvers.electric.strategy=pcg "
      "--set solvers.electric.max_iterations=2 --set solvers.electric.tolerance=1e-12" +
          std::string(kSmall));
  EXPECT_NE(r.output.find("pcg did not converge"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("solvers.electric.max_iterations"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out)) << "a failed run is never renamed as complete";
  const fs::path partial = out.string() + ".partial";
  ASSERT_TRUE(fs::exists(partial / "timing.json"));
  const auto timing = nlohmann::json::parse(readFile(partial / "timing.json"));
  EXPECT_FALSE(timing["complete"].get<bool>());
  EXPECT_NE(timing["failure"].get<std::string>().find("frame 0"), std::string::npos);
  EXPECT_NE(readFile(partial / "summary.txt").find("FAILED: partial"), std::string::npos);
  fs::remove_all(partial);
}

// an environment variable that is not UTF-8 (LP_NUM_THREADS, recorded in timing.json) is
// written as U+FFFD: the JSON writer threw after the last frame (exit 4, only DIR.partial/)
TEST(RunCli, BytesNotUtf8InTheEnvironmentDoNotEndTheRun) {
  const fs::path out = tempOut("env_not_utf8");
  const Result r =
      shell("LP_NUM_THREADS=\"$(printf '\\377')\" " + std::string(ESIM_EXE) +
            " run scenarios/paper_slab.yaml --frames 1 --no-video -q -o " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const auto timing = nlohmann::json::parse(readFile(out / "timing.json"));
  EXPECT_EQ(timing["machine"]["LP_NUM_THREADS"], "\xef\xbf\xbd");  // U+FFFD
  fs::remove_all(out);
}

// slab_cut at 1013 nodes with `set` fails in frame 0 with an error that starts with `message`
// and names its frame once: not "frame 0: STAGE, frame 0: ..."
Result failsInFrameZeroSayingSoOnce(const std::string& name, const std::string& set,
                                    const std::string& message, const std::string& stage) {
  const Result r = failingRun(name,
                              "scenarios/slab_cut.yaml --frames 3 --no-video --set "
                              "mesh.slab.nodes=1013 --set " +
                                  set + " -q");
  EXPECT_NE(r.output.find("esim: error: " + message), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("frame 0: " + stage), std::string::npos) << r.output;
  return r;
}

TEST(RunCli, AShortCircuitSaysItsFrameOnce) {
  const Result r = failsInFrameZeroSayingSoOnce(
      "short_circuit", "tool.contact_distance_m=0.01",
      "find_contacts, frame 0: short circuit: the tool touches node ", "find_contacts");
  EXPECT_NE(r.output.find("tool.contact_distance_m = 0.01 m"), std::string::npos) << r.output;
  fs::remove_all(tempOut("short_circuit").string() + ".partial");
}

TEST(RunCli, ARuptureThatEndsTheRunSaysSoOnce) {
  failsInFrameZeroSayingSoOnce("rupture_all", "material.critical_stress_pa=1e-9",
                               "rupture, frame 0: every element of the tissue has been removed\n",
                               "rupture");
  // the summary counts the cut that ended the run, as the mesh it reports shows it (it
  // said "0 tets removed in 0 frames (0 of 5832 alive)", peak von Mises 0)
  const std::string partial = tempOut("rupture_all").string() + ".partial";
  const std::string summary = readFile(partial + "/summary.txt");
  const std::size_t at = summary.find("  structural    peak von Mises ");
  ASSERT_NE(at, std::string::npos) << summary;
  double peakPa = 0;
  int removed = 0, frames = 0, debris = -1, alive = -1, total = 0;
  ASSERT_EQ(std::sscanf(summary.c_str() + at,
                        "  structural    peak von Mises %lf Pa; %d tets removed in %d frames, "
                        "%d of them cut loose as debris (%d of %d alive)",
                        &peakPa, &removed, &frames, &debris, &alive, &total),
            6)
      << summary;
  EXPECT_EQ(debris, 0) << "every tet broke: nothing was left to cut loose";
  EXPECT_GT(peakPa, 1e-9) << "the stress that broke every tet";
  EXPECT_EQ(frames, 1);
  EXPECT_EQ(alive, 0);
  EXPECT_EQ(removed, total);
  EXPECT_GT(total, 0);
  fs::remove_all(partial);
}

TEST(RunCli, AnInterruptedRunStaysPartialWithAPlayableVideo) {
  const fs::path out = tempOut("interrupted");
  const fs::path partial = out.string() + ".partial";
  fs::remove_all(partial);
  // a long run, SIGTERM after 3 s: it stops after the current frame
  const std::string cmd = std::string("cd ") + ESIM_SOURCE_DIR + " && (" + ESIM_EXE +
                          " run scenarios/paper_slab.yaml --frames 100000" + kSmall + " -o " +
                          out.string() + " >/dev/null 2>&1 & pid=$!; sleep 3; kill -TERM $pid; " +
                          "wait $pid; echo $?)";
  FILE* pipe = popen(cmd.c_str(), "r");
  char buf[64] = {0};
  ASSERT_NE(fgets(buf, sizeof buf, pipe), nullptr);
  pclose(pipe);
  EXPECT_EQ(std::atoi(buf), 1) << "exit code of an interrupted run";
  EXPECT_FALSE(fs::exists(out)) << "an interrupted run is never renamed as complete";
  ASSERT_TRUE(fs::exists(partial / "timing.json"));
  const auto timing = nlohmann::json::parse(readFile(partial / "timing.json"));
  EXPECT_TRUE(timing["interrupted"].get<bool>());
  EXPECT_FALSE(timing["complete"].get<bool>());
  const int frames = timing["frames"].get<int>();
  // the video holds the frames done and is playable
  EXPECT_EQ(videoFrames(partial / "video.mp4"), frames);
  EXPECT_GT(frames, 0);
  fs::remove_all(partial);
}

// a stop inside a frame of minutes (a dense explicit frame: ~1e5 sub-steps) is honoured at
// the next sub-step, not after the frame; the frames before it are kept and playable
TEST(RunCli, AStopInsideALongFrameIsHonouredWithinIt) {
  const fs::path out = tempOut("long_frame");
  const fs::path partial = out.string() + ".partial";
  fs::remove_all(partial);
  // frames 0 and 1 (t = 0, 50 s) have the generator off (nothing to do); frame 2 (t = 100 s)
  // heats: ~2 min of sub-steps on this machine (measured 121 s); SIGTERM 3 s after set-up
  const std::string sets =
      " --set mesh.slab.nodes=20000 --set material.thermal_conductivity_w_per_mk=100"
      " --set material.heat_capacity_j_per_m3k=38200 --set solvers.thermal.max_substeps=1000000"
      " --set time.fps=0.02 --set time.duration_s=200 --set tool.generator_on=[[100,.inf]]";
  const std::string cmd =
      std::string("cd ") + ESIM_SOURCE_DIR + " && (" + ESIM_EXE + " run scenarios/paper_slab.yaml" +
      sets + kSmall + " -o " + out.string() + " >/dev/null 2>&1 & pid=$!; " +
      // the set-up is done when DIR.partial appears (slower under ASan); frames 0 and 1
      // take well under 3 s
      "for i in $(seq 600); do [ -d " + partial.string() + " ] && break; sleep 0.2; done; " +
      "sleep 3; " + "t0=$(date +%s); kill -TERM $pid; wait $pid; rc=$?; " +
      "echo $rc $(( $(date +%s) - t0 )))";
  FILE* pipe = popen(cmd.c_str(), "r");
  int rc = -1, seconds = -1;
  ASSERT_EQ(fscanf(pipe, "%d %d", &rc, &seconds), 2);
  pclose(pipe);
  EXPECT_EQ(rc, 1) << "exit code of an interrupted run";
  EXPECT_LT(seconds, 30) << "the stop waited for the frame";
  ASSERT_TRUE(fs::exists(partial / "timing.json"));
  const auto timing = nlohmann::json::parse(readFile(partial / "timing.json"));
  EXPECT_TRUE(timing["interrupted"].get<bool>());
  EXPECT_EQ(timing["frames"].get<int>(), 2) << "the interrupted frame is not reported";
  // the summary's totals are those of the frames done, not of the half frame
  const std::string summary = readFile(partial / "summary.txt");
  EXPECT_NE(summary.find("energy        0.000 J delivered"), std::string::npos) << summary;
  EXPECT_NE(summary.find("(now 37.0 C)"), std::string::npos) << summary;
  fs::remove_all(partial);
}

// memory that runs out during set-up: exit 1 with the remedy, nothing written (a dense
// inverse of 20k nodes, 3.2 GB, under a 1.5 GB address-space limit)
TEST(RunCli, OutOfMemoryAtSetUpExitsOneAndWritesNothing) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "ASan reserves terabytes of address space: ulimit -v cannot apply";
#endif
  const fs::path out = tempOut("oom_setup");
  const Result r = shell(std::string("ulimit -v 1500000; ") + ESIM_EXE +
                         " run scenarios/paper_slab.yaml --set mesh.slab.nodes=20000"
                         " --set solvers.electric.strategy=dense-inverse"
                         " --set solvers.electric.dense_memory_limit_mb=100000 --frames 2"
                         " --no-video -q -o " +
                         out.string());
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("out of memory (a smaller mesh, fewer phases, or another electric "
                          "strategy: solvers.electric.strategy)"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".partial"));
}

// Linux overcommits: a scene too large for the machine was killed by the kernel (signal 9,
// no message: a 10-million-node slab after 287 s at 24 GB). esim bounds its address space
// by the memory there is, so that such an allocation throws and the run says "out of
// memory" (the test above): the bound is set, finite, and not below the memory available
TEST(RunCli, TheAddressSpaceIsBoundedByTheMemoryThereIs) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizers reserve terabytes of address space: esim sets no bound";
#endif
  if (shell("ulimit -v").output != "unlimited\n")
    GTEST_SKIP() << "a bound is set already (ulimit -v), which esim keeps when it is lower";
  const fs::path out = tempOut("address_space");
  const Result r = shell(std::string(ESIM_EXE) + " run scenarios/slab_cut.yaml --no-video -q -o " +
                         out.string() +
                         " & pid=$!; sleep 1; grep 'Max address space' /proc/$pid/limits; kill "
                         "-INT $pid; wait $pid; grep MemAvailable /proc/meminfo");
  std::istringstream lines(r.output);
  std::string line, limit;
  double availableKb = 0;
  while (std::getline(lines, line)) {
    if (line.rfind("Max address space", 0) == 0) {
      std::istringstream f(line.substr(17));
      f >> limit;
    }
    if (line.rfind("MemAvailable:", 0) == 0) availableKb = std::stod(line.substr(13));
  }
  ASSERT_FALSE(limit.empty()) << r.output;
  ASSERT_NE(limit, "unlimited") << r.output;
  EXPECT_GE(std::stod(limit), availableKb * 1024.0) << r.output;
  fs::remove_all(out.string() + ".partial");
}

// A memory cgroup of its own (cgroup v1 or v2, no swap) limited to `bytes`, and the shell
// words that move a command into it ("" where this machine gives none: not root, no
// writable cgroup file system). Removed by the destructor.
struct OwnMemoryCgroup {
  fs::path dir;
  std::string enter;  // "echo $$ > DIR/tasks && exec "
  explicit OwnMemoryCgroup(const std::string& bytes) {
    const std::string name = "esim_test_" + std::to_string(::getpid());
    std::error_code ec;
    const auto put = [](const fs::path& f, const std::string& v) {
      std::ofstream o(f);
      o << v;
      o.close();
      return static_cast<bool>(o);
    };
    if (fs::is_directory("/sys/fs/cgroup/memory") &&
        fs::create_directory("/sys/fs/cgroup/memory/" + name, ec)) {
      dir = "/sys/fs/cgroup/memory/" + name;
      put(dir / "memory.swappiness", "0");
      if (!put(dir / "memory.limit_in_bytes", bytes)) return;
      enter = "echo $$ > " + (dir / "tasks").string() + " && exec ";
    } else if (readFile("/sys/fs/cgroup/cgroup.controllers").find("memory") != std::string::npos &&
               fs::create_directory("/sys/fs/cgroup/" + name, ec)) {
      dir = "/sys/fs/cgroup/" + name;
      put(dir / "memory.swap.max", "0");
      if (!put(dir / "memory.max", bytes)) return;
      enter = "echo $$ > " + (dir / "cgroup.procs").string() + " && exec ";
    }
  }
  ~OwnMemoryCgroup() {
    // (its processes are gone a moment after the command: the watcher leaves last)
    for (int i = 0; i < 50 && !dir.empty() && ::rmdir(dir.c_str()) != 0; ++i) ::usleep(20000);
  }
};

// Under a memory cgroup's limit (a Slurm job's --mem, a container's --memory) a run whose
// memory grows past it was killed by the kernel with no word ("Killed", exit 137): the
// address-space bound takes the machine's memory and the cgroup's room only as a whole,
// while the run grows an allocation at a time. The watcher names the kill and the limit.
TEST(RunCli, AKillByTheOutOfMemoryKillerIsNamedWithTheLimit) {
  // first, a run that ends by itself, or by another signal, gets no such line (here: in one
  // test with the kill below, which another test running beside it could take for its own)
  const fs::path quiet = tempOut("oom_silent");
  Result r =
      esimRun("scenarios/paper_slab.yaml --frames 2 --no-video -o " + quiet.string() + kSmall);
  EXPECT_EQ(r.exitCode, 0) << r.output;
  r = shell(std::string(ESIM_EXE) + " run scenarios/slab_cut.yaml --no-video -q --overwrite -o " +
            quiet.string() + " & pid=$!; sleep 1; kill -9 $pid; wait $pid; echo status $?");
  EXPECT_NE(r.output.find("status 137"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("out-of-memory"), std::string::npos) << r.output;
  fs::remove_all(quiet);
  fs::remove_all(quiet.string() + ".partial");

  const OwnMemoryCgroup group("400000000");
  if (group.enter.empty()) GTEST_SKIP() << "no memory cgroup of our own here (root, cgroupfs)";
  const fs::path out = tempOut("oom_killed");
  fs::remove_all(out.string() + ".partial");
  r = shell("sh -c '" + group.enter + ESIM_EXE +
            " run scenarios/slab_cut.yaml --frames 2 --no-video -q -o " + out.string() +
            " --set mesh.slab.nodes=100000'");
  if (r.exitCode != 128 + 9) GTEST_SKIP() << "not killed here: " << r.output;
  EXPECT_NE(r.output.find("esim: error: the kernel's out-of-memory killer ended esim (signal 9): "
                          "its memory cgroup " +
                          group.dir.string() +
                          " allows 0.40 GB. It needed more: a coarser mesh (mesh.slab.nodes,"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out));
  fs::remove_all(out.string() + ".partial");
}

// A run killed mid-way (the kernel's out-of-memory killer, a scheduler's kill -9, a
// container stopped) writes no reports at the end, but its video so far plays: the MP4 is
// fragmented while it grows (a fragment from each key frame, 60 frames at 30 fps), and was a
// file without its index, which nothing could read. timing.csv's rows are streamed to
// timing.csv.partial as the frames are done.
TEST(RunCli, AKilledRunLeavesAVideoThatPlaysAndTheRowsOfItsFrames) {
  const fs::path out = tempOut("killed_video");
  fs::remove_all(out.string() + ".partial");
  const Result r = shell("ESIM_FAULT=kill@150 " + std::string(ESIM_EXE) +
                         " run scenarios/paper_slab.yaml --frames 200 -o " + out.string() + kSmall);
  ASSERT_EQ(r.exitCode, 128 + 9) << r.output;
  EXPECT_FALSE(fs::exists(out));
  const fs::path video = out.string() + ".partial/video.mp4.partial";
  ASSERT_TRUE(fs::exists(video));
  const int frames = videoFrames(video);
  EXPECT_GE(frames, 60) << "the first fragment";
  EXPECT_LE(frames, 151);
  // a row per frame done, whole, in order: frame 150 was handed to the drawing thread when
  // the process was killed, frame 149 at least was done
  const std::string csv = readFile(out.string() + ".partial/timing.csv.partial");
  ASSERT_FALSE(csv.empty());
  EXPECT_EQ(csv.back(), '\n');
  std::istringstream lines(csv);
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line.rfind("frame,time_s,move_tool_ms,", 0), 0u) << line;
  int rows = 0;
  while (std::getline(lines, line)) {
    EXPECT_EQ(line.rfind(std::to_string(rows) + ",", 0), 0u) << line;
    ++rows;
  }
  EXPECT_GE(rows, 150);
  EXPECT_LE(rows, 151);
  EXPECT_GE(rows, frames);
  fs::remove_all(out.string() + ".partial");
}

// a disk that fills while the reports are written (a file size limit stands for it: trace.json
// of 60 frames is 40 kB): exit 1, the run kept in DIR.partial, the failure named, and no
// report cut short (timing.csv was left empty, and the message was only "write failed")
TEST(RunCli, ReportsThatCannotBeWrittenFailTheRunAndLeaveNoCutFile) {
  const fs::path out = tempOut("reports_full");
  fs::remove_all(out.string() + ".partial");
  const Result r = shell("bash -c \"trap '' XFSZ; ulimit -f 20; " + std::string(ESIM_EXE) +
                         " run scenarios/paper_slab.yaml -q --frames 60 --no-video -o " +
                         out.string() + kSmall + "\"");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("esim: error: the run's reports could not be written: " + out.string() +
                          ".partial/trace.json: write failed (disk full?)"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out));
  for (const auto& e : fs::directory_iterator(out.string() + ".partial")) {
    const std::string name = e.path().filename().string();
    EXPECT_EQ(name.find(".tmp"), std::string::npos) << name;
    if (e.is_regular_file()) {
      EXPECT_GT(fs::file_size(e.path()), 0u) << name;
    }
  }
  EXPECT_FALSE(fs::exists(out.string() + ".partial/trace.json"));
  fs::remove_all(out.string() + ".partial");
}

// paper_slab for `frames` small frames into out, with the fault ESIM_FAULT injects (its
// earlier partial output removed first)
Result runWithFault(const std::string& fault, int frames, const fs::path& out,
                    const std::string& more = "") {
  fs::remove_all(out.string() + ".partial");
  return shell("ESIM_FAULT=" + fault + " " + ESIM_EXE + " run scenarios/paper_slab.yaml --frames " +
               std::to_string(frames) + kSmall + more + " -o " + out.string());
}

// frame k drawn on its own thread while frame k+1 is simulated gives the same images, the
// same video bytes, and reports the frames' period and latency
TEST(RunCli, TheDrawThreadGivesTheSameFramesAndReportsThePeriod) {
  std::string hash[2], video[2];
  for (int serial = 0; serial < 2; ++serial) {
    const fs::path out = tempOut(serial ? "draw_serial" : "draw_thread");
    const Result r = esimRun("scenarios/slab_cut.yaml --frames 12 --set mesh.slab.nodes=1013" +
                             std::string(kSmall) + (serial ? " --no-draw-thread" : "") +
                             " --overwrite -o " + out.string());
    ASSERT_EQ(r.exitCode, 0) << r.output;
    const auto timing = nlohmann::json::parse(readFile(out / "timing.json"));
    EXPECT_EQ(timing["draw_thread"].get<bool>(), serial == 0);
    EXPECT_EQ(timing["frame_period"]["frames_ran"].get<int>(), 12);
    EXPECT_EQ(timing["frame_latency"]["frames_ran"].get<int>(), 12);
    EXPECT_GT(timing["frame_period"]["p50_ms"].get<double>(), 0.0);
    // the periods over the frame's budget: none if the longest is under it, at least half if
    // the median is over it; the summary gives the same count
    const int slow = timing["frame_period"]["frames_over_budget"].get<int>();
    EXPECT_GE(slow, 0);
    EXPECT_LE(slow, 12);
    if (timing["frame_period"]["max_ms"].get<double>() <= 1000.0 / 30.0) {
      EXPECT_EQ(slow, 0);
    }
    if (timing["frame_period"]["p50_ms"].get<double>() > 1000.0 / 30.0) {
      EXPECT_GE(slow, 6);
    }
    EXPECT_NE(readFile(out / "summary.txt")
                  .find("(frames done, " + std::to_string(slow) + " of 12 over 33.3 ms;"),
              std::string::npos);
    EXPECT_GT(timing["structural"]["removed_tets"].get<int>(), 0);  // a cut: the mesh changes
    EXPECT_GE(timing["structural"]["structural_refactorizations"].get<int>(), 0);
    const int debris = timing["structural"]["debris_tets"].get<int>();
    EXPECT_GE(debris, 0);
    EXPECT_LE(debris, timing["structural"]["removed_tets"].get<int>());
    const std::string summary = readFile(out / "summary.txt");
    EXPECT_NE(summary.find(", " + std::to_string(debris) + " of them cut loose as debris ("),
              std::string::npos)
        << summary;
    EXPECT_NE(summary.find("  period "), std::string::npos) << summary;
    EXPECT_EQ(summary.find("drawn on a thread") != std::string::npos, serial == 0) << summary;
    hash[serial] = nlohmann::json::parse(readFile(out / "hashes.json"))["all_frames_xxh3"];
    video[serial] = readFile(out / "video.mp4");
    // the trace puts the drawing on a track of its own when it has one
    const auto trace = nlohmann::json::parse(readFile(out / "trace.json"));
    int drawTrack = 0;
    for (const auto& e : trace["traceEvents"]) drawTrack += e["tid"].get<int>() == 2;
    EXPECT_EQ(drawTrack > 0, serial == 0);
    fs::remove_all(out);
  }
  EXPECT_EQ(hash[0], hash[1]);
  EXPECT_FALSE(video[0].empty());
  EXPECT_EQ(video[0], video[1]);
}

// --physics-first moves the drawing thread and llvmpipe's threads to SCHED_IDLE (the reports
// count them; drawn in the loop, only llvmpipe's) and changes no byte of the frames or the video
TEST(RunCli, PhysicsFirstIdlesTheDrawingAndGivesTheSameFrames) {
  std::string hash[3], video[3];
  const std::string more[3] = {"", " --physics-first", " --physics-first --no-draw-thread"};
  for (int k = 0; k < 3; ++k) {
    const fs::path out = tempOut("physics_first_" + std::to_string(k));
    // two rasterizer threads whatever the machine's cores
    const Result r = shell("LP_NUM_THREADS=2 " + std::string(ESIM_EXE) +
                           " run scenarios/slab_cut.yaml --frames 12 --set mesh.slab.nodes=1013" +
                           kSmall + more[k] + " --overwrite -o " + out.string());
    ASSERT_EQ(r.exitCode, 0) << r.output;
    const auto timing = nlohmann::json::parse(readFile(out / "timing.json"));
    const int idle = timing["drawing_threads_idle"].get<int>();
    const std::string summary = readFile(out / "summary.txt");
    if (k == 0) {
      EXPECT_EQ(idle, 0);
      EXPECT_EQ(summary.find("SCHED_IDLE"), std::string::npos) << summary;
    } else {
      // llvmpipe's two rasterizer threads, and the drawing thread when there is one
      EXPECT_EQ(idle, k == 1 ? 3 : 2);
      EXPECT_NE(summary.find(std::to_string(idle) + " threads at SCHED_IDLE"), std::string::npos)
          << summary;
    }
    hash[k] = nlohmann::json::parse(readFile(out / "hashes.json"))["all_frames_xxh3"];
    video[k] = readFile(out / "video.mp4");
    fs::remove_all(out);
  }
  EXPECT_EQ(hash[1], hash[0]);
  EXPECT_EQ(hash[2], hash[0]);
  EXPECT_FALSE(video[0].empty());
  EXPECT_EQ(video[1], video[0]);
  EXPECT_EQ(video[2], video[0]);
}

// output.encode: after keeps the frames raw and encodes them after the loop: the same video
// bytes as encoding them during it, the raw frames' file gone, the reports saying which; a run
// whose raw frames would not fit on the disk is refused before anything is written
TEST(RunCli, TheVideoEncodedAfterTheLoopIsTheSameFile) {
  std::string video[2];
  for (int after = 0; after < 2; ++after) {
    const fs::path out = tempOut(after ? "encode_after" : "encode_during");
    const Result r = esimRun(
        "scenarios/slab_cut.yaml --frames 12 --set mesh.slab.nodes=1013" + std::string(kSmall) +
        " --set output.encode=" + (after ? "after" : "during") + " -o " + out.string());
    ASSERT_EQ(r.exitCode, 0) << r.output;
    video[after] = readFile(out / "video.mp4");
    EXPECT_FALSE(fs::exists(out / "video.mp4.frames.partial"));
    const auto timing = nlohmann::json::parse(readFile(out / "timing.json"));
    EXPECT_EQ(timing["offline"]["encode"].get<std::string>(), after ? "after" : "during");
    EXPECT_EQ(
        timing["cpu"]["note"].get<std::string>().find("output.encode: after") != std::string::npos,
        after == 1);
    const std::string summary = readFile(out / "summary.txt");
    EXPECT_EQ(summary.find(" s after the frame loop (output.encode: after)") != std::string::npos,
              after == 1)
        << summary;
    EXPECT_NE(summary.find("/ {video.mp4, timing.csv"), std::string::npos) << summary;
    fs::remove_all(out);
  }
  EXPECT_GT(video[0].size(), 1000u);
  EXPECT_EQ(video[0], video[1]);

  const fs::path out = tempOut("encode_after_no_room");
  const Result r = esimRun(
      "scenarios/slab_cut.yaml --frames 100000000 --set mesh.slab.nodes=1013 -q "
      "--set output.encode=after -o " +
      out.string());
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("esim: error: output.encode: after keeps the 100000000 frames raw until "
                          "the video is encoded at the end (1280 x 720 x 3 bytes each): "
                          "276480000 MB on the disk of "),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("set output.encode: during (encodes as the frames come) or free disk "
                          "space"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".partial"));
  // the labels' preview video is kept raw too, and counted
  const Result p = esimRun(
      "scenarios/slab_cut.yaml --frames 100000000 --set mesh.slab.nodes=1013 -q --no-video "
      "--labels preview --set output.encode=after -o " +
      out.string());
  EXPECT_EQ(p.exitCode, 2) << p.output;
  EXPECT_NE(p.output.find("(the labels' preview: 2560 x 720 x 3 bytes each): 552960000 MB on "
                          "the disk of "),
            std::string::npos)
      << p.output;
  EXPECT_FALSE(fs::exists(out.string() + ".partial"));
}

// the CPU the frames cost (timing.json's cpu, the summary's cpu line): on one CPU (taskset)
// the process cannot be busier than the one CPU, and what it reports is within what the
// shell's `times` counts for the whole child (set-up and exit included)
TEST(RunCli, TheCpuAFrameIsReportedAndBoundedByTheChildsOwn) {
  const fs::path out = tempOut("cpu");
  const Result r = shell(onOneCpu() + std::string(ESIM_EXE) +
                         " run scenarios/slab_cut.yaml --frames 12 --set mesh.slab.nodes=1013" +
                         kSmall + " -o " + out.string() + "; times");
  ASSERT_NE(r.output.find("m"), std::string::npos) << r.output;
  const auto timing = nlohmann::json::parse(readFile(out / "timing.json"));
  const auto& cpu = timing["cpu"];
  EXPECT_EQ(cpu["cpus"].get<int>(), 1);
  const double perFrame = cpu["ms_per_frame"].get<double>();
  EXPECT_GT(cpu["loop_thread_ms_per_frame"].get<double>(), 0.0);
  EXPECT_LE(cpu["loop_thread_ms_per_frame"].get<double>(), perFrame);
  EXPECT_DOUBLE_EQ(cpu["period_floor_ms"].get<double>(), perFrame);  // one CPU
  EXPECT_GT(cpu["busy_cpus"].get<double>(), 0.0);
  EXPECT_LE(cpu["busy_cpus"].get<double>(), 1.02);
  // `times`' second line: the children's user and system time, "XmY.YYs" each
  const std::string last = r.output.substr(r.output.rfind('\n', r.output.size() - 2) + 1);
  double childS = 0;
  std::istringstream in(last);
  std::string field;
  while (in >> field) {
    const size_t m = field.find('m');
    ASSERT_NE(m, std::string::npos) << last;
    childS += 60 * std::stod(field.substr(0, m)) + std::stod(field.substr(m + 1));
  }
  EXPECT_GT(childS, 0.0) << last;
  EXPECT_LE(perFrame * 12 / 1e3, childS + 0.02) << last;  // times counts in 10 ms ticks
  const std::string summary = readFile(out / "summary.txt");
  EXPECT_NE(summary.find("  cpu           "), std::string::npos) << summary;
  EXPECT_NE(summary.find(" of 1 CPUs busy"), std::string::npos) << summary;
  fs::remove_all(out);
}

// a frame that cannot be drawn (injected, ESIM_FAULT=draw@N; a disk that fills under the
// PNGs or the video) ends the run with the frames before it, on the drawing thread or not:
// exit 1, the error naming that frame, the video and reports of the frames before it
TEST(RunCli, AFrameThatCannotBeDrawnKeepsTheFramesBeforeIt) {
  for (const std::string more : {"", " --no-draw-thread"}) {
    SCOPED_TRACE(more);
    const fs::path out = tempOut("draw_fault");
    const fs::path partial = out.string() + ".partial";
    const Result r = runWithFault("draw@3", 8, out, more);
    EXPECT_EQ(r.exitCode, 1) << r.output;
    EXPECT_NE(r.output.find("frame 3: video: writing frame 3 failed"), std::string::npos)
        << r.output;
    ASSERT_TRUE(fs::exists(partial / "timing.json")) << r.output;
    const auto timing = nlohmann::json::parse(readFile(partial / "timing.json"));
    EXPECT_FALSE(timing["complete"].get<bool>());
    EXPECT_EQ(timing["frames"].get<int>(), 3);
    EXPECT_EQ(videoFrames(partial / "video.mp4"), 3);
    EXPECT_EQ(nlohmann::json::parse(readFile(partial / "hashes.json"))["frames"].size(), 3u);
    fs::remove_all(partial);
  }
}

// memory that runs out in the middle of a run (injected, ESIM_FAULT: a real one comes only
// by chance): exit 1, the frames before it kept in DIR.partial, marked incomplete with the
// reason, and a playable video of those frames
TEST(RunCli, OutOfMemoryMidRunKeepsTheFramesMarkedPartial) {
  const fs::path out = tempOut("oom_run");
  const Result r = runWithFault("bad_alloc@4", 10, out);
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("frame 4: out of memory"), std::string::npos) << r.output;
  expectFailedWithFramesKept(out, 4, r.output);
}

// a thread a frame needs that cannot be started (std::async and std::thread throw
// std::system_error: the address-space bound refused its stack, or ulimit -u; injected,
// ESIM_FAULT=thread@N) ends the run like memory that runs out: exit 1, named, the frames
// before it kept with their reports (it escaped as an internal error, exit 4, with none)
TEST(RunCli, AThreadThatCannotBeStartedKeepsTheFramesBeforeIt) {
  const fs::path out = tempOut("thread_run");
  const Result r = runWithFault("thread@2", 6, out);
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("esim: error: frame 2: a thread could not be started (thread "
                          "(injected: ESIM_FAULT): Resource temporarily unavailable): out of "
                          "memory or of threads (ulimit -u)"),
            std::string::npos)
      << r.output;
  expectFailedWithFramesKept(out, 2, r.output);
}

// a camera that sees none of the tissue gave a video of the background alone, silently: its
// eye inside the tissue (drawn from outside only), or pointed away; or one whose view misses
// the tool in most frames. Said at set-up on stderr and in the run's warnings (the summary,
// timing.json, a sweep's manifest); the run goes on
TEST(RunCli, ACameraThatSeesNoTissueIsWarnedOf) {
  const fs::path out = tempOut("camera_blind");
  const auto run = [&out](const std::string& camera) {
    fs::remove_all(out);
    return esimRun("scenarios/paper_slab.yaml --frames 2 --no-video" + std::string(kSmall) +
                   camera + " -o " + out.string());
  };
  Result r = run(" --set camera.eye_m=[0,0,0.005] --set camera.target_m=[0.01,0,0.005]");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  const std::string inside =
      "camera.eye_m [0.0, 0.0, 5.0] mm is inside the tissue, whose surface is drawn from outside "
      "only: the frames show the background; put the eye outside the tissue";
  EXPECT_NE(r.output.find("esim: warning: " + inside + "\n"), std::string::npos) << r.output;
  auto warnings = nlohmann::json::parse(readFile(out / "timing.json"))["warnings"];
  ASSERT_EQ(warnings.size(), 1u) << warnings.dump();
  EXPECT_EQ(warnings[0], inside);
  EXPECT_NE(readFile(out / "summary.txt").find("  WARNING       " + inside), std::string::npos);
  // the run with this camera goes on, warned with this text
  const auto warned = [&run](const std::string& camera, const std::string& warning) {
    const Result w = run(camera);
    EXPECT_EQ(w.exitCode, 0) << w.output;
    EXPECT_NE(w.output.find("esim: warning: " + warning), std::string::npos) << w.output;
  };
  warned(" --set camera.eye_m=[0,-0.1,0.05] --set camera.target_m=[0,-0.2,0.05]",
         "the camera sees none of the tissue (camera.eye_m [0.0, -100.0, 50.0] mm, "
         "camera.target_m [0.0, -200.0, 50.0] mm, camera.fov_deg ");
  // a view of a corner of the slab, away from the tool's path: the cut happens off screen
  warned(
      " --set camera.eye_m=[0.04,0.04,0.05] --set camera.target_m=[0.045,0.045,0] --set "
      "camera.fov_deg=10",
      "the tool's tip is outside the camera's view in 2 of 2 frames (camera.eye_m [40.0, 40.0, "
      "50.0] mm, camera.target_m [45.0, 45.0, 0.0] mm, camera.fov_deg 10): the video shows "
      "little of the cut; point camera.target_m at the tool's path\n");
  // from below the slab: the tissue hides the tool
  warned(" --set camera.eye_m=[-0.035,-0.03,-0.03] --set camera.target_m=[-0.035,0,0.005]",
         "the tissue hides the tool in 2 of 2 frames checked (its axis from the tip up, as the "
         "tissue is at the start; camera.eye_m [-35.0, -30.0, -30.0] mm, ");
  // the scene's own camera sees it: no such warning
  r = run("");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.output.find("esim: warning:"), std::string::npos) << r.output;
  warnings = nlohmann::json::parse(readFile(out / "timing.json"))["warnings"];
  EXPECT_TRUE(warnings.empty()) << warnings.dump();
  fs::remove_all(out);
}

// what the set-up finds (here a tool path 4 mm under the surface, deeper than its contact
// distance: sim/simulation.cpp) is said before the frames, even with -q, and the summary
// and timing.json repeat it
TEST(RunCli, ASetUpWarningIsSaidBeforeTheFrames) {
  const fs::path out = tempOut("setup_warning");
  const Result r = esimRun(
      "scenarios/slab_cut.yaml --frames 1 --no-video -q --set mesh.slab.nodes=1013 --set "
      "'tool.path=[{t_s: 0, position_m: [0.001, 0, 0.006], orientation_deg: [0, 0, 0]}]' -o " +
      out.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const std::string warning = "the tool reaches 4.0 mm under the tissue's surface at t = 0.00 s";
  const size_t said = r.output.find("esim: warning: " + warning);
  ASSERT_NE(said, std::string::npos) << r.output;
  EXPECT_LT(said, r.output.find("esim run slab_cut")) << r.output;  // before the summary
  const auto warnings = nlohmann::json::parse(readFile(out / "timing.json"))["warnings"];
  ASSERT_EQ(warnings.size(), 1u) << warnings.dump();
  EXPECT_EQ(warnings[0].get<std::string>().rfind(warning, 0), 0u);
  fs::remove_all(out);
}

// a run whose memory cgroup has almost nothing left (ESIM_MEMORY_ROOT: a folder standing for
// "/", whose v1 group has 20 MB left of 1 GB, under the guard's 32 MB reserve) stops after a
// whole frame with its reports, exit 1, instead of being killed by the kernel with none; with
// 100 MB left the same run completes and reports the least room it saw
// a folder standing for "/" (ESIM_MEMORY_ROOT) whose process is in a v1 memory cgroup "job"
// of 1 GB with `usage` bytes used, on a machine with 10 GB available; returns its writer
// (a path under it, the text), to change a file later
std::function<void(const std::string&, const std::string&)> fakeMemoryRoot(
    const fs::path& root, const std::string& usage) {
  const auto write = [root](const std::string& rel, const std::string& text) {
    fs::create_directories((root / rel).parent_path());
    std::ofstream(root / rel) << text;
  };
  write("proc/meminfo", "MemAvailable:   9765625 kB\nSwapFree:       0 kB\n");
  write("proc/self/cgroup", "4:memory:/job\n");
  write("sys/fs/cgroup/memory/job/memory.limit_in_bytes", "1000000000\n");
  write("sys/fs/cgroup/memory/job/memory.usage_in_bytes", usage + "\n");
  return write;
}

TEST(RunCli, ARunNearItsMemoryLimitStopsWithItsReports) {
  const fs::path root = tempOut("memory_root");
  const auto write = fakeMemoryRoot(root, "980000000");
  const fs::path out = tempOut("memory_low");
  const fs::path partial = out.string() + ".partial";
  fs::remove_all(partial);
  const std::string run = "ESIM_MEMORY_ROOT=" + root.string() + " " + ESIM_EXE +
                          " run scenarios/paper_slab.yaml --frames 5" + kSmall + " -o " +
                          out.string();
  Result r = shell(run);
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("esim: error: after frame 0: memory: its memory cgroup " +
                          (root / "sys/fs/cgroup/memory/job").string() +
                          " has 20 MB left of 1000 MB, under the 32 MB this run keeps in reserve"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out));
  ASSERT_TRUE(fs::exists(partial / "timing.json")) << r.output;
  auto timing = nlohmann::json::parse(readFile(partial / "timing.json"));
  EXPECT_FALSE(timing["complete"].get<bool>());
  EXPECT_EQ(timing["frames"].get<int>(), 1);
  EXPECT_DOUBLE_EQ(timing["memory_left_min_mb"].get<double>(), 20.0);
  EXPECT_EQ(videoFrames(partial / "video.mp4"), 1);
  fs::remove_all(partial);
  // --no-memory-guard: the run goes on (here to its end)
  r = shell(run + " --no-memory-guard");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.output.find("left between frames"), std::string::npos) << r.output;
  fs::remove_all(out);

  write("sys/fs/cgroup/memory/job/memory.usage_in_bytes", "900000000\n");
  r = shell(run);
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("at least 100 MB left between frames"), std::string::npos) << r.output;
  timing = nlohmann::json::parse(readFile(out / "timing.json"));
  EXPECT_EQ(timing["frames"].get<int>(), 5);
  EXPECT_DOUBLE_EQ(timing["memory_left_min_mb"].get<double>(), 100.0);
  // the electric column cache's cap is the scene's whatever the memory (the bits of a run
  // after a cut depend on it at round-off); it is cut only when memory runs short
  EXPECT_DOUBLE_EQ(timing["electric_cache_limit_mb"].get<double>(), 1024.0);
  EXPECT_TRUE(timing["electric_cache_cuts"].empty());
  fs::remove_all(out);
  fs::remove_all(root);
}

// A frame that asks for more than the room left (a rebuild's second model, a workspace the run
// has not needed before: ESIM_FAULT=alloc@N:MB stands for one) was given it and then killed by
// the kernel with no reports, the guard between frames seeing nothing coming. Between frames
// the address space is bounded by the room left (a folder standing for "/": its v1 group has
// 300 MB left), so that frame gets std::bad_alloc: exit 1, the frames before it kept with
// every report, the bound named. A frame that fits goes on, and without the guard nothing
// bounds the frame (the same 600 MB are given).
TEST(RunCli, AFrameAskingForMoreThanTheRoomStopsWithItsReports) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizers map terabytes: esim sets no address-space bound under them";
#endif
  const fs::path root = tempOut("memory_room_frame");
  fakeMemoryRoot(root, "700000000");
  const fs::path out = tempOut("memory_frame");
  const fs::path partial = out.string() + ".partial";
  const auto run = [&](const std::string& fault, const std::string& more = "") {
    fs::remove_all(out);
    fs::remove_all(partial);
    return shell("ESIM_FAULT=" + fault + " ESIM_MEMORY_ROOT=" + root.string() + " " + ESIM_EXE +
                 " run scenarios/paper_slab.yaml --frames 6" + kSmall + more + " -o " +
                 out.string());
  };
  Result r = run("alloc@3:600");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(
      r.output.find("esim: error: frame 3: out of memory (a smaller mesh, or another "
                    "electric strategy: see timing.json's electric_memory_mb); a frame may "
                    "map 268 MB more: its memory cgroup " +
                    (root / "sys/fs/cgroup/memory/job").string() + " has 300 MB left of 1000 MB\n"),
      std::string::npos)
      << r.output;
  EXPECT_EQ(nlohmann::json::parse(readFile(partial / "hashes.json"))["frames"].size(), 3u);
  expectFailedWithFramesKept(out, 3, r.output);
  // a frame within the room, and the same 600 MB without the guard, go on to the end
  r = run("alloc@3:200");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  r = run("alloc@3:600", " --no-memory-guard");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  fs::remove_all(out);
  fs::remove_all(partial);
  fs::remove_all(root);
}

// The same in a real memory cgroup (where this machine gives one of our own): the first
// removal of a synchronous rebuild builds a second model (~150 MB more at its peak) where the
// group allows ~84 MB more than the set-up took; it was killed by the kernel (exit 137, no
// reports) and now stops in that frame with its reports
TEST(RunCli, ARebuildThatOutgrowsItsCgroupStopsWithItsReports) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizers map terabytes: esim sets no address-space bound under them";
#endif
  // the limit: the set-up's peak here (246 MB on this project's machine, where 330 MB was
  // measured) + 84 MB, so that the set-up fits on any machine and the rebuild does not
  const fs::path out = tempOut("cgroup_rebuild");
  const fs::path partial = out.string() + ".partial";
  fs::remove_all(out);
  const Result setup = esimRun("scenarios/slab_cut.yaml --frames 1 --no-video -q -o " +
                               out.string() + " --set solvers.rebuild.mode=synchronous");
  ASSERT_EQ(setup.exitCode, 0) << setup.output;
  const double setupMb =
      nlohmann::json::parse(readFile(out / "timing.json"))["peak_rss_after_setup_mb"];
  fs::remove_all(out);
  const OwnMemoryCgroup group(std::to_string(std::lround((setupMb + 84) * 1e6)));
  if (group.enter.empty()) GTEST_SKIP() << "no memory cgroup of our own here (root, cgroupfs)";
  fs::remove_all(partial);
  const Result r = shell("sh -c '" + group.enter + ESIM_EXE +
                         " run scenarios/slab_cut.yaml --frames 12 --no-video -q -o " +
                         out.string() + " --set solvers.rebuild.mode=synchronous'");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find(": out of memory ("), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("; a frame may map "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" more: its memory cgroup " + group.dir.string() + " has "),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("out-of-memory killer"), std::string::npos) << r.output;
  ASSERT_TRUE(fs::exists(partial / "timing.json")) << r.output;
  const auto timing = nlohmann::json::parse(readFile(partial / "timing.json"));
  EXPECT_FALSE(timing["complete"].get<bool>());
  EXPECT_GE(timing["frames"].get<int>(), 1);
  EXPECT_LT(timing["frames"].get<int>(), 12);
  fs::remove_all(partial);
}

// a video that cannot be finished after the last frame (a disk that fills at the end,
// injected): the run failed, exit 1, its reports in DIR.partial marked incomplete with the
// reason (it escaped as bad input, exit 2, with no reports)
TEST(RunCli, AVideoThatCannotBeFinishedFailsTheRunWithItsReports) {
  const fs::path out = tempOut("video_close");
  const fs::path partial = out.string() + ".partial";
  const Result r = runWithFault("video_close@0", 5, out);
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("esim: error: closing the outputs: video: finishing"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out));
  ASSERT_TRUE(fs::exists(partial / "timing.json")) << r.output;
  const auto timing = nlohmann::json::parse(readFile(partial / "timing.json"));
  EXPECT_FALSE(timing["complete"].get<bool>());
  EXPECT_EQ(timing["frames"].get<int>(), 5);
  EXPECT_NE(timing["failure"].get<std::string>().find("No space left on device"),
            std::string::npos);
  EXPECT_NE(readFile(partial / "summary.txt").find("FAILED: partial"), std::string::npos);
  fs::remove_all(partial);
}

std::string probe(const std::string& args) {
  FILE* p = popen(("ffprobe -v error " + args + " 2>&1").c_str(), "r");
  std::string out;
  char buf[256];
  while (fgets(buf, sizeof buf, p)) out += buf;
  pclose(p);
  return out;
}

TEST(RunCli, AllowedValuesGetClearAnswers) {
  const fs::path out = tempOut("answers");
  // 29.97 fps is written as 29.97, not rounded to 30
  Result r = esimRun("scenarios/paper_slab.yaml --frames 4 --set time.fps=29.97" +
                     std::string(kSmall) + " -o " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(
      probe("-show_entries stream=avg_frame_rate -of csv=p=0 " + (out / "video.mp4").string()),
      "2997/100\n");
  fs::remove_all(out);
  // 0.1 fps (a frame every 10 s) makes a 30 s video of 3 frames
  r = esimRun("scenarios/paper_slab.yaml --frames 3 --set time.fps=0.1 --set time.duration_s=30" +
              std::string(kSmall) + " -o " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(probe("-show_entries format=duration -of csv=p=0 " + (out / "video.mp4").string()),
            "30.000000\n");
  fs::remove_all(out);
  // a rate a video cannot have: named by its key, with the remedy; nothing written
  r = esimRun("scenarios/paper_slab.yaml --frames 3 --set time.fps=500" + std::string(kSmall) +
              " -o " + out.string());
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("time.fps = 500: a video needs 0.01 to 240"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out.string() + ".partial"));
  // a tool at 0 V is allowed: it runs and delivers nothing (no message about colour ranges)
  r = esimRun("scenarios/paper_slab.yaml --frames 3 --set tool.voltage_v=0" + std::string(kSmall) +
              " -o " + out.string());
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("0.000 J delivered"), std::string::npos) << r.output;
  fs::remove_all(out);
  // --frames 0: the range, not a 309-digit number
  r = esimRun("scenarios/paper_slab.yaml --frames 0 -o " + out.string());
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--frames: Value 0 not in range 1 to 100000000"), std::string::npos)
      << r.output;
}

// a surface file is meshed before anything else is said, which takes minutes for a fine
// mesh: the run says what it meshes first (it was silent until the mesh was done), and -q
// keeps it quiet
TEST(RunCli, MeshingASurfaceFileIsAnnounced) {
  const fs::path out = tempOut("surface_file_announced");
  const std::string args =
      "scenarios/liver_cut.yaml --frames 1 --no-video --set output.hashes=false --set "
      "mesh.file.cell_size_m=0.01 --set mesh.file.facet_size_m=0.01 --set "
      "mesh.file.refine.enabled=false --overwrite -o " +
      out.string();
  const Result r = esimRun(args);
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.output.rfind("esim: meshing assets/liver.obj (mesh.file.cell_size_m 0.01 m)\n", 0),
            0u)
      << r.output;
  const Result quiet = esimRun(args + " -q");
  ASSERT_EQ(quiet.exitCode, 0) << quiet.output;
  EXPECT_EQ(quiet.output.find("esim: meshing"), std::string::npos) << quiet.output;
  fs::remove_all(out);
}

TEST(RunCli, AnEmptyScenarioRunsTheDefaultsAndTheirBladeDelivers) {
  const fs::path dir = tempOut("empty_scenario");
  fs::create_directories(dir);
  std::ofstream(dir / "empty.yaml") << "";
  const Result r = esimRun((dir / "empty.yaml").string() + " --frames 3 --no-video" +
                           std::string(kSmall) + " -o " + (dir / "run").string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  // the default blade's tip is 0.2 mm into a coarse slab with no node within reach: the
  // current still flows (through the tet holding the tip), and the summary says so
  EXPECT_EQ(r.output.find(" 0.000 J delivered"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("WARNING       3 frames: the tool was inside the tissue"),
            std::string::npos)
      << r.output;
  const auto timing = nlohmann::json::parse(readFile(dir / "run" / "timing.json"));
  EXPECT_EQ(timing["warnings"].size(), 1u);
  fs::remove_all(dir);
}

TEST(RunCli, ExitCodesOfEachKind) {
  // input: 2 (a key that does not exist), nothing written
  const fs::path out = tempOut("kinds");
  const Result bad = esimRun("scenarios/paper_slab.yaml --set tool.voltage=3 -o " + out.string());
  EXPECT_EQ(bad.exitCode, 2) << bad.output;
  EXPECT_FALSE(fs::exists(out.string() + ".partial"));
  // a rule only the core checked before: refused at load by `validate` and `run` alike
  const std::string rule = " --set material.boiling_temperature_c=30";
  const Result run = esimRun("scenarios/paper_slab.yaml" + rule + " -o " + out.string());
  EXPECT_EQ(run.exitCode, 2) << run.output;
  EXPECT_NE(run.output.find("material.boiling_temperature_c"), std::string::npos) << run.output;
  const std::string validate = std::string("cd ") + ESIM_SOURCE_DIR + " && " + ESIM_EXE +
                               " validate scenarios/paper_slab.yaml" + rule + " >/dev/null 2>&1";
  const int status = std::system(validate.c_str());
  EXPECT_EQ(WEXITSTATUS(status), 2);
}

// a command word that is no command is named, with the commands there are (CLI11 said "A
// subcommand is required"); a command's own arguments are not mistaken for one
TEST(RunCli, AnUnknownCommandIsNamed) {
  const Result top = shell(std::string(ESIM_EXE) + " rnu scenarios/paper_slab.yaml");
  EXPECT_EQ(top.exitCode, 2) << top.output;
  EXPECT_NE(top.output.find("esim: error: esim: unknown command 'rnu'; expected one of: run, "),
            std::string::npos)
      << top.output;
  const Result bench = shell(std::string(ESIM_EXE) + " bench cuts");
  EXPECT_EQ(bench.exitCode, 2) << bench.output;
  EXPECT_NE(bench.output.find("esim bench: unknown command 'cuts'; expected one of: "),
            std::string::npos)
      << bench.output;
  EXPECT_NE(bench.output.find("cut"), std::string::npos) << bench.output;
  const Result own = shell(std::string(ESIM_EXE) + " validate scenarios/paper_slab.yaml");
  EXPECT_EQ(own.exitCode, 0) << own.output;
}

// a value the command line refuses is quoted short and printable: CLI11's range message
// echoed a 5000-digit --frames whole and a byte 0x85 or a terminal's escape raw, as did the
// unknown command and the electric strategy's name
TEST(RunCli, RefusedOptionValuesAreQuotedPrintable) {
  struct Case {
    std::string args, expect;
  };
  const std::string escaped = "\"$(printf '/nonexistent/x\\033[31m.yaml')\"";
  const std::vector<Case> cases = {
      {"run scenarios/paper_slab.yaml --frames \"$(printf '\\205\\001')\"",
       "--frames: Value \\x85\\x01 not in range"},
      {"run scenarios/paper_slab.yaml --frames " + std::string(5000, '9'),
       "--frames: Value " + std::string(284, '9') + " ... (5044 characters)"},
      {"\"$(printf 'r\\033n')\"", "unknown command 'r\\x1Bn'"},
      {"bench cut --electric \"$(printf 'pc\\033g')\"", "unknown strategy 'pc\\x1Bg'; valid names"},
      // the net under the quoting: a file name with a terminal's escape, where esim prints it
      {"run " + escaped, "/nonexistent/x\\x1B[31m.yaml"},
      {"validate " + escaped, "/nonexistent/x\\x1B[31m.yaml"},
  };
  for (const Case& c : cases) {
    const Result r = shell(std::string(ESIM_EXE) + " " + c.args);
    EXPECT_EQ(r.exitCode, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.expect << "\n" << r.output;
    EXPECT_LT(r.output.size(), 600u) << r.output;
    EXPECT_EQ(r.output.find_first_of(std::string("\x1b\x85\x01", 3)), std::string::npos)
        << r.output;
  }
}

// A status line that is not an error (the run's summary of its outputs, render-sample's
// "FILE: 640x360 ...", bench's "wrote FILE") names the user's own folder: it printed the
// folder's bytes as given, so a name with a terminal's escape coloured the terminal
TEST(RunCli, StatusLinesShowTheOutputFolderPrintable) {
  const fs::path parent = tempOut("status_escape");
  fs::create_directories(parent);
  const std::string name = "a\x1b[31mb\x85";
  const std::string shown = "a\\x1B[31mb\\x85";
  struct Case {
    std::string args, folder, before, after;  // expected: before + PARENT/folder<shown> + after
  };
  const std::vector<Case> cases = {
      {"run scenarios/paper_slab.yaml --frames 1 --no-video" + std::string(kSmall) + " -o ", "run_",
       "  outputs       ", "/ {"},
      {"render-sample --width 64 --height 36 --out ", "sample_", "",
       "/sample_temperature.png: 64x36"},
      {"bench thermal --sizes 1013 --frames 4 --csv ", "csv_", "wrote ", "\n"}};
  for (const auto& [args, folder, before, after] : cases) {
    const fs::path out = parent / (folder + name);
    const std::string expect = before + (parent / folder).string() + shown + after;
    const Result r = shell(std::string(ESIM_EXE) + " " + args + "'" + out.string() + "'");
    EXPECT_EQ(r.exitCode, 0) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(expect), std::string::npos) << expect << "\n" << r.output;
    EXPECT_EQ(r.output.find_first_of(std::string("\x1b\x85", 2)), std::string::npos) << r.output;
    EXPECT_TRUE(fs::exists(out)) << "the folder or file is made with the name as given";
  }
  fs::remove_all(parent);
}

// An option or argument given an empty value, as an unset shell variable gives it (-o "$OUT"):
// -o "" ran into the default folder out/<name>, --csv "" and --report "" wrote nothing, all
// with exit 0; validate "" said "error: : cannot open the scenario file"
TEST(RunCli, AnEmptyValueIsRefusedAndNamed) {
  const fs::path defaultFolder = fs::path(ESIM_SOURCE_DIR) / "out" / "empty_value_test";
  fs::remove_all(defaultFolder);
  const std::vector<std::pair<std::string, std::string>> cases{
      {"run scenarios/paper_slab.yaml --frames 1 --no-video -q --set name=empty_value_test -o ''",
       "esim: error: --out (output folder"},
      {"run ''", "esim: error: scenario (scenario YAML file"},
      {"validate ''", "esim: error: scenarios (scenario YAML files"},
      {"bench cut --sizes 1013 --frames 2 --csv ''", "esim: error: --csv (write the table to FILE"},
      {"compare out out --report ''", "esim: error: --report (write compare.json"},
      {"sweep scenarios/sweeps/paper_slab_tiny_4.yaml -o ''", "esim: error: --out ("}};
  for (const auto& [args, message] : cases) {
    const Result r = shell(std::string(ESIM_EXE) + " " + args);
    EXPECT_EQ(r.exitCode, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(message + ""), std::string::npos) << args << "\n" << r.output;
    EXPECT_NE(r.output.find("): an empty value (an unset shell variable?)"), std::string::npos)
        << args << "\n"
        << r.output;
  }
  EXPECT_FALSE(fs::exists(defaultFolder));
  // an empty --run-args is no run option at all: allowed
  const Result dry =
      shell(std::string(ESIM_EXE) +
            " sweep scenarios/sweeps/paper_slab_tiny_4.yaml --run-args '' --dry-run");
  EXPECT_EQ(dry.exitCode, 0) << dry.output;
}

// ---- labels (esim run --labels) ----

// the acceptance run, shortened: every label file, one per frame of the video, pixel-aligned
// with it, consistent with each other; the same masks on a second run with one llvmpipe thread
TEST(RunCli, LabelsArePixelAlignedWithTheVideo) {
  const fs::path out = tempOut("labels");
  const int w = 160, h = 90, frames = 3;
  Result r = esimRun("scenarios/paper_slab.yaml --frames 3 --labels preview" + std::string(kSmall) +
                     " -o " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("labels/"), std::string::npos) << r.output;
  const fs::path dir = out / "labels";
  for (const char* f : {"classes.json", "camera.json", "frames.jsonl", "coco.json", "preview.mp4"})
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  EXPECT_FALSE(fs::exists(dir / "mask_00003.png"));
  // the video has as many frames as there are masks; the preview is frame | mask
  const std::string count =
      probe("-count_frames -select_streams v:0 -show_entries stream=nb_read_frames -of csv=p=0 " +
            (out / "video.mp4").string());
  EXPECT_EQ(std::atoi(count.c_str()), frames) << count;
  EXPECT_EQ(probe("-select_streams v:0 -show_entries stream=width,height -of csv=p=0 " +
                  (dir / "preview.mp4").string()),
            "320,90\n");
  // camera.json: the frame's size, OpenCV principal point, depth unit
  const auto camera = nlohmann::json::parse(readFile(dir / "camera.json"));
  EXPECT_EQ(camera["width"], w);
  EXPECT_EQ(camera["height"], h);
  EXPECT_DOUBLE_EQ(camera["cx"].get<double>(), (w - 1) / 2.0);
  EXPECT_DOUBLE_EQ(camera["cy"].get<double>(), (h - 1) / 2.0);
  // the scenario's camera is 0.166 m from its target: 4 x that needs 20 um units
  EXPECT_DOUBLE_EQ(camera["depth"]["unit_m"].get<double>(), 2e-5);
  const auto classes = nlohmann::json::parse(readFile(dir / "classes.json"));
  ASSERT_EQ(classes["classes"].size(), static_cast<size_t>(esim::kLabelClassCount));
  EXPECT_EQ(classes["classes"][2]["name"], "tool_tip");
  // frames.jsonl: one line per frame
  std::istringstream jsonl(readFile(dir / "frames.jsonl"));
  std::vector<nlohmann::json> lines;
  for (std::string line; std::getline(jsonl, line);) lines.push_back(nlohmann::json::parse(line));
  ASSERT_EQ(lines.size(), static_cast<size_t>(frames));
  const auto hashes = nlohmann::json::parse(readFile(out / "hashes.json"));
  ASSERT_EQ(hashes["frames"].size(), static_cast<size_t>(frames));
  const auto coco = nlohmann::json::parse(readFile(dir / "coco.json"));
  EXPECT_EQ(coco["images"].size(), static_cast<size_t>(frames));
  for (int f = 0; f < frames; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "%05d.png", f);
    const esim::GrayImage mask = esim::readPngGray((dir / ("mask_" + std::string(name))).string());
    const esim::GrayImage depth =
        esim::readPngGray((dir / ("depth_" + std::string(name))).string());
    ASSERT_EQ(mask.bitDepth, 8);
    ASSERT_EQ(depth.bitDepth, 16);
    ASSERT_EQ(mask.width, w);
    ASSERT_EQ(mask.height, h);
    ASSERT_EQ(depth.width, w);
    ASSERT_EQ(depth.height, h);
    // counts per class as frames.jsonl says; depth exactly where something is drawn
    std::map<int, long> counted;
    std::vector<std::uint8_t> bytes(mask.values.size()), tool(mask.values.size());
    for (size_t i = 0; i < mask.values.size(); ++i) {
      const int c = mask.values[i];
      ASSERT_LT(c, esim::kLabelClassCount);
      ++counted[c];
      bytes[i] = static_cast<std::uint8_t>(c);
      tool[i] = c == 1 || c == 2;
      const bool drawn = c != 0 && c != 7;
      if (c != 7) {
        EXPECT_EQ(depth.values[i] != 0, drawn) << "frame " << f << " pixel " << i;
      }
    }
    const nlohmann::json& line = lines[f];
    EXPECT_EQ(line["frame"], f);
    long total = 0;
    for (const auto& c : classes["classes"]) {
      const long n = line["class_pixels"][c["name"].get<std::string>()];
      EXPECT_EQ(n, counted[c["id"].get<int>()]) << c["name"];
      total += n;
    }
    EXPECT_EQ(total, w * h);
    EXPECT_GT(counted[3], w * h / 4) << "the slab should fill much of the view";
    EXPECT_GT(counted[1] + counted[2], 20) << "the electrode should show";
    EXPECT_EQ(line["generator_on"], true);
    EXPECT_GT(line["power_w"].get<double>(), 0);
    EXPECT_GT(line["contact_nodes"].get<int>(), 0);
    EXPECT_EQ(line["tool"]["position_m"].size(), 3u);
    EXPECT_EQ(line["tool"]["orientation_wxyz"].size(), 4u);
    EXPECT_EQ(line["tool"]["tip_in_image"], true);
    EXPECT_NEAR(line["time_s"].get<double>(), (f + 1) / 30.0, 1e-9);
    // hashes.json holds the mask's hash; coco.json's tool instance decodes to the tool pixels
    EXPECT_EQ(hashes["frames"][f]["mask_xxh3"],
              esim::hashToHex(esim::hashBytes(bytes.data(), bytes.size())));
    int toolInstances = 0;
    for (const auto& a : coco["annotations"]) {
      if (a["image_id"] != f || a["category_id"] != 1) continue;
      ++toolInstances;
      EXPECT_EQ(a["segmentation"]["size"], nlohmann::json({h, w}));
      EXPECT_EQ(
          esim::cocoRleDecode(a["segmentation"]["counts"].get<std::vector<std::uint32_t>>(), w, h),
          tool);
      EXPECT_EQ(a["area"], counted[1] + counted[2]);
    }
    EXPECT_EQ(toolInstances, 1);
  }
  // the labels' writing is a stage of its own
  EXPECT_NE(readFile(out / "timing.csv").find("write_labels_ms"), std::string::npos);
  // the same masks from a second run on one llvmpipe thread, and --labels before the scenario
  const fs::path again = tempOut("labels_again");
  const std::string cmd = std::string("cd ") + ESIM_SOURCE_DIR + " && LP_NUM_THREADS=1 " +
                          ESIM_EXE + " run --labels scenarios/paper_slab.yaml --frames 3 " +
                          kSmall + " -o " + again.string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  const auto hashesAgain = nlohmann::json::parse(readFile(again / "hashes.json"));
  EXPECT_EQ(hashesAgain["all_masks_xxh3"], hashes["all_masks_xxh3"]);
  for (int f = 0; f < frames; ++f)
    EXPECT_EQ(hashesAgain["frames"][f]["depth_xxh3"], hashes["frames"][f]["depth_xxh3"]);
  EXPECT_FALSE(fs::exists(again / "labels" / "preview.mp4"));
  fs::remove_all(out);
  fs::remove_all(again);
}

// --labels without a value, before another option or last (the empty-value check refused
// both with "--labels: an empty value", exit 2)
TEST(RunCli, LabelsWithoutAModeBeforeAnotherOptionOrLast) {
  for (const std::string& order : {std::string(" --labels -q -o "), std::string(" -q -o ")}) {
    const fs::path out = tempOut("labels_bare");
    fs::remove_all(out);
    const Result r = esimRun(
        "scenarios/paper_slab.yaml --frames 2 --set look.width=160 --set "
        "look.height=90" +
        order + out.string() + (order == " -q -o " ? " --labels" : ""));
    EXPECT_EQ(r.exitCode, 0) << order << r.output;
    EXPECT_TRUE(fs::exists(out / "labels" / "mask_00001.png")) << order;
    EXPECT_FALSE(fs::exists(out / "labels" / "preview.mp4")) << order;
    fs::remove_all(out);
  }
}

TEST(RunCli, LabelsWithAnUnknownModeExitTwo) {
  const fs::path out = tempOut("labels_bad");
  const Result r =
      esimRun("scenarios/paper_slab.yaml --frames 2 --labels colour -q -o " + out.string());
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--labels: 'colour' is unknown"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".partial"));
}

}  // namespace
