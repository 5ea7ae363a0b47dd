// surface_buffers.cpp - crease-limited smooth normals and the surface's GPU arrays
// (see surface_buffers.h).
#include "render/surface_buffers.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>

#include "render/renderer.h"
#include "render/vertex_layout.h"

namespace esim::render_detail {

std::array<float, 4> vertexState(const SurfaceSnapshot& snap, std::uint32_t v, float tDefaultC,
                                 bool potential) {
  return {potential ? snap.potentialV[v]
                    : (snap.temperatureC.empty() ? tDefaultC : snap.temperatureC[v]),
          snap.coagulation.empty() ? 0.0f : snap.coagulation[v],
          snap.desiccation.empty() ? 0.0f : snap.desiccation[v],
          snap.cutWall.empty() ? 0.0f : snap.cutWall[v]};
}

void SurfaceBuffers::update(const SurfaceSnapshot& snap, float tDefaultC, bool potential) {
  geometryReused =
      !vertices.empty() && snap.positionsM == lastPositionsM && snap.triangles == lastTriangles;
  if (!geometryReused) {
    build(snap, tDefaultC, potential);
    lastPositionsM = snap.positionsM;
    lastTriangles = snap.triangles;
    return;
  }
  const bool wallStates = smoothCutWallStates(snap);
  for (size_t c = 0; c < source.size(); ++c) {
    std::array<float, 4> s = vertexState(snap, source[c], tDefaultC, potential);
    if (wallStates) takeWallState(source[c], s);
    std::memcpy(&vertices[c * kFloatsPerVertex + kStateOffset], s.data(), sizeof s);
  }
}

void SurfaceBuffers::build(const SurfaceSnapshot& snap, float tDefaultC, bool potential) {
  std::vector<float>& out = vertices;
  const int nv = snap.numVertices();
  const int nt = snap.numTriangles();
  const float* P = snap.positionsM.data();
  auto pos = [&](std::uint32_t v) { return V3{P[3 * v], P[3 * v + 1], P[3 * v + 2]}; };
  // 1. area-weighted face normals (|cross| = 2 area)
  faceNormal.resize(nt);
  faceLength.resize(nt);
  for (int t = 0; t < nt; ++t) {
    const std::uint32_t* tri = &snap.triangles[3 * t];
    faceNormal[t] = cross(sub(pos(tri[1]), pos(tri[0])), sub(pos(tri[2]), pos(tri[0])));
    faceLength[t] = norm(faceNormal[t]);
  }
  // 2. vertex -> incident triangles (CSR, ascending triangle ids)
  offsets.assign(nv + 1, 0);
  for (std::uint32_t v : snap.triangles) ++offsets[v + 1];
  for (int v = 0; v < nv; ++v) offsets[v + 1] += offsets[v];
  incident.resize(snap.triangles.size());
  std::vector<int> fill(offsets.begin(), offsets.end() - 1);
  for (int t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) incident[fill[snap.triangles[3 * t + k]]++] = t;
  // 3. per corner: sum of the incident face normals within the crease angle; corners
  //    of a vertex with bit-identical normals share one GPU vertex (the sums run over
  //    the same faces in the same order, so equal face sets give equal bits)
  const float cosCrease = static_cast<float>(std::cos(kCreaseAngleDeg * 3.14159265358979 / 180.0));
  out.clear();
  source.clear();
  out.reserve(static_cast<size_t>(nv) * kFloatsPerVertex * 5 / 4);
  indices.resize(snap.triangles.size());
  firstCopy.assign(nv, -1);  // first GPU vertex of each snapshot vertex
  nextCopy.clear();          // chain of further copies (crease splits)
  // normalized(faceNormal[t]) with the stored length (the same bits)
  faceUnit.resize(nt);
  for (int t = 0; t < nt; ++t)
    faceUnit[t] = faceLength[t] > 0 ? mul(faceNormal[t], 1.0f / faceLength[t]) : V3{0, 0, 1};
  // the corner's test: face g joins the sum of the corner of face t
  // faces of the cut walls (every corner at cutWall >= 0.5) join each other up to the wider
  // kCutWallCreaseAngleDeg
  wallFace.assign(nt, 0);
  if (!snap.cutWall.empty())
    for (int t = 0; t < nt; ++t) {
      const std::uint32_t* tri = &snap.triangles[3 * t];
      wallFace[t] = snap.cutWall[tri[0]] >= 0.5f && snap.cutWall[tri[1]] >= 0.5f &&
                    snap.cutWall[tri[2]] >= 0.5f;
    }
  const float cosWall =
      static_cast<float>(std::cos(kCutWallCreaseAngleDeg * 3.14159265358979 / 180.0));
  auto joins = [&](int g, int t) {
    const float c = wallFace[g] && wallFace[t] ? cosWall : cosCrease;
    return faceLength[g] > 0 && dot(faceNormal[g], faceUnit[t]) >= c * faceLength[g];
  };
  // 3a. smooth vertices (most): every incident face joins every corner's sum, so all
  //     corners get the same sum over the same faces in the same order; it is formed
  //     and normalised once (the same bits as per corner)
  smoothNormal.resize(nv);
  smooth.assign(nv, 0);
  for (int v = 0; v < nv; ++v) {
    bool all = true;
    for (int i = offsets[v]; i < offsets[v + 1] && all; ++i)
      for (int j = offsets[v]; j < offsets[v + 1] && all; ++j)
        all = joins(incident[j], incident[i]);
    if (!all) continue;
    V3 sum{0, 0, 0};
    for (int i = offsets[v]; i < offsets[v + 1]; ++i) sum = add(sum, faceNormal[incident[i]]);
    if (norm(sum) > 0) {
      smoothNormal[v] = normalized(sum);
      smooth[v] = 1;
    }
  }
  // 3b. the cut walls' normals, averaged over their neighbours (the corners of wall faces
  //     take them), and their vertices' damage averaged the same way (see surface_buffers.h)
  buildWallAdjacency(snap);
  const bool wallNormals = smoothCutWallNormals(snap);
  const bool wallStates = smoothCutWallStates(snap);
  // 3c. per corner
  for (int t = 0; t < nt; ++t) {
    const V3& nf = faceUnit[t];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = snap.triangles[3 * t + k];
      V3 n = smoothNormal[v];
      if (wallNormals && wallFace[t] && hasWallNormal[v]) {
        n = wallNormal[v];
      } else if (!smooth[v]) {
        V3 sum{0, 0, 0};
        for (int i = offsets[v]; i < offsets[v + 1]; ++i)
          if (joins(incident[i], t)) sum = add(sum, faceNormal[incident[i]]);
        n = norm(sum) > 0 ? normalized(sum) : nf;
      }
      int found = -1;
      int* link = &firstCopy[v];
      for (int c = *link; c >= 0; link = &nextCopy[c], c = *link) {
        const float* q = &out[static_cast<size_t>(c) * kFloatsPerVertex + kNormalOffset];
        if (q[0] == n[0] && q[1] == n[1] && q[2] == n[2]) {
          found = c;
          break;
        }
      }
      if (found < 0) {
        found = static_cast<int>(nextCopy.size());
        *link = found;
        nextCopy.push_back(-1);
        std::array<float, 4> state = vertexState(snap, v, tDefaultC, potential);
        if (wallStates) takeWallState(v, state);
        pushVertex(out, pos(v), n, state);
        source.push_back(v);
      }
      indices[3 * t + k] = static_cast<std::uint32_t>(found);
    }
  }
}

