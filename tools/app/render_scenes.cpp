// render_scenes.cpp - analytic snapshots for bench/samples (see render_scenes.h).
#include "tools/app/render_scenes.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "sim/core_error.h"
#include "sim/io/mesh_import.h"

namespace esim::app {
namespace {

void fillDefaults(SurfaceSnapshot& s) {
  const size_t nv = static_cast<size_t>(s.numVertices());
  s.temperatureC.assign(nv, 37.0f);
  s.coagulation.assign(nv, 0.0f);
  s.desiccation.assign(nv, 0.0f);
  s.cutWall.assign(nv, 0.0f);
}

double smoothstep(double a, double b, double x) {
  const double t = std::clamp((x - a) / (b - a), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

}  // namespace

SurfaceSnapshot slabSurface(const SlabSpec& spec) {
  const TetMesh mesh = makeSlab(spec);
  const auto faces = boundaryFaces(mesh);
  const std::vector<int> nodes = boundaryNodes(mesh, faces);  // sorted
  std::vector<int> newId(mesh.numNodes(), -1);
  SurfaceSnapshot s;
  for (size_t i = 0; i < nodes.size(); ++i) {
    newId[nodes[i]] = static_cast<int>(i);
    for (int k = 0; k < 3; ++k) s.positionsM.push_back(static_cast<float>(mesh.nodes[nodes[i]][k]));
  }
  for (const BoundaryFace& f : faces)
    for (int v : f.nodes) s.triangles.push_back(static_cast<std::uint32_t>(newId[v]));
  fillDefaults(s);
  return s;
}

SurfaceSnapshot icosphereSurface(double radiusM, int level, std::array<double, 3> c) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<std::array<double, 3>> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                          {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                          {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int l = 0; l < level; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back({(v[a][0] + v[b][0]) / 2, (v[a][1] + v[b][1]) / 2, (v[a][2] + v[b][2]) / 2});
      return mid[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& tri : f) {
      const int a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]),
                d = midpoint(tri[2], tri[0]);
      next.insert(next.end(), {{tri[0], a, d}, {tri[1], b, a}, {tri[2], d, b}, {a, b, d}});
    }
    f = std::move(next);
  }
  SurfaceSnapshot s;
  for (const auto& p : v) {
    const double n = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    for (int k = 0; k < 3; ++k)
      s.positionsM.push_back(static_cast<float>(c[k] + radiusM * p[k] / n));
  }
  for (const auto& tri : f)
    for (int k : tri) s.triangles.push_back(static_cast<std::uint32_t>(k));
  fillDefaults(s);
  return s;
}

SurfaceSnapshot fileSurface(const std::string& path) {
  SurfaceMesh surface = readSurface(path);
  orientOutward(surface);
  SurfaceSnapshot s;
  for (const Vec3& p : surface.vertices)
    for (int k = 0; k < 3; ++k) s.positionsM.push_back(static_cast<float>(p[k]));
  for (const Tri& t : surface.triangles)
    for (int k : t) s.triangles.push_back(static_cast<std::uint32_t>(k));
  fillDefaults(s);
  return s;
}

std::array<float, 4> toolOrientation(std::array<double, 3> axis) {
  const double an = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
  ESIM_VERIFY(an > 0, "tool axis is zero");
  const double z[3] = {axis[0] / an, axis[1] / an, axis[2] / an};
  double x[3] = {1 - z[0] * z[0], -z[0] * z[1], -z[0] * z[2]};  // e_x minus its z part
  const double xn = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  ESIM_VERIFY(xn > 1e-6, "tool axis parallel to x is not supported here");
  for (double& e : x) e /= xn;
  const double y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2],
                       z[0] * x[1] - z[1] * x[0]};
  // rotation matrix R = [x y z] (columns) to a quaternion
  const double m00 = x[0], m11 = y[1], m22 = z[2];
  const double tr = m00 + m11 + m22;
  double w, qx, qy, qz;
  if (tr > 0) {
    const double s = std::sqrt(tr + 1.0) * 2;
    w = 0.25 * s;
    qx = (y[2] - z[1]) / s;
    qy = (z[0] - x[2]) / s;
    qz = (x[1] - y[0]) / s;
  } else if (m00 > m11 && m00 > m22) {
    const double s = std::sqrt(1.0 + m00 - m11 - m22) * 2;
    w = (y[2] - z[1]) / s;
    qx = 0.25 * s;
    qy = (y[0] + x[1]) / s;
    qz = (z[0] + x[2]) / s;
  } else if (m11 > m22) {
    const double s = std::sqrt(1.0 + m11 - m00 - m22) * 2;
    w = (z[0] - x[2]) / s;
    qx = (y[0] + x[1]) / s;
    qy = 0.25 * s;
    qz = (z[1] + y[2]) / s;
  } else {
    const double s = std::sqrt(1.0 + m22 - m00 - m11) * 2;
    w = (x[1] - y[0]) / s;
    qx = (z[0] + x[2]) / s;
    qy = (z[1] + y[2]) / s;
    qz = 0.25 * s;
  }
  return {static_cast<float>(w), static_cast<float>(qx), static_cast<float>(qy),
          static_cast<float>(qz)};
}

