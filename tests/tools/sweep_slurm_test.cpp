// `esim sweep --slurm --submit` through a real one-node Slurm cluster started on this
// machine from Debian's packages by tools/slurm-local (munged, slurmctld, slurmd): a
// 4-variant sweep of short scenes, every variant run by an array task, the manifest the
// same as a local sweep's, the outputs verified. Skipped, saying why, where Slurm cannot
// be started (no packages: tools/install-deps installs them; CI does).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "tests/tools/cli_test_util.h"

namespace {

namespace fs = std::filesystem;
using esim::cli_test::readFile;
using esim::cli_test::Result;
using esim::cli_test::shell;
using nlohmann::json;

// starts the cluster (or finds it running); stops it at the end if it started it
class LocalSlurm {
 public:
  LocalSlurm() {
    wasRunning_ = shell("tools/slurm-local status").exitCode == 0;
    const Result r = shell("tools/slurm-local start");
    startOutput_ = r.output;
    const std::string key = "export SLURM_CONF=";
    const auto at = r.output.find(key);
    if (r.exitCode != 0 || at == std::string::npos) return;
    conf_ = r.output.substr(at + key.size());
    conf_ = conf_.substr(0, conf_.find('\n'));
    up_ = true;
  }
  ~LocalSlurm() {
    if (up_ && !wasRunning_) shell("tools/slurm-local stop");
  }
  bool up() const { return up_; }
  const std::string& conf() const { return conf_; }
  const std::string& why() const { return startOutput_; }

 private:
  bool up_ = false, wasRunning_ = false;
  std::string conf_, startOutput_;
};

TEST(SweepSlurm, FourVariantsThroughALocalCluster) {
  LocalSlurm slurm;
  if (!slurm.up())
    GTEST_SKIP() << "Slurm cannot be started on this machine (tools/slurm-local start said: "
                 << slurm.why()
                 << "); install munge slurmctld slurmd slurm-client (tools/install-deps)";
  const fs::path dir = fs::temp_directory_path() / "esim_sweep_slurm_test";
  fs::remove_all(dir);
  const std::string env = "SLURM_CONF=" + slurm.conf() + " ";
  const Result r = shell(env + ESIM_EXE + " sweep scenarios/sweeps/paper_slab_tiny_4.yaml -o " +
                         dir.string() + " --slurm --submit");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  // the sizing run, then the other 3 as one array
  EXPECT_NE(r.output.find("sizing the tasks: v0000"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("4 variants: 4 complete"), std::string::npos) << r.output;
  const std::string script = readFile(dir / "slurm" / "sweep.sbatch");
  EXPECT_NE(script.find("#SBATCH --array=1-3\n"), std::string::npos) << script;
  EXPECT_NE(script.find("#SBATCH --mem="), std::string::npos) << script;
  EXPECT_NE(script.find("#SBATCH --time="), std::string::npos) << script;
  EXPECT_NE(script.find("# resources: measured on v0000"), std::string::npos) << script;
  std::istringstream in(readFile(dir / "manifest.jsonl"));
  int n = 0;
  for (std::string line; std::getline(in, line); ++n) {
    const json l = json::parse(line);
    EXPECT_EQ(l["status"], "complete") << l.dump();
    EXPECT_EQ(l["frames"], 15);
    ASSERT_TRUE(l["slurm_job"].is_string()) << "run by a Slurm task: " << l.dump();
    EXPECT_NE(l["slurm_job"].get<std::string>().find('_'), std::string::npos);
    EXPECT_TRUE(l["files"].contains("runs/" + l["id"].get<std::string>() + "/run/video.mp4"));
    EXPECT_TRUE(fs::exists(dir / "slurm" / "logs" / (l["slurm_job"].get<std::string>() + ".out")));
  }
  EXPECT_EQ(n, 4);
  const Result v = shell(std::string(ESIM_EXE) + " dataset verify " + dir.string());
  EXPECT_EQ(v.exitCode, 0) << v.output;
  fs::remove_all(dir);
}

}  // namespace
