// renderer.cpp - GL 3.3 core drawing of a SurfaceSnapshot (see renderer.h): option and
// snapshot checks, GL set-up (programs, vertex arrays, textures, framebuffers, the
// background column), and per frame: camera and lights, clear, surface, electrode, MSAA
// resolve, read-back and background composite, then the CPU overlay. The parts live
// beside it: shaders.h (GLSL), view_math.h, vertex_layout.h, surface_buffers.h,
// tool_mesh.h, overlay.h.
#include "render/renderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "render/colormap.h"
#include "render/gl_context.h"
#include "render/label_pass.h"
#include "render/overlay.h"
#include "render/shaders.h"
#include "render/surface_buffers.h"
#include "render/tool_mesh.h"
#include "render/vertex_layout.h"
#include "render/view_math.h"
#include "sim/core_error.h"

namespace esim {
using namespace render_detail;

// ---- validation ----

void validateRenderOptions(const RenderOptions& o) {
  ESIM_VERIFY(o.width >= 16 && o.width <= 8192 && o.height >= 16 && o.height <= 8192,
              "look.width/height: " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                  " is out of range, expected 16..8192 pixels each");
  ESIM_VERIFY(o.shading == "pixel" || o.shading == "vertex",
              "look.shading: '" + o.shading + "' is unknown, expected 'pixel' or 'vertex'");
  ESIM_VERIFY(
      o.look == "temperature" || o.look == "tissue" || o.look == "potential",
      "look.style: '" + o.look + "' is unknown, expected 'temperature', 'tissue' or 'potential'");
  colormapLut(o.colormap);  // throws for an unknown map
  ESIM_VERIFY(std::isfinite(o.tMinC) && std::isfinite(o.tMaxC) && o.tMaxC > o.tMinC,
              "look.t_min_c/t_max_c: need finite t_min_c < t_max_c, got " +
                  std::to_string(o.tMinC) + " and " + std::to_string(o.tMaxC));
  // the potential's colour range matters only to the potential look
  ESIM_VERIFY(o.look != "potential" ||
                  (std::isfinite(o.vMinV) && std::isfinite(o.vMaxV) && o.vMaxV > o.vMinV),
              "look.v_min_v/v_max_v: the potential look needs v_min_v < v_max_v, got " +
                  std::to_string(o.vMinV) + " and " + std::to_string(o.vMaxV) +
                  " V (v_max_v 0 stands for tool.voltage_v)");
  ESIM_VERIFY(o.look != "potential" || !o.potentialLogScale || o.vMinV > 0,
              "look.v_min_v: the logarithmic potential scale needs v_min_v > 0, got " +
                  std::to_string(o.vMinV));
  ESIM_VERIFY(o.fovDeg > 1 && o.fovDeg < 170,
              "camera.fov_deg: " + std::to_string(o.fovDeg) + " is out of range (1, 170)");
  const V3 view = sub(o.targetM, o.eyeM);
  ESIM_VERIFY(norm(view) > 0, "camera.eye_m/target_m: the camera eye and target coincide");
  // the sine of the angle between them (as the scenario checks: any length of up)
  ESIM_VERIFY(norm(o.up) > 0 && norm(cross(normalized(view), normalized(o.up))) > 1e-3,
              "camera.up: the up vector is zero or parallel to the viewing direction");
  ESIM_VERIFY(o.msaaSamples == 0 || o.msaaSamples == 2 || o.msaaSamples == 4,
              "look.msaa: " + std::to_string(o.msaaSamples) + ", expected 0, 2 or 4");
  for (int k = 0; k < 3; ++k)
    ESIM_VERIFY(std::isfinite(o.tissueTint[k]) && o.tissueTint[k] >= 0 && o.tissueTint[k] <= 2,
                "look.tissue_tint: " + std::to_string(o.tissueTint[k]) +
                    " is outside [0, 2] (a factor on the tissue's red, green and blue)");
  ESIM_VERIFY(std::isfinite(norm(o.keyLightCamera)) && norm(o.keyLightCamera) > 0,
              "look.light_direction: the key light's direction is zero or not finite");
  ESIM_VERIFY(std::isfinite(o.lightIntensity) && o.lightIntensity >= 0 && o.lightIntensity <= 4,
              "look.light_intensity: " + std::to_string(o.lightIntensity) +
                  " is outside [0, 4] (1 = the default lights)");
  ESIM_VERIFY(o.cutWallNormalPasses >= 0 && o.cutWallNormalPasses <= kMaxCutWallPasses,
              "look.cut_wall_smoothing: " + std::to_string(o.cutWallNormalPasses) +
                  " is outside [0, " + std::to_string(kMaxCutWallPasses) + "]");
  ESIM_VERIFY(o.cutWallDamagePasses >= 0 && o.cutWallDamagePasses <= kMaxCutWallPasses,
              "look.cut_wall_damage_smoothing: " + std::to_string(o.cutWallDamagePasses) +
                  " is outside [0, " + std::to_string(kMaxCutWallPasses) + "]");
  ESIM_VERIFY(o.backend == "osmesa" || o.backend == "egl",
              "RenderOptions::backend: '" + o.backend + "' is unknown, expected 'osmesa' or 'egl'");
}

void validateSnapshot(const SurfaceSnapshot& s) {
  ESIM_VERIFY(s.positionsM.size() % 3 == 0, "snapshot.positionsM: size " +
                                                std::to_string(s.positionsM.size()) +
                                                " is not a multiple of 3");
  ESIM_VERIFY(
      s.triangles.size() % 3 == 0,
      "snapshot.triangles: size " + std::to_string(s.triangles.size()) + " is not a multiple of 3");
  const size_t nv = static_cast<size_t>(s.numVertices());
  auto checkField = [&](const std::vector<float>& f, const char* name) {
    ESIM_VERIFY(f.empty() || f.size() == nv,
                std::string("snapshot.") + name + ": " + std::to_string(f.size()) + " values for " +
                    std::to_string(nv) + " vertices, expected one per vertex (or none)");
    for (float v : f)
      ESIM_VERIFY(std::isfinite(v), std::string("snapshot.") + name + ": non-finite value");
  };
  checkField(s.temperatureC, "temperatureC");
  checkField(s.coagulation, "coagulation");
  checkField(s.desiccation, "desiccation");
  checkField(s.cutWall, "cutWall");
  checkField(s.potentialV, "potentialV");
  for (float v : s.positionsM)
    ESIM_VERIFY(std::isfinite(v), "snapshot.positionsM: non-finite value");
  for (std::uint32_t v : s.triangles)
    ESIM_VERIFY(v < nv, "snapshot.triangles: vertex index " + std::to_string(v) +
                            " out of range (" + std::to_string(nv) + " vertices)");
}

void validateSnapshot(const SurfaceSnapshot& s, const RenderOptions& o) {
  validateSnapshot(s);
  ESIM_VERIFY(o.look != "potential" || s.numVertices() == 0 || !s.potentialV.empty(),
              "look.style: potential needs the electric phase (snapshot.potentialV is empty for " +
                  std::to_string(s.numVertices()) +
                  " vertices); add electric to physics or use another look");
}

std::array<std::uint8_t, 3> backgroundColor(int row, int height) {
  // pixel centre of the row, same arithmetic as the background shader
  const float fromTop = (static_cast<float>(row) + 0.5f) / static_cast<float>(height);
  const float top[3] = {104, 110, 120}, bottom[3] = {38, 40, 46};
  std::array<std::uint8_t, 3> c{};
  for (int k = 0; k < 3; ++k)
    c[k] = static_cast<std::uint8_t>(std::lround(top[k] + (bottom[k] - top[k]) * fromTop));
  return c;
}

// ---- Renderer ----

namespace {

using Clock = std::chrono::steady_clock;

// milliseconds from t to now
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// what one frame's draws share: camera, lights and the electrode's pose (world, metres)
struct FrameView {
  M4 viewProj;                  // projection * view
  V3 keyDir, fillDir, halfDir;  // towards the key and fill lights; Blinn-Phong half vector
  M4 toolPose;                  // electrode frame -> world
  V3 eye, forward;              // camera centre [m], unit viewing direction
  V3 toolAxis;                  // electrode axis, tip to handle, in world
  V3 toolSizes;                 // toolShadowSizes(): the shadow's capsules
};

// camera (clip planes from the camera distance: the tool may come close, the far
// plane covers the surface), lights from the camera frame, electrode pose
FrameView frameView(const RenderOptions& o, const SurfaceSnapshot& snap) {
  FrameView f;
  const float dist = norm(sub(o.targetM, o.eyeM));
  float farM = 20 * dist;
  for (int v = 0; v < snap.numVertices(); ++v) {
    const V3 p{snap.positionsM[3 * v], snap.positionsM[3 * v + 1], snap.positionsM[3 * v + 2]};
    farM = std::max(farM, 1.5f * norm(sub(p, o.eyeM)));
  }
  const M4 view = lookAt(o.eyeM, o.targetM, o.up);
  const M4 proj = perspective(o.fovDeg, static_cast<float>(o.width) / o.height, 0.02f * dist, farM);
  f.viewProj = matMul(proj, view);
  const V3 fwd = normalized(sub(o.targetM, o.eyeM));
  f.eye = o.eyeM;
  f.forward = fwd;
  const V3 right = normalized(cross(fwd, o.up));
  const V3 camUp = cross(right, fwd);
  const std::array<float, 3>& k = o.keyLightCamera;  // (right, up, towards the viewer)
  f.keyDir = normalized(add(add(mul(right, k[0]), mul(camUp, k[1])), mul(fwd, -k[2])));
  f.fillDir = normalized(add(add(mul(right, 0.70f), mul(camUp, 0.10f)), mul(fwd, -0.50f)));
  f.halfDir = normalized(sub(f.keyDir, fwd));  // towards the light + towards the viewer
  const ToolSnapshot& tool = snap.tool;
  f.toolPose = poseMatrix(tool.orientationWxyz, tool.tipM);
  f.toolAxis = {f.toolPose[8], f.toolPose[9], f.toolPose[10]};  // local +z in world
  f.toolSizes = toolShadowSizes(tool);
  return f;
}

// RGBA read-back (bottom row first) -> RGB24 frame (top row first), pixels still at
// alpha 0 taking the background colour of their row from bgColumn (RGBA, bottom first)
void compositeBackground(const std::vector<std::uint8_t>& readBuf,
                         const std::vector<std::uint8_t>& bgColumn, int width, int height,
                         std::vector<std::uint8_t>& frame) {
  const size_t w = static_cast<size_t>(width);
  for (int y = 0; y < height; ++y) {
    const int glRow = height - 1 - y;
    const std::uint8_t* src = &readBuf[w * 4 * glRow];
    const std::uint8_t* bg = &bgColumn[4 * static_cast<size_t>(glRow)];
    std::uint8_t* dst = &frame[w * 3 * y];
    std::uint32_t bgWord;
    std::memcpy(&bgWord, bg, 4);
    // 4-byte stores 3 bytes apart (each overwrites the previous one's spare byte);
    // the row's last pixel is stored as 3 bytes so nothing is written past the row
    for (size_t x = 0; x + 1 < w; ++x, src += 4, dst += 3) {
      std::uint32_t p;
      std::memcpy(&p, src, 4);
      if (src[3] == 0) p = bgWord;
      std::memcpy(dst, &p, 4);
    }
    std::memcpy(dst, src[3] == 0 ? bg : src, 3);
  }
}

}  // namespace

struct Renderer::Impl {
  RenderOptions opt;
  std::unique_ptr<GlContext> ctx;
  // one surface program per variant: the look's with and without the tool's
  // shadow, and the tool's own
  SurfaceProgram lookProgram[2], toolProgram;           // lookProgram[shadow]
  GLuint bgProgram = 0, bgVao = 0, resolveProgram = 0;  // bgVao: empty, full-screen passes
  GLuint bgTex = 0, bgFbo = 0;         // the background column (1 x height): MSAA resolve input
  std::vector<std::uint8_t> bgColumn;  // the same, RGBA bottom row first, for the composite
  GLint uSize = -1;
  GLuint surfVao = 0, surfVbo = 0, toolVao = 0, toolVbo = 0, lutTex = 0;
  GLuint msFbo = 0, msColor = 0, msDepth = 0, fbo = 0, color = 0, depth = 0;
  int toolVertexCount = 0;
  ToolSnapshot toolCached;
  bool toolBuilt = false;
  SurfaceBuffers surface;
  GLuint surfIbo = 0;
  std::vector<std::uint8_t> readBuf, frame;
  RenderTimings timings;
  // labels (renderLabels): made on first use, drawing what the last render() drew
  std::unique_ptr<LabelPass> labelPass;
  LabelFrame labelFrame;
  bool rendered = false;       // render() has run
  LabelGeometry lastGeometry;  // the last render()'s buffers and matrices
  double lastTimeS = 0;

