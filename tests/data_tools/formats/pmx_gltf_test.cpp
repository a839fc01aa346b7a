// PMX to glTF / VRM (pmx_gltf.h): the MMD-style test humanoid written as .glb and .vrm and read back through amt's
// own glTF reader (vertices, skin weights of every deform type, bones, the humanoid map, springs and colliders with
// their parameters), every file through the Khronos validator; spring chains at a branch; the parameter mapping;
// textures embedded or left out with a note; a .vrm without humanoid bones as a one-line error.
#include "data_tools/formats/pmx_gltf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/joint_map.h"
#include "data_tools/formats/render.h"
#include "tests/data_tools/builder/pmx_humanoid.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;
using test::error_of;

// The humanoid with a vertex of each deform type (weights not summing to 1 among them), so that the skin weights
// exercise pmx_skin_weights' whole reduction.
PmxModel humanoid_with_deforms(const std::string& source) {
  PmxModel m = test::pmx_humanoid(source);
  PmxVertices& v = m.vertices;
  v.deform[0] = PmxDeform::kBdef2;
  v.bone_indices.row(0) << 1, 2, -1, -1;
  v.bone_weights.row(0) << 0.3f, 0.7f, 0, 0;
  v.deform[1] = PmxDeform::kBdef4;
  v.bone_indices.row(1) << 1, 2, 3, 1;  // a repeated bone: merged
  v.bone_weights.row(1) << 0.2f, 0.4f, 0.4f, 0.2f;
  v.deform[2] = PmxDeform::kSdef;
  v.bone_indices.row(2) << 2, 0, -1, -1;
  v.bone_weights.row(2) << 0.25f, 0.75f, 0, 0;
  v.deform[3] = PmxDeform::kQdef;
  v.bone_indices.row(3) << 0, 1, 2, 3;
  v.bone_weights.row(3) << 0.1f, 0.2f, 0.3f, 0.6f;
  return m;
}

// Two materials over the humanoid's faces: the first box, then the rest.
void add_two_materials(PmxModel& m) {
  PmxMaterial a;
  a.name = "腰";
  a.diffuse = {0.9f, 0.5f, 0.25f, 1.0f};
  a.face_count = 12;
  PmxMaterial b = a;
  b.name = "体";
  b.diffuse = {0.5f, 0.5f, 0.5f, 1.0f};
  b.flags = kPmxMaterialDoubleSided;
  b.face_count = static_cast<int32_t>(m.faces.rows()) - 12;
  m.materials = {a, b};
}

// The bone of a skeleton joint read back: its node minus the mesh node.
int bone_of_joint(const GltfCharacter& c, int joint) {
  return c.joint_nodes[size_t(joint)] - 1;
}

