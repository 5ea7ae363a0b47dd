// build_info: this binary's values are well formed, the one-line form names the short commit
// and the tree's state, and the build-time script (tools/app/build_info.cmake) reads a git
// tree's commit and whether its tracked files changed, on scratch trees made here.
#include "tools/app/build_info.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>

#include "tests/tools/cli_test_util.h"

namespace {

namespace fs = std::filesystem;
using esim::app::BuildInfo;
using esim::app::buildInfo;
using esim::app::buildInfoLine;
using esim::cli_test::readFile;
using esim::cli_test::shell;

bool isCommit(const std::string& s) {
  return s.size() == 40 && s.find_first_not_of("0123456789abcdef") == std::string::npos;
}

TEST(BuildInfo, ThisBinarysValuesAreWellFormed) {
  const BuildInfo& b = buildInfo();
  EXPECT_EQ(b.version, ESIM_PROJECT_VERSION);
  EXPECT_TRUE(isCommit(b.commit) || b.commit == "unknown") << b.commit;
  EXPECT_TRUE(b.dirty == "false" || b.dirty == "true" || b.dirty == "unknown") << b.dirty;
  EXPECT_TRUE(b.compiler.rfind("g++ ", 0) == 0 || b.compiler.rfind("clang++ ", 0) == 0)
      << b.compiler;
}

TEST(BuildInfo, TheLineNamesTheShortCommitAndTheTreesState) {
  const std::string c = "4f067ee1c2d3a4b5c6d7e8f90123456789abcdef";
  EXPECT_EQ(buildInfoLine({"0.1.0", c, "false", "g++ 12.2.0"}),
            "esim 0.1.0 (commit 4f067ee1c2d3; g++ 12.2.0)");
  EXPECT_EQ(buildInfoLine({"0.1.0", c, "true", "g++ 12.2.0"}),
            "esim 0.1.0 (commit 4f067ee1c2d3, with uncommitted changes; g++ 12.2.0)");
  EXPECT_EQ(buildInfoLine({"0.1.0", c, "unknown", "g++ 12.2.0"}),
            "esim 0.1.0 (commit 4f067ee1c2d3, changes since it unknown; g++ 12.2.0)");
  EXPECT_EQ(buildInfoLine({"0.2.0", "unknown", "false", "clang++ 14"}),
            "esim 0.2.0 (commit unknown: no git checkout, or git could not read it; clang++ 14)");
}

// the record timing.json, hashes.json and a sweep's results hold, and read back (an edited
// or older file: a field that is not text reads "?", a record that is not an object none)
TEST(BuildInfo, TheRecordReadsBackAndAnEditedOneIsNotTakenForText) {
  const BuildInfo b{"0.1.0", std::string(40, 'c'), "true", "g++ 12.2.0"};
  const nlohmann::json j = esim::app::buildInfoJson(b);
  EXPECT_EQ(
      j.dump(),
      "{\"commit\":\"" + std::string(40, 'c') +
          "\",\"compiler\":\"g++ 12.2.0\",\"esim\":\"0.1.0\",\"uncommitted_changes\":\"true\"}");
  const auto back = esim::app::buildInfoFromJson(j);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(buildInfoLine(*back), buildInfoLine(b));
  nlohmann::json edited = j;
  edited["commit"] = 42;
  EXPECT_EQ(esim::app::buildInfoFromJson(edited)->commit, "?");
  EXPECT_FALSE(esim::app::buildInfoFromJson(nlohmann::json()).has_value());
  EXPECT_FALSE(esim::app::buildInfoFromJson(nlohmann::json::array()).has_value());
}

// runs the script on tree `src`, writing `out`; returns out's text
std::string runScript(const fs::path& src, const fs::path& out) {
  const auto r =
      shell(std::string(ESIM_CMAKE) + " -DSRC=" + src.string() + " -DOUT=" + out.string() +
            " -DVERSION=9.8.7 -P " + ESIM_SOURCE_DIR + "/tools/app/build_info.cmake");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  return readFile(out);
}

TEST(BuildInfo, TheBuildScriptReadsTheTreesCommitAndItsChanges) {
  const fs::path dir = fs::temp_directory_path() / "esim_build_info_test";
  fs::remove_all(dir);
  const fs::path tree = dir / "tree", out = dir / "gen" / "values.h";
  fs::create_directories(tree);
  // not a git checkout (a source archive)
  std::string text = runScript(tree, out);
  EXPECT_NE(text.find("#define ESIM_BUILD_VERSION \"9.8.7\""), std::string::npos) << text;
  EXPECT_NE(text.find("#define ESIM_BUILD_COMMIT \"unknown\""), std::string::npos) << text;
  EXPECT_NE(text.find("#define ESIM_BUILD_DIRTY \"false\""), std::string::npos) << text;

  // a checkout at a commit: its hash, no changes
  std::ofstream(tree / "a.txt") << "one\n";
  const std::string git = "git -C " + tree.string() + " -c user.name=t -c user.email=t@t ";
  ASSERT_EQ(shell(git + "init -q && " + git + "add a.txt && " + git + "commit -q -m one").exitCode,
            0);
  const auto head = shell("git -C " + tree.string() + " rev-parse HEAD");
  const std::string commit = head.output.substr(0, 40);
  ASSERT_TRUE(isCommit(commit)) << head.output;
  text = runScript(tree, out);
  EXPECT_NE(text.find("#define ESIM_BUILD_COMMIT \"" + commit + "\""), std::string::npos) << text;
  EXPECT_NE(text.find("#define ESIM_BUILD_DIRTY \"false\""), std::string::npos) << text;

  // unchanged: the file is not written again (nothing recompiles)
  fs::last_write_time(out, fs::last_write_time(out) - std::chrono::hours(1));
  const auto old = fs::last_write_time(out);
  runScript(tree, out);
  EXPECT_EQ(fs::last_write_time(out), old);

  // an untracked file (a build folder, a run's output) is not a change of the source
  fs::create_directories(tree / "build");
  std::ofstream(tree / "build" / "x.o") << "object\n";
  EXPECT_NE(runScript(tree, out).find("#define ESIM_BUILD_DIRTY \"false\""), std::string::npos);
  // a tracked file edited is
  std::ofstream(tree / "a.txt") << "two\n";
  text = runScript(tree, out);
  EXPECT_NE(text.find("#define ESIM_BUILD_COMMIT \"" + commit + "\""), std::string::npos) << text;
  EXPECT_NE(text.find("#define ESIM_BUILD_DIRTY \"true\""), std::string::npos) << text;
  fs::remove_all(dir);
}

}  // namespace
