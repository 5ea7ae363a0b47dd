// fuzz_vtu.cpp - libFuzzer target: the VTU reader (sim/io/vtu.h) on any bytes, then the
// mesh check `esim mesh-info` runs on what it read (validateMesh).
// Oracles on an accepted file: every tet refers to read points, every field has
// components * count values (count: points for point data, tets for cell data).
#include <cstddef>
#include <cstdint>

#include "sim/io/vtu.h"
#include "tests/fuzz/fuzz_common.h"

using namespace esim;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::writeTemp(data, size, ".vtu");
  VtuData d;
  if (!fuzz::accepts([&] { d = readVtu(path); })) return 0;
  const auto points = d.points.size();
  for (const Tet& t : d.tets)
    for (int v : t)
      if (v < 0 || static_cast<std::size_t>(v) >= points) fuzz::finding("tet node out of range");
  auto checkFields = [](const std::vector<VtuField>& fields, std::size_t count, const char* kind) {
    for (const VtuField& f : fields)
      if (f.components < 1 || f.values.size() != static_cast<std::size_t>(f.components) * count)
        fuzz::finding(std::string(kind) + " field '" + f.name + "' has " +
                      std::to_string(f.values.size()) + " values for " +
                      std::to_string(f.components) + " components and " + std::to_string(count) +
                      " entries");
  };
  checkFields(d.pointData, points, "point");
  checkFields(d.cellData, d.tets.size(), "cell");
  TetMesh mesh;
  mesh.nodes = std::move(d.points);
  mesh.tets = std::move(d.tets);
  mesh.alive.assign(mesh.tets.size(), 1);
  fuzz::accepts([&] { validateMesh(mesh, path); });
  return 0;
}
