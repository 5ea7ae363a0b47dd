// Tests for render/labels.cpp and the label pass (render/label_pass.cpp, Renderer::renderLabels):
// the tool's mask pixels are the frame's tool pixels (MSAA off), background and tissue match
// the lit frame too, tissue states and their priority, depth against the camera geometry,
// the overlay's pixels, determinism (renders, renderers, llvmpipe thread counts), COCO RLE.
#include "render/labels.h"

#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "render/image_hash.h"
#include "render/renderer.h"
#include "sim/core_error.h"
#include "tests/render/llvmpipe_threads_util.h"

namespace esim {
namespace {

constexpr int kW = 160, kH = 120;

std::uint8_t cls(LabelClass c) { return static_cast<std::uint8_t>(c); }

// the camera straight above the plane z = 0, 0.1 m up, +y up in the image
RenderOptions topDown(const std::string& look = "tissue") {
  RenderOptions o;
  o.width = kW;
  o.height = kH;
  o.look = look;
  o.eyeM = {0, 0, 0.1f};
  o.targetM = {0, 0, 0};
  o.up = {0, 1, 0};
  o.fovDeg = 35;
  o.showColorBar = false;
  o.showTime = false;
  o.lighting = false;
  o.msaaSamples = 0;
  return o;
}

// one quad (two triangles, counter-clockwise seen from +z) at height z; per-corner states
// (coagulation, desiccation, cut wall), corners in the order (x0,y0) (x1,y0) (x1,y1) (x0,y1)
void addQuad(SurfaceSnapshot& s, float x0, float x1, float y0, float y1, float z,
             std::array<std::array<float, 3>, 4> states = {}) {
  const auto base = static_cast<std::uint32_t>(s.numVertices());
  const float xs[4] = {x0, x1, x1, x0}, ys[4] = {y0, y0, y1, y1};
  for (int i = 0; i < 4; ++i) {
    s.positionsM.insert(s.positionsM.end(), {xs[i], ys[i], z});
    s.temperatureC.push_back(37);
    s.coagulation.push_back(states[i][0]);
    s.desiccation.push_back(states[i][1]);
    s.cutWall.push_back(states[i][2]);
  }
  s.triangles.insert(s.triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

std::array<std::array<float, 3>, 4> uniform(float coag, float dry, float wall) {
  return {{{coag, dry, wall}, {coag, dry, wall}, {coag, dry, wall}, {coag, dry, wall}}};
}

// tissue 60 x 40 mm, a blade lying 4 mm above it along +y, its handle over the background
SurfaceSnapshot withBlade(ElectrodeKind kind = ElectrodeKind::Blade) {
  SurfaceSnapshot s;
  addQuad(s, -0.03f, 0.03f, -0.02f, 0.02f, 0.0f);
  s.tool.present = true;
  s.tool.kind = kind;
  s.tool.tipM = {0.0f, -0.01f, 0.004f};
  s.tool.orientationWxyz = {0.70710678f, -0.70710678f, 0.0f, 0.0f};
  s.tool.radiusM = kind == ElectrodeKind::Blade ? 0.0004f : 0.002f;
  s.tool.widthM = 0.004f;
  s.tool.lengthM = 0.02f;
  return s;
}

bool samePixel(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b, size_t i) {
  return a[3 * i] == b[3 * i] && a[3 * i + 1] == b[3 * i + 1] && a[3 * i + 2] == b[3 * i + 2];
}

// the counts of LabelFrame recounted from its planes
void expectCountsMatch(const LabelFrame& l) {
  std::array<long, kLabelClassCount> classes{};
  std::array<long, kLabelStateCount> states{};
  for (size_t i = 0; i < l.classes.size(); ++i) {
    ++classes[l.classes[i]];
    for (int b = 0; b < kLabelStateCount; ++b) states[b] += (l.states[i] >> b) & 1;
  }
  EXPECT_EQ(l.classPixels, classes);
  EXPECT_EQ(l.statePixels, states);
}

bool isTool(std::uint8_t c) {
  return c == cls(LabelClass::ToolTip) || c == cls(LabelClass::ToolShaft);
}

TEST(Labels, ClassTableIsConsistent) {
  const auto& classes = labelClasses();
  for (int i = 0; i < kLabelClassCount; ++i) {
    EXPECT_EQ(classes[i].id, i);
    for (int j = 0; j < i; ++j) {
      EXPECT_STRNE(classes[i].name, classes[j].name);
      EXPECT_NE(classes[i].rgb, classes[j].rgb) << classes[i].name << " and " << classes[j].name;
    }
  }
  EXPECT_STREQ(classes[static_cast<int>(LabelClass::ToolTip)].name, "tool_tip");
  EXPECT_NEAR(kCoagulatedMin, 1 - std::exp(-1.0), 1e-7);
}

TEST(Labels, RenderLabelsNeedsAFrame) {
  Renderer r(topDown());
  EXPECT_THROW(r.renderLabels(), Error);
}

// MSAA off, flat colours: the pixels the electrode changes in the frame are exactly its mask
// pixels, and among them the bare metal's colour is exactly class tool_tip
TEST(Labels, ToolMaskIsExactlyWhereTheFrameShowsTheTool) {
  for (const ElectrodeKind kind : {ElectrodeKind::Blade, ElectrodeKind::Sphere}) {
    Renderer r(topDown());
    SurfaceSnapshot s = withBlade(kind);
    const std::vector<std::uint8_t> with = r.render(s);
    const LabelFrame labels = r.renderLabels();
    s.tool.present = false;
    const std::vector<std::uint8_t> without = r.render(s);
    ASSERT_EQ(labels.classes.size(), static_cast<size_t>(kW * kH));
    long toolPixels = 0, overBackground = 0, tip = 0;
    for (size_t i = 0; i < labels.classes.size(); ++i) {
      const bool shows = !samePixel(with, without, i);
      ASSERT_EQ(isTool(labels.classes[i]), shows)
          << "pixel " << i % kW << "," << i / kW << " class " << int(labels.classes[i]);
      toolPixels += shows;
      // unlit bare metal: albedo (0.70, 0.71, 0.73) = (178.5, 181.05, 186.15) / 255
      // (tool_mesh.cpp; the insulation is 33-36, the handle 201-207)
      const bool metal = std::abs(with[3 * i] - 178.5) < 1 &&
                         std::abs(with[3 * i + 1] - 181.05) < 1 &&
                         std::abs(with[3 * i + 2] - 186.15) < 1;
      if (shows) {
        EXPECT_EQ(labels.classes[i] == cls(LabelClass::ToolTip), metal)
            << int(with[3 * i]) << "," << int(with[3 * i + 1]) << "," << int(with[3 * i + 2]);
      }
      tip += labels.classes[i] == cls(LabelClass::ToolTip);
      const size_t row = i / kW;
      const auto bg = backgroundColor(static_cast<int>(row), kH);
      overBackground += shows && without[3 * i] == bg[0] && without[3 * i + 1] == bg[1] &&
                        without[3 * i + 2] == bg[2];
    }
    EXPECT_GT(toolPixels, 300);
    EXPECT_GT(tip, 30);
    EXPECT_GT(overBackground, 50) << "the handle should reach over the background";
    EXPECT_EQ(labels.classPixels[static_cast<int>(LabelClass::ToolTip)], tip);
  }
}

// lit, per-vertex shading, the electrode's shadow (the frame's other vertex shaders): the
// background of the mask is exactly where the frame shows the background gradient
TEST(Labels, BackgroundIsExactlyWhereTheLitFrameShowsIt) {
  for (const std::string look : {"temperature", "tissue"}) {
    for (const std::string shading : {"vertex", "pixel"}) {
      RenderOptions o = topDown(look);
      o.lighting = true;
      o.shading = shading;
      Renderer r(o);
      SurfaceSnapshot s = withBlade();
      const std::vector<std::uint8_t>& frame = r.render(s);
      const LabelFrame& labels = r.renderLabels();
      long background = 0;
      for (size_t i = 0; i < labels.classes.size(); ++i) {
        const auto bg = backgroundColor(static_cast<int>(i / kW), kH);
        const bool showsBackground =
            frame[3 * i] == bg[0] && frame[3 * i + 1] == bg[1] && frame[3 * i + 2] == bg[2];
        ASSERT_EQ(labels.classes[i] == cls(LabelClass::Background), showsBackground)
            << look << "/" << shading << " pixel " << i % kW << "," << i / kW;
        background += showsBackground;
      }
      EXPECT_GT(background, 1000);
      EXPECT_LT(background, kW * kH - 1000);
    }
  }
}

// pixel of world point (x, y, 0) in topDown()
size_t pixelIndex(const RenderOptions& o, double x, double y) {
  const auto p = projectToPixel(cameraModel(o), {x, y, 0});
  return static_cast<size_t>(std::lround(p[1])) * kW + static_cast<size_t>(std::lround(p[0]));
}

TEST(Labels, TissueStatesThresholdsAndPriority) {
  const RenderOptions o = topDown();
  SurfaceSnapshot s;
  // a row of 8 mm squares: intact, coagulated (0.64 >= 1 - 1/e), just below (0.62),
  // desiccated (0.51 >= 0.5), below (0.49), cut wall, cut wall + coagulated, all three
  const std::array<std::array<float, 3>, 8> states{{{0, 0, 0},
                                                    {0.64f, 0, 0},
                                                    {0.62f, 0, 0},
                                                    {0, 0.51f, 0},
                                                    {0, 0.49f, 0},
                                                    {0, 0, 1},
                                                    {0.9f, 0, 1},
                                                    {0.9f, 0.9f, 1}}};
  const std::array<LabelClass, 8> want{
      LabelClass::Tissue, LabelClass::Coagulated, LabelClass::Tissue,     LabelClass::Desiccated,
      LabelClass::Tissue, LabelClass::CutWall,    LabelClass::Coagulated, LabelClass::Desiccated};
  const std::array<std::uint8_t, 8> wantStates{0, 1, 0, 2, 0, 4, 5, 7};
  for (int k = 0; k < 8; ++k)
    addQuad(s, -0.032f + 0.008f * k, -0.024f + 0.008f * k, -0.004f, 0.004f, 0.0f,
            uniform(states[k][0], states[k][1], states[k][2]));
  Renderer r(o);
  r.render(s);
  const LabelFrame& labels = r.renderLabels();
  for (int k = 0; k < 8; ++k) {
    const size_t i = pixelIndex(o, -0.028 + 0.008 * k, 0.0);
    EXPECT_EQ(labels.classes[i], cls(want[k])) << "square " << k;
    EXPECT_EQ(labels.states[i], wantStates[k]) << "square " << k;
  }
  EXPECT_EQ(labels.classes[pixelIndex(o, 0.0, 0.01)], cls(LabelClass::Background));
  EXPECT_EQ(labels.depth[pixelIndex(o, 0.0, 0.01)], 0);
  expectCountsMatch(labels);
  EXPECT_GT(labels.statePixels[0], 600);  // coagulated: squares 1, 6, 7 (~15 x 15 px each)
}

// per-fragment thresholding: on a ramp of coagulation 0..1 along x the boundary falls where
// the interpolated value crosses 1 - 1/e, not on a triangle edge
TEST(Labels, StatesAreThresholdedPerFragment) {
  const RenderOptions o = topDown();
  SurfaceSnapshot s;
  const float x0 = -0.02f, x1 = 0.02f;
  addQuad(s, x0, x1, -0.01f, 0.01f, 0.0f, {{{0, 0, 0}, {1, 0, 0}, {1, 0, 0}, {0, 0, 0}}});
  Renderer r(o);
  r.render(s);
  const LabelFrame& labels = r.renderLabels();
  const CameraModel cam = cameraModel(o);
  const double metresPerPixel = 0.1 / cam.fx;
  const int row = kH / 2;
  int checked = 0;
  for (int col = 0; col < kW; ++col) {
    const double x = (col - cam.cx) * metresPerPixel;  // the pixel centre on the plane
    if (x < x0 + 1e-3 || x > x1 - 1e-3) continue;
    const double coag = (x - x0) / (x1 - x0);
    if (std::abs(coag - kCoagulatedMin) < 0.01) continue;  // the boundary pixel itself
    EXPECT_EQ(labels.classes[static_cast<size_t>(row) * kW + col],
              cls(coag >= kCoagulatedMin ? LabelClass::Coagulated : LabelClass::Tissue))
        << "column " << col << " coagulation " << coag;
    ++checked;
  }
  EXPECT_GT(checked, 60);
}

// depth of a plane seen obliquely (the paper_slab camera) against the pinhole model:
// the ray through each pixel centre, cut with the plane, its Z in camera coordinates
TEST(Labels, DepthOfTheTopFaceMatchesTheCameraGeometry) {
  RenderOptions o = topDown("temperature");
  o.width = 320;
  o.height = 180;
  o.eyeM = {0.0f, -0.085f, 0.095f};
  o.targetM = {0.0f, 0.0f, 0.006f};
  o.up = {0, 0, 1};
  o.lighting = true;
  const float top = 0.01f;  // the slab's top face [m]
  SurfaceSnapshot s;
  addQuad(s, -0.05f, 0.05f, -0.05f, 0.05f, top);
  Renderer r(o);
  r.render(s);
  const LabelFrame& labels = r.renderLabels();
  const CameraModel cam = cameraModel(o);
  ASSERT_EQ(labels.depthUnitM, cam.depthUnitM);
  EXPECT_EQ(cam.depthUnitM, 1e-5);  // 4 x 0.127 m fits in 65535 x 10 um
  const auto& R = cam.rotation;
  double maxErrUnits = 0;
  long n = 0;
  for (int v = 0; v < o.height; ++v)
    for (int u = 0; u < o.width; ++u) {
      const size_t i = static_cast<size_t>(v) * o.width + u;
      if (labels.classes[i] != cls(LabelClass::Tissue)) continue;
      // ray direction in the camera (Z = 1), then in the world (R^T d)
      const double dc[3] = {(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0};
      double dw[3];
      for (int k = 0; k < 3; ++k) dw[k] = R[k] * dc[0] + R[3 + k] * dc[1] + R[6 + k] * dc[2];
      const double zCam = (top - cam.eyeM[2]) / dw[2];  // the ray's parameter is its Z
      const double err = std::abs(labels.depth[i] - zCam / cam.depthUnitM);
      maxErrUnits = std::max(maxErrUnits, err);
      ++n;
    }
  EXPECT_GT(n, o.width * o.height / 3);
  // rounding to the unit (0.5) and float interpolation: within 0.6 units = 6 um
  EXPECT_LE(maxErrUnits, 0.6) << "largest depth error " << maxErrUnits * 1e-2 << " mm";
}

// the tool tip projects to a tool pixel (the camera model and the draw agree), whose depth is
// where that pixel's ray meets the ball
TEST(Labels, ToolTipProjectsOntoTheTip) {
  const RenderOptions o = topDown();
  Renderer r(o);
  SurfaceSnapshot s = withBlade(ElectrodeKind::Sphere);
  r.render(s);
  const LabelFrame& labels = r.renderLabels();
  const CameraModel cam = cameraModel(o);
  const auto p = projectToPixel(cam, {0.0, -0.01, 0.004});
  const long u = std::lround(p[0]), v = std::lround(p[1]);
  const size_t i = static_cast<size_t>(v) * kW + u;
  EXPECT_EQ(labels.classes[i], cls(LabelClass::ToolTip));
  // the camera looks down -z (R = diag(1, -1, -1)): ray (x, y, 0.1 - Z) with x = Z (u - cx)/fx,
  // y = -Z (v - cy)/fy; the ball of 2 mm around (0, -0.01, 0.004): the nearer root in Z
  const double a = (u - cam.cx) / cam.fx, b = -(v - cam.cy) / cam.fy;
  const double ox = 0, oy = 0.01, oz = 0.1 - 0.004, rr = 0.002;  // eye - centre
  // |(aZ + ox, bZ + oy, oz - Z)|^2 = r^2
  const double A = a * a + b * b + 1, B = 2 * (a * ox + b * oy - oz),
               C = ox * ox + oy * oy + oz * oz - rr * rr;
  const double zHit = (-B - std::sqrt(B * B - 4 * A * C)) / (2 * A);
  // a faceted ball (24 x 16 segments) lies within 2 mm x (1 - cos 7.5 deg cos 5.6 deg) =
  // 27 um inside the true one
  const double depth = labels.depth[i] * labels.depthUnitM;
  EXPECT_GE(depth, zHit - 1e-5);
  EXPECT_LE(depth, zHit + 3e-5);
}

// the overlay's pixels (time text, colour bar) are class overlay, the rest unchanged
TEST(Labels, OverlayPixelsAreMarked) {
  RenderOptions o = topDown("temperature");
  Renderer plain(o);
  plain.render(withBlade());
  const LabelFrame without = plain.renderLabels();
  o.showTime = true;
  o.showColorBar = true;
  Renderer r(o);
  SurfaceSnapshot s = withBlade();
  s.timeS = 1.25;
  const std::vector<std::uint8_t> frame = r.render(s);
  const LabelFrame& labels = r.renderLabels();
  const std::vector<std::uint8_t> bare = plain.render(s);
  long overlay = 0;
  for (size_t i = 0; i < labels.classes.size(); ++i) {
    if (labels.classes[i] == cls(LabelClass::Overlay)) {
      ++overlay;
    } else {
      EXPECT_EQ(labels.classes[i], without.classes[i]);
      EXPECT_TRUE(samePixel(frame, bare, i)) << "overlay pixel " << i << " not marked";
    }
  }
  EXPECT_GT(overlay, 200);
  EXPECT_EQ(labels.classPixels[static_cast<int>(LabelClass::Overlay)], overlay);
  expectCountsMatch(labels);
}

LabelFrame threadTestLabels() {
  RenderOptions o = topDown("tissue");
  o.lighting = true;
  o.showTime = true;
  SurfaceSnapshot s = withBlade();
  for (size_t v = 0; v < s.coagulation.size(); ++v) s.coagulation[v] = 0.4f * (v % 4);
  Renderer r(o);
  r.render(s);
  return r.renderLabels();
}

std::uint64_t labelHash(const LabelFrame& l) {
  return hashBytes(l.classes.data(), l.classes.size()) ^
         (3 * hashBytes(reinterpret_cast<const std::uint8_t*>(l.depth.data()), 2 * l.depth.size()));
}

TEST(Labels, DeterministicAcrossRendersAndRenderers) {
  RenderOptions o = topDown("tissue");
  o.lighting = true;
  Renderer a(o), b(o);
  a.render(withBlade());
  const std::uint64_t h1 = labelHash(a.renderLabels());
  a.render(withBlade());
  const std::uint64_t h2 = labelHash(a.renderLabels());
  b.render(withBlade());
  const std::uint64_t h3 = labelHash(b.renderLabels());
  EXPECT_EQ(h1, h2);
  EXPECT_EQ(h1, h3);
}

// child side: run by the test below in a fresh process with LP_NUM_THREADS set
TEST(Labels, DISABLED_WriteHashForThreadTest) {
  const char* out = std::getenv("ESIM_LABELS_HASH_OUT");
  ASSERT_NE(out, nullptr);
  std::ofstream(out) << labelHash(threadTestLabels());
}

TEST(Labels, SameLabelsWithOneAndTwoLlvmpipeThreads) {
  std::vector<std::uint64_t> hashes;
  ASSERT_NO_FATAL_FAILURE(
      render_test::hashesPerLlvmpipeThreads("Labels.DISABLED_WriteHashForThreadTest",
                                            "ESIM_LABELS_HASH_OUT", "esim_labels_test", &hashes));
  EXPECT_EQ(hashes[0], hashes[1]) << "LP_NUM_THREADS=1 and 2 gave different labels";
  EXPECT_EQ(hashes[0], labelHash(threadTestLabels()));
}

// ---- COCO RLE ----

TEST(Labels, CocoRleOfAKnownMask) {
  // 3 x 2, row-major:  0 1 1
  //                    1 1 0   column-major: 0 1 | 1 1 | 1 0 -> runs 1 zero, 4 ones, 1 zero
  const std::vector<std::uint8_t> mask{0, 1, 1, 1, 1, 0};
  EXPECT_EQ(cocoRleEncode(mask, 3, 2), (std::vector<std::uint32_t>{1, 4, 1}));
  // a mask starting with a set pixel begins with an empty run of zeros
  EXPECT_EQ(cocoRleEncode({1, 0, 0, 0, 0, 0}, 3, 2), (std::vector<std::uint32_t>{0, 1, 5}));
  EXPECT_EQ(cocoRleEncode(std::vector<std::uint8_t>(6, 0), 3, 2), (std::vector<std::uint32_t>{6}));
  EXPECT_THROW(cocoRleDecode({1, 4}, 3, 2), Error);
  EXPECT_THROW(cocoRleDecode({1, 4, 2}, 3, 2), Error);
}

TEST(Labels, CocoRleDecodesBackToTheToolMask) {
  Renderer r(topDown());
  r.render(withBlade());
  const LabelFrame& labels = r.renderLabels();
  std::vector<std::uint8_t> mask(labels.classes.size());
  for (size_t i = 0; i < mask.size(); ++i) mask[i] = isTool(labels.classes[i]) ? 1 : 0;
  const std::vector<std::uint32_t> counts = cocoRleEncode(mask, kW, kH);
  std::uint64_t sum = 0;
  for (std::uint32_t c : counts) sum += c;
  EXPECT_EQ(sum, static_cast<std::uint64_t>(kW * kH));
  EXPECT_EQ(cocoRleDecode(counts, kW, kH), mask);
}

// ---- camera ----

TEST(Labels, CameraModelIsOpenCv) {
  RenderOptions o = topDown();
  const CameraModel c = cameraModel(o);
  EXPECT_DOUBLE_EQ(c.cx, (kW - 1) / 2.0);
  EXPECT_DOUBLE_EQ(c.cy, (kH - 1) / 2.0);
  EXPECT_DOUBLE_EQ(c.fx, c.fy);
  EXPECT_NEAR(c.fy, 0.5 * kH / std::tan(17.5 * M_PI / 180), 1e-9);
  // +x of the world is right in the image, +y (the camera's up) is up: smaller v
  const auto centre = projectToPixel(c, {0, 0, 0});
  EXPECT_NEAR(centre[0], c.cx, 1e-6);
  EXPECT_NEAR(centre[1], c.cy, 1e-6);
  EXPECT_NEAR(centre[2], 0.1, 1e-7);
  EXPECT_GT(projectToPixel(c, {0.01, 0, 0})[0], c.cx);
  EXPECT_LT(projectToPixel(c, {0, 0.01, 0})[1], c.cy);
  // a far camera gets a coarser unit: {1, 2, 5} x 10^k, 4 x distance within 65535 units
  o.eyeM = {0, 0, 1.0f};
  EXPECT_DOUBLE_EQ(depthUnitM(o), 1e-4);
  o.eyeM = {0, 0, 0.2f};
  EXPECT_DOUBLE_EQ(depthUnitM(o), 2e-5);
}

}  // namespace
}  // namespace esim
