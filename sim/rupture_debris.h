// rupture_debris.h - the pieces of tissue a removal cuts loose, small enough to be debris
// (material.debris_volume_m3).
//
// A removal can leave alive tets that share no face with the rest of the tissue: one tet, or a
// few, in the groove behind the blade, held by an edge or a node or by nothing. The structural
// phase leaves such a floating piece out of its stiffness (an island: no stress, it never
// breaks), so it stays in the video, hanging in the air over the groove (slab_cut: 73 pieces of 1-6
// tets, 138 tets, after 100 frames). In the tissue such a fragment is carried off by the vapour and
// the electrode. With a volume V_max > 0, every piece that the removal cuts off is removed with
// it when:
//   - its volume (the sum of its tets' volumes) is at most V_max,
//   - none of its nodes is held by a structural support (a piece on the clamped base stays),
//   - and the debris found is not all the tissue left (then every piece stays).
// Pieces are face-connected sets of alive tets (as the structural phase's islands); only those
// holding an alive face neighbour of a removed tet are examined, each by a search that stops
// once its volume passes V_max, so the cost is the removed tets' neighbourhood, not the mesh.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "sim/fem_p1.h"
#include "sim/mesh_tet.h"

namespace esim {

// The alive tets (ascending) of the debris pieces that removing `removed` (alive now, in
// mesh.alive; not edited) would cut loose. neighbours: tetFaceNeighbours(mesh); geo: its
// tetGeometry (volumes); supported: per node, 1 when a support holds it (may be empty: no
// supports); maxVolumeM3 <= 0: none.
std::vector<int> debrisCutLoose(const TetMesh& mesh,
                                const std::vector<std::array<int, 4>>& neighbours,
                                const std::vector<TetGeometry>& geo,
                                const std::vector<std::uint8_t>& supported,
                                const std::vector<int>& removed, double maxVolumeM3);

}  // namespace esim
