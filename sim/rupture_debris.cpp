// rupture_debris.cpp - see rupture_debris.h.
#include "sim/rupture_debris.h"

#include <algorithm>

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
  // per tet: 0 unseen, 1 removed, 2 in the piece searched now, 3 in a piece that stays,
  // 4 debris
  enum : std::uint8_t { kUnseen, kRemoved, kSearched, kStays, kDebris };
  std::vector<std::uint8_t> mark(nt, kUnseen);
  for (int t : removed) mark[t] = kRemoved;
  auto left = [&](int t) { return mesh.isAlive(t) && mark[t] != kRemoved; };
  int aliveLeft = 0;  // tets alive after the removal
  for (int t = 0; t < nt; ++t) aliveLeft += left(t) ? 1 : 0;

  std::vector<int> debris, piece, stack;
  for (int r : removed) {
    for (int seed : neighbours[r]) {
      if (seed < 0 || !left(seed) || mark[seed] != kUnseen) continue;
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
          if (mark[nb] == kStays) small = false;
          if (mark[nb] != kUnseen) continue;
          mark[nb] = kSearched;
          piece.push_back(nb);
          stack.push_back(nb);
        }
      }
      for (int t : piece) mark[t] = small ? kDebris : kStays;
      if (small) debris.insert(debris.end(), piece.begin(), piece.end());
    }
  }
  // debris is never all the tissue left: then every piece stays (held in place)
  if (static_cast<int>(debris.size()) == aliveLeft) return {};
  std::sort(debris.begin(), debris.end());
  return debris;
}

}  // namespace esim
