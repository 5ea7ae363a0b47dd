// shaders.cpp - GLSL sources of the renderer and their compilation (see shaders.h).
#include "render/shaders.h"

#include "sim/core_error.h"

namespace esim::render_detail {

// a triangle covering the viewport (background and MSAA resolve passes)
const char* const kFullScreenVs = R"(#version 330 core
void main() {
  vec2 p = vec2((gl_VertexID == 1) ? 3.0 : -1.0, (gl_VertexID == 2) ? 3.0 : -1.0);
  gl_Position = vec4(p, 0.0, 1.0);
})";

// the gradient must match backgroundColor() on the CPU: top kBgTop, bottom kBgBottom
const char* const kBackgroundFs = R"(#version 330 core
uniform vec2 uSize;
out vec4 fragColor;
void main() {
  float fromTop = (uSize.y - gl_FragCoord.y) / uSize.y;   // 0 at the top edge
  vec3 top = vec3(104.0, 110.0, 120.0) / 255.0;
  vec3 bottom = vec3(38.0, 40.0, 46.0) / 255.0;
  fragColor = vec4(mix(top, bottom, fromTop), 1.0);
})";

// MSAA resolve as a full-screen pass (llvmpipe runs it on all its threads; the
// blit path is several times slower): the mean of the samples, like a box resolve.
// The background is not drawn into the multisampled buffer: it is cleared to alpha
// 0 (everything drawn has alpha 1), and a sample still at alpha 0 takes the
// background colour of its row from uBackground (1 x height, written once by the
// background pass itself, so the bytes are the ones that pass would have stored):
// the same sums as drawing the background first, without a full-screen pass per frame.
const char* const kResolveFs = R"(
uniform sampler2DMS uSamples;
uniform sampler2D uBackground;
out vec4 fragColor;
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 bg = texelFetch(uBackground, ivec2(0, p.y), 0);
  vec4 sum = vec4(0.0);
  for (int i = 0; i < SAMPLES; ++i) {
    vec4 s = texelFetch(uSamples, p, i);
    sum += s.a < 0.5 ? bg : s;
  }
  fragColor = sum / float(SAMPLES);
})";

// shared by the surface vertex and fragment shaders
const char* const kLightingGlsl = R"(
uniform vec3 uHalfDir;        // Blinn-Phong half vector of key light and view (infinite viewer)
uniform vec3 uKeyDir;         // towards the key light
uniform vec3 uFillDir;        // towards the fill light
uniform vec3 uLightWeights;   // the key's and the fill's diffuse weights, the highlights' factor

// Blinn-Phong lobe x^shininess by repeated squaring (pow costs ~20 operations
// per pixel on llvmpipe): 24 for the temperature and potential looks, 55 for tissue
float specLobe(float x) {
  float x2 = x * x, x4 = x2 * x2, x8 = x4 * x4, x16 = x8 * x8;
#if LOOK == 0 || LOOK == 3
  return x16 * x8;
#else
  return x16 * x16 * x16 * x4 * x2 * x;
#endif
}

// VERTEXLIT: the light terms of unit normal n, (key, fill, specular lobe), key and
// specular already in the electrode's shadow
vec3 lightTerms(vec3 n, float shadow) {
  float key = max(dot(n, uKeyDir), 0.0) * shadow;
  float fill = max(dot(n, uFillDir), 0.0);
  float nh = max(dot(n, uHalfDir), 0.0);
  return vec3(key, fill, specLobe(nh) * step(0.0, dot(n, uKeyDir)) * shadow);
}
)";

// the electrode's soft shadow is evaluated per vertex (it is smooth on the scale
// of the mesh, and llvmpipe would pay for it on every pixel)
const char* const kSurfaceVs = R"(
layout(location = 0) in vec3 aPos;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aState;
uniform mat4 uViewProj;
uniform mat4 uModel;
uniform vec3 uTipM;           // electrode tip [m]
uniform vec3 uToolAxis;       // unit axis, tip to handle
uniform vec3 uToolSizes;      // shaft length [m], shaft radius [m], handle radius [m]
out vec3 vPos;
out vec3 vNormal;
out vec4 vState;
out float vShadow;            // 1 lit, 0.25 fully in the electrode's shadow
#if VERTEXLIT
out vec3 vLightFront;         // lightTerms() of the front face's normal
out vec3 vLightBack;          // and of the back face's (open surfaces)
#endif

