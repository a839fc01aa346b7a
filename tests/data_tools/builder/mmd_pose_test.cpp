// MMD's pose evaluation on hand-made models: key translations and rotations down the hierarchy, leg IK on a
// two-link leg with MMD's knee limits (the ankle reaches a reachable goal, the knee bends forwards and stays in its
// limits) and toe IK after it, append rotation and translation at weight 0.5, and keys on bones the model does not
// have (counted, no error).
#include "data_tools/builder/mmd_pose.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "data_tools/formats/vmd_import.h"
#include "tests/data_tools/formats/vmd_dance.h"

namespace amt {
namespace {

constexpr float kPi = 3.14159265358979f;

PmxBone bone(const std::string& name, const Eigen::Vector3f& position, int parent) {
  PmxBone b;
  b.name = name;
  b.position = position;
  b.parent = parent;
  b.rotatable = b.translatable = b.visible = b.enabled = true;
  return b;
}

// A left leg in MMD's frame (PMX units, facing -Z): hip 10 units up, knee at 5, ankle at 0, toe 2 units in front,
// leg IK on the ankle (MMD's standard: 40 iterations, 2 radians per step, the knee limited to x in [-180, -0.5]
// degrees) and toe IK on the toe below it. `loops` replaces the leg IK's 40 iterations.
PmxModel leg(int loops = 40) {
  PmxModel m;
  m.source = "leg.pmx";
  m.bones.push_back(bone("左足", {0, 10, 0}, -1));     // 0
  m.bones.push_back(bone("左ひざ", {0, 5, 0}, 0));     // 1
  m.bones.push_back(bone("左足首", {0, 0, 0}, 1));     // 2
  m.bones.push_back(bone("左つま先", {0, 0, -2}, 2));  // 3
  PmxBone ik = bone("左足ＩＫ", {0, 0, 0}, -1);        // 4
  ik.is_ik = true;
  ik.ik.target = 2;
  ik.ik.loop_count = loops;
  ik.ik.limit_angle = 2.0f;
  PmxIkLink knee;
  knee.bone = 1;
  knee.has_limits = true;
  knee.limit_min = Eigen::Vector3f(-kPi, 0, 0);
  knee.limit_max = Eigen::Vector3f(-0.5f * kPi / 180, 0, 0);
  PmxIkLink hip;
  hip.bone = 0;
  ik.ik.links = {knee, hip};
  m.bones.push_back(ik);
  PmxBone toe = bone("左つま先ＩＫ", {0, 0, -2}, 4);  // 5
  toe.is_ik = true;
  toe.ik.target = 3;
  toe.ik.loop_count = 3;
  toe.ik.limit_angle = 4.0f;
  PmxIkLink ankle;
  ankle.bone = 2;
  toe.ik.links = {ankle};
  m.bones.push_back(toe);
  return m;
}

Eigen::Vector3f position(const Transforms& pose, int b) {
  return pose[size_t(b)].col(3);
}

Eigen::Matrix3f rotation(const Transforms& pose, int b) {
  return pose[size_t(b)].leftCols<3>();
}

TEST(MmdPose, KeysMoveBonesDownTheHierarchy) {
  PmxModel m = leg();
  m.bones.resize(4);  // without the IK bones
  MmdPoser poser(m);
  std::vector<VmdBonePose> local(m.bones.size());
  local[0].translation = Eigen::Vector3f(1, 0, 0);
  local[0].rotation = Eigen::Quaternionf(Eigen::AngleAxisf(0.5f * kPi, Eigen::Vector3f::UnitZ()));
  local[1].rotation = Eigen::Quaternionf(Eigen::AngleAxisf(-0.5f * kPi, Eigen::Vector3f::UnitX()));
  const Transforms pose = poser.pose(local);
  // Hip at (1, 10, 0), turned 90 degrees about Z: the thigh (-Y at rest) points along +X. The knee's -90 degrees
  // about X turn the shin from -Y to +Z, which the hip's turn about Z keeps; the toe's rest offset (0, 0, -2) goes
  // to (0, -2, 0) by the knee's turn and to (2, 0, 0) by the hip's.
  EXPECT_LT((position(pose, 0) - Eigen::Vector3f(1, 10, 0)).norm(), 1e-5f);
  EXPECT_LT((position(pose, 1) - Eigen::Vector3f(6, 10, 0)).norm(), 1e-4f);
  EXPECT_LT((position(pose, 2) - Eigen::Vector3f(6, 10, 5)).norm(), 1e-4f);
  EXPECT_LT((position(pose, 3) - Eigen::Vector3f(8, 10, 5)).norm(), 1e-4f);
}

// The leg IK goal at `goal` (the IK bone's key translation; its rest position is the ankle's, the origin).
Transforms leg_ik(const Eigen::Vector3f& goal, int loops = 40) {
  const PmxModel m = leg(loops);
  MmdPoser poser(m);
  std::vector<VmdBonePose> local(m.bones.size());
  local[4].translation = goal;
  return poser.pose(local);
}

TEST(MmdPose, LegIkReachesTheGoalWithTheKneeForwardsAndInItsLimits) {
  // Goals in the leg's plane converge within MMD's 40 iterations. CCD converges linearly: a goal out of the plane
  // (the hip must roll the knee's plane) and one straight below the hip (a straight leg sees the ankle and the goal
  // in line, and only the knee's -0.5 degree stop starts the bend) need more, as in MMD.
  const std::pair<Eigen::Vector3f, int> cases[] = {{Eigen::Vector3f(0, 3, -0.5f), 40},
                                                   {Eigen::Vector3f(0, 2, 1.5f), 40},
                                                   {Eigen::Vector3f(0.8f, 1, -2), 100},
                                                   {Eigen::Vector3f(0, 1.5f, 0), 100}};
  for (const auto& [goal, loops] : cases) {
    const Transforms pose = leg_ik(goal, loops);
    EXPECT_LT((position(pose, 2) - goal).norm(), 1e-3f) << goal.transpose();
    // Forwards is -Z: the knee lies in front of the line from the hip to the ankle.
    const Eigen::Vector3f hip = position(pose, 0), knee = position(pose, 1), ankle = position(pose, 2);
    const float along = (knee - hip).dot(ankle - hip) / (ankle - hip).squaredNorm();
    const Eigen::Vector3f on_line = hip + along * (ankle - hip);
    EXPECT_LT(knee.z() - on_line.z(), -0.5f) << goal.transpose();
    // The knee turns about its X axis only, by an angle in [-180, -0.5] degrees.
    const Eigen::Matrix3f local = rotation(pose, 0).transpose() * rotation(pose, 1);
    const Eigen::AngleAxisf aa(local);
    const float angle = aa.axis().x() < 0 ? -aa.angle() : aa.angle();
    EXPECT_GT(std::abs(aa.axis().x()), 1 - 1e-4f) << goal.transpose();
    EXPECT_LE(angle, -0.5f * kPi / 180 + 1e-5f);
    EXPECT_GE(angle, -kPi - 1e-5f);
    // Bone lengths are kept.
    EXPECT_NEAR((knee - hip).norm(), 5, 1e-4f);
    EXPECT_NEAR((ankle - knee).norm(), 5, 1e-4f);
  }
}

TEST(MmdPose, LegIkOutOfReachStretchesTheLegTowardsTheGoal) {
  const Transforms pose = leg_ik(Eigen::Vector3f(0, -5, 0));  // 15 units below the hip; the leg is 10 long
  EXPECT_LT((position(pose, 2) - Eigen::Vector3f(0, 0, 0)).norm(), 0.05f);
  const Eigen::AngleAxisf knee(Eigen::Matrix3f(rotation(pose, 0).transpose() * rotation(pose, 1)));
  EXPECT_LT(knee.angle(), 0.1f);  // nearly straight, at its -0.5 degree limit or close
}

TEST(MmdPose, ToeIkAfterLegIk) {
  const PmxModel m = leg();
  MmdPoser poser(m);
  std::vector<VmdBonePose> local(m.bones.size());
  local[4].translation = Eigen::Vector3f(0, 3, -0.5f);
  // The toe IK hangs below the leg IK: at rest 2 units in front of it, moved so that the toe must point 30 degrees
  // up: (0, 1, -sqrt 3) from the ankle, 2 units away.
  local[5].translation = Eigen::Vector3f(0, 1, 2 - std::sqrt(3.0f));
  const Transforms pose = poser.pose(local);
  EXPECT_LT((position(pose, 2) - Eigen::Vector3f(0, 3, -0.5f)).norm(), 1e-3f);
  EXPECT_LT((position(pose, 3) - Eigen::Vector3f(0, 4, -0.5f - std::sqrt(3.0f))).norm(), 1e-3f);
}

TEST(MmdPose, AppendRotationAndTranslationAtHalfWeight) {
  PmxModel m;
  m.source = "append.pmx";
  m.bones.push_back(bone("元", {0, 0, 0}, -1));  // 0: keyed
  PmxBone half = bone("半分", {0, 5, 0}, -1);    // 1: half of 元's rotation and translation
  half.inherit_rotation = half.inherit_translation = true;
  half.inherit_parent = 0;
  half.inherit_weight = 0.5f;
  half.layer = 1;
  m.bones.push_back(half);
  PmxBone quarter = bone("四分の一", {0, 8, 0}, -1);  // 2: half of 半分's append rotation
  quarter.inherit_rotation = true;
  quarter.inherit_parent = 1;
  quarter.inherit_weight = 0.5f;
  quarter.layer = 1;
  m.bones.push_back(quarter);
  MmdPoser poser(m);
  std::vector<VmdBonePose> local(m.bones.size());
  local[0].rotation = Eigen::Quaternionf(Eigen::AngleAxisf(1.0f, Eigen::Vector3f::UnitY()));
  local[0].translation = Eigen::Vector3f(2, 0, 0);
  const Transforms pose = poser.pose(local);
  const Eigen::AngleAxisf r1(rotation(pose, 1)), r2(rotation(pose, 2));
  EXPECT_NEAR(r1.angle(), 0.5f, 1e-5f);
  EXPECT_NEAR(r1.axis().y(), 1.0f, 1e-5f);
  EXPECT_NEAR(r2.angle(), 0.25f, 1e-5f);
  EXPECT_LT((position(pose, 1) - Eigen::Vector3f(1, 5, 0)).norm(), 1e-5f);
  EXPECT_LT((position(pose, 2) - Eigen::Vector3f(0, 8, 0)).norm(), 1e-5f);  // rotation only
}

TEST(MmdPose, KeysOnUnknownBonesAreCountedNotAnError) {
  const PmxModel m = leg();
  VmdMotion motion;
  motion.source = "dance.vmd";
  motion.bone_keys.push_back(test::vmd_key("左足ＩＫ", 0, {0, 3, -0.5f}));
  motion.bone_keys.push_back(test::vmd_key("左足ＩＫ", 10, {0, 2, -0.5f}));
  motion.bone_keys.push_back(test::vmd_key("存在しない", 0, {0, 0, 0}));
  motion.bone_keys.push_back(test::vmd_key("存在しない", 4, {0, 0, 0}));
  motion.bone_keys.push_back(test::vmd_key("右足ＩＫ", 4, {0, 1, 0}));
  const MmdBoneMotion out = mmd_bone_motion(m, motion);
  EXPECT_EQ(out.frames, 11);
  EXPECT_EQ(out.globals.size(), 11 * m.bones.size());
  EXPECT_EQ(out.matched_bones, 1);
  EXPECT_EQ(out.unmatched_keys, 3u);
  EXPECT_EQ(out.unmatched_bones, (std::vector<std::string>{"右足ＩＫ", "存在しない"}));
  // Linear keys: at frame 5 the goal is halfway, and the ankle is on it.
  const Eigen::Vector3f ankle = out.globals[5 * m.bones.size() + 2].col(3);
  EXPECT_LT((ankle - Eigen::Vector3f(0, 2.5f, -0.5f)).norm(), 1e-3f);
  // Keeping only the ankle gives the same transforms, one per frame.
  const MmdBoneMotion ankle_only = mmd_bone_motion(m, motion, {2});
  ASSERT_EQ(ankle_only.globals.size(), 11u);
  EXPECT_TRUE(ankle_only.globals[5].isApprox(out.globals[5 * m.bones.size() + 2]));
}

TEST(MmdPose, LongBoneNamesMatchTheirCutKeys) {
  PmxModel m;
  m.source = "long.pmx";
  m.bones.push_back(bone("あいうえおかきくけこ", {0, 0, 0}, -1));  // 20 bytes in Shift-JIS
  VmdMotion motion;
  motion.bone_keys.push_back(test::vmd_key(vmd_field_name("あいうえおかきくけこ"), 0, {1, 2, 3}));
  const MmdBoneMotion out = mmd_bone_motion(m, motion);
  EXPECT_EQ(out.matched_bones, 1);
  EXPECT_EQ(out.unmatched_keys, 0u);
  EXPECT_LT((Eigen::Vector3f(out.globals[0].col(3)) - Eigen::Vector3f(1, 2, 3)).norm(), 1e-6f);
}

}  // namespace
}  // namespace amt
