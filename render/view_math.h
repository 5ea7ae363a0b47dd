// view_math.h - the small float vector and 4x4 matrix helpers of the renderer.
//
// V3 is a 3-vector (positions in metres, or unit directions); M4 a 4x4 matrix
// stored column-major, as OpenGL's glUniformMatrix4fv wants it (element (row r,
// column c) at [c * 4 + r]). Inline, float arithmetic only (the build forbids FMA
// contraction, so the bits are the same in every translation unit).
// Ownership: plain values in and out. Internal to render/: not used outside the renderer.
#pragma once

#include <array>
#include <cmath>

namespace esim::render_detail {

using V3 = std::array<float, 3>;
using M4 = std::array<float, 16>;

// the 4x4 identity
inline constexpr M4 kIdentityM4{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

// a - b
inline V3 sub(V3 a, V3 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
// a + b
inline V3 add(V3 a, V3 b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
// a * s
inline V3 mul(V3 a, float s) { return {a[0] * s, a[1] * s, a[2] * s}; }
// scalar product
inline float dot(V3 a, V3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
// vector product a x b
inline V3 cross(V3 a, V3 b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
// Euclidean length
inline float norm(V3 a) { return std::sqrt(dot(a, a)); }
// a / |a|, or +z for the zero vector
inline V3 normalized(V3 a) {
  const float n = norm(a);
  return n > 0 ? mul(a, 1.0f / n) : V3{0, 0, 1};
}

// matrix product a * b
inline M4 matMul(const M4& a, const M4& b) {
  M4 r{};
  for (int c = 0; c < 4; ++c)
    for (int rr = 0; rr < 4; ++rr) {
      float s = 0;
      for (int k = 0; k < 4; ++k) s += a[k * 4 + rr] * b[c * 4 + k];
      r[c * 4 + rr] = s;
    }
  return r;
}

// view matrix of a camera at eye looking at target (gluLookAt)
inline M4 lookAt(V3 eye, V3 target, V3 up) {
  const V3 f = normalized(sub(target, eye));
  const V3 s = normalized(cross(f, up));
  const V3 u = cross(s, f);
  // clang-format off
  return {s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0,
          -dot(s, eye), -dot(u, eye), dot(f, eye), 1};
  // clang-format on
}

// projection matrix: vertical field of view [deg], width/height, clip planes [m]
inline M4 perspective(float fovYDeg, float aspect, float nearM, float farM) {
  const float f = 1.0f / std::tan(fovYDeg * 3.14159265358979f / 360.0f);
  M4 m{};
  m[0] = f / aspect;
  m[5] = f;
  m[10] = (farM + nearM) / (nearM - farM);
  m[11] = -1;
  m[14] = 2 * farM * nearM / (nearM - farM);
  return m;
}

// rotation by a unit quaternion (w,x,y,z) then translation, as a 4x4
inline M4 poseMatrix(const std::array<float, 4>& q, V3 t) {
  float w = q[0], x = q[1], y = q[2], z = q[3];
  const float n = std::sqrt(w * w + x * x + y * y + z * z);
  // clang-format off
  if (n > 0) { w /= n; x /= n; y /= n; z /= n; } else { w = 1; }
  return {1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y), 0,
          2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x), 0,
          2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y), 0,
          t[0], t[1], t[2], 1};
  // clang-format on
}

}  // namespace esim::render_detail
