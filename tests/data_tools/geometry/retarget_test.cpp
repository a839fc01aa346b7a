// Retargeting between a T-pose and an A-pose skeleton of other proportions: every posed bone of
// the target points where the source's does, and root translation scales with leg length.
#include "data_tools/geometry/retarget.h"

#include <gtest/gtest.h>

#include <random>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

// The canonical T-pose scaled by 0.8 (a shorter character) with both arms lowered 45 degrees at
// the shoulders (an A-pose) and legs 20 % longer.
Skeleton a_pose_character() {
  const Skeleton t_pose = canonical_skeleton();
  Skeleton s = t_pose;
  // Rebuild positions from scaled bone offsets, so bone directions change only where intended.
  const auto lower_arm = [](int j) {
    return j == kLeftElbow || j == kLeftWrist || j == kRightElbow || j == kRightWrist;
  };
  const auto in_leg = [](int j) {
    return j == kLeftKnee || j == kRightKnee || j == kLeftAnkle || j == kRightAnkle || j == kLeftFoot ||
           j == kRightFoot;
  };
  for (int j = 1; j < s.num_joints(); ++j) {
    const int p = s.parents[j];
    Eigen::Vector3f offset = (t_pose.rest_joints.row(j) - t_pose.rest_joints.row(p)).transpose() * 0.8f;
    if (in_leg(j)) offset *= 1.2f;
    if (lower_arm(j)) {
      const float sign = t_pose.rest_joints(j, 0) > 0 ? -1.0f : 1.0f;  // left arm (+X) turns down about -Z
      offset = Eigen::AngleAxisf(sign * float(M_PI) / 4, Eigen::Vector3f::UnitZ()) * offset;
    }
    s.rest_joints.row(j) = s.rest_joints.row(p) + offset.transpose();
  }
  return s;
}

TEST(Retarget, BoneDirectionsMatchBetweenTPoseAndAPose) {
  const Skeleton source = canonical_skeleton();
  const Skeleton target = a_pose_character();
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1);
  Motion m = rest_motion(source, 6);
  for (int t = 0; t < m.num_frames(); ++t) {
    for (int j = 0; j < source.num_joints(); ++j) {
      m.rotation(t, j) = Eigen::Quaternionf(1, 0.5f * u(rng), 0.5f * u(rng), 0.5f * u(rng)).normalized();
    }
    m.root_translation.row(t) << u(rng), 0.1f * u(rng), u(rng);
  }
  const Motion r = retarget_motion(m, source, target);
  for (int t = 0; t < m.num_frames(); ++t) {
    const Transforms S = forward_kinematics(source, m, t), T = forward_kinematics(target, r, t);
    for (int j = 1; j < source.num_joints(); ++j) {
      const int p = source.parents[j];
      const Eigen::Vector3f ds = (S[j].col(3) - S[p].col(3)).normalized();
      const Eigen::Vector3f dt = (T[j].col(3) - T[p].col(3)).normalized();
      EXPECT_GT(ds.dot(dt), 1.0f - 1e-5f) << "frame " << t << " bone to " << source.names[j];
    }
  }
  // Root translation scales by the ratio of leg lengths: 0.8 * 1.2 = 0.96.
  EXPECT_NEAR(leg_length(target) / leg_length(source), 0.96f, 1e-5f);
  EXPECT_TRUE(r.root_translation.isApprox(m.root_translation * 0.96f, 1e-5f));
}

TEST(Retarget, SourceRestPoseTurnsAPoseIntoTPose) {
  // The source's rest pose, retargeted, lifts the target's lowered arms back to horizontal.
  const Skeleton source = canonical_skeleton(), target = a_pose_character();
  const Motion r = retarget_motion(rest_motion(source, 1), source, target);
  const Transforms T = forward_kinematics(target, r, 0);
  const Eigen::Vector3f arm = (T[kLeftWrist].col(3) - T[kLeftElbow].col(3)).normalized();
  EXPECT_NEAR(arm.y(), 0.0f, 1e-5f);
  EXPECT_GT(arm.x(), 0.99f);
}

TEST(Retarget, RejectsDifferentSkeletons) {
  Skeleton other = canonical_skeleton();
  other.names[3] = "chest";
  EXPECT_THROW(retarget_motion(rest_motion(canonical_skeleton(), 2), canonical_skeleton(), other), Error);
}

}  // namespace
}  // namespace amt