TEST(PmxGltf, GlbReadsBackWithThePmxsVerticesWeightsAndBones) {
  const fs::path dir = test::temp_dir("pmx_gltf_glb");
  PmxModel model = humanoid_with_deforms((dir / "humanoid.pmx").string());
  add_two_materials(model);
  const std::string out = (dir / "humanoid.glb").string();
  const PmxGltfSummary s = write_pmx_gltf(model, out);
  const PmxModel amt = pmx_to_amt_frame(model);
  EXPECT_EQ(s.pmx_vertices, 168);
  EXPECT_EQ(s.vertices, 168);  // the boxes' vertices are the materials' own
  EXPECT_EQ(s.faces, 252);
  EXPECT_EQ(s.primitives, 2);
  EXPECT_EQ(s.materials, 2);
  EXPECT_EQ(s.bones, 28);
  EXPECT_GT(s.bytes, 0u);
  EXPECT_EQ(fs::file_size(out), s.bytes);
  EXPECT_FALSE(fs::exists(out + ".amt-tmp"));

  const GltfAsset asset = read_gltf(out);
  EXPECT_EQ(gltf_vrm_version(asset), "");
  const GltfCharacter c = gltf_character(asset);
  ASSERT_EQ(c.mesh.V.rows(), s.vertices);
  ASSERT_EQ(int(s.vertex_source.size()), s.vertices);
  for (int i = 0; i < s.vertices; ++i) {
    const int v = s.vertex_source[size_t(i)];
    EXPECT_LT((c.mesh.V.row(i) - amt.vertices.positions.row(v)).cwiseAbs().maxCoeff(), 1e-6f) << "vertex " << i;
  }
  // The same triangles (amt's winding), through the vertex map.
  ASSERT_EQ(c.mesh.F.rows(), amt.faces.rows());
  for (int f = 0; f < amt.faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) EXPECT_EQ(s.vertex_source[size_t(c.mesh.F(f, k))], amt.faces(f, k)) << "face " << f;
  }
  // Skin weights: per vertex, bone -> weight as pmx_skin_weights gives them.
  const SparseWeights expected = pmx_skin_weights(amt);
  for (int i = 0; i < s.vertices; ++i) {
    const int v = s.vertex_source[size_t(i)];
    std::map<int, float> want, got;
    for (int k = 0; k < kMaxInfluences; ++k) {
      if (expected.weights(v, k) > 0) want[expected.indices(v, k)] += expected.weights(v, k);
      if (c.weights.weights(i, k) > 0) got[bone_of_joint(c, c.weights.indices(i, k))] += c.weights.weights(i, k);
    }
    ASSERT_EQ(got.size(), want.size()) << "vertex " << i;
    for (const auto& [bone, w] : want) EXPECT_NEAR(got[bone], w, 1e-6f) << "vertex " << i << " bone " << bone;
  }
  // Vertex 1's BDEF4 (0.2, 0.4, 0.4, 0.2 on bones 1, 2, 3, 1) is 0.4, 0.4, 0.2 of 1.2 after the merge.
  std::map<int, float> vertex1;
  for (int k = 0; k < kMaxInfluences; ++k)
    if (c.weights.weights(1, k) > 0) vertex1[bone_of_joint(c, c.weights.indices(1, k))] = c.weights.weights(1, k);
  EXPECT_NEAR(vertex1[1], 0.4f / 1.2f, 1e-6f);
  EXPECT_NEAR(vertex1[2], 0.4f / 1.2f, 1e-6f);
  EXPECT_NEAR(vertex1[3], 0.4f / 1.2f, 1e-6f);
  // Every bone, by name, with its parent and its rest position in metres.
  ASSERT_EQ(c.skeleton.num_joints(), 28);
  for (int j = 0; j < 28; ++j) {
    const int b = bone_of_joint(c, j);
    ASSERT_GE(b, 0);
    EXPECT_EQ(c.skeleton.names[size_t(j)], amt.bones[size_t(b)].name);
    const int p = c.skeleton.parents[size_t(j)];
    EXPECT_EQ(p < 0 ? -1 : bone_of_joint(c, p), amt.bones[size_t(b)].parent) << amt.bones[size_t(b)].name;
    EXPECT_LT((c.skeleton.rest_joints.row(j).transpose() - amt.bones[size_t(b)].position).norm(), 1e-6f);
  }
  // 頭 at the canonical head, in metres.
  EXPECT_LT((amt.bones[5].position - canonical_skeleton().rest_joints.row(kHead).transpose()).norm(), 1e-5f);
  // A .glb carries the springs too, without VRMC_vrm.
  EXPECT_EQ(gltf_vrm_spring_rig(asset, c).num_joints(), 3);
  EXPECT_FALSE(gltf_vrm_joint_map(asset, c).has_value());
  test::expect_valid_gltf(out);
}

