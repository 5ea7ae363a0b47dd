// snapshot.h - SurfaceSnapshot: the plain data the renderer draws.
//
// Filled by the simulation after each frame (sim/snapshot_build.*), read by
// render/. It holds copies, never pointers into solver state, so that a renderer
// or encoder thread may keep it while the physics moves on. Units: metres,
// degrees Celsius, seconds. Per-vertex arrays have one entry per vertex.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace esim {

enum class ElectrodeKind : int { Blade = 0, Sphere = 1 };  // the order of tool.shape's names

struct ToolSnapshot {
  bool present = false;      // draw the electrode at all
  bool generatorOn = false;  // current flowing this frame
  ElectrodeKind kind = ElectrodeKind::Blade;
  std::array<float, 3> tipM{0, 0, 0};                // tip position [m]
  std::array<float, 4> orientationWxyz{1, 0, 0, 0};  // local +z = tool axis, tip to handle
  float radiusM = 0.0005f;  // sphere radius or blade edge half-thickness [m]
  float lengthM = 0.02f;    // shaft/blade length along the axis [m]
  float widthM = 0.003f;    // blade width (local x) [m]
};

struct SurfaceSnapshot {
  int frame = 0;
  double timeS = 0;                      // simulated time [s]
  std::vector<float> positionsM;         // 3 per vertex, displaced positions [m]
  std::vector<std::uint32_t> triangles;  // 3 per triangle, counter-clockwise seen from outside
  std::vector<float> temperatureC;       // per vertex [C]
  std::vector<float> coagulation;        // per vertex, thermal damage fraction [0,1]
  std::vector<float> desiccation;        // per vertex, vaporized water fraction [0,1]
  std::vector<float> cutWall;            // per vertex, 1 on surfaces exposed by removal [0,1]
  std::vector<float> potentialV;         // per vertex electric potential [V]; empty without
                                         // the electric phase
  ToolSnapshot tool;

  int numVertices() const { return static_cast<int>(positionsM.size() / 3); }
  int numTriangles() const { return static_cast<int>(triangles.size() / 3); }
};

}  // namespace esim
