// `esim sweep` and `esim dataset` end to end on this machine: a 4-variant sweep with 2
// workers writes its manifest, resumes without running anything again, `esim dataset
// verify` passes and then catches a changed, a missing and an added file; a failed variant
// is recorded and the others go on; bad sweeps exit 2 with nothing written; --slurm
// without --submit writes the job-array script (no Slurm needed).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>

#include "tests/tools/cli_test_util.h"

namespace {

namespace fs = std::filesystem;
using esim::cli_test::readFile;
using esim::cli_test::Result;
using esim::cli_test::shell;
using nlohmann::json;

Result esim(const std::string& args) { return shell(std::string(ESIM_EXE) + " " + args); }

void writeFile(const fs::path& p, const std::string& text) {
  std::ofstream os(p);
  os << text;
}

std::vector<json> manifest(const fs::path& dir) {
  std::vector<json> lines;
  std::istringstream in(readFile(dir / "manifest.jsonl"));
  for (std::string line; std::getline(in, line);) lines.push_back(json::parse(line));
  return lines;
}

fs::path tempDir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("esim_sweep_test_" + name);
  fs::remove_all(p);
  return p;
}

const std::string kTiny = "scenarios/sweeps/paper_slab_tiny_4.yaml";

// a sweep file over the paper's 506-node slab, 0.1 s at 160 x 90, with more `set:` lines and
// its grid in `more`
void writeTinySpec(const fs::path& spec, const std::string& more) {
  writeFile(spec, std::string("base: ") + ESIM_SOURCE_DIR +
                      "/scenarios/paper_slab_506.yaml\n"
                      "set:\n"
                      "  time.duration_s: 0.1\n"
                      "  look.width: 160\n"
                      "  look.height: 90\n" +
                      more);
}

TEST(SweepCli, LocalSweepRecordsResumesAndVerifies) {
  const fs::path dir = tempDir("local");
  const Result r = esim("sweep " + kTiny + " -o " + dir.string() + " --workers 2");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("4 variants: 4 complete"), std::string::npos) << r.output;
  const auto lines = manifest(dir);
  ASSERT_EQ(lines.size(), 4u);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const json& l = lines[i];
    const std::string id = l["id"];
    EXPECT_EQ(l["index"], i);
    EXPECT_EQ(l["status"], "complete") << l.dump();
    EXPECT_EQ(l["frames"], 15);
    EXPECT_GT(l["wall_s"].get<double>(), 0.0);
    EXPECT_TRUE(l["values"].contains("tool.voltage_v"));
    EXPECT_TRUE(l["values"].contains("camera.eye_m"));
    EXPECT_TRUE(l["labels_xxh3"].is_null()) << "no run option asked for labels";
    EXPECT_TRUE(l["warnings"].is_array());
    EXPECT_GT(l["cpu_s"].get<double>(), 0.0);
    const std::string video = "runs/" + id + "/run/video.mp4";
    EXPECT_EQ(l["video"], video);
    EXPECT_EQ(l["video_xxh3"], l["files"][video]);
    EXPECT_TRUE(l["files"].contains("runs/" + id + "/scenario.yaml"));
    EXPECT_TRUE(l["files"].contains("runs/" + id + "/run/hashes.json"));
    EXPECT_EQ(l["frames_xxh3"],
              json::parse(readFile(dir / "runs" / id / "run" / "hashes.json"))["all_frames_xxh3"]);
    EXPECT_TRUE(fs::exists(dir / "runs" / id / "log.txt"));
    // two runs at once each bound themselves to half the memory (memory_room.h); not under
    // the sanitizers, where esim sets no bound
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
    const json timing = json::parse(readFile(dir / "runs" / id / "run" / "timing.json"));
    const std::string bound = timing["machine"].value("memory_bound", "");
    if (!bound.empty()) {  // (empty where a lower ulimit -v was set already)
      EXPECT_NE(bound.find("; one of 2 sweep workers, "), std::string::npos) << bound;
    }