// The humanoid map of the .vrm gives the canonical joints the PMX's own names give; MMD's side-by-side 下半身 and
// 上半身 put the hips on センター above them.
TEST(PmxGltf, VrmHumanoidGivesTheCanonicalJoints) {
  const fs::path dir = test::temp_dir("pmx_gltf_vrm");
  for (const bool side_by_side : {true, false}) {
    SCOPED_TRACE(side_by_side ? "MMD's centre bone" : "spine under the pelvis");
    PmxModel model = test::pmx_humanoid((dir / "humanoid.pmx").string());
    if (!side_by_side) model.bones[2].parent = 1;  // 上半身 under 下半身
    const std::string out = (dir / (side_by_side ? "a.vrm" : "b.vrm")).string();
    PmxGltfOptions options;
    options.kind = PmxGltfKind::kVrm;
    const PmxGltfSummary s = write_pmx_gltf(model, out, options);
    std::map<std::string, std::string> human(s.humanoid.begin(), s.humanoid.end());
    EXPECT_EQ(human["hips"], side_by_side ? "センター" : "下半身");
    EXPECT_EQ(human["spine"], "上半身");
    EXPECT_EQ(human["chest"], "上半身2");
    EXPECT_EQ(human.count("upperChest"), 0u);
    EXPECT_EQ(human["neck"], "首");
    EXPECT_EQ(human["head"], "頭");
    EXPECT_EQ(human["leftShoulder"], "左肩");
    EXPECT_EQ(human["leftUpperArm"], "左腕");
    EXPECT_EQ(human["rightLowerArm"], "右ひじ");
    EXPECT_EQ(human["rightHand"], "右手首");
    EXPECT_EQ(human["leftUpperLeg"], "左足");
    EXPECT_EQ(human["leftLowerLeg"], "左ひざ");
    EXPECT_EQ(human["rightFoot"], "右足首");
    EXPECT_EQ(human["rightToes"], "右つま先");
    EXPECT_EQ(s.humanoid.size(), 21u);
    const bool noted = std::any_of(s.notes.begin(), s.notes.end(), [](const std::string& n) {
      return n.find("humanoid: hips on 'センター'") != std::string::npos;
    });
    EXPECT_EQ(noted, side_by_side);

    const GltfAsset asset = read_gltf(out);
    EXPECT_EQ(gltf_vrm_version(asset), "1");
    const GltfCharacter c = gltf_character(asset);
    const std::optional<JointMapFile> vrm_map = gltf_vrm_joint_map(asset, c);
    ASSERT_TRUE(vrm_map.has_value());
    EXPECT_EQ(vrm_map->entries.size(), 19u);  // every humanoid bone but the spine's, which come from the structure
    const JointMapping read = map_to_canonical(c.skeleton.names, c.skeleton.parents, vrm_map, "read");
    std::vector<std::string> names;
    std::vector<int> parents;
    for (const PmxBone& b : model.bones) names.push_back(b.name), parents.push_back(b.parent);
    const JointMapping own = map_to_canonical(names, parents, std::nullopt, "pmx");
    for (int j = 0; j < kCanonicalJointCount; ++j) {
      const std::string want = j == kPelvis && side_by_side ? "センター" : names[size_t(own.source_joint[j])];
      EXPECT_EQ(c.skeleton.names[size_t(read.source_joint[j])], want) << canonical_joint_names()[size_t(j)];
    }
    test::expect_valid_gltf(out);
  }
}

