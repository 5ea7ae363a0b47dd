// cli_test_util.h - what the command-line tests share: a shell command run in the source
// folder (its stdout and stderr together, its exit code) and a whole file read as text.
// Header-only; ESIM_SOURCE_DIR is defined for every test (tests/CMakeLists.txt).
#pragma once

#include <sched.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace esim::cli_test {

struct Result {
  int exitCode = 0;
  std::string output;  // stdout + stderr
};

// runs `command` with sh in the source folder; exit code -1 when it did not exit normally
inline Result shell(const std::string& command) {
  const std::string cmd = std::string("cd ") + ESIM_SOURCE_DIR + " && (" + command + ") 2>&1";
  Result r;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return {-1, "popen failed"};
  char buf[4096];
  while (fgets(buf, sizeof buf, pipe)) r.output += buf;
  const int status = pclose(pipe);
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// "taskset -c K " for the first CPU this process may run on (a CI machine's cpuset need not
// hold CPU 0): a command that follows runs on that one CPU
inline std::string onOneCpu() {
  cpu_set_t set;
  CPU_ZERO(&set);
  int first = 0;
  if (sched_getaffinity(0, sizeof set, &set) == 0)
    while (first < CPU_SETSIZE && !CPU_ISSET(first, &set)) ++first;
  return "taskset -c " + std::to_string(first < CPU_SETSIZE ? first : 0) + " ";
}

// the file's contents ("" when it cannot be read)
inline std::string readFile(const std::filesystem::path& p) {
  std::ifstream is(p, std::ios::binary);
  std::stringstream ss;
  ss << is.rdbuf();
  return ss.str();
}

}  // namespace esim::cli_test
