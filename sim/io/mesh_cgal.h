// mesh_cgal.h - the only door to CGAL (implemented in mesh_cgal.cpp, the single
// translation unit that includes CGAL headers, to bound build time and memory).
//
// Plain types in, plain types out; no CGAL header is included here. Callers
// (mesh_import.cpp) do the input checks and messages; these functions assume a
// closed, manifold, consistently oriented surface unless they say otherwise.
#pragma once

#include <array>
#include <cstddef>

#include "sim/io/mesh_import.h"

namespace esim::cgal {

// pairs of triangles that intersect other than in a shared vertex or edge
struct SelfIntersections {
  std::size_t pairCount = 0;         // number of intersecting pairs
  std::array<int, 2> first{-1, -1};  // the smallest pair (triangle ids, sorted)
};

// Self-intersection test (CGAL::Polygon_mesh_processing::self_intersections).
// Requires an edge- and vertex-manifold surface (throws esim::Error otherwise).
SelfIntersections findSelfIntersections(const SurfaceMesh& surface);

// Mesh_3 of the volume bounded by the surface: nodes [m] and tets with positive
// orientation, numbered in CGAL's (deterministic) iteration order, only nodes used
// by tets. Sizes must already be resolved (> 0). With options.refinement enabled, the
// cell, facet-size, facet-distance and edge bounds are sizing fields that shrink near
// the segment (already validated by the caller). Reseeds CGAL's default random.
TetMesh generateTets(const SurfaceMesh& surface, const MeshingOptions& options);

}  // namespace esim::cgal
