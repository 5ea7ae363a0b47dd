// bench_cli_test.cpp - the esim bench commands end to end, on their input checks and their
// --csv tables (timings are never asserted: the benches are measurements, not tests). A bench
// given bad input exits 2 naming it and leaves an earlier table as it was; one that runs
// writes its whole table.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tests/scratch_dir_util.h"
#include "tests/tools/cli_test_util.h"

namespace {

namespace fs = std::filesystem;
using esim::cli_test::readFile;
using esim::cli_test::shell;

class BenchCli : public esim::test::ScratchDirTest {
 protected:
  void SetUp() override {
    ScratchDirTest::SetUp();
    csv_ = root_ / "table.csv";
  }
  std::string esim(const std::string& args) const {
    return std::string("\"") + ESIM_EXE + "\" " + args + " --csv \"" + csv_.string() + "\"";
  }
  fs::path csv_;
};

TEST_F(BenchCli, BadInputExitsTwoAndKeepsAnEarlierTable) {
  struct Case {
    std::string args, message;
  };
  const std::vector<Case> cases = {
      {"bench cut --sizes 50 --structural bar",
       "--structural: 'bar' is not full, local or coarse (solvers.structural.method)"},
      // an empty list ran nothing and exited 0
      {"bench cut --sizes 50 --strategy ,", "--strategy is empty; expected synchronous"},
      {"bench cut --sizes 50 --repeat 0",
       "--repeat must be in 1..100 (rounds of the whole table), got 0"},
      {"bench cut --sizes 50 --structural ''",
       "--structural (solvers.structural.method values, comma separated (full,local"},
      {"bench cut --sizes 50 --scenario /nonexistent/cut.yaml",
       "/nonexistent/cut.yaml: cannot open the scenario file"},
      // the second size's run is checked before the first one runs
      {"bench cut --sizes 50,20000 --set tool.voltage_v=abc",
       "--set tool.voltage_v=abc: tool.voltage_v: expected a number in volts, got 'abc'"},
      // --voltage goes to the scene as written (it printed 309 digits)
      {"bench cut --sizes 50 --voltage 1e308",
       "--set tool.voltage_v=1e+308: tool.voltage_v = 1e+308 is outside [0, 10000]"},
      {"bench cut --sizes 50 --electric pcg,foo",
       "--electric: electric solver: unknown strategy 'foo'; valid names: refactor, "
       "dense-inverse, capacitance, pcg, local, downdate, auto"},
      {"bench electric --sizes 100 --local-margin 0",
       "bench electric: --local-margin must be > 0 m, got 0"},
      // the solvers' options were checked by the solvers: each of the update table's rows was
      // "skipped" (exit 0) naming the scenario's key, the sweep stopped after its header
      {"bench electric --sizes 100 --update --threads 0",
       "bench electric: --threads must be >= 1, got 0"},
      {"bench electric --sizes 100 --pcg-tolerance -1",
       "bench electric: --pcg-tolerance must be in (0, 1), got -1"},
      {"bench electric --sizes 100 --update --dense-limit-gb 0",
       "bench electric: --dense-limit-gb must be > 0, got 0"},
      {"bench electric --sizes 100 --update --local-refresh 0",
       "bench electric: --local-refresh must be >= 1, got 0"},
      {"bench structural --sizes 100 --solves 0", "--solves must be >= 1"},
      {"bench structural --sizes 100 --volumetric element,foo",
       "bench structural: --volumetric: 'foo' is not a form of the volumetric strain; expected "
       "element, nodal or both (element,nodal)"},
      // an option of the other bench is refused, not ignored
      {"bench structural --sizes 100 --margins-mm 5",
       "bench structural: --margins-mm is an option of --local only"},
      {"bench structural --sizes 100 --local",
       "bench structural: --csv is not an option of --local"},
      {"bench thermal --sizes 100 --solver foo", "--solver 'foo': expected auto, direct or cg"},
      {"bench electric --sizes 100 --frames 0", "bench electric: --frames must be >= 1"},
      // auto chooses between two solvers; it was an internal error (exit 4)
      {"bench electric --sizes 100 --strategies capacitance,auto",
       "bench electric: --strategies: 'auto' is not a solver of its own: it takes "
       "dense-inverse up to 3000 free nodes and capacitance above"},
      // checked before the blade-sweep table runs, not after it
      {"bench electric --sizes 100 --update --update-strategies auto",
       "bench electric: --update-strategies: 'auto' is not a solver of its own"},
      // --only-update skips the table these options (and the fixture's --csv) are for
      {"bench electric --only-update",
       "bench electric: --csv is an option of the blade-sweep "
       "table, which --only-update skips"},
      // the update table's lists were read by std::stoi ("internal error: stoi", exit 4)
      // and a cut larger than the slab read past its tets (a crash); all checked before
      // the blade sweep runs
      {"bench electric --sizes 100 --update --update-tets x",
       "--update-tets: 'x' is not an integer in [1, 100000000] (expected e.g. 5,95)"},
      {"bench electric --sizes 100 --update --update-tets 5,-5",
       "--update-tets: '-5' is not an integer in [1, 100000000]"},
      {"bench electric --sizes 100 --update --update-sizes 1013 --update-tets 1000000",
       "--update-tets: 1000000 tets is not less than the 1026-node slab's 3672 (--update-sizes "
       "1013)"},
      // it named --sizes
      {"bench electric --sizes 100 --update --update-sizes 10",
       "bench electric: --update-sizes: '10' is not a node count in [27, 5000000]"},
      // 0 and negative counts ran once
      {"bench electric --sizes 100 --update --update-reps 0", "--update-reps must be >= 1, got 0"},
      // the update table's options without the table were never read: the sweep table ran
      {"bench electric --sizes 100 --update-sizes qqq",
       "bench electric: --update-sizes is an option of the update table; add --update (both "
       "tables) or --only-update"},
      {"bench electric --sizes 100 --update-reps 3", "--update-reps is an option of the update"},
      // a value is quoted short and printable (it was echoed whole, 5000 characters)
      {"bench cut --sizes 50 --strategy " + std::string(5000, 'q'),
       "--strategy: '" + std::string(60, 'q') + " ...' (5000 characters) is not synchronous"},
      {"bench electric --sizes 100 --update --update-strategies ,", "--update-strategies is empty"},
      // the encoder refused them after the first surface's rows
      {"bench render --preset x", "--preset: x not in {ultrafast,superfast,veryfast"},
      {"bench render --crf -1", "--crf: Value -1 not in range 0 to 51"},
      {"bench render --sizes x", "--sizes: 'x' is not WIDTHxHEIGHT (e.g. 1280x720)"},
      // it ran as 1280x720
      {"bench render --sizes 1280x720x3",
       "--sizes: '1280x720x3' is not WIDTHxHEIGHT (e.g. 1280x720)"},
      // it named look.width/height, which bench render has not
      {"bench render --sizes 10x10",
       "--sizes: '10x10' is out of range, expected 16..8192 pixels each"},
      {"bench render --surfaces slab --liver assets/liver.obj",
       "bench render: --liver is the 'liver' case's, which --surfaces leaves out"},
  };
  for (const Case& c : cases) {
    std::ofstream(csv_) << "an earlier table\n";
    const auto r = shell(esim(c.args));
    EXPECT_EQ(r.exitCode, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << "\n" << r.output;
    EXPECT_EQ(readFile(csv_), "an earlier table\n") << c.args;
    EXPECT_EQ(std::distance(fs::directory_iterator(root_), fs::directory_iterator()), 1)
        << c.args << ": a file was left beside the table";
  }
}

// bench structural --local's margins were read by std::stod ("internal error: stod", exit
// 4); a negative one was refused from inside the phase ("local.marginM must be >= 0")
TEST_F(BenchCli, StructuralLocalMarginsAreChecked) {
  for (const char* margins : {"5,x", "-2", "nan", ","}) {
    const auto r = shell(std::string("\"") + ESIM_EXE +
                         "\" bench structural --sizes 1013 --local --margins-mm " + margins);
    EXPECT_EQ(r.exitCode, 2) << margins << "\n" << r.output;
    EXPECT_NE(r.output.find("error: --margins-mm"), std::string::npos) << margins << "\n"
                                                                       << r.output;
    EXPECT_NE(r.output.find("(expected e.g. 5,10,15)"), std::string::npos) << r.output;
  }
}

// bench render's surfaces are all made before the first is drawn: an unknown name, or a
// liver file that cannot be read, stopped the bench after the surfaces before it had run
TEST_F(BenchCli, RenderChecksItsSurfacesBeforeDrawingAny) {
  const std::string render = std::string("\"") + ESIM_EXE +
                             "\" bench render --sizes 160x120 --frames 1 --warmup 0 --msaa 0 ";
  struct Case {
    std::string args, message;
  };
  for (const Case& c : {Case{"--surfaces slab,foo", "--surfaces: unknown surface 'foo'"},
                        Case{"--surfaces slab,liver --liver " + (root_ / "none.obj").string(),
                             "none.obj: file not found"},
                        Case{"--surfaces ,", "--surfaces is empty"}}) {
    const auto r = shell(render + c.args);
    EXPECT_EQ(r.exitCode, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << "\n" << r.output;
    EXPECT_EQ(r.output.find("\nslab "), std::string::npos) << c.args << "\n" << r.output;
  }
}

// every size --sizes accepts runs: the smallest slab has a node on the return electrode (8
// to 26 nodes had none), and the electric bench's blade, whose reach is one grid spacing,
// no longer touches it through a coarse slab (a short circuit from 26 to 400 nodes)
TEST_F(BenchCli, EverySlabBenchRunsAtTheSmallestSizeItAccepts) {
  for (const char* args :
       {"bench electric --frames 5 --sizes 27,400", "bench cut --frames 3 --sizes 27,400",
        "bench structural --sizes 27", "bench thermal --sizes 27"}) {
    const auto r = shell(esim(args));
    EXPECT_EQ(r.exitCode, 0) << args << "\n" << r.output;
    EXPECT_TRUE(fs::is_regular_file(csv_)) << args;
    fs::remove(csv_);
  }
}

// --electric: each later strategy's run compared with the first's (the same scene, frames)
TEST_F(BenchCli, CutComparesElectricStrategiesWithTheFirst) {
  const auto r =
      shell(esim("bench cut --frames 6 --sizes 1013 --strategy update --electric "
                 "pcg,capacitance,local"));
  EXPECT_EQ(r.exitCode, 0) << r.output;
  for (const char* row : {"update/full+pcg ", "update/full+capacitance ", "update/full+local "})
    EXPECT_NE(r.output.find(row), std::string::npos) << row << "\n" << r.output;
  // two direct-to-1e-8 solvers remove the same tets in every frame
  EXPECT_NE(r.output.find("(0 tets removed by one of full+pcg/full+capacitance only; the same "
                          "removed set in the first 6 frames"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("of full+pcg/full+local only"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("electric local"), std::string::npos) << r.output;
}

// the update table runs every strategy it names: local (its region needs the nodes'
// positions: it was skipped, "node positions (0) do not match") and downdate, the cut's
// own, by default
TEST_F(BenchCli, UpdateTableRunsLocalAndDowndate) {
  // (without the fixture's --csv: the update table writes none)
  const auto bare = [](const std::string& args) {
    return std::string("\"") + ESIM_EXE + "\" " + args;
  };
  const auto r =
      shell(bare("bench electric --only-update --update-sizes 1013 --update-tets 5 "
                 "--update-strategies local,downdate,pcg"));
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(r.output.find("skipped"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(", the held far field kept; rel_err"), std::string::npos) << r.output;
  for (const char* row : {"\nlocal ", "\ndowndate ", "\npcg "})
    EXPECT_NE(r.output.find(row), std::string::npos) << row << "\n" << r.output;
  const auto d = shell(bare("bench electric --only-update --update-sizes 300 --update-tets 3"));
  EXPECT_EQ(d.exitCode, 0) << d.output;
  EXPECT_NE(d.output.find("\ndowndate "), std::string::npos) << d.output;
  // the solvers' options reach the update table (they were refused with --only-update):
  // local's region covering the slab gives the full solve's potential
  const auto localError = [&](const char* margin) {
    const auto m = shell(bare(std::string("bench electric --only-update --update-sizes 1013 "
                                          "--update-tets 5 --update-strategies local "
                                          "--pcg-preconditioner jacobi --local-margin ") +
                              margin));
    EXPECT_EQ(m.exitCode, 0) << m.output;
    const size_t at = m.output.find("\nlocal ");
    if (at == std::string::npos) return -1.0;
    std::istringstream row(m.output.substr(at));
    std::string field;
    for (int k = 0; k < 11 && row >> field;) ++k;  // strategy .. new_fr, then rel_err
    row >> field;
    return std::stod(field);
  };
  const double near = localError("0.002"), whole = localError("1");
  EXPECT_GT(near, 1e-3);
  EXPECT_GE(whole, 0.0);
  EXPECT_LT(whole, 1e-6);
}

TEST_F(BenchCli, AResultsFolderThatIsAFileIsRefusedBeforeAnythingRuns) {
  std::ofstream(csv_) << "an earlier table\n";
  for (const std::string& args :
       {std::string("bench accuracy --quick --only mesh_graded:1013 --out"),
        std::string("render-sample --out")}) {
    const auto r =
        shell(std::string("\"") + ESIM_EXE + "\" " + args + " \"" + csv_.string() + "\"");
    EXPECT_EQ(r.exitCode, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find("--out: '" + csv_.string() + "' is a file; expected a folder"),
              std::string::npos)
        << args << "\n"
        << r.output;
    EXPECT_EQ(readFile(csv_), "an earlier table\n") << args;
  }
}

// a results folder another command is writing (held here by the test, as esim holds it):
// refused before anything runs, nothing in it changed (two commands into one folder
// interleaved their files; bench accuracy's tables were written in place, unchecked)
TEST_F(BenchCli, AResultsFolderAnotherCommandWritesIsRefused) {
  const fs::path out = root_ / "busy";
  fs::create_directories(out);
  std::ofstream(out / "sample_tissue.png") << "an earlier sample\n";
  const int fd = ::open(out.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
  for (const std::string& args :
       {std::string("bench accuracy --quick --only mesh_graded:1013 --out"),
        std::string("render-sample --out")}) {
    const auto r = shell(std::string("\"") + ESIM_EXE + "\" " + args + " \"" + out.string() + "\"");
    EXPECT_EQ(r.exitCode, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find("--out: another esim is writing '" + out.string() + "'"),
              std::string::npos)
        << args << "\n"
        << r.output;
  }
  ::close(fd);
  EXPECT_EQ(readFile(out / "sample_tissue.png"), "an earlier sample\n");
  EXPECT_EQ(std::distance(fs::directory_iterator(out), fs::directory_iterator()), 1);
}

TEST_F(BenchCli, RenderSampleChecksItsOptionsBeforeMakingItsFolder) {
  const fs::path out = root_ / "samples";
  const auto r = shell(std::string("\"") + ESIM_EXE + "\" render-sample --width 5 --out \"" +
                       out.string() + "\"");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--width: Value 5 not in range 16 to 8192"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out)) << "a failed render-sample left its folder behind";
  // named as the option (it said "RenderOptions::backend")
  const auto b = shell(std::string("\"") + ESIM_EXE + "\" render-sample --backend foo --out \"" +
                       out.string() + "\"");
  EXPECT_EQ(b.exitCode, 2) << b.output;
  EXPECT_NE(b.output.find("--backend: foo not in {osmesa,egl}"), std::string::npos) << b.output;
  EXPECT_FALSE(fs::exists(out));
}

// bench accuracy checks its scene and --only before it makes its folder (a bad scenario was
// "the reference run failed", exit 1, in a folder made for nothing; "--only ," ran the
// reference alone and the plot refused the empty table)
TEST_F(BenchCli, AccuracyChecksItsSceneAndPointsBeforeMakingItsFolder) {
  const fs::path out = root_ / "accuracy";
  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"--scenario /dev/zero", "/dev/zero: more than 16 MiB; a scenario is"},
           {"--only ,", "--only ',': expected point names or knobs, comma separated"},
           // --set reaches the scene the reference runs, checked there too
           {"--set material.critical_stress_radius_m=0.5",
            "material.critical_stress_radius_m = 0.5 is outside [0, 0.05]"},
           // ... and alone: a value every point overrides was never read ('abc' ran)
           {"--set mesh.slab.nodes=abc", "mesh.slab.nodes: expected an integer, got 'abc'"},
           // nan passed CLI11's range and ran the default 2 s
           {"--seconds nan", "--seconds: expected a number in [0, 4] (0: the default), got nan"}}) {
    const auto r = shell(std::string("\"") + ESIM_EXE + "\" bench accuracy --quick " + args +
                         " --out \"" + out.string() + "\"");
    EXPECT_EQ(r.exitCode, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << args << "\n" << r.output;
    EXPECT_FALSE(fs::exists(out)) << args;
  }
}

TEST_F(BenchCli, AnUnwritableTableFailsBeforeTheBenchRuns) {
  const auto r = shell(std::string("\"") + ESIM_EXE + "\" bench cut --sizes 50 --csv \"" +
                       (root_ / "missing" / "t.csv").string() + "\"");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--csv: cannot write '" + (root_ / "missing" / "t.csv").string() +
                          "' (does its folder exist, and may it be written?)"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("strategy"), std::string::npos) << "the table was started:\n" << r.output;
}

TEST_F(BenchCli, CutWritesTheIssuesColumns) {
  std::ofstream(csv_) << "an earlier table\n";
  const auto r = shell(esim("bench cut --sizes 50 --frames 2 --strategy update,synchronous"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const std::string table = readFile(csv_);
  EXPECT_EQ(table.rfind("strategy,nodes,frames,median_ms,p95_ms,max_ms,removed_tets,rebuilds,"
                        "rebuild_median_ms,waits\nupdate,",
                        0),
            0u)
      << table;
  EXPECT_NE(table.find("\nsynchronous,"), std::string::npos) << table;
  EXPECT_EQ(std::count(table.begin(), table.end(), '\n'), 3) << table;
  // the printed rows name the electric solver auto took for the size
  EXPECT_NE(r.output.find("  electric dense-inverse\n"), std::string::npos) << r.output;
}

// --repeat: the rounds run one after the other, each with every strategy (the CSV's rows in
// that order, a round column), then each row's range and its ratio to the same round's update
// row; the strategies are deterministic, so every round removes the same tets
TEST_F(BenchCli, CutRepeatRunsRoundsAndComparesTheirRemovedSets) {
  const auto r =
      shell(esim("bench cut --sizes 1013 --frames 14 --strategy update,synchronous --repeat 2"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const std::string table = readFile(csv_);
  std::istringstream lines(table);
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line,
            "strategy,nodes,frames,median_ms,p95_ms,max_ms,removed_tets,rebuilds,"
            "rebuild_median_ms,waits,round");
  std::vector<std::string> order;
  std::vector<int> removed;
  while (std::getline(lines, line)) {
    const std::string strategy = line.substr(0, line.find(','));
    const std::string round = line.substr(line.rfind(',') + 1);
    order.push_back(strategy + " " + round);
    int fields = 0;
    size_t at = 0;
    while (fields < 6) at = line.find(',', at) + 1, ++fields;
    removed.push_back(std::stoi(line.substr(at)));
  }
  EXPECT_EQ(order,
            (std::vector<std::string>{"update 1", "synchronous 1", "update 2", "synchronous 2"}))
      << table;
  ASSERT_EQ(removed.size(), 4u);
  EXPECT_GT(removed[0], 0) << "nothing was removed: the check of the sets would be empty";
  for (int k : removed) EXPECT_EQ(k, removed[0]) << table;
  EXPECT_NE(r.output.find("round 2 of 2\n"), std::string::npos) << r.output;
  const size_t summary = r.output.find("over 2 rounds");
  ASSERT_NE(summary, std::string::npos) << r.output;
  const std::string tail = r.output.substr(summary);
  // the update row's ratio to itself, and both rows' removed sets the same in both rounds
  EXPECT_NE(tail.find("1.00 / 1.00 / 1.00     1.00 / 1.00 / 1.00  " + std::to_string(removed[0]) +
                      " tets, the same in every round\n"),
            std::string::npos)
      << tail;
  // the heading, the columns, the two rows and the CSV's "wrote" line
  EXPECT_EQ(std::count(tail.begin(), tail.end(), '\n'), 5) << tail;
  EXPECT_EQ(tail.find("DIFFERENT"), std::string::npos) << tail;
}

// --stages prints the CPU the frames cost (every thread): under taskset one CPU, and at most
// that one busy
TEST_F(BenchCli, CutStagesPrintTheCpuAFrame) {
  const auto r = shell(esim::cli_test::onOneCpu() +
                       esim("bench cut --sizes 50 --frames 4 --strategy update --stages"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const size_t at = r.output.find("  cpu            ");
  ASSERT_NE(at, std::string::npos) << r.output;
  double perFrame = 0, busy = 0, floorMs = 0;
  int cpus = 0;
  ASSERT_EQ(std::sscanf(r.output.c_str() + at,
                        "  cpu %lf ms a frame, all threads; %lf of %d CPUs busy (no frame below "
                        "%lf ms",
                        &perFrame, &busy, &cpus, &floorMs),
            4)
      << r.output.substr(at, 120);
  EXPECT_GT(perFrame, 0);
  EXPECT_EQ(cpus, 1);
  EXPECT_GT(busy, 0);
  EXPECT_LE(busy, 1.02);
  EXPECT_NEAR(floorMs, perFrame, 0.011);  // one CPU; both printed to 0.01
}

// --render draws each frame (timed apart): four more columns, physics + render at least the
// render; a look the renderer refuses stops the bench before it runs
TEST_F(BenchCli, CutWithRenderAddsTheRenderColumns) {
  const auto r = shell(
      esim("bench cut --sizes 50 --frames 3 --strategy update --render --set look.width=160 --set "
           "look.height=120"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("each frame drawn at 160x120"), std::string::npos) << r.output;
  std::ifstream in(csv_);
  std::string header, row;
  std::getline(in, header);
  std::getline(in, row);
  EXPECT_EQ(header,
            "strategy,nodes,frames,median_ms,p95_ms,max_ms,removed_tets,rebuilds,"
            "rebuild_median_ms,waits,render_median_ms,render_p95_ms,interactive_median_ms,"
            "interactive_p95_ms");
  std::vector<double> v;
  std::stringstream fields(row.substr(row.find(',') + 1));
  for (std::string f; std::getline(fields, f, ',');) v.push_back(std::stod(f));
  ASSERT_EQ(v.size(), 13u) << row;
  EXPECT_GT(v[9], 0) << row;       // render median
  EXPECT_GE(v[10], v[9]) << row;   // its p95
  EXPECT_GE(v[11], v[9]) << row;   // physics + render median
  EXPECT_GE(v[12], v[11]) << row;  // ... p95

  std::ofstream(csv_) << "an earlier table\n";
  const auto bad = shell(esim("bench cut --sizes 50 --frames 3 --render --set look.width=5"));
  EXPECT_EQ(bad.exitCode, 2) << bad.output;
  EXPECT_NE(bad.output.find("look.width = 5 is outside [16, 7680]"), std::string::npos)
      << bad.output;
  EXPECT_EQ(bad.output.find("strategy"), std::string::npos) << bad.output;
  EXPECT_EQ(readFile(csv_), "an earlier table\n");
}

// a small --voltage reaches the scene whole (std::to_string made 2.5e-7 V into 0 V)
TEST_F(BenchCli, CutPassesItsVoltageExactly) {
  const auto r = shell(esim("bench cut --sizes 50 --frames 1 --strategy update --voltage 2.5e-7"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("at 2.5e-07 V"), std::string::npos) << r.output;
}

}  // namespace