  // set-up: init() runs the create* steps and drawBackgroundColumn in this order
  void init();
  // the variant of the surface program of a look (kLook*), with or without the
  // electrode's shadow, and its linked program
  SurfaceVariant surfaceVariant(int look, bool shadow) const;
  SurfaceProgram makeSurfaceProgram(int look, bool shadow);
  int lookId() const;            // kLook* of opt.look
  void createPrograms();         // background and surface programs
  void createVertexArrays();     // background (empty), surface (with its index buffer), tool
  void createColormapTexture();  // the colour map as a 1D texture, unit 0
  void createTargets();          // plain framebuffer, and the multisampled one with MSAA
  void createMsaaTarget();       // multisampled framebuffer and the resolve program
  void drawBackgroundColumn();   // the background pass, once: bgTex and bgColumn
  void destroy();                // deletes the GL objects (the context must still be current-able)
  // per frame, in render()'s order
  void clearTarget();          // binds the draw framebuffer, clears colour (alpha 0) and depth
  void bindSurfaceTextures();  // colour map on unit 0
  // binds a surface program and sets its uniforms for this frame
  void useSurfaceProgram(const SurfaceProgram& p, const M4& model, const FrameView& view,
                         const ToolSnapshot& tool);
  void drawSurface(const FrameView& view, const ToolSnapshot& tool);  // uploads and draws
  void drawTool(const FrameView& view, const ToolSnapshot& tool);     // (re)builds and draws
  void resolveAndReadBack();  // MSAA resolve, glReadPixels into readBuf, GL error check
};

void Renderer::Impl::init() {
  createPrograms();
  createVertexArrays();
  createColormapTexture();
  createTargets();
  drawBackgroundColumn();
}

SurfaceVariant Renderer::Impl::surfaceVariant(int look, bool shadow) const {
  SurfaceVariant v;
  v.look = look;
  v.lit = opt.lighting;
  v.shadow = shadow;
  v.logScale = opt.potentialLogScale;
  v.vertexLit = look != kLookTool && opt.shading == "vertex";
  return v;
}

SurfaceProgram Renderer::Impl::makeSurfaceProgram(int look, bool shadow) {
  return linkSurfaceProgram(ctx->gl(), surfaceVariant(look, shadow));
}

int Renderer::Impl::lookId() const {
  return opt.look == "temperature" ? kLookTemperature
                                   : (opt.look == "tissue" ? kLookTissue : kLookPotential);
}

void Renderer::Impl::createPrograms() {
  const GlFunctions& gl = ctx->gl();
  bgProgram = linkProgram(gl, kFullScreenVs, kBackgroundFs, "background");
  uSize = gl.GetUniformLocation(bgProgram, "uSize");
  const int look = lookId();
  lookProgram[0] = makeSurfaceProgram(look, false);
  lookProgram[1] = makeSurfaceProgram(look, opt.lighting);
  toolProgram = makeSurfaceProgram(kLookTool, false);
}

void Renderer::Impl::createVertexArrays() {
  const GlFunctions& gl = ctx->gl();
  gl.GenVertexArrays(1, &bgVao);
  // vertex arrays: position, normal, state (interleaved floats, vertex_layout.h)
  auto makeVao = [&](GLuint& vao, GLuint& vbo) {
    gl.GenVertexArrays(1, &vao);
    gl.GenBuffers(1, &vbo);
    gl.BindVertexArray(vao);
    gl.BindBuffer(GL_ARRAY_BUFFER, vbo);
    const GLsizei stride = kFloatsPerVertex * sizeof(float);
    gl.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(0));
    gl.VertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride,
                           reinterpret_cast<void*>(kNormalOffset * sizeof(float)));
    gl.VertexAttribPointer(2, 4, GL_FLOAT, GL_FALSE, stride,
                           reinterpret_cast<void*>(kStateOffset * sizeof(float)));
    for (GLuint i = 0; i < 3; ++i) gl.EnableVertexAttribArray(i);
    gl.BindVertexArray(0);
  };
  makeVao(surfVao, surfVbo);
  gl.GenBuffers(1, &surfIbo);
  gl.BindVertexArray(surfVao);
  gl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, surfIbo);  // recorded in the vertex array
  gl.BindVertexArray(0);
  makeVao(toolVao, toolVbo);
}

