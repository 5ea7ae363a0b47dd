// mesh_tet.h - tetrahedral mesh: nodes [m], tets, alive flags, boundary, adjacency.
//
// A TetMesh owns its arrays by value. Tets list 4 node ids with positive
// orientation: (p1-p0) . ((p2-p0) x (p3-p0)) > 0, i.e. signed volume > 0.
// Element removal is designed in: `alive[e] == 0` marks a removed tet. Functions
// that take a mesh see only alive tets unless they say otherwise; `compactMesh`
// drops dead tets and orphan nodes and returns the old->new node map.
// Node sets are named, sorted lists of node ids (e.g. "top", "bottom").
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace esim {

using Vec3 = Eigen::Vector3d;
using Tet = std::array<int, 4>;
using Tri = std::array<int, 3>;

struct TetMesh {
  std::vector<Vec3> nodes;                           // positions [m]
  std::vector<Tet> tets;                             // node ids, positive orientation
  std::vector<std::uint8_t> alive;                   // per tet: 1 alive, 0 removed
  std::map<std::string, std::vector<int>> nodeSets;  // named sorted node ids

  int numNodes() const { return static_cast<int>(nodes.size()); }
  int numTets() const { return static_cast<int>(tets.size()); }
  int numAlive() const;  // number of alive tets
  bool isAlive(int tet) const { return alive.empty() || alive[tet] != 0; }
};

// A triangle on the boundary of the alive tets, oriented with outward normal.
struct BoundaryFace {
  Tri nodes;  // outward orientation (right-hand rule)
  int tet;    // the alive tet it belongs to
};

// Compressed sparse rows: the neighbours of item i are ids[offsets[i]..offsets[i+1]).
struct Adjacency {
  std::vector<int> offsets;
  std::vector<int> ids;
  int count(int i) const { return offsets[i + 1] - offsets[i]; }
  const int* begin(int i) const { return ids.data() + offsets[i]; }
  const int* end(int i) const { return ids.data() + offsets[i + 1]; }
};

struct MeshQuality {
  double minDihedralDeg = 0;      // smallest dihedral angle [deg]
  double maxDihedralDeg = 0;      // largest dihedral angle [deg]
  double maxRadiusEdgeRatio = 0;  // circumradius / shortest edge (regular tet: 0.612)
  double minVolume = 0;           // smallest tet volume [m^3]
  double totalVolume = 0;         // [m^3]
};

// signed volume of tet (a,b,c,d) [m^3]; positive for positive orientation
double tetSignedVolume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

// signed volume of tet e of the mesh [m^3]
double tetVolume(const TetMesh& mesh, int tet);

// total volume of the alive tets [m^3]
double meshVolume(const TetMesh& mesh);

// boundary faces of the alive tets, sorted by (tet, local face) for determinism
std::vector<BoundaryFace> boundaryFaces(const TetMesh& mesh);

// face.tet * 4 + the local index of face's tet vertex it does not hold (the order of
// boundaryFaces; faceAt's argument)
int boundaryFaceIndex(const TetMesh& mesh, const BoundaryFace& face);

// per tet, the tet across each local face f (the face opposite local vertex f, the faces
// boundaryFaces gives), -1 where no tet is; every tet, alive or not (the mesh's topology)
std::vector<std::array<int, 4>> tetFaceNeighbours(const TetMesh& mesh);

// Edits boundaryFaces(mesh) of the alive set before the tets `removed` died (mesh.alive
// already without them) into boundaryFaces(mesh) of the alive set now: the faces of the
// removed tets leave, the faces their alive neighbours (`neighbours`, from
// tetFaceNeighbours) shared with them join. The same faces in the same order as
// boundaryFaces(mesh), at a cost in the removed tets and the surface's size, with no pass
// over the tets.
void removeFromBoundary(const TetMesh& mesh, const std::vector<std::array<int, 4>>& neighbours,
                        const std::vector<int>& removed, std::vector<BoundaryFace>& faces);

// Edits boundaryNodes(mesh, faces) of the alive set before the tets `removed` died (mesh.alive
// already without them) into that of the alive set now, in place (`nodes`, sorted): only the
// nodes of the removed tets can change, a node being on the boundary when a face of an alive
// tet at it has no alive tet across (`neighbours`: tetFaceNeighbours). nodeTets: the tets at
// each node of an alive set holding the current one (the mesh's first, as nodeTets(mesh)).
// Returns the nodes that left the boundary and those that joined it (sorted). Cost: the
// removed tets' nodes and their tets, and one pass to merge (no pass over the tets).
struct BoundaryNodeChange {
  std::vector<int> left, joined;
};
BoundaryNodeChange updateBoundaryNodes(const TetMesh& mesh,
                                       const std::vector<std::array<int, 4>>& neighbours,
                                       const Adjacency& nodeTets, const std::vector<int>& removed,
                                       std::vector<int>& nodes);

// total area of the given faces [m^2]
double surfaceArea(const TetMesh& mesh, const std::vector<BoundaryFace>& faces);

// the distance from p to triangle (a, b, c) [m] (its closest point: Ericson, Real-Time
// Collision Detection, 5.1.5)
double pointTriangleDistance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// p's distance to the closed surface of `faces` [m], negative inside it (a ray from p
// crosses the faces an odd number of times); +inf without faces
double signedDistanceToSurface(const TetMesh& mesh, const std::vector<BoundaryFace>& faces,
                               const Vec3& p);

// sorted ids of the nodes on the given faces
std::vector<int> boundaryNodes(const TetMesh& mesh, const std::vector<BoundaryFace>& faces);

// sorted ids of the nodes of the alive tets
std::vector<int> aliveNodes(const TetMesh& mesh);

// sorted ids of the nodes of the given tets (alive or not): the columns of an assembled matrix
// their removal changes
std::vector<int> nodesOfTets(const TetMesh& mesh, const std::vector<int>& tets);

// the nodes of the `removed` tets that no alive tet holds any more (sorted), after their
// alive flags were cleared; nodeTets: the tets at each node of an alive set holding the
// current one (as for updateBoundaryNodes). Cost: the removed tets' nodes and their tets
std::vector<int> nodesWithoutAliveTets(const TetMesh& mesh, const Adjacency& nodeTets,
                                       const std::vector<int>& removed);

// node-node adjacency through alive tets (sorted, without the node itself)
Adjacency nodeAdjacency(const TetMesh& mesh);

// node -> alive tets containing it (sorted)
Adjacency nodeTets(const TetMesh& mesh);

// the alive tets (alive[t] != 0) at each node, ascending, by a counting sort (a tet listed
// once for each of its 4 node slots; validateMesh refuses an alive tet with a node twice):
// nodeTets for a phase that keeps its tets and alive flags apart from a TetMesh
Adjacency aliveTetsAtNodes(int numNodes, const std::vector<Tet>& tets, const std::uint8_t* alive);

// tet -> alive tets sharing a face (sorted)
Adjacency tetNeighbours(const TetMesh& mesh);

// the pieces of the alive tets connected through shared nodes (as a P1 field couples them):
// per node its piece 0 .. count - 1, numbered in the order of their lowest node, or -1 for a
// node in no alive tet; *count gets the number of pieces
std::vector<int> nodePieces(const TetMesh& mesh, int* count);

// the pieces of the alive tets connected through shared faces (as the structural phase and
// the debris rule see them: a tet hanging by an edge or a node is a piece of its own): per tet
// its piece 0 .. count - 1, numbered in the order of their lowest tet, or -1 for a removed
// tet; *count gets the number of pieces
std::vector<int> tetPieces(const TetMesh& mesh, int* count);

// quality of the alive tets
MeshQuality meshQuality(const TetMesh& mesh);

// Checks a mesh: non-empty, ids in range, every alive tet with volume > rel_tol * mean.
// Throws esim::Error "<source>: <what is wrong>" naming the first bad tet.
void validateMesh(const TetMesh& mesh, const std::string& source);

// Drops removed tets and nodes no alive tet uses; node sets follow. If node_map is
// given, it receives old id -> new id (-1 for dropped nodes).
TetMesh compactMesh(const TetMesh& mesh, std::vector<int>* node_map = nullptr);

}  // namespace esim
