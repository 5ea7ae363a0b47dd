// label_pass.cpp - the label pass: programs, integer framebuffer, draw, read-back and the
// overlay's pixels (see label_pass.h).
#include "render/label_pass.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstring>

#include "render/overlay.h"
#include "sim/core_error.h"

namespace esim::render_detail {

// Per fragment: (class | states << 8, depth) as unsigned 16-bit integers. Tissue states are
// thresholded on the interpolated fractions (vState = T or phi, coagulation, desiccation,
// cut wall); the class is the first of desiccated, coagulated, cut wall, tissue that holds.
// The electrode's vState.w is its material id (0 metal, 1 insulation, 2 handle). Depth: the
// interpolated world position projected on the viewing axis, in units, rounded to nearest,
// kept in 1..65535 (0 stays the cleared "no surface").
const char* const kLabelFs = R"(
in vec3 vPos;
in vec4 vState;
uniform vec3 uEye;
uniform vec3 uForward;
uniform float uDepthUnit;
layout(location = 0) out uvec2 oLabel;
void main() {
#if LABEL_TOOL
  uint cls = vState.w < 0.5 ? 2u : 1u;
  uint states = 0u;
#else
  bool coag = vState.y >= COAG_MIN;
  bool dry = vState.z >= DRY_MIN;
  bool wall = vState.w >= WALL_MIN;
  uint states = (coag ? 1u : 0u) | (dry ? 2u : 0u) | (wall ? 4u : 0u);
  uint cls = dry ? 5u : (coag ? 4u : (wall ? 6u : 3u));
#endif
  float z = dot(vPos - uEye, uForward);
  float d = clamp(floor(z / uDepthUnit + 0.5), 1.0, 65535.0);
  oLabel = uvec2(cls | (states << 8u), uint(d));
})";

std::string labelFragmentSource(bool tool) {
  char defs[256];
  std::snprintf(defs, sizeof defs,
                "#version 330 core\n#define LABEL_TOOL %d\n#define COAG_MIN %.9g\n"
                "#define DRY_MIN %.9g\n#define WALL_MIN %.9g\n",
                tool ? 1 : 0, static_cast<double>(kCoagulatedMin),
                static_cast<double>(kDesiccatedMin), static_cast<double>(kCutWallMin));
  return std::string(defs) + kLabelFs;
}

LabelPass::Program LabelPass::link(const GlFunctions& gl, const SurfaceVariant& vs, bool tool) {
  const std::string vsSource = surfaceShaderHeader(vs) + kSurfaceVs;
  const std::string fsSource = labelFragmentSource(tool);
  Program p;
  p.id = linkProgram(gl, vsSource.c_str(), fsSource.c_str(), tool ? "labels (tool)" : "labels");
  p.uViewProj = gl.GetUniformLocation(p.id, "uViewProj");
  p.uModel = gl.GetUniformLocation(p.id, "uModel");
  p.uEye = gl.GetUniformLocation(p.id, "uEye");
  p.uForward = gl.GetUniformLocation(p.id, "uForward");
  p.uDepthUnit = gl.GetUniformLocation(p.id, "uDepthUnit");
  return p;
}

LabelPass::LabelPass(const GlFunctions& gl, const RenderOptions& o,
                     const SurfaceVariant surfaceVs[2], const SurfaceVariant& toolVs)
    : width_(o.width), height_(o.height), depthUnitM_(depthUnitM(o)) {
  surface_[0] = link(gl, surfaceVs[0], false);
  surface_[1] = link(gl, surfaceVs[1], false);
  tool_ = link(gl, toolVs, true);
  gl.GenFramebuffers(1, &fbo_);
  gl.GenRenderbuffers(1, &color_);
  gl.GenRenderbuffers(1, &depth_);
  gl.BindRenderbuffer(GL_RENDERBUFFER, color_);
  gl.RenderbufferStorage(GL_RENDERBUFFER, GL_RG16UI, width_, height_);
  gl.BindRenderbuffer(GL_RENDERBUFFER, depth_);
  // the frame's depth format: the same depth-test decisions
  gl.RenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width_, height_);
  gl.BindFramebuffer(GL_FRAMEBUFFER, fbo_);
  gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_);
  gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_);
  const GLenum status = gl.CheckFramebufferStatus(GL_FRAMEBUFFER);
  ESIM_VERIFY(status == GL_FRAMEBUFFER_COMPLETE,
              "renderer: label framebuffer incomplete, status 0x" + std::to_string(status));
}

void LabelPass::destroy(const GlFunctions& gl) {
  for (const Program* p : {&surface_[0], &surface_[1], &tool_}) gl.DeleteProgram(p->id);
  gl.DeleteFramebuffers(1, &fbo_);
  GLuint rbs[] = {color_, depth_};
  gl.DeleteRenderbuffers(2, rbs);
}

void LabelPass::use(const GlFunctions& gl, const Program& p, const M4& model,
                    const LabelGeometry& g) {
  gl.UseProgram(p.id);
  gl.UniformMatrix4fv(p.uViewProj, 1, GL_FALSE, g.viewProj.data());
  gl.UniformMatrix4fv(p.uModel, 1, GL_FALSE, model.data());
  gl.Uniform3fv(p.uEye, 1, g.eyeM.data());
  gl.Uniform3fv(p.uForward, 1, g.forward.data());
  gl.Uniform1f(p.uDepthUnit, static_cast<float>(depthUnitM_));
}

