// run_output_test.cpp - the output folder never destroys what the run did not create
// (tools/app/run_output.cpp).
#include "tools/app/run_output.h"

#include <gtest/gtest.h>

#include <fstream>
#include <memory>
#include <utility>
#include <vector>

#include "sim/core_error.h"
#include "tests/scratch_dir_util.h"

namespace esim::app {
namespace {

namespace fs = std::filesystem;

class RunOutputTest : public test::ScratchDirTest {
 protected:
  static void touch(const fs::path& p, const std::string& text = "user data\n") {
    std::ofstream(p) << text;
  }
  static std::string read(const fs::path& p) {
    std::ifstream is(p);
    return std::string(std::istreambuf_iterator<char>(is), {});
  }
};

void expectInputError(const std::function<void()>& f, const std::string& part) {
  try {
    f();
    ADD_FAILURE() << "no error; expected '" << part << "'";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input);
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

TEST_F(RunOutputTest, NewFolderIsCreatedAndCommitted) {
  RunOutput out(root_ / "run", false);
  out.create();
  EXPECT_TRUE(fs::is_directory(root_ / "run.partial"));
  touch(out.partial() / "timing.json");
  out.commit();
  EXPECT_TRUE(fs::exists(root_ / "run" / "timing.json"));
  EXPECT_FALSE(fs::exists(root_ / "run.partial"));
}

TEST_F(RunOutputTest, AFileIsRefusedAndKept) {
  touch(root_ / "notes.txt");
  expectInputError([&] { RunOutput(root_ / "notes.txt", true); }, "a file is there");
  EXPECT_EQ(read(root_ / "notes.txt"), "user data\n");
}

TEST_F(RunOutputTest, AFolderOfUserFilesIsRefusedEvenWithOverwrite) {
  fs::create_directories(root_ / "mine");
  touch(root_ / "mine" / "thesis.tex");
  for (bool overwrite : {false, true})
    expectInputError([&] { RunOutput(root_ / "mine", overwrite); }, "not an ESim run");
  EXPECT_EQ(read(root_ / "mine" / "thesis.tex"), "user data\n");
}

TEST_F(RunOutputTest, TheWorkingFolderIsRefused) {
  touch(root_ / "keep.txt");
  const fs::path cwd = fs::current_path();
  fs::current_path(root_);
  expectInputError([&] { RunOutput(".", true); }, "not an ESim run");
  expectInputError([&] { RunOutput("./", true); }, "not an ESim run");
  fs::current_path(cwd);
  EXPECT_TRUE(fs::exists(root_ / "keep.txt"));
  expectInputError([&] { RunOutput("/", true); }, "the root");
}

TEST_F(RunOutputTest, AnEarlierRunNeedsOverwrite) {
  {
    RunOutput first(root_ / "run", false);
    first.create();
    touch(first.partial() / "summary.txt", "first\n");
    first.commit();
  }
  expectInputError([&] { RunOutput(root_ / "run", false); }, "--overwrite");
  EXPECT_EQ(read(root_ / "run" / "summary.txt"), "first\n");
  RunOutput second(root_ / "run", true);
  second.create();
  EXPECT_EQ(read(root_ / "run" / "summary.txt"), "first\n");  // untouched until the commit
  touch(second.partial() / "summary.txt", "second\n");
  second.commit();
  EXPECT_EQ(read(root_ / "run" / "summary.txt"), "second\n");
}

// what esim run writes, and only that, is recognised as a run's (foreignEntry)
TEST_F(RunOutputTest, ARunsOwnFilesAreKnownAndAnythingElseIsNamed) {
  const fs::path run = root_ / "run";
  fs::create_directories(run);
  for (const char* f :
       {".esim-run", "video.mp4", "timing.csv", "timing.json", "trace.json", "scenario.yaml",
        "hashes.json", "summary.txt", "timing.png", "timing.png.tmp4242"})
    touch(run / f);
  for (const auto& [dir, file] :
       std::vector<std::pair<std::string, std::string>>{{"frames", "frame_00000.png"},
                                                        {"frames", "frame_123456.png"},
                                                        {"fields", "frame_00030.vtu"},
                                                        {"labels", "coco.json"},
                                                        {"labels", "frames.jsonl"},
                                                        {"labels", "preview.mp4"},
                                                        {"labels", "depth_00002.png"},
                                                        {"labels", "mask_00002.png"},
                                                        {"compare", "compare.json"},
                                                        {"compare", "diff_frame_00001.png"}}) {
    fs::create_directories(run / dir);
    touch(run / dir / file);
  }
  EXPECT_EQ(foreignEntry(run), "");
  for (const auto& [extra, named] : std::vector<std::pair<fs::path, std::string>>{
           {"notes.txt", "notes.txt"},
           {"plots/fig.png", "plots/"},
           {"frames/notes.txt", "frames/notes.txt"},
           {"frames/frame_1.png", "frames/frame_1.png"},
           {"labels/mask_00002.png.bak", "labels/mask_00002.png.bak"},
           {"video.mp4.tmpx", "video.mp4.tmpx"}}) {
    fs::create_directories((run / extra).parent_path());
    touch(run / extra);
    EXPECT_EQ(foreignEntry(run), named) << extra;
    fs::remove(run / extra);
    if (extra.has_parent_path() && fs::is_empty(run / extra.parent_path()))
      fs::remove(run / extra.parent_path());
  }
  fs::create_symlink(root_ / "elsewhere", run / "video.mp4.partial");
  EXPECT_EQ(foreignEntry(run), "video.mp4.partial") << "a link is not a file the run wrote";
}

// --overwrite replaces an earlier run, never a file the user put into its folder (it deleted
// notes.txt and plots/ with the earlier run)
TEST_F(RunOutputTest, OverwriteNeverDeletesAFileTheRunsDidNotWrite) {
  {
    RunOutput first(root_ / "run", false);
    first.create();
    touch(first.partial() / "summary.txt", "first\n");
    first.commit();
  }
  touch(root_ / "run" / "notes.txt", "mine\n");
  expectInputError([&] { RunOutput(root_ / "run", true); },
                   "--overwrite would delete 'notes.txt', which no ESim run writes");
  EXPECT_EQ(read(root_ / "run" / "notes.txt"), "mine\n");
  fs::remove(root_ / "run" / "notes.txt");
  // ... nor one put there while the new run ran: the run stays in DIR.partial, a run error
  auto second = std::make_unique<RunOutput>(root_ / "run", true);
  second->create();
  touch(second->partial() / "summary.txt", "second\n");
  touch(root_ / "run" / "late.txt", "mine\n");
  try {
    second->commit();
    ADD_FAILURE() << "committed over late.txt";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Run);
    EXPECT_NE(std::string(e.what()).find("'late.txt' appeared in it during the run"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(read(root_ / "run" / "late.txt"), "mine\n");
  EXPECT_EQ(read(root_ / "run" / "summary.txt"), "first\n");
  EXPECT_EQ(read(root_ / "run.partial" / "summary.txt"), "second\n");
  // an earlier partial output with a user's file in it is not replaced either
  second.reset();  // that run ended (its lock with it)
  fs::remove(root_ / "run" / "late.txt");
  touch(root_ / "run.partial" / "draft.md", "mine\n");
  expectInputError([&] { RunOutput(root_ / "run", true); },
                   "is not an ESim run's partial output (it holds 'draft.md')");
  EXPECT_EQ(read(root_ / "run.partial" / "draft.md"), "mine\n");
}

TEST_F(RunOutputTest, APartialFolderOfUserFilesIsRefused) {
  fs::create_directories(root_ / "run.partial");
  touch(root_ / "run.partial" / "data.csv");
  expectInputError([&] { RunOutput(root_ / "run", false); }, "not an ESim run's partial");
  EXPECT_TRUE(fs::exists(root_ / "run.partial" / "data.csv"));
}

TEST_F(RunOutputTest, AnEarlierPartialRunIsReplaced) {
  {
    RunOutput first(root_ / "run", false);
    first.create();
    touch(first.partial() / "timing.json", "old\n");  // interrupted: never committed
  }
  RunOutput again(root_ / "run", false);
  again.create();
  EXPECT_FALSE(fs::exists(root_ / "run.partial" / "timing.json"));
  again.discard();
  EXPECT_FALSE(fs::exists(root_ / "run.partial"));
}

// one run at a time per folder (two used to write the same DIR.partial/ together: one
// committed a video that did not play, the other failed at its end)
TEST_F(RunOutputTest, ASecondRunIntoTheSameFolderIsRefusedWhileTheFirstWrites) {
  const std::string busy = "another esim run is writing this folder";
  auto first = std::make_unique<RunOutput>(root_ / "run", false);
  RunOutput early(root_ / "run", false);  // checked before the first locked its folder
  first->create();
  touch(first->partial() / "timing.json", "first\n");
  expectInputError([&] { RunOutput(root_ / "run", true); }, busy);  // at once
  expectInputError([&] { early.create(); }, busy);                  // or at its create()
  EXPECT_EQ(read(root_ / "run.partial" / "timing.json"), "first\n");
  // the first completes: a run checked before that finds it there, under its own lock
  first->commit();
  expectInputError([&] { early.create(); }, "holds an earlier ESim run; add --overwrite");
  EXPECT_FALSE(fs::exists(root_ / "run.partial")) << "the refused run's empty folder stays";
  first.reset();
  // a run that stopped (its lock gone with it, its partial output kept): the next replaces
  // that output; while it held the lock, the probe of a new run only looked
  auto stopped = std::make_unique<RunOutput>(root_ / "other", false);
  stopped->create();
  touch(stopped->partial() / "timing.json", "old\n");
  expectInputError([&] { RunOutput(root_ / "other", false); }, busy);
  stopped.reset();
  EXPECT_EQ(read(root_ / "other.partial" / "timing.json"), "old\n");
  RunOutput next(root_ / "other", false);
  next.create();
  EXPECT_FALSE(fs::exists(root_ / "other.partial" / "timing.json"));
  EXPECT_TRUE(fs::exists(root_ / "other.partial" / ".esim-run"));
}

TEST_F(RunOutputTest, AnUnwritableLocationIsRefused) {
  if (::geteuid() == 0) {
    // root writes everywhere: a location under a file stands in for "cannot be created"
    touch(root_ / "file");
    expectInputError([&] { RunOutput(root_ / "file" / "run", false); }, "is not a folder");
    return;
  }
  fs::create_directories(root_ / "ro");
  fs::permissions(root_ / "ro", fs::perms::owner_read | fs::perms::owner_exec);
  expectInputError([&] { RunOutput(root_ / "ro" / "run", false); }, "cannot write");
  fs::permissions(root_ / "ro", fs::perms::owner_all);
}

TEST_F(RunOutputTest, AResultsFolderIsCreatedOrRefusedWithoutTouchingAFile) {
  const fs::path nested = root_ / "a" / "b";
  FolderLock lock;
  createOutputFolder(nested, "--out", lock);
  EXPECT_TRUE(fs::is_directory(nested));
  lock.release();
  createOutputFolder(nested, "--out", lock);  // an existing folder is fine
  // held: a second command into it is refused (bench accuracy --out, render-sample --out and
  // compare --report into one folder interleaved their files)
  FolderLock second;
  try {
    createOutputFolder(nested, "--out", second);
    FAIL() << "a folder another command writes was taken";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "--out: another esim is writing '" + nested.string() +
                                         "'; give another folder, or wait for it to end "
                                         "(nothing was changed)");
    EXPECT_EQ(e.kind(), ErrorKind::Input);
  }
  lock.release();
  createOutputFolder(nested, "--out", second);
  const fs::path file = root_ / "f";
  touch(file);
  try {
    createOutputFolder(file, "--report", lock);
    FAIL() << "a file was taken for a folder";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "--report: '" + file.string() + "' is a file; expected a folder");
    EXPECT_EQ(e.kind(), ErrorKind::Input);
  }
  EXPECT_EQ(read(file), "user data\n");
  try {
    createOutputFolder(file / "under", "--out", lock);
    FAIL() << "a folder under a file was created";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(
                  "--out: cannot create the folder '" + (file / "under").string() + "': ", 0),
              0u)
        << e.what();
  }
  EXPECT_EQ(read(file), "user data\n");
}

// the scenario's name is free text (a title): the default folder is always one folder in out/
// (it was out/<name> as given: "/abs/path" wrote there, "../escape" beside out/, "." into
// out/ itself)
TEST(DefaultRunFolder, IsOneFolderInsideOutWhateverTheName) {
  EXPECT_EQ(defaultRunFolder("slab_cut"), fs::path("out/slab_cut"));
  EXPECT_EQ(defaultRunFolder("paper_slab-506.v2"), fs::path("out/paper_slab-506.v2"));
  EXPECT_EQ(defaultRunFolder("x: y"), fs::path("out/x__y"));
  EXPECT_EQ(defaultRunFolder("../escape"), fs::path("out/___escape"));
  EXPECT_EQ(defaultRunFolder("/abs/path"), fs::path("out/_abs_path"));
  EXPECT_EQ(defaultRunFolder("."), fs::path("out/_"));
  EXPECT_EQ(defaultRunFolder(".."), fs::path("out/__"));
  EXPECT_EQ(defaultRunFolder(".hidden"), fs::path("out/_hidden"));
  EXPECT_EQ(defaultRunFolder(""), fs::path("out/unnamed"));
  EXPECT_EQ(defaultRunFolder("caf\xc3\xa9\nline"), fs::path("out/caf___line"));
  for (const std::string name : {"../escape", "/abs/path", ".", "..", "", "a/../../b", "~"}) {
    const fs::path p = defaultRunFolder(name);
    EXPECT_EQ(p.parent_path(), fs::path("out")) << name;
    EXPECT_NE(p.filename(), fs::path(".")) << name;
    EXPECT_NE(p.filename(), fs::path("..")) << name;
  }
}

}  // namespace
}  // namespace esim::app
