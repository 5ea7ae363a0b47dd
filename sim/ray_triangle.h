// ray_triangle.h - where a ray crosses a triangle (Moller-Trumbore), on plain double[3]
// coordinates, so that the physics core's meshes (Eigen vectors) and the renderer's set-up
// checks (std::array) share one test. Header-only, no dependencies.
#pragma once

namespace esim {

// a direction that no symmetry of a box or a slab lies along: a ray from a point along it
// crosses a closed surface an odd number of times exactly when the point is inside
constexpr double kGenericRayDirection[3] = {0.5727, 0.6143, 0.5432};

// the parameter t of the point o + t d where the ray crosses triangle (a, b, c), or -1 when
// it misses it (or runs parallel to its plane); t may be negative (behind o)
inline double rayTriangleT(const double* o, const double* d, const double* a, const double* b,
                           const double* c) {
  const auto sub = [](const double* x, const double* y, double* r) {
    for (int k = 0; k < 3; ++k) r[k] = x[k] - y[k];
  };
  const auto cross = [](const double* x, const double* y, double* r) {
    r[0] = x[1] * y[2] - x[2] * y[1];
    r[1] = x[2] * y[0] - x[0] * y[2];
    r[2] = x[0] * y[1] - x[1] * y[0];
  };
  const auto dot = [](const double* x, const double* y) {
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
  };
  double e1[3], e2[3], p[3], s[3], q[3];
  sub(b, a, e1);
  sub(c, a, e2);
  cross(d, e2, p);
  const double det = dot(e1, p);
  if (det > -1e-30 && det < 1e-30) return -1;  // parallel to the triangle
  sub(o, a, s);
  const double u = dot(s, p) / det;
  if (u < 0 || u > 1) return -1;
  cross(s, e1, q);
  const double v = dot(d, q) / det;
  if (v < 0 || u + v > 1) return -1;
  return dot(e2, q) / det;
}

}  // namespace esim
