// tool_mesh.h - the electrode's triangle mesh (blade or sphere, shaft, handle) and
// the sizes of its analytic shadow.
//
// The mesh is built in the tool frame: the tip (blade edge or sphere centre) at the
// origin, +z the axis from the tip to the handle, metres; the renderer places it
// with ToolSnapshot's pose. Blade: a rounded flat spatula widthM wide and 2 radiusM
// thick; sphere: a ball of radiusM on a thin neck; each on an insulated shaft ending
// at lengthM and a pencil handle. Non-indexed triangles in the vertex format of
// vertex_layout.h, the state being (albedo rgb, material id: 0 metal, 1 insulation,
// 2 handle). Ownership: plain values. Internal to render/: not used outside the renderer.
#pragma once

#include <vector>

#include "render/view_math.h"
#include "sim/snapshot.h"

namespace esim::render_detail {

constexpr float kHandleRadiusM = 0.0045f;  // pencil handle radius [m]
constexpr float kHandleLengthM = 0.09f;    // pencil handle length [m] (also in kSurfaceVs)

// the electrode's vertices in the tool frame (kFloatsPerVertex per vertex, 3 per triangle)
std::vector<float> buildToolVertices(const ToolSnapshot& tool);

// true if a and b have the same mesh (kind and sizes; the pose may differ)
bool sameToolShape(const ToolSnapshot& a, const ToolSnapshot& b);

// the shadow's capsules (uToolSizes): shaft length [m], shaft radius [m], handle radius [m]
V3 toolShadowSizes(const ToolSnapshot& tool);

}  // namespace esim::render_detail
