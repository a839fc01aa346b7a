#pragma once
// Independent checks of the refit's no-intersection guarantee, for the tests only: an exact static test
// with CGAL's exact predicates, and a root-finding continuous test over a linear motion. Neither uses the
// refit's own distance, CCD or broad-phase code.
#include <cstdint>
#include <vector>

#include "data_tools/geometry/types.h"
#include "refit/contact.h"

namespace amt::refit::test {

/// The number of pairs of triangles of F at positions V (#V by 3) that intersect, decided exactly
/// (CGAL's filtered exact predicates on the double coordinates), by brute force over all pairs; pairs of
/// two obstacle triangles (all corners obstacle[v] = 1; obstacle may be empty) are left out. Triangles
/// that share an edge or a vertex count only when they meet beyond it.
int count_intersecting_triangle_pairs(const Positions& V, const MatrixX3i& F, const std::vector<uint8_t>& obstacle);

/// The number of non-incident point-triangle and edge-edge pairs (not both obstacle) that touch or
/// cross during the linear motion from x0 to x1, by brute force: the roots in [0, 1] of each pair's
/// coplanarity cubic (Provot 1997; Bridson, Fedkiw and Anderson 2002), then an inside test at each root
/// with tolerance `tolerance` (metres).
int count_crossings(const CollisionMesh& mesh, const Positions& x0, const Positions& x1, double tolerance = 1e-9);

}  // namespace amt::refit::test
