// sweep.cpp - `esim sweep` and `esim dataset run` (see sweep.h).
//
// Outline:
//   ---- processes ----  spawning `esim run` and the Slurm commands, signals
//   ---- one variant --- run it, read how it ended, hash what it wrote, record it
//   ---- the folder ----  create or resume DIR, write the variants
//   ---- local ----       --workers N at a time, the progress line
//   ---- Slurm ----       measure, write the job-array script, submit and wait
#include "tools/app/sweep.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>
#include <tuple>

#include "render/image_hash.h"
#include "sim/core_error.h"
#include "sim/io/scenario.h"
#include "sim/message_text.h"
#include "tools/app/dataset.h"
#include "tools/app/json_text.h"
#include "tools/app/run_output.h"
#include "tools/app/sweep_spec.h"

extern char** environ;

namespace esim::app {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using nlohmann::json;

// ---- processes ----

std::atomic<int> gSignals{0};  // SIGINT/SIGTERM received
std::atomic<int> gLastSignal{SIGINT};

extern "C" void onSweepSignal(int sig) {
  gLastSignal = sig;
  ++gSignals;
}

void catchSignals() {
  gSignals = 0;
  struct sigaction sa {};
  sa.sa_handler = onSweepSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

std::vector<char*> cArgs(const std::vector<std::string>& args) {
  std::vector<char*> a;
  for (const auto& s : args) a.push_back(const_cast<char*>(s.c_str()));
  a.push_back(nullptr);
  return a;
}

// the child starts with SIGINT/SIGTERM at their default action and nothing blocked
void defaultSignals(posix_spawnattr_t& attr, short extraFlags) {
  sigset_t def, none;
  sigemptyset(&def);
  sigaddset(&def, SIGINT);
  sigaddset(&def, SIGTERM);
  sigemptyset(&none);
  posix_spawnattr_setsigdefault(&attr, &def);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK | extraFlags);
}

// starts argv with stdout and stderr into log; ownGroup: in a process group of its own (a
// terminal's Ctrl-C then reaches only us, and we pass it on once); returns the pid
pid_t spawnLogged(const std::vector<std::string>& argv, const fs::path& log, bool ownGroup) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  defaultSignals(attr, ownGroup ? POSIX_SPAWN_SETPGROUP : 0);
  if (ownGroup) posix_spawnattr_setpgroup(&attr, 0);
  pid_t pid = -1;
  auto args = cArgs(argv);
  const int rc = posix_spawn(&pid, args[0], &fa, &attr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  if (rc != 0) {
    errno = rc;
    return -1;
  }
  return pid;
}

// waits for the child; cpuS (if given): the CPU time it used, user + system [s]
int waitFor(pid_t pid, double* cpuS = nullptr) {
  int status = 0;
  rusage ru{};
  while (::wait4(pid, &status, 0, &ru) < 0)
    if (errno != EINTR) return -1;
  if (cpuS)
    *cpuS = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
            1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  return status;
}

struct Captured {
  int exitCode = -1;
  std::string output;  // stdout + stderr
};

// runs a command found on PATH (sbatch, squeue, scancel) and captures its output
Captured capture(const std::vector<std::string>& argv) {
  Captured c;
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return c;
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&fa, fds[1], 1);
  posix_spawn_file_actions_adddup2(&fa, fds[1], 2);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  defaultSignals(attr, 0);
  pid_t pid = -1;
  auto args = cArgs(argv);
  const int rc = posix_spawnp(&pid, args[0], &fa, &attr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  ::close(fds[1]);
  if (rc != 0) {
    ::close(fds[0]);
    c.output = argv[0] + ": " + std::strerror(rc);
    return c;
  }
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n > 0) {
      c.output.append(buf, static_cast<size_t>(n));
    } else if (n == 0 || errno != EINTR) {
      break;
    }
  }
  ::close(fds[0]);
  const int status = waitFor(pid);
  c.exitCode = status >= 0 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return c;
}

std::string trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.erase(0, 1);
  return s;
}

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string clockText(double s) {
  const long t = std::lround(std::max(0.0, s));
  char buf[32];
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, t / 60 % 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", t / 60, t % 60);
  return buf;
}

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string hostName() {
  char buf[256] = {0};
  ::gethostname(buf, sizeof buf - 1);
  return buf;
}

json readJsonFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) return nullptr;
  try {
    return json::parse(in);
  } catch (const std::exception&) {
    return nullptr;
  }
}

std::string readText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// the last "esim: error: ..." (or internal error) line of a run's log
std::string lastErrorLine(const fs::path& log) {
  std::istringstream in(readText(log));
  std::string last;
  for (std::string line; std::getline(in, line);)
    if (line.rfind("esim: error: ", 0) == 0 || line.rfind("esim: internal error: ", 0) == 0)
      last = line.substr(6);
  return last;
}

// the frames a killed run had done: the rows of its timing.csv.partial (streamed as the
// frames are done); -1 without it
int streamedFrames(const fs::path& partial) {
  std::error_code ec;
  if (!fs::is_regular_file(partial / "timing.csv.partial", ec)) return -1;
  const std::string csv = readText(partial / "timing.csv.partial");
  const long lines = std::count(csv.begin(), csv.end(), '\n');
  return static_cast<int>(std::max(0L, lines - 1));
}

// ---- one variant ----

// xxh3-64 over "path\thash\n" of the files under labels/ (null when there are none)
json labelsHash(const json& files, const std::string& labelsPrefix) {
  std::string lines;
  for (auto it = files.begin(); it != files.end(); ++it)
    if (it.key().rfind(labelsPrefix, 0) == 0)
      lines += it.key() + "\t" + it.value().get<std::string>() + "\n";
  if (lines.empty()) return nullptr;
  return hashToHex(XXH3_64bits(lines.data(), lines.size()));
}

