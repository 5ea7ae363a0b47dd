// vtu.h - VTK XML unstructured grid (.vtu) export and import of tet meshes and fields.
//
// Written as <VTKFile type="UnstructuredGrid" header_type="UInt64"> with inline
// base64 binary DataArrays (header and data in one base64 block), which ParaView
// and meshio read. Points are Float64 [m]; cells are VTK_TETRA (type 10); point
// and cell data are Float64 with 1 or 3 components. Removed tets are left out
// (cell data then has one entry per alive tet; a cell array "tet_id" gives the
// original ids). The file is written to "<path>.tmp" and renamed when complete.
// readVtu reads the files writeVtu writes (binary or ascii DataArrays), for tests
// and for reloading a mesh.
#pragma once

#include <string>
#include <vector>

#include "sim/mesh_tet.h"

namespace esim {

struct VtuField {
  std::string name;
  int components = 1;          // 1 (scalar) or 3 (vector)
  std::vector<double> values;  // components * count, interleaved
};

struct VtuData {
  std::vector<Vec3> points;  // [m]
  std::vector<Tet> tets;
  std::vector<VtuField> pointData;
  std::vector<VtuField> cellData;  // per written (alive) tet

  const VtuField* findPointField(const std::string& name) const;
  const VtuField* findCellField(const std::string& name) const;
};

// writes the alive tets of mesh with per-node and per-tet fields (per-tet fields
// have one entry per tet of the mesh, dead ones included; they are filtered here)
void writeVtu(const std::string& path, const TetMesh& mesh, const std::vector<VtuField>& pointData,
              const std::vector<VtuField>& cellData);

// reads a .vtu file of tetrahedra; throws esim::Error naming the file on bad input
VtuData readVtu(const std::string& path);

}  // namespace esim