#if SHADOW
// distance between the ray p + s L (s >= 0, |L| = 1) and the segment [a, b]:
// closest points of the two lines, segment parameter clamped, ray parameter
// re-projected and clamped
float raySegmentDistance(vec3 p, vec3 L, vec3 a, vec3 b) {
  vec3 v = b - a;
  vec3 w = p - a;
  float B = dot(L, v), C = dot(v, v), D = dot(L, w), E = dot(v, w);
  float den = max(C - B * B, 1e-12 * C);
  float t = clamp((E - B * D) / den, 0.0, 1.0);
  float s = max(dot(a + t * v - p, L), 0.0);
  return length(p + s * L - (a + t * v));
}

// analytic soft shadow of the electrode (two capsules: shaft with blade, handle)
float toolShadow(vec3 p) {
  vec3 shaftEnd = uTipM + uToolAxis * uToolSizes.x;
  vec3 handleEnd = shaftEnd + uToolAxis * 0.09;
  float d1 = raySegmentDistance(p, uKeyDir, uTipM, shaftEnd);
  float d2 = raySegmentDistance(p, uKeyDir, shaftEnd, handleEnd);
  float lit1 = smoothstep(0.5 * uToolSizes.y, 1.8 * uToolSizes.y, d1);
  float lit2 = smoothstep(0.6 * uToolSizes.z, 1.6 * uToolSizes.z, d2);
  return mix(1.0, min(lit1, lit2), 0.75);
}
#else
float toolShadow(vec3 p) { return 1.0; }
#endif

void main() {
  vec4 world = uModel * vec4(aPos, 1.0);
  vPos = world.xyz;
  vNormal = mat3(uModel) * aNormal;
  vState = aState;
  vShadow = toolShadow(vPos);
#if VERTEXLIT
  vec3 n = normalize(vNormal);
  vLightFront = lightTerms(n, vShadow);
  vLightBack = lightTerms(-n, vShadow);
#endif
  gl_Position = uViewProj * world;
})";

// Specialised by the preprocessor (llvmpipe runs both sides of a branch on a
// uniform, so one program per variant is several times faster):
//   LOOK 0 temperature, 1 tissue, 2 tool (vState = albedo rgb, material id),
//        3 potential (vState.x = phi [V]; LOGSCALE 0/1 linear or logarithmic map)
//   LIT 0/1 lighting, SHADOW 0/1 the electrode's shadow on the tissue,
//   VERTEXLIT 0/1 lighting per pixel or per vertex (RenderOptions::shading; never
//   for the electrode, LOOK 2, whose metal needs its highlights per pixel)
const char* const kSurfaceFs = R"(
in vec3 vPos;
in vec3 vNormal;
in vec4 vState;
in float vShadow;
#if VERTEXLIT
in vec3 vLightFront;
in vec3 vLightBack;
#endif
uniform sampler1D uColormap;
uniform vec2 uTempRange;      // tMinC, tMaxC (potential look: vMinV, vMaxV)
uniform vec3 uTipM;           // electrode tip [m]
uniform float uGlow;          // 1 while the generator is on
out vec4 fragColor;


#if LOOK == 1
// the tissue's mottling: value noise on a tiling 64^2 lattice of hashed bytes, bilinear,
// computed here rather than looked up in a texture (two lookups a pixel cost llvmpipe 21 %
// more on slab_cut: README, "Rendering"). The depth shifts the lookup so vertical cut walls
// are mottled too.
uniform uint uSeedSalt;       // look.texture_seed's salt of the hash (0: the default pattern)
uniform vec3 uTint;           // look.tissue_tint
// one lattice value, in [0, 1]: an integer hash of the lattice index
float latticeValue(uint x, uint y) {
  uint h = ((y & 63u) * 64u + (x & 63u)) * 2654435761u + 0x9e3779b9u + uSeedSalt;
  h ^= h >> 15u;
  h *= 0x2c1b3c6du;
  h ^= h >> 12u;
  h *= 0x297a2d39u;
  h ^= h >> 15u;
  return float(h >> 24u) * (1.0 / 255.0);
}
// the lattice, bilinear between its values (at integer + 0.5, as texel centres) and
// tiling, at p in lattice units
float latticeNoise(vec2 p) {
  p -= 0.5;
  vec2 i = floor(p);
  vec2 f = p - i;
  uint x = uint(int(i.x) & 63), y = uint(int(i.y) & 63);
  float a = latticeValue(x, y), b = latticeValue(x + 1u, y);
  float c = latticeValue(x, y + 1u), d = latticeValue(x + 1u, y + 1u);
  return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}