#endif
  }
  EXPECT_EQ(lines[0]["values"]["tool.voltage_v"], 60);
  EXPECT_EQ(lines[3]["values"]["tool.voltage_v"], 80);
  EXPECT_NE(lines[0]["video_xxh3"], lines[1]["video_xxh3"]) << "the draws differ";
  EXPECT_EQ(readFile(dir / "sweep.yaml"), readFile(fs::path(ESIM_SOURCE_DIR) / kTiny));

  // resumed: nothing runs again, the manifest is the same
  const std::string before = readFile(dir / "manifest.jsonl");
  const Result again = esim("sweep " + kTiny + " -o " + dir.string() + " --workers 2");
  ASSERT_EQ(again.exitCode, 0) << again.output;
  EXPECT_NE(again.output.find("4 complete before, 0 to run"), std::string::npos) << again.output;
  EXPECT_EQ(readFile(dir / "manifest.jsonl"), before);

  // verify: all match; then a changed, a missing and an added file are each caught
  const Result ok = esim("dataset verify " + dir.string());
  EXPECT_EQ(ok.exitCode, 0) << ok.output;
  EXPECT_NE(ok.output.find("all match the manifest"), std::string::npos) << ok.output;
  {
    std::ofstream os(dir / "runs/v0002/run/video.mp4", std::ios::binary | std::ios::in);
    os.seekp(100);
    os.put('\x5a');
  }
  const Result changed = esim("dataset verify " + dir.string());
  EXPECT_EQ(changed.exitCode, 3) << changed.output;
  EXPECT_NE(changed.output.find("runs/v0002/run/video.mp4: changed"), std::string::npos)
      << changed.output;
  fs::remove(dir / "runs/v0001/run/timing.csv");
  writeFile(dir / "runs/v0003/run/notes.txt", "added\n");
  writeFile(dir / "runs/v0000/frame_0.png", "added next to run/\n");
  fs::create_directories(dir / "runs/v0009/run");
  writeFile(dir / "runs/v0009/run/video.mp4", "a variant the sweep never had\n");
  writeFile(dir / "runs/notes.txt", "added beside the variants\n");
  const Result more = esim("dataset verify " + dir.string());
  EXPECT_EQ(more.exitCode, 3) << more.output;
  EXPECT_NE(more.output.find("runs/v0001/run/timing.csv: missing"), std::string::npos)
      << more.output;
  EXPECT_NE(more.output.find("runs/v0003/run/notes.txt: not in the manifest"), std::string::npos)
      << more.output;
  EXPECT_NE(more.output.find("runs/v0000/frame_0.png: not in the manifest"), std::string::npos)
      << more.output;
  EXPECT_NE(more.output.find("runs/v0009: not in the manifest"), std::string::npos) << more.output;
  EXPECT_NE(more.output.find("runs/notes.txt: not in the manifest"), std::string::npos)
      << more.output;
  EXPECT_NE(more.output.find("6 problems"), std::string::npos) << more.output;
  fs::remove_all(dir);
}

// a grid over tool.path_file runs recorded paths: each variant's scenario.yaml names its CSV
// by absolute path (the variant runs on its own, from any folder), and the two paths give
// two different runs
TEST(SweepCli, AGridOverToolPathFilesRunsEachPath) {
  const fs::path dir = tempDir("path_files");
  const fs::path in = tempDir("path_files_in");
  fs::create_directories(in);
  writeFile(in / "left.csv", "t_s,x_m,y_m,z_m\n0,-0.02,0,0.0098\n0.5,-0.01,0,0.0098\n");
  writeFile(in / "right.csv", "t_s,x_m,y_m,z_m\n0,0.02,0,0.0098\n0.5,0.01,0,0.0098\n");
  writeFile(in / "base.yaml",
            "time: {duration_s: 0.2}\nlook: {width: 160, height: 90, msaa: 0}\ntool:\n"
            "  path_file: left.csv\n");
  writeFile(in / "sweep.yaml",
            "name: paths\nbase: base.yaml\ngrid:\n  tool.path_file: [left.csv, right.csv]\n");
  const Result r =
      esim("sweep " + (in / "sweep.yaml").string() + " -o " + dir.string() + " --workers 2");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const auto lines = manifest(dir);
  ASSERT_EQ(lines.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    const std::string yaml =
        readFile(dir / "runs" / lines[i]["id"].get<std::string>() / "scenario.yaml");
    const std::string want = (in / (i == 0 ? "left.csv" : "right.csv")).string();
    EXPECT_NE(yaml.find("path_file: \"" + want + "\""), std::string::npos) << yaml;
    EXPECT_EQ(yaml.find("t_s:"), std::string::npos) << "the keyframes stay in the file";
    EXPECT_EQ(lines[i]["status"], "complete");
  }
  EXPECT_NE(lines[0]["frames_xxh3"], lines[1]["frames_xxh3"]) << "the two paths drew alike";
  fs::remove_all(dir);
  fs::remove_all(in);
}

// an edited manifest is reported line by line (exit 3), never an internal error: a line that
// was a number, a status that was a number, or files that were a list ended in a JSON type
// error (exit 4); a repeated id, a hash that is not a string and a path outside the variant's
// folder are named as what they are
TEST(SweepCli, AnEditedManifestIsReportedLineByLine) {
  const fs::path dir = tempDir("edited_manifest");
  const Result r = esim("sweep " + kTiny + " -o " + dir.string() + " --workers 2");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const std::string manifest = readFile(dir / "manifest.jsonl");
  std::vector<json> lines;
  std::istringstream in(manifest);
  for (std::string text; std::getline(in, text);) lines.push_back(json::parse(text));
  ASSERT_EQ(lines.size(), 4u);
  json second = lines[1];
  second["files"]["runs/v0001/run/hashes.json"] = 5;
  json third = lines[2];
  third["files"]["../../../etc/passwd"] = "0000000000000000";
  std::string text = lines[0].dump() + "\n" + second.dump() + "\n" + third.dump() + "\n" +
                     lines[3].dump() + "\n" + lines[3].dump() + "\n5\n" +
                     R"({"status": 1})"
                     "\n" +
                     R"({"status": "complete", "id": "v0009", "files": [1]})"
                     "\n";
  writeFile(dir / "manifest.jsonl", text);
  const Result v = esim("dataset verify " + dir.string());
  EXPECT_EQ(v.exitCode, 3) << v.output;
  for (const char* part :
       {"manifest.jsonl:2: files[\"runs/v0001/run/hashes.json\"]: expected an xxh3 string, got 5",
        "manifest.jsonl:3: files: '../../../etc/passwd' is outside the variant's folder",
        "manifest.jsonl:5: id v0003 is listed a second time",
        "manifest.jsonl:6: expected a JSON object (a variant), got 5",
        "manifest.jsonl:7: status: expected a string",
        "manifest.jsonl:8: files: expected an object {path: xxh3}, got [1]", "6 problems"})
    EXPECT_NE(v.output.find(part), std::string::npos) << part << "\n" << v.output;
  EXPECT_EQ(v.output.find("runs/v0001/run/hashes.json: not in the manifest"), std::string::npos)
      << "a file listed with a malformed hash is not also 'added after the run'\n"
      << v.output;
  fs::remove_all(dir);
}

