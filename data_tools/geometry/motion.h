#pragma once
// Motions (local joint rotations + root translation at a frame rate) and forward kinematics to the
// paper's per-frame joint transforms T^(t) = [R_j | t_j].
#include <cstdint>
#include <string>

#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Motion

/// A motion on a skeleton whose joints it names. Rotations are relative to the rest pose: the
/// identity everywhere, with zero root translation, is the rest pose.
///   local_rotations  #T * #J quaternions, frame-major: entry t * J + j rotates joint j relative to
///                    its parent, expressed in the rest frame (rest orientations are identity).
///   root_translation #T by 3 displacement of the root joint from its rest position (metres).
struct Motion {
  float fps = 30.0f;
  std::vector<std::string> joint_names;
  Quaternions local_rotations;
  MatrixX3f root_translation;

  int num_joints() const { return static_cast<int>(joint_names.size()); }
  int num_frames() const { return static_cast<int>(root_translation.rows()); }
  const Eigen::Quaternionf& rotation(int t, int j) const { return local_rotations[static_cast<size_t>(t) * num_joints() + j]; }
  Eigen::Quaternionf& rotation(int t, int j) { return local_rotations[static_cast<size_t>(t) * num_joints() + j]; }
  /// Duration in seconds from the first to the last frame.
  float duration() const { return num_frames() > 1 ? (num_frames() - 1) / fps : 0.0f; }
};

/// A motion of `frames` frames in the rest pose.
Motion rest_motion(const Skeleton& skeleton, int frames, float fps = 30.0f);

/// Throws amt::Error unless the motion has the skeleton's joints in its order, #T * #J unit
/// quaternions, finite values and a positive frame rate.
void validate_motion(const Motion& motion, const Skeleton& skeleton, const std::string& source);

/// Maximum number of frames resample_motion produces.
constexpr int kMaxResampledFrames = 1000000;

/// Resamples a motion to `fps` (in (0, 1000]): output frame k is at time k / fps, for
/// k = 0 .. floor((T - 1) * fps / motion.fps + 1e-4), so every output frame lies within the clip;
/// rotations are slerped and root translation interpolated linearly between the two source frames
/// around that time. Throws amt::Error for a rate out of range or more than 1 000 000 output frames.
Motion resample_motion(const Motion& motion, float fps);

// === Forward kinematics

/// Joint transforms of frame t (the paper's T^(t)): for every joint, R_j its global rotation relative
/// to the rest pose and t_j its global position, so that a rest point p rigidly attached to joint j
/// moves to R_j (p - J_j) + t_j.
Transforms forward_kinematics(const Skeleton& skeleton, const Motion& motion, int t);

/// Joint transforms of every frame: #T * #J transforms, frame-major.
Transforms forward_kinematics(const Skeleton& skeleton, const Motion& motion);

/// Skinning matrices of one frame, M_j = [R_j | t_j - R_j J_j], so that M_j p = R_j (p - J_j) + t_j.
Transforms skinning_matrices(const Skeleton& skeleton, const Transforms& joint_transforms);

/// Frames that blend a character from its rest pose into a motion's first frame before the motion starts, at 30 fps
/// (`amt animate --lead-in`, evaluation's rollout protocol): 0.75 s, the dataset builder's blend from the rest pose.
/// Measured: ten frames (0.33 s) threw the apparel of PMX rigs about at the start, where the learned apparel missed
/// their own physics most (CHANGELOG.md, "A lead-in as long as the training data's").
inline constexpr int kDefaultLeadInFrames = 23;

/// The weight of a motion's first frame in lead-in frame k (0-based) of n, the frames that blend a character from its
/// rest pose into a motion before the motion starts (`amt animate --lead-in`): s = (k + 1) / (n + 1) eased in and out,
/// s^2 (3 - 2 s), as the dataset builder blends its clips from the rest pose (blend_from_rest,
/// data_tools/builder/motion_library.h): the pose leaves the rest pose and reaches the first frame without a jolt.
inline float lead_in_weight(int64_t k, int64_t n) {
  const float s = static_cast<float>(k + 1) / static_cast<float>(n + 1);
  return s * s * (3.0f - 2.0f * s);
}

}  // namespace amt
