// fuzz_surface.cpp - libFuzzer target: the surface import path of sim/io/mesh_import.h
// (readSurface through assimp, checkSurface, orientOutward) on any bytes; no Mesh_3.
// The bytes go to a temp file whose extension picks the reader, guessed from the content
// the way a user's file would look: "ply" first -> .ply; "solid" first, or a binary STL
// (84 + 50 n bytes, n the count at byte 80) -> .stl; anything else -> .obj.
// Oracles on an accepted surface: after orientOutward the enclosed volume is > 0.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "sim/io/mesh_import.h"
#include "tests/fuzz/fuzz_common.h"

using namespace esim;

namespace {

std::string extensionFor(const std::uint8_t* data, std::size_t size) {
  auto startsWith = [&](const char* s) {
    const std::size_t n = std::strlen(s);
    return size >= n && std::memcmp(data, s, n) == 0;
  };
  if (startsWith("ply")) return ".ply";
  if (startsWith("solid")) return ".stl";
  if (size >= 84) {
    std::uint32_t n;
    std::memcpy(&n, data + 80, 4);
    if (size == 84 + 50 * static_cast<std::uint64_t>(n)) return ".stl";
  }
  return ".obj";
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::writeTemp(data, size, extensionFor(data, size));
  SurfaceMesh surface;
  if (!fuzz::accepts([&] { surface = readSurface(path, 1.0); })) return 0;
  if (!fuzz::accepts([&] { checkSurface(surface, path); })) return 0;
  orientOutward(surface);
  const double volume = enclosedVolume(surface);
  if (!(volume > 0)) fuzz::finding("checked surface encloses " + std::to_string(volume) + " m^3");
  return 0;
}
