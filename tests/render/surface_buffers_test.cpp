// Tests for render/surface_buffers.cpp: crease-limited normals, the cut walls' wider crease.
#include "render/surface_buffers.h"

#include <gtest/gtest.h>

#include <cmath>

#include "render/renderer.h"
#include "render/vertex_layout.h"

namespace esim {
namespace {

using render_detail::kFloatsPerVertex;
using render_detail::kNormalOffset;
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

}  // namespace
}  // namespace esim