bool SurfaceBuffers::buildWallAdjacency(const SurfaceSnapshot& snap) {
  wallAdjacency = false;
  if ((cutWallNormalPasses <= 0 && cutWallDamagePasses <= 0) ||
      std::none_of(wallFace.begin(), wallFace.end(), [](std::uint8_t w) { return w != 0; }))
    return false;
  const int nv = snap.numVertices();
  // each vertex's normal over its wall faces (area-weighted), and its neighbours through
  // them (CSR, ascending: the sums below run in a fixed order)
  wallNormal.assign(nv, V3{0, 0, 0});
  hasWallNormal.assign(nv, 0);
  wallStart.assign(nv + 1, 0);
  wallAdjacent.clear();
  bool any = false;
  for (int v = 0; v < nv; ++v) {
    const std::size_t first = wallAdjacent.size();
    for (int i = offsets[v]; i < offsets[v + 1]; ++i) {
      const int t = incident[i];
      if (!wallFace[t]) continue;
      wallNormal[v] = add(wallNormal[v], faceNormal[t]);
      for (int k = 0; k < 3; ++k) {
        const int w = static_cast<int>(snap.triangles[3 * t + k]);
        if (w != v) wallAdjacent.push_back(w);
      }
    }
    std::sort(wallAdjacent.begin() + static_cast<std::ptrdiff_t>(first), wallAdjacent.end());
    wallAdjacent.erase(
        std::unique(wallAdjacent.begin() + static_cast<std::ptrdiff_t>(first), wallAdjacent.end()),
        wallAdjacent.end());
    wallStart[v + 1] = static_cast<int>(wallAdjacent.size());
    if (norm(wallNormal[v]) > 0) {
      wallNormal[v] = normalized(wallNormal[v]);
      hasWallNormal[v] = 1;
      any = true;
    }
  }
  wallAdjacency = any;  // false: every wall face degenerate
  return wallAdjacency;
}

