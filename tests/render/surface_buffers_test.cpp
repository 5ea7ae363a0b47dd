// Tests for render/surface_buffers.cpp: crease-limited normals, the cut walls' wider crease,
// their normals and damage averaged over the wall.
#include "render/surface_buffers.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "render/renderer.h"
#include "render/vertex_layout.h"
#include "sim/core_error.h"

namespace esim {
namespace {

using render_detail::kFloatsPerVertex;
using render_detail::kNormalOffset;
using render_detail::kStateOffset;
using render_detail::SurfaceBuffers;

// two triangles folded along the edge (0, 1) (the x axis): their normals foldDeg apart;
// cutWall at every vertex
SurfaceSnapshot fold(double foldDeg, float cutWall) {
  const double a = foldDeg * 3.14159265358979 / 180.0;
  SurfaceSnapshot s;
  s.positionsM = {0, 0, 0, 0.01f, 0, 0,
                  // (0, 1, 2) lies in z = 0, normal +z; (1, 0, 3) turned by foldDeg about x
                  0.005f, 0.01f, 0, 0.005f, static_cast<float>(-0.01 * std::cos(a)),
                  static_cast<float>(0.01 * std::sin(a))};
  s.triangles = {0, 1, 2, 1, 0, 3};
  s.temperatureC.assign(4, 37.0f);
  s.cutWall.assign(4, cutWall);
  return s;
}

// the angle between the normals of the first triangle's and the second's corners on the
// shared edge [deg]; and the GPU vertices made
std::pair<double, size_t> normalsAcrossTheEdge(const SurfaceSnapshot& s) {
  SurfaceBuffers b;
  b.build(s, 37.0f, false);
  auto normal = [&](int corner) {
    const float* n = &b.vertices[b.indices[corner] * kFloatsPerVertex + kNormalOffset];
    return std::array<double, 3>{n[0], n[1], n[2]};
  };
  const auto n0 = normal(0), n1 = normal(4);  // node 0 in triangle 0 and in triangle 1
  const double c = n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2];
  return {std::acos(std::min(1.0, c)) * 180 / 3.14159265358979,
          b.vertices.size() / kFloatsPerVertex};
}

TEST(SurfaceBuffers, TheFoldIsCreasedBeyondTheCreaseAngle) {
  const auto [smooth, smoothCount] = normalsAcrossTheEdge(fold(kCreaseAngleDeg - 5, 0));
  EXPECT_LT(smooth, 0.05);     // one normal (to float rounding of |n| = 1)
  EXPECT_EQ(smoothCount, 4u);  // one GPU vertex per snapshot vertex
  const auto [creased, creasedCount] = normalsAcrossTheEdge(fold(kCreaseAngleDeg + 5, 0));
  EXPECT_NEAR(creased, kCreaseAngleDeg + 5, 1e-3);  // each corner its face's normal
  EXPECT_EQ(creasedCount, 6u);                      // the edge's two vertices split
}

// a cut wall's stair steps are shaded as one surface up to kCutWallCreaseAngleDeg; the same
// fold off the wall (or only partly on it) stays creased
TEST(SurfaceBuffers, CutWallsJoinUpToTheirWiderCreaseAngle) {
  const double step = 0.5 * (kCreaseAngleDeg + kCutWallCreaseAngleDeg);  // 107.5 deg
  EXPECT_LT(normalsAcrossTheEdge(fold(step, 1.0f)).first, 0.05);
  EXPECT_EQ(normalsAcrossTheEdge(fold(step, 1.0f)).second, 4u);
  EXPECT_NEAR(normalsAcrossTheEdge(fold(step, 0.0f)).first, step, 1e-3);
  SurfaceSnapshot half = fold(step, 1.0f);
  half.cutWall[3] = 0.4f;  // the second triangle is not all wall
  EXPECT_NEAR(normalsAcrossTheEdge(half).first, step, 1e-3);
  EXPECT_NEAR(normalsAcrossTheEdge(fold(kCutWallCreaseAngleDeg + 5, 1.0f)).first,
              kCutWallCreaseAngleDeg + 5, 1e-3);
}

// A wall in the plane y = 0 (normal -y) cut into saw teeth: a strip of 2 x (kTeeth + 1)
// vertices along x, the middle row alternately pushed out and in along -y, as removed tets
// leave a groove's wall; a top row at z = h is the wall's rim, and a flat top face
// (cutWall 0 at its far vertex) meets the rim there. Returns the snapshot; the wall's
// triangles come first.
constexpr int kTeeth = 12;
SurfaceSnapshot sawToothWall() {
  SurfaceSnapshot s;
  const float dx = 0.001f, h = 0.001f, tooth = 0.0004f;
  // rows: bottom (z = 0), middle (z = h / 2, the teeth), top (z = h, the rim)
  for (int row = 0; row < 3; ++row)
    for (int i = 0; i <= kTeeth; ++i) {
      const float y = row == 1 ? (i % 2 == 0 ? -tooth : tooth) : 0.0f;
      s.positionsM.insert(s.positionsM.end(), {i * dx, y, row * 0.5f * h});
    }
  const auto id = [](int row, int i) { return static_cast<std::uint32_t>(row * (kTeeth + 1) + i); };
  for (int row = 0; row < 2; ++row)
    for (int i = 0; i < kTeeth; ++i)  // counter-clockwise seen from -y: normals along -y
      s.triangles.insert(s.triangles.end(), {id(row, i), id(row, i + 1), id(row + 1, i + 1),
                                             id(row, i), id(row + 1, i + 1), id(row + 1, i)});
  const int nv = static_cast<int>(s.positionsM.size() / 3);
  s.positionsM.insert(s.positionsM.end(), {0.5f * kTeeth * dx, 0.002f, h});  // the top's far vertex
  s.triangles.insert(s.triangles.end(),
                     {id(2, 0), id(2, kTeeth), static_cast<std::uint32_t>(nv)});  // normal +z
  s.temperatureC.assign(nv + 1, 37.0f);
  s.cutWall.assign(nv + 1, 1.0f);
  s.cutWall[nv] = 0.0f;
  return s;
}

// the largest angle between a wall corner's normal and -y, and the top face's corners'
// largest angle from +z [deg]
std::pair<double, double> sawToothNormals(int passes) {
  const SurfaceSnapshot s = sawToothWall();
  SurfaceBuffers b;
  b.cutWallNormalPasses = passes;
  b.build(s, 37.0f, false);
  auto angle = [&](int corner, std::array<double, 3> axis) {
    const float* n = &b.vertices[b.indices[corner] * kFloatsPerVertex + kNormalOffset];
    const double c = n[0] * axis[0] + n[1] * axis[1] + n[2] * axis[2];
    return std::acos(std::min(1.0, c)) * 180 / 3.14159265358979;
  };
  double wall = 0, top = 0;
  const int wallCorners = 2 * 6 * kTeeth;
  for (int c = 0; c < wallCorners; ++c) wall = std::max(wall, angle(c, {0, -1, 0}));
  for (int c = wallCorners; c < wallCorners + 3; ++c) top = std::max(top, angle(c, {0, 0, 1}));
  return {wall, top};
}

// the teeth are lit as one wall once the normals are averaged: each pass brings every wall
// corner's normal closer to the wall's, and the rim stays a crease (the top face's corners
// keep the normals they had without the passes, bit for bit)
TEST(SurfaceBuffers, CutWallNormalPassesShadeTheSawTeethAsOneWall) {
  const auto [raw, rawTop] = sawToothNormals(0);
  // a tooth's faces lean 38.7 deg from the wall; at the rim's ends the top face joins the
  // corners' sums (within kCreaseAngleDeg of the leaning faces): 88.8 deg
  EXPECT_GT(raw, 30.0);
  double last = raw;
  for (int passes : {1, 2, 3, 6}) {
    const auto [wall, top] = sawToothNormals(passes);
    EXPECT_LT(wall, last) << passes << " passes";
    last = wall;
    EXPECT_EQ(top, rawTop) << passes << " passes";
  }
  EXPECT_LT(sawToothNormals(3).first, 0.35 * raw);
}

// the surface s with no vertex on a cut wall: 5 passes build the same arrays as none, bit for
// bit (normals and states alike)
void expectPassesChangeNothingWithoutWalls(SurfaceSnapshot s) {
  s.cutWall.assign(s.cutWall.size(), 0.0f);
  SurfaceBuffers off, on;
  on.cutWallNormalPasses = on.cutWallDamagePasses = 5;
  off.build(s, 37.0f, false);
  on.build(s, 37.0f, false);
  EXPECT_EQ(on.vertices, off.vertices);
  EXPECT_EQ(on.indices, off.indices);
}

// a flat wall is unchanged by the passes (the mean of equal unit normals), so is a surface
// without walls (bit for bit: the passes touch only wall corners); the option's bound is
// refused past it
TEST(SurfaceBuffers, CutWallNormalPassesLeaveFlatWallsAndOtherSurfacesAlone) {
  SurfaceSnapshot flat = sawToothWall();
  for (size_t v = 0; v < flat.positionsM.size() / 3 - 1; ++v) flat.positionsM[3 * v + 1] = 0;
  SurfaceBuffers b;
  b.cutWallNormalPasses = 5;
  b.build(flat, 37.0f, false);
  for (int c = 0; c < 2 * 6 * kTeeth; ++c) {
    const float* n = &b.vertices[b.indices[c] * kFloatsPerVertex + kNormalOffset];
    EXPECT_NEAR(n[1], -1.0f, 1e-6f);
  }
  expectPassesChangeNothingWithoutWalls(sawToothWall());
  // either option past its bound is refused, naming its key
  const auto refused = [](RenderOptions o, const std::string& key) {
    try {
      validateRenderOptions(o);
      ADD_FAILURE() << "accepted " << key;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(key + ":"), std::string::npos) << e.what();
    }
  };
  RenderOptions normals, damage;
  normals.cutWallNormalPasses = kMaxCutWallPasses + 1;
  damage.cutWallDamagePasses = kMaxCutWallPasses + 1;
  refused(normals, "look.cut_wall_smoothing");
  refused(damage, "look.cut_wall_damage_smoothing");
}

