// mesh_slab.h - the paper's tissue slab as a structured tetrahedral mesh.
//
// A box [-Lx/2, Lx/2] x [-Ly/2, Ly/2] x [0, Lz] (metres, top face at z = Lz) cut
// into px x py x pz grid nodes; each hex is split into 6 tets along its main
// diagonal (Freudenthal/Kuhn), which is conforming across hexes. The grid is
// chosen to hit a requested node count (the paper's 506, 643, 1013 nodes) with
// cells as close to cubes as the count allows. Optionally the spacing is graded:
// `ratio` times finer within `width` of a planned cut segment (in x and y) and
// near the top face, so accuracy is spent where the cut is.
// Node sets: "top", "bottom", "xmin", "xmax", "ymin", "ymax".
#pragma once

#include <array>

#include "sim/mesh_tet.h"

namespace esim {

struct SlabGrading {
  bool enabled = false;
  Vec3 cutFrom{-0.04, 0.0, 0.01};  // planned cut segment, start [m]
  Vec3 cutTo{0.04, 0.0, 0.01};     // planned cut segment, end [m]
  double ratio = 4.0;              // coarse / fine spacing (>= 1)
  double widthM = 0.01;            // fine zone half-width around the cut [m]
  bool towardTop = true;           // also grade the depth toward the top face
};

struct SlabSpec {
  Vec3 sizeM{0.1, 0.1, 0.01};                // Lx, Ly, Lz [m]
  int targetNodes = 1013;                    // requested node count (used when divisions are 0)
  std::array<int, 3> nodesPerAxis{0, 0, 0};  // explicit px, py, pz (> 1) or zeros
  SlabGrading grading;
};

// nodes per axis (px, py, pz) that best reach spec.targetNodes
std::array<int, 3> slabNodesPerAxis(const SlabSpec& spec);

// builds the slab mesh; throws esim::Error on a bad spec
TetMesh makeSlab(const SlabSpec& spec);

}  // namespace esim