// The hair chain (髪1, 髪2 on mode 1 boxes, 髪3 on a mode 2 box, hung from 頭 by spring joints) is one spring of
// three turning joints with its tip at the far end of 髪3's box; the head sphere and the upper body capsule are its
// colliders.
TEST(PmxGltf, VrmSpringsAndCollidersReadBackWithTheirParameters) {
  const fs::path dir = test::temp_dir("pmx_gltf_springs");
  const PmxModel model = test::pmx_humanoid((dir / "humanoid.pmx").string());
  const std::string out = (dir / "humanoid.vrm").string();
  PmxGltfOptions options;
  options.kind = PmxGltfKind::kVrm;
  const PmxGltfSummary s = write_pmx_gltf(model, out, options);
  EXPECT_EQ(s.springs, 1);
  EXPECT_EQ(s.spring_joints, 4);  // 髪1, 髪2, 髪3 and the tip
  EXPECT_EQ(s.spring_segments, 3);
  EXPECT_EQ(s.colliders, 2);
  EXPECT_EQ(s.collider_groups, 1);

  const GltfAsset asset = read_gltf(out);
  const GltfCharacter c = gltf_character(asset);
  const SpringRig rig = gltf_vrm_spring_rig(asset, c);
  ASSERT_EQ(rig.num_joints(), 3);
  const PmxModel amt = pmx_to_amt_frame(model);
  const float s08 = kPmxMetresPerUnit;
  // MMD damping 0.5 / 0.5, joint springs 20 on every axis, limits of +-1 rad (a range of 2).
  const float stiffness = 0.5f * (1.0f + std::log2(21.0f)) / std::sqrt(2.0f);  // 1.9065
  for (int k = 0; k < 3; ++k) {
    const SpringJoint& j = rig.joints[size_t(k)];
    EXPECT_EQ(c.skeleton.names[size_t(j.joint)], "髪" + std::to_string(k + 1));
    EXPECT_EQ(j.spring, 0);
    EXPECT_NEAR(j.hit_radius, 0.35f * s08, 1e-6f);  // the box's smallest half extent
    EXPECT_NEAR(j.drag, 0.45f, 1e-6f);
    EXPECT_NEAR(j.stiffness, stiffness, 1e-5f);
    EXPECT_NEAR(j.stiffness, 1.9065f, 1e-3f);
    EXPECT_NEAR(j.gravity_power, 0.25f / 3.0f, 1e-6f);
    EXPECT_LT((j.gravity_dir - Eigen::Vector3f(0, -1, 0)).norm(), 1e-6f);
    // Each tail is the next bone; 髪3's is its box's far end, the end of the hair.
    const Eigen::Vector3f tail = k < 2 ? amt.bones[size_t(26 + k)].position
                                       : Eigen::Vector3f(2 * amt.rigid_bodies[4].position - amt.bones[27].position);
    EXPECT_LT((j.tail - tail).norm(), 1e-5f) << k;
  }
  ASSERT_EQ(rig.colliders.size(), 2u);
  const SpringCollider& head = rig.colliders[0];
  EXPECT_FALSE(head.capsule);
  EXPECT_EQ(c.skeleton.names[size_t(head.joint)], "頭");
  EXPECT_NEAR(head.radius, 1.2f * s08, 1e-6f);
  EXPECT_LT((head.center - amt.rigid_bodies[0].position).norm(), 1e-6f);
  const SpringCollider& chest = rig.colliders[1];
  EXPECT_TRUE(chest.capsule);
  EXPECT_EQ(c.skeleton.names[size_t(chest.joint)], "上半身");
  EXPECT_NEAR(chest.radius, 1.6f * s08, 1e-6f);
  const Eigen::Vector3f half(0, 0.5f * 2.5f * s08, 0);  // half the capsule's height, along its Y
  EXPECT_LT((chest.center - (amt.rigid_bodies[1].position - half)).norm(), 1e-6f);
  EXPECT_LT((chest.tail - (amt.rigid_bodies[1].position + half)).norm(), 1e-6f);
  ASSERT_EQ(rig.spring_colliders.size(), 1u);
  EXPECT_EQ(rig.spring_colliders[0], (std::vector<int>{0, 1}));  // the hair's group 1 collides with group 0
  test::expect_valid_gltf(out);

  // Hair that MMD's masks keep off the body collides with nothing.
  PmxModel apart = model;
  for (int k = 2; k < 5; ++k) apart.rigid_bodies[size_t(k)].collision_mask = 0xFFFE;  // not group 0
  const std::string out2 = (dir / "apart.glb").string();
  write_pmx_gltf(apart, out2);
  const GltfAsset asset2 = read_gltf(out2);
  const SpringRig rig2 = gltf_vrm_spring_rig(asset2, gltf_character(asset2));
  EXPECT_EQ(rig2.colliders.size(), 2u);
  ASSERT_EQ(rig2.spring_colliders.size(), 1u);
  EXPECT_TRUE(rig2.spring_colliders[0].empty());
}

