#include "data_tools/builder/physics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kDegree = kPi / 180.0f;

Eigen::Quaternionf about(const Eigen::Vector3f& axis, float angle) {
  return Eigen::Quaternionf(Eigen::AngleAxisf(angle, axis.normalized()));
}

PhysicsBone bone(const std::string& name, int parent, const Eigen::Vector3f& rest) {
  return {name, parent, rest};
}

PhysicsBody body(const std::string& name, int bone_index, PhysicsShape shape, const Eigen::Vector3f& size,
                 const RigidPose& rest, PhysicsMode mode, uint8_t group, uint16_t non_collision_mask) {
  PhysicsBody b;
  b.name = name;
  b.bone = bone_index;
  b.shape = shape;
  b.size = size;
  b.rest = rest;
  b.mode = mode;
  b.group = group;
  b.non_collision_mask = non_collision_mask;
  return b;
}

RigidPose at(const Eigen::Vector3f& position, const Eigen::Quaternionf& rotation = Eigen::Quaternionf::Identity()) {
  return {position, rotation};
}

// A joint locking translation, with the given angular limits, at a world position with world axes.
PhysicsJoint joint(const std::string& name, int a, int b, const Eigen::Vector3f& position,
                   const Eigen::Vector3f& angular_min, const Eigen::Vector3f& angular_max,
                   const Eigen::Vector3f& angular_stiffness = Eigen::Vector3f::Zero()) {
  PhysicsJoint j;
  j.name = name;
  j.body_a = a;
  j.body_b = b;
  j.rest = at(position);
  j.angular_min = angular_min;
  j.angular_max = angular_max;
  j.angular_stiffness = angular_stiffness;
  return j;
}

const Eigen::Vector3f kFreeMin = Eigen::Vector3f::Constant(1.0f);  // min > max: free
const Eigen::Vector3f kFreeMax = Eigen::Vector3f::Constant(-1.0f);

// Rotation angle (radians) of body b relative to body a, measured from their relative rotation at rest.
float relative_angle(const PhysicsWorld& world, int a, int b) {
  const Eigen::Quaternionf rest =
      body_rest_pose(world.rig(), a).rotation.conjugate() * body_rest_pose(world.rig(), b).rotation;
  const Eigen::Quaternionf now = world.body_pose(a).rotation.conjugate() * world.body_pose(b).rotation;
  return Eigen::AngleAxisf(now * rest.conjugate()).angle();
}

// Distance from point p to the segment [a, b].
float segment_distance(const Eigen::Vector3f& p, const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  const Eigen::Vector3f ab = b - a;
  const float s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0f, 1.0f);
  return (a + s * ab - p).norm();
}

// === Pendulum

