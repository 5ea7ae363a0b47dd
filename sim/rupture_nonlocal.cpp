// rupture_nonlocal.cpp - see rupture_nonlocal.h.
#include "sim/rupture_nonlocal.h"

#include <algorithm>
#include <cmath>

#include "sim/core_error.h"

namespace esim {

NonlocalStress::NonlocalStress(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                               double radiusM)
    : radiusM_(radiusM) {
  ESIM_VERIFY(std::isfinite(radiusM) && radiusM > 0,
              "material.critical_stress_radius_m must be > 0 for a nonlocal criterion, got " +
                  messageNumber(radiusM));
  ESIM_CHECK(static_cast<int>(geo.size()) == mesh.numTets());
  const int nt = mesh.numTets();
  centroid_.resize(nt);
  volume_.resize(nt);
  cellOf_.resize(nt);
  origin_ = Vec3::Constant(INFINITY);
  for (int e = 0; e < nt; ++e) {
    Vec3 c = Vec3::Zero();
    for (int v : mesh.tets[e]) c += mesh.nodes[v];
    centroid_[e] = c / 4.0;
    volume_[e] = geo[e].volume;
    origin_ = origin_.cwiseMin(centroid_[e]);
  }
  // cells of at least R (the 27 around a tet then hold every tet within R), and at most a
  // million a side (a radius of 1e-9 m on a 6 cm body would overflow the cell keys)
  Vec3 upper = origin_;
  for (const Vec3& c : centroid_) upper = upper.cwiseMax(c);
  cellM_ = std::max(radiusM_, (upper - origin_).maxCoeff() * 1e-6);
  for (int e = 0; e < nt; ++e) {
    const Vec3 g = (centroid_[e] - origin_) / cellM_;
    cellOf_[e] = {static_cast<long>(g.x()), static_cast<long>(g.y()), static_cast<long>(g.z())};
    cells_[cellKey(cellOf_[e][0], cellOf_[e][1], cellOf_[e][2])].push_back(e);
  }
  seen_.assign(nt, 0);
  // a frame in which every tet is a candidate visits every tet of the 27 cells around each:
  // bounded up front, never a frame of minutes (a radius of the body's size on the liver's
  // 161 323 tets would be 2.6e10 pairs)
  double pairs = 0;
  for (const auto& [key, tets] : cells_) {
    double around = 0;
    forCellsAround(cellOf_[tets.front()], [&](const std::vector<int>& cell) {
      around += static_cast<double>(cell.size());
    });
    pairs += static_cast<double>(tets.size()) * around;
  }
  ESIM_VERIFY(pairs <= kMaxPairs,
              "material.critical_stress_radius_m = " + messageNumber(radiusM) +
                  " m: a frame's average could visit " + messageNumber(pairs) +
                  " pairs of tets on this mesh of " + std::to_string(nt) + " tets (at most " +
                  messageNumber(kMaxPairs) +
                  "); use a radius of a few elements (the nonlocal length, not the body's)");
}

// 21 bits a coordinate: a grid of 2 million cells a side (checked: a body 2e6 R long)
std::uint64_t NonlocalStress::cellKey(long i, long j, long k) const {
  constexpr long kMax = (1L << 21) - 1;
  ESIM_CHECK(i >= -1 && j >= -1 && k >= -1 && i < kMax && j < kMax && k < kMax);
  return (static_cast<std::uint64_t>(i + 1) << 42) | (static_cast<std::uint64_t>(j + 1) << 21) |
         static_cast<std::uint64_t>(k + 1);
}

// visit(tets) for each non-empty cell of the 27 around cell c (c included), in a fixed order
template <class Visit>
void NonlocalStress::forCellsAround(const std::array<long, 3>& c, Visit&& visit) const {
  for (long dk = -1; dk <= 1; ++dk)
    for (long dj = -1; dj <= 1; ++dj)
      for (long di = -1; di <= 1; ++di) {
        if (c[0] + di < 0 || c[1] + dj < 0 || c[2] + dk < 0) continue;
        const auto it = cells_.find(cellKey(c[0] + di, c[1] + dj, c[2] + dk));
        if (it != cells_.end()) visit(it->second);
      }
}

// visit(j, w) for every alive tet j with its centroid within R of e's (e included), w the
// bell 1 - d^2 / R^2; cells in a fixed order, tets ascending in each: a fixed sum order
template <class Visit>
void NonlocalStress::forNeighbours(const TetMesh& mesh, int e, Visit&& visit) const {
  const double r2 = radiusM_ * radiusM_;
  forCellsAround(cellOf_[e], [&](const std::vector<int>& cell) {
    for (int j : cell) {
      if (!mesh.isAlive(j)) continue;
      const double d2 = (centroid_[j] - centroid_[e]).squaredNorm();
      if (d2 < r2) visit(j, 1.0 - d2 / r2);
    }
  });
}

double NonlocalStress::average(const TetMesh& mesh, const std::vector<double>& field, int e) const {
  double sumW = 0, sum = 0;
  int count = 0;
  forNeighbours(mesh, e, [&](int j, double w) {
    sumW += w * volume_[j];
    sum += w * volume_[j] * field[j];
    ++count;
  });
  // alone within R: its own value, bit for bit (the paper's criterion)
  return count > 1 ? sum / sumW : field[e];
}

std::vector<int> NonlocalStress::broken(const TetMesh& mesh, const std::vector<double>& local,
                                        double limit) const {
  std::vector<int> candidates;
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e) || !(local[e] > limit)) continue;
    forNeighbours(mesh, e, [&](int j, double) {
      if (!seen_[j]) {
        seen_[j] = 1;
        candidates.push_back(j);
      }
    });
  }
  std::vector<int> out;
  for (int j : candidates) {
    seen_[j] = 0;
    if (average(mesh, local, j) > limit) out.push_back(j);
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace esim
