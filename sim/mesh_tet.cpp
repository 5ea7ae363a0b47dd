// mesh_tet.cpp - tetrahedral mesh queries (see mesh_tet.h).
#include "sim/mesh_tet.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iterator>
#include <sstream>

#include "sim/core_error.h"
#include "sim/ray_triangle.h"

namespace esim {

namespace {

// local faces opposite vertex 0..3, outward for a positively oriented tet
constexpr int kFaceLocal[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

// builds a CSR from (row, id) pairs; rows sorted and unique
Adjacency buildCsr(int rows, std::vector<std::pair<int, int>>& pairs) {
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  Adjacency adj;
  adj.offsets.assign(rows + 1, 0);
  for (const auto& p : pairs) adj.offsets[p.first + 1]++;
  for (int i = 0; i < rows; ++i) adj.offsets[i + 1] += adj.offsets[i];
  adj.ids.reserve(pairs.size());
  for (const auto& p : pairs) adj.ids.push_back(p.second);
  return adj;
}

// a face of a tet under its sorted node triple; where = tet * 4 + local face
struct FaceEntry {
  Tri key;
  int where;
};

// the faces of the tets (alive ones only, or all), sorted by key then where: a face two
// tets share comes as two neighbouring entries
std::vector<FaceEntry> sortedFaceEntries(const TetMesh& mesh, bool aliveOnly) {
  std::vector<FaceEntry> entries;
  entries.reserve(static_cast<size_t>(aliveOnly ? mesh.numAlive() : mesh.numTets()) * 4);
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (aliveOnly && !mesh.isAlive(e)) continue;
    for (int f = 0; f < 4; ++f) {
      Tri key = {mesh.tets[e][kFaceLocal[f][0]], mesh.tets[e][kFaceLocal[f][1]],
                 mesh.tets[e][kFaceLocal[f][2]]};
      std::sort(key.begin(), key.end());
      entries.push_back({key, e * 4 + f});
    }
  }
  std::sort(entries.begin(), entries.end(), [](const FaceEntry& a, const FaceEntry& b) {
    return a.key != b.key ? a.key < b.key : a.where < b.where;
  });
  return entries;
}

// the outward face at slot where = tet * 4 + local face
BoundaryFace faceAt(const TetMesh& mesh, int where) {
  const int e = where / 4, f = where % 4;
  const Tet& t = mesh.tets[e];
  return {{t[kFaceLocal[f][0]], t[kFaceLocal[f][1]], t[kFaceLocal[f][2]]}, e};
}

}  // namespace

int TetMesh::numAlive() const {
  if (alive.empty()) return numTets();
  int n = 0;
  for (auto a : alive) n += a != 0;
  return n;
}

double tetSignedVolume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

double tetVolume(const TetMesh& mesh, int tet) {
  const Tet& t = mesh.tets[tet];
  return tetSignedVolume(mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]], mesh.nodes[t[3]]);
}

double meshVolume(const TetMesh& mesh) {
  // Neumaier-compensated sum: exact to ~1e-16 relative even for millions of tets
  double sum = 0, comp = 0;
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    const double v = tetVolume(mesh, e), t = sum + v;
    comp += std::abs(sum) >= std::abs(v) ? (sum - t) + v : (v - t) + sum;
    sum = t;
  }
  return sum + comp;
}

std::vector<BoundaryFace> boundaryFaces(const TetMesh& mesh) {
  const std::vector<FaceEntry> entries = sortedFaceEntries(mesh, true);
  std::vector<int> boundary;
  for (size_t i = 0; i < entries.size();) {
    size_t j = i + 1;
    while (j < entries.size() && entries[j].key == entries[i].key) ++j;
    if (j - i == 1) boundary.push_back(entries[i].where);
    i = j;
  }
  std::sort(boundary.begin(), boundary.end());
  std::vector<BoundaryFace> faces;
  faces.reserve(boundary.size());
  for (int w : boundary) faces.push_back(faceAt(mesh, w));
  return faces;
}

