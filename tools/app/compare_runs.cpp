// compare_runs.cpp - frame-by-frame comparison of two run folders (see compare_runs.h).
#include "tools/app/compare_runs.h"

#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <vector>

#include "render/image_hash.h"
#include "render/image_png.h"
#include "sim/core_error.h"
#include "sim/message_text.h"
#include "tools/app/build_info.h"
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
    throw Error(path.string() + ": not valid JSON: " + printableInMessage(e.what()));
  }
}

// 16 hexadecimal digits, as hashToHex writes a 64-bit hash
bool isHashText(const nlohmann::json& v) {
  if (!v.is_string()) return false;
  const std::string& t = v.get_ref<const std::string&>();
  return t.size() == 16 && t.find_first_not_of("0123456789abcdefABCDEF") == std::string::npos;
}

// what compareRuns reads of a hashes.json, checked: an edited or foreign file is refused at
// its field (a dhash that was not hex ended in "internal error: stoull", exit 4; a frame list
// out of order or numbered wrongly compared the frames by position and said "identical")
void checkHashes(const nlohmann::json& j, const fs::path& path) {
  const std::string file = path.string();
  ESIM_VERIFY(j.is_object(), file + ": expected a JSON object (the hashes.json of an esim run)");
  for (const char* key : {"width", "height"}) {
    const auto it = j.find(key);
    ESIM_VERIFY(it != j.end() && it->is_number_integer() && it->get<long long>() > 0 &&
                    it->get<long long>() <= 65536,
                file + ": " + key + " = " +
                    (it == j.end() ? std::string("(missing)") : jsonInMessage(*it)) +
                    "; expected the frame's size in pixels, an integer in [1, 65536]");
  }
  const auto frames = j.find("frames");
  ESIM_VERIFY(frames != j.end() && frames->is_array(),
              file + ": frames: expected a list of {frame, xxh3, dhash}");
  for (size_t i = 0; i < frames->size(); ++i) {
    const nlohmann::json& f = (*frames)[i];
    const std::string at = file + ": frames[" + std::to_string(i) + "]";
    ESIM_VERIFY(f.is_object(),
                at + ": expected an object {frame, xxh3, dhash}, got " + jsonInMessage(f));
    const auto number = f.find("frame");
    ESIM_VERIFY(
        number != f.end() && number->is_number_integer() &&
            number->get<long long>() == static_cast<long long>(i),
        at + ".frame = " + (number == f.end() ? std::string("(missing)") : jsonInMessage(*number)) +
            "; expected " + std::to_string(i) + " (every frame, in order from 0)");
    ESIM_VERIFY(f.contains("xxh3") && isHashText(f["xxh3"]),
                at + ".xxh3: expected 16 hexadecimal digits, got " +
                    (f.contains("xxh3") ? jsonInMessage(f["xxh3"]) : std::string("(missing)")));
    ESIM_VERIFY(!f.contains("dhash") || isHashText(f["dhash"]),
                at + ".dhash: expected 16 hexadecimal digits, got " + jsonInMessage(f["dhash"]));
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
  checkHashes(a, fs::path(runA) / "hashes.json");
  checkHashes(b, fs::path(runB) / "hashes.json");
  CompareResult r;
  ESIM_VERIFY(a.at("width") == b.at("width") && a.at("height") == b.at("height"),
              "compare: frame sizes differ (" + a.at("width").dump() + "x" + a.at("height").dump() +
                  " vs " + b.at("width").dump() + "x" + b.at("height").dump() + ")");
  const int w = a.at("width"), h = a.at("height");
  r.sameRenderer = a.value("renderer", nlohmann::json()) == b.value("renderer", nlohmann::json()) &&
                   a.value("libraries", "") == b.value("libraries", "");
  {
    // which esim made each run: a build that says nothing is not taken for the same one
    const auto build = [](const nlohmann::json& j) {
      return buildInfoFromJson(j.contains("esim_build") ? j["esim_build"] : nlohmann::json());
    };
    const std::optional<BuildInfo> ba = build(a), bb = build(b);
    if (ba) r.buildA = printableInMessage(buildInfoLine(*ba), 200);
    if (!ba || !bb) {
      r.buildDiffers = std::string(!ba && !bb ? "neither run says"
                                   : !ba      ? "run A does not say"
                                              : "run B does not say") +
                       " which esim made it (hashes.json without esim_build: made before esim "
                       "recorded it)";
    } else if (buildInfoLine(*ba) != buildInfoLine(*bb) || ba->commit != bb->commit) {
      r.buildDiffers = printableInMessage(buildInfoLine(*ba), 200) + " vs " +
                       printableInMessage(buildInfoLine(*bb), 200);
    }
  }
  {
    std::vector<std::string> differ;
    const std::string ha = a.value("scenario_hash", ""), hb = b.value("scenario_hash", "");
    if (ha != hb) differ.push_back("the scenario (hash " + ha + " vs " + hb + ")");
    const nlohmann::json none = nlohmann::json::object();
    const nlohmann::json& ia = a.contains("input_files") ? a["input_files"] : none;
    const nlohmann::json& ib = b.contains("input_files") ? b["input_files"] : none;
    std::set<std::string> keys;
    for (const nlohmann::json* in : {&ia, &ib})
      if (in->is_object())
        for (auto it = in->begin(); it != in->end(); ++it) keys.insert(it.key());
    const auto content = [](const nlohmann::json& in, const std::string& k) {
      return in.is_object() && in.contains(k) && in[k].is_object()
                 ? in[k].value("xxh3", nlohmann::json())
                 : nlohmann::json();
    };
    for (const std::string& k : keys)
      if (content(ia, k) != content(ib, k)) differ.push_back(k + "'s content");
    for (const std::string& d : differ) r.inputsDiffer += (r.inputsDiffer.empty() ? "" : ", ") + d;
  }
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
                          {"esim_build_differs", r.buildDiffers},
                          {"inputs_differ", r.inputsDiffer},
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
