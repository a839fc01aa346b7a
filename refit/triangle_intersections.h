#pragma once
// A static check that a scene is intersection-free, for input validation: the barrier and CCD keep an
// intersection-free scene so, but cannot tell whether the start is (the paper's section 3.1 assumes it).
#include <array>
#include <string>
#include <vector>

#include "refit/contact.h"

namespace amt::refit {

/// Pairs of triangles of the scene (mesh.F at positions x) that cross each other, found through an AABB
/// tree and decided in double precision by the signs of signed volumes (an edge of one triangle through
/// the other): pairs of two obstacle triangles and pairs sharing a vertex are left out, and so are
/// coplanar overlaps and contacts within rounding (signed volumes below 10⁻¹² of the pair's size cubed
/// count as zero). Stops after `max_pairs` pairs (≤ 0: all). Not exact: the tests compare it with
/// CGAL's exact predicates.
std::vector<std::array<int, 2>> crossing_triangle_pairs(const CollisionMesh& mesh, const Positions& x,
                                                        int max_pairs = 1);

/// Throws amt::Error naming the first crossing pair when a garment-and-avatar scene
/// (make_garment_avatar_mesh: the first num_garment_faces faces are the garment's) crosses itself at x;
/// `stage` and `avatar` name the step and the avatar in the message.
void check_garment_avatar_start(const CollisionMesh& mesh, const Positions& x, int num_garment_faces,
                                const std::string& stage, const std::string& avatar);

}  // namespace amt::refit
