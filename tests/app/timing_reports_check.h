// timing_reports_check.h - the structure and consistency of a run's timing reports
// (timing.csv, timing.json, trace.json; tools/app/run_report.h), shared by
// run_report_test (records made up inline) and plot_cli_test (a real run).
//
// Checks, with gtest expectations:
//   - timing.json: frames, budget_ms, a block per stage present in the CSV with ordered
//     statistics (p50 <= p95 <= p99 <= max), physics_total and interactive_total over every
//     frame, frames_over_budget equal to the CSV's over_budget count;
//   - timing.csv: one row per frame, a column per stage of timing.json's stages, and per
//     stage the mean and max of its "ran" cells equal timing.json's mean_ms and max_ms; a
//     period in every row, whose mean, max and count over the budget are timing.json's
//     frame_period's where it has one (a run's);
//   - trace.json: complete ("X") events of known stages, back to back within a frame in
//     stage order on each track (1: the loop; 2: the drawing thread's render, encode_wait
//     and write_labels, after the frame's physics), frames not overlapping on a track; per frame
//     the events before encode_wait sum to the CSV's interactive_ms (skipped stages included), and
//     every ran or skipped cell of the CSV has its event.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

namespace esim::test {

// the stages in frame order (sim/simulation.h), as named in the reports
inline const std::vector<std::string>& timingStageNames() {
  static const std::vector<std::string> names = {
      "move_tool", "find_contacts", "solve_potential", "heat",   "solve_stress",
      "rupture",   "rebuild",       "snapshot",        "render", "encode_wait"};
  return names;
}

inline std::vector<std::map<std::string, std::string>> parseTimingCsv(
    const std::string& text, std::string* header = nullptr) {
  std::istringstream is(text);
  std::string line;
  std::getline(is, line);
  if (header) *header = line;
  auto split = [](const std::string& l) {
    std::vector<std::string> cells;
    std::stringstream ss(l);
    std::string c;
    while (std::getline(ss, c, ',')) cells.push_back(c);
    if (!l.empty() && l.back() == ',') cells.push_back("");
    return cells;
  };
  const std::vector<std::string> cols = split(line);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(is, line)) {
    const std::vector<std::string> cells = split(line);
    EXPECT_EQ(cells.size(), cols.size()) << line;
    std::map<std::string, std::string> row;
    for (size_t i = 0; i < cols.size() && i < cells.size(); ++i) row[cols[i]] = cells[i];
    rows.push_back(row);
  }
  return rows;
}

// ms of a CSV cell: false for "skipped" and "" (absent)
inline bool cellMs(const std::string& cell, double* ms) {
  if (cell.empty() || cell == "skipped") return false;
  *ms = std::atof(cell.c_str());
  return true;
}

