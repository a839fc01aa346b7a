// `amt animate --apparel physics` underneath: the lead-in from the rest pose, the player frame for frame equal to
// the dataset builder's ground truth for the same model and motion, and the GLB the command writes passing the
// Khronos glTF validator.
#include "infer/pmx_physics_player.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "data_tools/formats/pmx_export.h"
#include "data_tools/geometry/motion.h"
#include "tests/data_tools/builder/pmx_humanoid.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

// The humanoid's clip: rest at frame 0, then the head nodding and the left elbow bending while it walks forwards.
Transforms nodding_clip(const Skeleton& skeleton, int frames) {
  Motion m = rest_motion(skeleton, frames);
  for (int t = 0; t < frames; ++t) {
    const float a = 0.5f * std::sin(0.3f * t);
    m.rotation(t, kHead) = Eigen::Quaternionf(Eigen::AngleAxisf(a, Eigen::Vector3f::UnitX()));
    m.rotation(t, kLeftElbow) = Eigen::Quaternionf(Eigen::AngleAxisf(a, Eigen::Vector3f::UnitY()));
    m.root_translation(t, 2) = 0.03f * t;
  }
  return forward_kinematics(skeleton, m);
}

TEST(PmxPhysicsPlayer, LeadInBlendsFromTheRestPoseTowardsTheFirstFrame) {
  const Skeleton skeleton = canonical_skeleton();
  const Transforms clip = nodding_clip(skeleton, 6);
  const Transforms first(clip.begin() + 5 * kCanonicalJointCount, clip.end());  // a turned head, moved forwards
  float previous = 0;
  for (int k = 0; k < 4; ++k) {
    const Transforms pose = lead_in_pose(skeleton, first, k, 4);
    const float head = Eigen::AngleAxisf(Eigen::Matrix3f(pose[kHead].leftCols<3>())).angle();
    EXPECT_GT(head, previous);  // monotonic from the rest pose
    previous = head;
    const float s = (k + 1) / 5.0f, w = s * s * (3.0f - 2.0f * s);  // eased in and out
    EXPECT_NEAR(pose[kPelvis](2, 3), skeleton.rest_joints(kPelvis, 2) + w * 0.15f, 1e-5f);
  }
  EXPECT_LT(previous, Eigen::AngleAxisf(Eigen::Matrix3f(first[kHead].leftCols<3>())).angle());  // never past it
  EXPECT_NE(test::error_of([&] { lead_in_pose(skeleton, first, 4, 4); }).find("lead-in"), std::string::npos);
}

TEST(PmxPhysicsPlayer, FramesAreTheDatasetGroundTruth) {
  const fs::path dir = test::temp_dir("pmx_physics_player");
  const std::string path = (dir / "humanoid.pmx").string();
  write_pmx(test::pmx_humanoid(), path);
  PmxSimulationOptions o;
  o.settle_seconds = 0.2f;
  PmxPhysicsPlayer player(path, std::nullopt, o);
  const PmxCharacter& c = player.character();
  const int T = 12, J = kCanonicalJointCount;
  const Transforms joints = nodding_clip(c.skeleton(), T);

  const PmxCharacter reference = load_pmx_character(path);
  const PmxDatasetCharacter d = pmx_dataset_character(reference, "pmx-0000", "train");
  std::unique_ptr<PmxRigSimulator> simulator;
  const Transforms rig = simulate_pmx_clip(reference, joints, T, o, simulator);
  SparseWeights weights;
  weights.indices = d.data.rig->skin_indices;
  weights.weights = d.data.rig->skin_weights;

  player.start(Transforms(joints.begin(), joints.begin() + J), 0);
  MatrixX3f V, truth;
  for (int t = 1; t < T; ++t) {
    player.step(Transforms(joints.begin() + t * J, joints.begin() + (t + 1) * J), V);
    linear_blend_skinning(d.data.mesh.V, weights,
                          Transforms(rig.begin() + t * c.num_bones(), rig.begin() + (t + 1) * c.num_bones()), truth);
    for (int k = 0; k < truth.rows(); ++k) {
      EXPECT_LT((V.row(d.vertex_order[size_t(k)]) - truth.row(k)).norm(), 1e-6f) << "frame " << t << " vertex " << k;
    }
  }
}

TEST(PmxPhysicsPlayer, AnimateWritesAGlbThatPassesTheValidator) {
  const fs::path dir = test::temp_dir("pmx_physics_glb");
  write_pmx(test::pmx_humanoid(), (dir / "humanoid.pmx").string());
  const std::string motion = std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh";
  const test::CommandResult run = test::run_command(
      "cd '" + dir.string() + "' && " +
      test::shell_command(AMT_BINARY, {"animate", "--character", "humanoid.pmx", "--motion", motion, "--apparel",
                                       "physics", "--frames", "8", "--out", "dance.glb", "--threads", "1", "--quiet"}));
  ASSERT_EQ(run.status, 0) << run.err;
  test::expect_valid_gltf(dir / "dance.glb");
}

}  // namespace
}  // namespace amt
