// label_pass.h - the GL side of the labels (labels.h): a second pass over the frame's own
// vertex buffers into an integer framebuffer, and the overlay's pixels.
//
// Programs: the frame's surface vertex shader (kSurfaceVs, compiled with the defines of the
// frame's program, so gl_Position comes from the same code and the same uniforms) and a
// flat-class fragment shader (kLabelFs) writing, per fragment, (class | states << 8,
// depth units) as unsigned 16-bit integers; one variant for the tissue (states thresholded
// on the interpolated coagulation, desiccation and cut-wall fractions) and one for the
// electrode (material id: metal = tool_tip, insulation and handle = tool_shaft).
// Target: RG16UI colour and a 24-bit depth renderbuffer, single sample, the frame's size;
// cleared to (0, 0), depth test LESS, the surface first (back faces culled like the frame)
// then the electrode: the frame's order and tests, so the same fragments win.
// Overlay: drawOverlay() (overlay.h) drawn over two constant images (black, white); a pixel
// it changes in either is written by the overlay (any colour differs from one of them).
// Ownership: LabelPass owns its GL objects (destroy() with the context current); the
// vertex arrays it draws belong to the renderer. Internal to render/.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "render/gl_functions.h"
#include "render/labels.h"
#include "render/renderer.h"
#include "render/shaders.h"
#include "render/view_math.h"

namespace esim::render_detail {

// the flat-class fragment shader (needs the LABEL_TOOL define and the thresholds,
// labelFragmentSource)
extern const char* const kLabelFs;

// the complete label fragment shader: electrode (tool) or tissue variant
std::string labelFragmentSource(bool tool);

// what one label pass draws: the renderer's vertex arrays and the frame's matrices
struct LabelGeometry {
  GLuint surfaceVao = 0;
  GLsizei surfaceIndices = 0;  // 0: no surface
  int surfaceVariant = 0;      // which of the frame's surface vertex shaders (shadow 0/1)
  bool cullBackFaces = true;
  GLuint toolVao = 0;
  GLsizei toolVertices = 0;  // 0: no electrode
  M4 viewProj{};
  M4 toolPose{};
  V3 eyeM{}, forward{};  // camera centre [m] and unit viewing direction
};

class LabelPass {
 public:
  // links the programs (surfaceVs[k]: the defines of the frame's surface program k,
  // toolVs: the electrode's) and creates the framebuffer; throws esim::Error
  LabelPass(const GlFunctions& gl, const RenderOptions& options, const SurfaceVariant surfaceVs[2],
            const SurfaceVariant& toolVs);
  // deletes the GL objects (the context current)
  void destroy(const GlFunctions& gl);

  // draws the geometry and reads back classes, states, depth and their counts into out
  void draw(const GlFunctions& gl, const LabelGeometry& geometry, LabelFrame& out);

  // sets class overlay (no states) where drawOverlay(options, timeS) writes, keeping out's
  // counts (nothing when the options draw no overlay)
  void markOverlay(const RenderOptions& options, double timeS, LabelFrame& out);

 private:
  struct Program {
    GLuint id = 0;
    GLint uViewProj = -1, uModel = -1, uEye = -1, uForward = -1, uDepthUnit = -1;
  };
  Program link(const GlFunctions& gl, const SurfaceVariant& vs, bool tool);
  void use(const GlFunctions& gl, const Program& p, const M4& model, const LabelGeometry& g);

  int width_ = 0, height_ = 0;
  double depthUnitM_ = 0;  // metres per depth unit (the shader gets it as a float)
  Program surface_[2], tool_;
  GLuint fbo_ = 0, color_ = 0, depth_ = 0;
  std::vector<std::uint16_t> readBuf_;      // RG16UI, bottom row first
  std::vector<std::uint8_t> overlayOn_[2];  // constant images under the overlay
};

}  // namespace esim::render_detail
