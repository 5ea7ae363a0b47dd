// view_check.cpp - see view_check.h. The camera is the one the label files publish
// (render/labels.h's CameraModel: the renderer's lookAt and perspective in double).
#include "render/view_check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "render/labels.h"
#include "render/vec3d.h"
#include "sim/ray_triangle.h"

namespace esim {
namespace {

using render_detail::D3;
using render_detail::dot;
using render_detail::sub;

// the ray eye + t d crosses triangle (a, b, c) at t in (0, tMax)
bool rayHits(const D3& eye, const D3& d, const D3& a, const D3& b, const D3& c,
             double tMax = INFINITY) {
  const double t = rayTriangleT(eye.data(), d.data(), a.data(), b.data(), c.data());
  return t > 0 && t < tMax;
}

D3 vertexOf(const SurfaceSnapshot& snap, std::uint32_t v) {
  return D3{snap.positionsM[3 * v], snap.positionsM[3 * v + 1], snap.positionsM[3 * v + 2]};
}

// p's pixel within the frame, in front of the eye
bool sees(const CameraModel& c, const D3& p) {
  const D3 px = projectToPixel(c, p);
  return px[2] > 0 && px[0] >= -0.5 && px[0] <= c.width - 0.5 && px[1] >= -0.5 &&
         px[1] <= c.height - 0.5;
}

// the world direction through pixel (u, v) (the camera's rotation rows: right, down, forward)
D3 rayThrough(const CameraModel& c, double u, double v) {
  const double x = (u - c.cx) / c.fx, y = (v - c.cy) / c.fy;
  const auto& r = c.rotation;
  return {r[0] * x + r[3] * y + r[6], r[1] * x + r[4] * y + r[7], r[2] * x + r[5] * y + r[8]};
}

}  // namespace

bool inView(const RenderOptions& o, const std::array<double, 3>& p) {
  return sees(cameraModel(o), p);
}

bool hiddenBySurface(const RenderOptions& o, const SurfaceSnapshot& snap,
                     const std::array<double, 3>& p) {
  const D3 eye = cameraModel(o).eyeM;
  const D3 d = sub(D3{p[0], p[1], p[2]}, eye);
  // short of p by a micrometre: a point on the surface is not hidden by itself
  const double tMax = 1 - 1e-6 / std::max(1e-12, std::sqrt(dot(d, d)));
  for (int t = 0; t < snap.numTriangles(); ++t) {
    const std::uint32_t* tri = &snap.triangles[3 * t];
    if (rayHits(eye, d, vertexOf(snap, tri[0]), vertexOf(snap, tri[1]), vertexOf(snap, tri[2]),
                tMax))
      return true;
  }
  return false;
}

ViewCheck checkView(const RenderOptions& o, const SurfaceSnapshot& snap) {
  ViewCheck r;
  const CameraModel cam = cameraModel(o);
  const D3& eye = cam.eyeM;
  const auto vertex = [&snap](int v) { return vertexOf(snap, static_cast<std::uint32_t>(v)); };
  for (int v = 0; v < snap.numVertices(); ++v) r.verticesInView += sees(cam, vertex(v));
  // rays: the generic direction for the parity, then the view's centre and corners
  const D3 generic{kGenericRayDirection[0], kGenericRayDirection[1], kGenericRayDirection[2]};
  const double w = cam.width - 0.5, h = cam.height - 0.5;
  const std::array<D3, 5> view{rayThrough(cam, cam.cx, cam.cy), rayThrough(cam, -0.5, -0.5),
                               rayThrough(cam, w, -0.5), rayThrough(cam, -0.5, h),
                               rayThrough(cam, w, h)};
  int crossings = 0;
  bool viewRayHits = false;
  for (int t = 0; t < snap.numTriangles(); ++t) {
    const D3 a = vertex(static_cast<int>(snap.triangles[3 * t]));
    const D3 b = vertex(static_cast<int>(snap.triangles[3 * t + 1]));
    const D3 c = vertex(static_cast<int>(snap.triangles[3 * t + 2]));
    crossings += rayHits(eye, generic, a, b, c);
    for (const D3& d : view)
      if (!viewRayHits && rayHits(eye, d, a, b, c)) viewRayHits = true;
  }
  r.eyeInside = crossings % 2 == 1;
  r.seesSurface = !r.eyeInside && (r.verticesInView > 0 || viewRayHits);
  return r;
}

}  // namespace esim
