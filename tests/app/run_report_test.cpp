// run_report_test.cpp - the timing reports of a run (tools/app/run_report.cpp) on records
// made up inline: their structure, per-stage sums that match the frame totals, and the rows
// streamed while a run goes.
#include "tools/app/run_report.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>

#include "tests/app/timing_reports_check.h"

namespace esim::app {
namespace {

FrameRecord record(int frame, std::initializer_list<std::pair<Stage, double>> ran,
                   std::initializer_list<std::pair<Stage, double>> skipped = {}) {
  FrameRecord r;
  r.frame = frame;
  r.timeS = frame / 30.0;
  for (auto [s, ms] : ran) {
    r.ms[static_cast<int>(s)] = ms;
    r.status[static_cast<int>(s)] = StageStatus::Ran;
  }
  for (auto [s, ms] : skipped) {
    r.ms[static_cast<int>(s)] = ms;
    r.status[static_cast<int>(s)] = StageStatus::Skipped;
  }
  return r;
}

// a structural scene: frame 2 rebuilds and waited for it (over budget), frame 1 skips the
// potential (no contact)
std::vector<FrameRecord> structuralFrames() {
  using S = Stage;
  std::vector<FrameRecord> r;
  r.push_back(record(0,
                     {{S::MoveTool, 0.01},
                      {S::FindContacts, 0.02},
                      {S::SolvePotential, 1.5},
                      {S::Heat, 0.75},
                      {S::SolveStress, 4.0},
                      {S::Snapshot, 0.1},
                      {S::Render, 12.0},
                      {S::Encode, 0.3}},
                     {{S::Rupture, 0.001}, {S::Rebuild, 0.002}}));
  r.push_back(record(1,
                     {{S::MoveTool, 0.01},
                      {S::FindContacts, 0.02},
                      {S::Heat, 0.5},
                      {S::SolveStress, 4.5},
                      {S::Snapshot, 0.1},
                      {S::Render, 11.0},
                      {S::Encode, 0.2}},
                     {{S::SolvePotential, 0.003}, {S::Rupture, 0.001}, {S::Rebuild, 0.002}}));
  r.push_back(record(2, {{S::MoveTool, 0.01},
                         {S::FindContacts, 0.02},
                         {S::SolvePotential, 2.0},
                         {S::Heat, 0.5},
                         {S::SolveStress, 4.0},
                         {S::Rupture, 0.25},
                         {S::Rebuild, 150.0},
                         {S::Snapshot, 0.3},
                         {S::Render, 13.0},
                         {S::Encode, 0.1}}));
  r[2].rebuildWaitMs = 120.5;
  r[2].removedTets = 7;
  r[2].powerW = 21.5;
  r[2].maxTemperatureC = 101.25;
  return r;
}

TEST(RunReport, StageSumsMatchTheFrameTotals) {
  const std::vector<FrameRecord> records = structuralFrames();
  const std::vector<double> startUs = {0, 40000, 80000};
  const std::vector<double> periods = framePeriodsMs({38000, 70000, 240000});
  const std::string csv = timingCsv(records, periods);
  nlohmann::json extra = {{"scenario", "inline"}};
  extra["frame_period"] = statsJson(seriesStats(periods));
  extra["frame_period"]["frames_over_budget"] = countOverBudget(periods);
  const nlohmann::json timing = timingJson(records, extra);
  const nlohmann::json trace = chromeTrace(records, startUs);
  test::checkTimingReports(csv, timing, trace, 1e-9 + 1e-4);
  // the numbers themselves
  EXPECT_NEAR(interactiveMs(records[2]), 0.01 + 0.02 + 2.0 + 0.5 + 4.0 + 0.25 + 150.0 + 0.3 + 13.0,
              1e-12);
  EXPECT_NEAR(interactiveMs(records[1]),
              0.01 + 0.02 + 0.003 + 0.5 + 4.5 + 0.001 + 0.002 + 0.1 + 11.0, 1e-12);
  EXPECT_EQ(timing["frames_over_budget"], 1);
  EXPECT_EQ(timing["stages"]["solve_potential"]["frames_skipped"], 1);
  EXPECT_EQ(timing["stages"]["rebuild"]["frames_ran"], 1);
  EXPECT_NEAR(timing["stages"]["heat"]["mean_ms"].get<double>(), (0.75 + 0.5 + 0.5) / 3, 1e-12);
  EXPECT_NEAR(timing["physics_total"]["max_ms"].get<double>(), interactiveMs(records[2]) - 13.0,
              1e-12);
  EXPECT_EQ(timing["scenario"], "inline");
  const auto rows = test::parseTimingCsv(csv);
  EXPECT_EQ(rows[0].at("period_ms"), "38.0000");
  EXPECT_EQ(rows[1].at("period_ms"), "32.0000");
  EXPECT_EQ(rows[2].at("period_ms"), "170.0000");
  EXPECT_EQ(timing["frame_period"]["frames_over_budget"], 2);
  // 8 + 2 skipped, 7 + 3 skipped, 10 events; the skipped ones flagged
  EXPECT_EQ(trace["traceEvents"].size(), 30u);
  int skippedEvents = 0;
  for (const auto& e : trace["traceEvents"]) skippedEvents += e["args"].value("skipped", false);
  EXPECT_EQ(skippedEvents, 5);
  EXPECT_DOUBLE_EQ(trace["traceEvents"][10]["ts"].get<double>(), 40000.0);  // frame 1's start
}

// CI once saw a frame of 33.33334 ms printed 33.3333 with over_budget 1: a row's flag is
// judged on the time as printed, and the JSON's count agrees with the rows
TEST(RunReport, AFrameAtTheBudgetIsJudgedAsItIsPrinted) {
  using S = Stage;
  std::vector<FrameRecord> r;
  r.push_back(record(0, {{S::Heat, 20.0}, {S::Render, 13.33334}}));  // prints 33.3333
  r.push_back(record(1, {{S::Heat, 20.0}, {S::Render, 13.33336}}));  // prints 33.3334
  r.push_back(record(2, {{S::Heat, 20.0}, {S::Render, 13.0}}));
  EXPECT_FALSE(overBudget(r[0]));
  EXPECT_TRUE(overBudget(r[1]));
  EXPECT_FALSE(overBudget(r[2]));
  const std::string csv = timingCsv(r, {40.0, 40.0, 40.0});
  EXPECT_NE(csv.find(",33.3333,0,"), std::string::npos) << csv;
  EXPECT_NE(csv.find(",33.3334,1,"), std::string::npos) << csv;
  EXPECT_EQ(timingJson(r, {})["frames_over_budget"].get<int>(), 1);
  test::checkTimingReports(csv, timingJson(r, {}), chromeTrace(r, {0, 40000, 80000}), 1e-9 + 1e-4);
}

// frame periods from the times the frames were done (the first from the loop's start), and
// those over 1000 / 30 ms counted
TEST(RunReport, PeriodsOverTheBudgetAreCounted) {
  const std::vector<double> ms = framePeriodsMs({40000, 60000, 93000, 130000});
  ASSERT_EQ(ms.size(), 4u);
  EXPECT_NEAR(ms[0], 40.0, 1e-12);
  EXPECT_NEAR(ms[1], 20.0, 1e-12);
  EXPECT_NEAR(ms[2], 33.0, 1e-12);
  EXPECT_NEAR(ms[3], 37.0, 1e-12);
  EXPECT_EQ(countOverBudget(ms), 2);
  EXPECT_EQ(countOverBudget({}), 0);
  EXPECT_EQ(countOverBudget({33.3333, 33.3334}), 1);
}

TEST(RunReport, CsvHasTheColumnsThePlotNeeds) {
  const std::string csv = timingCsv(structuralFrames(), {40.0, 30.0, 170.0});
  std::string header;
  const auto rows = test::parseTimingCsv(csv, &header);
  EXPECT_EQ(header,
            "frame,time_s,move_tool_ms,find_contacts_ms,solve_potential_ms,heat_ms,"
            "solve_stress_ms,rupture_ms,rebuild_ms,snapshot_ms,render_ms,encode_wait_ms,"
            "interactive_ms,over_budget,period_ms,generator_on,contacts,power_w,max_temperature_c,"
            "rebuild_wait_ms,max_von_mises_pa,removed_tets");
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[1].at("solve_potential_ms"), "skipped");
  EXPECT_EQ(rows[2].at("rebuild_wait_ms"), "120.5000");
  EXPECT_EQ(rows[2].at("removed_tets"), "7");
  EXPECT_EQ(rows[2].at("power_w"), "21.500000");
  EXPECT_EQ(rows[2].at("max_temperature_c"), "101.250000");
  EXPECT_EQ(rows[0].at("rebuild_wait_ms"), "0.0000");
}

// a scene without the structural phase: no structural columns, absent stages have neither
// a column nor trace events
TEST(RunReport, AbsentStagesHaveNoColumnAndNoEvent) {
  std::vector<FrameRecord> records = {
      record(0, {{Stage::MoveTool, 0.01}, {Stage::SolvePotential, 1.0}, {Stage::Snapshot, 0.1}}),
      record(1, {{Stage::MoveTool, 0.01}, {Stage::Snapshot, 0.1}},
             {{Stage::SolvePotential, 0.002}})};
  const std::string csv = timingCsv(records, {20.0, 33.333});
  EXPECT_EQ(csv.find("heat_ms"), std::string::npos);
  EXPECT_EQ(csv.find("removed_tets"), std::string::npos);
  EXPECT_EQ(csv.find("rebuild_wait_ms"), std::string::npos);
  const nlohmann::json trace = chromeTrace(records, {0, 33333});
  EXPECT_EQ(trace["traceEvents"].size(), 6u);
  test::checkTimingReports(csv, timingJson(records, {}), trace, 1e-4);
}

// the rows streamed as the frames are done are timing.csv's, byte for byte; remove() takes
// the file away; a file that cannot be written is no error (nothing is left)
TEST(RunReport, TheStreamedRowsAreTimingCsvs) {
  const std::vector<FrameRecord> records = structuralFrames();
  const auto dir = std::filesystem::temp_directory_path() / "esim_run_report_test";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "timing.csv.partial").string();
  TimingCsvStream stream(path);
  EXPECT_FALSE(std::filesystem::exists(path));  // nothing before the first frame
  const std::vector<double> periods = {40.0, 30.0, 170.0};
  for (size_t f = 0; f < records.size(); ++f) stream.add(records[f], periods[f]);
  std::ifstream in(path, std::ios::binary);
  const std::string streamed{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  EXPECT_EQ(streamed, timingCsv(records, periods));
  stream.remove();
  EXPECT_FALSE(std::filesystem::exists(path));
  stream.add(records[0], 1.0);  // removed: the stream has stopped
  EXPECT_FALSE(std::filesystem::exists(path));
  TimingCsvStream nowhere((dir / "no such folder" / "timing.csv.partial").string());
  EXPECT_NO_THROW(nowhere.add(records[0], 1.0));
  EXPECT_NO_THROW(nowhere.remove());
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace esim::app