// tolMs: the CSV's rounding (4 decimals) and, per frame, the sum of that rounding
inline void checkTimingReports(const std::string& csvText, const nlohmann::json& timing,
                               const nlohmann::json& trace, double tolMs = 2e-3) {
  const auto& names = timingStageNames();
  std::string header;
  const auto rows = parseTimingCsv(csvText, &header);
  const int frames = static_cast<int>(rows.size());
  // ---- timing.json ----
  ASSERT_TRUE(timing.contains("frames") && timing.contains("stages") &&
              timing.contains("budget_ms") && timing.contains("physics_total") &&
              timing.contains("interactive_total") && timing.contains("frames_over_budget"))
      << timing.dump(1).substr(0, 400);
  EXPECT_EQ(timing["frames"].get<int>(), frames);
  const double budget = timing["budget_ms"].get<double>();
  EXPECT_NEAR(budget, 1000.0 / 30.0, 1e-9);
  auto checkStats = [&](const nlohmann::json& s, const std::string& what) {
    for (const char* k :
         {"frames_ran", "frames_skipped", "mean_ms", "p50_ms", "p95_ms", "p99_ms", "max_ms"})
      ASSERT_TRUE(s.contains(k)) << what << " lacks " << k;
    EXPECT_LE(s["frames_ran"].get<int>() + s["frames_skipped"].get<int>(), frames) << what;
    EXPECT_GE(s["p50_ms"].get<double>(), 0) << what;
    EXPECT_LE(s["p50_ms"].get<double>(), s["p95_ms"].get<double>()) << what;
    EXPECT_LE(s["p95_ms"].get<double>(), s["p99_ms"].get<double>()) << what;
    EXPECT_LE(s["p99_ms"].get<double>(), s["max_ms"].get<double>()) << what;
    EXPECT_LE(s["mean_ms"].get<double>(), s["max_ms"].get<double>() + 1e-12) << what;
  };
  checkStats(timing["physics_total"], "physics_total");
  checkStats(timing["interactive_total"], "interactive_total");
  EXPECT_EQ(timing["interactive_total"]["frames_ran"].get<int>(), frames);
  // ---- timing.csv against timing.json, stage by stage ----
  ASSERT_EQ(header.rfind("frame,time_s,", 0), 0u) << header;
  std::vector<std::string> present;
  for (const std::string& n : names)
    if (header.find("," + n + "_ms,") != std::string::npos) present.push_back(n);
  std::vector<std::string> inJson;
  for (auto it = timing["stages"].begin(); it != timing["stages"].end(); ++it) {
    inJson.push_back(it.key());
    EXPECT_NE(std::find(names.begin(), names.end(), it.key()), names.end()) << it.key();
    checkStats(it.value(), it.key());
  }
  std::sort(inJson.begin(), inJson.end());
  std::vector<std::string> sortedPresent = present;
  std::sort(sortedPresent.begin(), sortedPresent.end());
  EXPECT_EQ(inJson, sortedPresent) << header;
  for (const std::string& n : present) {
    double sum = 0, mx = 0, ms = 0;
    int ran = 0, skipped = 0;
    for (const auto& r : rows) {
      const std::string& cell = r.at(n + "_ms");
      if (cellMs(cell, &ms)) {
        sum += ms;
        mx = std::max(mx, ms);
        ++ran;
      }
      skipped += cell == "skipped";
    }
    const nlohmann::json& s = timing["stages"][n];
    EXPECT_EQ(s["frames_ran"].get<int>(), ran) << n;
    EXPECT_EQ(s["frames_skipped"].get<int>(), skipped) << n;
    if (ran > 0) {
      EXPECT_NEAR(s["mean_ms"].get<double>(), sum / ran, tolMs) << n;
      EXPECT_NEAR(s["max_ms"].get<double>(), mx, tolMs) << n;
    }
  }
  int over = 0;
  for (const auto& r : rows) {
    const double im = std::atof(r.at("interactive_ms").c_str());
    EXPECT_EQ(r.at("over_budget"), im > budget ? "1" : "0") << r.at("frame");
    over += r.at("over_budget") == "1";
  }
  EXPECT_EQ(timing["frames_over_budget"].get<int>(), over);
  // ---- the periods: every row has one; where timing.json has frame_period (a run's), its
  // mean, maximum and count over the budget are the column's ----
  double periodSum = 0, periodMax = 0;
  int periodsOver = 0;
  for (const auto& r : rows) {
    double ms = -1;
    ASSERT_TRUE(cellMs(r.at("period_ms"), &ms)) << "frame " << r.at("frame");
    EXPECT_GE(ms, 0) << "frame " << r.at("frame");
    periodSum += ms;
    periodMax = std::max(periodMax, ms);
    periodsOver += ms > budget;
  }
  if (timing.contains("frame_period") && frames > 0) {
    const nlohmann::json& p = timing["frame_period"];
    checkStats(p, "frame_period");
    EXPECT_EQ(p["frames_ran"].get<int>(), frames);
    EXPECT_NEAR(p["mean_ms"].get<double>(), periodSum / frames, tolMs);
    EXPECT_NEAR(p["max_ms"].get<double>(), periodMax, tolMs);
    EXPECT_EQ(p["frames_over_budget"].get<int>(), periodsOver);
  }
  // ---- trace.json: per frame, back to back, summing to the frame's interactive time ----
  ASSERT_TRUE(trace.contains("traceEvents")) << trace.dump().substr(0, 200);
  std::map<int, std::vector<nlohmann::json>> byFrame;
  for (const auto& e : trace["traceEvents"]) {
    ASSERT_EQ(e["ph"], "X");
    ASSERT_TRUE(e.contains("ts") && e.contains("dur") && e.contains("pid") && e.contains("tid"));
    const std::string name = e["name"];
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
    EXPECT_NE(std::find(present.begin(), present.end(), name), present.end())
        << name << " in trace.json but not in timing.csv";
    EXPECT_GE(e["dur"].get<double>(), 0);
    byFrame[e["args"]["frame"].get<int>()].push_back(e);
  }
  ASSERT_EQ(static_cast<int>(byFrame.size()), frames);
  // per track (tid 1: the frame loop; tid 2: the drawing thread, when frames are drawn on
  // one): back to back within a frame, frames in order; a frame is drawn after its physics
  std::map<int, double> previousEndUs;
  for (const auto& r : rows) {
    const int f = std::atoi(r.at("frame").c_str());
    ASSERT_TRUE(byFrame.count(f)) << "frame " << f << " has no trace events";
    const auto& ev = byFrame[f];
    double sumMs = 0, ms = 0;
    int lastStage = -1, cells = 0;
    for (size_t i = 0; i < ev.size(); ++i) {
      const int stage = static_cast<int>(
          std::find(names.begin(), names.end(), ev[i]["name"].get<std::string>()) - names.begin());
      EXPECT_GT(stage, lastStage) << "frame " << f << ": stages out of order";
      lastStage = stage;
      const int tid = ev[i]["tid"].get<int>();
      EXPECT_TRUE(tid == 1 ||
                  (tid == 2 && (ev[i]["name"] == "render" || ev[i]["name"] == "encode_wait" ||
                                ev[i]["name"] == "write_labels")))
          << "frame " << f << ": " << ev[i]["name"] << " on track " << tid;
      if (i > 0 && ev[i - 1]["tid"].get<int>() == tid) {
        EXPECT_NEAR(ev[i]["ts"].get<double>(),
                    ev[i - 1]["ts"].get<double>() + ev[i - 1]["dur"].get<double>(), 1e-6)
            << "frame " << f << ": events not back to back";
      } else if (i > 0) {  // the drawing thread's first event: after the frame's physics
        EXPECT_GE(ev[i]["ts"].get<double>(),
                  ev[i - 1]["ts"].get<double>() + ev[i - 1]["dur"].get<double>() - 1e-6)
            << "frame " << f << ": drawn before its physics ended";
      }
      if (i == 0 || ev[i - 1]["tid"].get<int>() != tid) {
        if (previousEndUs.count(tid)) {
          EXPECT_GE(ev[i]["ts"].get<double>(), previousEndUs[tid] - 1e-6) << "frame " << f;
        }
      }
      if (i + 1 == ev.size() || ev[i + 1]["tid"].get<int>() != tid)
        previousEndUs[tid] = ev[i]["ts"].get<double>() + ev[i]["dur"].get<double>();
      const std::string& cell = r.at(ev[i]["name"].get<std::string>() + "_ms");
      EXPECT_FALSE(cell.empty()) << "frame " << f << ": event for an absent stage";
      EXPECT_EQ(cell == "skipped", ev[i]["args"].value("skipped", false)) << "frame " << f;
      if (cellMs(cell, &ms)) {
        EXPECT_NEAR(ev[i]["dur"].get<double>() / 1000.0, ms, tolMs);
      }
      if (ev[i]["name"] != "encode_wait") sumMs += ev[i]["dur"].get<double>() / 1000.0;
    }
    for (const std::string& n : present) cells += !r.at(n + "_ms").empty();
    EXPECT_EQ(static_cast<int>(ev.size()), cells) << "frame " << f;
    EXPECT_NEAR(sumMs, std::atof(r.at("interactive_ms").c_str()), tolMs) << "frame " << f;
  }
}

}  // namespace esim::test