void applyAnalyticCut(const AnalyticCut& cut, double timeS, SurfaceSnapshot& s) {
  const double x0 = cut.startXM, x1 = cut.tipXM, topZ = cut.topZM;
  const std::array<double, 3> tip{x1, 0.0, topZ - 0.8 * cut.grooveDepthM};
  for (int v = 0; v < s.numVertices(); ++v) {
    float* p = &s.positionsM[3 * v];
    // distance to the cut segment on the top face, and where along it
    const double xs = std::clamp(static_cast<double>(p[0]), x0, x1);
    const double dx = p[0] - xs, dy = p[1], dz = p[2] - topZ;
    const double d2 = dx * dx + dy * dy + dz * dz;
    const double behindM = x1 - xs;  // how far behind the tip this part of the trail is
    // peak temperature ever reached (trail) and the current temperature (cooling trail + tip)
    const double peakC = 37.0 + 95.0 * std::exp(-d2 / (2 * 0.0021 * 0.0021));
    const double tx = p[0] - tip[0], ty = p[1] - tip[1], tz = p[2] - tip[2];
    const double tip2 = tx * tx + ty * ty + tz * tz;
    const double nowC = 37.0 +
                        70.0 * std::exp(-d2 / (2 * 0.0026 * 0.0026)) * std::exp(-behindM / 0.022) +
                        55.0 * std::exp(-tip2 / (2 * 0.0022 * 0.0022));
    s.temperatureC[v] = static_cast<float>(std::max(nowC, 37.0));
    s.coagulation[v] = static_cast<float>(smoothstep(58.0, 72.0, peakC));
    s.desiccation[v] = static_cast<float>(0.85 * smoothstep(112.0, 130.0, peakC));
    // groove on the top face along the finished part of the cut
    if (std::abs(p[2] - topZ) < 1e-7) {
      const double g2 = dx * dx + dy * dy;
      const double depth =
          cut.grooveDepthM * std::exp(-g2 / (2 * cut.grooveSigmaM * cut.grooveSigmaM));
      p[2] = static_cast<float>(topZ - depth);
      s.cutWall[v] = static_cast<float>(smoothstep(0.15, 0.5, depth / cut.grooveDepthM));
    }
  }
  s.timeS = timeS;
  s.tool.present = true;
  s.tool.generatorOn = true;
  s.tool.kind = ElectrodeKind::Blade;
  s.tool.tipM = {static_cast<float>(tip[0]), static_cast<float>(tip[1]),
                 static_cast<float>(tip[2])};
  s.tool.orientationWxyz = toolOrientation({-0.30, 0.18, 0.94});
  s.tool.radiusM = 0.0004f;
  s.tool.widthM = 0.0024f;
  s.tool.lengthM = 0.03f;
}

}  // namespace esim::app