void Renderer::Impl::createColormapTexture() {
  // colour map as a 1D texture: exactly the CPU table
  const GlFunctions& gl = ctx->gl();
  const ColormapLut& lut = colormapLut(opt.colormap);
  gl.GenTextures(1, &lutTex);
  gl.BindTexture(GL_TEXTURE_1D, lutTex);
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
  gl.TexImage1D(GL_TEXTURE_1D, 0, GL_RGB8, 256, 0, GL_RGB, GL_UNSIGNED_BYTE, lut.data());
  gl.TexParameteri(GL_TEXTURE_1D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  gl.TexParameteri(GL_TEXTURE_1D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl.TexParameteri(GL_TEXTURE_1D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
}

void Renderer::Impl::createTargets() {
  // framebuffers: optional multisampled one, resolved into a plain one
  const GlFunctions& gl = ctx->gl();
  auto makeFbo = [&](GLuint& f, GLuint& c, GLuint& d, int samples) {
    gl.GenFramebuffers(1, &f);
    gl.GenRenderbuffers(1, &c);
    gl.GenRenderbuffers(1, &d);
    gl.BindRenderbuffer(GL_RENDERBUFFER, c);
    gl.RenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_RGBA8, opt.width, opt.height);
    gl.BindRenderbuffer(GL_RENDERBUFFER, d);
    gl.RenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_DEPTH_COMPONENT24, opt.width,
                                      opt.height);
    gl.BindFramebuffer(GL_FRAMEBUFFER, f);
    gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, c);
    gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, d);
    const GLenum status = gl.CheckFramebufferStatus(GL_FRAMEBUFFER);
    ESIM_VERIFY(status == GL_FRAMEBUFFER_COMPLETE,
                "renderer: framebuffer (" + std::to_string(samples) +
                    " samples) incomplete, status 0x" + std::to_string(status));
  };
  makeFbo(fbo, color, depth, 0);
  if (opt.msaaSamples > 0) createMsaaTarget();
}

