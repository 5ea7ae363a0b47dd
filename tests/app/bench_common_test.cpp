// bench_common_test.cpp - what the esim bench commands share (tools/app/bench_common.cpp):
// option lists, node counts, and a --csv table that is written whole or not at all.
#include "tools/app/bench_common.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "sim/core_error.h"
#include "tests/scratch_dir_util.h"

namespace esim::app {
namespace {

namespace fs = std::filesystem;

class CsvOutputTest : public test::ScratchDirTest {
 protected:
  static std::string read(const fs::path& p) {
    std::ifstream is(p);
    std::stringstream ss;
    ss << is.rdbuf();
    return ss.str();
  }
  // the files in root_, by name
  std::vector<std::string> files() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(root_)) names.push_back(e.path().filename());
    std::sort(names.begin(), names.end());
    return names;
  }
};

TEST_F(CsvOutputTest, CommitReplacesTheFileWithTheWholeTable) {
  const fs::path file = root_ / "t.csv";
  std::ofstream(file) << "an earlier table\n";
  CsvOutput csv(file.string(), "a,b");
  ASSERT_TRUE(static_cast<bool>(csv));
  csv.out() << "1,2\n";
  EXPECT_EQ(read(file), "an earlier table\n");  // untouched until commit
  csv.out() << "3,4\n";
  csv.commit();
  EXPECT_EQ(read(file), "a,b\n1,2\n3,4\n");
  EXPECT_EQ(files(), std::vector<std::string>{"t.csv"});  // no temporary file left
}

TEST_F(CsvOutputTest, ABenchThatStopsBeforeCommitLeavesTheFileAsItWas) {
  const fs::path file = root_ / "t.csv";
  std::ofstream(file) << "an earlier table\n";
  try {
    CsvOutput csv(file.string(), "a,b");
    csv.out() << "1,2\n";
    throw Error("bad input found after the table was opened");
  } catch (const Error&) {
  }
  EXPECT_EQ(read(file), "an earlier table\n");
  EXPECT_EQ(files(), std::vector<std::string>{"t.csv"});
  // and a path that did not exist is not created
  { CsvOutput csv((root_ / "new.csv").string(), "a"); }
  EXPECT_EQ(files(), std::vector<std::string>{"t.csv"});
}

TEST_F(CsvOutputTest, AnUnwritablePathFailsAtOnceNamingIt) {
  const std::string folder = root_.string();
  try {
    CsvOutput csv(folder, "a");
    FAIL() << "a folder was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "--csv: cannot write '" + folder + "' (a folder; expected a file name)");
    EXPECT_EQ(e.kind(), ErrorKind::Input);
  }
  const std::string missing = (root_ / "no" / "t.csv").string();
  try {
    CsvOutput csv(missing, "a");
    FAIL() << "a missing folder was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "--csv: cannot write '" + missing +
                                         "' (does its folder exist, and may it be written?)");
  }
  EXPECT_TRUE(files().empty());
}

TEST_F(CsvOutputTest, NoPathIsNoTable) {
  CsvOutput csv("", "a,b");
  EXPECT_FALSE(static_cast<bool>(csv));
  csv.commit();  // nothing to write
  EXPECT_TRUE(files().empty());
}

TEST(BenchOptions, TheDefaultSceneIsFoundFromAnyWorkingFolder) {
  const fs::path before = fs::current_path();
  fs::current_path(fs::temp_directory_path());
  const std::string found = benchScenarioPath("scenarios/slab_cut.yaml", "scenarios/slab_cut.yaml");
  fs::current_path(before);
  EXPECT_TRUE(fs::is_regular_file(found)) << found;
  EXPECT_EQ(fs::path(found).filename(), "slab_cut.yaml");
  // a path given is the caller's, found or not (the scenario loader names it)
  EXPECT_EQ(benchScenarioPath("nope.yaml", "scenarios/slab_cut.yaml"), "nope.yaml");
  try {
    benchScenarioPath("scenarios/missing_default.yaml", "scenarios/missing_default.yaml");
    FAIL() << "a default found nowhere was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "--scenario: the default scene scenarios/missing_default.yaml is neither in the "
              "working folder nor in ESim's source tree; run from the source folder or give "
              "--scenario FILE");
  }
}

TEST(BenchOptions, ListsAndNodeCounts) {
  EXPECT_EQ(splitList("a,,b,c"), (std::vector<std::string>{"a", "b", "c"}));
  EXPECT_EQ(parseNodeCounts("1013,50000", "bench cut"), (std::vector<int>{1013, 50000}));
  try {
    parseNodeCounts("1013,26", "bench cut");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "bench cut: --sizes: '26' is not a node count in [27, 5000000] (expected e.g. "
              "1013,20000,50000)");
  }
  EXPECT_THROW(parseNodeCounts(",", "bench cut"), Error);
}

}  // namespace
}  // namespace esim::app
