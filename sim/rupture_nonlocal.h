// rupture_nonlocal.h - the nonlocal stress that the rupture criterion can compare with the
// critical stress (material.critical_stress_radius_m).
//
// The paper removes a tet when its own von Mises stress passes the critical stress. Whole
// tets go, so the groove's shape follows the mesh: in `esim bench accuracy` the removed
// region did not converge with the mesh (README, "What accuracy costs"). With a radius R > 0
// the criterion compares the average of the von Mises stress over the alive tets whose
// centroids lie within R of the tet's own centroid instead, weighted by volume and by the
// bell 1 - d^2 / R^2 (the tet itself always counts, d = 0; alone within R, s_e is its own
// stress bit for bit, the paper's criterion):
//   s_e = sum_j w_j V_j s_j / sum_j w_j V_j,
// the classic nonlocal regularisation of element removal (Pijaudier-Cabot and Bazant 1987,
// "Nonlocal damage theory", J. Eng. Mech. 113(10)): R is a length of the material, so the
// removed region stops depending on the element size once the elements are smaller than R.
//
// The average is a convex combination of the local stresses, so it passes the critical
// stress only within R of a tet whose own stress passes it: broken() averages only there, over
// a uniform grid of cells of R (or more, for a radius far below the body's size), and its
// result is the brute-force one exactly (the same sums in the same order). On slab_cut at
// R = 1 mm the rupture stage takes 0.5 ms median, 3 ms p95 (README, "A cut that converges").
#pragma once

#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "sim/fem_p1.h"
#include "sim/mesh_tet.h"

namespace esim {

class NonlocalStress {
 public:
  // radiusM > 0 [m]; geo: the mesh's tetGeometry (volumes). Every tet is indexed, removed
  // or not (aliveness is read when averaging), so removals need no update. Throws
  // esim::Error (Input) naming material.critical_stress_radius_m when the radius is not
  // positive or so wide that a frame could visit more than kMaxPairs pairs of tets.
  NonlocalStress(const TetMesh& mesh, const std::vector<TetGeometry>& geo, double radiusM);

  // the average s_e of tet e's alive neighbours' field values (e alive) [the field's unit]
  double average(const TetMesh& mesh, const std::vector<double>& field, int e) const;

  // alive tets whose average passes limit, ascending; local: the per-tet field (von Mises
  // stress [Pa]). Averages only within R of a tet whose own value passes limit.
  std::vector<int> broken(const TetMesh& mesh, const std::vector<double>& local,
                          double limit) const;

  double radiusM() const { return radiusM_; }

  // the most pairs of tets a frame may visit (every tet a candidate): the constructor refuses
  // a radius whose grid would visit more
  static constexpr double kMaxPairs = 1e8;

 private:
  std::uint64_t cellKey(long i, long j, long k) const;
  template <class Visit>
  void forCellsAround(const std::array<long, 3>& cell, Visit&& visit) const;
  template <class Visit>
  void forNeighbours(const TetMesh& mesh, int e, Visit&& visit) const;

  double radiusM_;
  double cellM_ = 0;                                           // the grid's cell [m]: >= radiusM_
  Vec3 origin_;                                                // the grid's lower corner [m]
  std::vector<Vec3> centroid_;                                 // per tet [m]
  std::vector<double> volume_;                                 // per tet [m^3]
  std::vector<std::array<long, 3>> cellOf_;                    // per tet: its grid cell
  std::unordered_map<std::uint64_t, std::vector<int>> cells_;  // ascending tet ids per cell
  mutable std::vector<std::uint8_t> seen_;  // broken()'s marks (cleared before it returns)
};

}  // namespace esim