std::vector<std::array<int, 4>> tetFaceNeighbours(const TetMesh& mesh) {
  const std::vector<FaceEntry> entries = sortedFaceEntries(mesh, false);
  std::vector<std::array<int, 4>> out(mesh.numTets(), {-1, -1, -1, -1});
  for (size_t i = 0; i + 1 < entries.size(); ++i)
    if (entries[i].key == entries[i + 1].key) {
      const int a = entries[i].where, b = entries[i + 1].where;
      out[a / 4][a % 4] = b / 4;
      out[b / 4][b % 4] = a / 4;
    }
  return out;
}

BoundaryNodeChange updateBoundaryNodes(const TetMesh& mesh,
                                       const std::vector<std::array<int, 4>>& neighbours,
                                       const Adjacency& nodeTets, const std::vector<int>& removed,
                                       std::vector<int>& nodes) {
  std::vector<int> candidates;
  for (int e : removed)
    for (int v : mesh.tets[e]) candidates.push_back(v);
  std::sort(candidates.begin(), candidates.end());
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  BoundaryNodeChange change;
  for (int v : candidates) {
    bool onBoundary = false;
    for (const int* t = nodeTets.begin(v); t != nodeTets.end(v) && !onBoundary; ++t) {
      if (!mesh.isAlive(*t)) continue;
      for (int f = 0; f < 4 && !onBoundary; ++f) {
        if (mesh.tets[*t][f] == v) continue;  // the face opposite v does not hold it
        const int across = neighbours[*t][f];
        onBoundary = across < 0 || !mesh.isAlive(across);
      }
    }
    const bool was = std::binary_search(nodes.begin(), nodes.end(), v);
    if (was && !onBoundary) change.left.push_back(v);
    if (!was && onBoundary) change.joined.push_back(v);
  }
  if (change.left.empty() && change.joined.empty()) return change;
  std::vector<int> kept, merged;
  kept.reserve(nodes.size());
  std::set_difference(nodes.begin(), nodes.end(), change.left.begin(), change.left.end(),
                      std::back_inserter(kept));
  merged.reserve(kept.size() + change.joined.size());
  std::merge(kept.begin(), kept.end(), change.joined.begin(), change.joined.end(),
             std::back_inserter(merged));
  nodes.swap(merged);
  return change;
}

int boundaryFaceIndex(const TetMesh& mesh, const BoundaryFace& face) {
  const Tet& t = mesh.tets[face.tet];
  for (int f = 0; f < 4; ++f)
    if (std::find(face.nodes.begin(), face.nodes.end(), t[f]) == face.nodes.end())
      return face.tet * 4 + f;
  return face.tet * 4;
}

void removeFromBoundary(const TetMesh& mesh, const std::vector<std::array<int, 4>>& neighbours,
                        const std::vector<int>& removed, std::vector<BoundaryFace>& faces) {
  // faces are ordered by boundaryFaceIndex
  // the faces joining: of alive neighbours, across a face from a removed tet
  std::vector<int> joining;
  for (int e : removed)
    for (int f = 0; f < 4; ++f) {
      const int n = neighbours[e][f];
      if (n < 0 || !mesh.isAlive(n)) continue;
      for (int g = 0; g < 4; ++g)
        if (neighbours[n][g] == e) joining.push_back(n * 4 + g);
    }
  std::sort(joining.begin(), joining.end());
  joining.erase(std::unique(joining.begin(), joining.end()), joining.end());
  // the faces staying (of alive tets), merged with the joining ones in order
  std::vector<BoundaryFace> out;
  out.reserve(faces.size() + joining.size());
  size_t j = 0;
  for (const BoundaryFace& bf : faces) {
    if (!mesh.isAlive(bf.tet)) continue;
    const int w = boundaryFaceIndex(mesh, bf);
    for (; j < joining.size() && joining[j] < w; ++j) out.push_back(faceAt(mesh, joining[j]));
    out.push_back(bf);
  }
  for (; j < joining.size(); ++j) out.push_back(faceAt(mesh, joining[j]));
  faces.swap(out);
}

double surfaceArea(const TetMesh& mesh, const std::vector<BoundaryFace>& faces) {
  double area = 0;
  for (const auto& f : faces) {
    const Vec3& a = mesh.nodes[f.nodes[0]];
    area += 0.5 * (mesh.nodes[f.nodes[1]] - a).cross(mesh.nodes[f.nodes[2]] - a).norm();
  }
  return area;
}