bool SurfaceBuffers::smoothCutWallNormals(const SurfaceSnapshot& snap) {
  if (cutWallNormalPasses <= 0 || !wallAdjacency) return false;
  const int nv = snap.numVertices();
  // passes of the mean of a vertex's unit normal and its neighbours' (Jacobi: each pass
  // reads the last one's)
  for (int pass = 0; pass < cutWallNormalPasses; ++pass) {
    wallNext = wallNormal;
    for (int v = 0; v < nv; ++v) {
      if (!hasWallNormal[v]) continue;
      V3 sum = wallNormal[v];
      for (int i = wallStart[v]; i < wallStart[v + 1]; ++i)
        sum = add(sum, wallNormal[wallAdjacent[i]]);
      // opposite normals cancel (a sliver's two sides): the vertex keeps the last pass's
      if (norm(sum) > 1e-3f) wallNext[v] = normalized(sum);
    }
    wallNormal.swap(wallNext);
  }
  return true;
}

bool SurfaceBuffers::smoothCutWallStates(const SurfaceSnapshot& snap) {
  if (cutWallDamagePasses <= 0 || !wallAdjacency ||
      (snap.coagulation.empty() && snap.desiccation.empty()))
    return false;
  const int nv = snap.numVertices();
  // passes of the mean of a wall vertex's value and its wall neighbours' (Jacobi, in a
  // fixed order); the other vertices keep the snapshot's
  const auto smoothed = [&](const std::vector<float>& raw, std::vector<float>& value) {
    if (raw.empty()) {
      value.assign(nv, 0.0f);
      return;
    }
    value.assign(raw.begin(), raw.end());
    for (int pass = 0; pass < cutWallDamagePasses; ++pass) {
      wallStateNext = value;
      for (int v = 0; v < nv; ++v) {
        if (!hasWallNormal[v]) continue;
        float sum = value[v];
        for (int i = wallStart[v]; i < wallStart[v + 1]; ++i) sum += value[wallAdjacent[i]];
        wallStateNext[v] = sum / static_cast<float>(1 + wallStart[v + 1] - wallStart[v]);
      }
      value.swap(wallStateNext);
    }
  };
  smoothed(snap.coagulation, wallCoagulation);
  smoothed(snap.desiccation, wallDesiccation);
  return true;
}

void SurfaceBuffers::takeWallState(std::uint32_t v, std::array<float, 4>& state) const {
  state[1] = wallCoagulation[v];
  state[2] = wallDesiccation[v];
}

}  // namespace esim::render_detail
