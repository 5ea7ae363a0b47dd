// fem_p1.cpp - P1 tetrahedral assembly (see fem_p1.h).
#include "sim/fem_p1.h"

#include <Eigen/Dense>
#include <algorithm>

namespace esim {

std::vector<TetGeometry> tetGeometry(const TetMesh& mesh) {
  std::vector<TetGeometry> geo(mesh.tets.size());
  for (int e = 0; e < mesh.numTets(); ++e) {
    const Tet& t = mesh.tets[e];
    const Vec3& p0 = mesh.nodes[t[0]];
    Eigen::Matrix3d j;  // columns: edges from p0
    j.col(0) = mesh.nodes[t[1]] - p0;
    j.col(1) = mesh.nodes[t[2]] - p0;
    j.col(2) = mesh.nodes[t[3]] - p0;
    const double det = j.determinant();
    geo[e].volume = det / 6.0;
    if (det == 0) {
      geo[e].grad.setZero();
      continue;
    }
    // grad N_{1..3} are the rows of J^-1; grad N_0 = -(sum of the others)
    const Eigen::Matrix3d jinv = j.inverse();
    geo[e].grad.row(1) = jinv.row(0);
    geo[e].grad.row(2) = jinv.row(1);
    geo[e].grad.row(3) = jinv.row(2);
    geo[e].grad.row(0) = -(jinv.row(0) + jinv.row(1) + jinv.row(2));
  }
  return geo;
}

SparseMatrix patternOfZeros(int n, const std::vector<int>& outer, const std::vector<int>& inner) {
  SparseMatrix k(n, n);
  k.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), k.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), k.innerIndexPtr());
  std::fill(k.valuePtr(), k.valuePtr() + inner.size(), -0.0);
  return k;
}

// The pattern (each node's alive tets' nodes, rows ascending in each column) first, then
// each element matrix scattered in ascending tet order onto -0.0, the additive identity: every
// entry is summed left to right from its first tet's term, bitwise what setFromTriplets gave
// for the triplets emitted tet by tet, without their 16 a tet (1.5 GB at a million nodes) and
// their sort. Measured against it: `esim validate scenarios/slab_cut.yaml --set
// mesh.slab.nodes=1000000` 30.6 -> 22.2 s, peak memory 4.39 -> 2.43 GB; `esim run
// scenarios/fine_cut.yaml` (49 950 nodes) set-up 5.0-5.1 -> 4.4 s.
SparseMatrix assembleStiffness(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                               const std::vector<double>& coeff) {
  const int n = mesh.numNodes();
  const Adjacency tets = nodeTets(mesh);
  // the pattern, column by column
  std::vector<int> outer(static_cast<size_t>(n) + 1, 0), inner, seen(n, -1);
  inner.reserve(tets.ids.size() * 4);
  for (int col = 0; col < n; ++col) {
    const size_t first = inner.size();
    for (const int* t = tets.begin(col); t != tets.end(col); ++t)
      for (int v : mesh.tets[*t])
        if (seen[v] != col) {
          seen[v] = col;
          inner.push_back(v);
        }
    std::sort(inner.begin() + static_cast<std::ptrdiff_t>(first), inner.end());
    outer[col + 1] = static_cast<int>(inner.size());
  }
  SparseMatrix k = patternOfZeros(n, outer, inner);
  double* value = k.valuePtr();
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    const Eigen::Matrix4d ke = coeff[e] * geo[e].volume * geo[e].grad * geo[e].grad.transpose();
    const Tet& t = mesh.tets[e];
    for (int b = 0; b < 4; ++b) {
      const int* lo = inner.data() + outer[t[b]];
      const int* hi = inner.data() + outer[t[b] + 1];
      for (int a = 0; a < 4; ++a) value[std::lower_bound(lo, hi, t[a]) - inner.data()] += ke(a, b);
    }
  }
  return k;
}

int removeFromStiffness(SparseMatrix& k, const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                        const std::vector<double>& coeff, const Adjacency& nodeTets,
                        const std::vector<int>& removed) {
  // the entries (row, column) the removed tets touched, each once
  std::vector<std::pair<int, int>> entries;
  for (int e : removed)
    for (int a : mesh.tets[e])
      for (int b : mesh.tets[e]) entries.emplace_back(a, b);
  std::sort(entries.begin(), entries.end());
  entries.erase(std::unique(entries.begin(), entries.end()), entries.end());
  for (const auto& [row, col] : entries) {
    // assembleStiffness's triplets of this entry: alive tets ascending, one per tet; Eigen's
    // setFromTriplets sums duplicates left to right from the first
    double sum = 0;
    bool first = true;
    for (const int* t = nodeTets.begin(row); t != nodeTets.end(row); ++t) {
      const int e = *t;
      if (!mesh.isAlive(e)) continue;
      const Tet& tet = mesh.tets[e];
      const auto pos = [&](int v) {
        return static_cast<int>(std::find(tet.begin(), tet.end(), v) - tet.begin());
      };
      const int a = pos(row), b = pos(col);
      if (b == 4) continue;
      // the same expression as assembleStiffness (bitwise the same value)
      const Eigen::Matrix4d ke = coeff[e] * geo[e].volume * geo[e].grad * geo[e].grad.transpose();
      sum = first ? ke(a, b) : sum + ke(a, b);
      first = false;
    }
    double* value = &k.coeffRef(row, col);  // in the pattern: a removed tet had it
    *value = sum;
  }
  return static_cast<int>(entries.size());
}

SparseMatrix assembleMass(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                          const std::vector<double>& coeff) {
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(mesh.numAlive()) * 16);
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    const double m = coeff[e] * geo[e].volume / 20.0;
    const Tet& t = mesh.tets[e];
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) trip.emplace_back(t[a], t[b], a == b ? 2 * m : m);
  }
  SparseMatrix mm(mesh.numNodes(), mesh.numNodes());
  mm.setFromTriplets(trip.begin(), trip.end());
  return mm;
}

Eigen::VectorXd lumpedMass(const TetMesh& mesh, const std::vector<TetGeometry>& geo,
                           const std::vector<double>& coeff) {
  Eigen::VectorXd m = Eigen::VectorXd::Zero(mesh.numNodes());
  for (int e = 0; e < mesh.numTets(); ++e) {
    if (!mesh.isAlive(e)) continue;
    const double q = coeff[e] * geo[e].volume / 4.0;
    for (int v : mesh.tets[e]) m[v] += q;
  }
  return m;
}

}  // namespace esim