double pointTriangleDistance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.norm();  // vertex a
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.norm();  // vertex b
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();  // edge ab
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.norm();  // vertex c
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();  // edge ac
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)  // edge bc
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  const double denom = 1 / (va + vb + vc);  // inside the face
  return (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
}

double signedDistanceToSurface(const TetMesh& mesh, const std::vector<BoundaryFace>& faces,
                               const Vec3& p) {
  int crossings = 0;  // of the ray from p along the generic direction (the parity)
  double nearest = INFINITY;
  for (const BoundaryFace& f : faces) {
    const Vec3& a = mesh.nodes[f.nodes[0]];
    const Vec3& b = mesh.nodes[f.nodes[1]];
    const Vec3& c = mesh.nodes[f.nodes[2]];
    nearest = std::min(nearest, pointTriangleDistance(p, a, b, c));
    crossings += rayTriangleT(p.data(), kGenericRayDirection, a.data(), b.data(), c.data()) > 0;
  }
  return crossings % 2 == 1 ? -nearest : nearest;
}

std::vector<int> boundaryNodes(const TetMesh& mesh, const std::vector<BoundaryFace>& faces) {
  std::vector<std::uint8_t> mark(mesh.nodes.size(), 0);
  for (const auto& f : faces)
    for (int v : f.nodes) mark[v] = 1;
  std::vector<int> ids;
  for (int i = 0; i < mesh.numNodes(); ++i)
    if (mark[i]) ids.push_back(i);
  return ids;
}

std::vector<int> aliveNodes(const TetMesh& mesh) {
  std::vector<std::uint8_t> mark(mesh.nodes.size(), 0);
  for (int t = 0; t < mesh.numTets(); ++t)
    if (mesh.isAlive(t))
      for (int v : mesh.tets[t]) mark[v] = 1;
  std::vector<int> ids;
  for (int i = 0; i < mesh.numNodes(); ++i)
    if (mark[i]) ids.push_back(i);
  return ids;
}

std::vector<int> nodesOfTets(const TetMesh& mesh, const std::vector<int>& tets) {
  std::vector<int> out;
  out.reserve(4 * tets.size());
  for (int t : tets) out.insert(out.end(), mesh.tets[t].begin(), mesh.tets[t].end());
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::vector<int> nodesWithoutAliveTets(const TetMesh& mesh, const Adjacency& nodeTets,
                                       const std::vector<int>& removed) {
  std::vector<int> out;
  for (int e : removed)
    for (int v : mesh.tets[e]) {
      bool held = false;
      for (const int* t = nodeTets.begin(v); t != nodeTets.end(v) && !held; ++t)
        held = mesh.isAlive(*t);
      if (!held) out.push_back(v);
    }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

Adjacency nodeAdjacency(const TetMesh& mesh) {
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(static_cast<size_t>(mesh.numAlive()) * 12);
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        if (a != b) pairs.emplace_back(mesh.tets[e][a], mesh.tets[e][b]);
  }
  return buildCsr(mesh.numNodes(), pairs);
}

std::vector<int> nodePieces(const TetMesh& mesh, int* count) {
  const int n = mesh.numNodes();
  std::vector<int> root(n);
  for (int v = 0; v < n; ++v) root[v] = v;
  const auto find = [&](int v) {
    while (root[v] != v) v = root[v] = root[root[v]];
    return v;
  };
  std::vector<std::uint8_t> used(n, 0);
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    const Tet& t = mesh.tets[e];
    for (int a = 0; a < 4; ++a) {
      used[t[a]] = 1;
      const int ra = find(t[a]), r0 = find(t[0]);
      if (ra != r0) root[std::max(ra, r0)] = std::min(ra, r0);
    }
  }
  // each root is its piece's lowest node (unions keep the lower root), seen first in order
  std::vector<int> piece(n, -1);
  int pieces = 0;
  for (int v = 0; v < n; ++v)
    if (used[v]) piece[v] = find(v) == v ? pieces++ : piece[find(v)];
  if (count) *count = pieces;
  return piece;
}