// an edited sweep.json is refused at its field (exit 2) by every command that reads it, and
// nothing is written: an id "../../x" led `esim dataset run` to make and run a variant
// outside the sweep's folder; a list of variants that was a number, an id missing, a run
// option that was a number were internal errors (exit 4). A result.json of the wrong shape
// counts as not run (a status that was a number was an internal error too).
TEST(SweepCli, AnEditedSweepJsonIsRefusedAtItsField) {
  const fs::path dir = tempDir("edited_sweep_json");
  const Result r = esim("sweep " + kTiny + " -o " + dir.string() + " --workers 2");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const json original = json::parse(readFile(dir / "sweep.json"));
  const std::string outside = (dir.parent_path() / "x").string();
  fs::remove_all(outside);
  using Edit = std::function<void(json&)>;
  for (const auto& [edit, message] : std::vector<std::pair<Edit, std::string>>{
           {[](json& j) { j["variants"][1]["id"] = "../../x"; },
            "sweep.json: variants[1].id = \"../../x\"; expected \"v0001\" (sweep.json is esim "
            "sweep's record: an edited or foreign file)"},
           {[](json& j) { j["variants"][1].erase("id"); }, "variants[1].id = (missing)"},
           {[](json& j) { j["variants"][2]["index"] = "q"; }, "variants[2].index: expected 2"},
           {[](json& j) { j["variants"][1]["values"] = 5; }, "variants[1].values: expected"},
           {[](json& j) { j["variants"] = 5; }, "variants: expected a list of {id, index"},
           {[](json& j) { j["run_options"] = {5}; }, "run_options: expected a list of strings"},
           {[](json& j) { j = json::array(); }, "sweep.json: expected a JSON object"}}) {
    json j = original;
    edit(j);
    writeFile(dir / "sweep.json", j.dump(2));
    for (const std::string& command :
         {"dataset run " + dir.string() + " 1", "sweep " + kTiny + " -o " + dir.string()}) {
      const Result bad = esim(command);
      EXPECT_EQ(bad.exitCode, 2) << command << "\n" << bad.output;
      EXPECT_NE(bad.output.find(message), std::string::npos) << message << "\n" << bad.output;
    }
    EXPECT_FALSE(fs::exists(outside)) << "a variant was made outside the sweep";
  }
  writeFile(dir / "sweep.json", original.dump(2));
  // a malformed result.json: the variant is run again, its result written anew
  writeFile(dir / "runs/v0001/result.json", R"({"status": 5, "files": [1]})");
  const Result again = esim("dataset run " + dir.string() + " v0001");
  EXPECT_EQ(again.exitCode, 0) << again.output;
  EXPECT_NE(again.output.find("v0001: complete"), std::string::npos) << again.output;
  EXPECT_EQ(json::parse(readFile(dir / "runs/v0001/result.json"))["status"], "complete");
  EXPECT_EQ(esim("dataset verify " + dir.string()).exitCode, 0);
  fs::remove_all(dir);
}

// run_options: [--labels], the option without a value last on each run's command line:
// every variant failed with "--labels: an empty value" (exit 2 from esim run)
TEST(SweepCli, RunOptionsLabelsWithoutAModeLabelEveryVariant) {
  const fs::path dir = tempDir("labels");
  const fs::path spec = fs::temp_directory_path() / "esim_sweep_test_labels.yaml";
  writeFile(spec, "name: labels\nbase: " + std::string(ESIM_SOURCE_DIR) +
                      "/scenarios/paper_slab_506.yaml\nrun_options: [--labels]\nset:\n  "
                      "time.duration_s: 0.1\n  look.width: 160\n  look.height: 90\ngrid:\n  "
                      "tool.voltage_v: [60, 80]\n");
  const Result r = esim("sweep " + spec.string() + " -o " + dir.string() + " --workers 1");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("this run: 2 videos in "), std::string::npos) << r.output;
  const auto lines = manifest(dir);
  ASSERT_EQ(lines.size(), 2u);
  for (const json& l : lines) {
    EXPECT_EQ(l["status"], "complete") << l.dump();
    EXPECT_TRUE(l["labels_xxh3"].is_string()) << l.dump();
    EXPECT_TRUE(fs::exists(dir / "runs" / l["id"].get<std::string>() / "run" / "labels"))
        << l.dump();
  }
  // the same without videos: the throughput line counts runs ("2 videos" before)
  const fs::path bare = tempDir("labels_no_video");
  const Result nv = esim("sweep " + spec.string() + " -o " + bare.string() +
                         " --workers 1 --run-args --no-video");
  ASSERT_EQ(nv.exitCode, 0) << nv.output;
  EXPECT_NE(nv.output.find("this run: 2 runs in "), std::string::npos) << nv.output;
  EXPECT_NE(nv.output.find(" CPU s a run ("), std::string::npos) << nv.output;
  fs::remove_all(dir);
  fs::remove_all(bare);
  fs::remove(spec);
}

