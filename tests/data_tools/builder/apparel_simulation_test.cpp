#include "data_tools/builder/apparel_simulation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/retarget.h"
#include "tests/test_support.h"

namespace amt {
namespace {

const GeneratedBody& test_body() {
  static const GeneratedBody body = generate_body(sample_body_params(uint64_t{1009}), 1500);
  return body;
}

const DressedCharacter& skirt_character() {
  static const DressedCharacter c = dress_character_with(test_body(), {ApparelKind::kFlaredSkirt}, 4);
  return c;
}

// The canonical walk retargeted onto the test body.
Motion test_walk(int frames) {
  return retarget_motion(walk_motion(frames), canonical_skeleton(), test_body().skeleton);
}

TEST(ApparelSimulation, RigidPoseCarriesApparelBonesWithTheirParents) {
  const DressedCharacter& c = skirt_character();
  const ApparelSimulator sim(c);
  // Turn the whole body by 90 degrees about Y and move it: every bone, apparel included, turns and moves along.
  const Skeleton& s = c.body.skeleton;
  Motion m = rest_motion(s, 1);
  m.rotation(0, kPelvis) = Eigen::Quaternionf(Eigen::AngleAxisf(0.5f * 3.14159265f, Eigen::Vector3f::UnitY()));
  m.root_translation.row(0) << 0.5f, 0.0f, 1.0f;
  const Transforms body_pose = forward_kinematics(s, m, 0);
  const Transforms pose = sim.rigid_pose(body_pose);
  ASSERT_EQ(pose.size(), static_cast<size_t>(c.rig.num_bones()));
  const Eigen::Matrix3f R = body_pose[kPelvis].leftCols<3>();
  const Eigen::Vector3f pelvis = s.rest_joints.row(kPelvis).transpose();
  for (int b = kCanonicalJointCount; b < c.rig.num_bones(); ++b) {
    const Eigen::Vector3f expected = R * (c.rig.bones[b].rest_position - pelvis) + body_pose[kPelvis].col(3);
    EXPECT_TRUE(pose[b].col(3).isApprox(expected, 1e-5f)) << b;
    EXPECT_TRUE(pose[b].leftCols<3>().isApprox(R, 1e-5f)) << b;
  }
}

TEST(ApparelSimulation, WalkStaysBoundedFiniteAndBodyBonesFollowTheMotion) {
  const DressedCharacter& c = skirt_character();
  ApparelSimulator sim(c);
  const Motion walk = test_walk(45);
  sim.start(forward_kinematics(c.body.skeleton, walk, 0), 0.5f);
  MatrixX3f V;
  for (int t = 0; t < walk.num_frames(); ++t) {
    const Transforms jt = forward_kinematics(c.body.skeleton, walk, t);
    const Transforms& M = sim.step(jt, 1.0f / walk.fps);
    ASSERT_EQ(M.size(), static_cast<size_t>(c.rig.num_bones()));
    // Body bones are kinematic: their skinning matrices are the motion's.
    const Transforms body_M = skinning_matrices(c.body.skeleton, jt);
    for (int j = 0; j < kCanonicalJointCount; ++j) ASSERT_TRUE(M[j].isApprox(body_M[j], 1e-5f)) << t << " " << j;
    linear_blend_skinning(c.mesh.V, c.rig_weights, M, V);
    for (const ApparelPiece& p : c.pieces) {
      const Eigen::Vector3f joint = jt[p.attachment_joint].col(3);
      for (int v = p.first_vertex; v < p.end_vertex; ++v) {
        ASSERT_TRUE(V.row(v).allFinite()) << "frame " << t << " vertex " << v;
        ASSERT_LT((V.row(v).transpose() - joint).norm(), 1.5f * p.chain_length) << "frame " << t << " vertex " << v;
      }
    }
  }
}

TEST(ApparelSimulation, SameInputsGiveBitIdenticalTransforms) {
  const DressedCharacter c = dress_character_with(test_body(), {ApparelKind::kHairSheet, ApparelKind::kRibbons}, 8);
  const Motion walk = test_walk(20);
  auto run = [&]() {
    ApparelSimulator sim(c);
    sim.start(forward_kinematics(c.body.skeleton, walk, 0), 0.25f);
    Transforms all;
    for (int t = 0; t < walk.num_frames(); ++t) {
      const Transforms& M = sim.step(forward_kinematics(c.body.skeleton, walk, t), 1.0f / 30);
      all.insert(all.end(), M.begin(), M.end());
    }
    return all;
  };
  const Transforms a = run(), b = run();
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) ASSERT_TRUE(a[i] == b[i]) << i;
  // start() rebuilds the world: a second clip on the same simulator matches a fresh simulator.
  ApparelSimulator reused(c);
  reused.start(forward_kinematics(c.body.skeleton, walk, 5), 0.25f);
  for (int t = 0; t < 5; ++t) reused.step(forward_kinematics(c.body.skeleton, walk, t), 1.0f / 30);
  reused.start(forward_kinematics(c.body.skeleton, walk, 0), 0.25f);
  for (int t = 0; t < walk.num_frames(); ++t) {
    const Transforms& M = reused.step(forward_kinematics(c.body.skeleton, walk, t), 1.0f / 30);
    for (size_t b2 = 0; b2 < M.size(); ++b2) ASSERT_TRUE(M[b2] == a[t * M.size() + b2]) << t << " " << b2;
  }
}

TEST(ApparelSimulation, SkirtLagsBehindWhenTheBodyAccelerates) {
  const DressedCharacter& c = skirt_character();
  ApparelSimulator sim(c);
  const Skeleton& s = c.body.skeleton;
  // Standing still, then accelerating forward (+Z) at 6 m/s^2 for a third of a second.
  const int frames = 10;
  Motion m = rest_motion(s, frames);
  for (int t = 0; t < frames; ++t) {
    const float time = t / 30.0f;
    m.root_translation.row(t) << 0.0f, 0.0f, 0.5f * 6.0f * time * time;
  }
  sim.start(forward_kinematics(s, m, 0), 1.0f);
  MatrixX3f simulated, rigid;
  for (int t = 0; t < frames; ++t) sim.step(forward_kinematics(s, m, t), 1.0f / 30);
  linear_blend_skinning(c.mesh.V, c.rig_weights, sim.skinning(), simulated);
  linear_blend_skinning(c.mesh.V, c.rig_weights, rig_skinning_matrices(c.rig, sim.rigid_pose(forward_kinematics(s, m, frames - 1))),
                        rigid);
  // The hem (apparel vertices in the lowest quarter of the skirt) trails the rigidly carried skirt.
  float lo = 1e9f, hi = -1e9f;
  for (int v = 0; v < c.mesh.num_vertices(); ++v)
    if (c.apparel_mask[v]) {
      lo = std::min(lo, c.mesh.V(v, 1));
      hi = std::max(hi, c.mesh.V(v, 1));
    }
  double lag = 0;
  int count = 0;
  for (int v = 0; v < c.mesh.num_vertices(); ++v) {
    if (!c.apparel_mask[v] || c.mesh.V(v, 1) > lo + 0.25f * (hi - lo)) continue;
    lag += simulated(v, 2) - rigid(v, 2);
    ++count;
  }
  ASSERT_GT(count, 0);
  lag /= count;
  EXPECT_LT(lag, -0.01);  // more than a centimetre behind
  EXPECT_GT(lag, -0.25);  // but not torn off
}

TEST(ApparelSimulation, BadPosesGiveErrors) {
  ApparelSimulator sim(skirt_character());
  Transforms pose = forward_kinematics(test_body().skeleton, rest_motion(test_body().skeleton, 1), 0);
  Transforms short_pose(pose.begin(), pose.begin() + 5);
  EXPECT_NE(test::error_of([&] { sim.start(short_pose); }).find("expected 22 joint transforms"), std::string::npos);
  EXPECT_NE(test::error_of([&] { sim.start(pose, -1.0f); }).find("settle_seconds"), std::string::npos);
  pose[3](0, 0) = std::nanf("");
  EXPECT_NE(test::error_of([&] { sim.step(pose, 1.0f / 30); }).find("finite"), std::string::npos);
}

}  // namespace
}  // namespace amt
