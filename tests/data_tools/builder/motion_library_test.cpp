// Tests of data_tools/builder/motion_library.h and data_tools/geometry/procedural_motion.h.
#include "data_tools/builder/motion_library.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/retarget.h"
#include "tests/test_support.h"

namespace amt {
namespace {

using test::error_of;

constexpr float kPi = 3.14159265358979f;

bool all_finite(const Transforms& transforms) {
  for (const Transform34& T : transforms) {
    if (!T.allFinite()) return false;
  }
  return true;
}

// === Procedural motions

TEST(ProceduralMotion, EveryKindIsValidFiniteAndDeterministic) {
  const Skeleton skeleton = canonical_skeleton();
  for (int k = 0; k < kProceduralKindCount; ++k) {
    const auto kind = static_cast<ProceduralKind>(k);
    for (uint64_t seed : {1ULL, 7ULL, 123456789ULL}) {
      const Motion m = random_procedural_motion(kind, seed, 90);
      SCOPED_TRACE(std::string(procedural_kind_name(kind)) + " seed " + std::to_string(seed));
      EXPECT_NO_THROW(validate_motion(m, skeleton, "procedural"));
      EXPECT_EQ(m.num_frames(), 90);
      EXPECT_TRUE(m.root_translation.allFinite());
      const Transforms fk = forward_kinematics(skeleton, m);
      EXPECT_TRUE(all_finite(fk));
      // Feet stay near the floor and the root near the start: no motion flies off.
      for (int t = 0; t < m.num_frames(); ++t) {
        EXPECT_LT(std::abs(m.root_translation(t, 1)), 0.6f);
      }
      const Motion again = random_procedural_motion(kind, seed, 90);
      EXPECT_EQ(again.root_translation, m.root_translation);
      for (size_t i = 0; i < m.local_rotations.size(); ++i) {
        ASSERT_EQ(again.local_rotations[i].coeffs(), m.local_rotations[i].coeffs());
      }
    }
    // Different seeds vary the motion.
    const Motion a = random_procedural_motion(kind, 1, 60), b = random_procedural_motion(kind, 2, 60);
    float difference = (a.root_translation - b.root_translation).cwiseAbs().maxCoeff();
    for (size_t i = 0; i < a.local_rotations.size(); ++i) {
      difference = std::max(difference, (a.local_rotations[i].coeffs() - b.local_rotations[i].coeffs()).cwiseAbs().maxCoeff());
    }
    EXPECT_GT(difference, 0.01f) << procedural_kind_name(kind);
  }
}

TEST(ProceduralMotion, JumpReachesItsHeightAtMidFlight) {
  // height 0.2 m: flight 2 sqrt(2 h / g) = 0.40406 s; period 1.4 s; the take-off is at (1.4 - flight) / 2, so
  // mid-flight is at exactly 0.7 s = frame 21 at 30 fps, where the root is h above rest (no crouch in the air).
  const Motion m = jump_motion(60, 30.0f, 0.2f, 1.4f);
  EXPECT_NEAR(m.root_translation(21, 1), 0.2f, 1e-4f);
  EXPECT_FLOAT_EQ(m.root_translation(0, 1), 0.0f);
  EXPECT_NE(error_of([] { jump_motion(10, 30.0f, 0.5f, 0.8f); }).find("period_seconds"), std::string::npos);
}

TEST(ProceduralMotion, TurnFollowsItsArcAndHeading) {
  // 90 deg/s at 1 m/s: after 1 s the heading is 90 degrees (facing +X) and the root is at
  // (r (1 - cos 90), r sin 90) with r = 1 / (pi / 2).
  const Motion m = turn_motion(31, 30.0f, 90.0f, 1.0f);
  const float r = 2.0f / kPi;
  EXPECT_NEAR(m.root_translation(30, 0), r, 1e-4f);
  EXPECT_NEAR(m.root_translation(30, 2), r, 1e-4f);
  const Eigen::Vector3f forward = m.rotation(30, kPelvis) * Eigen::Vector3f::UnitZ();
  EXPECT_NEAR(std::atan2(forward.x(), forward.z()), kPi / 2, 0.1f);  // walk sway adds a few degrees
}

TEST(ProceduralMotion, SpinTurnsAtItsRateAfterTheRamp) {
  // 0.5 turns/s with a 0.5 s ramp: at t = 1.5 s the angle is pi * (1.5 - 0.25) = 1.25 pi = -0.75 pi (mod 2 pi).
  const Motion m = spin_motion(46, 30.0f, 0.5f);
  const Eigen::AngleAxisf aa(m.rotation(45, kPelvis));
  const Eigen::Vector3f forward = m.rotation(45, kPelvis) * Eigen::Vector3f::UnitZ();
  EXPECT_NEAR(std::atan2(forward.x(), forward.z()), -0.75f * kPi, 1e-4f);
  EXPECT_NEAR(std::abs(aa.axis().y()), 1.0f, 1e-5f);
}

// === Clips

TEST(MotionLibrary, ClipWindowsCutFullWindowsAndKeepLongTails) {
  using W = std::vector<std::pair<int, int>>;
  EXPECT_EQ(clip_windows(250, 120, 30), (W{{0, 120}, {120, 120}}));
  EXPECT_EQ(clip_windows(270, 120, 30), (W{{0, 120}, {120, 120}, {240, 30}}));
  EXPECT_EQ(clip_windows(100, 120, 30), (W{{0, 100}}));
  EXPECT_EQ(clip_windows(1, 120, 30), W{});
}

TEST(MotionLibrary, BlendStartsExactlyAtTheRestPoseAndReachesTheMotion) {
  const Motion walk = walk_motion(40, 30.0f);
  const Motion blended = blend_from_rest(walk, 0.5f);  // b = 15 frames
  for (int j = 0; j < blended.num_joints(); ++j) {
    EXPECT_EQ(blended.rotation(0, j).coeffs(), Eigen::Quaternionf::Identity().coeffs());
  }
  EXPECT_EQ(blended.root_translation.row(0), Eigen::RowVector3f::Zero());
  for (int t = 15; t < 40; ++t) {
    for (int j = 0; j < walk.num_joints(); ++j) ASSERT_EQ(blended.rotation(t, j).coeffs(), walk.rotation(t, j).coeffs());
    ASSERT_EQ(blended.root_translation.row(t), walk.root_translation.row(t));
  }
  // Halfway (s = 7.5 / 15 is not a frame; use s = 1/3 at frame 5): w = s^2 (3 - 2 s) = 7 / 27.
  const float w = 7.0f / 27.0f;
  EXPECT_NEAR(blended.root_translation(5, 2), w * walk.root_translation(5, 2), 1e-6f);
  const float full = Eigen::AngleAxisf(walk.rotation(5, kLeftShoulder)).angle();
  EXPECT_NEAR(Eigen::AngleAxisf(blended.rotation(5, kLeftShoulder)).angle(), w * full, 1e-4f);
}

TEST(MotionLibrary, BlendFollowsAJointTurningPastHalfATurn) {
  // The pelvis turns about +Y from 150 to 245 degrees (past 180) over 20 frames, blended over all of them: the
  // blend is the turn scaled by w(t), w * angle(t), not a flip to the shorter arc once the angle passes 180.
  Motion m = rest_motion(canonical_skeleton(), 20, 30.0f);
  for (int t = 0; t < 20; ++t) {
    m.rotation(t, kPelvis) = Eigen::Quaternionf(Eigen::AngleAxisf((150.0f + 5.0f * t) * kPi / 180, Eigen::Vector3f::UnitY()));
    if (t % 2) m.rotation(t, kPelvis).coeffs() *= -1.0f;  // the same rotations on alternating quaternion signs
  }
  const Motion blended = blend_from_rest(m, 10.0f);  // b = 19 frames
  for (int t = 0; t < 19; ++t) {
    const float s = t / 19.0f, w = s * s * (3 - 2 * s);
    const Eigen::Quaternionf expected(Eigen::AngleAxisf(w * (150.0f + 5.0f * t) * kPi / 180, Eigen::Vector3f::UnitY()));
    EXPECT_LT(blended.rotation(t, kPelvis).angularDistance(expected), 1e-4f) << "frame " << t;
  }
}

TEST(MotionLibrary, CutWindowFacesForwardAndStartsAtTheOrigin) {
  // The root faces +X (turned 90 degrees about +Y) and moves along +X from (3, 0.1, -2) at 1 m per frame; its left
  // hip is bent. The window from frame 10 faces +Z and moves along +Z from the origin, height kept.
  Motion m = rest_motion(canonical_skeleton(), 30, 30.0f);
  const Eigen::Quaternionf turn(Eigen::AngleAxisf(kPi / 2, Eigen::Vector3f::UnitY()));
  const Eigen::Quaternionf bend(Eigen::AngleAxisf(0.3f, Eigen::Vector3f::UnitX()));
  for (int t = 0; t < m.num_frames(); ++t) {
    m.rotation(t, kPelvis) = turn;
    m.rotation(t, kLeftHip) = bend;
    m.root_translation.row(t) << 3.0f + t, 0.1f, -2.0f;
  }
  const Motion window = cut_window(m, 10, 15);
  ASSERT_EQ(window.num_frames(), 15);
  for (int t = 0; t < 15; ++t) {
    EXPECT_NEAR(window.root_translation(t, 0), 0.0f, 1e-5f);
    EXPECT_FLOAT_EQ(window.root_translation(t, 1), 0.1f);
    EXPECT_NEAR(window.root_translation(t, 2), static_cast<float>(t), 1e-5f);
    EXPECT_TRUE(window.rotation(t, kPelvis).isApprox(Eigen::Quaternionf::Identity(), 1e-6f));
    EXPECT_EQ(window.rotation(t, kLeftHip).coeffs(), bend.coeffs());
  }
  EXPECT_NE(error_of([&] { cut_window(m, 20, 15); }).find("window"), std::string::npos);
}

TEST(MotionLibrary, ClipOnCharacterStartsAtTheCharactersRestPose) {
  // An A-pose character: retargeting alone would put frame 0 in the source's T-pose; the blend restores its rest.
  Skeleton character = canonical_skeleton();
  character.rest_joints.row(kLeftElbow) += Eigen::RowVector3f(-0.05f, -0.1f, 0.0f);
  MotionClip clip{"proc-walk-000", "procedural", 0, cut_window(walk_motion(20, 30.0f), 0, 20)};
  const Motion m = clip_on_character(clip, character, 0.5f);
  const Transforms first = forward_kinematics(character, m, 0);
  for (int j = 0; j < character.num_joints(); ++j) {
    EXPECT_TRUE(first[j].leftCols<3>().isIdentity(0.0f));
    EXPECT_TRUE(first[j].col(3).transpose().isApprox(character.rest_joints.row(j), 1e-6f));
  }
}

TEST(MotionLibrary, BuildsClipsFromBvhFilesAndProceduralMotions) {
  const auto dir = test::temp_dir("motion_library_bvh");
  std::filesystem::copy_file(AMT_ASSET_DIR "/mocap/cmu/09_03.bvh", dir / "09_03.bvh");
  MotionLibraryOptions options;
  options.bvh_folder = dir.string();
  options.procedural = 7;
  options.clip_frames = 12;
  options.min_tail_frames = 5;
  const std::vector<MotionClip> clips = build_motion_library(options);
  // 129 frames at 120 fps, about 1.07 s -> 32 or 33 frames at 30 fps: windows (0,12), (12,12), tail (24, T - 24).
  const int T = canonical_bvh_motion((dir / "09_03.bvh").string(), 30.0f).num_frames();
  ASSERT_GE(T, 29);
  ASSERT_LE(T, 36);
  ASSERT_EQ(clips.size(), 3u + 7u);
  EXPECT_EQ(clips[0].name, "bvh-09_03-000");
  EXPECT_EQ(clips[2].name, "bvh-09_03-002");
  EXPECT_EQ(clips[2].first_frame, 24);
  EXPECT_EQ(clips[2].motion.num_frames(), T - 24);
  EXPECT_EQ(clips[2].source, "09_03.bvh");
  EXPECT_EQ(clips[3].name, "proc-walk-000");
  EXPECT_EQ(clips[8].name, "proc-dance-005");
  EXPECT_EQ(clips[9].name, "proc-walk-006");
  for (const MotionClip& clip : clips) {
    EXPECT_NO_THROW(validate_motion(clip.motion, canonical_skeleton(), clip.name));
    EXPECT_EQ(clip.motion.root_translation(0, 0), 0.0f);
    EXPECT_EQ(clip.motion.root_translation(0, 2), 0.0f);
  }
}

TEST(MotionLibrary, BadFoldersAndFilesGiveOneLineErrors) {
  const auto empty = test::temp_dir("motion_library_empty");
  MotionLibraryOptions options;
  options.bvh_folder = empty.string();
  EXPECT_NE(error_of([&] { build_motion_library(options); }).find("has no .bvh file"), std::string::npos);
  options.bvh_folder = (empty / "missing").string();
  EXPECT_NE(error_of([&] { build_motion_library(options); }).find("no such folder"), std::string::npos);
  const auto bad = test::temp_dir("motion_library_bad");
  std::ofstream(bad / "broken.bvh") << "HIERARCHY\nROOT hips {\n";
  options.bvh_folder = bad.string();
  const std::string message = error_of([&] { build_motion_library(options); });
  EXPECT_NE(message.find("broken.bvh"), std::string::npos) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos);
  options.bvh_folder.clear();
  options.procedural = 0;
  EXPECT_NE(error_of([&] { build_motion_library(options); }).find("no clip"), std::string::npos);
  options.procedural = 1;
  options.clip_frames = 1;
  EXPECT_NE(error_of([&] { build_motion_library(options); }).find("--frames"), std::string::npos);
}

}  // namespace
}  // namespace amt