// two sweeps started together into one folder: one runs it, the other is refused (exit 2)
// with nothing run; every variant complete (both used to run the same variants, leaving
// variants marked failed that the other had completed, or a misleading "holds other files")
TEST(SweepCli, TwoSweepsIntoOneFolderAtOnceOneIsRefused) {
  const fs::path dir = tempDir("twice");
  const std::string sweep = std::string(ESIM_EXE) + " sweep " + kTiny + " -o " + dir.string();
  const Result r = shell("(" + sweep + "; echo \"exit=$?\") & (sleep 0.2; " + sweep +
                         "; echo \"exit=$?\") & wait");
  EXPECT_NE(r.output.find("exit=0"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("exit=2"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("another esim sweep is running in this folder"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find(" failed: "), std::string::npos) << r.output;  // a variant
  const auto lines = manifest(dir);
  ASSERT_EQ(lines.size(), 4u);
  for (const json& l : lines) EXPECT_EQ(l["status"], "complete") << l.dump();
  EXPECT_EQ(esim("dataset verify " + dir.string()).exitCode, 0);
  // once it ended, the folder is resumed as before
  const Result again = esim("sweep " + kTiny + " -o " + dir.string());
  EXPECT_EQ(again.exitCode, 0) << again.output;
  EXPECT_NE(again.output.find("4 complete before, 0 to run"), std::string::npos) << again.output;
  fs::remove_all(dir);
}

// One variant run by two processes at once (esim dataset run by hand beside a Slurm task
// or a local sweep): each deleted the other's run folder and the manifest kept the last to
// end (a failure over a complete run). The variant's folder is held while it runs: here
// held by the test, dataset run is refused (exit 2) and a sweep leaves the variant alone.
TEST(SweepCli, AVariantAnotherProcessRunsIsLeftToIt) {
  const fs::path dir = tempDir("busy");
  // the folder, v0000 run to measure the scene (no Slurm needed)
  ASSERT_EQ(esim("sweep " + kTiny + " -o " + dir.string() + " --slurm").exitCode, 0);
  const fs::path held = dir / "runs" / "v0001";
  const int fd = ::open(held.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
  const std::string before = readFile(dir / "manifest.jsonl");
  Result r = esim("dataset run " + dir.string() + " v0001");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("esim: error: " + held.string() +
                          ": another esim is running this variant; nothing was changed"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(held / "result.json"));
  EXPECT_FALSE(fs::exists(held / "log.txt"));
  EXPECT_EQ(readFile(dir / "manifest.jsonl"), before);
  // a local sweep runs the others and says which it left
  r = esim("sweep " + kTiny + " -o " + dir.string() + " -q");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("sweep: v0001: another esim was running this variant"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(held / "result.json"));
  for (const json& l : manifest(dir))
    EXPECT_EQ(l["status"], l["id"] == "v0001" ? "pending" : "complete") << l.dump();
  ::close(fd);
  r = esim("sweep " + kTiny + " -o " + dir.string() + " -q");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  for (const json& l : manifest(dir)) EXPECT_EQ(l["status"], "complete") << l.dump();
  EXPECT_EQ(esim("dataset verify " + dir.string()).exitCode, 0);
  fs::remove_all(dir);
}

TEST(SweepCli, AFailedVariantIsRecordedAndTheOthersGoOn) {
  const fs::path dir = tempDir("failed");
  const fs::path spec = tempDir("failed_spec.yaml");
  // pcg capped at 2 iterations cannot reach 1e-12: that variant's first solve fails
  writeTinySpec(spec,
                "  solvers.electric.strategy: pcg\n"
                "  solvers.electric.tolerance: 1.0e-12\n"
                "grid:\n"
                "  solvers.electric.max_iterations: [2, 1000]\n");
  const std::string cmd = "sweep " + spec.string() + " -o " + dir.string() + " --workers 2";
  const Result r = esim(cmd);
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("1 complete, 1 failed"), std::string::npos) << r.output;
  auto lines = manifest(dir);
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[0]["status"], "failed");
  EXPECT_EQ(lines[0]["exit_code"], 1);
  EXPECT_NE(lines[0]["message"].get<std::string>().find("pcg did not converge"), std::string::npos)
      << lines[0].dump();
  EXPECT_FALSE(lines[0].contains("files"));
  EXPECT_EQ(lines[1]["status"], "complete");
  // a failed variant is not run again unless asked
  const Result again = esim(cmd);
  EXPECT_EQ(again.exitCode, 1);
  EXPECT_NE(again.output.find("1 complete before, 0 to run"), std::string::npos) << again.output;
  const Result retry = esim(cmd + " --retry-failed");
  EXPECT_EQ(retry.exitCode, 1);
  EXPECT_NE(retry.output.find("1 complete before, 1 to run"), std::string::npos) << retry.output;
  // verify checks the complete one and says the other was not checked
  const Result v = esim("dataset verify " + dir.string());
  EXPECT_EQ(v.exitCode, 0) << v.output;
  EXPECT_NE(v.output.find("1 not complete (not checked)"), std::string::npos) << v.output;
  fs::remove_all(dir);
  fs::remove(spec);
}

// A variant killed (kill -9, the kernel's out-of-memory killer) writes no timing.json: its
// manifest line takes the frames it had done from the rows it streamed (timing.csv.partial),
// and says them; its run.partial/ keeps a video that plays
TEST(SweepCli, AKilledVariantIsRecordedWithTheFramesItHadDone) {
  const fs::path dir = tempDir("killed");
  const fs::path spec = tempDir("killed_spec.yaml");
  writeTinySpec(spec, "grid:\n  tool.voltage_v: [60]\n");
  const Result r = shell("ESIM_FAULT=kill@2 " + std::string(ESIM_EXE) + " sweep " + spec.string() +
                         " -o " + dir.string() + " --workers 1");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  const auto lines = manifest(dir);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0]["status"], "failed");
  EXPECT_EQ(lines[0]["frames"], 2) << lines[0].dump();  // frame 2 was being drawn
  EXPECT_EQ(lines[0]["message"].get<std::string>().rfind(
                "ended by signal 9 (Killed) after 2 frames: ", 0),
            0u)
      << lines[0].dump();
  EXPECT_TRUE(fs::exists(dir / "runs" / "v0000" / "run.partial" / "video.mp4.partial"));
  fs::remove_all(dir);
  fs::remove(spec);
}

