// tool_path.h - the scripted electrosurgical tool: pose over time and generator bursts.
//
// A ToolPath is a list of keyframes (time [s], tip position [m], orientation) and the
// intervals [tOnS, tOffS) during which the generator is on. Between keyframes the tip
// moves linearly and the orientation is interpolated by slerp (shortest arc, constant
// angular speed); before the first and after the last keyframe the pose is held (clamped).
//
// Orientation convention (shared with SurfaceSnapshot/ToolSnapshot): the tool's local
// +z is its axis pointing from the tip to the handle, local x is the blade's width.
// The identity orientation points the axis straight up (+z world).
// Euler angles [rx, ry, rz] in degrees (the scenario's `orientation_deg`) are rotations
// about the FIXED world axes applied in the order x, then y, then z:
//     R = Rz(rz) * Ry(ry) * Rx(rx),   axis = R * (0, 0, 1).
// E.g. [30, 0, 0] tilts the axis from +z toward -y by 30 degrees.
//
// Plain data owned by value; no file formats here (the YAML loader lives in sim/io).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <utility>
#include <vector>

#include "sim/electrode.h"  // ToolPose {tipM, orientation}
#include "sim/mesh_tet.h"

namespace esim {

struct ToolKeyframe {
  double timeS = 0;                                                 // [s]
  Vec3 positionM = Vec3::Zero();                                    // tool tip [m]
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // local -> world
};

struct ToolPath {
  std::vector<ToolKeyframe> keys;                       // strictly increasing timeS, >= 1
  std::vector<std::pair<double, double>> generatorOnS;  // sorted disjoint [on, off) [s]

  // tip position at time t [s] (linear between keys, clamped outside)
  Vec3 positionAt(double timeS) const;
  // orientation at time t [s] (slerp between keys, clamped outside), unit quaternion
  Eigen::Quaterniond orientationAt(double timeS) const;
  // both at once, as the electrode code takes them (sim/electrode.h)
  ToolPose poseAt(double timeS) const;
  // true when t lies in some interval [on, off); an empty list means never on
  bool generatorOnAt(double timeS) const;
};

// rotation R = Rz(rz) Ry(ry) Rx(rx) from [rx, ry, rz] in degrees (see the header comment)
Eigen::Quaterniond eulerXyzDegToQuaternion(const Vec3& anglesDeg);

// throws esim::Error unless: >= 1 key, finite strictly increasing times, finite positions,
// unit quaternions, and sorted disjoint generator intervals with on < off
void validateToolPath(const ToolPath& path);

}  // namespace esim