// the result of a variant whose run ended with wait status `status` (-1: not started)
json variantResult(const fs::path& dir, const std::string& id, int index, int status, double wallS,
                   bool stopping, const std::string& spawnError) {
  const fs::path vdir = dataset::variantDir(dir, id);
  const fs::path run = dataset::runDir(dir, id);
  const fs::path partial = run.string() + ".partial";
  json r = {{"id", id}, {"index", index}};
  const bool exited = status >= 0 && WIFEXITED(status);
  const int code = exited ? WEXITSTATUS(status) : -1;
  r["exit_code"] = exited ? json(code) : json(nullptr);
  r["wall_s"] = std::round(wallS * 1000.0) / 1000.0;
  r["host"] = hostName();
  const char* arrayJob = std::getenv("SLURM_ARRAY_JOB_ID");
  const char* arrayTask = std::getenv("SLURM_ARRAY_TASK_ID");
  const char* job = std::getenv("SLURM_JOB_ID");
  r["slurm_job"] = arrayJob && arrayTask ? json(std::string(arrayJob) + "_" + arrayTask)
                   : job                 ? json(job)
                                         : json(nullptr);
  r["finished"] = utcNow();
  std::error_code ec;
  const bool complete = exited && code == 0 && fs::is_directory(run, ec);
  const json timing = readJsonFile((complete ? run : partial) / "timing.json");
  // (a run killed before its reports: the rows it streamed)
  const int streamed = timing.is_object() || complete ? -1 : streamedFrames(partial);
  r["frames"] = timing.is_object() ? timing.value("frames", json(nullptr))
                : streamed >= 0    ? json(streamed)
                                   : json(nullptr);
  r["peak_rss_mb"] =
      timing.is_object() ? timing.value("peak_rss_mb", json(nullptr)) : json(nullptr);
  // the run's own warnings (e.g. tissue past 300 C): a dataset may want to leave them out
  r["warnings"] = timing.is_object() ? timing.value("warnings", json::array()) : json::array();
  // which esim made it (a sweep resumed after the code changed holds variants of two builds)
  r["esim_build"] = timing.is_object() ? timing.value("build", json(nullptr)) : json(nullptr);
  if (complete) {
    r["status"] = "complete";
    r["message"] = "";
    json files = json::object();
    const fs::path scen = vdir / "scenario.yaml";
    files[scen.lexically_relative(dir).generic_string()] = hashFile(scen);
    const json tree = hashTree(run, dir);
    for (auto it = tree.begin(); it != tree.end(); ++it) files[it.key()] = it.value();
    const std::string prefix = run.lexically_relative(dir).generic_string() + "/";
    const std::string video = prefix + "video.mp4";
    r["video"] = files.contains(video) ? json(video) : json(nullptr);
    r["video_xxh3"] = files.contains(video) ? files[video] : json(nullptr);
    const json hashes = readJsonFile(run / "hashes.json");
    r["frames_xxh3"] =
        hashes.is_object() ? hashes.value("all_frames_xxh3", json(nullptr)) : json(nullptr);
    r["labels_xxh3"] = labelsHash(files, prefix + "labels/");
    r["files"] = files;
    return r;
  }
  std::string message;
  bool interrupted = stopping;
  if (!spawnError.empty()) {
    message = spawnError;
  } else if (timing.is_object() && timing.value("interrupted", false)) {
    interrupted = true;
    message = "interrupted after " + std::to_string(timing.value("frames", 0)) + " frames";
  } else if (timing.is_object() && timing.contains("failure")) {
    message = timing["failure"].get<std::string>();
  } else {
    message = lastErrorLine(vdir / "log.txt");
  }
  if (status >= 0 && WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    message = "ended by signal " + std::to_string(sig) + " (" + strsignal(sig) + ")" +
              (streamed >= 0 ? " after " + std::to_string(streamed) + " frames" : "");
    if (sig == SIGKILL && !stopping) {
      // the run's out-of-memory watcher (memory_room.h) writes its line to the log once the
      // run has ended: a moment after this wait returned
      std::string oom;
      for (int i = 0; i < 40 && oom.find("out-of-memory killer") == std::string::npos; ++i) {
        if (i > 0) std::this_thread::sleep_for(std::chrono::milliseconds(25));
        oom = lastErrorLine(vdir / "log.txt");
      }
      message += oom.find("out-of-memory killer") != std::string::npos ? ": " + oom.substr(7)
                                                                       : ": out of memory?";
    }
    interrupted = interrupted || sig == SIGINT || sig == SIGTERM;
  }
  if (message.empty()) message = "esim run exited with " + std::to_string(code) + " (see log.txt)";
  r["status"] = interrupted ? "interrupted" : "failed";
  r["message"] = message;
  return r;
}

struct VariantJob {
  fs::path dir;
  std::string id;
  int index = 0;
  std::vector<std::string> runOptions;
  std::string exe;
  bool ownGroup = false;
  json extra = json::object();  // fields added to the result (memory_retry)
};

// what runVariant returns when another process runs the variant (nothing was touched)
constexpr const char* kBusy = "busy";