TEST(Physics, PendulumPeriodMatchesTheSmallAngleFormula) {
  const float L = 1.0f, g = 9.8f;
  PhysicsRig rig;
  rig.bones = {bone("anchor", -1, {0, 0, 0}), bone("bob", 0, {0, -L, 0})};
  // A bob of radius 0.1 m: its inertia about the pivot is 1.004 m L^2, which lengthens the period by 0.2 %. (A much
  // smaller radius makes the pivot constraint ill-conditioned for 10 solver iterations and slows the swing.)
  rig.bodies = {
      body("anchor", 0, PhysicsShape::kSphere, {0.02f, 0, 0}, at({0, 0, 0}), PhysicsMode::kFollowBone, 0, 0x0002),
      body("bob", 1, PhysicsShape::kSphere, {0.1f, 0, 0}, at({0, -L, 0}), PhysicsMode::kDynamic, 1, 0x0001)};
  rig.joints = {joint("pivot", 0, 1, {0, 0, 0}, kFreeMin, kFreeMax)};
  PhysicsWorld world(rig);

  Transforms pose = physics_rest_pose(rig);
  const Eigen::Matrix3f R = about({0, 0, 1}, 5.0f * kDegree).toRotationMatrix();
  pose[1] = make_transform(R, R * Eigen::Vector3f(0, -L, 0));
  world.reset(pose);
  EXPECT_NEAR(world.body_pose(1).position.x(), L * std::sin(5.0f * kDegree), 1e-6f);

  // Output at 120 Hz (one substep per step); zero crossings of x interpolated linearly between frames.
  const float dt = 1.0f / 120.0f;
  std::vector<double> crossings;
  float previous_x = world.body_pose(1).position.x();
  for (int frame = 1; frame <= 120 * 10; ++frame) {
    world.step(dt);
    const float x = world.body_pose(1).position.x();
    if ((previous_x > 0) != (x > 0)) crossings.push_back((frame - 1 + previous_x / (previous_x - x)) * dt);
    previous_x = x;
  }
  ASSERT_GE(crossings.size(), 8u);
  const double period = 2.0 * (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
  const double expected = 2.0 * kPi * std::sqrt(L / g);
  EXPECT_NEAR(period, expected, 0.05 * expected) << "measured period " << period << " s, expected " << expected;
  // The string length holds (linear axes locked).
  EXPECT_NEAR(world.body_pose(1).position.norm(), L, 0.01f);
}

// === A hanging chain and a pusher

constexpr int kLinks = 4;
constexpr float kLinkLength = 0.25f;
constexpr float kLinkRadius = 0.04f;
constexpr float kPusherRadius = 0.15f;
const Eigen::Vector3f kAnchor(0, 2, 0);
const Eigen::Vector3f kPusherStart(1.0f, 1.5f, 0);

// Bone 0 anchor, bones 1..4 the links (bone k at the top of link k - 1), bone 5 the pusher. Bodies in bone order.
// Groups: anchor 2, links 1 (no contact with each other or the anchor), pusher 0.
PhysicsRig chain_rig() {
  PhysicsRig rig;
  rig.bones.push_back(bone("anchor", -1, kAnchor));
  rig.bodies.push_back(
      body("anchor", 0, PhysicsShape::kSphere, {0.05f, 0, 0}, at(kAnchor), PhysicsMode::kFollowBone, 2, 0x0002));
  for (int k = 0; k < kLinks; ++k) {
    const Eigen::Vector3f top = kAnchor - Eigen::Vector3f(0, kLinkLength * k, 0);
    rig.bones.push_back(bone("link" + std::to_string(k), k, top));
    PhysicsBody b = body("link" + std::to_string(k), k + 1, PhysicsShape::kCapsule,
                         {kLinkRadius, kLinkLength - 2 * kLinkRadius - 0.01f, 0},
                         at(top - Eigen::Vector3f(0, kLinkLength / 2, 0)), PhysicsMode::kDynamic, 1, 0x0006);
    b.linear_damping = 0.9f;
    b.angular_damping = 0.9f;
    b.mass = 0.2f;
    rig.bodies.push_back(b);
    const Eigen::Vector3f limit(60 * kDegree, 10 * kDegree, 60 * kDegree);
    rig.joints.push_back(
        joint("joint" + std::to_string(k), k, k + 1, top, -limit, limit, Eigen::Vector3f::Constant(5.0f)));
  }
  rig.bones.push_back(bone("pusher", -1, kPusherStart));
  rig.bodies.push_back(body("pusher", kLinks + 1, PhysicsShape::kSphere, {kPusherRadius, 0, 0}, at(kPusherStart),
                            PhysicsMode::kFollowBone, 0, 0x0004));
  return rig;
}

// The rest pose with the pusher moved to x.
Transforms chain_pose(const PhysicsRig& rig, float pusher_x) {
  Transforms pose = physics_rest_pose(rig);
  pose[kLinks + 1].col(3) = Eigen::Vector3f(pusher_x, kPusherStart.y(), kPusherStart.z());
  return pose;
}

// Smallest distance from the pusher's centre to a link capsule's axis, over the links.
float pusher_clearance(const PhysicsWorld& world) {
  const Eigen::Vector3f centre = world.body_pose(kLinks + 1).position;
  const float half = 0.5f * world.rig().bodies[1].size.y();
  float smallest = 1e9f;
  for (int k = 1; k <= kLinks; ++k) {
    const RigidPose p = world.body_pose(k);
    const Eigen::Vector3f axis = p.rotation * Eigen::Vector3f(0, half, 0);
    smallest = std::min(smallest, segment_distance(centre, p.position - axis, p.position + axis));
  }
  return smallest;
}

TEST(Physics, ChainSettlesStraightDownAndIsPushedAsideWithoutPenetration) {
  const PhysicsRig rig = chain_rig();
  PhysicsWorld world(rig);

  // Start with the whole chain swung 40 degrees sideways; it must settle hanging straight down.
  Transforms swung = chain_pose(rig, kPusherStart.x());
  const Eigen::Quaternionf turn = about({0, 0, 1}, 40 * kDegree);
  for (int k = 1; k <= kLinks; ++k) {
    swung[k] = make_transform(turn.toRotationMatrix(), kAnchor + turn * (rig.bones[k].rest_position - kAnchor));
  }
  world.reset(swung);
  EXPECT_GT(world.body_pose(kLinks).position.x(), 0.3f);
  const Transforms start = chain_pose(rig, kPusherStart.x());
  world.settle(start, 6.0f);
  for (int k = 1; k <= kLinks; ++k) {
    SCOPED_TRACE(k);
    EXPECT_NEAR(world.body_pose(k).position.x(), 0.0f, 0.01f);
    EXPECT_NEAR(world.body_pose(k).position.z(), 0.0f, 1e-4f);
    EXPECT_NEAR(world.body_pose(k).position.y(), rig.bodies[k].rest.position.y(), 0.01f);
    EXPECT_LT(world.body_linear_velocity(k).norm(), 0.02f);
    EXPECT_LT(relative_angle(world, 0, k), 3 * kDegree);
  }
  // Bones follow their links: the chain's bone transforms are close to rest.
  const Transforms& settled = world.bone_transforms();
  for (int k = 1; k <= kLinks; ++k) EXPECT_LT((settled[k] - start[k]).norm(), 0.05f) << k;

  // The pusher moves from x = 1 to x = 0 in 3 s at the height of the third link, then holds for 1 s.
  const float fps = 30.0f;
  float worst_clearance = 1e9f;
  for (int frame = 1; frame <= 4 * 30; ++frame) {
    const float x = std::max(0.0f, kPusherStart.x() * (1.0f - frame / (3.0f * fps)));
    world.set_bone_pose(chain_pose(rig, x));
    world.step(1.0f / fps);
    worst_clearance = std::min(worst_clearance, pusher_clearance(world));
  }
  const float tolerance = 0.01f;
  EXPECT_GT(worst_clearance, kPusherRadius + kLinkRadius - tolerance)
      << "deepest penetration " << kPusherRadius + kLinkRadius - worst_clearance << " m";
  // The links at the pusher's height were pushed towards -X, the side away from where it came from.
  EXPECT_LT(world.body_pose(3).position.x(), -0.1f);
  EXPECT_LT(world.body_pose(4).position.x(), -0.1f);
  EXPECT_NEAR(world.body_pose(kLinks + 1).position.x(), 0.0f, 1e-6f);
}

// === Collision groups

// A kinematic box (group 3) on bone 0 and a dynamic sphere (group 4) on bone 1 dropped onto it from 1 m.
float sphere_height_after_drop(uint16_t box_non_collision, uint16_t sphere_non_collision) {
  PhysicsRig rig;
  rig.bones = {bone("floor", -1, {0, 0, 0}), bone("ball", -1, {0, 1, 0})};
  rig.bodies = {
      body("floor", 0, PhysicsShape::kBox, {1, 0.1f, 1}, at({0, 0, 0}), PhysicsMode::kFollowBone, 3, box_non_collision),
      body("ball", 1, PhysicsShape::kSphere, {0.1f, 0, 0}, at({0, 1, 0}), PhysicsMode::kDynamic, 4,
           sphere_non_collision)};
  PhysicsWorld world(rig);
  for (int frame = 0; frame < 60; ++frame) world.step(1.0f / 30.0f);
  // The ball's bone follows the ball.
  EXPECT_LT((world.bone_transforms()[1].col(3) - world.body_pose(1).position).norm(), 1e-5f);
  return world.body_pose(1).position.y();
}

TEST(Physics, CollisionGroupsAndMasksDecideContacts) {
  // Both masks admit the other group: the ball rests on the box (top at 0.1, radius 0.1).
  EXPECT_NEAR(sphere_height_after_drop(0, 0), 0.2f, 0.02f);
  // The ball's mask excludes group 3: it falls through.
  EXPECT_LT(sphere_height_after_drop(0, 1 << 3), -1.0f);
  // The box's mask excludes group 4: no contact either (both sides must admit the pair).
  EXPECT_LT(sphere_height_after_drop(1 << 4, 0), -1.0f);
  // Excluding unrelated groups changes nothing.
  EXPECT_NEAR(sphere_height_after_drop(0xFFFF & ~(1 << 4), 0xFFFF & ~(1 << 3)), 0.2f, 0.02f);
}

// === Springs and limits

// An anchor at the origin and one horizontal capsule link along +X on bone 1, jointed at the origin.
PhysicsRig arm_rig(const Eigen::Vector3f& angular_min, const Eigen::Vector3f& angular_max,
                   const Eigen::Vector3f& stiffness, float damping) {
  PhysicsRig rig;
  rig.bones = {bone("anchor", -1, {0, 0, 0}), bone("arm", 0, {0, 0, 0})};
  PhysicsBody arm = body("arm", 1, PhysicsShape::kCapsule, {0.03f, 0.4f, 0},
                         at({0.25f, 0, 0}, about({0, 0, 1}, -kPi / 2)), PhysicsMode::kDynamic, 1, 0x0001);
  arm.linear_damping = damping;
  arm.angular_damping = damping;
  rig.bodies = {
      body("anchor", 0, PhysicsShape::kSphere, {0.05f, 0, 0}, at({0, 0, 0}), PhysicsMode::kFollowBone, 0, 0x0002), arm};
  rig.joints = {joint("shoulder", 0, 1, {0, 0, 0}, angular_min, angular_max, stiffness)};
  return rig;
}

TEST(Physics, AngularSpringReturnsTowardsRest) {
  PhysicsSettings no_gravity;
  no_gravity.gravity.setZero();
  const Eigen::Vector3f limit = Eigen::Vector3f::Constant(80 * kDegree);
  auto angle_after = [&](float stiffness) {
    const PhysicsRig rig = arm_rig(-limit, limit, Eigen::Vector3f::Constant(stiffness), 0.8f);
    PhysicsWorld world(rig, no_gravity);
    Transforms pose = physics_rest_pose(rig);
    pose[1] = make_transform(about({0, 0, 1}, 40 * kDegree).toRotationMatrix(), Eigen::Vector3f::Zero());
    world.reset(pose);
    EXPECT_NEAR(relative_angle(world, 0, 1), 40 * kDegree, 1e-4f);
    world.settle(physics_rest_pose(rig), 3.0f);
    return relative_angle(world, 0, 1);
  };
  EXPECT_LT(angle_after(20.0f), 5 * kDegree);
  // Without a spring (and without gravity) the displaced arm stays where it was put.
  EXPECT_NEAR(angle_after(0.0f), 40 * kDegree, 1 * kDegree);
}

TEST(Physics, ArmWithoutSpringHangsUnderGravityAndStiffSpringHoldsIt) {
  auto droop_after = [&](float stiffness) {
    const PhysicsRig rig =
        arm_rig(-Eigen::Vector3f(0, 0, kPi), Eigen::Vector3f(0, 0, kPi), Eigen::Vector3f::Constant(stiffness), 0.9f);
    PhysicsWorld world(rig);
    world.settle(physics_rest_pose(rig), 4.0f);
    // The angle between the arm's axis (the capsule's Y, +X at rest) and the horizontal +X.
    const Eigen::Vector3f axis = world.body_pose(1).rotation * Eigen::Vector3f(0, 1, 0);
    return std::acos(std::clamp(axis.dot(Eigen::Vector3f::UnitX()), -1.0f, 1.0f));
  };
  EXPECT_NEAR(droop_after(0.0f), 90 * kDegree, 5 * kDegree);
  EXPECT_LT(droop_after(500.0f), 45 * kDegree);
}

TEST(Physics, AngularLimitHoldsUnderGravity) {
  // The arm may swing +-20 degrees about Z only; gravity pulls it down (about -Z) by far more.
  const float limit = 20 * kDegree;
  const PhysicsRig rig =
      arm_rig(Eigen::Vector3f(0, 0, -limit), Eigen::Vector3f(0, 0, limit), Eigen::Vector3f::Zero(), 0);
  PhysicsWorld world(rig);
  float largest = 0;
  for (int frame = 0; frame < 90; ++frame) {
    world.step(1.0f / 30.0f);
    largest = std::max(largest, relative_angle(world, 0, 1));
  }
  EXPECT_LT(largest, limit + 2 * kDegree);
  EXPECT_GT(largest, limit - 2 * kDegree);
  // It rests on the limit, below the horizontal, rotating about Z only.
  EXPECT_NEAR(relative_angle(world, 0, 1), limit, 2 * kDegree);
  EXPECT_LT(world.body_pose(1).position.y(), 0.0f);
  EXPECT_NEAR(world.body_pose(1).position.z(), 0.0f, 1e-3f);
}

// === Bone write-back

TEST(Physics, BonesFollowTheirBodiesAndParents) {
  // Bone 0 root (kinematic), bone 1 simulated (mode 1), bone 2 its unsimulated tip, bone 3 mode 2 under bone 0.
  PhysicsRig rig;
  rig.bones = {bone("root", -1, {0, 0, 0}), bone("swing", 0, {0, 0, 0}), bone("tip", 1, {0.5f, 0, 0}),
               bone("rot_only", 0, {0, 0, 0.5f})};
  rig.bodies = {
      body("root", 0, PhysicsShape::kBox, {0.1f, 0.1f, 0.1f}, at({0, 0, 0}), PhysicsMode::kFollowBone, 0, 0xFFFF),
      body("swing", 1, PhysicsShape::kSphere, {0.05f, 0, 0}, at({0.5f, 0, 0}), PhysicsMode::kDynamic, 1, 0xFFFF),
      body("rot_only", 3, PhysicsShape::kSphere, {0.05f, 0, 0}, at({0, -0.3f, 0}), PhysicsMode::kDynamicRotation, 2,
           0xFFFF)};
  rig.bodies[2].rest_is_bone_local = true;  // offset (0, -0.3, 0) from bone 3's rest position
  rig.joints = {joint("j1", 0, 1, {0, 0, 0}, kFreeMin, kFreeMax), joint("j3", 0, 2, {0, 0, 0.5f}, kFreeMin, kFreeMax)};
  PhysicsWorld world(rig);
  EXPECT_TRUE(body_rest_pose(rig, 2).position.isApprox(Eigen::Vector3f(0, -0.3f, 0.5f)));

  // The root slides along +Z and turns about Y while the bodies swing.
  Transforms pose = physics_rest_pose(rig);
  for (int frame = 1; frame <= 20; ++frame) {
    const Eigen::Matrix3f R = about({0, 1, 0}, 0.02f * frame).toRotationMatrix();
    const Eigen::Vector3f t(0, 0, 0.01f * frame);
    pose[0] = make_transform(R, t);
    pose[1] = make_transform(R, t);
    pose[2] = make_transform(R, t + R * Eigen::Vector3f(0.5f, 0, 0));
    pose[3] = make_transform(R, t + R * Eigen::Vector3f(0, 0, 0.5f));
    world.set_bone_pose(pose);
    world.step(1.0f / 30.0f);
  }
  const Transforms& out = world.bone_transforms();
  // The kinematic root keeps its animated transform exactly.
  EXPECT_EQ(out[0], pose[0]);
  // Mode 1: the bone carries its body rigidly.
  const RigidPose swing = world.body_pose(1);
  const Eigen::Matrix3f R1 = out[1].leftCols<3>();
  EXPECT_TRUE(apply(out[1], Eigen::Vector3f(0.5f, 0, 0)).isApprox(swing.position, 1e-5f));
  EXPECT_TRUE(R1.isApprox(swing.rotation.toRotationMatrix(), 1e-5f));
  EXPECT_GT(swing.position.y(), -0.5f);
  EXPECT_LT(swing.position.y(), -0.05f);  // it fell
  // The tip follows bone 1 rigidly.
  EXPECT_TRUE(out[2].leftCols<3>().isApprox(R1, 1e-5f));
  EXPECT_TRUE(Eigen::Vector3f(out[2].col(3)).isApprox(apply(out[1], Eigen::Vector3f(0.5f, 0, 0)), 1e-5f));
  // Mode 2: rotation from the body, position from the (unsimulated) parent chain, i.e. the animated one.
  const RigidPose rot_only = world.body_pose(2);
  EXPECT_TRUE(out[3].leftCols<3>().isApprox(rot_only.rotation.toRotationMatrix(), 1e-5f));
  EXPECT_EQ(Eigen::Vector3f(out[3].col(3)), Eigen::Vector3f(pose[3].col(3)));
}

// === Determinism

std::vector<Transforms> run_chain(PhysicsWorld& world, const PhysicsRig& rig) {
  std::vector<Transforms> frames;
  for (int frame = 1; frame <= 60; ++frame) {
    world.set_bone_pose(chain_pose(rig, kPusherStart.x() - 0.02f * frame));
    world.step(1.0f / 30.0f);
    frames.push_back(world.bone_transforms());
  }
  return frames;
}

bool bit_identical(const std::vector<Transforms>& a, const std::vector<Transforms>& b) {
  if (a.size() != b.size()) return false;
  for (size_t t = 0; t < a.size(); ++t) {
    if (a[t].size() != b[t].size()) return false;
    if (std::memcmp(a[t].data(), b[t].data(), a[t].size() * sizeof(Transform34)) != 0) return false;
  }
  return true;
}

TEST(Physics, RunsAreBitIdenticalAndResetStartsAfresh) {
  const PhysicsRig rig = chain_rig();
  Transforms swung = chain_pose(rig, kPusherStart.x());
  const Eigen::Quaternionf turn = about({0.3f, 0.2f, 1}, 30 * kDegree);
  for (int k = 1; k <= kLinks; ++k) {
    swung[k] = make_transform(turn.toRotationMatrix(), kAnchor + turn * (rig.bones[k].rest_position - kAnchor));
  }
  PhysicsWorld first(rig);
  first.reset(swung);
  const std::vector<Transforms> a = run_chain(first, rig);
  PhysicsWorld second(rig);
  second.reset(swung);
  const std::vector<Transforms> b = run_chain(second, rig);
  EXPECT_TRUE(bit_identical(a, b));
  // The simulation moved: the pose differs from the animated one.
  EXPECT_GT((a.back()[kLinks] - chain_pose(rig, kPusherStart.x() - 1.2f)[kLinks]).norm(), 0.01f);
  // After a reset, the same world repeats the run bit for bit.
  first.reset(swung);
  EXPECT_EQ(first.time(), 0.0);
  EXPECT_TRUE(bit_identical(run_chain(first, rig), a));
  EXPECT_NEAR(first.time(), 2.0, 1e-5);
}

// === Errors

TEST(Physics, InvalidRigsAndPosesAreRejectedWithTheField) {
  auto message = [](const PhysicsRig& rig) {
    try {
      PhysicsWorld world(rig);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  PhysicsRig rig = chain_rig();
  rig.bones[2].parent = 3;
  rig.bones[3].parent = 2;
  EXPECT_NE(message(rig).find("cycle"), std::string::npos) << message(rig);
  rig = chain_rig();
  rig.bodies[1].mass = 0;
  EXPECT_NE(message(rig).find("bodies[1] 'link0': mass"), std::string::npos) << message(rig);
  rig = chain_rig();
  rig.bodies[2].size.y() = -1;
  EXPECT_NE(message(rig).find("size[1]"), std::string::npos) << message(rig);
  rig = chain_rig();
  rig.bodies[2].group = 16;
  EXPECT_NE(message(rig).find("group"), std::string::npos) << message(rig);
  rig = chain_rig();
  rig.joints[1].body_b = rig.joints[1].body_a;
  EXPECT_NE(message(rig).find("joints[1] 'joint1': body_b"), std::string::npos) << message(rig);
  rig = chain_rig();
  rig.joints[0].angular_stiffness.x() = -1;
  EXPECT_NE(message(rig).find("angular_stiffness"), std::string::npos) << message(rig);

  PhysicsWorld world(chain_rig());
  EXPECT_THROW(world.set_bone_pose(Transforms(2)), Error);
  EXPECT_THROW(world.step(0.0f), Error);
  EXPECT_THROW(world.body_pose(99), Error);
}

}  // namespace
}  // namespace amt
