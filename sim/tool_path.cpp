// tool_path.cpp - keyframe interpolation of the tool pose and generator intervals.
#include "sim/tool_path.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "sim/core_error.h"

namespace esim {

namespace {

// index i of the segment [keys[i], keys[i+1]] holding t and the fraction in it;
// returns false (with i the clamped key) outside the keyed range or for one key
bool findSegment(const std::vector<ToolKeyframe>& keys, double t, size_t& i, double& frac) {
  ESIM_VERIFY(!keys.empty(), "tool path: no keyframes");
  if (keys.size() == 1 || !(t > keys.front().timeS)) {
    i = 0;
    return false;
  }
  if (t >= keys.back().timeS) {
    i = keys.size() - 1;
    return false;
  }
  // first key with time > t; the segment starts one before it
  auto it = std::upper_bound(keys.begin(), keys.end(), t,
                             [](double v, const ToolKeyframe& k) { return v < k.timeS; });
  i = static_cast<size_t>(it - keys.begin()) - 1;
  const double t0 = keys[i].timeS, t1 = keys[i + 1].timeS;
  frac = (t - t0) / (t1 - t0);
  return true;
}

}  // namespace

Vec3 ToolPath::positionAt(double timeS) const {
  size_t i = 0;
  double frac = 0;
  if (!findSegment(keys, timeS, i, frac)) return keys[i].positionM;
  return (1.0 - frac) * keys[i].positionM + frac * keys[i + 1].positionM;
}

Eigen::Quaterniond ToolPath::orientationAt(double timeS) const {
  size_t i = 0;
  double frac = 0;
  if (!findSegment(keys, timeS, i, frac)) return keys[i].orientation.normalized();
  return keys[i].orientation.slerp(frac, keys[i + 1].orientation).normalized();
}

ToolPose ToolPath::poseAt(double timeS) const {
  return ToolPose{positionAt(timeS), orientationAt(timeS)};
}

bool ToolPath::generatorOnAt(double timeS) const {
  for (const auto& [on, off] : generatorOnS)
    if (timeS >= on && timeS < off) return true;
  return false;
}

Eigen::Quaterniond eulerXyzDegToQuaternion(const Vec3& anglesDeg) {
  const double toRad = M_PI / 180.0;
  const Eigen::AngleAxisd rx(anglesDeg.x() * toRad, Vec3::UnitX());
  const Eigen::AngleAxisd ry(anglesDeg.y() * toRad, Vec3::UnitY());
  const Eigen::AngleAxisd rz(anglesDeg.z() * toRad, Vec3::UnitZ());
  return Eigen::Quaterniond(rz * ry * rx).normalized();
}

void validateToolPath(const ToolPath& path) {
  ESIM_VERIFY(!path.keys.empty(), "tool path: at least one keyframe is required");
  for (size_t i = 0; i < path.keys.size(); ++i) {
    const ToolKeyframe& k = path.keys[i];
    const std::string where = "tool path key " + std::to_string(i);
    ESIM_VERIFY(std::isfinite(k.timeS), where + ": time is not finite");
    ESIM_VERIFY(k.positionM.allFinite(), where + ": position is not finite");
    ESIM_VERIFY(std::abs(k.orientation.norm() - 1.0) < 1e-9,
                where + ": orientation is not a unit quaternion");
    if (i > 0)
      ESIM_VERIFY(k.timeS > path.keys[i - 1].timeS,
                  where + ": time " + std::to_string(k.timeS) + " s is not after the previous " +
                      std::to_string(path.keys[i - 1].timeS) + " s (times must strictly increase)");
  }
  for (size_t i = 0; i < path.generatorOnS.size(); ++i) {
    const auto& [on, off] = path.generatorOnS[i];
    const std::string where = "generator interval " + std::to_string(i);
    ESIM_VERIFY(std::isfinite(on) && !std::isnan(off), where + ": on time must be finite");
    ESIM_VERIFY(on < off, where + ": on time must be before off time");
    if (i > 0)
      ESIM_VERIFY(on >= path.generatorOnS[i - 1].second,
                  where + ": intervals must be sorted and must not overlap");
  }
}

}  // namespace esim
