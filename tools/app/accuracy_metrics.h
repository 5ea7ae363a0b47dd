// accuracy_metrics.h - how far a cut is from a reference cut, when the two were computed on
// different meshes (`esim bench accuracy`).
//
// Removed regions of two meshes cannot be compared tet by tet, so both are sampled on one
// voxel grid fixed in space: a voxel is removed when its centre lies in a removed (not
// alive) tet. On that grid: the intersection over union of two removed regions, and the
// groove's width and depth. Point probes are located once (the mesh's rest positions do
// not move; displacement is drawn, not simulated into the positions) and read nodal fields
// by linear interpolation in their tet. Lengths [m], volumes [m^3].
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "sim/fem_p1.h"
#include "sim/mesh_tet.h"

namespace esim::app {

// a box split into cells[0] x cells[1] x cells[2] voxels; voxel (i, j, k) is at index
// i + cells[0] * (j + cells[1] * k)
struct VoxelGrid {
  Eigen::AlignedBox3d boxM;
  std::array<int, 3> cells{1, 1, 1};
  Vec3 cellSizeM() const;
  Vec3 centreM(int i, int j, int k) const;
  std::size_t size() const;
};

// per voxel of the grid: 1 when its centre lies in a removed tet of the mesh (a centre on
// a face shared by a removed and an alive tet counts as removed)
std::vector<std::uint8_t> removedVoxels(const TetMesh& mesh, const VoxelGrid& grid);

// |A and B| / |A or B| of two indicators on the same grid; 1 when both are empty
double intersectionOverUnion(const std::vector<std::uint8_t>& a,
                             const std::vector<std::uint8_t>& b);

// the groove of a cut along x (the bench's blade path), from the removed voxels
struct GrooveShape {
  double removedVolumeM3 = 0;  // sum of the removed tets' volumes (exact, not voxelised)
  double widthM = 0;           // median over the cross-sections x = const holding removed voxels of
                               // their extent in y (voxel edges)
  double depthM = 0;           // median over the same sections of topZ - the lowest removed voxel's
                               // bottom
  int sections = 0;            // cross-sections with removed voxels
};
GrooveShape grooveShape(const TetMesh& mesh, const VoxelGrid& grid,
                        const std::vector<std::uint8_t>& removed, double topZM);

// the removed tets against a straight blade path p0 -> p1, each by its centroid
struct RemovedExtents {
  int tets = 0;
  double volumeM3 = 0;
  double alongMinM = INFINITY, alongMaxM = -INFINITY;  // centroid along the path, from p0
  double maxOffPathM = 0;  // largest horizontal (xy) distance of a centroid from the path
  double maxDepthM = 0;    // topZM - the lowest node of a removed tet
};
RemovedExtents removedTetExtents(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                                 const Vec3& p0M, const Vec3& p1M, double topZM);

// a point located in a tet: the tet and the point's barycentric coordinates
struct ProbeLocation {
  int tet = -1;  // -1: outside the mesh
  std::array<double, 4> bary{0, 0, 0, 0};
};

// locates each point in the mesh's tets (alive or not; brute force, once per mesh)
std::vector<ProbeLocation> locateProbes(const TetMesh& mesh, const std::vector<Vec3>& pointsM);

// a nodal field at a located probe (linear in its tet); NaN outside the mesh
double sampleNodal(const TetMesh& mesh, const Eigen::VectorXd& field, const ProbeLocation& probe);

// sum over all tets of value[tet] * volume (e.g. the vaporised fraction: vaporised volume)
double volumeIntegral(const TetMesh& mesh, const std::vector<double>& perTet);

// observed convergence order between two errors at two resolutions h1 > h2:
// log(e1 / e2) / log(h1 / h2); NaN when an error is 0 or not finite
double convergenceOrder(double h1, double e1, double h2, double e2);

// indices of the points (cost, error) on the Pareto front (no other point is at least as
// cheap and as accurate, and better in one); NaN errors are never on it
std::vector<int> paretoFront(const std::vector<double>& cost, const std::vector<double>& error);

}  // namespace esim::app
