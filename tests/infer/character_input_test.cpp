// Runtime characters: canonical rest skeletons of non-canonical files (placed and extra joints), the
// input formats' errors, apparel mask files.
#include "infer/character_input.h"

#include <gtest/gtest.h>

#include <fstream>

#include "data_tools/builder/apparel.h"
#include "data_tools/builder/body_generator.h"
#include "data_tools/formats/gltf_export.h"
#include "data_tools/formats/obj_io.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/shapes.h"
#include "tests/test_support.h"

namespace amt {
namespace {

// A Mixamo-like skeleton without collars, with 2 spine joints instead of 3, no toe joints, and an extra
// twist joint under the left elbow. Positions: hips at (0, 1, 0), spine at (0, 1.2, 0), chest at
// (0, 1.4, 0), neck at (0, 1.6, 0).
Skeleton incomplete_skeleton() {
  Skeleton s;
  auto add = [&s](const std::string& name, int parent, float x, float y) {
    s.names.push_back(name);
    s.parents.push_back(parent);
    s.rest_joints.conservativeResize(s.rest_joints.rows() + 1, 3);
    s.rest_joints.row(s.rest_joints.rows() - 1) << x, y, 0.0f;
    return int(s.names.size()) - 1;
  };
  const int hips = add("Hips", -1, 0, 1.0f);
  const int spine = add("Spine", hips, 0, 1.2f);
  const int chest = add("Chest", spine, 0, 1.4f);
  const int neck = add("Neck", chest, 0, 1.6f);
  add("Head", neck, 0, 1.7f);
  for (const int side : {1, -1}) {
    const std::string p = side > 0 ? "Left" : "Right";
    const int arm = add(p + "Arm", chest, side * 0.2f, 1.5f);
    const int fore = add(p + "ForeArm", arm, side * 0.45f, 1.5f);
    if (side > 0) add("LeftForeArmTwist", fore, 0.55f, 1.5f);
    add(p + "Hand", fore, side * 0.7f, 1.5f);
    const int up = add(p + "UpLeg", hips, side * 0.1f, 0.95f);
    const int leg = add(p + "Leg", up, side * 0.1f, 0.5f);
    add(p + "Foot", leg, side * 0.1f, 0.08f);
  }
  return s;
}

TEST(CanonicalRest, PlacesMissingJointsOnTheLineBetweenMappedNeighbours) {
  const Skeleton file = incomplete_skeleton();
  const CanonicalRest rest = canonical_rest(file, std::nullopt, "mixamo-like");
  const MatrixX3f& J = rest.skeleton.rest_joints;
  // The pelvis and the head come straight from the file.
  EXPECT_FLOAT_EQ(J(kPelvis, 1), 1.0f);
  EXPECT_FLOAT_EQ(J(kHead, 1), 1.7f);
  // Collars: on the segment from their mapped parent (spine3) to the shoulder, at its midpoint.
  const Eigen::RowVector3f spine3 = J.row(kSpine3);
  const Eigen::RowVector3f expected = 0.5f * (spine3 + J.row(kLeftShoulder));
  EXPECT_LT((J.row(kLeftCollar) - expected).norm(), 1e-6f);
  EXPECT_NE(std::find(rest.placed.begin(), rest.placed.end(), int(kLeftCollar)), rest.placed.end());
  // Every canonical joint has a distinct position (no zero-length bones).
  const auto& parents = canonical_joint_parents();
  for (int j = 1; j < kCanonicalJointCount; ++j) {
    EXPECT_GT((J.row(j) - J.row(parents[size_t(j)])).norm(), 1e-4f) << canonical_joint_names()[size_t(j)];
  }
  // The twist joint is extra and carried by the left elbow.
  ASSERT_EQ(rest.extra.size(), 1u);
  EXPECT_EQ(rest.extra[0], "LeftForeArmTwist");
  EXPECT_EQ(rest.carrier[size_t(file.index_of("LeftForeArmTwist"))], int(kLeftElbow));
  const std::string text = rest.describe(file.names);
  EXPECT_NE(text.find("left_collar <- (placed)"), std::string::npos) << text;
  EXPECT_NE(text.find("LeftForeArmTwist"), std::string::npos) << text;
}

TEST(CanonicalRest, ThreeSpineJointsOnThePelvisAreSpreadEvenly) {
  // A skeleton whose legs, arms and neck hang directly on the pelvis: spine1..3 all placed.
  MatrixX3f rest = canonical_skeleton().rest_joints;
  JointMapping mapping;
  for (int j = 0; j < kCanonicalJointCount; ++j) mapping.source_joint[size_t(j)] = j;
  mapping.source_joint[kSpine1] = mapping.source_joint[kSpine2] = mapping.source_joint[kSpine3] = kPelvis;
  rest.row(kSpine1) = rest.row(kSpine2) = rest.row(kSpine3) = rest.row(kPelvis);
  const std::vector<int> placed = place_missing_joints(rest, mapping);
  EXPECT_EQ(placed, (std::vector<int>{kSpine1, kSpine2, kSpine3}));
  const Eigen::RowVector3f a = rest.row(kPelvis), d = rest.row(kNeck);
  EXPECT_LT((rest.row(kSpine1) - (a + 0.25f * (d - a))).norm(), 1e-6f);
  EXPECT_LT((rest.row(kSpine2) - (a + 0.50f * (d - a))).norm(), 1e-6f);
  EXPECT_LT((rest.row(kSpine3) - (a + 0.75f * (d - a))).norm(), 1e-6f);
}

TEST(CanonicalRest, UnmappableSkeletonNamesTheJointMapOption) {
  Skeleton s;
  s.names = {"a", "b", "c"};
  s.parents = {-1, 0, 1};
  s.rest_joints = MatrixX3f::Zero(3, 3);
  const std::string error = test::error_of([&] { canonical_rest(s, std::nullopt, "blob.glb"); });
  EXPECT_NE(error.find("blob.glb"), std::string::npos) << error;
  EXPECT_NE(error.find("--character-joint-map"), std::string::npos) << error;
}

TEST(LoadCharacter, ObjWithoutJointsFileIsAClearError) {
  const auto dir = test::temp_dir("character_no_joints");
  const std::string obj = (dir / "blob.obj").string();
  write_obj(obj, uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 8, 6));
  const std::string error = test::error_of([&] { load_character({obj, "", ""}); });
  EXPECT_NE(error.find("blob.obj: joints: the character has no skeleton"), std::string::npos) << error;
  EXPECT_NE(error.find("--character-joints"), std::string::npos) << error;
}

TEST(LoadCharacter, ObjWithSidecarOnTheCanonicalSkeleton) {
  const auto dir = test::temp_dir("character_obj");
  const Skeleton s = canonical_skeleton();
  const std::string obj = (dir / "capsules.obj").string();
  write_obj(obj, capsule_character(s.rest_joints, s.parents, 600));
  write_joints_json(joints_sidecar_path(obj), s);
  const RuntimeCharacter c = load_character({obj, "", ""});
  EXPECT_EQ(c.name, "capsules");
  EXPECT_TRUE(c.rest.placed.empty());
  EXPECT_TRUE(c.rest.extra.empty());
  EXPECT_LT((c.skeleton.rest_joints - s.rest_joints).cwiseAbs().maxCoeff(), 1e-7f);
}

TEST(LoadCharacter, RiggedGltfChainsOutsideTheCanonicalMapAreTheRigsApparel) {
  // A generated character exported with its whole rig (the canonical joints, then the apparel chains'
  // bones) and its rig weights: the vertices on the chains are exactly the builder's apparel mask.
  const auto dir = test::temp_dir("character_gltf_chains");
  const DressedCharacter dressed = dress_character(generate_body(sample_body_params(5), 1400), 5);
  Skeleton rig;
  for (const PhysicsBone& bone : dressed.rig.bones) {
    rig.names.push_back(bone.name);
    rig.parents.push_back(bone.parent);
  }
  rig.rest_joints.resize(dressed.rig.num_bones(), 3);
  for (int b = 0; b < dressed.rig.num_bones(); ++b) rig.rest_joints.row(b) = dressed.rig.bones[b].rest_position;
  const std::string glb = (dir / "dressed.glb").string();
  export_gltf_rigged(glb, dressed.mesh, rig, dressed.rig_weights, rest_motion(rig, 1));
  const RuntimeCharacter c = load_character({glb, "", ""});
  ASSERT_EQ(c.rig_apparel_mask.size(), dressed.apparel_mask.size()) << c.rig_apparel;
  EXPECT_EQ(c.rig_apparel_mask, dressed.apparel_mask);
  EXPECT_EQ(c.rig_apparel.rfind("glTF chains: ", 0), 0u) << c.rig_apparel;
  // The same chains named as fingers are the body's: no rig apparel.
  for (size_t b = 22; b < rig.names.size(); ++b) rig.names[b] = "LeftHandIndex_" + rig.names[b];
  export_gltf_rigged(glb, dressed.mesh, rig, dressed.rig_weights, rest_motion(rig, 1));
  EXPECT_TRUE(load_character({glb, "", ""}).rig_apparel_mask.empty());
}

TEST(ApparelMask, ReadsJsonAndTextAndRejectsBadValues) {
  const auto dir = test::temp_dir("apparel_mask");
  const std::string json = (dir / "m.json").string(), text = (dir / "m.txt").string();
  std::ofstream(json) << "[0, 1, true, false]";
  std::ofstream(text) << "1 0\n0 1\n";
  EXPECT_EQ(read_apparel_mask(json, 4), (std::vector<uint8_t>{0, 1, 1, 0}));
  EXPECT_EQ(read_apparel_mask(text, 4), (std::vector<uint8_t>{1, 0, 0, 1}));
  EXPECT_NE(test::error_of([&] { read_apparel_mask(json, 5); }).find("expected 5 values"), std::string::npos);
  std::ofstream(text) << "1 0 2 1";
  EXPECT_NE(test::error_of([&] { read_apparel_mask(text, 4); }).find("value 2: expected 0 or 1, found 2"),
            std::string::npos);
}

}  // namespace
}  // namespace amt