std::vector<int> tetPieces(const TetMesh& mesh, int* count) {
  const int nt = mesh.numTets();
  const std::vector<std::array<int, 4>> neighbours = tetFaceNeighbours(mesh);
  std::vector<int> piece(nt, -1);
  std::vector<int> stack;
  int pieces = 0;
  for (int s = 0; s < nt; ++s) {
    if (!mesh.isAlive(s) || piece[s] >= 0) continue;
    piece[s] = pieces;
    stack.assign(1, s);
    while (!stack.empty()) {
      const int t = stack.back();
      stack.pop_back();
      for (int o : neighbours[t])
        if (o >= 0 && mesh.isAlive(o) && piece[o] < 0) {
          piece[o] = pieces;
          stack.push_back(o);
        }
    }
    ++pieces;
  }
  if (count) *count = pieces;
  return piece;
}

Adjacency nodeTets(const TetMesh& mesh) {
  if (!mesh.alive.empty()) return aliveTetsAtNodes(mesh.numNodes(), mesh.tets, mesh.alive.data());
  const std::vector<std::uint8_t> all(mesh.tets.size(), 1);
  return aliveTetsAtNodes(mesh.numNodes(), mesh.tets, all.data());
}

Adjacency aliveTetsAtNodes(int numNodes, const std::vector<Tet>& tets, const std::uint8_t* alive) {
  const int nt = static_cast<int>(tets.size());
  Adjacency adj;
  adj.offsets.assign(static_cast<size_t>(numNodes) + 1, 0);
  for (int t = 0; t < nt; ++t)
    if (alive[t])
      for (int v : tets[t]) ++adj.offsets[v + 1];
  for (int v = 0; v < numNodes; ++v) adj.offsets[v + 1] += adj.offsets[v];
  adj.ids.resize(adj.offsets[numNodes]);
  std::vector<int> fill(adj.offsets.begin(), adj.offsets.end() - 1);
  for (int t = 0; t < nt; ++t)
    if (alive[t])
      for (int v : tets[t]) adj.ids[fill[v]++] = t;
  return adj;
}

Adjacency tetNeighbours(const TetMesh& mesh) {
  struct Entry {
    Tri key;
    int tet;
  };
  std::vector<Entry> entries;
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    for (int f = 0; f < 4; ++f) {
      Tri key = {mesh.tets[e][kFaceLocal[f][0]], mesh.tets[e][kFaceLocal[f][1]],
                 mesh.tets[e][kFaceLocal[f][2]]};
      std::sort(key.begin(), key.end());
      entries.push_back({key, e});
    }
  }
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    return a.key != b.key ? a.key < b.key : a.tet < b.tet;
  });
  std::vector<std::pair<int, int>> pairs;
  for (size_t i = 0; i + 1 < entries.size(); ++i) {
    if (entries[i].key == entries[i + 1].key) {
      pairs.emplace_back(entries[i].tet, entries[i + 1].tet);
      pairs.emplace_back(entries[i + 1].tet, entries[i].tet);
    }
  }
  return buildCsr(mesh.numTets(), pairs);
}

MeshQuality meshQuality(const TetMesh& mesh) {
  MeshQuality q;
  q.minDihedralDeg = 180;
  q.maxDihedralDeg = 0;
  q.minVolume = INFINITY;
  bool any = false;
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    any = true;
    const Tet& t = mesh.tets[e];
    Vec3 p[4];
    for (int i = 0; i < 4; ++i) p[i] = mesh.nodes[t[i]];
    const double vol = tetSignedVolume(p[0], p[1], p[2], p[3]);
    q.totalVolume += vol;
    q.minVolume = std::min(q.minVolume, vol);
    // outward face normals (face opposite vertex k)
    Vec3 n[4];
    for (int k = 0; k < 4; ++k) {
      const Vec3& a = p[kFaceLocal[k][0]];
      n[k] = (p[kFaceLocal[k][1]] - a).cross(p[kFaceLocal[k][2]] - a).normalized();
    }
    // dihedral angle at the edge shared by the faces opposite k and l
    for (int k = 0; k < 4; ++k)
      for (int l = k + 1; l < 4; ++l) {
        const double c = std::clamp(-n[k].dot(n[l]), -1.0, 1.0);
        const double deg = std::acos(c) * 180.0 / M_PI;
        q.minDihedralDeg = std::min(q.minDihedralDeg, deg);
        q.maxDihedralDeg = std::max(q.maxDihedralDeg, deg);
      }
    // circumradius / shortest edge
    Eigen::Matrix3d a;
    Eigen::Vector3d b;
    for (int i = 0; i < 3; ++i) {
      const Vec3 d = p[i + 1] - p[0];
      a.row(i) = d.transpose();
      b[i] = 0.5 * d.squaredNorm();
    }
    const double radius = a.fullPivLu().solve(b).norm();
    double shortest = INFINITY;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) shortest = std::min(shortest, (p[i] - p[j]).norm());
    q.maxRadiusEdgeRatio = std::max(q.maxRadiusEdgeRatio, radius / shortest);
  }
  if (!any) q = MeshQuality{};
  return q;
}