// Two runs at once each have half the memory left (ESIM_MEMORY_SHARE); a variant that stops
// for memory beside another may fit alone, and was recorded failed. Such variants now run
// again one at a time after the others, the manifest saying so (memory_retry: the workers and
// the first run's message). Here a folder standing for "/" leaves 300 MB in its cgroup and
// each run's frame 3 asks for 200 MB more (ESIM_FAULT): 118 MB each beside another, 268 MB
// alone. Asking for 290 MB fails alone too: failed, with the message of the run alone.
TEST(SweepCli, AVariantThatStoppedForMemoryBesideOthersRunsAgainAlone) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizers map terabytes: esim sets no address-space bound under them";
#endif
  const fs::path root = tempDir("memory_root");
  fs::create_directories(root / "proc/self");
  fs::create_directories(root / "sys/fs/cgroup/memory/job");
  writeFile(root / "proc/meminfo", "MemAvailable:   9765625 kB\nSwapFree:       0 kB\n");
  writeFile(root / "proc/self/cgroup", "4:memory:/job\n");
  writeFile(root / "sys/fs/cgroup/memory/job/memory.limit_in_bytes", "1000000000\n");
  writeFile(root / "sys/fs/cgroup/memory/job/memory.usage_in_bytes", "700000000\n");
  const std::string group = (root / "sys/fs/cgroup/memory/job").string();
  const fs::path dir = tempDir("memory_alone");
  const auto sweep = [&](int megabytes, int workers) {
    fs::remove_all(dir);
    return shell("ESIM_MEMORY_ROOT=" + root.string() +
                 " ESIM_FAULT=alloc@3:" + std::to_string(megabytes) + " " + ESIM_EXE + " sweep " +
                 kTiny + " -o " + dir.string() + " --workers " + std::to_string(workers));
  };
  Result r = sweep(200, 2);
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("sweep: 4 variants stopped for memory beside other runs: run again one "
                          "at a time"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("sweep: 4 variants: 4 complete\n"), std::string::npos) << r.output;
  for (const json& l : manifest(dir)) {
    EXPECT_EQ(l["status"], "complete") << l.dump();
    ASSERT_TRUE(l.contains("memory_retry")) << l.dump();
    EXPECT_EQ(l["memory_retry"]["workers"], 2);
    EXPECT_EQ(l["memory_retry"]["message"],
              "frame 3: out of memory (a smaller mesh, or another electric strategy: see "
              "timing.json's electric_memory_mb); a frame may map 118 MB more: its memory cgroup " +
                  group + " has 300 MB left of 1000 MB (this run's share: 1 of 2)");
  }
  EXPECT_EQ(esim("dataset verify " + dir.string()).exitCode, 0);
  // one at a time from the start: nothing to run again
  r = sweep(200, 1);
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.output.find("stopped for memory"), std::string::npos) << r.output;
  for (const json& l : manifest(dir)) EXPECT_FALSE(l.contains("memory_retry")) << l.dump();
  // too much even alone: failed, the message the run alone gave
  r = sweep(290, 2);
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("sweep: 4 variants: 0 complete, 4 failed"), std::string::npos)
      << r.output;
  for (const json& l : manifest(dir)) {
    EXPECT_EQ(l["status"], "failed") << l.dump();
    EXPECT_NE(l["message"].get<std::string>().find("a frame may map 268 MB more"),
              std::string::npos)
        << l.dump();
    EXPECT_TRUE(l.contains("memory_retry")) << l.dump();
  }
  fs::remove_all(dir);
  fs::remove_all(root);
}

