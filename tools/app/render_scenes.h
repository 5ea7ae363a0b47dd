// render_scenes.h - analytic SurfaceSnapshots for the renderer benchmark and samples.
//
// Surfaces: the slab's boundary (makeSlab + boundaryFaces, compacted to the
// boundary nodes), an icosphere, and a surface file (e.g. assets/liver.obj).
// Fields: an analytic cut along a line on the slab's top face: a hot Gaussian
// trail behind the tool and a hot spot at the tip, coagulation and drying where
// the trail's peak temperature was high, and a shallow groove with cut walls.
// Units: metres, deg C, seconds. Everything is deterministic.
#pragma once

#include <array>
#include <string>

#include "sim/mesh_slab.h"
#include "sim/snapshot.h"

namespace esim::app {

// boundary surface of the slab with per-vertex fields at 37 C (body temperature)
SurfaceSnapshot slabSurface(const SlabSpec& spec);

// icosphere of the given radius and subdivision level (20 * 4^level triangles)
SurfaceSnapshot icosphereSurface(double radiusM, int level, std::array<double, 3> centreM);

// a closed surface file read with sim/io (assets/liver.obj), fields at 37 C
SurfaceSnapshot fileSurface(const std::string& path);

// the analytic cut: tool moving along +x at y = 0 on the top face z = topZ
struct AnalyticCut {
  double startXM = -0.035;  // where the cut began [m]
  double tipXM = 0.010;     // where the tool is now [m]
  double topZM = 0.010;     // top face height [m]
  double grooveDepthM = 0.0012;
  double grooveSigmaM = 0.0008;
};

// fills temperature, coagulation, desiccation, cutWall and displaces the top
// face into a groove; sets the tool (blade, handle trailing) at the tip
void applyAnalyticCut(const AnalyticCut& cut, double timeS, SurfaceSnapshot& snap);

// unit quaternion (w, x, y, z) of the frame whose +z is `axis` and whose +x is
// the world x direction made perpendicular to it
std::array<float, 4> toolOrientation(std::array<double, 3> axis);

}  // namespace esim::app