void Renderer::Impl::createMsaaTarget() {
  const GlFunctions& gl = ctx->gl();
  GLint maxSamples = 0;
  gl.GetIntegerv(GL_MAX_SAMPLES, &maxSamples);
  ESIM_VERIFY(opt.msaaSamples <= maxSamples, "look.msaa: " + std::to_string(opt.msaaSamples) +
                                                 " exceeds the driver's GL_MAX_SAMPLES " +
                                                 std::to_string(maxSamples));
  // colour in a multisample texture (resolved by kResolveFs), depth in a renderbuffer
  gl.GenFramebuffers(1, &msFbo);
  gl.GenTextures(1, &msColor);
  gl.GenRenderbuffers(1, &msDepth);
  gl.BindTexture(GL_TEXTURE_2D_MULTISAMPLE, msColor);
  gl.TexImage2DMultisample(GL_TEXTURE_2D_MULTISAMPLE, opt.msaaSamples, GL_RGBA8, opt.width,
                           opt.height, GL_TRUE);
  gl.BindTexture(GL_TEXTURE_2D_MULTISAMPLE, 0);
  gl.BindRenderbuffer(GL_RENDERBUFFER, msDepth);
  gl.RenderbufferStorageMultisample(GL_RENDERBUFFER, opt.msaaSamples, GL_DEPTH_COMPONENT24,
                                    opt.width, opt.height);
  gl.BindFramebuffer(GL_FRAMEBUFFER, msFbo);
  gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D_MULTISAMPLE, msColor,
                          0);
  gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, msDepth);
  const GLenum status = gl.CheckFramebufferStatus(GL_FRAMEBUFFER);
  ESIM_VERIFY(status == GL_FRAMEBUFFER_COMPLETE,
              "renderer: multisampled framebuffer incomplete, status 0x" + std::to_string(status));
  const std::string fs = resolveFragmentSource(opt.msaaSamples);
  resolveProgram = linkProgram(gl, kFullScreenVs, fs.c_str(), "msaa resolve");
  gl.UseProgram(resolveProgram);
  gl.Uniform1i(gl.GetUniformLocation(resolveProgram, "uSamples"), 2);
  gl.Uniform1i(gl.GetUniformLocation(resolveProgram, "uBackground"), 3);
  gl.UseProgram(0);
}

