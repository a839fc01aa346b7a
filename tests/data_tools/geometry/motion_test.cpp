// Forward kinematics on a hand-built 3-joint chain, against positions worked out by hand.
#include "data_tools/geometry/motion.h"

#include <gtest/gtest.h>

#include <cmath>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

// A chain along +X: root at the origin, joint 1 at (1,0,0), joint 2 at (3,0,0).
Skeleton chain() {
  Skeleton s;
  s.names = {"root", "mid", "tip"};
  s.parents = {-1, 0, 1};
  s.rest_joints.resize(3, 3);
  s.rest_joints << 0, 0, 0, 1, 0, 0, 3, 0, 0;
  return s;
}

Eigen::Quaternionf about_z(float degrees) {
  return Eigen::Quaternionf(Eigen::AngleAxisf(degrees * float(M_PI) / 180.0f, Eigen::Vector3f::UnitZ()));
}

TEST(ForwardKinematics, RestPoseIsIdentityAtRestPositions) {
  const Skeleton s = chain();
  const Transforms T = forward_kinematics(s, rest_motion(s, 1), 0);
  for (int j = 0; j < 3; ++j) {
    EXPECT_TRUE(T[j].leftCols<3>().isIdentity(1e-6f));
    EXPECT_TRUE(T[j].col(3).isApprox(s.rest_joints.row(j).transpose()));
  }
}

TEST(ForwardKinematics, ThreeJointChainByHand) {
  const Skeleton s = chain();
  Motion m = rest_motion(s, 1);
  // Root turns 90 degrees about Z, the middle joint another 90: the first bone points along +Y, the
  // second along -X. Root moved by (0, 0, 2).
  m.rotation(0, 0) = about_z(90);
  m.rotation(0, 1) = about_z(90);
  m.root_translation.row(0) << 0, 0, 2;
  const Transforms T = forward_kinematics(s, m, 0);
  EXPECT_TRUE(T[0].col(3).isApprox(Eigen::Vector3f(0, 0, 2), 1e-6f));
  EXPECT_NEAR((T[1].col(3) - Eigen::Vector3f(0, 1, 2)).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR((T[2].col(3) - Eigen::Vector3f(-2, 1, 2)).norm(), 0.0f, 1e-6f);
  // Global rotation of the tip is the 180 degree turn about Z.
  const Eigen::Matrix3f expected = about_z(180).toRotationMatrix();
  EXPECT_TRUE(T[2].leftCols<3>().isApprox(expected, 1e-5f));
  // A point one unit past the tip at rest, rigidly attached to the tip: R (p - J) + t.
  const Eigen::Vector3f p(4, 0, 0);
  const Eigen::Vector3f moved = T[2].leftCols<3>() * (p - s.rest_joints.row(2).transpose()) + T[2].col(3);
  EXPECT_NEAR((moved - Eigen::Vector3f(-3, 1, 2)).norm(), 0.0f, 1e-5f);
  // The same through the skinning matrices.
  const Transforms M = skinning_matrices(s, T);
  EXPECT_NEAR((apply(M[2], p) - moved).norm(), 0.0f, 1e-6f);
}

TEST(ForwardKinematics, AllFramesMatchPerFrame) {
  const Skeleton s = chain();
  Motion m = rest_motion(s, 4);
  for (int t = 0; t < 4; ++t) m.rotation(t, 1) = about_z(10.0f * t);
  const Transforms all = forward_kinematics(s, m);
  ASSERT_EQ(all.size(), 12u);
  for (int t = 0; t < 4; ++t) {
    const Transforms one = forward_kinematics(s, m, t);
    for (int j = 0; j < 3; ++j) EXPECT_TRUE(all[t * 3 + j].isApprox(one[j]));
  }
}

TEST(Motion, ValidationNamesTheProblem) {
  const Skeleton s = chain();
  Motion m = rest_motion(s, 2);
  m.rotation(1, 2) = Eigen::Quaternionf(std::nanf(""), 0, 0, 0);
  try {
    validate_motion(m, s, "clip.bvh");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("clip.bvh: rotations: expected unit quaternions"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("joint tip"), std::string::npos) << e.what();
  }
  Motion bad_fps = rest_motion(s, 2, 0.0f);
  EXPECT_THROW(validate_motion(bad_fps, s, "clip.bvh"), Error);
}

TEST(Skeleton, CanonicalIsValidAndTopological) {
  const Skeleton s = canonical_skeleton();
  EXPECT_EQ(s.num_joints(), kCanonicalJointCount);
  EXPECT_NO_THROW(validate_skeleton(s, "canonical"));
  EXPECT_TRUE(is_canonical(s));
  EXPECT_EQ(s.index_of("left_wrist"), kLeftWrist);
  EXPECT_EQ(s.parents[kLeftWrist], kLeftElbow);
  EXPECT_EQ(s.index_of("tail"), -1);
  Skeleton broken = s;
  broken.parents[5] = 7;  // parent after child
  EXPECT_THROW(validate_skeleton(broken, "x"), Error);
}

}  // namespace
}  // namespace amt
