// electrode.h - the active electrode (tool) geometry, its contact with the tissue
// surface, and the return electrode pad.
//
// Tool: a shape in local coordinates posed by ToolPose (tip position [m] and a
// rotation local -> world). Local +z is the tool axis from the tip toward the
// handle; local x is the blade width.
//   Sphere: the ball of radius radiusM centred at the tip.
//   Blade:  a flat spatula, the points within radiusM of the rectangle
//           {|x| <= widthM/2, y = 0, 0 <= z <= lengthM}; its tip edge passes
//           through the tip point.
// electrodeDistance is the signed distance to the electrode surface [m] (<= 0
// inside). Contact rule: the candidate nodes with distance <= contactDistanceM are
// held at the tool voltage; the candidates are the tissue's surface nodes (the paper's
// rule: a tool that touches the tissue from outside) or every node of the tissue
// (ContactNodes::Volume: a tool pushed into it, a needle, a buried ball). Contact sets
// are sorted node ids (deterministic).
// Return electrode: a disc pad (centre, normal, radius) pressed on the mesh; the
// surface nodes within toleranceM of its plane and within radiusM of its centre
// are grounded (0 V).
// All inputs are copied or read only; results are returned by value.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <utility>
#include <vector>

#include "sim/mesh_tet.h"
#include "sim/snapshot.h"

namespace esim {

// which nodes the tool may touch (tool.contact; the order of its names)
enum class ContactNodes : int { Surface = 0, Volume = 1 };

struct ElectrodeShape {
  ElectrodeKind kind = ElectrodeKind::Blade;
  double radiusM = 0.0005;  // sphere radius or blade half-thickness [m]
  double lengthM = 0.02;    // blade length along the axis, from the tip [m]
  double widthM = 0.003;    // blade width (local x) [m]
};

struct ToolPose {
  Vec3 tipM{0, 0, 0};                                               // tip position [m]
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // local -> world
};

// signed distance from pointM to the electrode surface [m], <= 0 inside
double electrodeDistance(const ElectrodeShape& shape, const ToolPose& pose, const Vec3& pointM);

// world-space axis-aligned box containing every point within `marginM` of the electrode
Eigen::AlignedBox3d electrodeBounds(const ElectrodeShape& shape, const ToolPose& pose,
                                    double marginM);

// sorted ids of the surfaceNodes within contactDistanceM of the electrode (brute force
// over the nodes with a bounding-box prefilter; use ContactFinder per frame)
std::vector<int> findContacts(const TetMesh& mesh, const std::vector<int>& surfaceNodes,
                              const ElectrodeShape& shape, const ToolPose& pose,
                              double contactDistanceM);

// A uniform grid over the surface nodes, built once per mesh topology (positions are
// copied; rebuild after moving or removing nodes). Queries visit only the cells the
// electrode's bounding box overlaps.
class ContactFinder {
 public:
  ContactFinder() = default;
  ContactFinder(const TetMesh& mesh, const std::vector<int>& surfaceNodes);
  // same result as findContacts(mesh, surfaceNodes, ...) for the mesh given at build
  std::vector<int> find(const ElectrodeShape& shape, const ToolPose& pose,
                        double contactDistanceM) const;
  // the surface's nodes edited in place after a cut (updateBoundaryNodes' change): the
  // nodes that left go, those that joined (inside the first surface's bounds, as every node
  // of the mesh is) come; afterwards find() is that of a finder built on the new nodes.
  // Cost: the changed nodes (each looked up in its cell), not the surface
  void update(const TetMesh& mesh, const std::vector<int>& left, const std::vector<int>& joined);
  int numNodes() const { return static_cast<int>(ids_.size()) - numGone_ + numExtra_; }

 private:
  int cellOf(const Vec3& p) const;
  Eigen::AlignedBox3d bounds_;
  Eigen::Array3i dims_{0, 0, 0};
  double cellM_ = 1;
  std::vector<int> cellStart_;  // CSR over cells
  std::vector<int> ids_;        // node ids sorted by cell
  std::vector<Vec3> points_;    // positions in the same order
  // update(): the slots whose node left, and per cell the nodes that joined
  std::vector<std::uint8_t> gone_;
  std::vector<std::vector<std::pair<int, Vec3>>> extra_;
  int numGone_ = 0, numExtra_ = 0;
};

struct ReturnElectrode {
  Vec3 centerM{0, 0, 0};     // disc centre [m] (the slab's bottom face is z = 0)
  Vec3 normal{0, 0, -1};     // outward normal of the pad's contact face
  double radiusM = 0.04;     // disc radius [m] (paper: 40 mm)
  double toleranceM = 1e-4;  // distance from the plane still in contact [m]
};

// sorted ids of the surfaceNodes within toleranceM of the disc's plane and within
// radiusM of its centre (measured in the plane); throws Error on a bad disc
std::vector<int> returnElectrodeNodes(const TetMesh& mesh, const std::vector<int>& surfaceNodes,
                                      const ReturnElectrode& pad);

}  // namespace esim