void LabelPass::draw(const GlFunctions& gl, const LabelGeometry& g, LabelFrame& out) {
  // clear to class background, depth 0; the frame's depth test
  gl.BindFramebuffer(GL_FRAMEBUFFER, fbo_);
  gl.Viewport(0, 0, width_, height_);
  const GLuint zero[4] = {0, 0, 0, 0};
  gl.ClearBufferuiv(GL_COLOR, 0, zero);
  gl.Clear(GL_DEPTH_BUFFER_BIT);
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthMask(GL_TRUE);
  gl.DepthFunc(GL_LESS);
  // the surface (its buffers as render() uploaded them), then the electrode
  if (g.surfaceIndices > 0) {
    use(gl, surface_[g.surfaceVariant], kIdentityM4, g);
    gl.BindVertexArray(g.surfaceVao);
    if (g.cullBackFaces) gl.Enable(GL_CULL_FACE);
    gl.DrawElements(GL_TRIANGLES, g.surfaceIndices, GL_UNSIGNED_INT, nullptr);
    gl.Disable(GL_CULL_FACE);
  }
  if (g.toolVertices > 0) {
    use(gl, tool_, g.toolPose, g);
    gl.BindVertexArray(g.toolVao);
    gl.DrawArrays(GL_TRIANGLES, 0, g.toolVertices);
  }
  gl.BindVertexArray(0);
  gl.UseProgram(0);
  // read back (GL rows bottom-up) and split into top-first planes
  const size_t w = static_cast<size_t>(width_), n = w * height_;
  readBuf_.resize(2 * n);
  gl.ReadBuffer(GL_COLOR_ATTACHMENT0);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 2);
  gl.ReadPixels(0, 0, width_, height_, GL_RG_INTEGER, GL_UNSIGNED_SHORT, readBuf_.data());
  const GLenum err = gl.GetError();
  ESIM_VERIFY(err == GL_NO_ERROR,
              "renderer: GL error 0x" + std::to_string(err) + " in the label pass");
  out.width = width_;
  out.height = height_;
  out.depthUnitM = depthUnitM_;
  out.classes.resize(n);
  out.states.resize(n);
  out.depth.resize(n);
  out.classPixels.fill(0);
  out.statePixels.fill(0);
  std::array<long, 8> stateCombos{};  // pixels per combination of the state bits
  for (int y = 0; y < height_; ++y) {
    const std::uint16_t* src = &readBuf_[2 * w * (height_ - 1 - y)];
    std::uint8_t* cls = &out.classes[w * y];
    std::uint8_t* st = &out.states[w * y];
    std::uint16_t* d = &out.depth[w * y];
    for (size_t x = 0; x < w; ++x) {
      const std::uint8_t c = static_cast<std::uint8_t>(src[2 * x] & 0xff);
      const std::uint8_t s = static_cast<std::uint8_t>((src[2 * x] >> 8) & 7);
      cls[x] = c;
      st[x] = s;
      d[x] = src[2 * x + 1];
      ++out.classPixels[c < kLabelClassCount ? c : 0];
      ++stateCombos[s];
    }
  }
  for (int s = 1; s < 8; ++s)
    for (int b = 0; b < kLabelStateCount; ++b)
      if ((s >> b) & 1) out.statePixels[b] += stateCombos[s];
}

void LabelPass::markOverlay(const RenderOptions& o, double timeS, LabelFrame& out) {
  const bool colorBar = o.showColorBar && o.look != "tissue";
  if (!o.showTime && !colorBar) return;
  const size_t n = static_cast<size_t>(width_) * height_;
  for (int k = 0; k < 2; ++k) {
    const std::uint8_t value = k == 0 ? 0 : 255;
    std::vector<std::uint8_t>& img = overlayOn_[k];
    if (img.size() != 3 * n) img.assign(3 * n, value);
    drawOverlay(img, o, timeS);
    // mark what changed and put the constant back (the overlay touches few pixels): 8 bytes
    // at a time, the pixels of a changed word one by one
    std::uint64_t constant;
    std::memset(&constant, value, sizeof constant);
    auto markPixels = [&](size_t first, size_t last) {  // pixels [first, last]
      for (size_t i = first; i <= last; ++i) {
        std::uint8_t* p = &img[3 * i];
        if (p[0] == value && p[1] == value && p[2] == value) continue;
        // class overlay, no state (the overlay hides the tissue)
        const std::uint8_t c = out.classes[i];
        --out.classPixels[c < kLabelClassCount ? c : 0];
        for (int b = 0; b < kLabelStateCount; ++b) out.statePixels[b] -= (out.states[i] >> b) & 1;
        out.classes[i] = static_cast<std::uint8_t>(LabelClass::Overlay);
        out.states[i] = 0;
        ++out.classPixels[static_cast<int>(LabelClass::Overlay)];
        p[0] = p[1] = p[2] = value;
      }
    };
    const size_t bytes = 3 * n, words = bytes / 8;
    for (size_t k = 0; k < words; ++k) {
      std::uint64_t word;
      std::memcpy(&word, &img[8 * k], 8);
      if (word != constant) markPixels(8 * k / 3, std::min(n - 1, (8 * k + 7) / 3));
    }
    if (8 * words < bytes) markPixels(8 * words / 3, n - 1);
  }
}

}  // namespace esim::render_detail
