// Tests for render/renderer.cpp: colours at known pixels, colour bar, looks, tool,
// determinism across renders and renderers, OSMesa vs EGL, input errors.
#include "render/renderer.h"

#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "render/colormap.h"
#include "render/gl_context.h"
#include "render/image_hash.h"
#include "sim/core_error.h"
#include "tests/render/llvmpipe_threads_util.h"

namespace esim {
namespace {

constexpr int kW = 160, kH = 120;
constexpr float kDist = 0.1f;  // camera height above the plane z = 0 [m]
constexpr float kFov = 35.0f;

using Rgb = std::array<int, 3>;

RenderOptions topDown(const std::string& look = "temperature") {
  RenderOptions o;
  o.width = kW;
  o.height = kH;
  o.look = look;
  o.eyeM = {0, 0, kDist};
  o.targetM = {0, 0, 0};
  o.up = {0, 1, 0};
  o.fovDeg = kFov;
  o.showColorBar = false;
  o.showTime = false;
  o.lighting = false;
  return o;
}

// pixel (column, row from the top) of world point (x, y, 0) seen by topDown()
std::array<int, 2> pixelOf(float x, float y) {
  const float halfH = kDist * std::tan(kFov * 3.14159265f / 360.0f);
  const float halfW = halfH * kW / kH;
  return {static_cast<int>(std::floor((x / halfW + 1) * 0.5f * kW)),
          static_cast<int>(std::floor((1 - y / halfH) * 0.5f * kH))};
}

Rgb at(const std::vector<std::uint8_t>& img, int col, int row) {
  const std::uint8_t* p = &img[(static_cast<size_t>(row) * kW + col) * 3];
  return {p[0], p[1], p[2]};
}
Rgb atWorld(const std::vector<std::uint8_t>& img, float x, float y) {
  const auto p = pixelOf(x, y);
  return at(img, p[0], p[1]);
}

void expectNear(Rgb got, std::array<std::uint8_t, 3> want, int tol, const char* what) {
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(got[k], want[k], tol)
        << what << " channel " << k << " got (" << got[0] << "," << got[1] << "," << got[2] << ")";
}

// one quad (two triangles, counter-clockwise seen from +z) with uniform state
void addQuad(SurfaceSnapshot& s, float x0, float x1, float y0, float y1, std::array<float, 4> state,
             std::array<float, 2> temps = {-1, -1}) {
  const auto base = static_cast<std::uint32_t>(s.numVertices());
  const float xs[4] = {x0, x1, x1, x0}, ys[4] = {y0, y0, y1, y1};
  for (int i = 0; i < 4; ++i) {
    s.positionsM.insert(s.positionsM.end(), {xs[i], ys[i], 0.0f});
    float t = state[0];
    if (temps[0] >= 0) t = (i == 0 || i == 3) ? temps[0] : temps[1];  // ramp along x
    s.temperatureC.push_back(t);
    s.coagulation.push_back(state[1]);
    s.desiccation.push_back(state[2]);
    s.cutWall.push_back(state[3]);
  }
  s.triangles.insert(s.triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

// cold block (T = 0 C, below tMin) | ramp 0..200 C | hot block (T = 200 C, above tMax)
SurfaceSnapshot gradientStrip() {
  SurfaceSnapshot s;
  s.timeS = 1.25;
  addQuad(s, -0.03f, -0.006f, -0.02f, 0.02f, {0, 0, 0, 0});
  addQuad(s, -0.006f, 0.006f, -0.02f, 0.02f, {0, 0, 0, 0}, {0, 200});
  addQuad(s, 0.006f, 0.03f, -0.02f, 0.02f, {200, 0, 0, 0});
  return s;
}

TEST(Renderer, ContextStringsAndCoreVersion) {
  Renderer r(topDown());
  EXPECT_FALSE(r.glRenderer().empty());
  EXPECT_NE(r.glRenderer(), "unknown");
  const std::string v = r.glVersion();
  ASSERT_FALSE(v.empty());
  EXPECT_GE(std::stod(v.substr(0, 3)), 3.3) << v;
}

TEST(Renderer, ColormapEndpointsAndBackgroundUnlit) {
  for (const std::string map : {"inferno", "viridis"}) {
    RenderOptions o = topDown();
    o.colormap = map;
    Renderer r(o);
    const auto& img = r.render(gradientStrip());
    ASSERT_EQ(img.size(), static_cast<size_t>(kW * kH * 3));
    const ColormapLut& lut = colormapLut(map);
    expectNear(atWorld(img, -0.018f, 0.0f), lut[0], 1, "cold end");
    expectNear(atWorld(img, 0.018f, 0.01f), lut[255], 1, "hot end");
    // inside the ramp T = 100 C + x * 200 C / 12 mm; t = (T - 37) / 83 at the pixel centre
    const auto px = pixelOf(-0.002f, 0.0f);
    const float halfW = kDist * std::tan(kFov * 3.14159265f / 360.0f) * kW / kH;
    const double xCentre = ((px[0] + 0.5) / kW * 2 - 1) * halfW;
    const double tRamp = (100.0 + xCentre / 0.012 * 200.0 - 37.0) / 83.0;
    expectNear(at(img, px[0], px[1]), lut[static_cast<int>(std::lround(tRamp * 255))], 3,
               "ramp middle");
    // corners are background: top row and bottom row of the gradient
    expectNear(at(img, 0, 0), backgroundColor(0, kH), 1, "top-left background");
    expectNear(at(img, kW - 1, kH - 1), backgroundColor(kH - 1, kH), 1, "bottom-right background");
  }
  // the gradient runs from light grey-blue at the top to near black at the bottom
  EXPECT_GT(backgroundColor(0, kH)[2], backgroundColor(kH - 1, kH)[2] + 30);
}

TEST(Renderer, ColorBarShowsTheMapHotOnTop) {
  RenderOptions o = topDown();
  o.showColorBar = true;
  Renderer r(o);
  const auto& img = r.render(SurfaceSnapshot{});  // background and overlay only
  const ColormapLut& lut = colormapLut(o.colormap);
  // find the column in the right quarter holding the longest run of lut[255]..lut[0]
  bool found = false;
  for (int col = kW - 1; col > 3 * kW / 4 && !found; --col) {
    int top = -1, bottom = -1;
    for (int row = 0; row < kH; ++row) {
      const Rgb c = at(img, col, row);
      if (top < 0 && c == Rgb{lut[255][0], lut[255][1], lut[255][2]}) top = row;
      if (c == Rgb{lut[0][0], lut[0][1], lut[0][2]}) bottom = row;
    }
    if (top >= 0 && bottom > top + kH / 3) {
      found = true;
      // monotone darkening (luma) from top to bottom of the bar
      int prevLuma = 1 << 30;
      for (int row = top; row <= bottom; ++row) {
        const Rgb c = at(img, col, row);
        const int luma = 77 * c[0] + 150 * c[1] + 29 * c[2];
        EXPECT_LE(luma, prevLuma + 256) << "row " << row;
        prevLuma = luma;
      }
    }
  }
  EXPECT_TRUE(found) << "no colour bar from lut[255] down to lut[0] in the right quarter";
  // tick labels: light text pixels left of the bar
  int textPixels = 0;
  for (int row = 0; row < kH; ++row)
    for (int col = kW / 2; col < kW - 10; ++col)
      if (at(img, col, row) == Rgb{236, 236, 236}) ++textPixels;
  EXPECT_GT(textPixels, 40);
}

TEST(Renderer, TimeTextAppearsTopLeftAndChangesWithTime) {
  RenderOptions o = topDown();
  o.showTime = true;
  Renderer r(o);
  SurfaceSnapshot s = gradientStrip();
  const std::vector<std::uint8_t> a = r.render(s);
  s.timeS = 2.5;
  const std::vector<std::uint8_t> b = r.render(s);
  o.showTime = false;
  Renderer plain(o);
  const std::vector<std::uint8_t> c = plain.render(s);
  int diffs = 0, outside = 0, white = 0;
  for (int row = 0; row < kH; ++row)
    for (int col = 0; col < kW; ++col) {
      if (at(b, col, row) != at(c, col, row)) {
        ++diffs;
        if (row > kH / 3 || col > kW / 2) ++outside;
      }
      if (at(b, col, row) == Rgb{236, 236, 236}) ++white;
    }
  EXPECT_GT(diffs, 30);
  EXPECT_EQ(outside, 0) << "the time text must stay in the top-left corner";
  EXPECT_GT(white, 20);
  EXPECT_NE(hashFrame(a), hashFrame(b));
}

TEST(Renderer, LightingShadesButKeepsHotBrighter) {
  RenderOptions o = topDown();
  o.lighting = true;
  Renderer lit(o);
  const std::vector<std::uint8_t> a = lit.render(gradientStrip());
  Renderer flat(topDown());
  const std::vector<std::uint8_t>& b = flat.render(gradientStrip());
  EXPECT_NE(hashFrame(a), hashFrame(b));
  const Rgb hot = atWorld(a, 0.018f, 0.0f), cold = atWorld(a, -0.018f, 0.0f);
  EXPECT_GT(hot[0] + hot[1] + hot[2], cold[0] + cold[1] + cold[2] + 300);
  // a plane facing the camera: key light at ~50 deg plus ambient keeps the hue
  const Rgb hotFlat = atWorld(b, 0.018f, 0.0f);
  EXPECT_GT(hot[0], hot[2]);
  EXPECT_NEAR(static_cast<double>(hot[1]) / hot[0], static_cast<double>(hotFlat[1]) / hotFlat[0],
              0.15);
}

TEST(Renderer, TissueLookStates) {
  // four separate quads: fresh | coagulated | charred | cut wall
  SurfaceSnapshot s;
  addQuad(s, -0.030f, -0.016f, -0.02f, 0.02f, {37, 0, 0, 0});
  addQuad(s, -0.014f, -0.001f, -0.02f, 0.02f, {37, 1, 0, 0});
  addQuad(s, 0.001f, 0.014f, -0.02f, 0.02f, {37, 1, 1, 0});
  addQuad(s, 0.016f, 0.030f, -0.02f, 0.02f, {37, 0, 0, 1});
  Renderer r(topDown("tissue"));
  const auto& img = r.render(s);
  const Rgb fresh = atWorld(img, -0.023f, 0.0f), coag = atWorld(img, -0.0075f, 0.0f);
  const Rgb charred = atWorld(img, 0.0075f, 0.0f), wall = atWorld(img, 0.023f, 0.0f);
  EXPECT_GT(fresh[0], fresh[1] + 60) << "fresh tissue is pink-red";
  EXPECT_GT(fresh[0], 150);
  EXPECT_GT(std::min({coag[0], coag[1], coag[2]}), 150) << "coagulated tissue whitens";
  EXPECT_LT(coag[0] - coag[2], 60);
  EXPECT_LT(std::max({charred[0], charred[1], charred[2]}), 40) << "desiccated tissue chars";
  EXPECT_LT(wall[0], fresh[0] - 25) << "the cut wall is darker";
  EXPECT_GT(wall[0], wall[1] + 40) << "and still red";
}

// look.texture_seed: another seed another mottling, the same seed the same bytes, the tissue's
// mean colour kept; the temperature look has no mottling to change
TEST(Renderer, TextureSeedChangesTheTissueMottlingOnly) {
  SurfaceSnapshot s;
  addQuad(s, -0.03f, 0.03f, -0.02f, 0.02f, {37, 0, 0, 0});
  auto render = [&](const std::string& look, std::uint32_t seed) {
    RenderOptions o = topDown(look);
    o.textureSeed = seed;
    Renderer r(o);
    return r.render(s);
  };
  const auto mean = [](const std::vector<std::uint8_t>& img, int c) {
    double sum = 0;
    int n = 0;
    for (int row = 10; row < kH - 10; ++row)
      for (int col = 10; col < kW - 10; ++col, ++n) sum += img[(row * kW + col) * 3 + c];
    return sum / n;
  };
  const auto a = render("tissue", 0), b = render("tissue", 7), b2 = render("tissue", 7);
  EXPECT_EQ(hashFrame(b), hashFrame(b2));
  int differ = 0;
  for (size_t i = 0; i < a.size(); i += 3) differ += a[i] != b[i];
  EXPECT_GT(differ, static_cast<int>(a.size() / 3 / 4)) << "the pattern changes";  // 43 % here
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean(a, c), mean(b, c), 3.0) << "channel " << c;
  EXPECT_EQ(hashFrame(render("temperature", 0)), hashFrame(render("temperature", 7)));
}

// look.tissue_tint multiplies the tissue's colours (unlit: the albedo itself, to rounding);
// look.light_intensity 0 leaves the ambient term alone (0.30 of the albedo, fill and key and
// highlights off), 2 brightens; a key light from behind the plane darkens it
TEST(Renderer, TintAndLightsScaleAsAsked) {
  SurfaceSnapshot s;
  addQuad(s, -0.03f, 0.03f, -0.02f, 0.02f, {37, 0, 0, 0});
  RenderOptions o = topDown("tissue");
  Renderer plain(o);
  const std::vector<std::uint8_t> base = plain.render(s);
  o.tissueTint = {1.0f, 0.5f, 0.25f};
  Renderer tinted(o);
  const std::vector<std::uint8_t> tint = tinted.render(s);
  for (const float x : {-0.02f, 0.0f, 0.015f}) {
    const Rgb p = atWorld(base, x, 0.0f), q = atWorld(tint, x, 0.0f);
    EXPECT_NEAR(q[0], p[0], 1);
    EXPECT_NEAR(q[1], 0.5 * p[1], 1);
    EXPECT_NEAR(q[2], 0.25 * p[2], 1);
  }
  const auto litPixel = [&](float intensity, std::array<float, 3> key) {
    RenderOptions l = topDown("tissue");
    l.lighting = true;
    l.lightIntensity = intensity;
    l.keyLightCamera = key;
    Renderer r(l);
    return atWorld(r.render(s), 0.0f, 0.0f);
  };
  const std::array<float, 3> defaultKey = RenderOptions{}.keyLightCamera;
  const Rgb albedo = atWorld(base, 0.0f, 0.0f), dark = litPixel(0, defaultKey);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(dark[c], 0.30 * albedo[c], 1.0) << "channel " << c;
  const Rgb lit = litPixel(1, defaultKey), bright = litPixel(2, defaultKey);
  const Rgb behind = litPixel(1, {0.0f, 0.0f, -1.0f});
  EXPECT_GT(lit[0] + lit[1] + lit[2], dark[0] + dark[1] + dark[2] + 60);
  EXPECT_GT(bright[1] + bright[2], lit[1] + lit[2] + 30);
  EXPECT_LT(behind[0] + behind[1] + behind[2], lit[0] + lit[1] + lit[2] - 60);
  EXPECT_GT(behind[0] + behind[1] + behind[2], dark[0] + dark[1] + dark[2]) << "the fill stays";
}

// rotation taking the tool axis (local +z) to world +y: -90 deg about x
SurfaceSnapshot withBlade(bool generatorOn) {
  SurfaceSnapshot s;
  addQuad(s, -0.03f, 0.03f, -0.02f, 0.02f, {37, 0, 0, 0});
  s.tool.present = true;
  s.tool.generatorOn = generatorOn;
  s.tool.kind = ElectrodeKind::Blade;
  s.tool.tipM = {0.0f, -0.01f, 0.004f};
  s.tool.orientationWxyz = {0.70710678f, -0.70710678f, 0.0f, 0.0f};
  s.tool.radiusM = 0.0004f;
  s.tool.widthM = 0.004f;
  s.tool.lengthM = 0.02f;
  return s;
}

TEST(Renderer, BladeElectrodeIsMetallicGreyAndGlowsWhenOn) {
  Renderer r(topDown("tissue"));
  const std::vector<std::uint8_t> off = r.render(withBlade(false));
  // blade face between 2 and 8 mm from the tip along +y: unlit metal albedo (0.70, 0.71, 0.73)
  const Rgb metal = atWorld(off, 0.0f, -0.01f + 0.006f);
  expectNear(metal, {179, 181, 186}, 2, "blade metal");
  // insulated shaft is dark, the handle light
  const Rgb shaft = atWorld(off, 0.0f, -0.01f + 0.016f);
  EXPECT_LT(std::max({shaft[0], shaft[1], shaft[2]}), 50);
  // beside the blade the tissue shows
  const Rgb beside = atWorld(off, 0.008f, -0.006f);
  EXPECT_GT(beside[0], beside[1] + 60);
  // generator on: orange glow at the tip
  const std::vector<std::uint8_t> on = r.render(withBlade(true));
  const Rgb tip = atWorld(on, 0.0f, -0.01f + 0.0012f),
            tipOff = atWorld(off, 0.0f, -0.01f + 0.0012f);
  EXPECT_GT(tip[0] - tip[2], tipOff[0] - tipOff[2] + 30);
}

TEST(Renderer, SphereElectrodeIsDrawnAtTheTip) {
  SurfaceSnapshot s = withBlade(false);
  s.tool.kind = ElectrodeKind::Sphere;
  s.tool.radiusM = 0.002f;
  Renderer r(topDown("tissue"));
  const auto& img = r.render(s);
  // ball centred at the tip: metallic grey there (unlit albedo)
  expectNear(atWorld(img, 0.0f, -0.01f), {179, 181, 186}, 2, "ball centre");
  // 3 mm to the side of the ball: tissue
  const Rgb side = atWorld(img, 0.004f, -0.01f);
  EXPECT_GT(side[0], side[1] + 60);
}

TEST(Renderer, DeterministicAcrossRendersAndRenderers) {
  RenderOptions o = topDown("tissue");
  o.lighting = true;
  o.showTime = true;
  Renderer a(o);
  const std::uint64_t h1 = hashFrame(a.render(withBlade(true)));
  const std::uint64_t h2 = hashFrame(a.render(withBlade(true)));
  Renderer b(o);
  const std::uint64_t h3 = hashFrame(b.render(withBlade(true)));
  EXPECT_EQ(h1, h2);
  EXPECT_EQ(h1, h3);
}

// frames with the same geometry rewrite only the vertex states (renderer.cpp,
// SurfaceBuffers): the result must be the bytes a fresh renderer draws, and a
// change of positions or triangles must rebuild the normals
TEST(Renderer, ReusedGeometryGivesTheBytesOfAFreshRender) {
  RenderOptions o = topDown("temperature");
  o.lighting = true;
  o.msaaSamples = 0;
  SurfaceSnapshot cold = withBlade(true);
  SurfaceSnapshot hot = cold;
  for (size_t v = 0; v < hot.temperatureC.size(); ++v) hot.temperatureC[v] = 37.0f + 30.0f * v;
  SurfaceSnapshot tilted = hot;
  for (size_t v = 0; v < tilted.temperatureC.size(); ++v)
    tilted.positionsM[3 * v + 2] = 0.2f * tilted.positionsM[3 * v];  // z = 0.2 x
  Renderer fresh(o);
  const std::uint64_t hotFresh = hashFrame(fresh.render(hot));
  Renderer freshTilted(o);
  const std::uint64_t tiltedFresh = hashFrame(freshTilted.render(tilted));
  ASSERT_NE(hotFresh, tiltedFresh);
  Renderer r(o);
  r.render(cold);
  EXPECT_EQ(hashFrame(r.render(hot)), hotFresh);        // states rewritten only
  EXPECT_EQ(hashFrame(r.render(tilted)), tiltedFresh);  // positions changed: rebuilt
  EXPECT_EQ(hashFrame(r.render(hot)), hotFresh);
}

// closed latitude-longitude sphere of radius r [m] at the origin, counter-clockwise
// from outside, T ramping 37..97 C from bottom to top
SurfaceSnapshot uvSphere(float r, int segments, int rings) {
  SurfaceSnapshot s;
  auto add = [&](float x, float y, float z) {
    s.positionsM.insert(s.positionsM.end(), {x, y, z});
    s.temperatureC.push_back(67.0f + 30.0f * z / r);
    return static_cast<std::uint32_t>(s.temperatureC.size() - 1);
  };
  const std::uint32_t south = add(0, 0, -r), north = add(0, 0, r);
  auto ring = [&](int j, int i) {  // vertex i of ring j = 1..rings-1
    return 2 + static_cast<std::uint32_t>((j - 1) * segments + (i % segments));
  };
  for (int j = 1; j < rings; ++j) {
    const float th = 3.14159265f * j / rings;
    for (int i = 0; i < segments; ++i) {
      const float ph = 2 * 3.14159265f * i / segments;
      add(r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), -r * std::cos(th));
    }
  }
  for (int i = 0; i < segments; ++i) {
    s.triangles.insert(s.triangles.end(), {south, ring(1, i + 1), ring(1, i)});
    s.triangles.insert(s.triangles.end(), {north, ring(rings - 1, i), ring(rings - 1, i + 1)});
    for (int j = 1; j + 1 < rings; ++j)
      s.triangles.insert(s.triangles.end(), {ring(j, i), ring(j, i + 1), ring(j + 1, i + 1),
                                             ring(j, i), ring(j + 1, i + 1), ring(j + 1, i)});
  }
  return s;
}

// per-vertex lighting: the same as per pixel on a flat face (one normal), visibly
// different on a coarse sphere, and converging to it as the sphere is refined
TEST(Renderer, VertexShadingMatchesPixelShadingOnFineMeshes) {
  RenderOptions o = topDown("temperature");
  o.lighting = true;
  o.msaaSamples = 0;
  o.eyeM = {0.0f, -0.06f, 0.05f};
  o.up = {0, 0, 1};
  auto compare = [&](const SurfaceSnapshot& s) {
    RenderOptions pixel = o, vertex = o;
    pixel.shading = "pixel";
    vertex.shading = "vertex";
    Renderer a(pixel), b(vertex);
    return compareImages(a.render(s), b.render(s), kW, kH);
  };
  SurfaceSnapshot flat = withBlade(false);
  flat.tool.present = false;
  const ImageComparison plane = compare(flat);
  EXPECT_LE(plane.maxDiff, 1);
  const ImageComparison coarse = compare(uvSphere(0.02f, 8, 6));
  const ImageComparison fine = compare(uvSphere(0.02f, 128, 64));
  EXPECT_GT(coarse.maxDiff, 20) << "coarse facets should show Gouraud interpolation";
  EXPECT_LT(coarse.psnrDb, 45);  // measured 38.9 dB, max diff 27
  EXPECT_GT(fine.psnrDb, 55) << "fine sphere: max diff " << fine.maxDiff;  // measured 66.8 dB
  EXPECT_GT(fine.psnrDb, coarse.psnrDb + 20);
}

TEST(Renderer, OsMesaAndEglGiveIdenticalPixels) {
  std::string reason;
  if (!eglBackendAvailable(&reason)) GTEST_SKIP() << "EGL backend unavailable here: " << reason;
  RenderOptions o = topDown("temperature");
  o.lighting = true;
  o.showColorBar = true;
  o.showTime = true;
  SurfaceSnapshot s = withBlade(true);
  for (size_t v = 0; v < s.temperatureC.size(); ++v) s.temperatureC[v] = 37.0f + 30.0f * v;
  Renderer osm(o);
  const std::vector<std::uint8_t> a = osm.render(s);
  o.backend = "egl";
  Renderer egl(o);
  const std::vector<std::uint8_t> b = egl.render(s);
  EXPECT_NE(egl.glPlatform().find("EGL"), std::string::npos);
  const ImageComparison c = compareImages(a, b, kW, kH);
  EXPECT_EQ(hashFrame(a), hashFrame(b))
      << "PSNR " << c.psnrDb << " dB, " << c.offPixels << " pixels off";
  // and the first renderer still works after the second context was made current
  EXPECT_EQ(hashFrame(osm.render(s)), hashFrame(a));
}

// the scene of the thread test: lit tissue with a glowing blade, MSAA on
std::uint64_t threadTestHash() {
  RenderOptions o = topDown("tissue");
  o.lighting = true;
  o.showTime = true;
  SurfaceSnapshot s = withBlade(true);
  for (size_t v = 0; v < s.coagulation.size(); ++v) s.coagulation[v] = 0.3f * (v % 4);
  Renderer r(o);
  return hashFrame(r.render(s));
}

// child side: run by the test below in a fresh process with LP_NUM_THREADS set
TEST(Renderer, DISABLED_WriteHashForThreadTest) {
  const char* out = std::getenv("ESIM_RENDER_HASH_OUT");
  ASSERT_NE(out, nullptr);
  std::ofstream(out) << threadTestHash();
}

TEST(Renderer, SameHashWithOneAndTwoLlvmpipeThreads) {
  std::vector<std::uint64_t> hashes;
  ASSERT_NO_FATAL_FAILURE(
      render_test::hashesPerLlvmpipeThreads("Renderer.DISABLED_WriteHashForThreadTest",
                                            "ESIM_RENDER_HASH_OUT", "esim_renderer_test", &hashes));
  EXPECT_EQ(hashes[0], hashes[1]) << "LP_NUM_THREADS=1 and 2 rendered different pixels";
  EXPECT_EQ(hashes[0], threadTestHash()) << "differs from this process's default thread count";
}

// potential look: low block (0 V = vMin) | ramp 0..144 V along x | high block (100 V, above
// vMax); temperatures vary against the potential so a look mix-up shows
SurfaceSnapshot potentialStrip() {
  SurfaceSnapshot s;
  s.timeS = 0.5;
  addQuad(s, -0.03f, -0.006f, -0.02f, 0.02f, {120, 0, 0, 0});
  addQuad(s, -0.006f, 0.006f, -0.02f, 0.02f, {0, 0, 0, 0}, {200, 0});
  addQuad(s, 0.006f, 0.03f, -0.02f, 0.02f, {37, 0, 0, 0});
  s.potentialV = {0, 0, 0, 0, 0, 144, 144, 0, 100, 100, 100, 100};
  return s;
}

TEST(Renderer, PotentialLookColoursThePotentialLinearly) {
  for (const std::string map : {"viridis", "inferno"}) {
    RenderOptions o = topDown("potential");
    o.colormap = map;
    Renderer r(o);
    const auto& img = r.render(potentialStrip());
    const ColormapLut& lut = colormapLut(map);
    expectNear(atWorld(img, -0.018f, 0.0f), lut[0], 1, "0 V end");
    expectNear(atWorld(img, 0.018f, 0.01f), lut[255], 1, "above vMaxV, clamped");
    // ramp: phi = 72 V + x * 144 V / 12 mm; t = phi / 72 V at the pixel centre
    const auto px = pixelOf(-0.003f, 0.0f);
    const float halfW = kDist * std::tan(kFov * 3.14159265f / 360.0f) * kW / kH;
    const double xCentre = ((px[0] + 0.5) / kW * 2 - 1) * halfW;
    const double tRamp = (72.0 + xCentre / 0.012 * 144.0) / 72.0;
    ASSERT_GT(tRamp, 0.2);
    ASSERT_LT(tRamp, 0.8);
    expectNear(at(img, px[0], px[1]), lut[static_cast<int>(std::lround(tRamp * 255))], 3,
               "ramp middle");
  }
  // a different range moves the colours: vMaxV = 200 V puts 100 V at t = 0.5
  RenderOptions o = topDown("potential");
  o.colormap = "viridis";
  o.vMaxV = 200;
  Renderer r(o);
  expectNear(atWorld(r.render(potentialStrip()), 0.018f, 0.01f), colormapLut("viridis")[128], 2,
             "100 V of 0..200 V");
}

TEST(Renderer, PotentialLookLogScale) {
  RenderOptions o = topDown("potential");
  o.colormap = "viridis";
  o.potentialLogScale = true;
  o.vMinV = 1;
  o.vMaxV = 10000;
  Renderer r(o);
  SurfaceSnapshot s = potentialStrip();
  // 0 V is below vMinV (clamped to the low end), 100 V is half way in decades
  const auto& img = r.render(s);
  const ColormapLut& lut = colormapLut("viridis");
  expectNear(atWorld(img, -0.018f, 0.0f), lut[0], 1, "below vMinV");
  expectNear(atWorld(img, 0.018f, 0.01f), lut[128], 2, "100 V of 1..10^4 V");
  o.vMinV = 0;
  EXPECT_THROW(Renderer bad(o), Error) << "the log scale needs vMinV > 0";
}

TEST(Renderer, PotentialLookHasAVoltColorBar) {
  RenderOptions o = topDown("potential");
  o.colormap = "viridis";
  o.showColorBar = true;
  Renderer r(o);
  const std::vector<std::uint8_t> img = r.render(SurfaceSnapshot{});  // background and overlay
  const ColormapLut& lut = colormapLut(o.colormap);
  // a column in the right quarter running from lut[255] (top) down to lut[0]
  bool found = false;
  for (int col = kW - 1; col > 3 * kW / 4 && !found; --col) {
    int top = -1, bottom = -1;
    for (int row = 0; row < kH; ++row) {
      const Rgb c = at(img, col, row);
      if (top < 0 && c == Rgb{lut[255][0], lut[255][1], lut[255][2]}) top = row;
      if (c == Rgb{lut[0][0], lut[0][1], lut[0][2]}) bottom = row;
    }
    found = top >= 0 && bottom > top + kH / 3;
  }
  EXPECT_TRUE(found) << "no colour bar from lut[255] down to lut[0] in the right quarter";
  // labels differ from the temperature bar's (V and 0..72 instead of deg C and 37..120)
  RenderOptions t = o;
  t.look = "temperature";
  Renderer rt(t);
  const std::vector<std::uint8_t> timg = rt.render(SurfaceSnapshot{});
  int textPixels = 0, differing = 0;
  for (int row = 0; row < kH; ++row)
    for (int col = kW / 2; col < kW; ++col) {
      if (at(img, col, row) == Rgb{236, 236, 236}) ++textPixels;
      if (at(img, col, row) != at(timg, col, row)) ++differing;
    }
  EXPECT_GT(textPixels, 40);
  EXPECT_GT(differing, 20);
  // the log bar draws more ticks than 0..72 V linear (1, 2, 5, 10, 20, 50 vs 0, 20, 40, 60)
  o.potentialLogScale = true;
  o.vMinV = 1;
  Renderer rl(o);
  const std::vector<std::uint8_t> limg = rl.render(SurfaceSnapshot{});
  // ticks: grey rows just left of the bar's grey frame (its left column is the one with
  // the most grey pixels)
  auto tickRows = [&](const std::vector<std::uint8_t>& im) {
    const Rgb grey{200, 200, 200};
    int frameCol = -1, best = 0;
    for (int col = kW * 3 / 4; col < kW; ++col) {
      int n = 0;
      for (int row = 0; row < kH; ++row) n += at(im, col, row) == grey;
      if (n > best) best = n, frameCol = col;
    }
    int n = 0;
    for (int row = 0; row < kH && frameCol >= 2; ++row) n += at(im, frameCol - 2, row) == grey;
    return n;
  };
  EXPECT_GT(tickRows(limg), tickRows(img));
}

TEST(Renderer, PotentialLookNeedsTheElectricPhase) {
  Renderer r(topDown("potential"));
  SurfaceSnapshot s = gradientStrip();  // no potentialV
  try {
    r.render(s);
    ADD_FAILURE() << "no error for a potential look without potentialV";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("look.style: potential needs the electric phase"),
              std::string::npos)
        << e.what();
  }
  s = potentialStrip();
  s.potentialV.pop_back();
  EXPECT_THROW(r.render(s), Error);
  s = potentialStrip();
  s.potentialV[3] = std::nanf("");
  EXPECT_THROW(r.render(s), Error);
  // other looks ignore a missing potential
  Renderer t(topDown("temperature"));
  EXPECT_NO_THROW(t.render(gradientStrip()));
}

TEST(Renderer, RejectsBadOptionsAndSnapshots) {
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  RenderOptions o = topDown();
  o.look = "xray";
  EXPECT_NE(message([&] { Renderer r(o); }).find("look.style"), std::string::npos);
  o = topDown();
  o.colormap = "jet";
  EXPECT_NE(message([&] { Renderer r(o); }).find("look.colormap"), std::string::npos);
  o = topDown();
  o.tMaxC = o.tMinC;
  EXPECT_NE(message([&] { Renderer r(o); }).find("t_min_c"), std::string::npos);
  o = topDown();
  o.shading = "gouraud";
  EXPECT_NE(message([&] { Renderer r(o); }).find("look.shading"), std::string::npos);
  o = topDown();
  o.backend = "vulkan";
  EXPECT_NE(message([&] { Renderer r(o); }).find("RenderOptions::backend"), std::string::npos);
  // camera.up is judged by its angle to the view, whatever its length (as the scenario
  // checks do: a short up 0.2 degrees off the view passed there and was refused here)
  o = topDown();
  o.up = {0, 0.001 * std::sin(0.0035), -0.001 * std::cos(0.0035)};  // 0.2 deg off, 1 mm long
  EXPECT_EQ(message([&] { Renderer r(o); }), "no error");
  o.up = {0, 10 * std::sin(0.0005), -10 * std::cos(0.0005)};  // sine 5e-4, 10 m long
  EXPECT_NE(message([&] { Renderer r(o); }).find("camera.up"), std::string::npos);
  o.up = {0, 0, 0};
  EXPECT_NE(message([&] { Renderer r(o); }).find("camera.up"), std::string::npos);
  o = topDown();
  o.tissueTint = {1, 2.5f, 1};
  EXPECT_NE(message([&] { Renderer r(o); }).find("look.tissue_tint: 2.5"), std::string::npos);
  o = topDown();
  o.keyLightCamera = {0, 0, 0};
  EXPECT_NE(message([&] { Renderer r(o); }).find("look.light_direction"), std::string::npos);
  o = topDown();
  o.lightIntensity = -1;
  EXPECT_NE(message([&] { Renderer r(o); }).find("look.light_intensity"), std::string::npos);
  o = topDown();
  o.fovDeg = 170;  // the scenario schema's range, (1, 170)
  EXPECT_NE(message([&] { Renderer r(o); }).find("camera.fov_deg"), std::string::npos);
  Renderer r(topDown());
  SurfaceSnapshot s = gradientStrip();
  s.triangles.back() = 99;
  EXPECT_NE(message([&] { r.render(s); }).find("snapshot.triangles"), std::string::npos);
  s = gradientStrip();
  s.temperatureC.pop_back();
  EXPECT_NE(message([&] { r.render(s); }).find("snapshot.temperatureC"), std::string::npos);
  s = gradientStrip();
  s.positionsM[4] = std::nanf("");
  EXPECT_NE(message([&] { r.render(s); }).find("snapshot.positionsM"), std::string::npos);
}

}  // namespace
}  // namespace esim
