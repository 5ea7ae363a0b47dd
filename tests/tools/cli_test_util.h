// cli_test_util.h - what the command-line tests share: a shell command run in the source
// folder (its stdout and stderr together, its exit code) and a whole file read as text.
// Header-only; ESIM_SOURCE_DIR is defined for every test (tests/CMakeLists.txt).
#pragma once

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

// the file's contents ("" when it cannot be read)
inline std::string readFile(const std::filesystem::path& p) {
  std::ifstream is(p, std::ios::binary);
  std::stringstream ss;
  ss << is.rdbuf();
  return ss.str();
}

}  // namespace esim::cli_test