// runs one variant to its end; records its result and the manifest; returns the result.
// The variant's folder is held (flock) from before its earlier outputs go until its result is
// recorded: two processes running one variant (esim dataset run by hand beside a Slurm task or
// a local sweep) deleted each other's run folder, and the manifest kept the last to end (a
// failure, over a complete run). Held by another: returns {"status": "busy"}, changes nothing.
json runVariant(const VariantJob& job, const std::function<void(pid_t)>& started,
                const std::function<void(pid_t)>& ended) {
  const fs::path vdir = dataset::variantDir(job.dir, job.id);
  const fs::path run = dataset::runDir(job.dir, job.id);
  std::error_code ec;
  fs::create_directories(vdir, ec);
  FolderLock held;
  if (!held.tryLock(vdir, job.id)) return json{{"id", job.id}, {"status", kBusy}};
  fs::remove(vdir / "result.json", ec);
  json result;
  if (fs::is_regular_file(run / "timing.json", ec) &&
      readJsonFile(run / "timing.json").value("complete", false)) {
    // run/ complete but not recorded (the recording process stopped): record it
    result = variantResult(job.dir, job.id, job.index, 0, 0.0, false, "");
  } else {
    // an earlier attempt's partial folder goes (the new run makes its own)
    fs::remove_all(run.string() + ".partial", ec);
    fs::remove_all(run, ec);
    std::vector<std::string> argv{job.exe, "run",        (vdir / "scenario.yaml").string(),
                                  "-o",    run.string(), "-q"};
    argv.insert(argv.end(), job.runOptions.begin(), job.runOptions.end());
    const auto t0 = Clock::now();
    const pid_t pid = spawnLogged(argv, vdir / "log.txt", job.ownGroup);
    if (pid < 0) {
      result = variantResult(job.dir, job.id, job.index, -1, 0.0, false,
                             "cannot start " + job.exe + ": " + std::strerror(errno));
    } else {
      if (started) started(pid);
      double cpuS = 0;
      const int status = waitFor(pid, &cpuS);
      if (ended) ended(pid);
      result =
          variantResult(job.dir, job.id, job.index, status, secondsSince(t0), gSignals > 0, "");
      result["cpu_s"] = std::round(cpuS * 1000.0) / 1000.0;
    }
  }
  for (auto it = job.extra.begin(); it != job.extra.end(); ++it) result[it.key()] = it.value();
  writeResult(job.dir, job.id, result);
  writeManifest(job.dir);
  return result;
}

// a run that stopped for memory: its guard between frames, an allocation or a thread refused,
// the kernel's out-of-memory kill (the messages of run.cpp, memory_room.cpp, main.cpp and
// variantResult). Beside other runs it had a share of the memory; alone it may fit.
bool stoppedForMemory(const json& r) {
  if (r.value("status", "") != "failed") return false;
  const std::string m = r.value("message", "");
  for (const char* mark :
       {"out of memory", ": memory: ", "out-of-memory killer", "a thread could not be started"})
    if (m.find(mark) != std::string::npos) return true;
  return m.rfind("memory: ", 0) == 0;
}

// ---- the folder ----

std::vector<std::string> allRunOptions(const SweepSpec& spec, const SweepOptions& opt) {
  std::vector<std::string> o = spec.runOptions;
  o.insert(o.end(), opt.runArgs.begin(), opt.runArgs.end());
  return o;
}

// the variant as its run reads it: fully resolved, a mesh file and a tool path file by their
// absolute paths
std::string variantYaml(const SweepVariant& v) {
  Scenario s = v.scenario;
  if (s.mesh.source == MeshSource::File && !s.mesh.file.resolvedPath.empty())
    s.mesh.file.path = fs::absolute(s.mesh.file.resolvedPath).lexically_normal().string();
  if (!s.tool.pathFileResolved.empty())
    s.tool.pathFile = fs::absolute(s.tool.pathFileResolved).lexically_normal().string();
  return scenarioToYaml(s);
}

// The sweep's folder held by one `esim sweep` while it runs (FolderLock; DIR/.lock is the
// manifest's, held only while it is rewritten). Two sweeps into one folder ran the same
// variants at once and left variants marked failed that the other had completed.
void lockSweepFolder(const fs::path& dir, FolderLock& lock) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) return;  // checkFolder says why
  fs::create_directories(dir, ec);
  ESIM_VERIFY(!ec, dir.string() + ": cannot create the sweep's folder: " + ec.message());
  ESIM_VERIFY(lock.tryLock(dir, "-o"), dir.string() +
                                           ": another esim sweep is running in this folder; "
                                           "resume it once that one ends (nothing was changed)");
}

// checks DIR (new, empty, or this sweep's earlier folder) before anything is written;
// throws Error (bad input) naming what differs
void checkFolder(const fs::path& dir, const SweepSpec& spec, const std::vector<SweepVariant>& vs,
                 const std::vector<std::string>& runOptions) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) return;
  if (!fs::is_directory(dir, ec))
    throw Error(dir.string() +
                ": is a file; -o takes a folder (new, empty, or an earlier "
                "sweep's to resume)");
  if (!fs::exists(dir / "sweep.json", ec)) {
    if (fs::directory_iterator(dir, ec) == fs::directory_iterator()) return;
    throw Error(dir.string() +
                ": holds other files and no sweep.json; -o takes a new or empty "
                "folder, or an earlier sweep's to resume");
  }
  const json old = readSweepJson(dir);
  const std::string again = "; give a new folder (or remove " + dir.string() + ")";
  if (old.value("run_options", json::array()) != json(runOptions))
    throw Error(dir.string() + ": made with run options " +
                jsonText(old.value("run_options", json::array())) + ", now " +
                jsonText(json(runOptions)) + again);
  if (old.at("variants").size() != vs.size())
    throw Error(dir.string() + ": holds a sweep of " + std::to_string(old.at("variants").size()) +
                " variants; " + spec.file + " makes " + std::to_string(vs.size()) + again);
  for (const auto& v : vs) {
    const fs::path p = dataset::variantDir(dir, v.id) / "scenario.yaml";
    if (fs::exists(p, ec) && readText(p) != variantYaml(v))
      throw Error(p.string() + ": differs from the variant " + spec.file +
                  " makes now (the sweep file or its base scenario changed)" + again);
  }
}

void writeFolder(const fs::path& dir, const SweepSpec& spec, const std::vector<SweepVariant>& vs,
                 const std::vector<std::string>& runOptions, const std::string& exe) {
  fs::create_directories(dir / "runs");
  writeFileAtomic(dir / "sweep.yaml", spec.text);
  json variants = json::array();
  for (const auto& v : vs)
    variants.push_back({{"id", v.id}, {"index", v.index}, {"values", v.values}});
  const json sweep = {{"format", "esim-sweep 1"},
                      {"name", spec.name},
                      {"description", spec.description},
                      {"spec", fs::absolute(spec.file).lexically_normal().string()},
                      {"base", fs::absolute(spec.base).lexically_normal().string()},
                      {"seed", spec.seed},
                      {"draws", spec.draws},
                      {"run_options", runOptions},
                      {"esim", exe},
                      {"variants", variants}};
  writeFileAtomic(dir / "sweep.json", jsonText(sweep, 2) + "\n");
  for (const auto& v : vs) {
    const fs::path vdir = dataset::variantDir(dir, v.id);
    fs::create_directories(vdir);
    const fs::path p = vdir / "scenario.yaml";
    std::error_code ec;
    if (!fs::exists(p, ec)) writeFileAtomic(p, variantYaml(v));
  }
}

