// run_report.cpp - timing statistics and report files (see run_report.h).
#include "tools/app/run_report.h"

#include <fcntl.h>
#include <sched.h>
#include <sys/utsname.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <fstream>
#include <sstream>
#include <thread>

#include "sim/core_error.h"
#include "tools/app/memory_room.h"

namespace esim::app {

namespace {

// p-th percentile by linear interpolation between closest ranks (sorted input)
double percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0;
  const double pos = p / 100.0 * (sorted.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - lo) * (sorted[hi] - sorted[lo]);
}

bool stagePresent(const std::vector<FrameRecord>& records, Stage stage) {
  for (const auto& r : records)
    if (r.status[static_cast<int>(stage)] != StageStatus::Absent) return true;
  return false;
}

}  // namespace

nlohmann::json statsJson(const StageStats& s) {
  return {{"frames_ran", s.ran}, {"frames_skipped", s.skipped}, {"mean_ms", s.meanMs},
          {"p50_ms", s.p50Ms},   {"p95_ms", s.p95Ms},           {"p99_ms", s.p99Ms},
          {"max_ms", s.maxMs}};
}

StageStats seriesStats(std::vector<double> ms) {
  StageStats s;
  s.ran = static_cast<int>(ms.size());
  if (ms.empty()) return s;
  std::sort(ms.begin(), ms.end());
  double sum = 0;
  for (double v : ms) sum += v;
  s.meanMs = sum / ms.size();
  s.p50Ms = percentile(ms, 50);
  s.p95Ms = percentile(ms, 95);
  s.p99Ms = percentile(ms, 99);
  s.maxMs = ms.back();
  return s;
}

StageStats stageStats(const std::vector<FrameRecord>& records, Stage stage) {
  std::vector<double> ms;
  int skipped = 0;
  for (const auto& r : records) {
    const auto st = r.status[static_cast<int>(stage)];
    if (st == StageStatus::Ran) ms.push_back(r.ms[static_cast<int>(stage)]);
    if (st == StageStatus::Skipped) ++skipped;
  }
  StageStats s = seriesStats(ms);
  s.skipped = skipped;
  return s;
}

double interactiveMs(const FrameRecord& r) {
  return r.physicsMs() + r.ms[static_cast<int>(Stage::Render)];
}

bool overBudget(const FrameRecord& r) {
  const double scale = std::pow(10.0, kCsvMsDecimals);
  return std::round(interactiveMs(r) * scale) / scale > kBudgetMs;
}

namespace {

void timingCsvHeader(std::ostream& os, const std::vector<Stage>& present, bool structural) {
  os << "frame,time_s";
  for (Stage s : present) os << ',' << stageName(s) << "_ms";
  os << ",interactive_ms,over_budget,period_ms,generator_on,contacts,power_w,max_temperature_c";
  os << (structural ? ",rebuild_wait_ms,max_von_mises_pa,removed_tets\n" : "\n");
}

void timingCsvRow(std::ostream& os, const FrameRecord& r, double periodMs,
                  const std::vector<Stage>& present, bool structural) {
  os.setf(std::ios::fixed);
  os.precision(kCsvMsDecimals);
  os << r.frame << ',' << r.timeS;
  for (Stage s : present) {
    const int i = static_cast<int>(s);
    if (r.status[i] == StageStatus::Skipped)
      os << ",skipped";
    else if (r.status[i] == StageStatus::Absent)
      os << ",";
    else
      os << ',' << r.ms[i];
  }
  const double im = interactiveMs(r);
  os << ',' << im << ',' << (overBudget(r) ? 1 : 0) << ',' << periodMs << ','
     << (r.generatorOn ? 1 : 0) << ',' << r.contactNodes << ',';
  os.precision(6);
  os << r.powerW << ',' << r.maxTemperatureC;
  if (structural) {
    os.precision(kCsvMsDecimals);
    os << ',' << r.rebuildWaitMs;
    os.precision(6);
    os << ',' << r.maxVonMisesPa << ',' << r.removedTets;
  }
  os << '\n';
}

// the stage columns of these records: a stage the scene did not build has none
std::vector<Stage> presentStages(const std::vector<FrameRecord>& records) {
  std::vector<Stage> present;
  for (int s = 0; s < kStageCount; ++s)
    if (stagePresent(records, static_cast<Stage>(s))) present.push_back(static_cast<Stage>(s));
  return present;
}

// the whole of `text` to fd, retried across partial writes; false on an error
bool writeAll(int fd, const std::string& text) {
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<size_t>(n);
  }
  return true;
}

}  // namespace

std::string timingCsv(const std::vector<FrameRecord>& records,
                      const std::vector<double>& periodsMs) {
  ESIM_CHECK(periodsMs.size() == records.size());
  const std::vector<Stage> present = presentStages(records);
  const bool structural = stagePresent(records, Stage::SolveStress);
  std::ostringstream os;
  timingCsvHeader(os, present, structural);
  for (size_t f = 0; f < records.size(); ++f)
    timingCsvRow(os, records[f], periodsMs[f], present, structural);
  return os.str();
}

