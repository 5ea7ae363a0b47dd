// surface_buffers.h - the surface's GPU vertex and index arrays, built from a SurfaceSnapshot.
//
// An indexed triangle list with crease-limited smooth normals: area-weighted face
// normals summed per corner over the incident faces within kCreaseAngleDeg
// (renderer.h; between two faces of a cut wall, kCutWallCreaseAngleDeg); a vertex is split only
// where its corners get different normals (creases), so a smooth surface keeps one GPU vertex per
// snapshot vertex. With cutWallNormalPasses > 0 the corners of cut-wall faces take instead a
// normal averaged over the wall (each vertex's over its wall faces, then that many passes of
// the mean with its neighbours'): the saw teeth removed tets leave are shaded as one wall and
// the rim where it meets the original surface stays a crease. With cutWallDamagePasses > 0
// the wall vertices' coagulation and desiccation are averaged over the wall (that many passes
// of each one's mean with its wall neighbours'), so the damage of the tets under a wall is
// drawn as a band, not as the teeth of their faces (display only: the snapshot keeps the
// per-vertex values; the labels, drawn from these arrays, follow the colours). Vertex
// format: vertex_layout.h; the state is (T [C] or, for the potential look, phi [V], coagulation,
// desiccation, cut wall), positions in metres. Reuse: while a snapshot's positions and triangles
// are bit-identical to the previous one's (no structural phase, or a frame without deformation) the
// normals and the crease splits are the same, and update() rewrites the state columns only.
// Ownership: SurfaceBuffers owns its arrays (and scratch space kept across frames); the renderer
// uploads them. Internal to render/: not used outside the renderer.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "render/view_math.h"
#include "sim/snapshot.h"

namespace esim::render_detail {

// the vertex state the shaders read: (T [C] or phi [V], coagulation, desiccation,
// cut wall); tDefaultC when the snapshot has no temperatures
std::array<float, 4> vertexState(const SurfaceSnapshot& snap, std::uint32_t v, float tDefaultC,
                                 bool potential);

// GPU vertex and index arrays of the surface, with what is needed to skip the
// geometry on the next frame
struct SurfaceBuffers {
  std::vector<float> vertices;         // kFloatsPerVertex per GPU vertex
  std::vector<std::uint32_t> indices;  // 3 per triangle
  std::vector<std::uint32_t> source;   // GPU vertex -> snapshot vertex
  std::vector<float> lastPositionsM;   // geometry the arrays were built from
  std::vector<std::uint32_t> lastTriangles;
  bool geometryReused = false;  // last update() rewrote the states only
  // scratch
  std::vector<V3> faceNormal, faceUnit, smoothNormal;
  std::vector<float> faceLength;
  std::vector<int> offsets, incident, firstCopy, nextCopy;
  std::vector<std::uint8_t> smooth, wallFace, hasWallNormal;
  std::vector<V3> wallNormal, wallNext;
  std::vector<int> wallStart, wallAdjacent;
  bool wallAdjacency = false;  // wallStart / wallAdjacent / hasWallNormal hold this geometry's
  std::vector<float> wallCoagulation, wallDesiccation, wallStateNext;
  // passes that average the cut walls' normals over their neighbours (RenderOptions::
  // cutWallNormalPasses; 0: each corner's own faces, up to kCutWallCreaseAngleDeg)
  int cutWallNormalPasses = 0;
  // passes that average the cut walls' coagulation and desiccation over their neighbours
  // (RenderOptions::cutWallDamagePasses; 0: each vertex's own)
  int cutWallDamagePasses = 0;

  // brings the arrays to the snapshot: the states only when the geometry is
  // unchanged, else build(); potential: the state's first entry is potentialV
  void update(const SurfaceSnapshot& snap, float tDefaultC, bool potential);
  // rebuilds normals, crease splits, vertices and indices from scratch
  void build(const SurfaceSnapshot& snap, float tDefaultC, bool potential);
  // build's step 3b: every vertex's normal over its wall faces (wallNormal, hasWallNormal) and
  // its neighbours through them (wallStart, wallAdjacent); wallAdjacency: done (false for no
  // passes of either kind, no wall, or only degenerate wall faces). Needs wallFace,
  // faceNormal, offsets and incident
  bool buildWallAdjacency(const SurfaceSnapshot& snap);
  // wallNormal averaged over its neighbours cutWallNormalPasses times; false (nothing done)
  // for 0 passes or no adjacency
  bool smoothCutWallNormals(const SurfaceSnapshot& snap);
  // the coagulation and desiccation of every vertex, those on a cut wall averaged over their
  // neighbours through wall faces cutWallDamagePasses times (wallCoagulation,
  // wallDesiccation); false (nothing done) for 0 passes, no adjacency or neither state. Run
  // by build and, on the kept geometry, by update
  bool smoothCutWallStates(const SurfaceSnapshot& snap);
  // a vertex's state with the averaged coagulation and desiccation
  void takeWallState(std::uint32_t v, std::array<float, 4>& state) const;
};

}  // namespace esim::render_detail