// the variants to run now: not complete; failed ones only with retryFailed
std::vector<const SweepVariant*> toRun(const fs::path& dir, const std::vector<SweepVariant>& vs,
                                       bool retryFailed) {
  std::vector<const SweepVariant*> out;
  for (const auto& v : vs) {
    const json r = readResult(dir, v.id);
    const std::string status = r.is_object() ? r.value("status", "") : "";
    std::error_code ec;
    if (status == "complete" && fs::is_directory(dataset::runDir(dir, v.id), ec)) continue;
    if (status == "failed" && !retryFailed) continue;
    out.push_back(&v);
  }
  return out;
}

struct Tally {
  int complete = 0, failed = 0, interrupted = 0, pending = 0;
  std::vector<std::string> failures;  // "v0003 failed: ..."
  std::vector<std::string> warned;    // complete with warnings: "v0003: <its first warning>"
  std::map<std::string, int> builds;  // the esim builds of the complete variants, and how many
};

Tally tally(const fs::path& dir) {
  Tally t;
  for (const auto& line : manifestLines(dir)) {
    const std::string s = line.value("status", "");
    if (s == "complete") {
      ++t.complete;
      ++t.builds[variantBuildLine(line)];
      const json w = line.value("warnings", json::array());
      if (w.is_array() && !w.empty() && w[0].is_string())
        t.warned.push_back(
            line.value("id", "") + ": " + w[0].get<std::string>() +
            (w.size() > 1 ? " (and " + std::to_string(w.size() - 1) + " more)" : ""));
    } else if (s == "pending") {
      ++t.pending;
    } else {
      (s == "failed" ? t.failed : t.interrupted)++;
      t.failures.push_back(line.value("id", "") + " " + s + ": " + line.value("message", ""));
    }
  }
  return t;
}

// this process's sweep: when it started and the variants it set out to run (the
// throughput line of the final report)
struct Session {
  Clock::time_point start = Clock::now();
  std::set<std::string> ids;
};
Session gSession;

// "this run: 8 videos in 4:05 (117.6 videos/hour), 54.2 CPU s a video (15.1 core-hours per
// 1000 videos)"; "runs" where no run wrote a video (--run-args --no-video)
void throughputLine(const fs::path& dir) {
  int n = 0;
  bool video = false;
  double cpu = 0;
  for (const auto& line : manifestLines(dir))
    if (gSession.ids.count(line.value("id", "")) && line.value("status", "") == "complete") {
      ++n;
      cpu += line.value("cpu_s", 0.0);
      video = video || (line.contains("video") && line["video"].is_string());
    }
  if (n == 0) return;
  const double wall = secondsSince(gSession.start);
  const char* what = video ? "video" : "run";
  char buf[300];
  std::snprintf(buf, sizeof buf,
                "this run: %d %s%s in %s (%.1f %ss/hour), %.1f CPU s a %s (%.2f "
                "core-hours per 1000 %ss)\n",
                n, what, n == 1 ? "" : "s", clockText(wall).c_str(),
                n * 3600.0 / std::max(wall, 1e-3), what, cpu / n, what, cpu / n * 1000.0 / 3600.0,
                what);
  std::cout << buf;
}

int finalReport(const fs::path& dir, std::size_t total, bool quiet) {
  writeManifest(dir);
  const Tally t = tally(dir);
  if (!quiet) {
    throughputLine(dir);
    std::cout << "sweep: " << total << " variants: " << t.complete << " complete";
    if (t.failed) std::cout << ", " << t.failed << " failed";
    if (t.interrupted) std::cout << ", " << t.interrupted << " interrupted";
    if (t.pending) std::cout << ", " << t.pending << " not run";
    std::cout << "\n";
    for (const auto& f : t.failures) std::cout << "  " << printableMessage(f, 300) << "\n";
    // a complete run may still not be what a dataset wants (a camera that sees no tissue,
    // tissue past 300 C): said here, each variant's in the manifest's warnings
    if (!t.warned.empty()) {
      std::cout << "  " << t.warned.size() << " complete variant"
                << (t.warned.size() == 1 ? " has" : "s have")
                << " warnings (the manifest's \"warnings\"):\n";
      for (size_t i = 0; i < t.warned.size() && i < 5; ++i)
        std::cout << "    " << printableMessage(t.warned[i], 300) << "\n";
      if (t.warned.size() > 5) std::cout << "    ...\n";
    }
    // a dataset whose variants two builds made (a sweep resumed after the code changed)
    if (t.builds.size() > 1) std::cout << "  warning: " << datasetBuildsText(t.builds);
    if (t.failed)
      std::cout << "  (failed variants run again with --retry-failed; each has its "
                   "runs/<id>/log.txt)\n";
    std::cout << "manifest: " << printablePath((dir / "manifest.jsonl").string()) << "\n";
  }
  return t.complete == static_cast<int>(total) ? 0 : 1;
}

// ---- local ----

class ProgressLine {
 public:
  ProgressLine(std::string name, std::size_t total, bool quiet, std::string running = "running")
      : name_(std::move(name)),
        running_(std::move(running)),
        total_(total),
        quiet_(quiet),
        tty_(isatty(2) != 0) {}