void Renderer::Impl::drawBackgroundColumn() {
  // the background column (it depends on the row only), drawn once by the background
  // pass: a texture for the MSAA resolve, and read back for the composite on the CPU
  // (compositeBackground), so both paths store the bytes that pass would have stored
  const GlFunctions& gl = ctx->gl();
  gl.GenTextures(1, &bgTex);
  gl.BindTexture(GL_TEXTURE_2D, bgTex);
  gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, 1, opt.height, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  gl.BindTexture(GL_TEXTURE_2D, 0);
  gl.GenFramebuffers(1, &bgFbo);
  gl.BindFramebuffer(GL_FRAMEBUFFER, bgFbo);
  gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, bgTex, 0);
  ESIM_VERIFY(gl.CheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE,
              "renderer: background framebuffer incomplete");
  gl.Viewport(0, 0, 1, opt.height);
  gl.Disable(GL_DEPTH_TEST);
  gl.UseProgram(bgProgram);
  gl.Uniform2f(uSize, static_cast<float>(opt.width), static_cast<float>(opt.height));
  gl.BindVertexArray(bgVao);
  gl.DrawArrays(GL_TRIANGLES, 0, 3);
  gl.BindVertexArray(0);
  gl.UseProgram(0);
  bgColumn.resize(static_cast<size_t>(opt.height) * 4);
  gl.ReadBuffer(GL_COLOR_ATTACHMENT0);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl.ReadPixels(0, 0, 1, opt.height, GL_RGBA, GL_UNSIGNED_BYTE, bgColumn.data());
  const GLenum err = gl.GetError();
  ESIM_VERIFY(err == GL_NO_ERROR, "renderer: GL error 0x" + std::to_string(err) + " at setup");
}