PmxBone plain_bone(const std::string& name, const Eigen::Vector3f& position, int parent) {
  PmxBone b;
  b.name = name;
  b.position = position;
  b.parent = parent;
  b.tail_offset = Eigen::Vector3f(0, -1, 0);
  return b;
}

PmxRigidBody body_on(int bone, const Eigen::Vector3f& position, PmxPhysicsMode mode) {
  PmxRigidBody r;
  r.bone = bone;
  r.shape = PmxShape::kSphere;
  r.size = {0.5f, 0, 0};
  r.position = position;
  r.mode = mode;
  return r;
}

// A (kinematic) - B - C, C branching to D and E, E ending in a bone without a body F; G a lone physics bone
// with no tail. In amt's frame already (metres).
TEST(PmxGltf, SpringChainsFollowTheSpecificationAtABranch) {
  PmxModel m;
  m.frame = PmxFrame::kAmt;
  m.scale = 1.0f;
  m.bones = {plain_bone("A", {0, 3, 0}, -1),      plain_bone("B", {0, 2.5f, 0}, 0),
             plain_bone("C", {0, 2, 0}, 1),       plain_bone("D", {-0.5f, 1.5f, 0}, 2),
             plain_bone("E", {0.5f, 1.5f, 0}, 2), plain_bone("F", {0.5f, 1, 0}, 4),
             plain_bone("G", {1, 3, 0}, 0)};
  m.bones[6].tail_offset = Eigen::Vector3f::Zero();
  m.rigid_bodies = {body_on(0, {0, 3, 0}, PmxPhysicsMode::kFollowBone),
                    body_on(1, {0, 2.2f, 0}, PmxPhysicsMode::kDynamic),
                    body_on(2, {0, 1.8f, 0}, PmxPhysicsMode::kDynamic),
                    body_on(3, {-0.5f, 1.2f, 0}, PmxPhysicsMode::kDynamicWithBonePosition),
                    body_on(4, {0.5f, 1.2f, 0}, PmxPhysicsMode::kDynamic),
                    body_on(6, {1, 3, 0}, PmxPhysicsMode::kDynamic)};
  std::vector<std::string> notes;
  const std::vector<PmxSpringChain> chains = pmx_spring_chains(m, &notes);
  ASSERT_EQ(chains.size(), 2u);
  EXPECT_EQ(chains[0].bones, (std::vector<int>{1, 2, 3}));  // B C D and D's tip: the first child goes on
  EXPECT_EQ(chains[0].parameters.size(), 3u);
  EXPECT_TRUE(chains[0].tip);
  EXPECT_LT((chains[0].tip_position - Eigen::Vector3f(-0.5f, 0.5f, 0)).norm(), 1e-6f);  // D's tail offset
  EXPECT_EQ(chains[1].bones, (std::vector<int>{4, 5}));  // E, then F (no body) as the tail: C is not repeated
  EXPECT_EQ(chains[1].parameters.size(), 1u);
  EXPECT_FALSE(chains[1].tip);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_EQ(notes[0], "1 physics bone(s) with neither a child nor a tail to turn towards (G): no spring");
  // No joints: no spring and the widest range; sphere bodies of radius 0.5 m.
  const PmxSpringParameters free = pmx_spring_parameters(0.0f, 0.0f, 6.2831853f);
  EXPECT_NEAR(chains[0].parameters[0].stiffness, free.stiffness, 1e-6f);
  EXPECT_NEAR(chains[0].parameters[0].hit_radius, 0.5f, 1e-6f);
  const std::vector<PmxSpringCollider> colliders = pmx_spring_colliders(m);
  ASSERT_EQ(colliders.size(), 1u);
  EXPECT_EQ(colliders[0].bone, 0);
  EXPECT_FALSE(colliders[0].capsule);
  EXPECT_NEAR(colliders[0].radius, 0.5f, 1e-6f);
}

