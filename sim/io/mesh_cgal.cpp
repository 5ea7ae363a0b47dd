// mesh_cgal.cpp - every CGAL instantiation of ESim lives here (see mesh_cgal.h).
//
// A Mesh_3 unit takes minutes and GBs to compile, so this file is kept small and
// stable: self-intersection test (PMP) and Mesh_3 with a polyhedral domain, with
// constant size bounds or sizing fields refined around a segment (SegmentSizing).
// Kernel: Epick (exact predicates, inexact constructions). The polyhedral domain
// uses exact intersection constructions internally where it needs them.
// Under valgrind, CGAL's interval arithmetic self-check fails because valgrind
// does not emulate FPU rounding modes: compile with CGAL_DISABLE_ROUNDING_MATH_CHECK
// for valgrind runs (ASan/UBSan need nothing).
#include "sim/io/mesh_cgal.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polyhedral_mesh_domain_with_features_3.h>
#include <CGAL/Random.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/exude_mesh_3.h>
#include <CGAL/lloyd_optimize_mesh_3.h>
#include <CGAL/make_mesh_3.h>
#include <CGAL/perturb_mesh_3.h>

#include <algorithm>
#include <map>
#include <string>
#include <utility>

#include "sim/core_error.h"

namespace esim::cgal {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using CgalSurface = CGAL::Surface_mesh<Point>;
using Domain = CGAL::Polyhedral_mesh_domain_with_features_3<Kernel, CgalSurface>;
using Triangulation = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using Complex = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation, Domain::Corner_index,
                                                        Domain::Curve_index>;
using Criteria = CGAL::Mesh_criteria_3<Triangulation>;

// ---- surface conversion ----
CgalSurface toCgal(const SurfaceMesh& surface) {
  CgalSurface sm;
  std::vector<CgalSurface::Vertex_index> vh;
  vh.reserve(surface.vertices.size());
  for (const Vec3& p : surface.vertices) vh.push_back(sm.add_vertex(Point(p.x(), p.y(), p.z())));
  for (size_t t = 0; t < surface.triangles.size(); ++t) {
    const Tri& tri = surface.triangles[t];
    const auto f = sm.add_face(vh[tri[0]], vh[tri[1]], vh[tri[2]]);
    ESIM_VERIFY(f != CgalSurface::null_face(),
                "triangle " + std::to_string(t) + " (vertices " + std::to_string(tri[0]) + " " +
                    std::to_string(tri[1]) + " " + std::to_string(tri[2]) +
                    ") makes the surface non-manifold; expected a closed 2-manifold");
  }
  return sm;
}

// ---- local refinement: a size bound that shrinks near a segment ----
// h(p) = fine + (coarse - fine) * clamp((d(p) - width) / width, 0, 1), d = distance of p
// to the segment [a, b]. A pure function of the point: meshing stays deterministic.
struct SegmentSizing {
  Vec3 a, b;
  double fineM, coarseM, widthM;
  template <class Index>
  Kernel::FT operator()(const Point& p, int /*dim*/, const Index& /*index*/) const {
    const Vec3 q(p.x(), p.y(), p.z());
    const Vec3 ab = b - a;
    const double s = std::clamp((q - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    const double d = (q - (a + s * ab)).norm();
    const double w = std::clamp((d - widthM) / widthM, 0.0, 1.0);
    return fineM + (coarseM - fineM) * w;
  }
};

// runs make_mesh_3 and the optional optimisers in a fixed order
template <class MeshCriteria>
Complex meshDomain(const Domain& domain, const MeshCriteria& criteria,
                   const MeshingOptions& options) {
  namespace params = CGAL::parameters;
  Complex c3t3;
  try {
    // manifold(): the boundary of the tets is a 2-manifold (rendered, cut, exported)
    c3t3 = CGAL::make_mesh_3<Complex>(domain, criteria, params::manifold(), params::no_perturb(),
                                      params::no_exude());
    if (options.lloyd) {
      CGAL::lloyd_optimize_mesh_3(c3t3, domain, params::time_limit = 0,
                                  params::max_iteration_number = options.lloydIterations);
    }
    if (options.perturb) {
      CGAL::perturb_mesh_3(c3t3, domain, params::time_limit = 0,
                           params::sliver_bound = options.sliverBoundDeg);
    }
    if (options.exude) {
      CGAL::exude_mesh_3(c3t3, params::time_limit = 0,
                         params::sliver_bound = options.sliverBoundDeg);
    }
  } catch (const CGAL::Failure_exception& e) {
    throw Error(std::string("CGAL Mesh_3 failed: ") + e.what());
  }
  return c3t3;
}

}  // namespace

SelfIntersections findSelfIntersections(const SurfaceMesh& surface) {
  const CgalSurface sm = toCgal(surface);
  std::vector<std::pair<CgalSurface::Face_index, CgalSurface::Face_index>> pairs;
  CGAL::Polygon_mesh_processing::self_intersections(sm, std::back_inserter(pairs));
  SelfIntersections out;
  out.pairCount = pairs.size();
  for (const auto& [fa, fb] : pairs) {
    std::array<int, 2> p{static_cast<int>(fa.idx()), static_cast<int>(fb.idx())};
    if (p[0] > p[1]) std::swap(p[0], p[1]);
    if (out.first[0] < 0 || p < out.first) out.first = p;
  }
  return out;
}

TetMesh generateTets(const SurfaceMesh& surface, const MeshingOptions& options) {
  namespace params = CGAL::parameters;
  // 1. domain (deterministic random for initial points and perturbation)
  CGAL::get_default_random() = CGAL::Random(options.seed);
  CGAL::Random rng(options.seed);
  const CgalSurface sm = toCgal(surface);
  Domain domain(sm, &rng);
  if (options.featureAngleDeg > 0) domain.detect_features(options.featureAngleDeg);

  // 2. criteria (constant sizes, or sizing fields around the planned cut), then Mesh_3
  Complex c3t3;
  const auto& r = options.refinement;
  if (!r.enabled) {
    const Criteria criteria(
        params::edge_size = options.edgeSizeM, params::facet_angle = options.facetAngleDeg,
        params::facet_size = options.facetSizeM, params::facet_distance = options.facetDistanceM,
        params::cell_radius_edge_ratio = options.cellRadiusEdgeRatio,
        params::cell_size = options.cellSizeM);
    c3t3 = meshDomain(domain, criteria, options);
  } else {
    const double k = r.cellSizeM / options.cellSizeM;  // fine / global, in (0, 1]
    auto field = [&](double globalM) {
      return SegmentSizing{r.fromM, r.toM, k * globalM, globalM, r.widthM};
    };
    const Criteria criteria(params::edge_size = field(options.edgeSizeM),
                            params::facet_angle = options.facetAngleDeg,
                            params::facet_size = field(options.facetSizeM),
                            params::facet_distance = field(options.facetDistanceM),
                            params::cell_radius_edge_ratio = options.cellRadiusEdgeRatio,
                            params::cell_size = field(options.cellSizeM));
    c3t3 = meshDomain(domain, criteria, options);
  }

  // 3. convert: nodes numbered by first use in CGAL's cell order
  TetMesh mesh;
  std::map<Triangulation::Vertex_handle, int> nodeId;
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    Tet tet;
    for (int i = 0; i < 4; ++i) {
      const auto v = c->vertex(i);
      auto [it, inserted] = nodeId.emplace(v, mesh.numNodes());
      if (inserted) {
        const auto& p = v->point();
        mesh.nodes.emplace_back(CGAL::to_double(p.x()), CGAL::to_double(p.y()),
                                CGAL::to_double(p.z()));
      }
      tet[i] = it->second;
    }
    const double vol = tetSignedVolume(mesh.nodes[tet[0]], mesh.nodes[tet[1]], mesh.nodes[tet[2]],
                                       mesh.nodes[tet[3]]);
    if (vol < 0) std::swap(tet[2], tet[3]);
    mesh.tets.push_back(tet);
  }
  mesh.alive.assign(mesh.tets.size(), 1);
  return mesh;
}

}  // namespace esim::cgal
