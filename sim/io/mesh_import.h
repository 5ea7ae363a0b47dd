// mesh_import.h - closed surface meshes (OBJ, STL, PLY, glTF/GLB) read with assimp,
// checked, and tetrahedralized with CGAL's 3D mesh generation (Mesh_3).
//
// Pipeline (loadTetMesh):
//   1. readSurface: assimp reads every mesh of the scene (node transforms applied),
//      triangulates, and the vertices are welded by exact position across meshes.
//      Coordinates are multiplied by scaleToMetres (our assets are in metres).
//   2. checkSurface: the surface must bound a volume: no degenerate triangles, every
//      edge shared by exactly two triangles (closed, edge-manifold), a single fan
//      around every vertex (vertex-manifold), consistently oriented, and no two
//      triangles intersecting except at shared vertices/edges (CGAL PMP).
//   3. orientOutward: flips all triangles if the enclosed volume is negative.
//   4. tetrahedralize: Mesh_3 with a polyhedral domain (sharp edges above a
//      feature angle are protected), refinement criteria in metres, optional
//      Lloyd smoothing, sliver perturbation and exudation; converted to a TetMesh
//      (positive orientation, only nodes used by tets, validateMesh passed).
// Enclosed volume by the divergence theorem: V = 1/6 sum_t p0 . (p1 x p2) [m^3].
// Errors are esim::Error "<file>: <what is wrong>". Results are owned by value.
// Optional local refinement (MeshingOptions::Refinement): CGAL sizing fields make tets
// and surface facets finer within a distance of a planned cut segment.
// Meshing is deterministic: CGAL's random generator is reseeded from options.seed.
#pragma once

#include <string>
#include <vector>

#include "sim/mesh_slab.h"
#include "sim/mesh_tet.h"

namespace esim {

// A triangulated surface. Triangles are counter-clockwise seen from outside once
// orientOutward has run. Positions in metres.
struct SurfaceMesh {
  std::vector<Vec3> vertices;  // [m]
  std::vector<Tri> triangles;  // vertex ids
};

// Mesh_3 refinement criteria and optimisation steps (sizes in metres).
// A size of 0 means "derived": facetSizeM = cellSizeM, facetDistanceM = cellSizeM/20,
// edgeSizeM = facetSizeM.
struct MeshingOptions {
  double cellSizeM = 0.008;          // upper bound on tet circumradius [m]
  double facetSizeM = 0;             // upper bound on surface Delaunay ball radius [m]
  double facetDistanceM = 0;         // max distance facet centre - input surface [m]
  double facetAngleDeg = 25;         // lower bound on surface triangle angles [deg] (<= 30)
  double cellRadiusEdgeRatio = 2.5;  // upper bound circumradius / shortest edge (>= 2)
  double featureAngleDeg = 60;       // protect edges sharper than this [deg]; 0: none
  double edgeSizeM = 0;              // sampling of protected sharp edges [m]
  bool lloyd = false;                // Lloyd smoothing before perturbation
  int lloydIterations = 10;          // Lloyd iterations when enabled
  bool perturb = true;               // sliver perturbation
  bool exude = true;                 // sliver exudation (weights)
  double sliverBoundDeg = 10;        // perturb/exude target min dihedral [deg]; 0: best effort
  unsigned seed = 0;                 // CGAL random seed (fixed: deterministic output)

  // Local refinement around a planned cut segment [fromM, toM]. With d the distance of a
  // point to the segment, the size bounds are h(d) = fine for d <= widthM, growing
  // linearly to the global bound at d = 2 widthM, global beyond:
  //   h(d) = fine + (global - fine) * clamp((d - widthM) / widthM, 0, 1).
  // Applied to the cell size (fine = cellSizeM here), and to facet size, facet
  // distance and edge size with fine = their global value * cellSizeM / global cellSizeM.
  struct Refinement {
    bool enabled = false;
    Vec3 fromM{0, 0, 0};       // segment start [m]
    Vec3 toM{0, 0, 0};         // segment end [m] (must differ from fromM)
    double cellSizeM = 0.001;  // cell size bound near the segment [m] (0 < . <= cellSizeM)
    double widthM = 0.005;     // fine-zone radius; the transition is as wide again [m]
  };
  Refinement refinement;
};

// The most tetrahedra a scene's mesh may have (a file's predicted count, a slab's grid):
// beyond, meshing and the solvers' factors take hours and more memory than a workstation has,
// so the scene is refused up front (a unit mix-up, or a node count off by a factor).
inline constexpr double kMaxSceneTets = 2e7;

// "" if the slab's grid (6 tets a cell) holds at most kMaxSceneTets, else what it would hold
// ("gives a grid of A x B x C nodes, T tetrahedra; at most ..."), for the caller to prefix
// with the option or scenario key at fault
std::string slabTooLarge(const SlabSpec& spec);

// Reads a surface with assimp, in a child process (fork; the triangles come back through a
// pipe): a file that crashes assimp or corrupts its heap ends the child, not this process,
// and so does one it reads for longer than timeoutS [s] (the child is killed; assimp 5.2
// spins forever on some damaged files), or a stop asked meanwhile (checkInterrupt).
// Throws "<path>: file not found", "<path>: cannot read surface mesh: <reason>" (the reader
// crashed: "... the reader (assimp) crashed on it (signal N, name) ..."; or "... did not
// finish within T s ...") or "<path>: ... no triangles"; std::bad_alloc when memory runs
// out; Interrupted on a stop.
SurfaceMesh readSurface(const std::string& path, double scaleToMetres = 1.0,
                        double timeoutS = 600.0);

// Volume enclosed by the surface [m^3], divergence theorem; negative if inward.
double enclosedVolume(const SurfaceMesh& surface);

// Checks that the surface bounds a volume (closed, manifold, consistently
// oriented, not self-intersecting); throws esim::Error naming `source`.
void checkSurface(const SurfaceMesh& surface, const std::string& source);

// Flips every triangle if the enclosed volume is negative (surface already checked).
void orientOutward(SurfaceMesh& surface);

// Steps 1-2 of tetrahedralize, without Mesh_3: the options checked (derived sizes filled in,
// returned) and the predicted tet count bounded by kMaxSceneTets (a unit mix-up, millimetres
// read as metres, would mesh for hours). Throws esim::Error "<sourceName>: ..." as
// tetrahedralize does.
MeshingOptions checkMeshing(const SurfaceMesh& surface, const MeshingOptions& options,
                            const std::string& sourceName);

// Tetrahedralizes a checked closed surface with Mesh_3; the result is validated.
// Throws esim::Error "<sourceName>: ..." on bad options or a failed meshing.
TetMesh tetrahedralize(const SurfaceMesh& surface, const MeshingOptions& options,
                       const std::string& sourceName);

// readSurface(path) -> checkSurface -> orientOutward -> tetrahedralize.
TetMesh loadTetMesh(const std::string& path, const MeshingOptions& options,
                    double scaleToMetres = 1.0);

// loadTetMesh up to Mesh_3 (checkMeshing): what esim validate checks of a file mesh, in a
// fraction of a second, so that a file that validates is not refused at set-up for them
// (a surface in millimetres validated "ok" and was refused by esim run)
void checkTetMeshSource(const std::string& path, const MeshingOptions& options,
                        double scaleToMetres = 1.0);

}  // namespace esim