#endif

void main() {
  vec3 albedo;
  vec3 emissive = vec3(0.0);
  float specStrength;
  float shininess;
  bool metal = false;
#if LOOK == 0
  float t = clamp((vState.x - uTempRange.x) / (uTempRange.y - uTempRange.x), 0.0, 1.0);
  albedo = texture(uColormap, t * (255.0 / 256.0) + 0.5 / 256.0).rgb;
  specStrength = 0.18;
  shininess = 24.0;
#elif LOOK == 3
#if LOGSCALE
  float t = clamp(log(max(vState.x, uTempRange.x) / uTempRange.x) /
                  log(uTempRange.y / uTempRange.x), 0.0, 1.0);
#else
  float t = clamp((vState.x - uTempRange.x) / (uTempRange.y - uTempRange.x), 0.0, 1.0);
#endif
  albedo = texture(uColormap, t * (255.0 / 256.0) + 0.5 / 256.0).rgb;
  specStrength = 0.18;
  shininess = 24.0;
#elif LOOK == 1
  float coag = clamp(vState.y, 0.0, 1.0);
  float dry = clamp(vState.z, 0.0, 1.0);
  float wall = clamp(vState.w, 0.0, 1.0);
  vec3 fresh = vec3(0.74, 0.33, 0.31);       // pink-red liver
  vec3 cutFresh = vec3(0.56, 0.17, 0.15);    // exposed parenchyma: darker, redder
  vec3 cooked = vec3(0.86, 0.79, 0.72);      // coagulated: whitish tan
  vec3 brown = vec3(0.50, 0.31, 0.17);       // desiccated
  vec3 charred = vec3(0.09, 0.07, 0.06);     // carbonised
  vec3 mm = vPos * 1000.0;
  vec2 uv = mm.xy + mm.z * vec2(0.61, 0.83);
  float mottle = 0.65 * latticeNoise(uv * 0.8) +
                 0.35 * latticeNoise(uv * 2.3 + vec2(0.37, 0.61) * 64.0);
  albedo = mix(fresh, cutFresh, wall) * (0.90 + 0.18 * mottle);
  albedo = mix(albedo, cooked * (0.95 + 0.08 * mottle), smoothstep(0.0, 1.0, coag));
  albedo = mix(albedo, brown, smoothstep(0.0, 0.55, dry));
  albedo = mix(albedo, charred, smoothstep(0.5, 1.0, dry));
  albedo *= uTint;
  specStrength = 0.38 * (1.0 - dry) * (1.0 - 0.4 * coag);   // wet capsule shine
  shininess = 55.0;
  float dTip = length(vPos - uTipM) * 1000.0;                // [mm]
  emissive = uGlow * vec3(1.0, 0.55, 0.20) * 0.85 * exp(-dTip * dTip / 1.2);
#else
  albedo = vState.rgb;
  metal = vState.w < 0.5;
  specStrength = metal ? 0.85 : (vState.w < 1.5 ? 0.35 : 0.25);
  shininess = metal ? 70.0 : 30.0;
  float dTip = length(vPos - uTipM) * 1000.0;                // [mm]
  emissive = (metal ? uGlow : 0.0) * vec3(1.0, 0.62, 0.28) * 0.9 * exp(-dTip / 1.5);
#endif
#if LIT == 0
  fragColor = vec4(clamp(albedo + emissive, 0.0, 1.0), 1.0);
#elif VERTEXLIT
  // lighting interpolated from the vertices (Gouraud); colour map and tissue per pixel
  vec3 L = gl_FrontFacing ? vLightFront : vLightBack;
  vec3 color = albedo * (0.30 + uLightWeights.x * L.x + uLightWeights.y * L.y);
#if LOOK == 0 || LOOK == 3
  color += vec3(0.10 * uLightWeights.z) * (L.x + 0.3 * L.y);
#endif
  color += vec3(specStrength * uLightWeights.z * L.z);
  fragColor = vec4(clamp(color + emissive, 0.0, 1.0), 1.0);
#else
  vec3 n = normalize(vNormal);
  if (!gl_FrontFacing) n = -n;
  float shadow = vShadow;
  float key = max(dot(n, uKeyDir), 0.0) * shadow;
  float fill = max(dot(n, uFillDir), 0.0);
  float ambient = metal ? 0.38 : 0.30;
  vec3 color = albedo * (ambient + uLightWeights.x * key + uLightWeights.y * fill);
#if LOOK == 0 || LOOK == 3
  // a faint grey diffuse sheen, so that the shape of tissue at the dark end of
  // the map (inferno is black at tMin) stays readable
  color += vec3(0.10 * uLightWeights.z) * (key + 0.3 * fill);
#endif
  float nh = max(dot(n, uHalfDir), 0.0);
#if LOOK == 2
  float spec = specStrength * pow(nh, shininess);
#else
  float spec = specStrength * specLobe(nh);
#endif
  spec *= step(0.0, dot(n, uKeyDir)) * shadow * uLightWeights.z;
  color += (metal ? mix(vec3(1.0), albedo, 0.4) : vec3(1.0)) * spec;
  fragColor = vec4(clamp(color + emissive, 0.0, 1.0), 1.0);
#endif
})";