TEST(PmxGltf, BoxCollidersBecomeTheCapsuleOrSphereThatCoversThem) {
  PmxModel m;
  m.frame = PmxFrame::kAmt;
  m.bones = {plain_bone("A", {0, 1, 0}, -1)};
  PmxRigidBody slab = body_on(0, {0, 1, 0}, PmxPhysicsMode::kFollowBone);
  slab.shape = PmxShape::kBox;
  slab.size = {0.1f, 0.4f, 0.05f};     // long along Y
  slab.rotation = {0, 0, 1.5707963f};  // turned a quarter about Z: long along -X
  PmxRigidBody cube = slab;
  cube.size = {0.2f, 0.2f, 0.2f};
  cube.rotation = Eigen::Vector3f::Zero();
  m.rigid_bodies = {slab, cube};
  const std::vector<PmxSpringCollider> c = pmx_spring_colliders(m);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_TRUE(c[0].capsule);
  EXPECT_NEAR(c[0].radius, std::sqrt(0.1f * 0.1f + 0.05f * 0.05f), 1e-6f);
  EXPECT_NEAR((c[0].tail - c[0].offset).norm(), 0.8f, 1e-5f);
  EXPECT_NEAR(std::abs(c[0].tail.x() - c[0].offset.x()), 0.8f, 1e-5f);
  // Every corner of the slab is inside the capsule.
  const Eigen::Matrix3f R = pmx_euler_rotation(slab.rotation);
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3f corner =
        R * Eigen::Vector3f(k & 1 ? 0.1f : -0.1f, k & 2 ? 0.4f : -0.4f, k & 4 ? 0.05f : -0.05f);
    const Eigen::Vector3f axis = c[0].tail - c[0].offset;
    const float t = std::clamp((corner - c[0].offset).dot(axis) / axis.squaredNorm(), 0.0f, 1.0f);
    EXPECT_LE((corner - (c[0].offset + t * axis)).norm(), c[0].radius + 1e-6f) << k;
  }
  EXPECT_FALSE(c[1].capsule);  // a cube: the sphere through its corners is smaller than any covering capsule
  EXPECT_NEAR(c[1].radius, std::sqrt(3.0f) * 0.2f, 1e-6f);
}

TEST(PmxGltf, SpringParametersAreMonotoneInTheMmdValues) {
  const PmxSpringParameters p = pmx_spring_parameters(0.5f, 20.0f, 2.0f);
  EXPECT_NEAR(p.drag_force, 0.45f, 1e-6f);
  EXPECT_NEAR(p.stiffness, 0.5f * (1 + std::log2(21.0f)) / std::sqrt(2.0f), 1e-6f);
  EXPECT_NEAR(p.gravity_power, 0.25f / 3, 1e-6f);
  EXPECT_NEAR(pmx_spring_parameters(0, 0, 1).stiffness, 0.5f, 1e-6f);
  EXPECT_NEAR(pmx_spring_parameters(0, 0, 1).drag_force, 0.1f, 1e-6f);
  EXPECT_NEAR(pmx_spring_parameters(1, 0, 1).drag_force, 0.8f, 1e-6f);
  EXPECT_NEAR(pmx_spring_parameters(5, 0, 1).drag_force, 0.8f, 1e-6f);        // damping clamped to [0, 1]
  EXPECT_NEAR(pmx_spring_parameters(0, 1e6f, 0.01f).stiffness, 4.0f, 1e-6f);  // the cap
  float last_drag = -1, last_stiff = -1, last_gravity = 1e9f, last_range_stiff = 1e9f;
  for (int k = 0; k <= 20; ++k) {
    const float x = 0.05f * k;
    const PmxSpringParameters by_damping = pmx_spring_parameters(x, 5, 1);
    EXPECT_GT(by_damping.drag_force, last_drag);
    last_drag = by_damping.drag_force;
    const PmxSpringParameters by_spring = pmx_spring_parameters(0.5f, 50 * x, 1);
    EXPECT_GE(by_spring.stiffness, last_stiff);
    EXPECT_LE(by_spring.gravity_power, last_gravity);
    last_stiff = by_spring.stiffness;
    last_gravity = by_spring.gravity_power;
    const PmxSpringParameters by_range = pmx_spring_parameters(0.5f, 5, 0.2f + 0.3f * k);
    EXPECT_LE(by_range.stiffness, last_range_stiff);
    last_range_stiff = by_range.stiffness;
  }
}