void Renderer::Impl::destroy() {
  if (!ctx) return;
  try {
    ctx->makeCurrent();
  } catch (const Error&) {
    return;
  }
  const GlFunctions& gl = ctx->gl();
  gl.DeleteProgram(bgProgram);
  gl.DeleteProgram(lookProgram[0].id);
  gl.DeleteProgram(lookProgram[1].id);
  gl.DeleteProgram(toolProgram.id);
  GLuint vaos[] = {bgVao, surfVao, toolVao};
  gl.DeleteVertexArrays(3, vaos);
  GLuint bufs[] = {surfVbo, toolVbo, surfIbo};
  gl.DeleteBuffers(3, bufs);
  gl.DeleteTextures(1, &lutTex);
  gl.DeleteTextures(1, &msColor);
  gl.DeleteTextures(1, &bgTex);
  gl.DeleteProgram(resolveProgram);
  GLuint fbos[] = {fbo, msFbo, bgFbo};
  gl.DeleteFramebuffers(3, fbos);
  GLuint rbs[] = {color, depth, msDepth};
  gl.DeleteRenderbuffers(3, rbs);
  if (labelPass) labelPass->destroy(gl);
}

void Renderer::Impl::clearTarget() {
  // target framebuffer, colour cleared to alpha 0 (everything drawn has alpha 1):
  // the background is filled in where alpha stayed 0, by the MSAA resolve
  // (kResolveFs) or, without MSAA, by compositeBackground after the read-back;
  // a full-screen background pass would shade every pixel once more
  const GlFunctions& gl = ctx->gl();
  gl.BindFramebuffer(GL_FRAMEBUFFER, opt.msaaSamples > 0 ? msFbo : fbo);
  gl.Viewport(0, 0, opt.width, opt.height);
  gl.ClearColor(0, 0, 0, 0);
  gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthMask(GL_TRUE);
  gl.DepthFunc(GL_LESS);
}

void Renderer::Impl::bindSurfaceTextures() {
  const GlFunctions& gl = ctx->gl();
  gl.ActiveTexture(GL_TEXTURE0);
  gl.BindTexture(GL_TEXTURE_1D, lutTex);
}

void Renderer::Impl::useSurfaceProgram(const SurfaceProgram& p, const M4& model,
                                       const FrameView& view, const ToolSnapshot& tool) {
  const GlFunctions& gl = ctx->gl();
  gl.UseProgram(p.id);
  gl.UniformMatrix4fv(p.uViewProj, 1, GL_FALSE, view.viewProj.data());
  gl.UniformMatrix4fv(p.uModel, 1, GL_FALSE, model.data());
  gl.Uniform1i(p.uColormap, 0);
  if (opt.look == "potential")
    gl.Uniform2f(p.uTempRange, opt.vMinV, opt.vMaxV);
  else
    gl.Uniform2f(p.uTempRange, opt.tMinC, opt.tMaxC);
  gl.Uniform3fv(p.uHalfDir, 1, view.halfDir.data());
  gl.Uniform3fv(p.uKeyDir, 1, view.keyDir.data());
  gl.Uniform3fv(p.uFillDir, 1, view.fillDir.data());
  gl.Uniform3fv(p.uTipM, 1, tool.tipM.data());
  gl.Uniform1f(p.uGlow, tool.present && tool.generatorOn ? 1.0f : 0.0f);
  gl.Uniform3fv(p.uToolAxis, 1, view.toolAxis.data());
  gl.Uniform3fv(p.uToolSizes, 1, view.toolSizes.data());
  // the lights' weights (their products with 1 are the literals they replaced: the default
  // look keeps its bytes), the tint and the mottling's salt
  gl.Uniform3f(p.uLightWeights, 0.78f * opt.lightIntensity, 0.22f * opt.lightIntensity,
               opt.lightIntensity);
  gl.Uniform3fv(p.uTint, 1, opt.tissueTint.data());
  gl.Uniform1ui(p.uSeedSalt, opt.textureSeed * 0x85ebca6bu);
}

