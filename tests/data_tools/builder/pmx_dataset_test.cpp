// PMX characters: the constraint fixtures simulate through PmxRigSimulator exactly as through the plain physics
// world; broken physics gives the expected warnings or one-line errors; the bone pass of the MMD-style test humanoid
// (D bone, twist bone, bones above the root, hair chain) and its body exactness; the dataset character; a build.
#include "data_tools/builder/pmx_dataset.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "data_tools/builder/dataset_builder.h"
#include "data_tools/builder/pmx_physics.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/pmx_export.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/motion.h"
#include "tests/data_tools/builder/pmx_humanoid.h"
#include "tests/test_support.h"

namespace amt {
namespace {

std::string fixture(const std::string& name) {
  return std::string(AMT_ASSET_DIR) + "/pmx/" + name;
}

bool contains(const std::vector<std::string>& lines, const std::string& a, const std::string& b) {
  for (const std::string& line : lines) {
    if (line.find(a) != std::string::npos && line.find(b) != std::string::npos) return true;
  }
  return false;
}

// A short build of PMX models alone: `clips` procedural clips of `frames` frames, settled briefly.
DatasetBuildOptions pmx_build_options(int clips, int frames) {
  DatasetBuildOptions o;
  o.characters = 0;
  o.procedural = clips;
  o.frames = frames;
  o.settle_seconds = 0.1f;
  o.blend_seconds = 0.2f;
  return o;
}

// A turn of bone 0 about the model's Z axis by `angle` radians (its rest position kept), every other bone carried.
Transforms turned_fixture_pose(const PhysicsRig& rig, float angle) {
  Transforms pose = physics_rest_pose(rig);
  const Eigen::Matrix3f R = Eigen::AngleAxisf(angle, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  const Eigen::Vector3f p0 = rig.bones[0].rest_position;
  for (size_t b = 0; b < pose.size(); ++b) pose[b] = make_transform(R, R * (rig.bones[b].rest_position - p0) + p0);
  return pose;
}

TEST(PmxDataset, ConstraintFixturesSimulateThroughTheNewPathAsThroughThePhysicsWorld) {
  for (const char* name :
       {"constraint_test.pmx", "constraint_test2.pmx", "constraint_test3.pmx", "constraint_test4.pmx"}) {
    SCOPED_TRACE(name);
    const PmxCharacter c = pmx_physics_character(read_pmx(fixture(name)));
    EXPECT_TRUE(c.warnings.empty()) << c.warnings.front();
    EXPECT_EQ(c.simulated_bodies, 1);
    PmxSimulationOptions o;
    o.settle_seconds = 0.5f;
    PmxRigSimulator simulator(c, o);
    // The reference: the plain world with the same settings (MMD's gravity, the builder's substep).
    PhysicsSettings settings = pmx_physics_settings();
    settings.fixed_step = o.physics_step;
    settings.solver_iterations = o.solver_iterations;
    settings.max_substeps = 16;
    PhysicsWorld reference(pmx_physics_rig(read_pmx(fixture(name))), settings);
    const Transforms rest = physics_rest_pose(c.physics);
    simulator.start_bones(rest);
    reference.reset(rest);
    reference.settle(rest, o.settle_seconds);
    for (int t = 1; t <= 20; ++t) {
      const Transforms pose = turned_fixture_pose(c.physics, 0.05f * t);
      const Transforms& amt_bones = simulator.step_bones(pose);
      reference.set_bone_pose(pose);
      reference.step(1.0f / o.fps);
      const Transforms expected = pmx_transforms_to_amt(reference.bone_transforms(), c.scale);
      ASSERT_EQ(amt_bones.size(), expected.size());
      for (size_t b = 0; b < expected.size(); ++b) EXPECT_EQ(amt_bones[b], expected[b]) << "frame " << t;
    }
    // The simulated bone moved off its rigid place under MMD's gravity, and stayed finite.
    const Transforms rigid = pmx_transforms_to_amt(turned_fixture_pose(c.physics, 1.0f), c.scale);
    EXPECT_TRUE(simulator.bone_transforms()[1].allFinite());
    EXPECT_GT((simulator.bone_transforms()[1] - rigid[1]).norm(), 1e-3f);
    EXPECT_EQ(simulator.bone_transforms()[0], rigid[0]);  // the kinematic bone is exactly its pose
  }
}

TEST(PmxDataset, BrokenPhysicsIsRepairedWithAWarningNamingTheBody) {
  PmxModel m = test::pmx_humanoid("broken.pmx");
  m.rigid_bodies[3].mass = 0;                             // a simulated hair body without mass
  m.rigid_bodies[4].size = Eigen::Vector3f(0, 0.9f, -1);  // zero and negative box extents
  PmxRigidBody orphan = m.rigid_bodies[1];                // a kinematic body without a bone
  orphan.name = "orphan";
  orphan.bone = -1;
  m.rigid_bodies.push_back(orphan);  // body 5
  PmxJoint statics = m.joints[0];    // a joint between two kinematic bodies
  statics.name = "statics";
  statics.rigid_body_a = 0;
  statics.rigid_body_b = 1;
  m.joints.push_back(statics);
  PmxJoint self = m.joints[1];
  self.name = "self";
  self.rigid_body_b = self.rigid_body_a;
  m.joints.push_back(self);
  m.rigid_bodies[2].linear_damping = 1.5f;

  std::vector<std::string> warnings;
  const PmxModel repaired = repair_pmx_physics(m, warnings);
  EXPECT_TRUE(contains(warnings, "rigid_bodies[3] '髪2'", "mass: expected a positive mass")) << warnings.size();
  EXPECT_EQ(repaired.rigid_bodies[3].mode, PmxPhysicsMode::kFollowBone);
  EXPECT_TRUE(contains(warnings, "rigid_bodies[4] '髪3'", "size[0]"));
  EXPECT_TRUE(contains(warnings, "rigid_bodies[4] '髪3'", "size[2]"));
  EXPECT_EQ(repaired.rigid_bodies[4].size, Eigen::Vector3f(kPmxMinimumBodySize, 0.9f, kPmxMinimumBodySize));
  EXPECT_TRUE(contains(warnings, "rigid_bodies[5] 'orphan'", "follows bone 0"));
  EXPECT_EQ(repaired.rigid_bodies[5].bone, 0);
  EXPECT_TRUE(contains(warnings, "joints[3] 'statics'", "joint dropped"));
  EXPECT_TRUE(contains(warnings, "joints[4] 'self'", "joint dropped"));
  EXPECT_TRUE(contains(warnings, "rigid_bodies[2] '髪1'", "linear_damping"));
  // Joint 2 joined hair 2 and 3; hair 2 now follows its bone but hair 3 is simulated: it stays.
  EXPECT_EQ(repaired.joints.size(), 3u);
  for (const std::string& w : warnings) EXPECT_EQ(w.rfind("broken.pmx: ", 0), 0u) << w;

  // The repaired model simulates without trouble.
  const PmxCharacter c = pmx_character(m);
  EXPECT_EQ(c.warnings, warnings);
  PmxRigSimulator simulator(c);
  const Transforms rest = forward_kinematics(c.skeleton(), rest_motion(c.skeleton(), 1), 0);
  simulator.start(rest);
  for (int t = 0; t < 10; ++t) simulator.step(rest);
  for (const Transform34& T : simulator.bone_transforms()) EXPECT_TRUE(T.allFinite());

  // A simulated body without a bone is kept, simulated, driving nothing.
  PmxModel loose = test::pmx_humanoid("loose.pmx");
  loose.rigid_bodies[4].bone = -1;
  warnings.clear();
  EXPECT_EQ(repair_pmx_physics(loose, warnings).rigid_bodies[4].bone, -1);
  EXPECT_TRUE(contains(warnings, "rigid_bodies[4] '髪3'", "drives no bone"));
}

TEST(PmxDataset, WhatCannotBeRepairedIsAOneLineError) {
  PmxModel m = test::pmx_humanoid("bad.pmx");
  m.joints[1].type = PmxJointType::kHinge;
  std::vector<std::string> warnings;
  const std::string message = test::error_of([&] { repair_pmx_physics(m, warnings); });
  EXPECT_NE(message.find("bad.pmx: joints[1] '髪2': type: expected a spring 6-DOF joint"), std::string::npos)
      << message;
  EXPECT_EQ(message.find('\n'), std::string::npos);

  // A NaN size never reaches the repairs: the reader refuses it, naming the file and the field.
  PmxModel nan = test::pmx_humanoid("nan.pmx");
  nan.rigid_bodies[2].size.x() = std::numeric_limits<float>::quiet_NaN();
  const std::vector<uint8_t> bytes = pmx_to_bytes(nan);
  const std::string read = test::error_of([&] { parse_pmx(bytes.data(), bytes.size(), "nan.pmx"); });
  EXPECT_NE(read.find("nan.pmx"), std::string::npos) << read;
  EXPECT_NE(read.find("size"), std::string::npos) << read;
  EXPECT_EQ(read.find('\n'), std::string::npos);

  PmxModel converted = pmx_to_amt_frame(test::pmx_humanoid("amt.pmx"));
  EXPECT_NE(test::error_of([&] { repair_pmx_physics(converted, warnings); }).find("amt.pmx: physics: expected"),
            std::string::npos);
}

TEST(PmxDataset, BonesFollowTheirCanonicalCarriers) {
  const PmxCharacter c = pmx_character(test::pmx_humanoid());
  EXPECT_TRUE(c.warnings.empty());
  EXPECT_EQ(c.simulated_bodies, 3);
  const auto carrier = [&](const std::string& name) { return c.carrier.at(size_t(c.file_skeleton.index_of(name))); };
  EXPECT_EQ(carrier("センター"), kPelvis);  // above the root
  EXPECT_EQ(carrier("下半身"), kPelvis);
  EXPECT_EQ(carrier("左腕捩"), kLeftShoulder);  // twist bone between shoulder and elbow
  EXPECT_EQ(carrier("左ひざD"), kLeftKnee);     // D bone: its parent is 左足, its rotation 左ひざ's
  EXPECT_EQ(carrier("左ひじ"), kLeftElbow);
  EXPECT_EQ(carrier("髪1"), kHead);
  EXPECT_EQ(carrier("髪3"), kHead);

  // The rest pose gives every bone [I | rest position].
  const Transforms rest = forward_kinematics(c.skeleton(), rest_motion(c.skeleton(), 1), 0);
  const Transforms bones = pmx_bone_pose(c, rest);
  for (size_t b = 0; b < bones.size(); ++b) {
    EXPECT_TRUE(bones[b].leftCols<3>().isIdentity(1e-6f)) << b;
    EXPECT_LT((bones[b].col(3) - c.model.bones[b].position).norm(), 1e-4f) << b;
  }
}

// A clip on the humanoid: rest, then the head nodding and the left knee and elbow bending.
Transforms humanoid_clip(const Skeleton& skeleton, int frames) {
  Motion m = rest_motion(skeleton, frames);
  for (int t = 0; t < frames; ++t) {
    const float a = 0.6f * std::sin(0.25f * t) * std::min(1.0f, t / 5.0f);
    m.rotation(t, kHead) = Eigen::Quaternionf(Eigen::AngleAxisf(a, Eigen::Vector3f::UnitX()));
    m.rotation(t, kLeftKnee) = Eigen::Quaternionf(Eigen::AngleAxisf(std::abs(a), Eigen::Vector3f::UnitX()));
    m.rotation(t, kLeftElbow) = Eigen::Quaternionf(Eigen::AngleAxisf(a, Eigen::Vector3f::UnitY()));
    m.root_translation(t, 2) = 0.02f * t;
  }
  return forward_kinematics(skeleton, m);
}

TEST(PmxDataset, BodyIsExactAndHairIsSimulated) {
  const PmxCharacter c = pmx_character(test::pmx_humanoid());
  const PmxDatasetCharacter d = pmx_dataset_character(c, "pmx-0000", "train");
  const int N = d.data.mesh.num_vertices(), T = 20, J = kCanonicalJointCount;
  ASSERT_EQ(d.data.rig->num_bones(), c.num_bones());
  EXPECT_EQ(d.pieces.size(), 1u);  // one hair chain
  EXPECT_EQ(d.pieces[0].attachment_joint, kHead);
  EXPECT_EQ(d.body_vertices + 24, N);  // three hair boxes
  for (int i = 0; i < N; ++i) EXPECT_EQ(d.data.apparel_mask[size_t(i)], i >= d.body_vertices ? 1 : 0);
  for (int f = 0; f < d.data.mesh.num_faces(); ++f) {
    EXPECT_EQ(d.data.mesh.F.row(f).maxCoeff() < d.body_vertices, f < d.body_faces) << f;
  }

  const Transforms joints = humanoid_clip(c.skeleton(), T);
  std::unique_ptr<PmxRigSimulator> simulator;
  const Transforms rig = simulate_pmx_clip(c, joints, T, {}, simulator);
  ASSERT_EQ(rig.size(), size_t(T) * size_t(c.num_bones()));
  const SparseWeights body = sparsify_weights(d.data.body_weights);
  SparseWeights rig_weights;
  rig_weights.indices = d.data.rig->skin_indices;
  rig_weights.weights = d.data.rig->skin_weights;
  float body_error = 0, hair_offset = 0;
  MatrixX3f truth, skinned;
  for (int t = 0; t < T; ++t) {
    const Transforms pose(joints.begin() + t * J, joints.begin() + (t + 1) * J);
    const Transforms M(rig.begin() + t * c.num_bones(), rig.begin() + (t + 1) * c.num_bones());
    linear_blend_skinning(d.data.mesh.V, rig_weights, M, truth);
    linear_blend_skinning(d.data.mesh.V, body, skinning_matrices(d.data.skeleton, pose), skinned);
    ASSERT_TRUE(truth.allFinite());
    for (int i = 0; i < N; ++i) {
      const float e = (truth.row(i) - skinned.row(i)).norm();
      if (i < d.body_vertices)
        body_error = std::max(body_error, e);
      else
        hair_offset = std::max(hair_offset, e);
    }
  }
  EXPECT_LT(body_error, 1e-4f);   // the body is the motion's, through the model's own weights
  EXPECT_GT(hair_offset, 0.01f);  // the hair lags behind the head: physics, not skinning
  EXPECT_LT(hair_offset, 1.5f * d.pieces[0].chain_length * 2);

  // Deterministic: a fresh simulator gives the same bytes.
  std::unique_ptr<PmxRigSimulator> again;
  EXPECT_EQ(simulate_pmx_clip(c, joints, T, {}, again), rig);
}

TEST(PmxDataset, AModelWithoutPhysicsIsABodyWithoutApparel) {
  PmxModel m = test::pmx_humanoid("bare.pmx");
  m.rigid_bodies.clear();
  m.joints.clear();
  const PmxCharacter c = pmx_character(m);
  EXPECT_EQ(c.simulated_bodies, 0);
  const PmxDatasetCharacter d = pmx_dataset_character(c, "pmx-0000", "test");
  EXPECT_TRUE(d.pieces.empty());
  EXPECT_EQ(d.body_vertices, d.data.mesh.num_vertices());
  const Transforms joints = humanoid_clip(c.skeleton(), 5);
  std::unique_ptr<PmxRigSimulator> simulator;
  const Transforms rig = simulate_pmx_clip(c, joints, 5, {}, simulator);
  // Every bone is its bone pass: rigid with its carrier.
  const Transforms last(joints.end() - kCanonicalJointCount, joints.end());
  const Transforms expected = pmx_transforms_to_amt(pmx_bone_pose(c, last), c.scale);
  for (int b = 0; b < c.num_bones(); ++b) {
    EXPECT_LT((simulator->bone_transforms()[size_t(b)] - expected[size_t(b)]).cwiseAbs().maxCoeff(), 1e-6f) << b;
  }
  EXPECT_EQ(rig.size(), size_t(5 * c.num_bones()));
}

TEST(PmxDataset, BuildFromAPmxFileRecordsItAndRefusesOtherFiles) {
  const std::filesystem::path dir = test::temp_dir("pmx_dataset_build");
  const std::string model = (dir / "humanoid.pmx").string();
  write_pmx(test::pmx_humanoid(), model);
  DatasetBuildOptions o = pmx_build_options(2, 10);
  o.out = (dir / "ds").string();
  o.pmx = {model};
  const DatasetBuildReport report = build_dataset(o);
  EXPECT_EQ(report.characters_built, 1);
  EXPECT_EQ(report.clips_built, 2);
  const DatasetReader reader((dir / "ds" / "pmx-0000.h5").string());
  const CharacterData character = reader.read_character("pmx-0000");
  ASSERT_TRUE(character.rig.has_value());
  EXPECT_EQ(character.rig->num_bones(), 28);
  std::ifstream manifest(dir / "ds" / "manifest.json");
  const std::string text((std::istreambuf_iterator<char>(manifest)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"pmx_files\""), std::string::npos);
  EXPECT_NE(text.find("humanoid.pmx"), std::string::npos);

  // The same file again: nothing to do. An edited file: refused, naming the checksum.
  EXPECT_EQ(build_dataset(o).characters_skipped, 1);
  PmxModel edited = test::pmx_humanoid();
  edited.rigid_bodies[2].mass = 2.0f;
  write_pmx(edited, model);
  const std::string message = test::error_of([&] { build_dataset(o); });
  EXPECT_NE(message.find("pmx_files.0.fnv1a64"), std::string::npos) << message;
}

// A model whose head bone the MMD name table does not know is refused with a hint to --character-joint-map; with a
// map naming it, the build is the same as the build of the model under its MMD name, and the manifest records the
// map so that a rerun with an edited map is refused. The refusal leaves no manifest, so the rerun with the map starts.
TEST(PmxDataset, AJointMapMapsBonesTheNameTableCannot) {
  const std::filesystem::path dir = test::temp_dir("pmx_dataset_joint_map");
  DatasetBuildOptions o = pmx_build_options(1, 8);
  const std::string named = (dir / "named" / "humanoid.pmx").string(),
                    renamed = (dir / "renamed" / "humanoid.pmx").string();
  std::filesystem::create_directories(dir / "named");
  std::filesystem::create_directories(dir / "renamed");
  write_pmx(test::pmx_humanoid(), named);
  PmxModel model = test::pmx_humanoid();
  ASSERT_EQ(model.bones[5].name, "頭");
  model.bones[5].name = "Kopf";
  write_pmx(model, renamed);

  o.out = (dir / "ds_named").string();
  o.pmx = {named};
  build_dataset(o);
  o.out = (dir / "ds_renamed").string();
  o.pmx = {renamed};
  const std::string refused = test::error_of([&] { build_dataset(o); });
  EXPECT_NE(refused.find("head"), std::string::npos) << refused;
  EXPECT_NE(refused.find("--character-joint-map"), std::string::npos) << refused;
  EXPECT_FALSE(std::filesystem::exists(dir / "ds_renamed" / "manifest.json")) << "a refused build leaves no manifest";

  const std::string map = (dir / "map.json").string();
  std::ofstream(map) << R"({"head": "Kopf"})";
  o.character_joint_map = map;
  EXPECT_EQ(build_dataset(o).characters_built, 1);
  const DatasetReader a((dir / "ds_named" / "pmx-0000.h5").string()), b((dir / "ds_renamed" / "pmx-0000.h5").string());
  ASSERT_EQ(a.clip_names(), b.clip_names());
  const std::string clip = a.clip_names().front();
  EXPECT_EQ((a.read_vertices(clip, 0, 8) - b.read_vertices(clip, 0, 8)).cwiseAbs().maxCoeff(), 0.0f);
  EXPECT_EQ(a.read_character("pmx-0000").body_weights, b.read_character("pmx-0000").body_weights);

  std::ofstream(map) << R"({"head": "Kopf", "neck": "首"})";
  const std::string edited = test::error_of([&] { build_dataset(o); });
  EXPECT_NE(edited.find("character_joint_map"), std::string::npos) << edited;

  o.pmx.clear();
  o.characters = 1;
  const std::string alone = test::error_of([&] { validate_build_options(o); });
  EXPECT_NE(alone.find("--character-joint-map"), std::string::npos) << alone;
}

}  // namespace
}  // namespace amt
