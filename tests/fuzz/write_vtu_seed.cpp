// write_vtu_seed.cpp - writes the VTU seed of fuzz_vtu with the project's own writer: a
// 2 x 2 x 2 node slab (its tets), a scalar and a vector point field, a cell field, one
// tet removed (so tet_id skips it). Usage: fuzz_write_vtu_seed OUT.vtu
#include <cstdio>

#include "sim/io/vtu.h"
#include "sim/mesh_slab.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT.vtu\n", argv[0]);
    return 2;
  }
  esim::SlabSpec spec;
  spec.sizeM = esim::Vec3(0.002, 0.002, 0.001);
  spec.nodesPerAxis = {2, 2, 2};
  esim::TetMesh mesh = esim::makeSlab(spec);
  mesh.alive[1] = 0;
  esim::VtuField temperature{"temperature", 1, {}}, displacement{"displacement", 3, {}};
  for (int i = 0; i < mesh.numNodes(); ++i) {
    temperature.values.push_back(37.0 + i);
    for (int c = 0; c < 3; ++c) displacement.values.push_back(1e-6 * mesh.nodes[i][c]);
  }
  esim::VtuField damage{"damage", 1, {}};
  for (int e = 0; e < mesh.numTets(); ++e) damage.values.push_back(0.1 * e);
  esim::writeVtu(argv[1], mesh, {temperature, displacement}, {damage});
  return 0;
}
