// compare_runs.cpp - frame-by-frame comparison of two run folders (see compare_runs.h).
#include "tools/app/compare_runs.h"

#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "render/image_hash.h"
#include "render/image_png.h"
#include "sim/core_error.h"
#include "tools/app/json_text.h"
#include "tools/app/run_output.h"

namespace esim::app {

namespace fs = std::filesystem;

namespace {

nlohmann::json readJson(const fs::path& path) {
  std::ifstream is(path);
  ESIM_VERIFY(is.good(), path.string() + ": not found (is this a run folder of `esim run`?)");
  try {
    return nlohmann::json::parse(is);
  } catch (const std::exception& e) {
    throw Error(path.string() + ": not valid JSON: " + e.what());
  }
}

std::string frameName(int f) {
  std::ostringstream name;
  name << "frame_" << std::setw(5) << std::setfill('0') << f << ".png";
  return name.str();
}

// a file an earlier report of compareRuns wrote: compare.json, diff_frame_NNNNN.png
bool isReportFile(const fs::path& p) {
  const std::string name = p.filename().string();
  return name == "compare.json" || isNumberedName(name, "diff_frame_", ".png");
}

// the report folder, new or emptied of an earlier report (only that: a folder holding
// anything else is refused, nothing removed)
void prepareReportFolder(const fs::path& dir, FolderLock& lock) {
  createOutputFolder(dir, "--report", lock);  // (held before anything in it is judged)
  std::error_code ec;
  std::vector<fs::path> earlier;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    ESIM_VERIFY(e.is_regular_file(ec) && isReportFile(e.path()),
                "--report: '" + dir.string() + "' holds '" + e.path().filename().string() +
                    "', which is not a file of an esim compare report; give a new or empty "
                    "folder (nothing was changed)");
    earlier.push_back(e.path());
  }
  ESIM_VERIFY(!ec, "--report: cannot list '" + dir.string() + "': " + ec.message());
  for (const fs::path& p : earlier) fs::remove(p, ec);  // the earlier report replaced
}

}  // namespace

CompareResult compareRuns(const std::string& runA, const std::string& runB,
                          const std::string& reportDir, bool writeDiffs) {
  const nlohmann::json a = readJson(fs::path(runA) / "hashes.json");
  const nlohmann::json b = readJson(fs::path(runB) / "hashes.json");
  CompareResult r;
  ESIM_VERIFY(a.at("width") == b.at("width") && a.at("height") == b.at("height"),
              "compare: frame sizes differ (" + a.at("width").dump() + "x" + a.at("height").dump() +
                  " vs " + b.at("width").dump() + "x" + b.at("height").dump() + ")");
  const int w = a.at("width"), h = a.at("height");
  r.sameRenderer = a.value("renderer", nlohmann::json()) == b.value("renderer", nlohmann::json()) &&
                   a.value("libraries", "") == b.value("libraries", "");
  const auto& fa = a.at("frames");
  const auto& fb = b.at("frames");
  r.framesA = static_cast<int>(fa.size());
  r.framesB = static_cast<int>(fb.size());
  const int n = std::min(r.framesA, r.framesB);
  FolderLock reportLock;
  if (!reportDir.empty()) prepareReportFolder(reportDir, reportLock);
  nlohmann::json frames = nlohmann::json::array();
  for (int f = 0; f < n; ++f) {
    if (fa[f].at("xxh3") == fb[f].at("xxh3")) continue;
    FrameDiff d;
    d.frame = f;
    d.dhashBits = hammingDistance(std::stoull(fa[f].value("dhash", "0"), nullptr, 16),
                                  std::stoull(fb[f].value("dhash", "0"), nullptr, 16));
    const fs::path pa = fs::path(runA) / "frames" / frameName(f);
    const fs::path pb = fs::path(runB) / "frames" / frameName(f);
    if (fs::exists(pa) && fs::exists(pb)) {
      const RgbImage ia = readPng(pa.string()), ib = readPng(pb.string());
      ESIM_VERIFY(ia.width == w && ia.height == h && ib.width == w && ib.height == h,
                  "compare: " + pa.string() + " or " + pb.string() + " has the wrong size");
      const ImageComparison c = compareImages(ia.rgb, ib.rgb, w, h);
      d.hasImages = true;
      d.psnrDb = c.psnrDb;
      d.offShare = c.offShare;
      d.maxDiff = c.maxDiff;
      d.withinTolerance = imagesMatch(c);
      if (writeDiffs && !reportDir.empty())
        writePng((fs::path(reportDir) / ("diff_" + frameName(f))).string(),
                 diffImage(ia.rgb, ib.rgb, w, h), w, h);
    }
    r.diffs.push_back(d);
    frames.push_back({{"frame", f},
                      {"dhash_bits", d.dhashBits},
                      {"psnr_db", d.hasImages ? nlohmann::json(d.psnrDb) : nlohmann::json()},
                      {"off_share", d.hasImages ? nlohmann::json(d.offShare) : nlohmann::json()},
                      {"max_diff", d.hasImages ? nlohmann::json(d.maxDiff) : nlohmann::json()},
                      {"within_tolerance", d.withinTolerance}});
  }
  if (!reportDir.empty()) {  // written last: a report without it is incomplete
    nlohmann::json rep = {{"run_a", runA},
                          {"run_b", runB},
                          {"frames_a", r.framesA},
                          {"frames_b", r.framesB},
                          {"same_renderer_and_libraries", r.sameRenderer},
                          {"identical", r.identical()},
                          {"thresholds",
                           {{"pixel_diff_levels", kPixelDiffThreshold},
                            {"min_psnr_db", kMinPsnrDb},
                            {"max_off_share", kMaxOffShare}}},
                          {"differing_frames", frames}};
    writeFileAtomic(fs::path(reportDir) / "compare.json", jsonText(rep, 2) + "\n");
  }
  return r;
}

bool CompareResult::withinTolerance() const {
  if (framesA != framesB) return false;
  for (const auto& d : diffs)
    if (!d.withinTolerance) return false;
  return true;
}

}  // namespace esim::app
