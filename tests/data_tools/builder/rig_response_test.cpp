#include "data_tools/builder/rig_response.h"

#include <gtest/gtest.h>

#include <string>

#include "data_tools/geometry/apparel_topology.h"
#include "data_tools/geometry/error.h"

namespace amt {
namespace {

// A pendulum in `unit` lengths per metre: a kinematic anchor on bone 0 at a head's height (1.6 m, off the origin: the
// world poses bones by their frames, the probe by skinning transforms, and only a rig away from the origin tells
// them apart), a 0.4 m capsule hanging down
// on bone 1 (its head at the pivot) jointed to it there with the given angular limits and spring, and bone 2 (no
// body) at the capsule's lower end, a child of bone 1 (bone_tails: bone 1 is measured at the tip, the tip half a
// bone below it).
PhysicsRig pendulum(const Eigen::Vector3f& angular_min, const Eigen::Vector3f& angular_max, float stiffness,
                    float damping, float unit = 1.0f) {
  const Eigen::Vector3f origin = Eigen::Vector3f(0.3f, 1.6f, -0.2f) * unit;
  PhysicsRig rig;
  rig.bones = {{"anchor", -1, origin}, {"hair", 0, origin}, {"tip", 1, origin + Eigen::Vector3f(0, -0.4f * unit, 0)}};
  PhysicsBody anchor;
  anchor.name = "anchor";
  anchor.rest = {origin, Eigen::Quaternionf::Identity()};
  anchor.bone = 0;
  anchor.shape = PhysicsShape::kSphere;
  anchor.size = Eigen::Vector3f(0.05f * unit, 0, 0);
  anchor.group = 0;
  anchor.non_collision_mask = 0x0002;
  PhysicsBody hair;
  hair.name = "hair";
  hair.bone = 1;
  hair.shape = PhysicsShape::kCapsule;
  hair.size = Eigen::Vector3f(0.03f * unit, 0.34f * unit, 0);  // radius, cylinder height: 0.4 tip to tip
  hair.rest = {origin + Eigen::Vector3f(0, -0.2f * unit, 0), Eigen::Quaternionf::Identity()};
  hair.mode = PhysicsMode::kDynamic;
  hair.linear_damping = hair.angular_damping = damping;
  hair.group = 1;
  hair.non_collision_mask = 0x0001;
  rig.bodies = {anchor, hair};
  PhysicsJoint joint;
  joint.name = "root";
  joint.body_a = 0;
  joint.body_b = 1;
  joint.rest = {origin, Eigen::Quaternionf::Identity()};
  joint.angular_min = angular_min;
  joint.angular_max = angular_max;
  joint.angular_stiffness = Eigen::Vector3f::Constant(stiffness * unit * unit);
  rig.joints = {joint};
  return rig;
}

const Eigen::Vector3f kFreeMin = Eigen::Vector3f::Constant(1.0f);  // min > max: free
const Eigen::Vector3f kFreeMax = Eigen::Vector3f::Constant(-1.0f);

TEST(RigResponse, ALoosePendulumSwingsAStiffOneLessAndALockedOneNot) {
  const MatrixXfR loose = rig_response(pendulum(kFreeMin, kFreeMax, 0.0f, 0.1f), PhysicsSettings{}, 1.0f);
  ASSERT_EQ(loose.rows(), 3);
  ASSERT_EQ(loose.cols(), kRigResponseChannels);
  // Which bones the simulation moves: the anchor no, the hair and its child yes.
  EXPECT_EQ(loose.row(0), Eigen::RowVector3f::Zero());
  EXPECT_EQ(loose(1, 0), 1.0f);
  EXPECT_EQ(loose(2, 0), 1.0f);
  // The hair bone is measured at its tail (the tip's head), the tip, carried by it, half a bone further out: both
  // lag the sway and keep swinging after it (a 0.4 m pendulum, period 1.27 s, driven at 1.2 Hz), the tip 1.5x as far.
  EXPECT_GT(loose(1, 1), 0.3f);
  EXPECT_GT(loose(1, 2), 0.3f);
  EXPECT_NEAR(loose(2, 1) / loose(1, 1), 1.5f, 0.05f);
  EXPECT_LE(loose(2, 1), 4.0f);

  const MatrixXfR stiff = rig_response(pendulum(kFreeMin, kFreeMax, 20.0f, 0.9f), PhysicsSettings{}, 1.0f);
  EXPECT_LT(stiff(1, 1), 0.6f * loose(1, 1));
  EXPECT_LT(stiff(1, 2), 0.3f * loose(1, 2));  // damped: little is left once the body stops

  const MatrixXfR locked =
      rig_response(pendulum(Eigen::Vector3f::Zero(), Eigen::Vector3f::Zero(), 0.0f, 0.1f), PhysicsSettings{}, 1.0f);
  EXPECT_EQ(locked(1, 0), 1.0f);  // simulated, but held rigidly
  EXPECT_LT(locked(1, 1), 0.1f);
  EXPECT_LT(locked(1, 2), 0.1f);

  // Deterministic: the world is rebuilt for every call.
  EXPECT_EQ(rig_response(pendulum(kFreeMin, kFreeMax, 0.0f, 0.1f), PhysicsSettings{}, 1.0f), loose);
}

TEST(RigResponse, IsTheSameInAnyLengthUnitAndZeroForAKinematicRig) {
  // The loose pendulum in PMX-like units (12.5 per metre, gravity scaled with them): the response is per unit of
  // sway, so it does not depend on the unit.
  const float unit = 12.5f;
  PhysicsSettings scaled;
  scaled.gravity *= unit;
  scaled.box_margin *= unit;
  const MatrixXfR metres = rig_response(pendulum(kFreeMin, kFreeMax, 0.0f, 0.1f), PhysicsSettings{}, 1.0f);
  const MatrixXfR units = rig_response(pendulum(kFreeMin, kFreeMax, 0.0f, 0.1f, unit), scaled, 1.0f / unit);
  EXPECT_NEAR(units(1, 1), metres(1, 1), 0.1f * metres(1, 1));
  EXPECT_NEAR(units(1, 2), metres(1, 2), 0.1f * metres(1, 2));

  PhysicsRig kinematic = pendulum(kFreeMin, kFreeMax, 0.0f, 0.1f);
  kinematic.bodies[1].mode = PhysicsMode::kFollowBone;
  EXPECT_TRUE(rig_response(kinematic, PhysicsSettings{}, 1.0f).isZero());
}

TEST(RigResponse, RefusesBadUnitsProbesAndRigs) {
  const PhysicsRig rig = pendulum(kFreeMin, kFreeMax, 0.0f, 0.1f);
  EXPECT_THROW(rig_response(rig, PhysicsSettings{}, 0.0f), Error);
  RigProbeOptions probe;
  probe.frequency = 0.0f;
  EXPECT_THROW(rig_response(rig, PhysicsSettings{}, 1.0f, probe), Error);
  probe = RigProbeOptions{};
  probe.hold_seconds = 0.0f;
  EXPECT_THROW(rig_response(rig, PhysicsSettings{}, 1.0f, probe), Error);
  PhysicsRig broken = rig;
  broken.bodies[1].mass = 0.0f;
  try {
    rig_response(broken, PhysicsSettings{}, 1.0f);
    ADD_FAILURE() << "expected an error: a simulated body without mass";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("mass"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace amt
