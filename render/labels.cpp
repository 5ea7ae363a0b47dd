// labels.cpp - label classes, camera model, preview colours and COCO RLE (see labels.h).
#include "render/labels.h"

#include <algorithm>
#include <cmath>

#include "render/renderer.h"
#include "render/vec3d.h"
#include "sim/core_error.h"

namespace esim {

const std::array<LabelClassInfo, kLabelClassCount>& labelClasses() {
  static const std::array<LabelClassInfo, kLabelClassCount> kClasses{{
      {0, "background", {0, 0, 0}, "nothing drawn (the background gradient)"},
      {1, "tool_shaft", {60, 120, 220}, "the electrode's insulated shaft and handle"},
      {2, "tool_tip", {255, 210, 0}, "the electrode's bare metal: blade, or ball and neck"},
      {3, "tissue", {225, 120, 130}, "intact tissue"},
      {4,
       "coagulated",
       {245, 240, 215},
       "tissue with coagulation >= 1 - 1/e (Arrhenius damage Omega >= 1)"},
      {5,
       "desiccated",
       {120, 70, 20},
       "tissue with desiccation >= 0.5 (half its water vaporised; includes charred tissue)"},
      {6,
       "cut_wall",
       {150, 40, 200},
       "tissue on faces exposed by removed elements (cutWall >= 0.5), neither coagulated nor "
       "desiccated"},
      {7, "overlay", {128, 128, 128}, "pixels written by the overlay (colour bar, time text)"},
  }};
  return kClasses;
}

const std::array<const char*, kLabelStateCount>& labelStateNames() {
  static const std::array<const char*, kLabelStateCount> kNames{"coagulated", "desiccated",
                                                                "cut_wall"};
  return kNames;
}

// ---- camera ----

namespace {

using render_detail::cross;
using render_detail::D3;
using render_detail::dot;
using render_detail::normalized;
using render_detail::sub;

D3 toD3(const std::array<float, 3>& a) { return {a[0], a[1], a[2]}; }

}  // namespace

double depthUnitM(const RenderOptions& o) {
  const double dist =
      std::sqrt(dot(sub(toD3(o.targetM), toD3(o.eyeM)), sub(toD3(o.targetM), toD3(o.eyeM))));
  const double need = std::max(1e-5, 4.0 * dist / 65535.0);
  double p = std::pow(10.0, std::floor(std::log10(need)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * p >= need * (1 - 1e-12)) return m * p;
  return 10 * p;
}

CameraModel cameraModel(const RenderOptions& o) {
  CameraModel c;
  c.width = o.width;
  c.height = o.height;
  c.fovYDeg = o.fovDeg;
  const double f = 0.5 * o.height / std::tan(o.fovDeg * 3.14159265358979323846 / 360.0);
  c.fx = c.fy = f;
  c.cx = 0.5 * (o.width - 1);
  c.cy = 0.5 * (o.height - 1);
  c.eyeM = toD3(o.eyeM);
  const D3 fwd = normalized(sub(toD3(o.targetM), c.eyeM));
  const D3 right = normalized(cross(fwd, toD3(o.up)));
  const D3 up = cross(right, fwd);
  const D3 rows[3] = {right, {-up[0], -up[1], -up[2]}, fwd};
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) c.rotation[3 * r + k] = rows[r][k];
    c.translation[r] = -dot(rows[r], c.eyeM);
  }
  c.depthUnitM = depthUnitM(o);
  return c;
}

std::array<double, 3> projectToPixel(const CameraModel& c, const std::array<double, 3>& p) {
  D3 x{};
  for (int r = 0; r < 3; ++r)
    x[r] = c.rotation[3 * r] * p[0] + c.rotation[3 * r + 1] * p[1] + c.rotation[3 * r + 2] * p[2] +
           c.translation[r];
  return {c.fx * x[0] / x[2] + c.cx, c.fy * x[1] / x[2] + c.cy, x[2]};
}

// ---- preview and COCO ----

std::vector<std::uint8_t> colorizeLabels(const LabelFrame& labels) {
  const auto& classes = labelClasses();
  std::vector<std::uint8_t> rgb(labels.classes.size() * 3);
  for (size_t i = 0; i < labels.classes.size(); ++i) {
    const auto& c = classes[labels.classes[i] < kLabelClassCount ? labels.classes[i] : 0].rgb;
    rgb[3 * i] = c[0];
    rgb[3 * i + 1] = c[1];
    rgb[3 * i + 2] = c[2];
  }
  return rgb;
}

std::vector<std::uint32_t> cocoRleEncode(const std::vector<std::uint8_t>& mask, int width,
                                         int height) {
  ESIM_VERIFY(mask.size() == static_cast<size_t>(width) * height,
              "cocoRleEncode: mask of " + std::to_string(mask.size()) + " pixels for " +
                  std::to_string(width) + "x" + std::to_string(height));
  std::vector<std::uint32_t> counts;
  std::uint8_t current = 0;  // runs alternate 0, 1, 0, ...: the first counts zeros
  std::uint32_t run = 0;
  for (int x = 0; x < width; ++x)
    for (int y = 0; y < height; ++y) {
      const std::uint8_t v = mask[static_cast<size_t>(y) * width + x] != 0 ? 1 : 0;
      if (v != current) {
        counts.push_back(run);
        run = 0;
        current = v;
      }
      ++run;
    }
  counts.push_back(run);
  return counts;
}

std::vector<std::uint8_t> cocoRleDecode(const std::vector<std::uint32_t>& counts, int width,
                                        int height) {
  const size_t n = static_cast<size_t>(width) * height;
  std::vector<std::uint8_t> mask(n, 0);
  size_t at = 0;  // position in column-major order
  std::uint8_t value = 0;
  for (std::uint32_t run : counts) {
    ESIM_VERIFY(at + run <= n, "cocoRleDecode: the runs cover more than " + std::to_string(width) +
                                   "x" + std::to_string(height) + " pixels");
    for (std::uint32_t k = 0; k < run; ++k, ++at) mask[(at % height) * width + at / height] = value;
    value ^= 1;
  }
  ESIM_VERIFY(at == n, "cocoRleDecode: the runs cover " + std::to_string(at) + " of " +
                           std::to_string(n) + " pixels");
  return mask;
}

}  // namespace esim
