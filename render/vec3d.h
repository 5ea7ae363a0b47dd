// vec3d.h - the double-precision 3-vector helpers of the camera geometry that the label files
// publish (labels.cpp) and the set-up's view check (view_check.cpp) share. Internal to
// render/.
#pragma once

#include <array>
#include <cmath>

namespace esim::render_detail {

using D3 = std::array<double, 3>;

inline D3 sub(const D3& a, const D3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline double dot(const D3& a, const D3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline D3 cross(const D3& a, const D3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline D3 normalized(const D3& a) {
  const double n = std::sqrt(dot(a, a));
  return {a[0] / n, a[1] / n, a[2] / n};
}

}  // namespace esim::render_detail
