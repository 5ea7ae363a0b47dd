// labels.h - per-pixel labels of a rendered frame: class, tissue state, depth; the camera
// model that goes with them; COCO run-length encoding; the preview palette.
//
// The labels come from the frame's own draw: Renderer::renderLabels() (renderer.h) draws
// the vertex buffers of the last render() again, with the same camera, projection, culling
// and depth test, through a flat-class fragment shader into an integer target
// (label_pass.h), and reads it back. With MSAA off, the pixels of each class are exactly the
// pixels where the frame shows that part; with MSAA on, the frame's edge pixels mix the
// classes while the labels keep the class at the pixel centre.
//
// Classes (one byte per pixel, LabelClass; priority top to bottom where states overlap):
//   7 overlay      pixels the CPU overlay writes (colour bar, ticks, unit, time text)
//   2 tool_tip     the electrode's bare metal (blade or ball, with the ball's neck)
//   1 tool_shaft   the electrode's insulated shaft and its handle
//   5 desiccated   tissue with desiccation >= kDesiccatedMin (half its water vaporised;
//                  ESim has no charring model: charred tissue is in this class)
//   4 coagulated   tissue with coagulation >= kCoagulatedMin = 1 - 1/e (Arrhenius Omega >= 1)
//   6 cut_wall     tissue with cutWall >= kCutWallMin (faces exposed by removed elements)
//   3 tissue       intact tissue (none of the above)
//   0 background   nothing drawn
// The tissue states are thresholded per fragment on the interpolated per-vertex fractions
// (as the tissue look colours them per fragment), never per triangle; the tool's parts
// are constant per triangle. Each tissue pixel also keeps its three states as bits
// (LabelFrame::states: kStateCoagulated, kStateDesiccated, kStateCutWall), whatever the
// class shows: a coagulated cut wall is class coagulated with the cut-wall bit set.
// Depth: the distance along the camera's viewing axis (OpenCV Z) at the pixel centre,
// written by the shader from the interpolated world position, in units of depthUnitM,
// rounded to nearest; 0 = no surface (background), 65535 = at or beyond 65535 units.
// Camera: OpenCV pinhole, x right, y down, z forward, pixel (0, 0) the centre of the top
// left pixel: fx = fy = (height / 2) / tan(fov_y / 2), cx = (width - 1) / 2,
// cy = (height - 1) / 2; world -> camera X_c = R X_w + t with R's rows (right, -up, forward).
// Units: metres, pixels. Ownership: plain values.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace esim {

struct RenderOptions;

// ---- classes and states ----

enum class LabelClass : std::uint8_t {
  Background = 0,
  ToolShaft = 1,
  ToolTip = 2,
  Tissue = 3,
  Coagulated = 4,
  Desiccated = 5,
  CutWall = 6,
  Overlay = 7,
};
constexpr int kLabelClassCount = 8;

struct LabelClassInfo {
  int id;
  const char* name;                 // "tool_tip", ... (classes.json, frames.jsonl)
  std::array<std::uint8_t, 3> rgb;  // the preview's colour
  const char* description;
};

// the classes in id order
const std::array<LabelClassInfo, kLabelClassCount>& labelClasses();

// thresholds of the tissue states (on the snapshot's per-vertex fractions, interpolated)
constexpr float kCoagulatedMin = 0.63212055882855767f;  // 1 - exp(-1): Omega >= 1
constexpr float kDesiccatedMin = 0.5f;                  // half the water vaporised
constexpr float kCutWallMin = 0.5f;                     // on a face exposed by removal

// bits of LabelFrame::states (tissue pixels only)
constexpr std::uint8_t kStateCoagulated = 1, kStateDesiccated = 2, kStateCutWall = 4;
constexpr int kLabelStateCount = 3;
// "coagulated", "desiccated", "cut_wall" for bit 0, 1, 2
const std::array<const char*, kLabelStateCount>& labelStateNames();

// the labels of one frame, top row first
struct LabelFrame {
  int width = 0, height = 0;
  std::vector<std::uint8_t> classes;                 // LabelClass per pixel
  std::vector<std::uint8_t> states;                  // kState* bits per pixel
  std::vector<std::uint16_t> depth;                  // camera-axis depth in depthUnitM (0: none)
  double depthUnitM = 0;                             // metres per depth unit
  std::array<long, kLabelClassCount> classPixels{};  // pixels per class
  std::array<long, kLabelStateCount> statePixels{};  // pixels with each state bit
};

// ---- camera ----

// the camera of a render, OpenCV convention (see above)
struct CameraModel {
  int width = 0, height = 0;              // [px]
  double fx = 0, fy = 0, cx = 0, cy = 0;  // [px]
  std::array<double, 9> rotation{};       // world -> camera, row-major
  std::array<double, 3> translation{};    // world -> camera [m]
  std::array<double, 3> eyeM{};           // camera centre in the world [m]
  double fovYDeg = 0;
  double depthUnitM = 0;  // metres per unit of the depth image
};

// metres per depth unit for the options' camera: 10 um, or coarser when 4x the camera's
// distance to its target would not fit in 65535 units ({1, 2, 5} x 10^k m)
double depthUnitM(const RenderOptions& options);

// the camera of the options (the renderer's lookAt and perspective, in double)
CameraModel cameraModel(const RenderOptions& options);

// a world point [m] in the camera: {u, v, Z} (pixels, OpenCV; Z the depth [m], > 0 in front)
std::array<double, 3> projectToPixel(const CameraModel& camera, const std::array<double, 3>& p);

// ---- preview and COCO ----

// the classes in the palette of labelClasses() (RGB24, top row first)
std::vector<std::uint8_t> colorizeLabels(const LabelFrame& labels);

// COCO uncompressed RLE of a binary mask (mask[i] != 0, row-major, top row first):
// run lengths in column-major (Fortran) order, starting with a run of zeros (maybe 0 long);
// what pycocotools' frPyObjects reads from {"size": [height, width], "counts": [...]}
std::vector<std::uint32_t> cocoRleEncode(const std::vector<std::uint8_t>& mask, int width,
                                         int height);

// the mask (0/1, row-major, top row first) of COCO uncompressed RLE counts; throws
// esim::Error when the counts do not cover width x height exactly
std::vector<std::uint8_t> cocoRleDecode(const std::vector<std::uint32_t>& counts, int width,
                                        int height);

}  // namespace esim