// the state a corner's GPU vertex carries: (T, coagulation, desiccation, cut wall)
std::array<float, 4> cornerState(const SurfaceBuffers& b, int corner) {
  const float* q = &b.vertices[b.indices[corner] * kFloatsPerVertex + kStateOffset];
  return {q[0], q[1], q[2], q[3]};
}

// the saw-tooth wall with the damage of the tets behind it: every other vertex of the
// bottom row coagulated (and desiccated) fully, the rest none: the teeth of whitening a
// groove's floor shows. The passes turn them into a band: each pass a mean over the wall
// (the values stay in [0, 1], a pass never widens their range), the spread between
// neighbouring bottom vertices shrinking pass by pass; the top face's far vertex (off the
// wall) keeps its own value; 0 passes, or a surface without walls, draw each vertex's own.
// The normals' passes are 0 here: the damage's passes build the wall's neighbours themselves
SurfaceSnapshot toothedDamage() {
  SurfaceSnapshot s = sawToothWall();
  const int nv = s.numVertices();
  s.coagulation.assign(nv, 0.0f);
  s.desiccation.assign(nv, 0.0f);
  for (int i = 0; i <= kTeeth; i += 2) s.coagulation[i] = s.desiccation[i] = 1.0f;
  s.coagulation[nv - 1] = 0.7f;  // the top face's far vertex
  return s;
}

