// The physics response probe (data_tools/geometry/rig_probe.h) on hand-made simulators, and on VRM spring bones.
#include "data_tools/geometry/rig_probe.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/spring_bones.h"

namespace amt {
namespace {

TEST(RigProbe, BoneTailsAreTheChildrensMeanHeadOrHalfABoneOnward) {
  MatrixX3f heads(4, 3);
  heads << 0, 0, 0,  // root: children 1 and 2
      1, 0, 0,       // 1: child 3
      0, 2, 0,       // 2: a leaf
      1, 1, 0;       // 3: a leaf
  const MatrixX3f tails = bone_tails(heads, {-1, 0, 0, 1});
  EXPECT_TRUE(tails.row(0).isApprox(Eigen::RowVector3f(0.5f, 1.0f, 0.0f)));
  EXPECT_TRUE(tails.row(1).isApprox(Eigen::RowVector3f(1.0f, 1.0f, 0.0f)));
  EXPECT_TRUE(tails.row(2).isApprox(Eigen::RowVector3f(0.0f, 3.0f, 0.0f)));
  EXPECT_TRUE(tails.row(3).isApprox(Eigen::RowVector3f(1.0f, 1.5f, 0.0f)));
  MatrixX3f lone(1, 3);
  lone << 1, 2, 3;
  EXPECT_TRUE(bone_tails(lone, {-1}).isApprox(lone));  // a root without children: its head
  EXPECT_THROW(bone_tails(heads, {-1, 0, 0}), Error);
  EXPECT_THROW(bone_tails(heads, {-1, 0, 0, 3}), Error);  // its own parent
}

// A simulator whose bone 1 never moves (it stays at rest while the rig sways): its distance from rigid skinning is
// the sway itself, so the response is the RMS of the sway's samples over the amplitude, and 0 over the hold. Bone 2
// hangs below it (moved, measured the same way), bone 0 follows rigidly (not simulated: zeros).
TEST(RigProbe, ABoneThatStaysBehindRespondsWithTheSwaysRms) {
  MatrixX3f heads(3, 3);
  heads << 0, 0, 0, 0, -1, 0, 0, -2, 0;
  const std::vector<int32_t> parents{-1, 0, 1};
  int calls = 0;
  const auto stay = [&](const Transforms& pose, float seconds) {
    EXPECT_FLOAT_EQ(seconds, 1.0f / 30.0f);
    ++calls;
    Transforms out = pose;
    out[1] = out[2] = Transform34::Identity();
    return out;
  };
  RigProbeOptions probe;
  probe.settle_seconds = 0.5f;
  const float amplitude = 0.25f;
  const MatrixXfR r = probe_response(heads, parents, {0, 1, 0}, amplitude, probe, stay);
  // By hand: 38 sway frames (1.5 periods at 1.2 Hz, 30 fps; the last one at rest), then 30 hold frames.
  const int sway = 38;
  double sum = 0;
  for (int f = 1; f < sway; ++f) {
    const double s = amplitude * std::sin(2 * M_PI * 1.2 * f / 30.0);
    sum += s * s;
  }
  const float expected = static_cast<float>(std::sqrt(sum / sway) / amplitude);
  EXPECT_EQ(calls, 15 + sway + 30);
  EXPECT_EQ(r.row(0), Eigen::RowVector3f::Zero());
  for (int b : {1, 2}) {
    EXPECT_EQ(r(b, 0), 1.0f);
    EXPECT_NEAR(r(b, 1), expected, 1e-5f) << b;
    EXPECT_NEAR(r(b, 2), 0.0f, 1e-6f) << b;
  }
  // A rig that nothing simulates is not probed.
  calls = 0;
  EXPECT_TRUE(probe_response(heads, parents, {0, 0, 0}, amplitude, probe, stay).isZero());
  EXPECT_EQ(calls, 0);
  // Bad input.
  EXPECT_THROW(probe_response(heads, parents, {0, 1}, amplitude, probe, stay), Error);
  EXPECT_THROW(probe_response(heads, parents, {0, 1, 0}, 0.0f, probe, stay), Error);
  probe.hold_seconds = std::nanf("");
  EXPECT_THROW(probe_response(heads, parents, {0, 1, 0}, amplitude, probe, stay), Error);
}

// A root and a chain of three spring joints hanging down, 0.1 m apart, springs with the given parameters.
struct SpringChain {
  Skeleton skeleton;
  SpringRig rig;
};

SpringChain spring_chain(float stiffness, float drag) {
  SpringChain c;
  c.skeleton.rest_joints = MatrixX3f::Zero(4, 3);
  c.rig.spring_colliders.push_back({});
  for (int j = 0; j < 4; ++j) {
    c.skeleton.names.push_back("j" + std::to_string(j));
    c.skeleton.parents.push_back(j - 1);
    c.skeleton.rest_joints(j, 1) = -0.1f * float(j);
    if (j == 0) continue;
    SpringJoint s;
    s.joint = j;
    s.tail = Eigen::Vector3f(0.0f, -0.1f * float(j + 1), 0.0f);
    s.stiffness = stiffness;
    s.drag = drag;
    c.rig.joints.push_back(s);
  }
  return c;
}

TEST(RigProbe, LooseSpringBonesRespondMoreThanStiffOnesAndRigidOnesNot) {
  const SpringChain loose = spring_chain(0.5f, 0.05f), stiff = spring_chain(40.0f, 0.5f),
                    rigid = spring_chain(1e3f, 1.0f);
  const MatrixXfR a = spring_response(loose.skeleton, loose.rig);
  const MatrixXfR b = spring_response(stiff.skeleton, stiff.rig);
  const MatrixXfR c = spring_response(rigid.skeleton, rigid.rig);
  ASSERT_EQ(a.rows(), 4);
  EXPECT_EQ(a.row(0), Eigen::RowVector3f::Zero());  // the root is animated, not simulated
  for (int j = 1; j < 4; ++j) {
    EXPECT_EQ(a(j, 0), 1.0f) << j;
    EXPECT_GT(a(j, 1), b(j, 1)) << j;
    EXPECT_GT(a(j, 2), b(j, 2)) << j;
    EXPECT_LT(c(j, 1), 0.05f) << j;
    EXPECT_LT(c(j, 2), 0.05f) << j;
  }
  EXPECT_GT(a(3, 1), 0.3f);
  EXPECT_EQ(spring_response(loose.skeleton, loose.rig), a);  // deterministic
  SpringChain broken = loose;
  broken.rig.joints[0].drag = 2.0f;
  EXPECT_THROW(spring_response(broken.skeleton, broken.rig), Error);
}

}  // namespace
}  // namespace amt