// === Textures

struct Glb {
  nlohmann::json json;
  std::string bin;

  std::string view(int index) const {
    const nlohmann::json& v = json["bufferViews"][size_t(index)];
    return bin.substr(v.value("byteOffset", size_t(0)), v["byteLength"].get<size_t>());
  }
};

Glb read_glb(const std::string& path) {
  const std::string bytes = test::read_file_bytes(path);
  uint32_t json_length = 0, bin_length = 0;
  std::memcpy(&json_length, bytes.data() + 12, 4);
  std::memcpy(&bin_length, bytes.data() + 20 + json_length, 4);
  return {nlohmann::json::parse(bytes.substr(20, json_length)), bytes.substr(28 + json_length, bin_length)};
}

TEST(PmxGltf, PngTexturesAreEmbeddedAndOthersLeftOutWithANote) {
  const fs::path dir = test::temp_dir("pmx_gltf_textures");
  fs::create_directories(dir / "model" / "tex");
  Image picture;
  picture.width = 2;
  picture.height = 2;
  picture.rgb = {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255};
  write_png(picture, (dir / "model" / "tex" / "skin.png").string());
  std::ofstream(dir / "model" / "tex" / "cloth.bmp", std::ios::binary) << std::string("BM\x3a\0\0\0", 6);
  write_png(picture, (dir / "outside.png").string());

  PmxModel model = test::pmx_humanoid((dir / "model" / "humanoid.pmx").string());
  for (int v = 0; v < model.vertices.size(); ++v) model.vertices.uvs.row(v) << 0.125f * (v % 8), 0.25f * (v % 4);
  model.textures = {"tex\\SKIN.PNG", "tex\\cloth.bmp", "tex\\missing.png", "..\\outside.png"};
  const char* names[4] = {"肌", "布", "髪", "靴"};
  for (int k = 0; k < 4; ++k) {
    PmxMaterial m;
    m.name = names[k];
    m.diffuse = {0.25f * k, 0.5f, 1.0f, k == 3 ? 0.5f : 1.0f};
    m.texture = k;
    m.flags = k == 1 ? kPmxMaterialDoubleSided : 0;
    m.face_count = k < 3 ? 12 : static_cast<int32_t>(model.faces.rows()) - 36;
    model.materials.push_back(m);
  }
  const std::string out = (dir / "model.glb").string();
  const PmxGltfSummary s = write_pmx_gltf(model, out);
  EXPECT_EQ(s.textures_embedded, 1);
  EXPECT_EQ(s.textures_left_out, 3);
  const auto has_note = [&](const std::string& text) {
    return std::find(s.notes.begin(), s.notes.end(), text) != s.notes.end();
  };
  EXPECT_TRUE(
      has_note("texture tex\\cloth.bmp (material 布): BMP cannot go into glTF (only PNG and JPEG can): "
               "left out, the colour kept"));
  EXPECT_TRUE(has_note("texture tex\\missing.png (material 髪): not found in " + (dir / "model").string() +
                       ": left out, the colour kept"));
  EXPECT_TRUE(
      has_note("texture ..\\outside.png (material 靴): outside the model's folder (only files in it or "
               "below it are read): left out, the colour kept"));

  const Glb glb = read_glb(out);
  ASSERT_EQ(glb.json["images"].size(), 1u);
  EXPECT_EQ(glb.json["images"][0]["mimeType"], "image/png");
  EXPECT_EQ(glb.view(glb.json["images"][0]["bufferView"].get<int>()),
            test::read_file_bytes(dir / "model" / "tex" / "skin.png"));
  ASSERT_EQ(glb.json["textures"].size(), 1u);
  EXPECT_EQ(glb.json["textures"][0]["source"], 0);
  const nlohmann::json& materials = glb.json["materials"];
  ASSERT_EQ(materials.size(), 4u);
  EXPECT_EQ(materials[0]["pbrMetallicRoughness"]["baseColorTexture"]["index"], 0);
  for (int k = 1; k < 4; ++k) {
    const nlohmann::json& pbr = materials[size_t(k)]["pbrMetallicRoughness"];
    EXPECT_FALSE(pbr.contains("baseColorTexture")) << k;
    EXPECT_NEAR(pbr["baseColorFactor"][0].get<double>(), 0.25 * k, 1e-7);  // the colour kept
    EXPECT_EQ(pbr["metallicFactor"], 0.0);
  }
  EXPECT_EQ(materials[1].value("doubleSided", false), true);
  EXPECT_EQ(materials[0].value("doubleSided", false), false);
  EXPECT_EQ(materials[3].value("alphaMode", std::string("OPAQUE")), "BLEND");
  EXPECT_EQ(materials[0].value("alphaMode", std::string("OPAQUE")), "OPAQUE");
  // TEXCOORD_0 is PMX's uv unchanged: both put (0, 0) at the image's top-left corner.
  const nlohmann::json& primitive = glb.json["meshes"][0]["primitives"][0];
  EXPECT_EQ(primitive["material"], 0);
  const nlohmann::json& accessor = glb.json["accessors"][primitive["attributes"]["TEXCOORD_0"].get<size_t>()];
  ASSERT_EQ(accessor["count"], 8);
  const std::string uv = glb.view(accessor["bufferView"].get<int>());
  for (int i = 0; i < 8; ++i) {
    float u = 0, v = 0;
    std::memcpy(&u, uv.data() + 8 * i, 4);
    std::memcpy(&v, uv.data() + 8 * i + 4, 4);
    EXPECT_EQ(u, model.vertices.uvs(s.vertex_source[size_t(i)], 0));
    EXPECT_EQ(v, model.vertices.uvs(s.vertex_source[size_t(i)], 1));
  }
  test::expect_valid_gltf(out);
}