void TimingCsvStream::add(const FrameRecord& record, double periodMs) {
  if (stopped_) return;
  std::ostringstream os;
  if (fd_ < 0) {
    const std::vector<FrameRecord> first{record};
    present_ = presentStages(first);
    structural_ = stagePresent(first, Stage::SolveStress);
    fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) {
      stopped_ = true;
      return;
    }
    timingCsvHeader(os, present_, structural_);
  }
  timingCsvRow(os, record, periodMs, present_, structural_);
  if (!writeAll(fd_, os.str())) remove();  // (a cut row is never left)
}

TimingCsvStream::~TimingCsvStream() {
  if (fd_ >= 0) ::close(fd_);
}

void TimingCsvStream::remove() {
  stopped_ = true;
  if (fd_ < 0) return;
  ::close(fd_);
  fd_ = -1;
  ::unlink(path_.c_str());
}

nlohmann::json timingJson(const std::vector<FrameRecord>& records, const nlohmann::json& extra) {
  nlohmann::json j;
  j["frames"] = records.size();
  j["budget_ms"] = kBudgetMs;
  nlohmann::json stages = nlohmann::json::object();
  for (int s = 0; s < kStageCount; ++s) {
    const Stage st = static_cast<Stage>(s);
    if (!stagePresent(records, st)) continue;
    stages[stageName(st)] = statsJson(stageStats(records, st));
  }
  j["stages"] = stages;
  std::vector<double> physics, interactive;
  int over = 0;
  for (const auto& r : records) {
    physics.push_back(r.physicsMs());
    interactive.push_back(interactiveMs(r));
    over += overBudget(r);
  }
  j["physics_total"] = statsJson(seriesStats(physics));
  j["interactive_total"] = statsJson(seriesStats(interactive));
  j["interactive_total"]["note"] = "physics stages + snapshot + render, against the 30 Hz budget";
  j["frames_over_budget"] = over;
  for (auto it = extra.begin(); it != extra.end(); ++it) j[it.key()] = it.value();
  return j;
}

nlohmann::json chromeTrace(const std::vector<FrameRecord>& records,
                           const std::vector<double>& frameStartUs,
                           const std::vector<double>& drawStartUs) {
  nlohmann::json events = nlohmann::json::array();
  for (size_t f = 0; f < records.size(); ++f) {
    double ts = f < frameStartUs.size() ? frameStartUs[f] : 0;
    double drawTs = f < drawStartUs.size() ? drawStartUs[f] : -1;
    for (int s = 0; s < kStageCount; ++s) {
      const StageStatus st = records[f].status[s];
      if (st == StageStatus::Absent) continue;
      // the drawing thread's stages on a track of their own, from when it began the frame
      const bool drawn = drawTs >= 0 && (s == static_cast<int>(Stage::Render) ||
                                         s == static_cast<int>(Stage::Encode) ||
                                         s == static_cast<int>(Stage::Labels));
      // a skipped stage's event is the time it took to find it had nothing to do
      const double dur = records[f].ms[s] * 1000.0;
      nlohmann::json args = {{"frame", records[f].frame}};
      if (st == StageStatus::Skipped) args["skipped"] = true;
      events.push_back({{"name", stageName(static_cast<Stage>(s))},
                        {"cat", "frame"},
                        {"ph", "X"},
                        {"ts", drawn ? drawTs : ts},
                        {"dur", dur},
                        {"pid", 1},
                        {"tid", drawn ? 2 : 1},
                        {"args", args}});
      (drawn ? drawTs : ts) += dur;
    }
  }
  return {{"traceEvents", events}, {"displayTimeUnit", "ms"}};
}

std::vector<double> framePeriodsMs(const std::vector<double>& doneUs) {
  std::vector<double> ms;
  for (size_t f = 0; f < doneUs.size(); ++f)
    ms.push_back((doneUs[f] - (f > 0 ? doneUs[f - 1] : 0.0)) / 1000.0);
  return ms;
}

int countOverBudget(const std::vector<double>& ms) {
  return static_cast<int>(
      std::count_if(ms.begin(), ms.end(), [](double x) { return x > kBudgetMs; }));
}

std::vector<double> frameLatenciesMs(const std::vector<double>& startUs,
                                     const std::vector<double>& doneUs) {
  std::vector<double> ms;
  for (size_t f = 0; f < std::min(startUs.size(), doneUs.size()); ++f)
    ms.push_back((doneUs[f] - startUs[f]) / 1000.0);
  return ms;
}

extern "C" char* openblas_get_corename(void);

nlohmann::json machineInfo() {
  nlohmann::json j;
  std::ifstream cpu("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpu, line)) {
    if (line.rfind("model name", 0) == 0) {
      j["cpu"] = line.substr(line.find(':') + 2);
      break;
    }
  }
  j["hardware_threads"] = std::thread::hardware_concurrency();
  utsname u{};
  if (uname(&u) == 0) j["system"] = std::string(u.sysname) + " " + u.release + " " + u.machine;
  const char* lp = std::getenv("LP_NUM_THREADS");
  j["LP_NUM_THREADS"] = lp ? lp : "";
  const char* core = openblas_get_corename();
  j["openblas_core"] = core ? core : "";
  j["memory_bound"] = addressSpaceBound();  // empty: none set (tools/app/memory_room.h)
  j["transparent_huge_pages"] = transparentHugePagesNote();
  j["malloc"] = mallocNote();
  return j;
}

double processCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double threadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

int usableCpus() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0 && CPU_COUNT(&set) > 0) return CPU_COUNT(&set);
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

}  // namespace esim::app
