#pragma once
// Step 1 of the garment refit (the garment-refit paper, section 3.3): the target avatar shrunk onto its
// skeleton, and that shrunk avatar carried onto the source skeleton so that it sits inside the garment,
// each limb inside its sleeve or trouser leg. Inflating it back (section 3.5) moves every vertex on a
// straight line from its shrunk position to its position on the target avatar.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "data_tools/geometry/types.h"
#include "refit/contact.h"

namespace amt::refit {

// === Bones

/// The bones of a skeleton given by its joint parents (#J, -1 for roots; the convention of
/// data_tools/geometry/skeleton.h): bone b runs from joint parents[j] to joint j, for every non-root j in order.
/// Returns #B by 2 (parent joint, child joint).
MatrixX2i skeleton_bones(const std::vector<int32_t>& parents);

/// A point on a skeleton: on bone `bone`, at parameter `t` in [0, 1] from its first joint to its second.
struct SkeletonPoint {
  int bone = 0;
  double t = 0.0;
};

/// For every vertex of V (#V by 3), the bone (of bones, #B by 2 over joints #J by 3) nearest to it.
std::vector<int> nearest_bones(const Positions& V, const Positions& joints, const MatrixX2i& bones);

// === Shrink (section 3.3)

/// The shrunk avatar: the target avatar's triangles subdivided (non-conforming) until every triangle
/// lies on one bone, with each vertex at its skeleton point.
struct ShrunkAvatar {
  MatrixX3i F;                      // #F' by 3 faces over the #V' vertices
  Positions shrunk;                 // #V' by 3: on the source skeleton (t = 0 of the inflation)
  Positions target;                 // #V' by 3: on the target avatar (t = 1); inserted vertices on their edges
  std::vector<SkeletonPoint> at;    // #V' skeleton points; the first #V vertices are the avatar's own
  int subdivision_rounds = 0;       // passes over the triangle list until no triangle spanned a joint
};

/// Shrinks the target avatar (V #V by 3, F #F by 3) onto the target skeleton: vertex i moves to the
/// closest point of its bone vertex_bone[i] (#V; see nearest_bones). A triangle whose vertices then lie
/// on different bones is split along the edge that spans the most joints (joint counts between bones by
/// Floyd-Warshall over the skeleton), one inserted vertex per joint on that edge, each moved to its
/// joint, the triangle fanned from the opposite corner; repeated until every triangle lies on one bone.
/// The skeleton points are then placed on the source skeleton (source_joints, #J by 3, same joints and
/// bones). Throws amt::Error when a bone index is out of range, a bone has zero length, the sizes
/// disagree, or two bones that a triangle spans are not connected in the skeleton.
ShrunkAvatar shrink_to_skeleton(const Positions& V, const MatrixX3i& F, const Positions& target_joints,
                                const Positions& source_joints, const MatrixX2i& bones,
                                const std::vector<int>& vertex_bone);

}  // namespace amt::refit