std::string surfaceShaderHeader(const SurfaceVariant& v) {
  return "#version 330 core\n#define LOOK " + std::to_string(v.look) + "\n#define LIT " +
         std::to_string(v.lit ? 1 : 0) + "\n#define SHADOW " + std::to_string(v.shadow ? 1 : 0) +
         "\n#define LOGSCALE " + std::to_string(v.logScale ? 1 : 0) + "\n#define VERTEXLIT " +
         std::to_string(v.vertexLit ? 1 : 0) + "\n" + kLightingGlsl;
}

std::string resolveFragmentSource(int samples) {
  return "#version 330 core\n#define SAMPLES " + std::to_string(samples) + "\n" + kResolveFs;
}

namespace {

// compiles one stage; throws esim::Error with the driver's log
GLuint compileShader(const GlFunctions& gl, GLenum type, const char* src, const char* what) {
  const GLuint s = gl.CreateShader(type);
  gl.ShaderSource(s, 1, &src, nullptr);
  gl.CompileShader(s);
  GLint ok = 0;
  gl.GetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {0};
    gl.GetShaderInfoLog(s, sizeof log, nullptr, log);
    gl.DeleteShader(s);
    throw Error(std::string("renderer: shader '") + what + "' failed to compile: " + log);
  }
  return s;
}

}  // namespace

GLuint linkProgram(const GlFunctions& gl, const char* vs, const char* fs, const char* what) {
  const GLuint v = compileShader(gl, GL_VERTEX_SHADER, vs, what);
  const GLuint f = compileShader(gl, GL_FRAGMENT_SHADER, fs, what);
  const GLuint p = gl.CreateProgram();
  gl.AttachShader(p, v);
  gl.AttachShader(p, f);
  gl.LinkProgram(p);
  gl.DeleteShader(v);
  gl.DeleteShader(f);
  GLint ok = 0;
  gl.GetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {0};
    gl.GetProgramInfoLog(p, sizeof log, nullptr, log);
    gl.DeleteProgram(p);
    throw Error(std::string("renderer: program '") + what + "' failed to link: " + log);
  }
  return p;
}

SurfaceProgram linkSurfaceProgram(const GlFunctions& gl, const SurfaceVariant& variant) {
  const std::string header = surfaceShaderHeader(variant);
  const std::string fs = header + kSurfaceFs;
  SurfaceProgram p;
  const std::string vs = header + kSurfaceVs;
  p.id = linkProgram(gl, vs.c_str(), fs.c_str(), "surface");
  auto loc = [&](const char* n) { return gl.GetUniformLocation(p.id, n); };
  p.uViewProj = loc("uViewProj");
  p.uModel = loc("uModel");
  p.uColormap = loc("uColormap");
  p.uTempRange = loc("uTempRange");
  p.uHalfDir = loc("uHalfDir");
  p.uKeyDir = loc("uKeyDir");
  p.uFillDir = loc("uFillDir");
  p.uTipM = loc("uTipM");
  p.uGlow = loc("uGlow");
  p.uToolAxis = loc("uToolAxis");
  p.uToolSizes = loc("uToolSizes");
  p.uLightWeights = loc("uLightWeights");
  p.uTint = loc("uTint");
  p.uSeedSalt = loc("uSeedSalt");
  return p;
}

}  // namespace esim::render_detail