TEST(SurfaceBuffers, CutWallDamagePassesDrawTheDamageUnderAWallAsABand) {
  const SurfaceSnapshot s = toothedDamage();
  const int nv = s.numVertices();
  // the largest difference between bottom-row neighbours, of coagulation and desiccation,
  // and the range of the values drawn
  const auto spread = [&](int passes, const SurfaceSnapshot& snap) {
    SurfaceBuffers b;
    b.cutWallDamagePasses = passes;  // the normals' passes 0: the damage's work alone
    b.build(snap, 37.0f, false);
    std::vector<std::array<float, 4>> state(nv);
    for (size_t c = 0; c < b.indices.size(); ++c) {
      const std::uint32_t v = snap.triangles[c];
      state[v] = cornerState(b, static_cast<int>(c));
    }
    float jump = 0, lo = 1, hi = 0;
    for (int i = 0; i < kTeeth; ++i)
      for (int k : {1, 2}) jump = std::max(jump, std::abs(state[i][k] - state[i + 1][k]));
    for (int v = 0; v < nv - 1; ++v) {
      lo = std::min(lo, state[v][1]);
      hi = std::max(hi, state[v][1]);
      EXPECT_EQ(state[v][1], state[v][2]) << "coagulation and desiccation alike, vertex " << v;
    }
    EXPECT_EQ(state[nv - 1][1], 0.7f) << "off the wall: its own value";
    return std::array<float, 3>{jump, lo, hi};
  };
  const auto raw = spread(0, s);
  EXPECT_EQ(raw[0], 1.0f);  // the teeth: 1, 0, 1, ... along the floor
  float last = raw[0];
  for (int passes : {1, 2, 3, 6}) {
    const auto [jump, lo, hi] = spread(passes, s);
    EXPECT_LT(jump, last) << passes << " passes";
    EXPECT_GE(lo, 0.0f);
    EXPECT_LE(hi, 1.0f);
    last = jump;
  }
  EXPECT_LT(spread(3, s)[0], 0.25f);
  expectPassesChangeNothingWithoutWalls(s);
}