// a complete variant may still not be what a dataset wants (here a camera pointed away from
// the tissue: the video is the background alone): its warnings are in its manifest line, and
// the sweep's last lines say which variants have some
TEST(SweepCli, CompleteVariantsWithWarningsAreListedAtTheEnd) {
  const fs::path dir = tempDir("warned");
  const fs::path spec = tempDir("warned_spec.yaml");
  writeTinySpec(spec,
                "grid:\n"
                "  camera.target_m: [[0, 0, 0.005], [0, -1, 0.05]]\n");
  const Result r = esim("sweep " + spec.string() + " -o " + dir.string());
  EXPECT_EQ(r.exitCode, 0) << r.output;
  const std::string blind = "the camera sees none of the tissue (camera.eye_m ";
  EXPECT_NE(r.output.find("sweep: 2 variants: 2 complete\n  1 complete variant has warnings "
                          "(the manifest's \"warnings\"):\n    v0001: " +
                          blind),
            std::string::npos)
      << r.output;
  const auto lines = manifest(dir);
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_TRUE(lines[0]["warnings"].empty()) << lines[0].dump();
  ASSERT_EQ(lines[1]["warnings"].size(), 1u) << lines[1].dump();
  EXPECT_EQ(lines[1]["warnings"][0].get<std::string>().rfind(blind, 0), 0u) << lines[1].dump();
  fs::remove_all(dir);
  fs::remove(spec);
}

// each variant records which esim made it (its run's timing.json "build"); a sweep resumed
// after the code changed holds variants of two builds, which the final report names (a
// dataset from one commit is what a training set wants to say it is)
TEST(SweepCli, VariantsMadeByTwoBuildsOfEsimAreNamedAtTheEnd) {
  const fs::path dir = tempDir("builds");
  const fs::path spec = tempDir("builds_spec.yaml");
  writeTinySpec(spec, "grid:\n  tool.voltage_v: [60, 70]\n");
  const Result r = esim("sweep " + spec.string() + " -o " + dir.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.output.find("builds of esim"), std::string::npos) << r.output;
  for (const json& l : manifest(dir)) {
    const std::string id = l["id"];
    EXPECT_EQ(l["esim_build"],
              json::parse(readFile(dir / "runs" / id / "run" / "timing.json"))["build"]);
    EXPECT_TRUE(l["esim_build"]["commit"].is_string()) << l.dump();
  }
  // v0001 as an earlier commit would have recorded it
  const fs::path result = dir / "runs" / "v0001" / "result.json";
  json edited = json::parse(readFile(result));
  edited["esim_build"]["commit"] = std::string(40, 'a');
  writeFile(result, edited.dump(2));
  const Result again = esim("sweep " + spec.string() + " -o " + dir.string());
  EXPECT_EQ(again.exitCode, 0) << again.output;
  EXPECT_NE(again.output.find("  warning: the complete variants were made by 2 builds of esim "
                              "(the manifest's \"esim_build\"):\n"),
            std::string::npos)
      << again.output;
  EXPECT_NE(again.output.find("    1 by esim "), std::string::npos) << again.output;
  EXPECT_NE(again.output.find("(commit aaaaaaaaaaaa"), std::string::npos) << again.output;
  // verify says it too, and still passes: the files match the manifest
  const Result verify = esim("dataset verify " + dir.string());
  EXPECT_EQ(verify.exitCode, 0) << verify.output;
  EXPECT_NE(verify.output.find("all match the manifest\n  note: the complete variants were made "
                               "by 2 builds of esim"),
            std::string::npos)
      << verify.output;
  fs::remove_all(dir);
  fs::remove(spec);
}

TEST(SweepCli, AnInterruptedSweepStopsItsRunsAndRunsThemAgain) {
  const fs::path dir = tempDir("interrupted");
  const fs::path spec = tempDir("interrupted_spec.yaml");
  // two runs of 3000 frames (minutes), both running when the sweep is interrupted
  writeFile(spec, std::string("base: ") + ESIM_SOURCE_DIR +
                      "/scenarios/paper_slab_506.yaml\n"
                      "set: {time.duration_s: 100, look.width: 160, look.height: 90, "
                      "output.video: false}\n"
                      "grid: {tool.voltage_v: [60, 70]}\n");
  // the sweep in the background, a signal once both runs have their partial folder
  const std::string partial = dir.string() + "/runs/v000";
  const auto sweepThenSignal = [&](const std::string& signal) {
    return shell(std::string(ESIM_EXE) + " sweep " + spec.string() + " -o " + dir.string() +
                 " --workers 2 & pid=$!; for i in $(seq 1200); do [ -d " + partial +
                 "0/run.partial ] && [ -d " + partial +
                 "1/run.partial ] && break; sleep 0.05; done; sleep 1; kill -" + signal +
                 " $pid; wait $pid");
  };
  const Result r = sweepThenSignal("INT");  // Ctrl-C
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("stopping: 2 running variants finish their frame"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("2 interrupted"), std::string::npos) << r.output;
  const auto lines = manifest(dir);
  ASSERT_EQ(lines.size(), 2u);
  for (const auto& l : lines) {
    EXPECT_EQ(l["status"], "interrupted") << l.dump();
    EXPECT_NE(l["message"].get<std::string>().find("interrupted after"), std::string::npos)
        << l.dump();
    EXPECT_LT(l["frames"].get<int>(), 3000);
  }
  EXPECT_TRUE(fs::exists(dir / "runs/v0000/run.partial/timing.json")) << "the frames are kept";
  // an interrupted variant is run again (here interrupted again, by SIGTERM)
  fs::remove_all(dir / "runs/v0000/run.partial");
  fs::remove_all(dir / "runs/v0001/run.partial");
  const Result again = sweepThenSignal("TERM");
  EXPECT_EQ(again.exitCode, 1) << again.output;
  EXPECT_NE(again.output.find("0 complete before, 2 to run"), std::string::npos) << again.output;
  fs::remove_all(dir);
  fs::remove(spec);
}

