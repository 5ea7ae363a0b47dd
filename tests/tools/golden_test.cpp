// Golden image regression: short runs of shipped scenarios compared with the committed
// frame hashes and key frames in tests/golden/<name>/ (re-bless: tools/bless-golden).
// Where the recorded renderer and library versions match this machine's, every frame
// hash must be identical. Where they differ, the test says so and falls back to the
// tolerant comparison of the key frames (PSNR, share of pixels off: render/image_hash.h);
// it never passes silently.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "tools/app/compare_runs.h"

namespace esim::app {
namespace {

namespace fs = std::filesystem;

std::string readFile(const fs::path& p) {
  std::ifstream is(p);
  std::stringstream ss;
  ss << is.rdbuf();
  std::string s = ss.str();
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

// runs esim with the golden args into a fresh folder; returns the folder
fs::path runGolden(const std::string& name, const std::string& suffix = "") {
  const fs::path golden = fs::path(ESIM_SOURCE_DIR) / "tests" / "golden" / name;
  const fs::path out = fs::temp_directory_path() / ("esim_golden_" + name + suffix);
  fs::remove_all(out);
  const std::string cmd = std::string("cd ") + ESIM_SOURCE_DIR + " && " + ESIM_EXE + " run " +
                          readFile(golden / "args.txt") + " -q -o " + out.string() + " > " +
                          out.string() + ".log 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd << "\n" << readFile(out.string() + ".log");
  return out;
}

void checkGolden(const std::string& name) {
  const fs::path golden = fs::path(ESIM_SOURCE_DIR) / "tests" / "golden" / name;
  ASSERT_TRUE(fs::exists(golden / "hashes.json")) << "run tools/bless-golden " << name;
  const fs::path out = runGolden(name);
  const CompareResult r = compareRuns(golden.string(), out.string(), "", false);
  EXPECT_EQ(r.framesA, r.framesB);
  std::ostringstream why;
  for (const auto& d : r.diffs) {
    why << "  frame " << d.frame << ": dhash " << d.dhashBits << " bits";
    if (d.hasImages) why << ", PSNR " << d.psnrDb << " dB, " << 100 * d.offShare << " % off";
    why << "\n";
  }
  if (r.sameRenderer) {
    EXPECT_TRUE(r.identical()) << name << ": " << r.diffs.size()
                               << " frames changed (same renderer and libraries):\n"
                               << why.str() << "re-bless with tools/bless-golden " << name
                               << " if the change is intended";
  } else {
    std::printf(
        "[ NOTE ] %s: renderer or library versions differ from the golden run; "
        "comparing key frames with tolerance instead of exact hashes\n",
        name.c_str());
    int compared = 0;
    for (const auto& d : r.diffs) {
      if (!d.hasImages) continue;
      ++compared;
      EXPECT_TRUE(d.withinTolerance) << name << " frame " << d.frame << " out of tolerance\n"
                                     << why.str();
    }
    std::printf("[ NOTE ] %s: %d differing key frames compared, %zu frames differ in all\n",
                name.c_str(), compared, r.diffs.size());
  }
  fs::remove_all(out);
}

TEST(Golden, PaperSlab) { checkGolden("paper_slab"); }

TEST(Golden, CoagulationSpot) { checkGolden("coagulation_spot"); }

TEST(Golden, SameRunTwiceAndAcrossLlvmpipeThreadsIsIdentical) {
  const fs::path a = runGolden("paper_slab", "_a");
  setenv("LP_NUM_THREADS", "1", 1);
  const fs::path b = runGolden("paper_slab", "_b");
  setenv("LP_NUM_THREADS", "2", 1);
  const fs::path c = runGolden("paper_slab", "_c");
  unsetenv("LP_NUM_THREADS");
  const CompareResult ab = compareRuns(a.string(), b.string(), "", false);
  const CompareResult ac = compareRuns(a.string(), c.string(), "", false);
  EXPECT_TRUE(ab.identical()) << ab.diffs.size() << " frames differ with LP_NUM_THREADS=1";
  EXPECT_TRUE(ac.identical()) << ac.diffs.size() << " frames differ with LP_NUM_THREADS=2";
  EXPECT_EQ(ab.framesA, 24);
  fs::remove_all(a);
  fs::remove_all(b);
  fs::remove_all(c);
}

}  // namespace
}  // namespace esim::app