  // done: complete this session, failed, earlier: complete before, meanS: of this session
  void show(int complete, int failed, int running, int earlier, double meanS, int workers,
            bool final = false) {
    if (quiet_) return;
    std::cout.flush();  // what was said before comes first
    const double wall = secondsSince(start_);
    const int doneNow = complete + failed;
    const int left = static_cast<int>(total_) - earlier - doneNow;
    const double eta = doneNow > 0 ? meanS * std::ceil(static_cast<double>(left) / workers) : -1;
    char line[300];
    std::snprintf(line, sizeof line, "sweep %s: %d/%zu complete, %d failed, %d %s, %s elapsed%s%s",
                  name_.c_str(), earlier + complete, total_, failed, running, running_.c_str(),
                  clockText(wall).c_str(), eta >= 0 ? ", ETA " : "",
                  eta >= 0 ? clockText(eta).c_str() : "");
    if (tty_) {
      std::fprintf(stderr, "\r%-100s", line);
      if (final) std::fprintf(stderr, "\n");
    } else if ((final && doneNow != printedDone_) || doneNow != lastDone_ ||
               wall - lastLine_ >= 30.0) {
      printedDone_ = doneNow;
      std::fprintf(stderr, "%s\n", line);
      lastLine_ = wall;
    }
    lastDone_ = doneNow;
  }

 private:
  std::string name_, running_;
  std::size_t total_;
  bool quiet_, tty_;
  Clock::time_point start_ = Clock::now();
  double lastLine_ = -1e9;
  int lastDone_ = -1, printedDone_ = -1;
};

void runLocal(const fs::path& dir, const std::string& name,
              const std::vector<const SweepVariant*>& jobs, std::size_t total, int earlier,
              const std::vector<std::string>& runOptions, const std::string& exe, int workers,
              bool quiet) {
  std::mutex mu;
  std::condition_variable cv;
  std::set<pid_t> running;
  std::vector<std::string> busy;  // variants another process was running (not touched)
  int complete = 0, failed = 0;
  double wallSum = 0;
  ProgressLine progress(name, total, quiet);
  // variants that stopped for memory beside others: run again one at a time, after the rest
  std::vector<std::pair<const SweepVariant*, std::string>> alone;
  int forwarded = 0;
  // runs the list, nThreads at once
  const auto phase = [&](const std::vector<std::pair<const SweepVariant*, std::string>>& list,
                         int nThreads, bool retry) {
    std::size_t next = 0;
    int active = 0;
    // the runs at once share the memory there is: each bounds itself to its share
    // (memory_room.h; they inherit the environment, set before any thread of ours starts)
    if (nThreads > 1)
      ::setenv("ESIM_MEMORY_SHARE", std::to_string(nThreads).c_str(), 1);
    else
      ::unsetenv("ESIM_MEMORY_SHARE");
    std::vector<std::thread> threads;
    for (int w = 0; w < nThreads; ++w) {
      ++active;
      threads.emplace_back([&] {
        for (;;) {
          const SweepVariant* v = nullptr;
          std::string before;  // retry: the message of the run that stopped for memory
          {
            std::lock_guard<std::mutex> lock(mu);
            if (gSignals > 0 || next >= list.size()) break;
            std::tie(v, before) = list[next++];
          }
          VariantJob job{dir, v->id, v->index, runOptions, exe, true};
          if (retry) job.extra["memory_retry"] = {{"workers", workers}, {"message", before}};
          const json r = runVariant(
              job,
              [&](pid_t pid) {
                std::lock_guard<std::mutex> lock(mu);
                running.insert(pid);
                // started just as a stop came: it stops too
                if (gSignals > 0) ::kill(pid, gLastSignal.load());
              },
              [&](pid_t pid) {
                std::lock_guard<std::mutex> lock(mu);
                running.erase(pid);
              });
          std::lock_guard<std::mutex> lock(mu);
          if (r.value("status", "") == kBusy) {
            busy.push_back(v->id);
            continue;
          }
          const bool done = r.value("status", "") == "complete";
          if (!retry) {
            (done ? complete : failed)++;
          } else if (done) {  // counted failed by the first phase
            --failed;
            ++complete;
          }
          if (!retry && nThreads > 1 && stoppedForMemory(r))
            alone.emplace_back(v, r.value("message", ""));
          wallSum += r.value("wall_s", 0.0);
          cv.notify_all();
        }
        std::lock_guard<std::mutex> lock(mu);
        --active;
        cv.notify_all();
      });
    }
    std::unique_lock<std::mutex> lock(mu);
    while (active > 0) {
      cv.wait_for(lock, std::chrono::milliseconds(200));
      // each signal we got is passed on once to every running child
      const int got = gSignals;
      if (got > forwarded) {
        for (pid_t pid : running) ::kill(pid, gLastSignal.load());
        if (forwarded == 0 && !quiet)
          std::fprintf(stderr,
                       "\nsweep: stopping: %zu running variant%s finish their frame "
                       "(again to end them at once); no new one starts\n",
                       running.size(), running.size() == 1 ? "" : "s");
        forwarded = got;
      }
      const int done = complete + failed;
      progress.show(complete, failed, static_cast<int>(running.size()), earlier,
                    done ? wallSum / done : 0, nThreads);
    }
    lock.unlock();
    for (auto& t : threads) t.join();
  };
  std::vector<std::pair<const SweepVariant*, std::string>> all;
  for (const SweepVariant* v : jobs) all.emplace_back(v, "");
  const int nThreads = std::max(1, std::min<int>(workers, static_cast<int>(jobs.size())));
  phase(all, nThreads, false);
  if (!alone.empty() && gSignals == 0) {
    std::sort(alone.begin(), alone.end(),
              [](const auto& a, const auto& b) { return a.first->index < b.first->index; });
    if (!quiet)
      std::fprintf(stderr,
                   "\nsweep: %zu variant%s stopped for memory beside other runs: run again one "
                   "at a time\n",
                   alone.size(), alone.size() == 1 ? "" : "s");
    phase(alone, 1, true);
  }
  progress.show(complete, failed, 0, earlier, 0, nThreads, true);
  if (!busy.empty()) {  // (even with -q: these were not run)
    std::sort(busy.begin(), busy.end());
    std::string ids;
    for (const auto& id : busy) ids += (ids.empty() ? "" : ", ") + id;
    std::fprintf(stderr,
                 "sweep: %s: another esim was running %s (esim dataset run?); left to it, "
                 "not run here: resume the sweep once it ends\n",
                 ids.c_str(), busy.size() == 1 ? "this variant" : "these variants");
  }
}

