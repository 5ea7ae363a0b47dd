// `esim run --plots` and `esim plot RUN_DIR` end to end: a real run's timing reports are
// consistent (tests/app/timing_reports_check.h), timing.png is written when matplotlib is
// there, and a missing python3 or matplotlib is a warning that leaves the run's exit status
// alone. Uses fixed /tmp/esim_run_test_plot_* folders (run under flock /tmp/esim_cli.lock
// next to run_cli_test).
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "tests/app/timing_reports_check.h"
#include "tests/tools/cli_test_util.h"

namespace {

namespace fs = std::filesystem;
using esim::cli_test::readFile;
using esim::cli_test::Result;
using esim::cli_test::shell;

Result esim(const std::string& args, const std::string& env = "") {
  return shell(env + (env.empty() ? "" : " ") + ESIM_EXE + " " + args);
}

fs::path tempOut(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("esim_run_test_plot_" + name);
  fs::remove_all(p);
  fs::remove_all(p.string() + ".partial");
  return p;
}

// the python the plots use (tools/app/plot_script.h) has matplotlib
bool haveMatplotlib() {
  return shell("/usr/bin/python3 -c 'import matplotlib' >/dev/null").exitCode == 0;
}

bool isPng(const fs::path& p) {
  const std::string head = readFile(p).substr(0, 8);
  return head == std::string("\x89PNG\r\n\x1a\n", 8);
}

void checkReports(const fs::path& dir) {
  esim::test::checkTimingReports(readFile(dir / "timing.csv"),
                                 nlohmann::json::parse(readFile(dir / "timing.json")),
                                 nlohmann::json::parse(readFile(dir / "trace.json")));
}

// the paper's slab, rendered: every stage of a rendered scene; timing.png next to the reports
TEST(PlotCli, RunWithPlotsWritesTimingPng) {
  const fs::path out = tempOut("paper");
  const Result r = esim(
      "run scenarios/paper_slab.yaml --frames 12 --no-video --set look.width=160 "
      "--set look.height=90 -q --plots -o " +
      out.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  checkReports(out);
  const auto timing = nlohmann::json::parse(readFile(out / "timing.json"));
  EXPECT_EQ(timing["physics"], nlohmann::json({"electric", "thermal", "boiling"}));
  EXPECT_TRUE(timing["stages"].contains("render"));
  if (!haveMatplotlib()) GTEST_SKIP() << "no matplotlib for /usr/bin/python3";
  ASSERT_TRUE(fs::exists(out / "timing.png")) << r.output;
  EXPECT_TRUE(isPng(out / "timing.png"));
  EXPECT_GT(fs::file_size(out / "timing.png"), 20000u);  // three panels drawn, not a blank
  EXPECT_NE(r.output.find("timing.png"), std::string::npos) << r.output;  // in the summary
  fs::remove_all(out);
}

// the cut with a background rebuild: rebuild waits and removed tets in timing.csv; then
// `esim plot` redraws the existing folder
TEST(PlotCli, CutReportsAndEsimPlot) {
  const fs::path out = tempOut("cut");
  const Result r = esim(
      "run scenarios/slab_cut.yaml --set mesh.slab.nodes=1013 --frames 20 --no-video "
      "--set output.hashes=false -q -o " +
      out.string());
  ASSERT_EQ(r.exitCode, 0) << r.output;
  checkReports(out);
  const std::string csv = readFile(out / "timing.csv");
  const auto rows = esim::test::parseTimingCsv(csv);
  int removed = 0;
  double waited = 0;
  for (const auto& row : rows) {
    removed += std::atoi(row.at("removed_tets").c_str());
    waited += std::atof(row.at("rebuild_wait_ms").c_str());
  }
  EXPECT_GT(removed, 0) << "the cut removed nothing in 20 frames";
  EXPECT_GE(waited, 0);
  EXPECT_FALSE(fs::exists(out / "timing.png"));  // no --plots
  // -o must name a .png in a folder that exists: refused (exit 2) before python runs, nothing
  // written (matplotlib wrote FOLDER.png for a folder and NAME.png for a name without .png,
  // and a missing folder ended in a traceback)
  const fs::path note = out / "notes";  // a user's file without the extension
  std::ofstream(note) << "user data\n";
  for (const auto& [arg, message] : std::vector<std::pair<std::string, std::string>>{
           {out.string(), "is a folder; expected a .png file name"},
           {note.string(), "must end in .png"},
           {(out / "missing" / "t.png").string(), "' does not exist"}}) {
    const Result bad = esim("plot " + out.string() + " -o " + arg);
    EXPECT_EQ(bad.exitCode, 2) << arg << "\n" << bad.output;
    EXPECT_NE(bad.output.find(message), std::string::npos) << arg << "\n" << bad.output;
  }
  EXPECT_EQ(readFile(note), "user data\n");
  EXPECT_FALSE(fs::exists(note.string() + ".png"));
  EXPECT_FALSE(fs::exists(out.string() + ".png"));
  fs::remove(note);
  // RUN_DIR missing or a file: said so (it said "holds no timing.csv" of a file)
  EXPECT_NE(esim("plot " + out.string() + "/nowhere").output.find("nowhere' does not exist"),
            std::string::npos);
  EXPECT_NE(esim("plot " + (out / "timing.csv").string()).output.find("' is a file; expected"),
            std::string::npos);
  if (!haveMatplotlib()) GTEST_SKIP() << "no matplotlib for /usr/bin/python3";
  // a cut or edited timing.csv or timing.json is refused where it is (exit 2, nothing
  // written): the script drew bad cells as 0 and a cut line as a short frame
  const fs::path edited = tempOut("edited");
  fs::create_directories(edited);
  const std::string header = csv.substr(0, csv.find('\n') + 1);
  const std::string row1 =
      csv.substr(header.size(), csv.find('\n', header.size()) + 1 - header.size());
  for (const auto& [csvText, json, message] :
       std::vector<std::tuple<std::string, std::string, std::string>>{
           {header + row1.substr(0, 12) + "\n", "", "timing.csv:2: 3 fields where the header"},
           {header + "0,abc" + row1.substr(row1.find(',', 2)), "",
            "timing.csv:2: time_s = 'abc' is not a number"},
           {header, "", "timing.csv: no frames"},
           {csv, "{\"budget_ms\": \"x\"}", "timing.json: budget_ms = 'x'; expected a number"},
           {csv, "{\"budget_ms\": ", "timing.json: not readable JSON"}}) {
    std::ofstream(edited / "timing.csv") << csvText;
    fs::remove(edited / "timing.json");
    if (!json.empty()) std::ofstream(edited / "timing.json") << json;
    const Result bad = esim("plot " + edited.string());
    EXPECT_EQ(bad.exitCode, 2) << message << "\n" << bad.output;
    EXPECT_NE(bad.output.find(message), std::string::npos) << bad.output;
    EXPECT_FALSE(fs::exists(edited / "timing.png"));
  }
  fs::remove_all(edited);
  const Result p = esim("plot " + out.string());
  ASSERT_EQ(p.exitCode, 0) << p.output;
  EXPECT_TRUE(isPng(out / "timing.png"));
  const fs::path other = out.string() + "_other.png";
  ASSERT_EQ(esim("plot " + out.string() + " -o " + other.string()).exitCode, 0);
  EXPECT_TRUE(isPng(other));
  // the script's temporary PNGs were renamed, none left beside the targets
  for (const auto& [dir, name] : {std::pair{out.parent_path(), other.filename().string()},
                                  std::pair{out, std::string("timing.png")}})
    for (const auto& e : fs::directory_iterator(dir))
      EXPECT_NE(e.path().filename().string().rfind(name + ".tmp", 0), 0u) << e.path();
  fs::remove(other);
  fs::remove_all(out);
}

// a sweep's run (DIR/runs/<id>/run) lists its files in DIR/manifest.jsonl: `esim plot` of it
// needs -o (a timing.png written into it failed `esim dataset verify`); refused before python
// runs, nothing written
TEST(PlotCli, ASweepsRunNeedsAnOutputOutsideIt) {
  const fs::path sweep = tempOut("sweep");
  const fs::path run = sweep / "runs" / "v0000" / "run";
  fs::create_directories(run);
  std::ofstream(sweep / "manifest.jsonl") << "{}\n";
  std::ofstream(run / "timing.csv") << "frame,time_s\n0,0\n";
  for (const std::string& arg : {run.string(), run.string() + "/", run.string() + "/."}) {
    const Result r = esim("plot " + arg);
    EXPECT_EQ(r.exitCode, 2) << arg << "\n" << r.output;
    EXPECT_NE(r.output.find("is a run of the sweep '" + sweep.string() + "'"), std::string::npos)
        << arg << "\n"
        << r.output;
    EXPECT_NE(r.output.find("give -o PNG outside it"), std::string::npos) << r.output;
  }
  EXPECT_FALSE(fs::exists(run / "timing.png"));
  // the same layout without a manifest is a plain folder: not refused as a sweep's run
  fs::remove(sweep / "manifest.jsonl");
  const Result plain = esim("plot " + run.string());
  EXPECT_EQ(plain.output.find("is a run of the sweep"), std::string::npos) << plain.output;
  fs::remove_all(sweep);
}

// no python3, or a python3 without matplotlib: the run completes (exit 0), says why there is
// no plot, writes none; `esim plot` fails with the reason (1), a folder that is no run is bad
// input (2)
TEST(PlotCli, MissingPythonOrMatplotlibIsAWarning) {
  const fs::path out = tempOut("nopython");
  Result r = esim(
      "run scenarios/electric_only.yaml --frames 2 --no-video --set output.hashes=false"
      " -q --plots -o " +
          out.string(),
      "ESIM_PYTHON=/nonexistent/python3");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("esim: warning: no timing.png: cannot start /nonexistent/python3"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out / "timing.png"));
  EXPECT_TRUE(fs::exists(out / "timing.json"));  // the run itself is complete
  // a matplotlib that cannot be imported, first on the module path
  const fs::path fake = tempOut("fake_matplotlib");
  fs::create_directories(fake / "matplotlib");
  std::ofstream(fake / "matplotlib" / "__init__.py") << "raise ImportError('made missing')\n";
  const std::string noMpl = "PYTHONPATH=" + fake.string();
  r = esim(
      "run scenarios/electric_only.yaml --frames 2 --no-video --set output.hashes=false -q "
      "--plots --overwrite -o " +
          out.string(),
      noMpl);
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("no timing.png: matplotlib is missing"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out / "timing.png"));
  r = esim("plot " + out.string(), noMpl);
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("matplotlib is missing"), std::string::npos) << r.output;
  r = esim("plot " + fake.string());
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("holds no timing.csv"), std::string::npos) << r.output;
  fs::remove_all(fake);
  fs::remove_all(out);
}

}  // namespace
