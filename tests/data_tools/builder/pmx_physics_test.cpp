#include "data_tools/builder/pmx_physics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

constexpr float kDegree = 3.14159265358979f / 180.0f;

std::string fixture(const std::string& name) {
  return std::string(AMT_ASSET_DIR) + "/pmx/" + name;
}

// Bullet's 6-DOF angles (x, y, z) of a relative rotation R_rel = A^T B (joint frame on B seen from the one on A):
// the XYZ Euler angles of R_rel^T, R_rel^T = Rx(x) Ry(y) Rz(z). So B turned by +a about the joint's X axis reads
// x = -a (checked against btGeneric6DofSpringConstraint::getAngle when this test was written).
Eigen::Vector3f bullet_6dof_angles(const Eigen::Matrix3f& R_rel) {
  const Eigen::Matrix3f M = R_rel.transpose();
  return Eigen::Vector3f(std::atan2(-M(1, 2), M(2, 2)), std::asin(std::clamp(M(0, 2), -1.0f, 1.0f)),
                         std::atan2(-M(0, 1), M(0, 0)));
}

// The joint's frame as carried by body `b` (its rest offset from the body applied to the body's current pose).
Eigen::Matrix3f joint_frame_on(const PhysicsWorld& world, int b, const PhysicsJoint& joint) {
  const Eigen::Quaternionf offset = body_rest_pose(world.rig(), b).rotation.conjugate() * joint.rest.rotation;
  return (world.body_pose(b).rotation * offset).toRotationMatrix();
}

TEST(PmxPhysics, RigOfTheConstraintFixture) {
  const PmxModel model = read_pmx(fixture("constraint_test.pmx"));
  const PhysicsRig rig = pmx_physics_rig(model);
  ASSERT_EQ(rig.num_bones(), 2);
  ASSERT_EQ(rig.num_bodies(), 2);
  ASSERT_EQ(rig.num_joints(), 1);
  EXPECT_EQ(rig.bones[1].parent, 0);
  EXPECT_EQ(rig.bones[1].rest_position, Eigen::Vector3f(0, 5, 0));
  EXPECT_EQ(rig.bodies[0].mode, PhysicsMode::kFollowBone);
  EXPECT_EQ(rig.bodies[1].mode, PhysicsMode::kDynamic);
  EXPECT_EQ(rig.bodies[1].shape, PhysicsShape::kBox);
  EXPECT_EQ(rig.bodies[1].size, Eigen::Vector3f(2, 2, 2));
  EXPECT_TRUE(rig.bodies[1].rest.position.isApprox(Eigen::Vector3f(0, 8.1f, 0)));
  // Stored mask 0xFFFF: collides with every group, so no non-collision bits.
  EXPECT_EQ(rig.bodies[1].non_collision_mask, 0);
  EXPECT_EQ(rig.joints[0].body_a, 0);
  EXPECT_EQ(rig.joints[0].body_b, 1);
  EXPECT_NEAR(rig.joints[0].angular_max.x(), 90 * kDegree, 1e-5f);
  EXPECT_EQ(pmx_physics_settings().gravity, Eigen::Vector3f(0, -98, 0));
}

TEST(PmxPhysics, ApparelMaskIsTheVerticesOfPhysicsDrivenBones) {
  // The fixture: box 1 (vertices 0-23) on bone 0, which a body follows; box 2 (24-47) on bone 1, which a
  // simulated body drives.
  PmxModel model = read_pmx(fixture("constraint_test.pmx"));
  int drivers = 0;
  std::vector<uint8_t> mask = pmx_physics_apparel_mask(model, &drivers);
  ASSERT_EQ(mask.size(), 48u);
  EXPECT_EQ(drivers, 1);
  for (int i = 0; i < 48; ++i) EXPECT_EQ(mask[i], i >= 24 ? 1 : 0) << "vertex " << i;
  // A tip bone below the simulated bone (no body of its own) moves with it; one below the followed bone
  // does not; a vertex with any weight on a driven bone is apparel.
  PmxBone tip = model.bones[1], still = model.bones[0];
  tip.parent = 1;
  still.parent = 0;
  model.bones.push_back(tip);    // bone 2
  model.bones.push_back(still);  // bone 3
  model.vertices.bone_indices.row(0) << 2, -1, -1, -1;
  model.vertices.bone_indices.row(1) << 3, -1, -1, -1;
  model.vertices.bone_indices.row(2) << 0, 1, -1, -1;
  model.vertices.bone_weights.row(2) << 0.9f, 0.1f, 0, 0;
  model.vertices.bone_indices.row(30) << 0, 1, -1, -1;
  model.vertices.bone_weights.row(30) << 1.0f, 0.0f, 0, 0;  // a zero weight does not count
  mask = pmx_physics_apparel_mask(model);
  EXPECT_EQ(mask[0], 1);
  EXPECT_EQ(mask[1], 0);
  EXPECT_EQ(mask[2], 1);
  EXPECT_EQ(mask[30], 0);
  // Nothing simulated: no apparel.
  for (PmxRigidBody& body : model.rigid_bodies) body.mode = PmxPhysicsMode::kFollowBone;
  mask = pmx_physics_apparel_mask(model, &drivers);
  EXPECT_EQ(drivers, 0);
  EXPECT_EQ(std::count(mask.begin(), mask.end(), uint8_t(1)), 0);
}