// ---- Slurm ----

std::string shellQuote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// "1-3,5,7-9" from sorted indices
std::string arraySpec(std::vector<int> idx) {
  std::sort(idx.begin(), idx.end());
  std::string s;
  for (std::size_t i = 0; i < idx.size();) {
    std::size_t j = i;
    while (j + 1 < idx.size() && idx[j + 1] == idx[j] + 1) ++j;
    if (!s.empty()) s += ',';
    s += std::to_string(idx[i]);
    if (j > i) {
      s += '-';
      s += std::to_string(idx[j]);
    }
    i = j + 1;
  }
  return s;
}

struct Resources {
  int memMb = 0, timeMin = 0, cpus = 1;
  std::string basis;  // how they were chosen
};

// the largest peak memory and wall time among the complete variants (0 when none)
void measured(const fs::path& dir, double& peakMb, double& wallS, std::string& from) {
  peakMb = wallS = 0;
  for (const auto& line : manifestLines(dir)) {
    if (line.value("status", "") != "complete") continue;
    const double p =
        line.value("peak_rss_mb", json(0.0)).is_number() ? line["peak_rss_mb"].get<double>() : 0.0;
    const double w = line.value("wall_s", 0.0);
    if (p > peakMb || w > wallS) from += (from.empty() ? "" : ", ") + line.value("id", "");
    peakMb = std::max(peakMb, p);
    wallS = std::max(wallS, w);
  }
}

// the job-array script of the variants `indices`; no --mem and --time lines when res has
// none (a sizing run: the partition's defaults)
fs::path writeScript(const fs::path& absDir, const std::string& file, const SweepSpec& spec,
                     const std::vector<int>& indices, const Resources& res, const std::string& exe,
                     const SweepOptions& opt) {
  const fs::path script = absDir / "slurm" / file;
  std::ostringstream s;
  s << "#!/bin/bash\n"
    << "# written by esim sweep --slurm: one variant of " << absDir.string() << " per array task\n"
    << "# (the folder must be shared with the nodes, and " << exe << " on them)\n"
    << "# resources: " << res.basis << "\n"
    << "#SBATCH --job-name=esim-" << defaultRunFolder(spec.name).filename().string()
    << "\n"  // (the name's letters, digits, '-', '_' and '.'; a line break ended the line)
    << "#SBATCH --array=" << arraySpec(indices)
    << (opt.maxParallel > 0 ? "%" + std::to_string(opt.maxParallel) : "") << "\n"
    << "#SBATCH --ntasks=1\n"
    << "#SBATCH --cpus-per-task=" << res.cpus << "\n";
  if (res.memMb > 0) s << "#SBATCH --mem=" << res.memMb << "M\n";
  if (res.timeMin > 0) s << "#SBATCH --time=" << res.timeMin << "\n";
  s << "#SBATCH --output=" << (absDir / "slurm" / "logs" / "%A_%a.out").string() << "\n";
  for (const auto& a : opt.sbatchArgs) s << "#SBATCH " << a << "\n";
  s << "exec " << shellQuote(exe) << " dataset run " << shellQuote(absDir.string())
    << " \"$SLURM_ARRAY_TASK_ID\"" << (opt.retryFailed ? " --retry-failed" : "") << "\n";
  writeFileAtomic(script, s.str());
  fs::permissions(script, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                  fs::perm_options::add);
  return script;
}

