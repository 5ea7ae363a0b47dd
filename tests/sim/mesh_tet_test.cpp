// Tests for sim/mesh_tet.cpp: volumes, boundary, adjacency, validation, compaction.
#include "sim/mesh_tet.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iterator>

#include "sim/core_error.h"
#include "sim/mesh_slab.h"

namespace esim {
namespace {

// two tets sharing face (1,2,3): nodes 0..4
TetMesh twoTets() {
  TetMesh m;
  m.nodes = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(1, 1, 1)};
  m.tets = {{0, 1, 2, 3}, {1, 4, 2, 3}};
  m.alive = {1, 1};
  return m;
}

TEST(MeshTet, VolumeOfTwoTets) {
  const TetMesh m = twoTets();
  EXPECT_NEAR(tetVolume(m, 0), 1.0 / 6.0, 1e-15);
  EXPECT_GT(tetVolume(m, 1), 0.0);
  // second tet: (1,4,2,3) with p1=(1,0,0): edges (0,1,1),(-1,1,0),(-1,0,1) -> det 2 -> 1/3
  EXPECT_NEAR(tetVolume(m, 1), 1.0 / 3.0, 1e-15);
  EXPECT_NEAR(meshVolume(m), 0.5, 1e-15);
}

TEST(MeshTet, NodeAdjacencyByHand) {
  const Adjacency adj = nodeAdjacency(twoTets());
  // node 0 touches 1,2,3; node 4 touches 1,2,3; nodes 1,2,3 touch all others
  ASSERT_EQ(adj.offsets.size(), 6u);
  EXPECT_EQ(std::vector<int>(adj.begin(0), adj.end(0)), (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(std::vector<int>(adj.begin(1), adj.end(1)), (std::vector<int>{0, 2, 3, 4}));
  EXPECT_EQ(std::vector<int>(adj.begin(2), adj.end(2)), (std::vector<int>{0, 1, 3, 4}));
  EXPECT_EQ(std::vector<int>(adj.begin(3), adj.end(3)), (std::vector<int>{0, 1, 2, 4}));
  EXPECT_EQ(std::vector<int>(adj.begin(4), adj.end(4)), (std::vector<int>{1, 2, 3}));
  const Adjacency nt = nodeTets(twoTets());
  EXPECT_EQ(nt.count(0), 1);
  EXPECT_EQ(nt.count(1), 2);
  const Adjacency tn = tetNeighbours(twoTets());
  EXPECT_EQ(std::vector<int>(tn.begin(0), tn.end(0)), (std::vector<int>{1}));
  EXPECT_EQ(std::vector<int>(tn.begin(1), tn.end(1)), (std::vector<int>{0}));
}

// pieces through shared nodes: a tet touching another at one node is the same piece; a
// dead tet joins nothing; a node in no alive tet is in none; pieces numbered by lowest node
TEST(MeshTet, NodePiecesJoinThroughSharedNodes) {
  TetMesh m;
  for (int k = 0; k < 13; ++k) m.nodes.push_back(Vec3(k, (k * 7) % 5, (k * 3) % 4));
  m.tets = {{5, 6, 7, 8}, {0, 1, 2, 3}, {3, 10, 11, 12}, {4, 8, 9, 2}, {0, 4, 5, 9}};
  m.alive = {1, 1, 1, 1, 0};
  int count = -1;
  std::vector<int> piece = nodePieces(m, &count);
  // {0,1,2,3} + {3,10,11,12} (node 3) + {4,8,9,2} (node 2) + {5,6,7,8} (node 8): one piece
  EXPECT_EQ(count, 1);
  EXPECT_EQ(piece, std::vector<int>(13, 0));
  m.tets[3] = {4, 9, 12, 1};  // now {5,6,7,8} stands alone; 4 and 9 join through 12 and 1
  piece = nodePieces(m, &count);
  EXPECT_EQ(count, 2);
  EXPECT_EQ(piece, (std::vector<int>{0, 0, 0, 0, 0, 1, 1, 1, 1, 0, 0, 0, 0}));
  m.alive = {1, 1, 0, 0, 0};  // 9-12 and 4 in no alive tet
  piece = nodePieces(m, &count);
  EXPECT_EQ(count, 2);
  EXPECT_EQ(piece, (std::vector<int>{0, 0, 0, 0, -1, 1, 1, 1, 1, -1, -1, -1, -1}));
}

// pieces through shared faces: tets sharing only a node or an edge are pieces of their own; a
// dead tet splits a chain; pieces numbered by their lowest tet
TEST(MeshTet, TetPiecesJoinThroughSharedFacesOnly) {
  TetMesh m;
  for (int k = 0; k < 9; ++k) m.nodes.push_back(Vec3(k, (k * 7) % 5, (k * 3) % 4));
  m.tets = {{0, 1, 2, 3}, {1, 2, 3, 4}, {2, 3, 4, 5}, {4, 5, 6, 7}, {7, 8, 6, 0}};
  int count = -1;
  std::vector<int> piece = tetPieces(m, &count);
  // tets 0-1-2 by faces; 3 touches 2 by the edge {4,5}; 4 touches 3 by the edge {6,7}
  EXPECT_EQ(count, 3);
  EXPECT_EQ(piece, (std::vector<int>{0, 0, 0, 1, 2}));
  m.alive = {1, 0, 1, 1, 1};  // the middle of the chain gone
  piece = tetPieces(m, &count);
  EXPECT_EQ(count, 4);
  EXPECT_EQ(piece, (std::vector<int>{0, -1, 1, 2, 3}));
  m.tets[4] = {4, 5, 6, 8};  // shares the face {4,5,6} with tet 3
  piece = tetPieces(m, &count);
  EXPECT_EQ(count, 3);
  EXPECT_EQ(piece, (std::vector<int>{0, -1, 1, 2, 2}));
  EXPECT_EQ(piece, tetPieces(m, nullptr));
}

// the alive tets at each node, ascending, against a search of every tet; a mesh without
// alive flags counts every tet
TEST(MeshTet, AliveTetsAtNodesAreEveryAliveTetAtTheNode) {
  const TetMesh two = twoTets();
  const Adjacency both = aliveTetsAtNodes(two.numNodes(), two.tets, two.alive.data());
  EXPECT_EQ(std::vector<int>(both.begin(1), both.end(1)), (std::vector<int>{0, 1}));
  EXPECT_EQ(std::vector<int>(both.begin(4), both.end(4)), (std::vector<int>{1}));
  SlabSpec spec;
  spec.nodesPerAxis = {4, 3, 3};
  TetMesh slab = makeSlab(spec);
  for (int t = 0; t < slab.numTets(); t += 3) slab.alive[t] = 0;
  const Adjacency counted = nodeTets(slab);
  for (int v = 0; v < slab.numNodes(); ++v) {
    std::vector<int> expected;
    for (int t = 0; t < slab.numTets(); ++t)
      if (slab.alive[t] && std::count(slab.tets[t].begin(), slab.tets[t].end(), v) > 0)
        expected.push_back(t);
    EXPECT_EQ(std::vector<int>(counted.begin(v), counted.end(v)), expected) << "node " << v;
  }
  slab.alive.clear();
  const Adjacency all = nodeTets(slab);
  EXPECT_EQ(all.ids.size(), 4u * slab.numTets());
}

TEST(MeshTet, BoundaryFacesAreOutwardAndClosed) {
  const TetMesh m = twoTets();
  const auto faces = boundaryFaces(m);
  ASSERT_EQ(faces.size(), 6u);  // 8 faces, the shared one is interior
  // divergence theorem: sum over faces of (centroid . n) * area / 3 = volume
  double vol = 0;
  for (const auto& f : faces) {
    const Vec3 &a = m.nodes[f.nodes[0]], &b = m.nodes[f.nodes[1]], &c = m.nodes[f.nodes[2]];
    vol += a.dot((b - a).cross(c - a)) / 6.0;
  }
  EXPECT_NEAR(vol, 0.5, 1e-15);
  EXPECT_EQ(boundaryNodes(m, faces), (std::vector<int>{0, 1, 2, 3, 4}));
}

TEST(MeshTet, RemovalChangesBoundaryAndCompacts) {
  TetMesh m = twoTets();
  m.nodeSets["apex"] = {4};
  m.nodeSets["origin"] = {0};
  m.alive[0] = 0;
  EXPECT_EQ(m.numAlive(), 1);
  EXPECT_EQ(boundaryFaces(m).size(), 4u);
  std::vector<int> map;
  const TetMesh c = compactMesh(m, &map);
  EXPECT_EQ(c.numNodes(), 4);
  EXPECT_EQ(c.numTets(), 1);
  EXPECT_EQ(map, (std::vector<int>{-1, 0, 1, 2, 3}));
  EXPECT_EQ(c.nodeSets.at("apex"), (std::vector<int>{3}));
  EXPECT_TRUE(c.nodeSets.at("origin").empty());
  EXPECT_NEAR(meshVolume(c), 1.0 / 3.0, 1e-15);
}

// the nearest point of a triangle in each of its regions: the face, an edge, a vertex
TEST(MeshTet, PointTriangleDistanceInEachRegion) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_NEAR(pointTriangleDistance(Vec3(0.25, 0.25, 2), a, b, c), 2.0, 1e-15);         // face
  EXPECT_NEAR(pointTriangleDistance(Vec3(0.5, -3, 4), a, b, c), 5.0, 1e-15);            // edge ab
  EXPECT_NEAR(pointTriangleDistance(Vec3(-3, 0.5, 4), a, b, c), 5.0, 1e-15);            // edge ac
  EXPECT_NEAR(pointTriangleDistance(Vec3(1, 1, 0), a, b, c), std::sqrt(0.5), 1e-15);    // bc
  EXPECT_NEAR(pointTriangleDistance(Vec3(-1, -1, 0), a, b, c), std::sqrt(2.0), 1e-15);  // a
  EXPECT_NEAR(pointTriangleDistance(Vec3(3, -4, 0) + b, a, b, c), 5.0, 1e-15);          // vertex b
  EXPECT_NEAR(pointTriangleDistance(Vec3(-3, 4, 0) + c, a, b, c), 5.0, 1e-15);          // vertex c
}

// a 60 x 60 x 10 mm slab: inside negative (the nearest face), outside positive
TEST(MeshTet, SignedDistanceToTheSurfaceIsNegativeInside) {
  SlabSpec spec;
  spec.sizeM = Vec3(0.06, 0.06, 0.01);
  spec.nodesPerAxis = {7, 7, 3};
  const TetMesh mesh = makeSlab(spec);
  const std::vector<BoundaryFace> faces = boundaryFaces(mesh);
  EXPECT_NEAR(signedDistanceToSurface(mesh, faces, Vec3(0.001, 0.002, 0.006)), -0.004, 1e-12);
  EXPECT_NEAR(signedDistanceToSurface(mesh, faces, Vec3(0.001, 0.002, 0.0098)), -0.0002, 1e-12);
  EXPECT_NEAR(signedDistanceToSurface(mesh, faces, Vec3(0.001, 0.002, 0.013)), 0.003, 1e-12);
  EXPECT_NEAR(signedDistanceToSurface(mesh, faces, Vec3(0.034, 0, 0.005)), 0.004, 1e-12);
  EXPECT_EQ(signedDistanceToSurface(mesh, {}, Vec3::Zero()), INFINITY);
}

TEST(MeshTet, QualityOfRegularTet) {
  TetMesh m;
  m.nodes = {Vec3(1, 1, 1), Vec3(1, -1, -1), Vec3(-1, 1, -1), Vec3(-1, -1, 1)};
  m.tets = {{0, 1, 2, 3}};
  if (tetVolume(m, 0) < 0) std::swap(m.tets[0][2], m.tets[0][3]);
  const MeshQuality q = meshQuality(m);
  const double dihedral = std::acos(1.0 / 3.0) * 180.0 / M_PI;  // 70.53 deg
  EXPECT_NEAR(q.minDihedralDeg, dihedral, 1e-9);
  EXPECT_NEAR(q.maxDihedralDeg, dihedral, 1e-9);
  EXPECT_NEAR(q.maxRadiusEdgeRatio, std::sqrt(6.0) / 4.0, 1e-12);
  EXPECT_NEAR(q.minVolume, 8.0 / 3.0, 1e-12);
}

// the message thrown by validateMesh, or "" when it passes
std::string validationMessage(const TetMesh& m, const std::string& source) {
  try {
    validateMesh(m, source);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(MeshTet, ValidateNamesTheProblem) {
  EXPECT_EQ(validationMessage(twoTets(), "ok.vtu"), "");
  EXPECT_EQ(validationMessage(TetMesh{}, "empty.vtu"),
            "empty.vtu: mesh is empty (0 nodes, 0 tetrahedra); expected at least one tetrahedron");
  TetMesh inverted = twoTets();
  std::swap(inverted.tets[1][0], inverted.tets[1][1]);
  EXPECT_EQ(
      validationMessage(inverted, "inv.vtu")
          .rfind("inv.vtu: tetrahedron 1 (nodes 4 1 2 3) is inverted (signed volume -0.333", 0),
      0u)
      << validationMessage(inverted, "inv.vtu");
  TetMesh flat = twoTets();
  flat.nodes[4] = Vec3(0.5, 0.5, 0);  // coplanar with nodes 1, 2 ... and 3? make it degenerate:
  flat.nodes[4] = Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3);  // on the face (1,2,3): zero volume
  EXPECT_NE(validationMessage(flat, "flat.vtu").find("flat.vtu: tetrahedron 1"), std::string::npos);
  EXPECT_NE(validationMessage(flat, "flat.vtu").find("has zero volume"), std::string::npos);
  TetMesh bad_id = twoTets();
  bad_id.tets[0][3] = 9;
  EXPECT_EQ(validationMessage(bad_id, "id.vtu"),
            "id.vtu: tetrahedron 0 refers to node 9 but the mesh has 5 nodes");
}

// a 6 x 6 x 4-node slab (20 x 20 x 10 mm), every tet alive
TetMesh removalSlab() {
  SlabSpec spec;
  spec.sizeM = Vec3(0.02, 0.02, 0.01);
  spec.nodesPerAxis = {6, 6, 4};
  TetMesh mesh = makeSlab(spec);
  mesh.alive.assign(mesh.tets.size(), 1);
  return mesh;
}

// up to `tries` pseudo-random alive tets (distinct), marked dead in the mesh
std::vector<int> removeRandomBatch(TetMesh& mesh, unsigned& seed, int tries) {
  std::vector<int> removed;
  for (int k = 0; k < tries; ++k) {
    seed = seed * 1103515245u + 12345u;
    const int e = static_cast<int>((seed >> 8) % mesh.tets.size());
    if (mesh.alive[e] && std::find(removed.begin(), removed.end(), e) == removed.end())
      removed.push_back(e);
  }
  for (int e : removed) mesh.alive[e] = 0;
  return removed;
}

// boundaryFaceIndex is the index faceAt's faces come from: boundaryFaces' order, the face
// given back by the tet's face opposite that vertex, whatever the face's first node
TEST(MeshTet, BoundaryFaceIndexGivesTheFaceBack) {
  TetMesh mesh = removalSlab();
  unsigned seed = 7;
  removeRandomBatch(mesh, seed, 40);
  const std::vector<BoundaryFace> faces = boundaryFaces(mesh);
  ASSERT_GT(faces.size(), 0u);
  int last = -1;
  for (const BoundaryFace& f : faces) {
    const int w = boundaryFaceIndex(mesh, f);
    EXPECT_GT(w, last);  // strictly ascending: boundaryFaces' order
    last = w;
    EXPECT_EQ(w / 4, f.tet);
    const Tet& t = mesh.tets[f.tet];
    EXPECT_EQ(std::count(f.nodes.begin(), f.nodes.end(), t[w % 4]), 0);
    // the same face rotated: the same index
    const BoundaryFace rotated{{f.nodes[1], f.nodes[2], f.nodes[0]}, f.tet};
    EXPECT_EQ(boundaryFaceIndex(mesh, rotated), w);
  }
}

// the surface edited by removeFromBoundary is boundaryFaces of the new alive set: the same
// faces in the same order, batch after batch (a slab, tets removed in a pseudo-random order)
TEST(MeshTet, RemoveFromBoundaryIsTheBoundaryOfTheAliveSet) {
  TetMesh mesh = removalSlab();
  const auto neighbours = tetFaceNeighbours(mesh);
  std::vector<BoundaryFace> faces = boundaryFaces(mesh);
  unsigned seed = 12345;
  int alive = mesh.numTets();
  while (alive > 10) {
    const std::vector<int> removed = removeRandomBatch(mesh, seed, 7);
    alive -= static_cast<int>(removed.size());
    removeFromBoundary(mesh, neighbours, removed, faces);
    const std::vector<BoundaryFace> fresh = boundaryFaces(mesh);
    ASSERT_EQ(faces.size(), fresh.size());
    for (size_t i = 0; i < fresh.size(); ++i) {
      ASSERT_EQ(faces[i].tet, fresh[i].tet) << i;
      ASSERT_EQ(faces[i].nodes, fresh[i].nodes) << i;
    }
  }
}

// updateBoundaryNodes after each batch of random removals (orphaned nodes, holes, pieces
// cut loose) is boundaryNodes of the fresh boundary, and what it says left or joined is
// exactly the difference
TEST(MeshTet, UpdateBoundaryNodesIsTheBoundaryNodesOfTheAliveSet) {
  TetMesh mesh = removalSlab();
  const auto neighbours = tetFaceNeighbours(mesh);
  const Adjacency tetsAt = nodeTets(mesh);
  std::vector<int> nodes = boundaryNodes(mesh, boundaryFaces(mesh));
  unsigned seed = 777;
  int alive = mesh.numTets(), joinedAny = 0, leftAny = 0;
  while (alive > 5) {
    const std::vector<int> removed = removeRandomBatch(mesh, seed, 9);
    alive -= static_cast<int>(removed.size());
    const std::vector<int> before = nodes;
    const BoundaryNodeChange change = updateBoundaryNodes(mesh, neighbours, tetsAt, removed, nodes);
    const std::vector<int> fresh = boundaryNodes(mesh, boundaryFaces(mesh));
    ASSERT_EQ(nodes, fresh) << alive << " tets alive";
    std::vector<int> left, joined;
    std::set_difference(before.begin(), before.end(), fresh.begin(), fresh.end(),
                        std::back_inserter(left));
    std::set_difference(fresh.begin(), fresh.end(), before.begin(), before.end(),
                        std::back_inserter(joined));
    EXPECT_EQ(change.left, left);
    EXPECT_EQ(change.joined, joined);
    joinedAny += !joined.empty();
    leftAny += !left.empty();
  }
  EXPECT_GT(joinedAny, 0);  // interior nodes exposed
  EXPECT_GT(leftAny, 0);    // nodes orphaned
}

// aliveNodes: the nodes of the alive tets; nodesWithoutAliveTets after each batch of random
// removals is exactly what aliveNodes lost (tool.contact volume's candidates)
TEST(MeshTet, NodesWithoutAliveTetsAreWhatTheAliveNodesLost) {
  TetMesh pair = twoTets();
  EXPECT_EQ(aliveNodes(pair), (std::vector<int>{0, 1, 2, 3, 4}));
  pair.alive = {1, 0};
  EXPECT_EQ(aliveNodes(pair), (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(nodesOfTets(pair, {1}), (std::vector<int>{1, 2, 3, 4}));  // dead or alive
  EXPECT_EQ(nodesOfTets(pair, {1, 0, 1}), (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_EQ(nodesWithoutAliveTets(pair, nodeTets(twoTets()), {1}), std::vector<int>{4});
  TetMesh mesh = removalSlab();
  const Adjacency tetsAt = nodeTets(mesh);
  std::vector<int> nodes = aliveNodes(mesh);
  EXPECT_EQ(static_cast<int>(nodes.size()), mesh.numNodes());
  unsigned seed = 91;
  int lost = 0;
  while (mesh.numAlive() > 5) {
    const std::vector<int> removed = removeRandomBatch(mesh, seed, 9);
    const std::vector<int> fresh = aliveNodes(mesh);
    std::vector<int> gone;
    std::set_difference(nodes.begin(), nodes.end(), fresh.begin(), fresh.end(),
                        std::back_inserter(gone));
    ASSERT_EQ(nodesWithoutAliveTets(mesh, tetsAt, removed), gone) << mesh.numAlive();
    lost += static_cast<int>(gone.size());
    nodes = fresh;
  }
  EXPECT_GT(lost, 0);
}

}  // namespace
}  // namespace esim
