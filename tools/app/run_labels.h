// run_labels.h - `esim run --labels`: the label files of a run, RUN/labels/.
//
// Per frame of the video (same camera, same size, same frame numbers):
//   mask_NNNNN.png   8-bit grey, the class id per pixel (render/labels.h: LabelClass)
//   depth_NNNNN.png  16-bit grey, depth along the camera axis in camera.json's depth.unit_m
//                    (0: no surface; 65535: at or beyond depth.far_m)
//   frames.jsonl     one JSON object per line and frame: time, tool pose (world), tool tip
//                    in pixels, generator, power, contact nodes, pixels per class and state
// Once per run:
//   classes.json     ids, names, preview colours, descriptions, thresholds, priority
//   camera.json      OpenCV intrinsics (fx, fy, cx, cy, width, height, K), extrinsics
//                    (world -> camera R, t; the camera does not move in ESim runs), depth
//                    unit and range
//   coco.json        COCO instances: per frame (image id = frame number) the tool (classes
//                    tool_shaft + tool_tip) and the cut (tissue pixels with the cut-wall
//                    state) as uncompressed RLE, with area and bbox; empty ones left out
//   preview.mp4      (--labels preview) the frame beside its colourised mask, 2W x H, H.264
// Lossless: PNG for masks and depth; the preview alone is lossy (for a person's eyes).
// Ownership: LabelWriter owns its files and the preview encoder; used from the frame loop's
// thread.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "render/labels.h"
#include "render/renderer.h"
#include "render/video_encoder.h"
#include "sim/simulation.h"

namespace esim::app {

struct LabelOutputOptions {
  bool enabled = false;  // --labels
  bool preview = false;  // --labels preview
};

class LabelWriter {
 public:
  // creates dir/labels/ with classes.json and camera.json; opens frames.jsonl and, with
  // preview, preview.mp4 (video: its rate, quality and reproducibility); throws Error
  LabelWriter(const RenderOptions& render, const std::filesystem::path& runDir, bool preview,
              const VideoEncoder::Options& video);
  ~LabelWriter();
  LabelWriter(const LabelWriter&) = delete;
  LabelWriter& operator=(const LabelWriter&) = delete;

  // one frame: mask and depth PNGs, a frames.jsonl line, its COCO annotations, the preview
  // (rgb: the frame as rendered, overlay included)
  void add(int frame, const SurfaceSnapshot& snapshot, const FrameRecord& record,
           const std::vector<std::uint8_t>& rgb, const LabelFrame& labels);

  // writes coco.json and closes frames.jsonl and the preview (playable however many frames)
  void close();

 private:
  std::filesystem::path dir_;
  CameraModel camera_;
  std::ofstream jsonl_;
  nlohmann::json images_ = nlohmann::json::array(), annotations_ = nlohmann::json::array();
  std::unique_ptr<VideoEncoder> preview_;
  std::vector<std::uint8_t> side_, mask_;  // scratch: preview frame, binary mask
  bool closed_ = false;
};

// classes.json: ids, names, colours, descriptions, thresholds, priority, state bits
nlohmann::json labelClassesJson();

// camera.json for the camera and frame size
nlohmann::json labelCameraJson(const CameraModel& camera);

}  // namespace esim::app
