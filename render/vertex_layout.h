// vertex_layout.h - the interleaved vertex format of the surface and electrode buffers.
//
// Each GPU vertex is kFloatsPerVertex floats: position [m] (3), unit normal (3) and
// a state (4) that the surface shaders read per look: (T [C] or phi [V],
// coagulation, desiccation, cut wall) for the tissue, (albedo rgb, material id) for
// the electrode. Attribute locations 0, 1, 2 of the vertex arrays (renderer.cpp).
// Ownership: pushVertex appends to the caller's vector. Internal to render/: not used
// outside the renderer.
#pragma once

#include <array>
#include <vector>

#include "render/view_math.h"

namespace esim::render_detail {

constexpr int kFloatsPerVertex = 10;  // position 3, normal 3, state 4
constexpr int kNormalOffset = 3;      // first normal float within a vertex
constexpr int kStateOffset = 6;       // first state float within a vertex

// appends one vertex (position, normal, state) to out
inline void pushVertex(std::vector<float>& out, V3 p, V3 n, const std::array<float, 4>& s) {
  out.insert(out.end(), {p[0], p[1], p[2], n[0], n[1], n[2], s[0], s[1], s[2], s[3]});
}

}  // namespace esim::render_detail
