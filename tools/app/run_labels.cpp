// run_labels.cpp - the label files of a run (see run_labels.h).
#include "tools/app/run_labels.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iomanip>
#include <sstream>

#include "render/image_png.h"
#include "sim/core_error.h"
#include "tools/app/json_text.h"
#include "tools/app/run_output.h"

namespace esim::app {

namespace fs = std::filesystem;

namespace {

std::string numberedName(const char* prefix, int frame, const char* ext) {
  std::ostringstream name;
  name << prefix << std::setw(5) << std::setfill('0') << frame << ext;
  return name.str();
}

// indent -1: one line (coco.json's run lengths would take a line each)
// (whole or not at all: a disk that fills leaves no cut file)
void writeJson(const fs::path& path, const nlohmann::json& j, int indent = 2) {
  writeFileAtomic(path, jsonText(j, indent) + "\n");
}

// the tool's pose, and its tip in the image (projection; visible: the tip's pixel shows it)
nlohmann::json toolJson(const ToolSnapshot& tool, const CameraModel& camera,
                        const LabelFrame& labels) {
  nlohmann::json t;
  t["present"] = tool.present;
  if (!tool.present) return t;
  t["position_m"] = {tool.tipM[0], tool.tipM[1], tool.tipM[2]};
  t["orientation_wxyz"] = {tool.orientationWxyz[0], tool.orientationWxyz[1],
                           tool.orientationWxyz[2], tool.orientationWxyz[3]};
  const std::array<double, 3> px =
      projectToPixel(camera, {tool.tipM[0], tool.tipM[1], tool.tipM[2]});
  const bool inImage = px[2] > 0 && px[0] > -0.5 && px[0] < camera.width - 0.5 && px[1] > -0.5 &&
                       px[1] < camera.height - 0.5;
  bool visible = false;
  if (inImage) {
    const long col = std::lround(px[0]), row = std::lround(px[1]);
    visible = labels.classes[static_cast<size_t>(row) * labels.width + col] ==
              static_cast<std::uint8_t>(LabelClass::ToolTip);
  }
  t["tip_px"] = {px[0], px[1]};
  t["tip_depth_m"] = px[2];
  t["tip_in_image"] = inImage;
  t["tip_visible"] = visible;
  return t;
}

}  // namespace

nlohmann::json labelClassesJson() {
  nlohmann::json classes = nlohmann::json::array();
  for (const LabelClassInfo& c : labelClasses())
    classes.push_back({{"id", c.id},
                       {"name", c.name},
                       {"color_rgb", {c.rgb[0], c.rgb[1], c.rgb[2]}},
                       {"description", c.description}});
  nlohmann::json states = nlohmann::json::array();
  for (int b = 0; b < kLabelStateCount; ++b)
    states.push_back({{"bit", b}, {"value", 1 << b}, {"name", labelStateNames()[b]}});
  return {{"classes", classes},
          {"mask",
           "mask_NNNNN.png: 8-bit grey, one class id per pixel, top row first; frame NNNNN "
           "of video.mp4 (0-based)"},
          {"thresholds",
           {{"coagulated",
             {{"field", "coagulation = 1 - exp(-Omega)"},
              {"min", kCoagulatedMin},
              {"note", "Arrhenius damage Omega >= 1"}}},
            {"desiccated",
             {{"field", "desiccation (vaporised water fraction)"}, {"min", kDesiccatedMin}}},
            {"cut_wall",
             {{"field", "cutWall (1 on faces exposed by removal)"}, {"min", kCutWallMin}}}}},
          {"thresholding",
           "per fragment, on the per-vertex fractions interpolated across each triangle"},
          {"priority",
           {"overlay", "tool_tip", "tool_shaft", "desiccated", "coagulated", "cut_wall", "tissue",
            "background"}},
          {"state_bits", states},
          {"state_note",
           "frames.jsonl state_pixels count the tissue pixels with each state, whatever "
           "class the priority gave them"},
          {"source",
           "a second pass over the frame's own vertex buffers (same camera, culling and "
           "depth test), one sample at each pixel centre; with MSAA on, the video's edge "
           "pixels blend classes"}};
}

nlohmann::json labelCameraJson(const CameraModel& c) {
  const auto& R = c.rotation;
  nlohmann::json rows = {{R[0], R[1], R[2]}, {R[3], R[4], R[5]}, {R[6], R[7], R[8]}};
  nlohmann::json m4 = nlohmann::json::array();
  for (int r = 0; r < 3; ++r)
    m4.push_back({R[3 * r], R[3 * r + 1], R[3 * r + 2], c.translation[r]});
  m4.push_back({0, 0, 0, 1});
  const double far = 65535.0 * c.depthUnitM;
  return {
      {"convention",
       "OpenCV pinhole: x right, y down, z forward; pixel (0, 0) is the centre of "
       "the top-left pixel; no distortion"},
      {"width", c.width},
      {"height", c.height},
      {"fx", c.fx},
      {"fy", c.fy},
      {"cx", c.cx},
      {"cy", c.cy},
      {"K", {{c.fx, 0, c.cx}, {0, c.fy, c.cy}, {0, 0, 1}}},
      {"distortion", {0, 0, 0, 0, 0}},
      {"fov_y_deg", c.fovYDeg},
      {"world_to_camera",
       {{"R", rows},
        {"t", {c.translation[0], c.translation[1], c.translation[2]}},
        {"matrix", m4}}},
      {"camera_position_m", {c.eyeM[0], c.eyeM[1], c.eyeM[2]}},
      {"moves", false},
      {"moves_note", "ESim's camera is fixed for a run: these parameters hold for every frame"},
      {"depth",
       {{"file", "depth_NNNNN.png: 16-bit grey, top row first"},
        {"quantity", "Z: distance along the camera axis (not along the ray) at the pixel centre"},
        {"unit_m", c.depthUnitM},
        {"near_m", c.depthUnitM},
        {"far_m", far},
        {"none_value", 0},
        {"saturated_value", 65535},
        {"formula", "Z_m = value * unit_m; 0: no surface; 65535: at or beyond far_m"}}}};
}

LabelWriter::LabelWriter(const RenderOptions& render, const fs::path& runDir, bool preview,
                         const VideoEncoder::Options& video)
    : dir_(runDir / "labels"), camera_(cameraModel(render)) {
  fs::create_directories(dir_);
  writeJson(dir_ / "classes.json", labelClassesJson());
  writeJson(dir_ / "camera.json", labelCameraJson(camera_));
  jsonl_.open(dir_ / "frames.jsonl", std::ios::binary | std::ios::trunc);
  ESIM_RUN_CHECK(jsonl_.good(), (dir_ / "frames.jsonl").string() + ": cannot open for writing");
  if (preview) {
    VideoEncoder::Options vo = video;
    vo.path = (dir_ / "preview.mp4").string();
    vo.width = 2 * render.width;
    vo.height = render.height;
    preview_ = std::make_unique<VideoEncoder>();
    preview_->open(vo);
  }
}

LabelWriter::~LabelWriter() {
  if (closed_) return;
  try {
    close();
  } catch (...) {  // the run's own error (if any) is the one reported
  }
}

void LabelWriter::add(int frame, const SurfaceSnapshot& snap, const FrameRecord& rec,
                      const std::vector<std::uint8_t>& rgb, const LabelFrame& labels) {
  const int w = labels.width, h = labels.height;
  // 1. the images
  writePngGray8((dir_ / numberedName("mask_", frame, ".png")).string(), labels.classes, w, h);
  writePngGray16((dir_ / numberedName("depth_", frame, ".png")).string(), labels.depth, w, h);
  // 2. the frame's line
  nlohmann::json line;
  line["frame"] = frame;
  line["time_s"] = snap.timeS;
  line["tool"] = toolJson(snap.tool, camera_, labels);
  line["generator_on"] = rec.generatorOn;
  line["power_w"] = rec.powerW;
  line["contact_nodes"] = rec.contactNodes;
  nlohmann::json classPixels, statePixels;
  for (const LabelClassInfo& c : labelClasses()) classPixels[c.name] = labels.classPixels[c.id];
  for (int b = 0; b < kLabelStateCount; ++b)
    statePixels[labelStateNames()[b]] = labels.statePixels[b];
  line["class_pixels"] = classPixels;
  line["state_pixels"] = statePixels;
  jsonl_ << jsonText(line) << "\n";
  jsonl_.flush();
  ESIM_RUN_CHECK(jsonl_.good(), (dir_ / "frames.jsonl").string() + ": write failed (disk full?)");
  // 3. COCO: the tool and the cut as instances of this frame
  images_.push_back({{"id", frame},
                     {"frame", frame},
                     {"file_name", numberedName("frame_", frame, ".png")},
                     {"mask_file", numberedName("mask_", frame, ".png")},
                     {"width", w},
                     {"height", h},
                     {"time_s", snap.timeS}});
  const size_t n = labels.classes.size();
  mask_.resize(n);
  for (int category : {1, 2}) {
    // the instance's pixels, their count and bounding box in one pass
    long area = 0;
    int x0 = w, y0 = h, x1 = -1, y1 = -1;
    for (int y = 0; y < h; ++y) {
      const std::uint8_t* cls = &labels.classes[static_cast<size_t>(y) * w];
      const std::uint8_t* st = &labels.states[static_cast<size_t>(y) * w];
      std::uint8_t* out = &mask_[static_cast<size_t>(y) * w];
      for (int x = 0; x < w; ++x) {
        const bool in = category == 1
                            ? cls[x] == static_cast<std::uint8_t>(LabelClass::ToolShaft) ||
                                  cls[x] == static_cast<std::uint8_t>(LabelClass::ToolTip)
                            : (st[x] & kStateCutWall) != 0;
        out[x] = in;
        if (!in) continue;
        ++area;
        x0 = std::min(x0, x);
        x1 = std::max(x1, x);
        y0 = std::min(y0, y);
        y1 = std::max(y1, y);
      }
    }
    if (area == 0) continue;
    annotations_.push_back(
        {{"id", static_cast<int>(annotations_.size()) + 1},
         {"image_id", frame},
         {"category_id", category},
         {"iscrowd", 0},
         {"area", area},
         {"bbox", {x0, y0, x1 - x0 + 1, y1 - y0 + 1}},
         {"segmentation", {{"size", {h, w}}, {"counts", cocoRleEncode(mask_, w, h)}}}});
  }
  // 4. the preview: the frame | its colourised classes
  if (preview_) {
    const std::vector<std::uint8_t> colours = colorizeLabels(labels);
    side_.resize(static_cast<size_t>(2 * w) * h * 3);
    const size_t row = static_cast<size_t>(w) * 3;
    for (int y = 0; y < h; ++y) {
      std::memcpy(&side_[2 * row * y], &rgb[row * y], row);
      std::memcpy(&side_[2 * row * y + row], &colours[row * y], row);
    }
    preview_->push(side_);
  }
}

void LabelWriter::close() {
  if (closed_) return;
  closed_ = true;
  jsonl_.close();
  if (preview_) preview_->close();
  nlohmann::json coco;
  coco["info"] = {
      {"description",
       "ESim labels: one image per frame of video.mp4 (id = frame, 0-based); file_name as "
       "output.png_every = 1 writes them to frames/, or as `ffmpeg -i video.mp4 -start_number 0 "
       "frame_%05d.png` extracts them"},
      {"version", "1.0"}};
  coco["images"] = images_;
  coco["categories"] = {{{"id", 1}, {"name", "tool"}, {"supercategory", "instrument"}},
                        {{"id", 2}, {"name", "cut"}, {"supercategory", "tissue"}}};
  coco["annotations"] = annotations_;
  writeJson(dir_ / "coco.json", coco, -1);
}

}  // namespace esim::app