TEST(SweepCli, BadSweepsExitTwoWithNothingWritten) {
  const fs::path dir = tempDir("bad");
  const fs::path spec = tempDir("bad_spec.yaml");
  writeFile(spec, std::string("base: ") + ESIM_SOURCE_DIR +
                      "/scenarios/paper_slab_506.yaml\n"
                      "grid:\n"
                      "  tool.voltage_v: [60, 20000]\n");
  const Result r = esim("sweep " + spec.string() + " -o " + dir.string());
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find(spec.string() + ":3:24: tool.voltage_v: variant v0001"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir));
  // a folder for the sweep file is named as one
  const Result folder = esim("sweep scenarios/sweeps -o " + dir.string());
  EXPECT_EQ(folder.exitCode, 2) << folder.output;
  EXPECT_NE(folder.output.find("scenarios/sweeps: is a folder; expected a sweep file"),
            std::string::npos)
      << folder.output;
  EXPECT_FALSE(fs::exists(dir));
  // run options are checked with esim run's own definition
  const Result opt = esim("sweep " + kTiny + " -o " + dir.string() + " --run-args=--bogus");
  EXPECT_EQ(opt.exitCode, 2) << opt.output;
  EXPECT_NE(opt.output.find("--run-args: run_options: esim run does not take them"),
            std::string::npos)
      << opt.output;
  EXPECT_FALSE(fs::exists(dir));
  // the sweep's own options, refused as in run_options (with -o, every variant failed on
  // "--out: At Most 1 required but received 2" and the sweep exited 1)
  for (const std::string own : {"-o /tmp/elsewhere", "--out=/tmp/elsewhere", "-o/tmp/elsewhere",
                                "--overwrite", "-q", "--quiet", "--set tool.voltage_v=60"}) {
    const Result o = esim("sweep " + kTiny + " -o " + dir.string() + " --run-args='" + own + "'");
    EXPECT_EQ(o.exitCode, 2) << own << "\n" << o.output;
    EXPECT_NE(o.output.find("--run-args: "), std::string::npos) << own << "\n" << o.output;
    EXPECT_TRUE(o.output.find("is the sweep's to give") != std::string::npos ||
                o.output.find("put the key under set:") != std::string::npos)
        << own << "\n"
        << o.output;
    EXPECT_FALSE(fs::exists(dir)) << own;
  }
  // an option the chosen kind of sweep would ignore is refused
  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"--mem-mb 100", "sweep: --mem-mb is a Slurm option; it goes with --slurm"},
           {"--sbatch-arg=--partition=long",
            "sweep: --sbatch-arg is a Slurm option; it goes with --slurm"},
           {"--slurm --workers 3", "sweep: --workers runs variants on this machine; with --slurm"},
       }) {
    const Result ignored = esim("sweep " + kTiny + " -o " + dir.string() + " " + args);
    EXPECT_EQ(ignored.exitCode, 2) << args << "\n" << ignored.output;
    EXPECT_NE(ignored.output.find(message), std::string::npos) << args << "\n" << ignored.output;
    EXPECT_FALSE(fs::exists(dir)) << args;
  }
  // a folder of other files is refused
  fs::create_directories(dir);
  writeFile(dir / "mine.txt", "x");
  const Result other = esim("sweep " + kTiny + " -o " + dir.string());
  EXPECT_EQ(other.exitCode, 2) << other.output;
  EXPECT_NE(other.output.find("holds other files"), std::string::npos) << other.output;
  EXPECT_EQ(readFile(dir / "mine.txt"), "x");
  fs::remove_all(dir);
  fs::remove(spec);
}

TEST(SweepCli, AFolderOfAnotherSweepIsNotResumed) {
  const fs::path dir = tempDir("changed");
  const fs::path spec = tempDir("changed_spec.yaml");
  const std::string head = std::string("base: ") + ESIM_SOURCE_DIR +
                           "/scenarios/paper_slab_506.yaml\nset: {time.duration_s: 0.1, "
                           "look.width: 160, look.height: 90}\n";
  writeFile(spec, head + "grid: {tool.voltage_v: [60]}\n");
  ASSERT_EQ(esim("sweep " + spec.string() + " -o " + dir.string() + " -q").exitCode, 0);
  writeFile(spec, head + "grid: {tool.voltage_v: [61]}\n");
  const Result r = esim("sweep " + spec.string() + " -o " + dir.string());
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("differs from the variant"), std::string::npos) << r.output;
  fs::remove_all(dir);
  fs::remove(spec);
}

