// tool_path_test.cpp - keyframe interpolation, clamping, slerp, generator intervals, Euler
// convention and validation of sim/tool_path.h.
#include "sim/tool_path.h"

#include <gtest/gtest.h>

#include <cmath>

#include "sim/core_error.h"

namespace esim {
namespace {

ToolPath twoKeyPath() {
  ToolPath p;
  p.keys.push_back({1.0, Vec3(-0.035, 0.0, 0.0098), Eigen::Quaterniond::Identity()});
  p.keys.push_back({3.0, Vec3(0.035, 0.01, 0.0098), eulerXyzDegToQuaternion(Vec3(0, 90, 0))});
  return p;
}

TEST(ToolPath, LinearPositionBetweenKeys) {
  const ToolPath p = twoKeyPath();
  const Vec3 mid = p.positionAt(2.0);
  EXPECT_NEAR(mid.x(), 0.0, 1e-15);
  EXPECT_NEAR(mid.y(), 0.005, 1e-15);
  EXPECT_NEAR(mid.z(), 0.0098, 1e-15);
  const Vec3 quarter = p.positionAt(1.5);
  EXPECT_NEAR(quarter.x(), -0.0175, 1e-15);
  EXPECT_NEAR(quarter.y(), 0.0025, 1e-15);
}

TEST(ToolPath, ClampedOutsideTheKeyedRange) {
  const ToolPath p = twoKeyPath();
  EXPECT_EQ(p.positionAt(-5.0), p.keys[0].positionM);
  EXPECT_EQ(p.positionAt(1.0), p.keys[0].positionM);
  EXPECT_EQ(p.positionAt(3.0), p.keys[1].positionM);
  EXPECT_EQ(p.positionAt(100.0), p.keys[1].positionM);
  EXPECT_NEAR(p.orientationAt(100.0).angularDistance(p.keys[1].orientation), 0.0, 1e-12);
  EXPECT_NEAR(p.orientationAt(0.0).angularDistance(Eigen::Quaterniond::Identity()), 0.0, 1e-12);
}

TEST(ToolPath, SingleKeyIsHeld) {
  ToolPath p;
  p.keys.push_back({0.5, Vec3(0.01, 0.02, 0.03), eulerXyzDegToQuaternion(Vec3(10, 20, 30))});
  for (double t : {0.0, 0.5, 7.0}) {
    EXPECT_EQ(p.positionAt(t), Vec3(0.01, 0.02, 0.03));
    EXPECT_NEAR(p.orientationAt(t).angularDistance(p.keys[0].orientation), 0.0, 1e-12);
  }
}

TEST(ToolPath, SlerpHasConstantAngularSpeed) {
  const ToolPath p = twoKeyPath();  // 0 -> 90 degrees about y over 2 s
  for (double frac : {0.1, 0.25, 0.5, 0.9}) {
    const Eigen::Quaterniond q = p.orientationAt(1.0 + 2.0 * frac);
    EXPECT_NEAR(q.norm(), 1.0, 1e-14);
    EXPECT_NEAR(q.angularDistance(Eigen::Quaterniond::Identity()), frac * M_PI / 2, 1e-12);
    // the axis stays in the x-z plane, tilting from +z toward +x
    const ToolPose pose = p.poseAt(1.0 + 2.0 * frac);
    EXPECT_EQ(pose.tipM, p.positionAt(1.0 + 2.0 * frac));
    const Vec3 axis = pose.orientation * Vec3::UnitZ();
    EXPECT_NEAR(axis.y(), 0.0, 1e-14);
    EXPECT_NEAR(axis.x(), std::sin(frac * M_PI / 2), 1e-12);
    EXPECT_NEAR(axis.z(), std::cos(frac * M_PI / 2), 1e-12);
  }
}

TEST(ToolPath, SlerpTakesTheShortArc) {
  ToolPath p;
  p.keys.push_back({0.0, Vec3::Zero(), eulerXyzDegToQuaternion(Vec3(0, 0, 170))});
  p.keys.push_back({1.0, Vec3::Zero(), eulerXyzDegToQuaternion(Vec3(0, 0, -170))});
  // 20 degrees apart through 180, never through 0
  const Eigen::Quaterniond mid = p.orientationAt(0.5);
  EXPECT_NEAR(mid.angularDistance(eulerXyzDegToQuaternion(Vec3(0, 0, 180))), 0.0, 1e-12);
}

TEST(ToolPath, EulerConventionIsFixedAxesXyz) {
  // identity: axis straight up
  EXPECT_NEAR((eulerXyzDegToQuaternion(Vec3::Zero()) * Vec3::UnitZ() - Vec3::UnitZ()).norm(), 0,
              1e-15);
  // [30, 0, 0] tilts the axis toward -y
  const Vec3 a = eulerXyzDegToQuaternion(Vec3(30, 0, 0)) * Vec3::UnitZ();
  EXPECT_NEAR(a.x(), 0.0, 1e-15);
  EXPECT_NEAR(a.y(), -0.5, 1e-15);
  EXPECT_NEAR(a.z(), std::sqrt(3.0) / 2, 1e-15);
  // R = Rz Ry Rx: x first. [90, 0, 90]: z -> -y (by Rx) -> +x (by Rz)
  const Vec3 b = eulerXyzDegToQuaternion(Vec3(90, 0, 90)) * Vec3::UnitZ();
  EXPECT_NEAR((b - Vec3::UnitX()).norm(), 0.0, 1e-15);
  // the other order would give a different result: Rx after Rz maps z -> -y
  const Eigen::Quaterniond wrongOrder =
      Eigen::AngleAxisd(M_PI / 2, Vec3::UnitX()) * Eigen::AngleAxisd(M_PI / 2, Vec3::UnitZ());
  EXPECT_GT((wrongOrder * Vec3::UnitZ() - b).norm(), 1.0);
}

TEST(ToolPath, GeneratorIntervalsAreHalfOpen) {
  ToolPath p = twoKeyPath();
  p.generatorOnS = {{0.5, 1.0}, {2.0, 2.5}};
  EXPECT_FALSE(p.generatorOnAt(0.49));
  EXPECT_TRUE(p.generatorOnAt(0.5));
  EXPECT_TRUE(p.generatorOnAt(0.99));
  EXPECT_FALSE(p.generatorOnAt(1.0));
  EXPECT_FALSE(p.generatorOnAt(1.5));
  EXPECT_TRUE(p.generatorOnAt(2.2));
  EXPECT_FALSE(p.generatorOnAt(2.5));
  p.generatorOnS = {{0.0, std::numeric_limits<double>::infinity()}};
  EXPECT_TRUE(p.generatorOnAt(0.0));
  EXPECT_TRUE(p.generatorOnAt(1e9));
  p.generatorOnS.clear();
  EXPECT_FALSE(p.generatorOnAt(1.0));
}

TEST(ToolPath, ValidationRejectsBadPaths) {
  ToolPath ok = twoKeyPath();
  EXPECT_NO_THROW(validateToolPath(ok));

  ToolPath empty;
  EXPECT_THROW(validateToolPath(empty), Error);

  ToolPath backwards = twoKeyPath();
  backwards.keys[1].timeS = 1.0;  // equal time
  try {
    validateToolPath(backwards);
    FAIL() << "equal times accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("strictly increase"), std::string::npos) << e.what();
  }

  ToolPath overlap = twoKeyPath();
  overlap.generatorOnS = {{0.0, 2.0}, {1.0, 3.0}};
  EXPECT_THROW(validateToolPath(overlap), Error);

  ToolPath reversed = twoKeyPath();
  reversed.generatorOnS = {{2.0, 1.0}};
  EXPECT_THROW(validateToolPath(reversed), Error);

  ToolPath nonUnit = twoKeyPath();
  nonUnit.keys[0].orientation = Eigen::Quaterniond(2, 0, 0, 0);
  EXPECT_THROW(validateToolPath(nonUnit), Error);
}

}  // namespace
}  // namespace esim