void Renderer::Impl::drawSurface(const FrameView& view, const ToolSnapshot& tool) {
  // uploads `surface` (updated by render()) and draws it
  const GlFunctions& gl = ctx->gl();
  useSurfaceProgram(lookProgram[tool.present ? 1 : 0], kIdentityM4, view, tool);
  gl.BindVertexArray(surfVao);
  gl.BindBuffer(GL_ARRAY_BUFFER, surfVbo);
  gl.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(surface.vertices.size() * sizeof(float)),
                surface.vertices.data(), GL_STREAM_DRAW);
  if (!surface.geometryReused)  // the element buffer belongs to surfVao
    gl.BufferData(GL_ELEMENT_ARRAY_BUFFER,
                  static_cast<GLsizeiptr>(surface.indices.size() * sizeof(std::uint32_t)),
                  surface.indices.data(), GL_STATIC_DRAW);
  // a closed surface, counter-clockwise from outside: its back faces are hidden
  if (opt.cullBackFaces) gl.Enable(GL_CULL_FACE);
  gl.DrawElements(GL_TRIANGLES, static_cast<GLsizei>(surface.indices.size()), GL_UNSIGNED_INT,
                  nullptr);
  gl.Disable(GL_CULL_FACE);
}

void Renderer::Impl::drawTool(const FrameView& view, const ToolSnapshot& tool) {
  // the mesh is rebuilt only when the electrode's shape changes
  const GlFunctions& gl = ctx->gl();
  if (!toolBuilt || !sameToolShape(tool, toolCached)) {
    const std::vector<float> verts = buildToolVertices(tool);
    gl.BindBuffer(GL_ARRAY_BUFFER, toolVbo);
    gl.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(verts.size() * sizeof(float)),
                  verts.data(), GL_STATIC_DRAW);
    toolVertexCount = static_cast<int>(verts.size() / kFloatsPerVertex);
    toolCached = tool;
    toolBuilt = true;
  }
  useSurfaceProgram(toolProgram, view.toolPose, view, tool);
  gl.BindVertexArray(toolVao);
  gl.DrawArrays(GL_TRIANGLES, 0, toolVertexCount);
}

void Renderer::Impl::resolveAndReadBack() {
  // MSAA resolve into the plain framebuffer, then its RGBA into readBuf (GL rows are
  // bottom-up); compositeBackground turns it into the frame
  const GlFunctions& gl = ctx->gl();
  gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
  if (opt.msaaSamples > 0) {
    gl.Disable(GL_DEPTH_TEST);
    gl.UseProgram(resolveProgram);  // samplers: uSamples unit 2, uBackground unit 3
    gl.ActiveTexture(GL_TEXTURE3);
    gl.BindTexture(GL_TEXTURE_2D, bgTex);
    gl.ActiveTexture(GL_TEXTURE2);
    gl.BindTexture(GL_TEXTURE_2D_MULTISAMPLE, msColor);
    gl.BindVertexArray(bgVao);
    gl.DrawArrays(GL_TRIANGLES, 0, 3);
    gl.BindVertexArray(0);
    gl.ActiveTexture(GL_TEXTURE0);
  }
  // RGBA is the framebuffer's own layout (a copy in the driver); the composite packs
  // it to RGB, flips the rows and puts the background where alpha is still 0
  gl.ReadBuffer(GL_COLOR_ATTACHMENT0);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
  const size_t w = static_cast<size_t>(opt.width);
  readBuf.resize(w * 4 * opt.height);
  frame.resize(w * 3 * opt.height);
  gl.ReadPixels(0, 0, opt.width, opt.height, GL_RGBA, GL_UNSIGNED_BYTE, readBuf.data());
  const GLenum err = gl.GetError();
  ESIM_VERIFY(err == GL_NO_ERROR, "renderer: GL error 0x" + std::to_string(err) + " while drawing");
}