TEST(PmxPhysics, MasksEulerAnglesAndSkippedJointsConvert) {
  PmxModel model = read_pmx(fixture("constraint_test4.pmx"));
  model.rigid_bodies[1].collision_mask = 0xFFFF & ~(1 << 3);
  model.rigid_bodies[1].rotation = Eigen::Vector3f(0.1f, 0.2f, 0.3f);
  PmxJoint dangling = model.joints[0];
  dangling.rigid_body_b = -1;
  model.joints.push_back(dangling);
  const PhysicsRig rig = pmx_physics_rig(model);
  EXPECT_EQ(rig.bodies[1].non_collision_mask, 1 << 3);
  EXPECT_TRUE(rig.bodies[1].rest.rotation.toRotationMatrix().isApprox(pmx_euler_rotation({0.1f, 0.2f, 0.3f}), 1e-5f));
  EXPECT_EQ(rig.num_joints(), 1);
  EXPECT_TRUE(rig.joints[0].rest.rotation.isApprox(
      Eigen::Quaternionf(Eigen::AngleAxisf(45 * kDegree, Eigen::Vector3f::UnitY())), 1e-5f));

  model.rigid_bodies[1].mass = 0;
  EXPECT_THROW(pmx_physics_rig(model), Error);
  EXPECT_THROW(pmx_physics_rig(pmx_to_amt_frame(read_pmx(fixture("constraint_test.pmx")))), Error);
}

// Simulates each fixture 2 s in MMD units while the centre bone shakes, and checks the dynamic box against the
// joint's angular limits every frame, measured as Bullet measures them (bullet_6dof_angles).
TEST(PmxPhysics, DynamicBodyStaysWithinTheJointLimits) {
  for (const char* name :
       {"constraint_test.pmx", "constraint_test2.pmx", "constraint_test3.pmx", "constraint_test4.pmx"}) {
    SCOPED_TRACE(name);
    const PhysicsRig rig = pmx_physics_rig(read_pmx(fixture(name)));
    const PhysicsJoint& joint = rig.joints[0];
    PhysicsWorld world(rig, pmx_physics_settings());
    const Transforms rest = physics_rest_pose(rig);
    world.reset(rest);
    const float tolerance = 3 * kDegree;
    float largest = 0;
    for (int frame = 1; frame <= 60; ++frame) {
      const float t = frame / 30.0f;
      Transforms pose = rest;
      const Eigen::Vector3f shake(3.0f * std::sin(2 * 3.14159265f * t), 0, 3.0f * std::sin(2 * 3.14159265f * 1.3f * t));
      pose[0].col(3) += shake;
      pose[1].col(3) += shake;
      world.set_bone_pose(pose);
      world.step(1.0f / 30.0f);
      const Eigen::Vector3f angles = bullet_6dof_angles(joint_frame_on(world, joint.body_a, joint).transpose() *
                                                        joint_frame_on(world, joint.body_b, joint));
      for (int k = 0; k < 3; ++k) {
        const float lo = std::min(joint.angular_min[k], joint.angular_max[k]);
        const float hi = std::max(joint.angular_min[k], joint.angular_max[k]);
        ASSERT_GE(angles[k], lo - tolerance) << "frame " << frame << " axis " << k;
        ASSERT_LE(angles[k], hi + tolerance) << "frame " << frame << " axis " << k;
        largest = std::max(largest, std::abs(angles[k]));
      }
      // Mode 1: the simulated bone carries the box rigidly.
      const RigidPose box = world.body_pose(1);
      const Transform34& T = world.bone_transforms()[1];
      const Eigen::Vector3f carried =
          T.leftCols<3>() * (rig.bodies[1].rest.position - rig.bones[1].rest_position) + T.col(3);
      EXPECT_TRUE(carried.isApprox(box.position, 1e-4f)) << carried.transpose() << " vs " << box.position.transpose();
    }
    // The shaking tipped the box: the test exercised the limits.
    EXPECT_GT(largest, 10 * kDegree);
  }
}

TEST(PmxPhysics, TransformsToAmtMatchTheConvertedModel) {
  const PmxModel model = read_pmx(fixture("constraint_test.pmx"));
  const PmxModel amt_model = pmx_to_amt_frame(model, 0.08f);
  Transforms pose = physics_rest_pose(pmx_physics_rig(model));
  // Bone 1 turned by Euler angles e in the file's frame is turned by pmx_to_amt_euler(e) in amt's.
  const Eigen::Vector3f e(0.3f, -0.2f, 0.5f);
  pose[1] = make_transform(pmx_euler_rotation(e), Eigen::Vector3f(1, 5, 2));
  const Transforms out = pmx_transforms_to_amt(pose, 0.08f);
  EXPECT_TRUE(Eigen::Vector3f(out[0].col(3)).isApprox(amt_model.bones[0].position));
  EXPECT_TRUE(Eigen::Vector3f(out[1].col(3)).isApprox(Eigen::Vector3f(0.08f, 0.4f, -0.16f)));
  EXPECT_TRUE(Eigen::Matrix3f(out[1].leftCols<3>()).isApprox(pmx_euler_rotation(pmx_to_amt_euler(e)), 1e-5f));
}

}  // namespace
}  // namespace amt
