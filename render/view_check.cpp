// view_check.cpp - see view_check.h
#include "render/view_check.h"

#include <array>
#include <cmath>

namespace esim {
namespace {

using D3 = std::array<double, 3>;

D3 sub(const D3& a, const D3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const D3& a, const D3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
D3 cross(const D3& a, const D3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
D3 unit(const D3& a) {
  const double n = std::sqrt(dot(a, a));
  return n > 0 ? D3{a[0] / n, a[1] / n, a[2] / n} : D3{0, 0, 1};
}
D3 along(const D3& a, const D3& b, const D3& c, double x, double y, double z) {
  return {a[0] * x + b[0] * y + c[0] * z, a[1] * x + b[1] * y + c[1] * z,
          a[2] * x + b[2] * y + c[2] * z};
}

// the ray eye + t d (t > 0) crosses triangle (a, b, c) (Moller-Trumbore)
bool rayHits(const D3& eye, const D3& d, const D3& a, const D3& b, const D3& c) {
  const D3 e1 = sub(b, a), e2 = sub(c, a);
  const D3 p = cross(d, e2);
  const double det = dot(e1, p);
  if (std::abs(det) < 1e-30) return false;  // parallel to the triangle
  const D3 s = sub(eye, a);
  const double u = dot(s, p) / det;
  if (u < 0 || u > 1) return false;
  const D3 q = cross(s, e1);
  const double v = dot(d, q) / det;
  if (v < 0 || u + v > 1) return false;
  return dot(e2, q) / det > 0;
}

// the camera's frame: eye, forward, right, up, and the half-angles' tangents
struct Camera {
  D3 eye, fwd, right, up;
  double tanX, tanY;
  explicit Camera(const RenderOptions& o) {
    eye = {o.eyeM[0], o.eyeM[1], o.eyeM[2]};
    fwd = unit(sub({o.targetM[0], o.targetM[1], o.targetM[2]}, eye));
    right = unit(cross(fwd, {o.up[0], o.up[1], o.up[2]}));
    up = cross(right, fwd);
    tanY = std::tan(o.fovDeg * M_PI / 360.0);
    tanX = tanY * o.width / o.height;
  }
  bool sees(const D3& point) const {
    const D3 p = sub(point, eye);
    const double z = dot(p, fwd);
    return z > 0 && std::abs(dot(p, right)) <= z * tanX && std::abs(dot(p, up)) <= z * tanY;
  }
};

}  // namespace

bool inView(const RenderOptions& o, const std::array<double, 3>& p) { return Camera(o).sees(p); }

ViewCheck checkView(const RenderOptions& o, const SurfaceSnapshot& snap) {
  ViewCheck r;
  const Camera cam(o);
  const D3& eye = cam.eye;
  const D3 &fwd = cam.fwd, &right = cam.right, &camUp = cam.up;
  const double tanX = cam.tanX, tanY = cam.tanY;
  const auto vertex = [&snap](int v) {
    return D3{snap.positionsM[3 * v], snap.positionsM[3 * v + 1], snap.positionsM[3 * v + 2]};
  };
  for (int v = 0; v < snap.numVertices(); ++v) r.verticesInView += cam.sees(vertex(v));
  // rays: a generic direction for the parity (no symmetry of a box or a slab lies along it),
  // then the view's centre and corners
  const D3 generic = unit({0.5727, 0.6143, 0.5432});
  const std::array<D3, 5> view{
      fwd, along(right, camUp, fwd, tanX, tanY, 1), along(right, camUp, fwd, -tanX, tanY, 1),
      along(right, camUp, fwd, tanX, -tanY, 1), along(right, camUp, fwd, -tanX, -tanY, 1)};
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
