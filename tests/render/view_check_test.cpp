// view_check_test.cpp - does the camera see the tissue (render/view_check.h): a cube's
// surface seen from outside, from inside, looked away from, a quad filling the view with
// every vertex outside it, and points the cube hides
#include "render/view_check.h"

#include <gtest/gtest.h>

#include <cmath>

namespace esim {
namespace {

// the unit cube's surface [0, 1]^3 (m), counter-clockwise from outside
SurfaceSnapshot cube() {
  SurfaceSnapshot s;
  for (int i = 0; i < 8; ++i) {
    s.positionsM.push_back(static_cast<float>(i & 1));
    s.positionsM.push_back(static_cast<float>((i >> 1) & 1));
    s.positionsM.push_back(static_cast<float>((i >> 2) & 1));
  }
  s.triangles = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  return s;
}

RenderOptions camera(std::array<float, 3> eye, std::array<float, 3> target) {
  RenderOptions o;
  o.eyeM = eye;
  o.targetM = target;
  o.up = {0, 0, 1};
  o.fovDeg = 35;
  o.width = 1280;
  o.height = 720;
  return o;
}

TEST(ViewCheck, ACubeSeenFromOutsideIsSeen) {
  const ViewCheck v = checkView(camera({3, -4, 2.5f}, {0.5f, 0.5f, 0.5f}), cube());
  EXPECT_FALSE(v.eyeInside);
  EXPECT_TRUE(v.seesSurface);
  EXPECT_EQ(v.verticesInView, 8);
}

TEST(ViewCheck, AnEyeInsideTheSurfaceSeesNothingOfIt) {
  for (const auto& eye : {std::array<float, 3>{0.5f, 0.5f, 0.5f}, {0.01f, 0.98f, 0.3f}}) {
    const ViewCheck v = checkView(camera(eye, {2, 0.5f, 0.5f}), cube());
    EXPECT_TRUE(v.eyeInside);
    EXPECT_FALSE(v.seesSurface);
  }
  // just outside a face, looking along it: outside
  EXPECT_FALSE(checkView(camera({1.01f, 0.5f, 0.5f}, {1.01f, 2, 0.5f}), cube()).eyeInside);
}

// a point behind the cube, on it, in front of it, or inside it, from an eye in front
TEST(ViewCheck, APointBehindTheSurfaceIsHidden) {
  const RenderOptions o = camera({0.5f, -3, 0.5f}, {0.5f, 0.5f, 0.5f});
  const SurfaceSnapshot c = cube();
  EXPECT_TRUE(hiddenBySurface(o, c, {0.5, 2, 0.5}));    // behind it
  EXPECT_TRUE(hiddenBySurface(o, c, {0.3, 0.5, 0.6}));  // inside it
  EXPECT_TRUE(hiddenBySurface(o, c, {0.5, 1, 0.5}));    // on its far face
  EXPECT_FALSE(hiddenBySurface(o, c, {0.5, 0, 0.5}));   // on its near face: not by itself
  EXPECT_FALSE(hiddenBySurface(o, c, {0.5, -1, 0.5}));  // in front of it
  EXPECT_FALSE(hiddenBySurface(o, c, {0.5, 2, 1.5}));   // behind, but above it
  EXPECT_FALSE(hiddenBySurface(o, SurfaceSnapshot{}, {0.5, 2, 0.5}));  // nothing to hide it
}

TEST(ViewCheck, ACameraLookingAwaySeesNothing) {
  const ViewCheck v = checkView(camera({3, -4, 2.5f}, {6, -8, 4}), cube());
  EXPECT_FALSE(v.eyeInside);
  EXPECT_FALSE(v.seesSurface);
  EXPECT_EQ(v.verticesInView, 0);
}

// the eye 1 mm above the middle of a 1 m face: no vertex in the 35-degree view, the face
// fills it; the same camera turned to the horizon half sees it (the lower corners' rays)
TEST(ViewCheck, AFaceFillingTheViewIsSeenWithNoVertexInIt) {
  RenderOptions o = camera({0.5f, 0.5f, 1.001f}, {0.5f, 0.5f, 0});
  o.up = {0, 1, 0};  // (not along the view: the scenario refuses that)
  ViewCheck v = checkView(o, cube());
  EXPECT_FALSE(v.eyeInside);
  EXPECT_EQ(v.verticesInView, 0);
  EXPECT_TRUE(v.seesSurface);
  v = checkView(camera({0.5f, 0.5f, 1.001f}, {0.5f, 3, 1.001f}), cube());
  EXPECT_EQ(v.verticesInView, 0);
  EXPECT_TRUE(v.seesSurface);
}

// a point in the view: in front of the eye, within both half-angles (35 deg vertical, 16:9)
TEST(ViewCheck, APointIsInViewWithinTheFieldOfViewInFrontOfTheEye) {
  const RenderOptions o = camera({0, 0, 0}, {1, 0, 0});  // looking along +x, up +z
  EXPECT_TRUE(inView(o, {1, 0, 0}));
  EXPECT_FALSE(inView(o, {-1, 0, 0}));  // behind
  const double tanY = std::tan(17.5 * M_PI / 180.0), tanX = tanY * 1280 / 720;
  EXPECT_TRUE(inView(o, {1, 0, 0.99 * tanY}));   // just inside the top edge
  EXPECT_FALSE(inView(o, {1, 0, 1.01 * tanY}));  // just outside it
  EXPECT_TRUE(inView(o, {1, -0.99 * tanX, 0}));  // the right edge (right = -y here)
  EXPECT_FALSE(inView(o, {1, -1.01 * tanX, 0}));
}

}  // namespace
}  // namespace esim
