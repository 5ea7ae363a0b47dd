// tool_mesh.cpp - the electrode's triangle mesh (see tool_mesh.h).
#include "render/tool_mesh.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "render/vertex_layout.h"

namespace esim::render_detail {
namespace {

// tool parts in the tool frame (z = axis from tip to handle), metres
struct ToolMeshBuilder {
  std::vector<float> out;
  static constexpr std::array<float, 4> kMetal{0.70f, 0.71f, 0.73f, 0.0f};
  static constexpr std::array<float, 4> kInsulation{0.13f, 0.13f, 0.14f, 1.0f};
  static constexpr std::array<float, 4> kHandle{0.80f, 0.81f, 0.79f, 2.0f};

  void tri(V3 a, V3 b, V3 c, V3 na, V3 nb, V3 nc, const std::array<float, 4>& m) {
    pushVertex(out, a, na, m);
    pushVertex(out, b, nb, m);
    pushVertex(out, c, nc, m);
  }
  // frustum of a cone along z from (z0, r0) to (z1, r1), with end caps
  void cone(float z0, float r0, float z1, float r1, const std::array<float, 4>& m, int seg = 24) {
    const float slope = (r0 - r1) / std::max(1e-9f, z1 - z0);
    for (int i = 0; i < seg; ++i) {
      const float a0 = 2 * 3.14159265f * i / seg, a1 = 2 * 3.14159265f * (i + 1) / seg;
      const V3 d0{std::cos(a0), std::sin(a0), 0}, d1{std::cos(a1), std::sin(a1), 0};
      const V3 n0 = normalized({d0[0], d0[1], slope}), n1 = normalized({d1[0], d1[1], slope});
      const V3 p00{r0 * d0[0], r0 * d0[1], z0}, p01{r0 * d1[0], r0 * d1[1], z0};
      const V3 p10{r1 * d0[0], r1 * d0[1], z1}, p11{r1 * d1[0], r1 * d1[1], z1};
      tri(p00, p01, p11, n0, n1, n1, m);
      tri(p00, p11, p10, n0, n1, n0, m);
      tri({0, 0, z0}, p01, p00, {0, 0, -1}, {0, 0, -1}, {0, 0, -1}, m);
      tri({0, 0, z1}, p10, p11, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}, m);
    }
  }
  void sphere(float r, const std::array<float, 4>& m, int seg = 24, int rings = 16) {
    auto at = [&](int i, int j) {
      const float th = 3.14159265f * j / rings, ph = 2 * 3.14159265f * i / seg;
      return V3{std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)};
    };
    for (int j = 0; j < rings; ++j)
      for (int i = 0; i < seg; ++i) {
        const V3 a = at(i, j), b = at(i + 1, j), c = at(i + 1, j + 1), d = at(i, j + 1);
        tri(mul(a, r), mul(d, r), mul(c, r), a, d, c, m);
        tri(mul(a, r), mul(c, r), mul(b, r), a, c, b, m);
      }
  }
  // flat spatula: rounded front (half disc of radius w/2) at z = 0, straight to
  // z = len, thickness 2*halfT in y
  void blade(float w, float halfT, float len, const std::array<float, 4>& m) {
    const int arc = 12;
    std::vector<std::array<float, 2>> outline;  // (x, z), counter-clockwise seen from +y
    const float r = w / 2;
    for (int i = 0; i <= arc; ++i) {
      const float a = 3.14159265f * (1.0f + static_cast<float>(i) / arc);  // pi..2pi
      outline.push_back({r * std::cos(a), r + r * std::sin(a)});
    }
    outline.push_back({r, len});
    outline.push_back({-r, len});
    const int n = static_cast<int>(outline.size());
    const V3 centre{0, 0, 0.5f * (r + len)};
    for (int i = 0; i < n; ++i) {
      const auto& p = outline[i];
      const auto& q = outline[(i + 1) % n];
      const V3 pf{p[0], halfT, p[1]}, qf{q[0], halfT, q[1]};
      const V3 pb{p[0], -halfT, p[1]}, qb{q[0], -halfT, q[1]};
      // faces (+y and -y), fans from the centre
      tri({centre[0], halfT, centre[2]}, qf, pf, {0, 1, 0}, {0, 1, 0}, {0, 1, 0}, m);
      tri({centre[0], -halfT, centre[2]}, pb, qb, {0, -1, 0}, {0, -1, 0}, {0, -1, 0}, m);
      // rim: outward normal in the x-z plane (smooth round the arc)
      auto rimNormal = [&](const std::array<float, 2>& s, int idx) {
        if (idx <= arc) return normalized({s[0], 0, s[1] - r});
        return V3{0, 0, 1};
      };
      V3 np = rimNormal(p, i), nq = rimNormal(q, (i + 1) % n);
      if (i == arc) {
        np = {1, 0, 0};
        nq = {1, 0, 0};
      }  // right straight side
      if (i == arc + 1) {
        np = {0, 0, 1};
        nq = {0, 0, 1};
      }  // back end
      if (i == arc + 2) {
        np = {-1, 0, 0};
        nq = {-1, 0, 0};
      }  // left straight side
      tri(pf, qf, qb, np, nq, nq, m);
      tri(pf, qb, pb, np, nq, np, m);
    }
  }
};

}  // namespace

std::vector<float> buildToolVertices(const ToolSnapshot& tool) {
  ToolMeshBuilder b;
  const float L = std::max(tool.lengthM, 1e-3f);
  const float handleR = kHandleRadiusM, handleLen = kHandleLengthM;
  if (tool.kind == ElectrodeKind::Blade) {
    const float w = std::max(tool.widthM, 2 * tool.radiusM);
    const float bladeLen = 0.45f * L;
    const float shaftR = 0.55f * w;  // covers the blade's back end
    b.blade(w, std::max(tool.radiusM, 1e-5f), bladeLen, ToolMeshBuilder::kMetal);
    b.cone(0.9f * bladeLen, shaftR, L, shaftR, ToolMeshBuilder::kInsulation);
    b.cone(L, shaftR, L + 0.012f, handleR, ToolMeshBuilder::kHandle);
    b.cone(L + 0.012f, handleR, L + handleLen, handleR, ToolMeshBuilder::kHandle);
  } else {
    const float r = std::max(tool.radiusM, 1e-5f);
    const float neckR = std::max(0.35f * r, 3e-4f);
    b.sphere(r, ToolMeshBuilder::kMetal);
    b.cone(0.5f * r, neckR, 0.35f * L, neckR, ToolMeshBuilder::kMetal);
    b.cone(0.35f * L, 1.6f * neckR, L, 1.6f * neckR, ToolMeshBuilder::kInsulation);
    b.cone(L, 1.6f * neckR, L + 0.012f, handleR, ToolMeshBuilder::kHandle);
    b.cone(L + 0.012f, handleR, L + handleLen, handleR, ToolMeshBuilder::kHandle);
  }
  return std::move(b.out);
}

bool sameToolShape(const ToolSnapshot& a, const ToolSnapshot& b) {
  return a.kind == b.kind && a.radiusM == b.radiusM && a.lengthM == b.lengthM &&
         a.widthM == b.widthM;
}

V3 toolShadowSizes(const ToolSnapshot& tool) {
  const float shaftR = tool.kind == ElectrodeKind::Blade
                           ? 0.5f * std::max(tool.widthM, 2 * tool.radiusM)
                           : std::max(tool.radiusM, 3e-4f);
  return V3{std::max(tool.lengthM, 1e-3f), shaftR, kHandleRadiusM};
}

}  // namespace esim::render_detail