// sbatch the script, wait until its tasks have left the queue (Ctrl-C: scancel), then record
// the tasks that left no result; returns false when cancelled
bool submitAndWait(const fs::path& dir, const fs::path& script,
                   const std::vector<const SweepVariant*>& jobs, std::size_t total,
                   const std::string& name, bool quiet) {
  // the results of the variants submitted go: each task writes its own
  std::error_code ec;
  for (const auto* v : jobs) fs::remove(dataset::variantDir(dir, v->id) / "result.json", ec);
  writeManifest(dir);
  const Captured sub = capture({"sbatch", "--parsable", script.string()});
  const std::string jobId = trim(sub.output.substr(0, sub.output.find(';')));
  if (sub.exitCode != 0 || jobId.empty() ||
      jobId.find_first_not_of("0123456789") != std::string::npos)
    throw Error("sbatch " + script.string() + " failed: " + trim(sub.output), ErrorKind::Run);
  if (!quiet)
    std::cout << "sweep: submitted job " << jobId << " (" << jobs.size() << " task"
              << (jobs.size() == 1 ? "" : "s") << "); waiting (Ctrl-C cancels it)" << std::endl;
  ProgressLine progress(name, total, quiet, "queued or running");
  const int earlier = tally(dir).complete;
  bool cancelled = false, gaveUp = false;
  int squeueFailures = 0;
  for (;;) {
    if (gSignals > 0 && !cancelled) {
      capture({"scancel", jobId});
      cancelled = true;
      if (!quiet) std::cerr << "\nsweep: cancelled job " << jobId << "\n";
    }
    // done when the job has left the queue; a controller that does not answer for a
    // minute ends the wait too (the tasks still record themselves)
    const Captured q = capture({"squeue", "-h", "-j", jobId, "-o", "%i"});
    if (q.exitCode == 0 && trim(q.output).empty()) break;
    if (q.exitCode != 0) {
      if (q.output.find("Invalid job id") != std::string::npos) break;
      if (++squeueFailures >= 30) {
        std::cerr << "\nsweep: squeue keeps failing (" << trim(q.output)
                  << "); not waiting for job " << jobId << " any longer\n";
        gaveUp = true;
        break;
      }
    } else {
      squeueFailures = 0;
    }
    int done = 0, failed = 0;
    for (const auto* v : jobs) {
      const json r = readResult(dir, v->id);
      if (r.is_object()) (r.value("status", "") == "complete" ? done : failed)++;
    }
    progress.show(done, failed, static_cast<int>(jobs.size()) - done - failed, earlier, 0, 1);
    for (int i = 0; i < 20 && (gSignals == 0 || cancelled); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  progress.show(0, 0, 0, tally(dir).complete, 0, 1, true);
  // a task that left no result was killed before it could write one
  const fs::path absDir = fs::absolute(dir).lexically_normal();
  for (const auto* v : jobs) {
    if (gaveUp || readResult(dir, v->id).is_object()) continue;
    const std::string task = jobId + "_" + std::to_string(v->index);
    const json r = {
        {"id", v->id},
        {"index", v->index},
        {"status", cancelled ? "interrupted" : "failed"},
        {"exit_code", nullptr},
        {"slurm_job", task},
        {"finished", utcNow()},
        {"message", std::string(cancelled ? "cancelled"
                                          : "the Slurm task left no result (a time or memory "
                                            "limit?)") +
                        ": see " + (absDir / "slurm" / "logs" / (task + ".out")).string()}};
    writeResult(dir, v->id, r);
  }
  writeManifest(dir);
  return !cancelled;
}

int runSlurm(const fs::path& dir, const SweepSpec& spec, const std::vector<SweepVariant>& vs,
             std::vector<const SweepVariant*> jobs, const std::vector<std::string>& runOptions,
             const std::string& exe, const SweepOptions& opt) {
  const fs::path absDir = fs::absolute(dir).lexically_normal();
  fs::create_directories(absDir / "slurm" / "logs");
  Resources res;
  // cpus: the solver threads, and one more for a background rebuild
  for (const auto& v : vs)
    res.cpus = std::max(res.cpus, v.scenario.solvers.electricThreads +
                                      (v.scenario.solvers.rebuildMode == RebuildMode::Background));
  if (opt.cpus > 0) res.cpus = opt.cpus;
  double peakMb = 0, wallS = 0;
  std::string from;
  measured(dir, peakMb, wallS, from);
  if ((opt.memMb <= 0 || opt.timeMin <= 0) && peakMb <= 0 && !jobs.empty()) {
    // nothing measured yet: one variant sizes the others, on the cluster when submitting
    // (with the partition's default limits), else here
    const SweepVariant* first = jobs.front();
    jobs.erase(jobs.begin());
    if (opt.submit) {
      if (!opt.quiet)
        std::cout << "sweep: sizing the tasks: " << first->id
                  << " runs first, alone (--mem-mb and --time-min skip this)\n";
      Resources probe = res;
      probe.basis = "sizing run (the partition's default memory and time)";
      const fs::path script =
          writeScript(absDir, "measure.sbatch", spec, {first->index}, probe, exe, opt);
      if (!submitAndWait(dir, script, {first}, vs.size(), spec.name, opt.quiet))
        return finalReport(dir, vs.size(), opt.quiet);
    } else {
      if (!opt.quiet)
        std::cerr << "sweep: sizing the tasks: running " << first->id
                  << " here first (--mem-mb and --time-min skip this)\n";
      VariantJob job{dir, first->id, first->index, runOptions, exe, false};
      runVariant(job, nullptr, nullptr);
    }
    const json r = readResult(dir, first->id);
    if (!r.is_object() || r.value("status", "") != "complete") {
      std::cerr << "sweep: the sizing run " << first->id << " did not complete"
                << (r.is_object() ? ": " + r.value("message", "") : std::string())
                << "; give --mem-mb and --time-min to submit without it\n";
      return finalReport(dir, vs.size(), opt.quiet);
    }
    measured(dir, peakMb, wallS, from);
  }
  // the margins: other variants may cut more (ruptures, rebuilds) than the one measured
  res.memMb =
      opt.memMb > 0 ? opt.memMb : static_cast<int>(std::ceil((1.5 * peakMb + 256.0) / 64.0) * 64.0);
  res.timeMin = opt.timeMin > 0 ? opt.timeMin : static_cast<int>(std::ceil(3.0 * wallS / 60.0)) + 5;
  {
    std::ostringstream b;
    b.precision(4);
    if (opt.memMb > 0 && opt.timeMin > 0)
      b << "given (--mem-mb, --time-min)";
    else
      b << "measured on " << from << ": peak " << peakMb << " MB, wall " << wallS
        << " s; mem = 1.5 x peak + 256 MB, time = 3 x wall + 5 min (unless given)";
    res.basis = b.str();
  }
  if (jobs.empty()) {
    if (!opt.quiet) std::cout << "sweep: nothing left to submit\n";
    return finalReport(dir, vs.size(), opt.quiet);
  }
  std::vector<int> indices;
  for (const auto* v : jobs) indices.push_back(v->index);
  const fs::path script = writeScript(absDir, "sweep.sbatch", spec, indices, res, exe, opt);
  if (!opt.quiet)
    std::cout << "sweep: wrote " << printablePath(script.string()) << ": " << jobs.size() << " task"
              << (jobs.size() == 1 ? "" : "s") << ", --cpus-per-task=" << res.cpus
              << " --mem=" << res.memMb << "M --time=" << res.timeMin << " (" << res.basis << ")\n";
  if (!opt.submit) {
    if (!opt.quiet)
      std::cout << "submit it with: sbatch " << printablePath(script.string())
                << "\n(each task writes its result and the manifest as it ends)\n";
    writeManifest(dir);
    return 0;
  }
  submitAndWait(dir, script, jobs, vs.size(), spec.name, opt.quiet);
  return finalReport(dir, vs.size(), opt.quiet);
}

}  // namespace

std::string esimExecutable() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("/proc/self/exe") : p.string();
}

namespace {
// a control character (a line break) ends a line of the Slurm script
bool hasControlCharacter(const std::string& text) {
  return std::any_of(text.begin(), text.end(),
                     [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7F; });
}
}  // namespace

