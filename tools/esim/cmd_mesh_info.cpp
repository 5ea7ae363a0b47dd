// cmd_mesh_info.cpp - `esim mesh-info FILE`: mesh a surface (or build the slab, or read
// a .vtu) and print counts, volume, bounding box, quality and meshing time.
//
// 1. Parse options (sizes in metres).
// 2. Build the mesh: "slab" / --slab-nodes -> makeSlab; *.vtu -> readVtu; otherwise
//    a closed surface file -> readSurface, checkSurface, orientOutward, tetrahedralize.
//    --refine-from/--refine-to make the mesh finer around a planned cut segment.
// 3. validateMesh, then print the report; optionally write the mesh as VTU.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "sim/core_error.h"
#include "sim/io/mesh_import.h"
#include "sim/io/vtu.h"
#include "sim/mesh_slab.h"
#include "sim/mesh_tet.h"
#include "sim/message_text.h"
#include "tools/esim/command.h"

namespace esim::cli {
namespace {

struct MeshInfoOptions {
  std::string file;
  int slabNodes = 0;
  double scaleToMetres = 1.0;
  MeshingOptions meshing;
  bool noPerturb = false;
  bool noExude = false;
  std::string vtuOut;
  std::vector<double> refineFrom, refineTo;  // planned cut ends x,y,z [m]; both enable refinement
};

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

int runMeshInfo(const MeshInfoOptions& opt) {
  using Clock = std::chrono::steady_clock;
  ESIM_VERIFY(opt.refineFrom.empty() == opt.refineTo.empty(),
              "mesh-info: --refine-from and --refine-to go together (the planned cut's ends)");
  ESIM_VERIFY(opt.refineFrom.empty() || (opt.refineFrom.size() == 3 && opt.refineTo.size() == 3),
              "mesh-info: --refine-from and --refine-to take x,y,z in metres");
  if (!opt.vtuOut.empty())  // before the meshing, which may take minutes
    checkOutputFileName("mesh-info: --vtu", opt.vtuOut, ".vtu");
  // 2. build or load
  TetMesh mesh;
  std::string source = opt.file;
  double meshingS = 0;
  const auto t0 = Clock::now();
  if (opt.slabNodes > 0 || opt.file == "slab") {
    SlabSpec spec;
    if (opt.slabNodes > 0) spec.targetNodes = opt.slabNodes;
    const std::string problem = slabTooLarge(spec);
    ESIM_VERIFY(problem.empty(),
                "mesh-info: --slab-nodes " + std::to_string(spec.targetNodes) + " " + problem);
    source = "slab (" + std::to_string(spec.targetNodes) + " nodes requested)";
    mesh = makeSlab(spec);
    meshingS = std::chrono::duration<double>(Clock::now() - t0).count();
  } else if (endsWith(opt.file, ".vtu")) {
    VtuData data = readVtu(opt.file);
    mesh.nodes = std::move(data.points);
    mesh.tets = std::move(data.tets);
    mesh.alive.assign(mesh.tets.size(), 1);
  } else {
    ESIM_VERIFY(!opt.file.empty(), "mesh-info: give a surface file, a .vtu file or 'slab'");
    SurfaceMesh surface = readSurface(opt.file, opt.scaleToMetres);
    checkSurface(surface, opt.file);
    orientOutward(surface);
    const auto tRead = Clock::now();
    std::printf("surface          %s\n", printablePath(opt.file).c_str());
    std::printf("  vertices       %zu\n", surface.vertices.size());
    std::printf("  triangles      %zu\n", surface.triangles.size());
    std::printf("  enclosed vol.  %.6e m^3\n", enclosedVolume(surface));
    std::printf("  read+check     %.3f s\n", std::chrono::duration<double>(tRead - t0).count());
    MeshingOptions meshing = opt.meshing;
    if (!opt.refineFrom.empty()) {
      meshing.refinement.enabled = true;
      meshing.refinement.fromM = Vec3(opt.refineFrom[0], opt.refineFrom[1], opt.refineFrom[2]);
      meshing.refinement.toM = Vec3(opt.refineTo[0], opt.refineTo[1], opt.refineTo[2]);
    }
    meshing.perturb = !opt.noPerturb;
    meshing.exude = !opt.noExude;
    mesh = tetrahedralize(surface, meshing, opt.file);
    meshingS = std::chrono::duration<double>(Clock::now() - tRead).count();
  }
  validateMesh(mesh, source);

  // 3. report
  const auto faces = boundaryFaces(mesh);
  const MeshQuality q = meshQuality(mesh);
  Vec3 lo = mesh.nodes[0], hi = mesh.nodes[0];
  for (const Vec3& p : mesh.nodes) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  std::printf("tet mesh         %s\n", printablePath(source).c_str());
  std::printf("  nodes          %d\n", mesh.numNodes());
  std::printf("  tets           %d\n", mesh.numAlive());
  std::printf("  boundary faces %zu\n", faces.size());
  std::printf("  boundary nodes %zu\n", boundaryNodes(mesh, faces).size());
  std::printf("  volume         %.6e m^3\n", meshVolume(mesh));
  std::printf("  surface area   %.6e m^2\n", surfaceArea(mesh, faces));
  std::printf("  bounding box   [%.6g, %.6g] x [%.6g, %.6g] x [%.6g, %.6g] m\n", lo.x(), hi.x(),
              lo.y(), hi.y(), lo.z(), hi.z());
  // pieces through shared faces (a cut's fields: the pieces it left loose, README "Debris")
  int pieces = 0;
  const std::vector<int> pieceOf = tetPieces(mesh, &pieces);
  std::vector<int> tetsIn(pieces, 0);
  std::vector<double> volumeIn(pieces, 0.0);
  for (int e = 0; e < mesh.numTets(); ++e)
    if (pieceOf[e] >= 0) {
      ++tetsIn[pieceOf[e]];
      volumeIn[pieceOf[e]] += tetVolume(mesh, e);
    }
  const int largest =
      static_cast<int>(std::max_element(tetsIn.begin(), tetsIn.end()) - tetsIn.begin());
  std::printf("  pieces         %d through shared faces", pieces);
  if (pieces > 1) {
    double restV = 0;
    for (int p = 0; p < pieces; ++p) restV += p == largest ? 0.0 : volumeIn[p];
    std::printf(" (the largest %d tets; the %d others %d tets, %.3e m^3)", tetsIn[largest],
                pieces - 1, mesh.numAlive() - tetsIn[largest], restV);
  }
  std::printf("\n");
  std::printf("quality\n");
  std::printf("  min dihedral   %.2f deg\n", q.minDihedralDeg);
  std::printf("  max dihedral   %.2f deg\n", q.maxDihedralDeg);
  std::printf("  max radius/edge %.3f (regular tet 0.612)\n", q.maxRadiusEdgeRatio);
  std::printf("  min volume     %.3e m^3\n", q.minVolume);
  if (meshingS > 0) std::printf("meshing time     %.3f s\n", meshingS);
  if (!opt.vtuOut.empty()) {
    writeVtu(opt.vtuOut, mesh, {}, {});
    std::printf("written          %s\n", printablePath(opt.vtuOut).c_str());
  }
  return kExitOk;
}

Registrar reg(
    {"mesh-info"},
    "Mesh a closed surface (OBJ/STL/PLY/glTF), build the slab or read a .vtu, and "
    "print counts, volume and quality",
    [](CLI::App& app) -> Runner {
      // 1. options
      auto opt = std::make_shared<MeshInfoOptions>();
      app.add_option("file", opt->file, "surface mesh file, a .vtu tet mesh, or 'slab'");
      app.add_option("--slab-nodes", opt->slabNodes, "report the paper's slab with this many nodes")
          ->check(CLI::PositiveNumber);
      // what only the meshing of a surface file reads (the slab and a .vtu would ignore it)
      std::vector<const CLI::Option*> meshing;
      meshing.push_back(
          app.add_option("--cell-size", opt->meshing.cellSizeM, "tet circumradius bound [m]")
              ->capture_default_str());
      meshing.push_back(app.add_option("--facet-size", opt->meshing.facetSizeM,
                                       "surface facet size [m] (default: cell size)"));
      meshing.push_back(
          app.add_option("--facet-distance", opt->meshing.facetDistanceM,
                         "surface approximation error [m] (default: cell size / 20)"));
      meshing.push_back(app.add_option("--radius-edge", opt->meshing.cellRadiusEdgeRatio,
                                       "tet radius-edge ratio bound (>= 2)")
                            ->capture_default_str());
      meshing.push_back(app.add_option("--sliver-bound", opt->meshing.sliverBoundDeg,
                                       "perturb/exude target min dihedral angle [deg]")
                            ->capture_default_str());
      meshing.push_back(
          app.add_option("--scale", opt->scaleToMetres,
                         "multiply file coordinates by this to get metres (0.001 for mm)")
              ->capture_default_str());
      meshing.push_back(app.add_option("--seed", opt->meshing.seed, "meshing random seed")
                            ->capture_default_str());
      meshing.push_back(app.add_flag("--lloyd", opt->meshing.lloyd, "Lloyd smoothing"));
      meshing.push_back(app.add_flag("--no-perturb", opt->noPerturb, "skip sliver perturbation"));
      meshing.push_back(app.add_flag("--no-exude", opt->noExude, "skip sliver exudation"));
      meshing.push_back(
          app.add_option("--refine-from", opt->refineFrom,
                         "refine around a planned cut from x,y,z [m] (with --refine-to)")
              ->delimiter(','));
      meshing.push_back(app.add_option("--refine-to", opt->refineTo, "planned cut end x,y,z [m]")
                            ->delimiter(','));
      // what only the refinement reads (without --refine-from it would be ignored)
      std::vector<const CLI::Option*> refinement;
      refinement.push_back(app.add_option("--refine-size", opt->meshing.refinement.cellSizeM,
                                          "tet size bound near the planned cut [m]")
                               ->capture_default_str());
      refinement.push_back(app.add_option("--refine-width", opt->meshing.refinement.widthM,
                                          "radius of the fine zone around the planned cut [m]")
                               ->capture_default_str());
      meshing.insert(meshing.end(), refinement.begin(), refinement.end());
      app.add_option("--vtu", opt->vtuOut, "also write the tet mesh to this .vtu file");
      return [opt, meshing, refinement] {
        const bool slab = opt->slabNodes > 0 || opt->file == "slab";
        ESIM_VERIFY(opt->slabNodes == 0 || opt->file.empty() || opt->file == "slab",
                    "mesh-info: --slab-nodes reports the slab; give it without '" + opt->file +
                        "' (or with 'slab')");
        if (slab || endsWith(opt->file, ".vtu"))
          refuseGiven(
              meshing, "mesh-info",
              std::string("is an option of meshing a surface file, and ") +
                  (slab ? "the slab is built, not meshed" : "a .vtu tet mesh is read as it is"));
        if (opt->refineFrom.empty())
          refuseGiven(refinement, "mesh-info",
                      "is an option of the refinement around a planned cut, which needs "
                      "--refine-from and --refine-to");
        return runMeshInfo(*opt);
      };
    });

}  // namespace
}  // namespace esim::cli
