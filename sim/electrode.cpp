// electrode.cpp - tool distance, contact search and the return pad (see electrode.h).
#include "sim/electrode.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "sim/core_error.h"

namespace esim {

namespace {
void checkShape(const ElectrodeShape& shape, double contactDistanceM) {
  ESIM_VERIFY(std::isfinite(shape.radiusM) && shape.radiusM >= 0,
              "electrode: radiusM must be finite and >= 0");
  ESIM_VERIFY(std::isfinite(shape.lengthM) && shape.lengthM >= 0,
              "electrode: lengthM must be finite and >= 0");
  ESIM_VERIFY(std::isfinite(shape.widthM) && shape.widthM >= 0,
              "electrode: widthM must be finite and >= 0");
  ESIM_VERIFY(std::isfinite(contactDistanceM) && contactDistanceM >= 0,
              "electrode: contact distance must be finite and >= 0");
}
}  // namespace

double electrodeDistance(const ElectrodeShape& shape, const ToolPose& pose, const Vec3& pointM) {
  const Vec3 q = pose.orientation.normalized().conjugate() * (pointM - pose.tipM);
  if (shape.kind == ElectrodeKind::Sphere) return q.norm() - shape.radiusM;
  // blade: distance to the rectangle |x| <= w/2, y = 0, 0 <= z <= L, minus the thickness
  const double dx = std::max(std::abs(q.x()) - 0.5 * shape.widthM, 0.0);
  const double dz = q.z() < 0 ? -q.z() : std::max(q.z() - shape.lengthM, 0.0);
  return std::sqrt(dx * dx + q.y() * q.y() + dz * dz) - shape.radiusM;
}

Eigen::AlignedBox3d electrodeBounds(const ElectrodeShape& shape, const ToolPose& pose,
                                    double marginM) {
  const double m = shape.radiusM + marginM;
  Eigen::AlignedBox3d box;
  if (shape.kind == ElectrodeKind::Sphere) {
    box.extend(pose.tipM - Vec3::Constant(m));
    box.extend(pose.tipM + Vec3::Constant(m));
    return box;
  }
  const Eigen::Quaterniond r = pose.orientation.normalized();
  for (double x : {-0.5 * shape.widthM, 0.5 * shape.widthM})
    for (double z : {0.0, shape.lengthM}) {
      const Vec3 corner = pose.tipM + r * Vec3(x, 0, z);
      box.extend(corner - Vec3::Constant(m));
      box.extend(corner + Vec3::Constant(m));
    }
  return box;
}

std::vector<int> findContacts(const TetMesh& mesh, const std::vector<int>& surfaceNodes,
                              const ElectrodeShape& shape, const ToolPose& pose,
                              double contactDistanceM) {
  checkShape(shape, contactDistanceM);
  const Eigen::AlignedBox3d box = electrodeBounds(shape, pose, contactDistanceM);
  std::vector<int> out;
  for (int id : surfaceNodes) {
    ESIM_VERIFY(id >= 0 && id < mesh.numNodes(), "findContacts: surface node id out of range");
    const Vec3& p = mesh.nodes[id];
    if (!box.contains(p)) continue;
    if (electrodeDistance(shape, pose, p) <= contactDistanceM) out.push_back(id);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

// ---- ContactFinder ----

ContactFinder::ContactFinder(const TetMesh& mesh, const std::vector<int>& surfaceNodes) {
  if (surfaceNodes.empty()) return;
  for (int id : surfaceNodes) {
    ESIM_VERIFY(id >= 0 && id < mesh.numNodes(), "ContactFinder: surface node id out of range");
    bounds_.extend(mesh.nodes[id]);
  }
  // about 2 nodes per cell on a surface: cell ~ sqrt(area / nodes)
  const Vec3 ext = bounds_.sizes();
  const double area = std::max({ext.x() * ext.y(), ext.y() * ext.z(), ext.x() * ext.z(), 1e-30});
  cellM_ = std::max(std::sqrt(2.0 * area / surfaceNodes.size()), 1e-9);
  // grow the cell until the grid holds at most ~4 cells per node
  for (;;) {
    for (int a = 0; a < 3; ++a)
      dims_[a] = std::clamp(static_cast<int>(ext[a] / cellM_) + 1, 1, 1 << 20);
    if (static_cast<double>(dims_[0]) * dims_[1] * dims_[2] <= 4.0 * surfaceNodes.size() + 64)
      break;
    cellM_ *= 1.5;
  }
  const int ncell = dims_.prod();
  cellStart_.assign(ncell + 1, 0);
  std::vector<int> sorted(surfaceNodes);
  std::sort(sorted.begin(), sorted.end());
  sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
  for (int id : sorted) ++cellStart_[cellOf(mesh.nodes[id]) + 1];
  for (int c = 0; c < ncell; ++c) cellStart_[c + 1] += cellStart_[c];
  std::vector<int> fill(cellStart_.begin(), cellStart_.end() - 1);
  ids_.resize(sorted.size());
  points_.resize(sorted.size());
  for (int id : sorted) {
    const int slot = fill[cellOf(mesh.nodes[id])]++;
    ids_[slot] = id;
    points_[slot] = mesh.nodes[id];
  }
}

int ContactFinder::cellOf(const Vec3& p) const {
  Eigen::Array3i c;
  for (int a = 0; a < 3; ++a)
    c[a] = std::clamp(static_cast<int>((p[a] - bounds_.min()[a]) / cellM_), 0, dims_[a] - 1);
  return (c[2] * dims_[1] + c[1]) * dims_[0] + c[0];
}

void ContactFinder::update(const TetMesh& mesh, const std::vector<int>& left,
                           const std::vector<int>& joined) {
  if (left.empty() && joined.empty()) return;
  ESIM_VERIFY(!cellStart_.empty(), "ContactFinder::update: built on no surface");
  if (gone_.empty()) {
    gone_.assign(ids_.size(), 0);
    extra_.resize(cellStart_.size() - 1);
  }
  for (int id : left) {
    ESIM_VERIFY(id >= 0 && id < mesh.numNodes(), "ContactFinder: surface node id out of range");
    const int c = cellOf(mesh.nodes[id]);
    for (int s = cellStart_[c]; s < cellStart_[c + 1]; ++s)
      if (ids_[s] == id && !gone_[s]) {
        gone_[s] = 1;
        ++numGone_;
      }
    auto& more = extra_[c];
    for (size_t k = 0; k < more.size(); ++k)
      if (more[k].first == id) {
        more.erase(more.begin() + static_cast<long>(k));
        --numExtra_;
        break;
      }
  }
  for (int id : joined) {
    ESIM_VERIFY(id >= 0 && id < mesh.numNodes(), "ContactFinder: surface node id out of range");
    const int c = cellOf(mesh.nodes[id]);
    bool back = false;  // a node of the first surface that had left
    for (int s = cellStart_[c]; s < cellStart_[c + 1]; ++s)
      if (ids_[s] == id && gone_[s]) {
        gone_[s] = 0;
        --numGone_;
        back = true;
      }
    if (back) continue;
    extra_[c].emplace_back(id, mesh.nodes[id]);
    ++numExtra_;
  }
}

std::vector<int> ContactFinder::find(const ElectrodeShape& shape, const ToolPose& pose,
                                     double contactDistanceM) const {
  checkShape(shape, contactDistanceM);
  std::vector<int> out;
  if (ids_.empty()) return out;
  const Eigen::AlignedBox3d box = electrodeBounds(shape, pose, contactDistanceM);
  if (!box.intersects(bounds_)) return out;
  Eigen::Array3i lo, hi;
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::clamp(static_cast<int>(std::floor((box.min()[a] - bounds_.min()[a]) / cellM_)), 0,
                       dims_[a] - 1);
    hi[a] = std::clamp(static_cast<int>(std::floor((box.max()[a] - bounds_.min()[a]) / cellM_)), 0,
                       dims_[a] - 1);
  }
  for (int k = lo[2]; k <= hi[2]; ++k)
    for (int j = lo[1]; j <= hi[1]; ++j)
      for (int i = lo[0]; i <= hi[0]; ++i) {
        const int c = (k * dims_[1] + j) * dims_[0] + i;
        for (int s = cellStart_[c]; s < cellStart_[c + 1]; ++s) {
          if (!box.contains(points_[s]) || (!gone_.empty() && gone_[s])) continue;
          if (electrodeDistance(shape, pose, points_[s]) <= contactDistanceM)
            out.push_back(ids_[s]);
        }
        if (extra_.empty()) continue;
        for (const auto& [id, p] : extra_[c])
          if (box.contains(p) && electrodeDistance(shape, pose, p) <= contactDistanceM)
            out.push_back(id);
      }
  std::sort(out.begin(), out.end());
  return out;
}

// ---- return electrode ----

std::vector<int> returnElectrodeNodes(const TetMesh& mesh, const std::vector<int>& surfaceNodes,
                                      const ReturnElectrode& pad) {
  ESIM_VERIFY(pad.normal.allFinite() && pad.normal.norm() > 0,
              "return electrode: normal must be a nonzero finite vector");
  ESIM_VERIFY(pad.centerM.allFinite(), "return electrode: centre must be finite");
  ESIM_VERIFY(std::isfinite(pad.radiusM) && pad.radiusM > 0,
              "return electrode: radiusM must be > 0");
  ESIM_VERIFY(std::isfinite(pad.toleranceM) && pad.toleranceM >= 0,
              "return electrode: toleranceM must be >= 0");
  const Vec3 nrm = pad.normal.normalized();
  std::vector<int> out;
  for (int id : surfaceNodes) {
    ESIM_VERIFY(id >= 0 && id < mesh.numNodes(),
                "returnElectrodeNodes: surface node id out of range");
    const Vec3 d = mesh.nodes[id] - pad.centerM;
    const double h = d.dot(nrm);
    if (std::abs(h) > pad.toleranceM) continue;
    const double rho = (d - h * nrm).norm();
    if (rho <= pad.radiusM * (1 + 1e-12)) out.push_back(id);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace esim
