// shaders.h - the renderer's GLSL 3.30 core sources and their compilation.
//
// Passes: a full-screen triangle (kFullScreenVs) for the background column
// (kBackgroundFs) and the MSAA resolve (kResolveFs); the surface program
// (kSurfaceVs + kSurfaceFs, sharing kLightingGlsl) draws the tissue in every look
// and the electrode. The surface program is specialised per variant with
// preprocessor defines (llvmpipe runs both sides of a branch on a uniform, so one
// program per variant is several times faster); SurfaceVariant names them.
// Units in the shaders: positions in metres, temperatures in deg C, potentials in V.
// Ownership: the sources are static strings; linked programs belong to the caller
// (glDeleteProgram). Internal to render/: not used outside the renderer.
#pragma once

#include <string>

#include "render/gl_functions.h"

namespace esim::render_detail {

// full-screen triangle from gl_VertexID (no vertex buffer): background and resolve passes
extern const char* const kFullScreenVs;
// the background gradient; must match backgroundColor() (renderer.h) on the CPU
extern const char* const kBackgroundFs;
// MSAA resolve (needs "#define SAMPLES n", see resolveFragmentSource): the mean of
// the samples, background colour of the row where a sample's alpha is still 0
extern const char* const kResolveFs;
// specLobe() and lightTerms(), shared by the surface vertex and fragment shaders
extern const char* const kLightingGlsl;
// surface vertex shader: world position, normal, state, the electrode's soft shadow
// and, with VERTEXLIT, the light terms per vertex
extern const char* const kSurfaceVs;
// surface fragment shader: albedo per look, lighting per pixel or interpolated
extern const char* const kSurfaceFs;

// the LOOK define of the surface shaders
constexpr int kLookTemperature = 0;  // vState.x = T [C] through the colour map
constexpr int kLookTissue = 1;       // vState = (T, coagulation, desiccation, cut wall)
constexpr int kLookTool = 2;         // vState = albedo rgb, material id (the electrode)
constexpr int kLookPotential = 3;    // vState.x = phi [V] through the colour map

// one specialisation of the surface program (its preprocessor defines)
struct SurfaceVariant {
  int look = kLookTemperature;  // LOOK: kLook*
  bool lit = true;              // LIT: lighting, else flat albedo
  bool shadow = false;          // SHADOW: the electrode's shadow on the surface
  bool logScale = false;        // LOGSCALE: logarithmic potential map
  bool vertexLit = false;       // VERTEXLIT: lighting per vertex, else per pixel
};

// a linked surface program and its uniform locations (-1: unused by the variant)
struct SurfaceProgram {
  GLuint id = 0;
  GLint uViewProj = -1, uModel = -1, uColormap = -1, uTempRange = -1, uHalfDir = -1, uKeyDir = -1,
        uFillDir = -1, uTipM = -1, uGlow = -1, uToolAxis = -1, uToolSizes = -1, uLightWeights = -1,
        uTint = -1, uSeedSalt = -1;
};

// "#version" line, the variant's defines and kLightingGlsl: the prefix of both surface stages
std::string surfaceShaderHeader(const SurfaceVariant& variant);

// the complete resolve fragment shader for the given number of samples
std::string resolveFragmentSource(int samples);

// compiles and links a vertex and a fragment shader; throws esim::Error naming
// `what` with the driver's log
GLuint linkProgram(const GlFunctions& gl, const char* vs, const char* fs, const char* what);

// links the surface program of the variant and looks up its uniforms
SurfaceProgram linkSurfaceProgram(const GlFunctions& gl, const SurfaceVariant& variant);

}  // namespace esim::render_detail
