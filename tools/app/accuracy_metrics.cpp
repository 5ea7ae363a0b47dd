// accuracy_metrics.cpp - cut metrics across meshes (accuracy_metrics.h).
#include "tools/app/accuracy_metrics.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

namespace esim::app {

namespace {

// barycentric coordinates of p in tet e (sum 1)
std::array<double, 4> barycentric(const TetMesh& mesh, int e, const Vec3& p) {
  const Tet& t = mesh.tets[e];
  const Vec3& p0 = mesh.nodes[t[0]];
  Eigen::Matrix3d m;
  m.col(0) = mesh.nodes[t[1]] - p0;
  m.col(1) = mesh.nodes[t[2]] - p0;
  m.col(2) = mesh.nodes[t[3]] - p0;
  const Vec3 l = m.partialPivLu().solve(p - p0);
  return {1 - l.sum(), l[0], l[1], l[2]};
}

bool inside(const std::array<double, 4>& b) {
  constexpr double kTol = 1e-12;
  return b[0] >= -kTol && b[1] >= -kTol && b[2] >= -kTol && b[3] >= -kTol;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

Vec3 VoxelGrid::cellSizeM() const {
  return (boxM.max() - boxM.min()).cwiseQuotient(Vec3(cells[0], cells[1], cells[2]));
}

Vec3 VoxelGrid::centreM(int i, int j, int k) const {
  return boxM.min() + cellSizeM().cwiseProduct(Vec3(i + 0.5, j + 0.5, k + 0.5));
}

std::size_t VoxelGrid::size() const {
  return static_cast<std::size_t>(cells[0]) * cells[1] * cells[2];
}

std::vector<std::uint8_t> removedVoxels(const TetMesh& mesh, const VoxelGrid& grid) {
  std::vector<std::uint8_t> out(grid.size(), 0);
  const Vec3 h = grid.cellSizeM(), lo = grid.boxM.min();
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (mesh.isAlive(e)) continue;
    Eigen::AlignedBox3d b;
    for (int v : mesh.tets[e]) b.extend(mesh.nodes[v]);
    // voxel index ranges whose centres can lie in the tet's box
    std::array<int, 3> from{}, to{};
    for (int a = 0; a < 3; ++a) {
      from[a] = std::max(0, static_cast<int>(std::ceil((b.min()[a] - lo[a]) / h[a] - 0.5)));
      to[a] = std::min(grid.cells[a] - 1,
                       static_cast<int>(std::floor((b.max()[a] - lo[a]) / h[a] - 0.5)));
    }
    for (int k = from[2]; k <= to[2]; ++k)
      for (int j = from[1]; j <= to[1]; ++j)
        for (int i = from[0]; i <= to[0]; ++i) {
          const size_t idx = i + static_cast<size_t>(grid.cells[0]) * (j + grid.cells[1] * k);
          if (!out[idx] && inside(barycentric(mesh, e, grid.centreM(i, j, k)))) out[idx] = 1;
        }
  }
  return out;
}

double intersectionOverUnion(const std::vector<std::uint8_t>& a,
                             const std::vector<std::uint8_t>& b) {
  const size_t n = std::min(a.size(), b.size());
  long both = 0, either = 0;
  for (size_t i = 0; i < n; ++i) {
    both += a[i] && b[i];
    either += a[i] || b[i];
  }
  return either == 0 ? 1.0 : static_cast<double>(both) / either;
}

RemovedExtents removedTetExtents(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                                 const Vec3& p0M, const Vec3& p1M, double topZM) {
  RemovedExtents out;
  const Vec3 d = p1M - p0M;
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (mesh.isAlive(e)) continue;
    Vec3 c = Vec3::Zero();
    double zLow = INFINITY;
    for (int v : mesh.tets[e]) {
      c += 0.25 * mesh.nodes[v];
      zLow = std::min(zLow, mesh.nodes[v].z());
    }
    ++out.tets;
    out.volumeM3 += geo[e].volume;
    out.maxDepthM = std::max(out.maxDepthM, topZM - zLow);
    const double t = d.squaredNorm() > 0 ? (c - p0M).dot(d) / d.norm() : 0.0;
    const Vec3 q = d.squaredNorm() > 0 ? Vec3(p0M + d.normalized() * t) : p0M;
    out.maxOffPathM = std::max(out.maxOffPathM, std::hypot(c.x() - q.x(), c.y() - q.y()));
    out.alongMinM = std::min(out.alongMinM, t);
    out.alongMaxM = std::max(out.alongMaxM, t);
  }
  return out;
}

GrooveShape grooveShape(const TetMesh& mesh, const VoxelGrid& grid,
                        const std::vector<std::uint8_t>& removed, double topZM) {
  GrooveShape g;
  for (int e = 0; e < mesh.numTets(); ++e)
    if (!mesh.isAlive(e)) g.removedVolumeM3 += tetVolume(mesh, e);
  const Vec3 h = grid.cellSizeM();
  const auto [nx, ny, nz] = grid.cells;
  std::vector<double> widths, depths;
  for (int i = 0; i < nx; ++i) {
    int jMin = ny, jMax = -1, kMin = nz;
    for (int k = 0; k < nz; ++k)
      for (int j = 0; j < ny; ++j)
        if (removed[i + static_cast<size_t>(nx) * (j + ny * k)]) {
          jMin = std::min(jMin, j);
          jMax = std::max(jMax, j);
          kMin = std::min(kMin, k);
        }
    if (jMax < 0) continue;
    widths.push_back((jMax - jMin + 1) * h.y());
    depths.push_back(topZM - (grid.boxM.min().z() + kMin * h.z()));
  }
  g.sections = static_cast<int>(widths.size());
  g.widthM = median(widths);
  g.depthM = median(depths);
  return g;
}

std::vector<ProbeLocation> locateProbes(const TetMesh& mesh, const std::vector<Vec3>& pointsM) {
  std::vector<ProbeLocation> out(pointsM.size());
  for (size_t p = 0; p < pointsM.size(); ++p)
    for (int e = 0; e < mesh.numTets(); ++e) {
      Eigen::AlignedBox3d b;
      for (int v : mesh.tets[e]) b.extend(mesh.nodes[v]);
      if (!b.contains(pointsM[p])) continue;
      const auto bary = barycentric(mesh, e, pointsM[p]);
      if (inside(bary)) {
        out[p] = {e, bary};
        break;
      }
    }
  return out;
}

double sampleNodal(const TetMesh& mesh, const Eigen::VectorXd& field, const ProbeLocation& probe) {
  if (probe.tet < 0) return std::numeric_limits<double>::quiet_NaN();
  double v = 0;
  for (int c = 0; c < 4; ++c) v += probe.bary[c] * field[mesh.tets[probe.tet][c]];
  return v;
}

double volumeIntegral(const TetMesh& mesh, const std::vector<double>& perTet) {
  double sum = 0;
  for (int e = 0; e < mesh.numTets() && e < static_cast<int>(perTet.size()); ++e)
    sum += perTet[e] * tetVolume(mesh, e);
  return sum;
}

double convergenceOrder(double h1, double e1, double h2, double e2) {
  if (!(e1 > 0) || !(e2 > 0) || !std::isfinite(e1) || !std::isfinite(e2) || h1 == h2)
    return std::numeric_limits<double>::quiet_NaN();
  return std::log(e1 / e2) / std::log(h1 / h2);
}

std::vector<int> paretoFront(const std::vector<double>& cost, const std::vector<double>& error) {
  std::vector<int> front;
  const int n = static_cast<int>(cost.size());
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(error[i]) || !std::isfinite(cost[i])) continue;
    bool dominated = false;
    for (int j = 0; j < n && !dominated; ++j) {
      if (j == i || !std::isfinite(error[j]) || !std::isfinite(cost[j])) continue;
      dominated =
          cost[j] <= cost[i] && error[j] <= error[i] && (cost[j] < cost[i] || error[j] < error[i]);
    }
    if (!dominated) front.push_back(i);
  }
  return front;
}

}  // namespace esim::app