TEST(SweepCli, DryRunListsTheVariants) {
  const Result r = esim("sweep scenarios/sweeps/slab_cut_8.yaml --dry-run");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("8 variants"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("v0007"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("path.angle_deg"), std::string::npos) << r.output;
}

// what would break the Slurm script is refused before anything is written: a line break in
// --sbatch-arg or -o (the rest of the line became a command of the script), an option the
// script sets itself; a sweep name's line break is left out of the job name
TEST(SweepCli, SlurmScriptsTakeNothingThatBreaksThem) {
  const fs::path dir = tempDir("slurm_refused");
  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"--sbatch-arg=\"$(printf '%s\\n%s' --partition=a 'rm -rf x')\"",
            "--sbatch-arg '--partition=a ...' (22 characters): a line break or control "
            "character would end the #SBATCH line; give one option per --sbatch-arg"},
           {"--sbatch-arg=--mem=1G",
            "--sbatch-arg '--mem=1G': --mem is set by esim: give --mem-mb"},
           {"--sbatch-arg=--mem-per-cpu=1G", "--mem-per-cpu is set by esim: give --mem-mb"},
           {"--sbatch-arg=-c4", "--sbatch-arg '-c4': -c is set by esim: give --cpus"},
           {"--sbatch-arg='--time 5'", "--time is set by esim: give --time-min"},
           {"--sbatch-arg=--array=0-1", "--array is set by esim: esim writes the job array"},
           {"--sbatch-arg=-o/tmp/x", "-o is set by esim: esim writes each task's log"},
           {"--sbatch-arg=partition=long", "expected an sbatch option, e.g. --partition=long"}}) {
    const Result r = esim("sweep " + kTiny + " -o " + dir.string() + " --slurm " + args);
    EXPECT_EQ(r.exitCode, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << args << "\n" << r.output;
    EXPECT_FALSE(fs::exists(dir)) << args;
  }
  const Result folder =
      esim("sweep " + kTiny + " -o \"$(printf '%s\\n%s' " + dir.string() + " x)\" --slurm");
  EXPECT_EQ(folder.exitCode, 2) << folder.output;
  EXPECT_NE(folder.output.find("a folder name with a line break or control character cannot go "
                               "into the Slurm script"),
            std::string::npos)
      << folder.output;
  EXPECT_FALSE(fs::exists(dir.string() + "\nx"));
  // a name with a line break (a YAML escape): the job name keeps what a file name may hold
  const fs::path spec = tempDir("slurm_name.yaml");
  writeFile(spec, std::string("name: \"a\\nb c\"\nbase: ") + ESIM_SOURCE_DIR +
                      "/scenarios/paper_slab_506.yaml\nset: {time.duration_s: 0.1, look.width: "
                      "160, look.height: 90}\ngrid: {tool.voltage_v: [60, 70]}\n");
  const Result named = esim("sweep " + spec.string() + " -o " + dir.string() + " --slurm");
  ASSERT_EQ(named.exitCode, 0) << named.output;
  const std::string script = readFile(dir / "slurm" / "sweep.sbatch");
  EXPECT_NE(script.find("#SBATCH --job-name=esim-a_b_c\n#SBATCH --array="), std::string::npos)
      << script;
  fs::remove_all(dir);
  fs::remove(spec);
}

TEST(SweepCli, SlurmWithoutSubmitWritesTheJobArrayScript) {
  const fs::path dir = tempDir("slurm_script");
  const Result r = esim("sweep " + kTiny + " -o " + dir.string() +
                        " --slurm --mem-mb 900 --time-min 7 --max-parallel 2 "
                        "--sbatch-arg=--partition=short");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const std::string script = readFile(dir / "slurm" / "sweep.sbatch");
  for (const char* line :
       {"#SBATCH --array=0-3%2\n", "#SBATCH --mem=900M\n", "#SBATCH --time=7\n",
        "#SBATCH --cpus-per-task=1\n", "#SBATCH --partition=short\n", " dataset run '"})
    EXPECT_NE(script.find(line), std::string::npos) << line << " in\n" << script;
  const auto lines = manifest(dir);
  ASSERT_EQ(lines.size(), 4u);
  for (const auto& l : lines) EXPECT_EQ(l["status"], "pending");
  // a task runs one variant by its index and records it
  const Result one = esim("dataset run " + dir.string() + " 2");
  EXPECT_EQ(one.exitCode, 0) << one.output;
  EXPECT_EQ(manifest(dir)[2]["status"], "complete");
  EXPECT_EQ(manifest(dir)[1]["status"], "pending");
  EXPECT_EQ(esim("dataset run " + dir.string() + " v0002").output, "v0002: already complete\n");
  fs::remove_all(dir);
}

}  // namespace
