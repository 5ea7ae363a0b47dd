// renderer.h - off-screen OpenGL drawing of a SurfaceSnapshot into RGB24 frames.
//
// Renderer owns a headless GL context (gl_context.h) and draws, per call:
//   1. a vertical grey gradient background (backgroundColor()),
//   2. the tissue surface with smooth per-vertex normals (area-weighted face
//      normals; faces meeting at more than kCreaseAngleDeg = 65 deg keep separate
//      normals so the slab's box edges and cut walls stay crisp); back faces are
//      culled (the snapshot is closed and counter-clockwise from outside),
//   3. the electrode from ToolSnapshot (blade: rounded flat spatula of widthM and
//      thickness 2 radiusM, its edge at tipM; sphere: a ball of radiusM centred at
//      tipM; each on an insulated shaft ending at lengthM and a pencil handle;
//      metallic grey, an orange glow at the tip while generatorOn),
// into its own framebuffer object (multisampled when msaaSamples > 0, resolved
// by a full-screen pass into a plain one) and reads it back; then 4. the overlay
// (colour bar with ticks in deg C or V, simulated time) is drawn on the CPU with the
// built-in 5x7 font (bitmap_font.h). On request, renderLabels() then draws the same
// buffers again for per-pixel labels (class, tissue state, depth: labels.h).
// Looks: "temperature" colours T with a perceptual map (colormap.h) between
// tMinC and tMaxC (clamped); "tissue" shows pink liver-like tissue, whitening with
// coagulation, browning then charring with desiccation, darker on cut walls, with
// a faint mottling (hashed value noise, computed per pixel); "potential" colours the electric
// potential phi [V] (SurfaceSnapshot::potentialV) with the same map between vMinV and
// vMaxV, linear t = (phi - vMin) / (vMax - vMin) or, with potentialLogScale,
// t = ln(phi / vMin) / ln(vMax / vMin) (vMinV > 0), clamped to [0, 1], with a bar in V.
// Lighting: a key light from the upper left of the camera, a weak fill light from
// the right and ambient; Blinn-Phong specular with an infinite viewer; the
// electrode casts a soft analytic shadow of the key light (two capsules,
// evaluated per vertex). Shaders are specialised per look with the preprocessor
// (llvmpipe pays for both sides of a branch). Everything is deterministic: the
// same snapshot and options give the same bytes on the same driver, whatever
// the backend (osmesa or egl) and LP_NUM_THREADS.
// Units: positions in metres, temperatures in deg C, potentials in volts, time in seconds.
// Ownership: render() returns a reference to an internal buffer (RGB24, top row
// first, width*height*3 bytes) that stays valid until the next render() call.
// A Renderer is used from one thread (the GL context is current on it).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "render/labels.h"
#include "sim/snapshot.h"