Renderer::Renderer(const RenderOptions& options) : impl_(std::make_unique<Impl>()) {
  validateRenderOptions(options);
  impl_->opt = options;
  impl_->surface.cutWallNormalPasses = options.cutWallNormalPasses;
  impl_->surface.cutWallDamagePasses = options.cutWallDamagePasses;
  impl_->ctx = createGlContext(options.backend);
  impl_->init();
}

Renderer::~Renderer() { impl_->destroy(); }

std::string Renderer::glRenderer() const { return impl_->ctx->glRenderer(); }
std::string Renderer::glVersion() const { return impl_->ctx->glVersion(); }
std::string Renderer::glPlatform() const { return impl_->ctx->platform(); }
const RenderOptions& Renderer::options() const { return impl_->opt; }
const RenderTimings& Renderer::lastTimings() const { return impl_->timings; }

const std::vector<std::uint8_t>& Renderer::render(const SurfaceSnapshot& snap) {
  const auto tStart = Clock::now();
  validateSnapshot(snap, impl_->opt);
  Impl& m = *impl_;
  const RenderOptions& o = m.opt;
  m.ctx->makeCurrent();
  const GlFunctions& gl = m.ctx->gl();

  // 1. camera, lights, electrode pose; 2. clear the target
  const FrameView view = frameView(o, snap);
  m.clearTarget();
  // 3. surface: vertex arrays on the CPU (timed as prepare), upload and draw
  m.bindSurfaceTextures();
  double prepareMs = 0;
  if (snap.numTriangles() > 0) {
    const auto tPrep = Clock::now();
    m.surface.update(snap, o.tMinC, o.look == "potential");
    prepareMs = msSince(tPrep);
    m.drawSurface(view, snap.tool);
  }
  // 4. electrode
  if (snap.tool.present) m.drawTool(view, snap.tool);
  gl.BindVertexArray(0);
  // what a label pass of this frame draws again
  LabelGeometry& lg = m.lastGeometry;
  lg.surfaceVao = m.surfVao;
  lg.surfaceIndices = snap.numTriangles() > 0 ? static_cast<GLsizei>(m.surface.indices.size()) : 0;
  lg.surfaceVariant = snap.tool.present ? 1 : 0;
  lg.cullBackFaces = o.cullBackFaces;
  lg.toolVao = m.toolVao;
  lg.toolVertices = snap.tool.present ? m.toolVertexCount : 0;
  lg.viewProj = view.viewProj;
  lg.toolPose = view.toolPose;
  lg.eyeM = view.eye;
  lg.forward = view.forward;
  m.lastTimeS = snap.timeS;
  m.rendered = true;

  // 5. resolve, read back and composite the background
  gl.Finish();
  m.timings.drawMs = msSince(tStart) - prepareMs;
  const auto tRead = Clock::now();
  m.resolveAndReadBack();
  compositeBackground(m.readBuf, m.bgColumn, o.width, o.height, m.frame);
  m.timings.readbackMs = msSince(tRead);

  // 6. overlay on the CPU
  const auto tOverlay = Clock::now();
  drawOverlay(m.frame, o, snap.timeS);
  m.timings.overlayMs = msSince(tOverlay);
  m.timings.prepareMs = prepareMs;
  m.timings.totalMs = msSince(tStart);
  return m.frame;
}

const LabelFrame& Renderer::renderLabels() {
  Impl& m = *impl_;
  ESIM_VERIFY(m.rendered, "Renderer::renderLabels: no frame drawn yet (call render() first)");
  const auto tStart = Clock::now();
  m.ctx->makeCurrent();
  const GlFunctions& gl = m.ctx->gl();
  if (!m.labelPass) {
    // the vertex shaders of the frame's programs: lookProgram[0], [1] and toolProgram
    const SurfaceVariant surfaceVs[2] = {m.surfaceVariant(m.lookId(), false),
                                         m.surfaceVariant(m.lookId(), m.opt.lighting)};
    m.labelPass =
        std::make_unique<LabelPass>(gl, m.opt, surfaceVs, m.surfaceVariant(kLookTool, false));
  }
  m.labelPass->draw(gl, m.lastGeometry, m.labelFrame);
  m.labelPass->markOverlay(m.opt, m.lastTimeS, m.labelFrame);
  m.timings.labelsMs = msSince(tStart);
  return m.labelFrame;
}

}  // namespace esim
