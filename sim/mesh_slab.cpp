// mesh_slab.cpp - structured slab meshes (see mesh_slab.h).
#include "sim/mesh_slab.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "sim/core_error.h"

namespace esim {

namespace {

// Coordinates of n nodes on [lo, hi] whose spacing is `ratio` times finer inside
// [fine_lo, fine_hi] (widened by width) and grows linearly to coarse over `width`.
std::vector<double> gradedAxis(double lo, double hi, int n, bool graded, double fine_lo,
                               double fine_hi, double ratio, double width) {
  std::vector<double> x(n);
  if (!graded || ratio <= 1.0) {
    for (int i = 0; i < n; ++i) x[i] = lo + (hi - lo) * i / (n - 1);
    x[n - 1] = hi;
    return x;
  }
  // density 1/h: 1 in the coarse zone, `ratio` in the fine zone, linear in between
  auto density = [&](double s) {
    const double d = s < fine_lo ? fine_lo - s : (s > fine_hi ? s - fine_hi : 0.0);
    if (d <= width) return ratio;
    if (d >= 2 * width) return 1.0;
    return ratio + (1.0 - ratio) * (d - width) / width;
  };
  // integrate the density on a fine sample grid and invert it
  const int samples = 20000;
  std::vector<double> cum(samples + 1, 0.0);
  const double ds = (hi - lo) / samples;
  for (int k = 0; k < samples; ++k) {
    const double s0 = lo + k * ds;
    cum[k + 1] = cum[k] + 0.5 * (density(s0) + density(s0 + ds)) * ds;
  }
  const double total = cum[samples];
  int k = 0;
  for (int i = 0; i < n; ++i) {
    const double target = total * i / (n - 1);
    while (k < samples - 1 && cum[k + 1] < target) ++k;
    const double f = (target - cum[k]) / std::max(cum[k + 1] - cum[k], 1e-300);
    x[i] = lo + (k + std::clamp(f, 0.0, 1.0)) * ds;
  }
  x[0] = lo;
  x[n - 1] = hi;
  return x;
}

}  // namespace

std::array<int, 3> slabNodesPerAxis(const SlabSpec& spec) {
  if (spec.nodesPerAxis[0] > 0) return spec.nodesPerAxis;
  const double lx = spec.sizeM.x(), ly = spec.sizeM.y(), lz = spec.sizeM.z();
  const double n = spec.targetNodes;
  std::array<int, 3> best{2, 2, 2};
  double best_score = INFINITY;
  // px along x; py follows the aspect Ly/Lx (+-1); pz >= 3 (two element layers)
  for (int px = 2; px <= 2000; ++px) {
    const int py0 = std::max(2, static_cast<int>(std::lround((px - 1) * ly / lx)) + 1);
    for (int py = std::max(2, py0 - 1); py <= py0 + 1; ++py) {
      for (int pz = 3; pz <= 400; ++pz) {
        const double count = static_cast<double>(px) * py * pz;
        if (count > 2 * n + 100) break;
        const double hx = lx / (px - 1), hz = lz / (pz - 1);
        const double score = std::abs(count - n) / n + 0.02 * std::abs(std::log(hx / hz));
        if (score < best_score) {
          best_score = score;
          best = {px, py, pz};
        }
      }
    }
    if (static_cast<double>(px) * px * 3 * ly / lx > 2 * n + 100) break;
  }
  return best;
}

TetMesh makeSlab(const SlabSpec& spec) {
  ESIM_VERIFY(spec.sizeM.minCoeff() > 0 && spec.sizeM.allFinite(),
              "slab: size must be positive in x, y and z [m]");
  const auto p = slabNodesPerAxis(spec);
  ESIM_VERIFY(p[0] >= 2 && p[1] >= 2 && p[2] >= 2,
              "slab: need at least 2 nodes per axis (targetNodes >= 8)");
  const auto& g = spec.grading;
  ESIM_VERIFY(!g.enabled || (g.ratio >= 1.0 && g.widthM > 0),
              "slab: grading ratio must be >= 1 and width > 0");
  const double lx = spec.sizeM.x(), ly = spec.sizeM.y(), lz = spec.sizeM.z();
  const auto xs = gradedAxis(-lx / 2, lx / 2, p[0], g.enabled, std::min(g.cutFrom.x(), g.cutTo.x()),
                             std::max(g.cutFrom.x(), g.cutTo.x()), g.ratio, g.widthM);
  const auto ys = gradedAxis(-ly / 2, ly / 2, p[1], g.enabled, std::min(g.cutFrom.y(), g.cutTo.y()),
                             std::max(g.cutFrom.y(), g.cutTo.y()), g.ratio, g.widthM);
  const auto zs = gradedAxis(0, lz, p[2], g.enabled && g.towardTop, lz, lz, g.ratio,
                             std::min(g.widthM, lz / 3));

  TetMesh mesh;
  const int px = p[0], py = p[1], pz = p[2];
  auto id = [&](int i, int j, int k) { return (k * py + j) * px + i; };
  mesh.nodes.resize(static_cast<size_t>(px) * py * pz);
  for (int k = 0; k < pz; ++k)
    for (int j = 0; j < py; ++j)
      for (int i = 0; i < px; ++i) mesh.nodes[id(i, j, k)] = Vec3(xs[i], ys[j], zs[k]);

  // 6 tets per hex: paths 000 -> e_a -> e_a + e_b -> 111 over the axis permutations
  static constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                      {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  mesh.tets.reserve(static_cast<size_t>(px - 1) * (py - 1) * (pz - 1) * 6);
  for (int k = 0; k + 1 < pz; ++k)
    for (int j = 0; j + 1 < py; ++j)
      for (int i = 0; i + 1 < px; ++i)
        for (const auto& perm : kPerm) {
          int c[3] = {i, j, k};
          Tet t;
          t[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 2; ++s) {
            c[perm[s]] += 1;
            t[s + 1] = id(c[0], c[1], c[2]);
          }
          t[3] = id(i + 1, j + 1, k + 1);
          if (tetSignedVolume(mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]],
                              mesh.nodes[t[3]]) < 0)
            std::swap(t[2], t[3]);
          mesh.tets.push_back(t);
        }
  mesh.alive.assign(mesh.tets.size(), 1);

  // node sets of the six faces (ids ascending by construction)
  for (int n = 0; n < mesh.numNodes(); ++n) {
    const int i = n % px, j = (n / px) % py, k = n / (px * py);
    if (k == pz - 1) mesh.nodeSets["top"].push_back(n);
    if (k == 0) mesh.nodeSets["bottom"].push_back(n);
    if (i == 0) mesh.nodeSets["xmin"].push_back(n);
    if (i == px - 1) mesh.nodeSets["xmax"].push_back(n);
    if (j == 0) mesh.nodeSets["ymin"].push_back(n);
    if (j == py - 1) mesh.nodeSets["ymax"].push_back(n);
  }
  return mesh;
}

}  // namespace esim