namespace esim {

constexpr double kCreaseAngleDeg = 65.0;
// between two faces of a cut wall (all three corners exposed by removal): the stair steps a
// cut leaves in the tets (faces at 45-90 deg on the structured slab) are shaded as one
// wall, not as a saw-tooth of lit and dark facets (slab_cut's zoomed groove, frame 99: the
// teeth read at 65, faint stripes at 130-150, the rim blurred at 179); the outline is the
// tets' still
constexpr double kCutWallCreaseAngleDeg = 150.0;
// RenderOptions::cutWallNormalPasses and cutWallDamagePasses at most (each pass reaches one
// ring further)
constexpr int kMaxCutWallPasses = 20;

struct RenderOptions {
  int width = 1280, height = 720;                    // frame size [px]
  std::string look = "temperature";                  // "temperature", "tissue" or "potential"
  std::array<float, 3> eyeM{0.0f, -0.085f, 0.095f};  // camera position [m]
  std::array<float, 3> targetM{0.0f, 0.0f, 0.006f};  // point looked at [m]
  std::array<float, 3> up{0.0f, 0.0f, 1.0f};         // world up direction
  float fovDeg = 35;                                 // vertical field of view [deg]
  float tMinC = 37, tMaxC = 120;                     // colour map range [C]
  float vMinV = 0, vMaxV = 72;                       // potential look: colour map range [V]
  bool potentialLogScale = false;    // potential look: logarithmic map (needs vMinV > 0)
  std::string colormap = "inferno";  // "inferno" or "viridis" (temperature, potential)
  bool showColorBar = true;          // temperature and potential looks only
  bool showTime = true;              // "t = 1.25 s" at the top left
  std::string backend = "osmesa";    // "osmesa" or "egl"
  int msaaSamples = 4;               // 0 (off), 2 or 4
  bool lighting = true;              // false: flat albedo (tests, colour checks)
  std::string shading = "pixel";     // lighting "pixel" (Blinn-Phong per pixel) or
                                     // "vertex" (per vertex, interpolated: faster,
                                     // highlights follow the mesh); colours per pixel
  bool cullBackFaces = true;         // skip triangles seen from behind (closed
                                     // surfaces; false for open ones)
  // appearance, for datasets that vary it (the defaults are the look drawn before them)
  std::uint32_t textureSeed = 0;                      // tissue look: the mottling's pattern
  std::array<float, 3> tissueTint{1.0f, 1.0f, 1.0f};  // tissue look: its colours times this RGB
  // where the key light comes from in the camera's frame (right, up, towards the viewer);
  // any length, not zero. The fill light stays where it is, on the other side
  std::array<float, 3> keyLightCamera{-0.45f, 0.65f, 0.60f};
  float lightIntensity = 1;  // the key and fill lights' strength, highlights included
                             // (the ambient term stays)
  // passes that average the cut walls' normals over their neighbours (surface_buffers.h): the
  // stair steps of removed tets shaded as one wall, its rim a crease; 0: each corner's own
  // faces, joined up to kCutWallCreaseAngleDeg (the zipper of lit and dark teeth along a groove)
  int cutWallNormalPasses = 3;
  // passes that average the cut walls' coagulation and desiccation over their neighbours
  // (surface_buffers.h): the damage under a groove's floor drawn as a band, its peaks paler
  // (and the labels' coagulated area smaller: they follow the colours); 0: each vertex's own
  // (the mean of the tets under its faces: whitened teeth along the floor)
  int cutWallDamagePasses = 0;
};

// wall-clock split of the last render() call [ms]
struct RenderTimings {
  double prepareMs = 0;   // CPU: checks, normals, vertex buffer
  double drawMs = 0;      // upload and GL drawing until glFinish (excluding prepare)
  double readbackMs = 0;  // MSAA resolve, glReadPixels, row flip
  double overlayMs = 0;   // colour bar and text on the CPU
  double totalMs = 0;
  double labelsMs = 0;  // the last renderLabels() call (not in totalMs)
};

// background colour (RGB24) at the given image row, top row 0 (the gradient)
std::array<std::uint8_t, 3> backgroundColor(int row, int height);

class Renderer {
 public:
  // creates the GL context and resources; throws esim::Error on bad options or
  // when the backend cannot give an OpenGL 3.3 core context
  explicit Renderer(const RenderOptions& options);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // draws the snapshot; returns RGB24, top row first (valid until the next call);
  // throws esim::Error naming the field when the snapshot is inconsistent
  const std::vector<std::uint8_t>& render(const SurfaceSnapshot& snapshot);

  // the labels of the last render()'s frame (labels.h): its vertex buffers drawn again
  // with the same camera, culling and depth test through a flat-class shader, single
  // sample; the overlay's pixels marked; valid until the next call. The label programs
  // and framebuffer are made on the first call. Throws esim::Error before any render().
  const LabelFrame& renderLabels();

  std::string glRenderer() const;  // GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
  std::string glVersion() const;   // GL_VERSION, e.g. "4.5 (Core Profile) Mesa 22.3.6"
  std::string glPlatform() const;  // "OSMesa", "EGL surfaceless (...)"
  const RenderOptions& options() const;
  const RenderTimings& lastTimings() const;  // of the last render() call

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// checks options (sizes, look, colour map, range, camera); throws esim::Error
void validateRenderOptions(const RenderOptions& options);

// checks the snapshot's array sizes, indices and finiteness; throws esim::Error
void validateSnapshot(const SurfaceSnapshot& snapshot);

// validateSnapshot plus what the options' look needs (the potential look needs
// potentialV unless the snapshot has no vertices); render() calls it
void validateSnapshot(const SurfaceSnapshot& snapshot, const RenderOptions& options);

}  // namespace esim
