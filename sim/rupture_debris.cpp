// rupture_debris.cpp - see rupture_debris.h.
#include "sim/rupture_debris.h"

#include <algorithm>
#include <unordered_map>

#include "sim/core_error.h"

namespace esim {

std::vector<int> debrisCutLoose(const TetMesh& mesh,
                                const std::vector<std::array<int, 4>>& neighbours,
                                const std::vector<TetGeometry>& geo,
                                const std::vector<std::uint8_t>& supported,
                                const std::vector<int>& removed, double maxVolumeM3) {
  if (!(maxVolumeM3 > 0) || removed.empty()) return {};
  const int nt = mesh.numTets();
  ESIM_CHECK(static_cast<int>(neighbours.size()) == nt && static_cast<int>(geo.size()) == nt);
  ESIM_CHECK(supported.empty() || static_cast<int>(supported.size()) == mesh.numNodes());
  // per tet seen: removed, in the piece searched now, in a piece that stays, debris (a map:
  // a removal costs what it searches, not a pass over the mesh)
  enum : std::uint8_t { kUnseen, kRemoved, kSearched, kStays, kDebris };
  std::unordered_map<int, std::uint8_t> mark;
  mark.reserve(16 * removed.size());
  for (int t : removed) mark[t] = kRemoved;
  auto markOf = [&](int t) {
    const auto it = mark.find(t);
    return it == mark.end() ? static_cast<std::uint8_t>(kUnseen) : it->second;
  };
  auto left = [&](int t) { return mesh.isAlive(t) && markOf(t) != kRemoved; };

  std::vector<int> debris, piece, stack;
  bool anyStays = false;
  for (int r : removed) {
    for (int seed : neighbours[r]) {
      if (seed < 0 || !left(seed) || markOf(seed) != kUnseen) continue;
      // the seed's piece, until its volume passes the limit, it meets a support, or it
      // reaches a piece found to stay (the same piece: a search stopped early marks the
      // part it saw)
      piece.assign(1, seed);
      stack.assign(1, seed);
      mark[seed] = kSearched;
      double volumeM3 = 0;
      bool small = true;
      while (!stack.empty() && small) {
        const int t = stack.back();
        stack.pop_back();
        volumeM3 += geo[t].volume;
        if (volumeM3 > maxVolumeM3) small = false;
        for (int v : mesh.tets[t])
          if (!supported.empty() && supported[v]) small = false;
        for (int nb : neighbours[t]) {
          if (nb < 0 || !left(nb)) continue;
          const std::uint8_t m = markOf(nb);
          if (m == kStays) small = false;
          if (m != kUnseen) continue;
          mark[nb] = kSearched;
          piece.push_back(nb);
          stack.push_back(nb);
        }
      }
      for (int t : piece) mark[t] = small ? kDebris : kStays;
      if (small) {
        debris.insert(debris.end(), piece.begin(), piece.end());
      } else {
        anyStays = true;
      }
    }
  }
  // debris is never all the tissue left: then every piece stays. Only when
  // no piece searched stays can it be: then count the tets left (a pass over the mesh)
  if (!debris.empty() && !anyStays) {
    int aliveLeft = 0;
    for (int t = 0; t < nt; ++t) aliveLeft += left(t) ? 1 : 0;
    if (static_cast<int>(debris.size()) == aliveLeft) return {};
  }
  std::sort(debris.begin(), debris.end());
  return debris;
}

}  // namespace esim
