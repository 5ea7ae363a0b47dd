// plot_script.cpp - running the plot scripts of tools/ (plot_script.h).
#include "tools/app/plot_script.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "tools/app/source_tree.h"

extern char** environ;

namespace esim::app {

namespace fs = std::filesystem;

namespace {

// exit status of the scripts when their input is refused (a message on stderr names the
// file, line and field) and when matplotlib cannot be imported (tools/plot_*.py)
constexpr int kScriptBadInput = 2;
constexpr int kScriptNoMatplotlib = 3;

std::string pythonInterpreter() {
  if (const char* p = std::getenv("ESIM_PYTHON"); p && *p) return p;
  if (access("/usr/bin/python3", X_OK) == 0) return "/usr/bin/python3";
  return "python3";
}

}  // namespace

fs::path findToolScript(const std::string& name) {
  std::error_code ec;
  if (const char* d = std::getenv("ESIM_TOOLS_DIR"); d && *d) {
    const fs::path p = fs::path(d) / name;
    return fs::is_regular_file(p, ec) ? p : fs::path();
  }
  return findSourceTreeFile("tools/" + name);
}

PlotResult runPlotScript(const std::string& script, const std::vector<std::string>& args) {
  const fs::path path = findToolScript(script);
  if (path.empty())
    return {PlotStatus::Unavailable,
            "tools/" + script +
                " not found next to the esim executable or in the source tree "
                "(set ESIM_TOOLS_DIR)"};
  const std::string python = pythonInterpreter();
  std::vector<std::string> argv = {python, path.string()};
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<char*> cargv;
  for (std::string& a : argv) cargv.push_back(a.data());
  cargv.push_back(nullptr);
  pid_t pid = 0;
  const int err = posix_spawnp(&pid, python.c_str(), nullptr, nullptr, cargv.data(), environ);
  if (err != 0)
    return {PlotStatus::Unavailable, "cannot start " + python + " (" + std::strerror(err) +
                                         "): install python3 and python3-matplotlib "
                                         "(tools/install-deps)"};
  int status = 0;
  while (waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) return {PlotStatus::Failed, "waiting for " + python + " failed"};
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0)
    return {PlotStatus::Written, "tools/" + script + " done"};
  if (WIFEXITED(status) && WEXITSTATUS(status) == kScriptNoMatplotlib)
    return {PlotStatus::Unavailable,
            "matplotlib is missing for " + python +
                " (Debian: apt-get install python3-matplotlib, or tools/install-deps)"};
  if (WIFEXITED(status) && WEXITSTATUS(status) == kScriptBadInput)
    return {PlotStatus::BadInput, "tools/" + script + " refused its input (above)"};
  if (WIFEXITED(status) && WEXITSTATUS(status) == 127)
    return {PlotStatus::Unavailable, python + " not found: install python3 (tools/install-deps)"};
  return {PlotStatus::Failed,
          "tools/" + script + " failed (" +
              (WIFEXITED(status) ? "exit status " + std::to_string(WEXITSTATUS(status))
                                 : "signal " + std::to_string(WTERMSIG(status))) +
              ")"};
}

PlotResult plotTiming(const fs::path& runDir, const fs::path& png) {
  // the script writes a temporary PNG beside the target, renamed when it succeeded: a failed
  // or interrupted plot never leaves a half-written or truncated PNG in its place
  const fs::path target = png.empty() ? runDir / "timing.png" : png;
  const fs::path tmp = target.string() + ".tmp" + std::to_string(::getpid()) + ".png";
  PlotResult r = runPlotScript("plot_timing.py", {runDir.string(), "-o", tmp.string()});
  std::error_code ec;
  if (r.status == PlotStatus::Written) {
    fs::rename(tmp, target, ec);
    if (ec) r = {PlotStatus::Failed, "cannot write " + target.string() + ": " + ec.message()};
  }
  fs::remove(tmp, ec);
  if (r.status == PlotStatus::Written) r.message = "wrote " + target.string();
  return r;
}

}  // namespace esim::app
