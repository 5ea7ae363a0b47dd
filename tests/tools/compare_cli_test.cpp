// `esim compare RUN_A RUN_B [--report DIR]` end to end (tools/esim/cmd_compare.cpp): two
// identical runs and a run at another voltage, every frame kept as PNG. Nothing is ever
// written into either run (a sweep's run would no longer match its manifest: `esim
// compare` used to write RUN_B/compare/ by default); a report folder holds one report (an
// earlier one replaced whole) and a folder holding anything else is refused. Uses
// /tmp/esim_compare_test_<pid>_* folders (ctest runs each test in a process of its own).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "tests/tools/cli_test_util.h"

namespace {

namespace fs = std::filesystem;
using esim::cli_test::readFile;
using esim::cli_test::Result;
using esim::cli_test::shell;
using nlohmann::json;

Result esim(const std::string& args) { return shell(std::string(ESIM_EXE) + " " + args); }

fs::path temp(const std::string& name) {
  const fs::path p =
      fs::temp_directory_path() / ("esim_compare_test_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(p);
  return p;
}

// every path under dir with its size: what "nothing written" compares
std::vector<std::string> listing(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    std::string line = e.path().string();
    line += e.is_regular_file() ? ' ' : '/';
    if (e.is_regular_file()) line += std::to_string(e.file_size());
    out.push_back(line);
  }
  std::sort(out.begin(), out.end());
  return out;
}

int countFiles(const fs::path& dir, const std::string& prefix) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir))
    n += e.path().filename().string().rfind(prefix, 0) == 0;
  return n;
}

// three short runs of paper_slab, every frame as PNG: a, b = a, c at another voltage
class CompareCli : public ::testing::Test {
 protected:
  // `frames` small frames of paper_slab, each as PNG, into temp(name)
  static Result runSlab(const std::string& name, int frames, const std::string& extra = "") {
    return esim("run scenarios/paper_slab.yaml --frames " + std::to_string(frames) +
                " --no-video -q --set look.width=160 --set look.height=90 --set "
                "output.png_every=1 " +
                extra + "-o " + temp(name).string());
  }
  static void SetUpTestSuite() {
    for (const auto& [name, extra] : std::vector<std::pair<std::string, std::string>>{
             {"a", ""}, {"b", ""}, {"c", "--set tool.voltage_v=150 "}}) {
      const Result r = runSlab(name, 4, extra);
      ASSERT_EQ(r.exitCode, 0) << r.output;
    }
  }
  static void TearDownTestSuite() {
    for (const char* name : {"a", "b", "c"}) fs::remove_all(temp(name));
  }
  static fs::path run(const char* name) {
    return fs::temp_directory_path() /
           ("esim_compare_test_" + std::to_string(::getpid()) + "_" + name);
  }
  const fs::path a_ = run("a"), b_ = run("b"), c_ = run("c");
};

TEST_F(CompareCli, WritesNothingIntoEitherRun) {
  const auto beforeA = listing(a_), beforeB = listing(b_), beforeC = listing(c_);
  const Result same = esim("compare " + a_.string() + " " + b_.string());
  EXPECT_EQ(same.exitCode, 0) << same.output;
  EXPECT_NE(same.output.find("identical (every frame hash equal)"), std::string::npos)
      << same.output;
  const Result differ = esim("compare " + a_.string() + " " + c_.string());
  EXPECT_EQ(differ.exitCode, 3) << differ.output;
  EXPECT_NE(differ.output.find("differing     4 frames"), std::string::npos) << differ.output;
  EXPECT_NE(differ.output.find("report        none (--report DIR"), std::string::npos)
      << differ.output;
  EXPECT_EQ(listing(a_), beforeA);
  EXPECT_EQ(listing(b_), beforeB);
  EXPECT_EQ(listing(c_), beforeC) << "the run checked gained a compare/ folder";
}