void validateMesh(const TetMesh& mesh, const std::string& source) {
  ESIM_VERIFY(mesh.numNodes() > 0 && mesh.numAlive() > 0,
              source + ": mesh is empty (" + std::to_string(mesh.numNodes()) + " nodes, " +
                  std::to_string(mesh.numAlive()) +
                  " tetrahedra); expected at least one tetrahedron");
  ESIM_VERIFY(mesh.alive.empty() || mesh.alive.size() == mesh.tets.size(),
              source + ": alive flags have " + std::to_string(mesh.alive.size()) + " entries for " +
                  std::to_string(mesh.tets.size()) + " tetrahedra");
  for (int i = 0; i < mesh.numNodes(); ++i) {
    ESIM_VERIFY(mesh.nodes[i].allFinite(),
                source + ": node " + std::to_string(i) + " has a non-finite coordinate");
  }
  double mean_abs = 0;
  for (int e = 0; e < mesh.numTets(); ++e) {
    for (int v : mesh.tets[e]) {
      ESIM_VERIFY(v >= 0 && v < mesh.numNodes(), source + ": tetrahedron " + std::to_string(e) +
                                                     " refers to node " + std::to_string(v) +
                                                     " but the mesh has " +
                                                     std::to_string(mesh.numNodes()) + " nodes");
    }
    if (mesh.isAlive(e)) mean_abs += std::abs(tetVolume(mesh, e));
  }
  mean_abs /= mesh.numAlive();
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    const double vol = tetVolume(mesh, e);
    std::ostringstream msg;
    msg << source << ": tetrahedron " << e << " (nodes " << mesh.tets[e][0] << " "
        << mesh.tets[e][1] << " " << mesh.tets[e][2] << " " << mesh.tets[e][3] << ") ";
    if (vol < 0 && std::abs(vol) > 1e-10 * mean_abs) {
      msg << "is inverted (signed volume " << vol << " m^3); expected positive orientation";
      throw Error(msg.str());
    }
    if (!(std::abs(vol) > 1e-10 * mean_abs)) {
      msg << "has zero volume (" << vol << " m^3); expected a non-degenerate tetrahedron";
      throw Error(msg.str());
    }
  }
}

TetMesh compactMesh(const TetMesh& mesh, std::vector<int>* node_map) {
  std::vector<int> map(mesh.nodes.size(), -1);
  for (int e = 0; e < mesh.numTets(); ++e)
    if (mesh.isAlive(e))
      for (int v : mesh.tets[e]) map[v] = 0;
  TetMesh out;
  for (int i = 0; i < mesh.numNodes(); ++i) {
    if (map[i] < 0) continue;
    map[i] = out.numNodes();
    out.nodes.push_back(mesh.nodes[i]);
  }
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    const Tet& t = mesh.tets[e];
    out.tets.push_back({map[t[0]], map[t[1]], map[t[2]], map[t[3]]});
  }
  out.alive.assign(out.tets.size(), 1);
  for (const auto& [name, ids] : mesh.nodeSets) {
    std::vector<int> kept;
    for (int v : ids)
      if (map[v] >= 0) kept.push_back(map[v]);
    out.nodeSets[name] = kept;  // stays sorted: the map is monotone
  }
  if (node_map) *node_map = std::move(map);
  return out;
}

}  // namespace esim