// a frame whose geometry is kept (update rewrites the states only) averages the new damage
// as a fresh build does, bit for bit
TEST(SurfaceBuffers, CutWallDamagePassesFollowTheDamageOnAKeptGeometry) {
  SurfaceSnapshot s = sawToothWall();
  const int nv = s.numVertices();
  s.coagulation.assign(nv, 0.0f);
  s.desiccation.assign(nv, 0.0f);
  SurfaceBuffers kept;
  kept.cutWallDamagePasses = 3;
  kept.update(s, 37.0f, false);
  for (int i = 1; i <= kTeeth; i += 3) s.coagulation[i] = 0.9f;
  s.desiccation[kTeeth + 2] = 0.5f;
  kept.update(s, 37.0f, false);
  ASSERT_TRUE(kept.geometryReused);
  SurfaceBuffers fresh;
  fresh.cutWallDamagePasses = 3;
  fresh.build(s, 37.0f, false);
  EXPECT_EQ(kept.vertices, fresh.vertices);
  EXPECT_NE(cornerState(kept, 0)[1], 0.0f);  // vertex 0 has a coagulated neighbour
}

// the two kinds of passes are independent: the damage's leave every normal as the normals'
// passes alone make it, bit for bit, and the normals' leave every vertex's own damage
TEST(SurfaceBuffers, CutWallNormalAndDamagePassesAreIndependent) {
  const SurfaceSnapshot s = toothedDamage();
  SurfaceBuffers normals, both;
  normals.cutWallNormalPasses = both.cutWallNormalPasses = 3;
  both.cutWallDamagePasses = 3;
  normals.build(s, 37.0f, false);
  both.build(s, 37.0f, false);
  ASSERT_EQ(normals.indices, both.indices);
  bool damageDiffers = false;
  for (size_t c = 0; c < normals.indices.size(); ++c) {
    const float* a = &normals.vertices[normals.indices[c] * kFloatsPerVertex + kNormalOffset];
    const float* b = &both.vertices[both.indices[c] * kFloatsPerVertex + kNormalOffset];
    EXPECT_TRUE(a[0] == b[0] && a[1] == b[1] && a[2] == b[2]) << "corner " << c;
    const std::uint32_t v = s.triangles[c];
    EXPECT_EQ(cornerState(normals, static_cast<int>(c))[1], s.coagulation[v]) << "corner " << c;
    damageDiffers |= cornerState(both, static_cast<int>(c))[1] != s.coagulation[v];
  }
  EXPECT_TRUE(damageDiffers);
}

}  // namespace
}  // namespace esim
