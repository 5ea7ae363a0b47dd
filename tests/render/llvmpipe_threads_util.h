// llvmpipe_threads_util.h - the renderer's determinism across llvmpipe thread counts, shared
// by renderer_test and labels_test. llvmpipe reads LP_NUM_THREADS when its screen is
// created, so each count needs its own process: this binary's (disabled) child test runs
// again with LP_NUM_THREADS set and writes its hash to the file named by hashVar.
#pragma once

#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

extern char** environ;

namespace esim::render_test {

// the hash the child test `childFilter` writes with LP_NUM_THREADS = 1 and 2, in that order
inline void hashesPerLlvmpipeThreads(const std::string& childFilter, const std::string& hashVar,
                                     const std::string& dirName,
                                     std::vector<std::uint64_t>* hashes) {
  const std::string self = std::filesystem::read_symlink("/proc/self/exe").string();
  const auto dir = std::filesystem::temp_directory_path() / dirName;
  std::filesystem::create_directories(dir);
  for (const char* threads : {"1", "2"}) {
    const std::string out = (dir / (std::string("hash_") + threads)).string();
    std::filesystem::remove(out);
    std::vector<std::string> env;
    for (char** e = environ; *e; ++e) {
      const std::string kv = *e;
      if (kv.rfind("LP_NUM_THREADS=", 0) != 0 && kv.rfind(hashVar + "=", 0) != 0) env.push_back(kv);
    }
    env.push_back(std::string("LP_NUM_THREADS=") + threads);
    env.push_back(hashVar + "=" + out);
    std::vector<char*> envp;
    for (auto& kv : env) envp.push_back(kv.data());
    envp.push_back(nullptr);
    std::string a0 = self, a1 = "--gtest_filter=" + childFilter,
                a2 = "--gtest_also_run_disabled_tests";
    char* argv[] = {a0.data(), a1.data(), a2.data(), nullptr};
    pid_t pid = 0;
    ASSERT_EQ(posix_spawn(&pid, self.c_str(), nullptr, nullptr, argv, envp.data()), 0);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
        << "child with LP_NUM_THREADS=" << threads << " failed";
    std::uint64_t h = 0;
    std::ifstream(out) >> h;
    ASSERT_NE(h, 0u) << "no hash from the child with LP_NUM_THREADS=" << threads;
    hashes->push_back(h);
  }
}

}  // namespace esim::render_test
