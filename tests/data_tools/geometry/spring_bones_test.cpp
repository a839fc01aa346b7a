// Spring bones (data_tools/geometry/spring_bones.h): one step against the specification's update computed by hand,
// colliders, the rigid carry of joints below a spring, the stated fallbacks for bad rigs, and frame-rate
// invariance: the same motion at 30, 60 and 120 fps moves the springs the same way.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include <Eigen/Geometry>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/spring_bones.h"
#include "tests/test_support.h"

namespace amt {
namespace {

Transform34 identity() {
  return make_transform(Eigen::Matrix3f::Identity(), Eigen::Vector3f::Zero());
}

// A root at the origin and a chain of `links` joints hanging along +X, 0.1 m apart (joint k at x = 0.1 k).
Skeleton chain_skeleton(int links) {
  Skeleton s;
  const int J = links + 1;
  s.rest_joints = MatrixX3f::Zero(J, 3);
  for (int j = 0; j < J; ++j) {
    s.names.push_back("j" + std::to_string(j));
    s.parents.push_back(j - 1);
    s.rest_joints(j, 0) = 0.1f * float(j);
  }
  return s;
}

// Springs on joints 1..links of chain_skeleton, each tail at the next joint (the last 0.1 m further on).
SpringRig chain_rig(int links, float stiffness, float gravity, float drag) {
  SpringRig rig;
  rig.spring_colliders.push_back({});
  for (int j = 1; j <= links; ++j) {
    SpringJoint sj;
    sj.joint = j;
    sj.tail = Eigen::Vector3f(0.1f * float(j + 1), 0.0f, 0.0f);
    sj.stiffness = stiffness;
    sj.gravity_power = gravity;
    sj.drag = drag;
    rig.joints.push_back(sj);
  }
  return rig;
}

TEST(SpringBones, OneStepIsTheSpecificationsUpdateComputedByHand) {
  // One segment from (0.1, 0, 0) to (0.2, 0, 0) under a fixed root: stiffness 2, gravity 3 down, drag 0.25.
  const SpringRig rig = chain_rig(1, 2.0f, 3.0f, 0.25f);
  SpringBoneSimulator sim(chain_skeleton(1), rig);
  const Transforms pose(2, identity());
  sim.reset(pose);
  const float dt = 0.1f;
  // Step 1: at rest, no inertia: next = tail + axis * stiffness * dt + down * gravity * dt, back to length 0.1.
  Eigen::Vector3f tail0(0.2f, 0.0f, 0.0f), head(0.1f, 0.0f, 0.0f);
  Eigen::Vector3f next = tail0 + Eigen::Vector3f(1, 0, 0) * (2.0f * dt) + Eigen::Vector3f(0, -1, 0) * (3.0f * dt);
  Eigen::Vector3f tail1 = head + (next - head).normalized() * 0.1f;
  sim.step(pose, dt);
  EXPECT_LT((sim.tails()[0] - tail1).norm(), 1e-6f);
  // By hand: next = (0.4, -0.3, 0), so the tail is at (0.1, 0, 0) + 0.1 (0.3, -0.3) / |(0.3, -0.3)|.
  EXPECT_NEAR(sim.tails()[0].x(), 0.1f + 0.1f / std::sqrt(2.0f), 1e-6f);
  EXPECT_NEAR(sim.tails()[0].y(), -0.1f / std::sqrt(2.0f), 1e-6f);
  // Step 2: the inertia (tail1 - tail0) less a quarter.
  next = tail1 + (tail1 - tail0) * 0.75f + Eigen::Vector3f(1, 0, 0) * (2.0f * dt) +
         Eigen::Vector3f(0, -1, 0) * (3.0f * dt);
  const Eigen::Vector3f tail2 = head + (next - head).normalized() * 0.1f;
  const Transforms M = [&] {
    sim.step(pose, dt);
    return sim.advance(pose, 1e-6);  // no internal step: the placed pose of the last one
  }();
  EXPECT_LT((sim.tails()[0] - tail2).norm(), 1e-6f);
  // The joint's transform carries its rest tail onto the simulated tail and keeps its head.
  EXPECT_LT((apply(M[1], rig.joints[0].tail) - tail2).norm(), 1e-5f);
  EXPECT_LT((apply(M[1], head) - head).norm(), 1e-6f);
}

TEST(SpringBones, WithoutForcesASpringFollowsItsParentRigidly) {
  // No gravity, full drag, stiff: the chain turns with its root as if skinned to it.
  SpringBoneSimulator sim(chain_skeleton(2), chain_rig(2, 1e3f, 0.0f, 1.0f));
  const Eigen::Matrix3f R = Eigen::AngleAxisf(0.5f, Eigen::Vector3f::UnitY()).toRotationMatrix();
  const Transforms pose(3, make_transform(R, Eigen::Vector3f(0.0f, 0.2f, 0.0f)));
  sim.reset(pose);
  Transforms M;
  for (int k = 0; k < 30; ++k) M = sim.advance(pose, 1.0 / 30.0);
  for (int j = 1; j <= 2; ++j) {
    const Eigen::Vector3f rest_tail(0.1f * float(j + 1), 0.0f, 0.0f);
    EXPECT_LT((sim.tails()[size_t(j - 1)] - apply(pose[0], rest_tail)).norm(), 1e-4f) << j;
    EXPECT_LT((M[size_t(j)] - pose[0]).norm(), 1e-3f) << j;
  }
}

TEST(SpringBones, GravityHangsAChainStraightDown) {
  SpringBoneSimulator sim(chain_skeleton(3), chain_rig(3, 0.0f, 5.0f, 0.4f));
  const Transforms pose(4, identity());
  sim.reset(pose);
  for (int k = 0; k < 120; ++k) sim.advance(pose, 1.0 / 30.0);
  // Each segment keeps its length and points down from the head it hangs from (x of the first head, 0.1).
  for (int s = 0; s < 3; ++s) {
    EXPECT_NEAR(sim.tails()[size_t(s)].x(), 0.1f, 2e-3f) << s;
    EXPECT_NEAR(sim.tails()[size_t(s)].y(), -0.1f * float(s + 1), 2e-3f) << s;
  }
}

TEST(SpringBones, ASphereAndACapsuleColliderPushTheTailOutToTheirRadiusPlusItsOwn) {
  for (const bool capsule : {false, true}) {
    SpringRig rig = chain_rig(1, 0.0f, 5.0f, 0.4f);
    rig.joints[0].hit_radius = 0.01f;
    SpringCollider c;
    c.joint = 0;
    // Below the segment's head, where gravity would hang the tail: (0.1, -0.1, 0).
    c.center = capsule ? Eigen::Vector3f(0.1f, -0.1f, -0.5f) : Eigen::Vector3f(0.1f, -0.1f, 0.0f);
    c.tail = capsule ? Eigen::Vector3f(0.1f, -0.1f, 0.5f) : c.center;
    c.capsule = capsule;
    c.radius = 0.04f;
    rig.colliders.push_back(c);
    rig.spring_colliders[0].push_back(0);
    SpringBoneSimulator sim(chain_skeleton(1), rig);
    const Transforms pose(2, identity());
    sim.reset(pose);
    for (int k = 0; k < 60; ++k) sim.advance(pose, 1.0 / 30.0);
    const Eigen::Vector3f t = sim.tails()[0];
    const Eigen::Vector3f axis_point(0.1f, -0.1f, capsule ? t.z() : 0.0f);
    // Pushed out to 5 cm (radius plus hit radius), then back onto the segment's length as the specification
    // does, which lets it in by a millimetre here: well outside the collider's own radius.
    EXPECT_GT((t - axis_point).norm(), 0.045f) << capsule;
    EXPECT_LT((t - axis_point).norm(), 0.05f + 1e-5f) << capsule;
    EXPECT_NEAR((t - Eigen::Vector3f(0.1f, 0.0f, 0.0f)).norm(), 0.1f, 1e-5f) << capsule;
    // Without the collider it hangs at the collider's centre.
    rig.spring_colliders[0].clear();
    SpringBoneSimulator free(chain_skeleton(1), rig);
    free.reset(pose);
    for (int k = 0; k < 60; ++k) free.advance(pose, 1.0 / 30.0);
    EXPECT_LT((free.tails()[0] - Eigen::Vector3f(0.1f, -0.1f, 0.0f)).norm(), 2e-3f);
  }
}

TEST(SpringBones, AJointBelowASpringIsCarriedByIt) {
  // Joint 2 hangs below the spring on joint 1 but is not simulated itself: it shares joint 1's transform.
  SpringBoneSimulator sim(chain_skeleton(2), chain_rig(1, 0.0f, 5.0f, 0.4f));
  const Transforms pose(3, identity());
  sim.reset(pose);
  Transforms M;
  for (int k = 0; k < 10; ++k) M = sim.advance(pose, 1.0 / 30.0);
  EXPECT_GT((M[1] - pose[1]).norm(), 0.1f);
  EXPECT_EQ(M[2], M[1]);
}

// The tips of a three-segment chain on a root that swings about Y and bobs, sampled at `fps` for 2 s; returns the
// tips at every 1/30 s.
std::vector<Eigen::Vector3f> swinging_tips(double fps) {
  SpringBoneSimulator sim(chain_skeleton(3), chain_rig(3, 1.0f, 2.0f, 0.3f));
  const auto pose_at = [](double t) {
    const Eigen::Matrix3f R =
        Eigen::AngleAxisf(float(1.2 * std::sin(5.0 * t)), Eigen::Vector3f::UnitY()).toRotationMatrix();
    return Transforms(4, make_transform(R, Eigen::Vector3f(0.0f, float(0.05 * std::sin(9.0 * t)), 0.0f)));
  };
  sim.reset(pose_at(0.0));
  std::vector<Eigen::Vector3f> tips;
  const int frames = int(std::lround(2.0 * fps)), every = int(std::lround(fps / 30.0));
  for (int k = 1; k <= frames; ++k) {
    const Transforms M = sim.advance(pose_at(double(k) / fps), 1.0 / fps);
    if (k % every == 0) tips.push_back(apply(M[3], Eigen::Vector3f(0.4f, 0.0f, 0.0f)));
  }
  return tips;
}

TEST(SpringBones, TheSameMotionAt30And60And120FpsMovesTheSpringsTheSameWay) {
  const std::vector<Eigen::Vector3f> a = swinging_tips(30.0), b = swinging_tips(60.0), c = swinging_tips(120.0);
  ASSERT_EQ(a.size(), 60u);
  ASSERT_EQ(b.size(), a.size());
  ASSERT_EQ(c.size(), a.size());
  float ab = 0.0f, bc = 0.0f, motion = 0.0f;
  for (size_t k = 0; k < a.size(); ++k) {
    ab = std::max(ab, (a[k] - b[k]).norm());
    bc = std::max(bc, (b[k] - c[k]).norm());
    if (k > 0) motion = std::max(motion, (c[k] - c[k - 1]).norm());
  }
  // The tip moves up to several centimetres a frame; the runs differ only by how the driving pose is interpolated
  // between frames: a few millimetres at 30 fps, less at 60.
  EXPECT_GT(motion, 0.02f);
  EXPECT_LT(ab, 0.005f);
  EXPECT_LT(bc, 0.002f);
}

TEST(SpringBones, BadRigsAreOneLineErrorsNamingTheSegment) {
  const Skeleton s = chain_skeleton(2);
  const auto error_for = [&](const std::function<void(SpringRig&)>& edit) {
    SpringRig rig = chain_rig(2, 1.0f, 1.0f, 0.4f);
    edit(rig);
    return test::error_of([&] { validate_spring_rig(rig, s, "avatar.vrm"); });
  };
  EXPECT_EQ(error_for([](SpringRig& r) { r.joints[1].joint = 7; }),
            "avatar.vrm: spring bone 1: joint: expected an index in [0, 3), found 7");
  EXPECT_EQ(error_for([](SpringRig& r) { r.joints[1].drag = 2.0f; }),
            "avatar.vrm: spring bone 1 (j2): dragForce: expected a value in [0, 1], found 2");
  EXPECT_EQ(error_for([](SpringRig& r) { r.joints[0].stiffness = NAN; }),
            "avatar.vrm: spring bone 0 (j1): stiffness: expected a value in [0, 1e4), found nan");
  EXPECT_EQ(error_for([](SpringRig& r) { r.joints[1].joint = 1; }),
            "avatar.vrm: spring bone 1 (j1): expected each joint in one segment, found it twice");
  EXPECT_EQ(error_for([](SpringRig& r) { r.joints[0].tail = Eigen::Vector3f(0.1f, 0.0f, 0.0f); }),
            "avatar.vrm: spring bone 0 (j1): expected a tail away from its head, found them at one point");
  EXPECT_EQ(error_for([](SpringRig& r) { r.spring_colliders[0].push_back(3); }),
            "avatar.vrm: spring 0: collider: expected an index in [0, 0), found 3");
  EXPECT_EQ(error_for([](SpringRig&) {}), "");
}

}  // namespace
}  // namespace amt