void checkSbatchArgs(const std::vector<std::string>& args) {
  // the options the script sets itself, and the esim option that sets each
  static const std::vector<std::pair<std::vector<std::string>, std::string>> owned{
      {{"--array", "-a"},
       "esim writes the job array, one task per variant (--max-parallel "
       "limits how many run at once)"},
      {{"--output", "-o", "--error", "-e"}, "esim writes each task's log to DIR/slurm/logs/"},
      {{"--ntasks", "-n"}, "a variant is one task"},
      {{"--cpus-per-task", "-c"}, "give --cpus"},
      {{"--mem", "--mem-per-cpu", "--mem-per-gpu"}, "give --mem-mb (esim writes --mem)"},
      {{"--time", "-t"}, "give --time-min"},
  };
  for (const std::string& a : args) {
    if (hasControlCharacter(a))
      throw Error("--sbatch-arg " + quoteInMessage(a) +
                  ": a line break or control character would end the #SBATCH line; give one "
                  "option per --sbatch-arg");
    ESIM_VERIFY(
        !a.empty() && a[0] == '-',
        "--sbatch-arg " + quoteInMessage(a) + ": expected an sbatch option, e.g. --partition=long");
    const std::string name = a.substr(0, a.find_first_of("= "));
    for (const auto& [names, why] : owned)
      for (const std::string& n : names)
        if (name == n || (n.size() == 2 && a.rfind(n, 0) == 0 && a.size() > 2 && a[1] != '-'))
          throw Error("--sbatch-arg " + quoteInMessage(a) + ": " + n + " is set by esim: " + why);
  }
}

int runSweep(const SweepOptions& opt, const RunOptionsCheck& checkRunOptions) {
  if (opt.workers < 1) throw Error("--workers: expected 1 or more");
  if (opt.submit && !opt.slurm) throw Error("--submit goes with --slurm");
  checkSbatchArgs(opt.sbatchArgs);
  // ---- 1. the sweep file, every variant, the run options ----
  const SweepSpec spec = loadSweepSpec(opt.spec);
  const std::vector<std::string> runOptions = allRunOptions(spec, opt);
  for (const std::string& a : opt.runArgs)  // as run_options (every variant failed on -o)
    if (const std::string why = sweepOwnedRunOption(a); !why.empty())
      throw Error("--run-args: " + why);
  if (checkRunOptions) {
    try {
      checkRunOptions(runOptions);
    } catch (const Error& e) {
      throw Error((opt.runArgs.empty() ? spec.runOptionsWhere : std::string("--run-args")) +
                  ": run_options: " + e.what());
    }
  }
  const std::vector<SweepVariant> vs = expandSweep(spec);
  if (opt.dryRun) {
    std::cout << "sweep " << spec.name << ": " << vs.size() << " variant"
              << (vs.size() == 1 ? "" : "s") << " of " << spec.base << ", all checked\n";
    for (const auto& v : vs) std::cout << "  " << v.id << "  " << jsonText(v.values) << "\n";
    return 0;
  }
  if (opt.outDir.empty()) throw Error("-o DIR: the sweep's folder is required");
  const fs::path dir(opt.outDir);
  if (opt.slurm && hasControlCharacter(opt.outDir))  // on the script's #SBATCH, comment lines
    throw Error("-o " + quoteInMessage(opt.outDir) +
                ": a folder name with a line break or control character cannot go into the "
                "Slurm script; choose another");
  // ---- 2. the folder (this sweep's alone until it ends) ----
  FolderLock lock;
  lockSweepFolder(dir, lock);
  checkFolder(dir, spec, vs, runOptions);
  const std::string exe = esimExecutable();
  writeFolder(dir, spec, vs, runOptions, exe);
  writeManifest(dir);
  const std::vector<const SweepVariant*> jobs = toRun(dir, vs, opt.retryFailed);
  gSession.start = Clock::now();
  for (const auto* v : jobs) gSession.ids.insert(v->id);
  const int earlier = tally(dir).complete;
  if (!opt.quiet)
    std::cout << "sweep " << spec.name << ": " << vs.size() << " variants -> "
              << printablePath(dir.string()) << " (" << earlier << " complete before, "
              << jobs.size() << " to run"
              << (opt.slurm ? ", on Slurm" : ", " + std::to_string(opt.workers) + " at once") << ")"
              << std::endl;  // before the progress line (stderr)
  catchSignals();
  // ---- 3-4. run ----
  if (opt.slurm) return runSlurm(dir, spec, vs, jobs, runOptions, exe, opt);
  runLocal(dir, spec.name, jobs, vs.size(), earlier, runOptions, exe, opt.workers, opt.quiet);
  return finalReport(dir, vs.size(), opt.quiet);
}

int runSweepVariant(const std::string& dirText, const std::string& variant, bool retryFailed) {
  const fs::path dir(dirText);
  const json sweep = readSweepJson(dir);
  const json* found = nullptr;
  for (const auto& v : sweep.at("variants"))
    if (v.at("id") == variant || std::to_string(v.at("index").get<int>()) == variant) found = &v;
  if (!found)
    throw Error(dir.string() + ": no variant " + quoteInMessage(variant) +
                " (ids v0000.., or their index)");
  const std::string id = found->at("id");
  const json old = readResult(dir, id);
  const std::string status = old.is_object() ? old.value("status", "") : "";
  std::error_code ec;
  if (status == "complete" && fs::is_directory(dataset::runDir(dir, id), ec)) {
    std::cout << id << ": already complete\n";
    return 0;
  }
  if (status == "failed" && !retryFailed) {
    std::cout << id << ": failed earlier (" << printableMessage(old.value("message", ""), 300)
              << "); --retry-failed runs it again\n";
    return 1;
  }
  catchSignals();  // a stop (scancel, a time limit) reaches the run too: it is recorded
  const std::vector<std::string> runOptions =
      sweep.value("run_options", std::vector<std::string>{});
  VariantJob job{dir, id, found->at("index").get<int>(), runOptions, esimExecutable(), false};
  const json r = runVariant(job, nullptr, nullptr);
  if (r.value("status", "") == kBusy)
    throw Error(dataset::variantDir(dir, id).string() +
                ": another esim is running this variant; nothing was changed");
  std::cout << id << ": " << r.value("status", "") << " in " << r.value("wall_s", 0.0) << " s"
            << (r.value("message", "").empty() ? ""
                                               : ": " + printableMessage(r.value("message", "")))
            << "\n";
  return r.value("status", "") == "complete" ? 0 : 1;
}

}  // namespace esim::app
