#pragma once
// Retargeting a motion onto a character skeleton with other bone lengths and another rest pose
// (T-pose vs A-pose): bone directions are aligned at rest, root translation scaled by leg length.
#include <string>

#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/skeleton.h"

namespace amt {

/// Per-joint rest alignment Q_j: the rotation that turns the target's rest bone directions from
/// joint j to its children onto the source's (exact for one child, least squares for several; a
/// leaf joint takes its parent's). With R_j^target = R_j^source Q_j every posed bone of the target
/// points where the source's does. Both skeletons need the same joints in the same order.
Quaternions rest_alignment(const Skeleton& source, const Skeleton& target);

/// Length of the legs: hip to knee to ankle, averaged over both sides (canonical skeletons), or the
/// root's rest height above the lowest joint for other skeletons.
float leg_length(const Skeleton& skeleton);

/// Returns `motion` (on `source`) as a motion on `target`: same frames and fps, local rotations
/// such that every target bone points where the source bone points at each frame, and root
/// translation scaled by leg_length(target) / leg_length(source). Throws amt::Error unless the two
/// skeletons name the same joints in the same order and the motion is on `source`.
Motion retarget_motion(const Motion& motion, const Skeleton& source, const Skeleton& target);

}  // namespace amt
