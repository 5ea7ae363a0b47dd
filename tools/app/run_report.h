// run_report.h - the timing report of a run: timing.csv, timing.json, trace.json.
//
// One FrameRecord per frame (sim/simulation.h). Statistics per stage are taken over
// the frames where the stage ran (skipped frames count in `skipped`). The 30 Hz
// budget (33.3 ms) applies to the interactive part: physics + snapshot + render;
// encoding runs on its own thread and is reported apart.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/simulation.h"

namespace esim::app {

struct StageStats {
  int ran = 0, skipped = 0;
  double meanMs = 0, p50Ms = 0, p95Ms = 0, p99Ms = 0, maxMs = 0;
};

// statistics of one stage over the records (ran frames only)
StageStats stageStats(const std::vector<FrameRecord>& records, Stage stage);

// statistics of a derived per-frame time (e.g. physics + render)
StageStats seriesStats(std::vector<double> ms);

// frames_ran, frames_skipped, mean_ms, p50_ms, p95_ms, p99_ms, max_ms
nlohmann::json statsJson(const StageStats& stats);

// interactive time of a frame: the simulation stages + render [ms]
double interactiveMs(const FrameRecord& record);

constexpr double kBudgetMs = 1000.0 / 30.0;
constexpr int kCsvMsDecimals = 4;  // timing.csv's times [ms]
// whether a frame is over the budget, judged on its interactive time as timing.csv prints
// it (kCsvMsDecimals), so that a row's over_budget never contradicts its interactive_ms
bool overBudget(const FrameRecord& record);

// timing.csv: frame,time_s,<stage columns>,interactive_ms,over_budget,period_ms,generator_on,
// contacts,power_w,max_temperature_c[,rebuild_wait_ms,max_von_mises_pa,removed_tets
// (structural)]; a stage the scene did not build has no column, "skipped" where it had nothing
// to do. periodsMs: each frame's period (framePeriodsMs: since the frame before it was done,
// what a viewer sees; timing.json's frame_period), one per record
std::string timingCsv(const std::vector<FrameRecord>& records,
                      const std::vector<double>& periodsMs);

// timing.csv's rows written as the frames are done, so that a run killed mid-way (the
// kernel's out-of-memory killer, kill -9) leaves the rows of its frames: the header and a
// row per add(), each flushed whole, in `path` (DIR.partial/timing.csv.partial), with the
// columns of the first record (the scene's phases). The run's own timing.csv replaces it
// (remove()). A write that fails removes the file and stops the stream: never a cut row,
// never the run's failure (the reports at the end say what the disk did).
class TimingCsvStream {
 public:
  explicit TimingCsvStream(std::string path) : path_(std::move(path)) {}
  ~TimingCsvStream();  // closes the file, which stays (a run that ended before its reports)
  TimingCsvStream(const TimingCsvStream&) = delete;
  TimingCsvStream& operator=(const TimingCsvStream&) = delete;
  void add(const FrameRecord& record, double periodMs);
  void remove();

 private:
  std::string path_;
  std::vector<Stage> present_;
  bool structural_ = false, stopped_ = false;
  int fd_ = -1;
};

// timing.json: per stage and in total mean/p50/p95/p99/max, frames over budget, machine
nlohmann::json timingJson(const std::vector<FrameRecord>& records, const nlohmann::json& extra);

// trace.json: Chrome trace format (Perfetto), one complete event per stage per frame, back
// to back from the frame's start; a skipped stage's event (args.skipped) is the time it took
// to find nothing to do, so a frame's events before encode_wait sum to its interactive time.
// With drawStartUs (a frame drawn on a thread of its own), the render, encode_wait and
// write_labels events are on track 2, back to back from when that thread began the frame.
nlohmann::json chromeTrace(const std::vector<FrameRecord>& records,
                           const std::vector<double>& frameStartUs,
                           const std::vector<double>& drawStartUs = {});

// the time between frames whose outputs are done (the first from the loop's start), and
// each frame's latency from the start of its physics to its outputs done [ms]
std::vector<double> framePeriodsMs(const std::vector<double>& doneUs);
// how many of these times [ms] (frame periods, say) are over the 30 Hz budget
int countOverBudget(const std::vector<double>& ms);
std::vector<double> frameLatenciesMs(const std::vector<double>& startUs,
                                     const std::vector<double>& doneUs);

// "Intel(R) Xeon(R) ..." from /proc/cpuinfo, and the core count
nlohmann::json machineInfo();

// CPU time of the whole process (every thread: the frame loop's, the solvers' helpers,
// llvmpipe's, the encoder's), or of the calling thread [s]
double processCpuSeconds();
double threadCpuSeconds();
// the CPUs this process may run on (its affinity: taskset, a cpuset), at least 1
int usableCpus();

}  // namespace esim::app