TEST(PmxGltf, VrmWithoutHumanoidBonesIsAOneLineError) {
  const fs::path dir = test::temp_dir("pmx_gltf_no_humanoid");
  PmxModel model = test::pmx_humanoid((dir / "props.pmx").string());
  model.bones[5].name = "atama";
  model.bones[17].name = "hiza";
  PmxGltfOptions options;
  options.kind = PmxGltfKind::kVrm;
  const std::string out = (dir / "props.vrm").string();
  const std::string error = error_of([&] { write_pmx_gltf(model, out, options); });
  EXPECT_EQ(error,
            (dir / "props.pmx").string() +
                ": humanoid: expected a bone for each of the VRM humanoid bones head (頭), leftLowerLeg (左ひざ) "
                "(MMD's standard names in brackets), found none among the model's 28 bones; write a .glb "
                "instead, or pass --joint-map FILE {canonical joint: bone}");
  EXPECT_FALSE(fs::exists(out));
  // A joint map names them.
  options.joint_map = parse_joint_map(R"({"head": "atama", "left_knee": "hiza"})", "map.json");
  const PmxGltfSummary s = write_pmx_gltf(model, out, options);
  std::map<std::string, std::string> human(s.humanoid.begin(), s.humanoid.end());
  EXPECT_EQ(human["head"], "atama");
  EXPECT_EQ(human["leftLowerLeg"], "hiza");
  // A .glb needs no humanoid.
  EXPECT_EQ(write_pmx_gltf(model, (dir / "props.glb").string()).humanoid.size(), 0u);
  // A model without faces (the fuzzer's empty sections) has nothing to convert.
  const PmxModel empty = read_pmx(std::string(AMT_TEST_ASSETS_DIR) + "/pmx/fuzz_empty_sections.pmx");
  EXPECT_NE(error_of([&] {
              write_pmx_gltf(empty, (dir / "empty.glb").string());
            }).find("fuzz_empty_sections.pmx: faces: expected at least 1 face to convert, found none"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "empty.glb"));
}

}  // namespace
}  // namespace amt