// runs of different lengths are a mismatch that says why (it said "differing 0 frames",
// "MISMATCH" and nothing more)
TEST_F(CompareCli, RunsOfDifferentLengthsSayWhyTheyDiffer) {
  const Result r = runSlab("shorter", 3);
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const fs::path shorter = run("shorter");
  const Result differ = esim("compare " + a_.string() + " " + shorter.string());
  EXPECT_EQ(differ.exitCode, 3) << differ.output;
  EXPECT_NE(differ.output.find("result        MISMATCH (the runs have 4 and 3 frames; the 3 "
                               "frames of both are identical)"),
            std::string::npos)
      << differ.output;
  fs::remove_all(shorter);
}

// frames without a PNG in both runs cannot be compared within a tolerance: the result says
// so (it said MISMATCH, and "set output.png_every" on frames of runs that had set it)
TEST_F(CompareCli, FramesWithoutAPngAreNamedAsTheMismatch) {
  for (const char* name : {"every2a", "every2b"}) {
    const Result r =
        esim(std::string("run scenarios/paper_slab.yaml --frames 4 --no-video -q "
                         "--set look.width=160 --set look.height=90 --set "
                         "output.png_every=2 ") +
             (name[6] == 'b' ? "--set tool.voltage_v=74 " : "") + "-o " + temp(name).string());
    ASSERT_EQ(r.exitCode, 0) << r.output;
  }
  const Result r = esim("compare " + run("every2a").string() + " " + run("every2b").string());
  EXPECT_EQ(r.exitCode, 3) << r.output;
  EXPECT_NE(r.output.find("frame 1: dhash 0 bits (no PNG of this frame in both runs: no "
                          "tolerant comparison)"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("result        MISMATCH (2 differing frames without a PNG in both "
                          "runs, so not comparable within a tolerance; output.png_every: 1 "
                          "writes every frame's)"),
            std::string::npos)
      << r.output;
  fs::remove_all(run("every2a"));
  fs::remove_all(run("every2b"));
}

TEST_F(CompareCli, AReportFolderHoldsOneReportAndAnEarlierOneIsReplaced) {
  const fs::path report = temp("report");
  const Result differ =
      esim("compare " + a_.string() + " " + c_.string() + " --report " + report.string());
  EXPECT_EQ(differ.exitCode, 3) << differ.output;
  ASSERT_TRUE(fs::exists(report / "compare.json")) << differ.output;
  auto json = nlohmann::json::parse(readFile(report / "compare.json"));
  EXPECT_FALSE(json["identical"].get<bool>());
  ASSERT_EQ(json["differing_frames"].size(), 4u);
  for (const auto& f : json["differing_frames"]) {
    EXPECT_FALSE(f["within_tolerance"].get<bool>()) << f.dump();  // 150 V against 72 V
    EXPECT_GT(f["max_diff"].get<int>(), 16) << f.dump();
  }
  EXPECT_EQ(countFiles(report, "diff_frame_"), 4);
  // the same folder again, for two identical runs: the earlier diffs go with their report
  const Result same =
      esim("compare " + a_.string() + " " + b_.string() + " --report " + report.string());
  EXPECT_EQ(same.exitCode, 0) << same.output;
  json = nlohmann::json::parse(readFile(report / "compare.json"));
  EXPECT_TRUE(json["identical"].get<bool>());
  EXPECT_EQ(countFiles(report, "diff_frame_"), 0) << "a stale diff of the earlier report";
  EXPECT_EQ(countFiles(report, ""), 1);
  fs::remove_all(report);
}

TEST_F(CompareCli, AReportFolderHoldingOtherFilesIsRefusedUntouched) {
  const fs::path report = temp("busy");
  fs::create_directories(report);
  std::ofstream(report / "notes.txt") << "mine\n";
  std::ofstream(report / "compare.json") << "{}\n";
  const Result r =
      esim("compare " + a_.string() + " " + c_.string() + " --report " + report.string());
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--report: '" + report.string() + "' holds 'notes.txt'"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(readFile(report / "notes.txt"), "mine\n");
  EXPECT_EQ(readFile(report / "compare.json"), "{}\n") << "nothing changed when refused";
  EXPECT_EQ(countFiles(report, ""), 2);
  // a run folder as the report folder is one such
  const auto beforeC = listing(c_);
  const Result intoRun =
      esim("compare " + a_.string() + " " + c_.string() + " --report " + c_.string());
  EXPECT_EQ(intoRun.exitCode, 2) << intoRun.output;
  EXPECT_EQ(listing(c_), beforeC);
  // a file
  const Result file = esim("compare " + a_.string() + " " + c_.string() + " --report " +
                           (report / "notes.txt").string());
  EXPECT_EQ(file.exitCode, 2) << file.output;
  EXPECT_NE(file.output.find("is a file; expected a folder"), std::string::npos) << file.output;
  fs::remove_all(report);
}

// an edited or foreign hashes.json is refused at its field (exit 2), nothing compared: a
// dhash that was not hex ended in "internal error: stoull" (exit 4), a frame that was not an
// object in a JSON type error (exit 4), and frames numbered out of order (7, a repeated 0,
// -1) were compared by position and called identical
TEST_F(CompareCli, AnEditedHashesFileIsRefusedAtItsField) {
  const fs::path edited = temp("edited");
  fs::create_directories(edited);
  const auto original = nlohmann::json::parse(readFile(b_ / "hashes.json"));
  using Edit = std::function<void(nlohmann::json&)>;
  for (const auto& [edit, message] : std::vector<std::pair<Edit, std::string>>{
           {[](auto& j) { j["frames"][1]["frame"] = 7; },
            "hashes.json: frames[1].frame = 7; expected 1 (every frame, in order from 0)"},
           {[](auto& j) { j["frames"][1]["frame"] = 0; }, "frames[1].frame = 0; expected 1"},
           {[](auto& j) { j["frames"][2]["frame"] = 1e30; }, "frames[2].frame = 1e+30"},
           {[](auto& j) { j["frames"][1]["dhash"] = "xyz"; },
            "frames[1].dhash: expected 16 hexadecimal digits, got \"xyz\""},
           {[](auto& j) { j["frames"][0].erase("xxh3"); }, "frames[0].xxh3: expected 16"},
           {[](auto& j) { j["frames"][2] = 5; },
            "frames[2]: expected an object {frame, xxh3, dhash}, got 5"},
           {[](auto& j) { j["frames"] = nlohmann::json::object(); },
            "frames: expected a list of {frame, xxh3, dhash}"},
           {[](auto& j) { j["width"] = -5; },
            "width = -5; expected the frame's size in pixels, an integer in [1, 65536]"},
           {[](auto& j) { j.erase("height"); }, "height = (missing); expected"},
           {[](auto& j) { j = nlohmann::json::array(); }, "expected a JSON object"},
           // a value is shown short: a list of 100 000 entries was dumped whole (200 kB)
           {[](auto& j) { j["frames"][2] = std::vector<int>(100000, 7); },
            "frames[2]: expected an object {frame, xxh3, dhash}, got '[7,7,7,7,7,7,7,7,7,7,7,7,7,7,"
            "7,7,7,7,7,7,7,7,7,7,7,7,7,7,7,7 ...' (200001 characters)"}}) {
    nlohmann::json j = original;
    edit(j);
    std::ofstream(edited / "hashes.json") << j.dump(2);
    for (const auto& [first, second] : {std::pair{b_, edited}, std::pair{edited, b_}}) {
      const Result r = esim("compare " + first.string() + " " + second.string());
      EXPECT_EQ(r.exitCode, 2) << message << "\n" << r.output;
      EXPECT_NE(r.output.find((edited / "hashes.json").string() + ": "), std::string::npos)
          << r.output;
      EXPECT_NE(r.output.find(message), std::string::npos) << r.output;
    }
  }
  // bytes that are not text are written \\xNN in the JSON parser's message (it quotes what it
  // read last)
  std::ofstream(edited / "hashes.json", std::ios::binary) << "{\"frames\": [\x85\x01]}";
  const Result r = esim("compare " + b_.string() + " " + edited.string());
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("hashes.json: not valid JSON: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("last read: '\"frames\": [\\x85'"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find('\x85'), std::string::npos) << r.output;
  fs::remove_all(edited);
}

// what differs in the inputs is said: the scenario (another voltage) or, the scenario the
// same, the content of a file it names (a tool path CSV edited between two runs: its name,
// and so the scenario's hash, unchanged)
TEST_F(CompareCli, DifferentInputsAreNamed) {
  const Result same = esim("compare " + a_.string() + " " + b_.string());
  EXPECT_NE(same.output.find("inputs        same"), std::string::npos) << same.output;
  const Result voltage = esim("compare " + a_.string() + " " + c_.string());
  EXPECT_NE(voltage.output.find("inputs        DIFFERENT: the scenario (hash "), std::string::npos)
      << voltage.output;
  const fs::path dir = temp("inputs");
  fs::create_directories(dir);
  const auto runWith = [&](const std::string& csv, const std::string& name) {
    std::ofstream(dir / "path.csv") << csv;
    std::ofstream(dir / "s.yaml")
        << "tool: {path_file: path.csv}\nlook: {width: 160, height: 90}\n";
    return esim("run " + (dir / "s.yaml").string() + " --frames 2 -q -o " + (dir / name).string());
  };
  ASSERT_EQ(runWith("t_s,x_m,y_m,z_m\n0,0,0,0.0098\n", "one").exitCode, 0);
  ASSERT_EQ(runWith("t_s,x_m,y_m,z_m\n0,0.001,0,0.0098\n", "two").exitCode, 0);
  const Result edited = esim("compare " + (dir / "one").string() + " " + (dir / "two").string());
  EXPECT_NE(edited.output.find("inputs        DIFFERENT: tool.path_file's content"),
            std::string::npos)
      << edited.output;
  EXPECT_EQ(edited.output.find("the scenario (hash"), std::string::npos) << edited.output;
  fs::remove_all(dir);
}

// which esim made each run: hashes.json's esim_build, this binary's in both (its commit); a
// run made by another commit, or by an esim from before builds were recorded, is named
// DIFFERENT (a regression's first question: which code made the frames). Equal frames
// still exit 0: the build is information, not a mismatch
TEST_F(CompareCli, TheEsimBuildOfEachRunIsCompared) {
  const json build = json::parse(readFile(a_ / "hashes.json"))["esim_build"];
  ASSERT_TRUE(build.is_object());
  const json timing = json::parse(readFile(a_ / "timing.json"))["build"];
  EXPECT_EQ(build, timing) << "hashes.json's esim_build is timing.json's build";
  const Result same = esim("compare " + a_.string() + " " + b_.string());
  EXPECT_NE(same.output.find("esim build    same: esim " + build["esim"].get<std::string>() +
                             " (commit "),
            std::string::npos)
      << same.output;
  // esim --version prints the line compare shows (this binary made both runs)
  const Result version = esim("--version");
  EXPECT_EQ(version.exitCode, 0) << version.output;
  const std::string line = version.output.substr(0, version.output.find('\n'));
  EXPECT_NE(same.output.find("esim build    same: " + line + "\n"), std::string::npos)
      << version.output << same.output;

  const fs::path other = temp("other_build");
  fs::copy(b_, other, fs::copy_options::recursive);
  json hashes = json::parse(readFile(other / "hashes.json"));
  hashes["esim_build"]["commit"] = std::string(40, '0');
  std::ofstream(other / "hashes.json") << hashes.dump(2);
  const Result differ = esim("compare " + a_.string() + " " + other.string());
  EXPECT_EQ(differ.exitCode, 0) << differ.output;
  EXPECT_NE(differ.output.find("esim build    DIFFERENT: esim "), std::string::npos)
      << differ.output;
  EXPECT_NE(
      differ.output.find(" vs esim " + build["esim"].get<std::string>() + " (commit 000000000000"),
      std::string::npos)
      << differ.output;
  EXPECT_NE(differ.output.find("identical (every frame hash equal)"), std::string::npos);
  hashes.erase("esim_build");
  std::ofstream(other / "hashes.json") << hashes.dump(2);
  const Result old = esim("compare " + a_.string() + " " + other.string());
  EXPECT_NE(old.output.find("esim build    DIFFERENT: run B does not say which esim made it"),
            std::string::npos)
      << old.output;
  fs::remove_all(other);
}

TEST_F(CompareCli, AMissingRunIsNamed) {
  const Result r = esim("compare " + a_.string() + " /nonexistent/run");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("/nonexistent/run/hashes.json: not found"), std::string::npos)
      << r.output;
}

}  // namespace
