// VRM avatars: the committed artist-made avatar data/characters/Godette.vrm (VRM 0.x, CC-BY) is mapped by its
// humanoid bone map without a joint map, turned to face +Z, and its spring bones name its apparel; the same avatar
// rewritten as VRM 1.0 with renamed nodes (no naming convention can match them) maps through VRMC_vrm and
// VRMC_springBone; malformed maps are one-line errors naming the field.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>
#include <set>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/gltf_import.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/motion.h"
#include "infer/character_input.h"
#include "infer/motion_input.h"
#include "tests/test_support.h"

namespace amt {
namespace {

const std::string kGodette = std::string(AMT_ASSET_DIR) + "/characters/Godette.vrm";

struct Glb {
  nlohmann::json json;
  std::vector<uint8_t> bin;  // the BIN chunk's data
};

Glb read_glb(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto u32 = [&](size_t at) {
    uint32_t v;
    std::memcpy(&v, &bytes[at], 4);
    return v;
  };
  Glb glb;
  const uint32_t json_length = u32(12);
  glb.json = nlohmann::json::parse(bytes.begin() + 20, bytes.begin() + 20 + json_length);
  const size_t bin_at = 20 + json_length;
  glb.bin.assign(bytes.begin() + long(bin_at) + 8, bytes.begin() + long(bin_at) + 8 + u32(bin_at));
  return glb;
}

void write_glb(const Glb& glb, const std::string& path) {
  std::string json = glb.json.dump();
  while (json.size() % 4) json += ' ';
  std::vector<uint8_t> bin = glb.bin;
  while (bin.size() % 4) bin.push_back(0);
  auto u32 = [](std::vector<uint8_t>& out, uint32_t v) {
    for (int k = 0; k < 4; ++k) out.push_back(uint8_t(v >> (8 * k)));
  };
  std::vector<uint8_t> out;
  u32(out, 0x46546C67);  // "glTF"
  u32(out, 2);
  u32(out, uint32_t(12 + 8 + json.size() + 8 + bin.size()));
  u32(out, uint32_t(json.size()));
  u32(out, 0x4E4F534A);  // "JSON"
  out.insert(out.end(), json.begin(), json.end());
  u32(out, uint32_t(bin.size()));
  u32(out, 0x004E4942);  // "BIN\0"
  out.insert(out.end(), bin.begin(), bin.end());
  std::ofstream file(path, std::ios::binary);
  file.write(reinterpret_cast<const char*>(out.data()), std::streamsize(out.size()));
}

// The nodes below (and including) `roots`, read from the raw JSON.
std::set<int> subtree(const nlohmann::json& nodes, const std::vector<int>& roots) {
  std::set<int> out;
  std::vector<int> stack = roots;
  while (!stack.empty()) {
    const int n = stack.back();
    stack.pop_back();
    if (!out.insert(n).second) continue;
    for (const auto& c : nodes[size_t(n)].value("children", nlohmann::json::array())) stack.push_back(c.get<int>());
  }
  return out;
}

// The spring roots of the VRM 0.x file, and the node of each humanoid bone.
std::vector<int> spring_roots(const nlohmann::json& json) {
  std::vector<int> roots;
  for (const auto& group : json["extensions"]["VRM"]["secondaryAnimation"]["boneGroups"])
    for (const auto& bone : group["bones"]) roots.push_back(bone.get<int>());
  return roots;
}

std::map<std::string, int> human_bones(const nlohmann::json& json) {
  std::map<std::string, int> out;
  for (const auto& h : json["extensions"]["VRM"]["humanoid"]["humanBones"])
    out[h["bone"].get<std::string>()] = h["node"].get<int>();
  return out;
}

// Checks the character loaded from an edit of Godette against the raw file: mapping, turn, spring apparel.
void expect_godette(const RuntimeCharacter& c, const Glb& raw, const std::set<int>& spring_nodes) {
  const GltfAsset asset = read_gltf(kGodette);
  const GltfCharacter g = gltf_character(asset);
  // Mapped by the humanoid map: the bones the map names, each as "joint map" (no naming convention involved).
  const std::map<std::string, int> bones = human_bones(read_glb(kGodette).json);
  const std::vector<std::pair<std::string, int>> expected = {{"hips", kPelvis},
                                                             {"leftUpperLeg", kLeftHip},
                                                             {"rightLowerLeg", kRightKnee},
                                                             {"leftFoot", kLeftAnkle},
                                                             {"rightToes", kRightFoot},
                                                             {"neck", kNeck},
                                                             {"head", kHead},
                                                             {"leftShoulder", kLeftCollar},
                                                             {"rightUpperArm", kRightShoulder},
                                                             {"leftLowerArm", kLeftElbow},
                                                             {"rightHand", kRightWrist}};
  for (const auto& [bone, joint] : expected) {
    const int source = c.rest.mapping.source_joint[size_t(joint)];
    EXPECT_EQ(c.file_skeleton.names[size_t(source)], raw.json["nodes"][size_t(bones.at(bone))]["name"]) << bone;
    EXPECT_EQ(c.rest.mapping.kind[size_t(joint)], JointMatchKind::kUserMap) << bone;
  }
  // The spine from the structure: spine3 is the chest, the common ancestor of the neck and the collars.
  EXPECT_EQ(c.file_skeleton.names[size_t(c.rest.mapping.source_joint[kSpine3])],
            raw.json["nodes"][size_t(bones.at("chest"))]["name"]);
  // Turned half a turn about Y: x and z negated, exactly; the left hip on +X, the toes ahead of the ankles (+Z).
  EXPECT_TRUE(c.turned);
  ASSERT_EQ(c.mesh.V.rows(), g.mesh.V.rows());
  EXPECT_EQ(c.mesh.V.col(0), (-g.mesh.V.col(0)).eval());
  EXPECT_EQ(c.mesh.V.col(1), g.mesh.V.col(1));
  EXPECT_EQ(c.mesh.V.col(2), (-g.mesh.V.col(2)).eval());
  EXPECT_GT(c.skeleton.rest_joints(kLeftHip, 0), 0.05f);
  EXPECT_LT(c.skeleton.rest_joints(kRightHip, 0), -0.05f);
  EXPECT_GT(c.skeleton.rest_joints(kLeftFoot, 2), c.skeleton.rest_joints(kLeftAnkle, 2) + 0.03f);
  // The apparel: the vertices with weight on a joint below a spring root, exactly.
  ASSERT_EQ(c.rig_apparel_mask.size(), size_t(g.mesh.num_vertices()));
  int expected_count = 0;
  for (int i = 0; i < g.weights.num_vertices(); ++i) {
    bool on_spring = false;
    for (int k = 0; k < kMaxInfluences; ++k) {
      const int j = g.weights.indices(i, k);
      on_spring |= g.weights.weights(i, k) > 0.0f && spring_nodes.count(g.joint_nodes[size_t(j)]) > 0;
    }
    EXPECT_EQ(c.rig_apparel_mask[size_t(i)], on_spring ? 1 : 0) << "vertex " << i;
    expected_count += on_spring;
  }
  EXPECT_GT(expected_count, 100);
  EXPECT_LT(expected_count, g.mesh.num_vertices() / 10);
  ASSERT_NE(c.rig_bones, nullptr);
  EXPECT_NE(c.rig_apparel.find("spring bones"), std::string::npos) << c.rig_apparel;
  // The springs' physics response (spring_response), measured on request: every bone of the rig has a row, the
  // simulated ones (the spring joints and what hangs below them) are flagged, and they swing off rigid skinning under
  // the probe, within the cap.
  EXPECT_EQ(c.rig_bones->response.rows(), 0);  // measured only when asked for
  ASSERT_TRUE(c.rig_bones_with_response);
  const std::shared_ptr<const ApparelBones> measured = c.rig_bones_with_response();
  const MatrixXfR& r = measured->response;
  ASSERT_EQ(r.rows(), c.rig_bones->num_bones());
  int simulated = 0;
  for (Eigen::Index b = 0; b < r.rows(); ++b) {
    simulated += r(b, 0) == 1.0f;
    EXPECT_LE(r.row(b).maxCoeff(), 4.0f);
  }
  EXPECT_GT(simulated, 0);
  EXPECT_GT(r.col(1).maxCoeff(), 0.01f);
}

TEST(VrmAvatar, AVrm0AvatarMapsByItsHumanoidTurnsToFacePlusZAndItsSpringBonesAreItsApparel) {
  const Glb raw = read_glb(kGodette);
  ASSERT_TRUE(raw.json["extensions"].contains("VRM"));
  const RuntimeCharacter c = load_character({kGodette, "", ""});
  EXPECT_EQ(c.file_kind, "VRM 0.x");
  expect_godette(c, raw, subtree(raw.json["nodes"], spring_roots(raw.json)));
  // Its 3 spring groups: the front hair, the ribbon (with its end joint) and the hair balls.
  std::set<std::string> names;
  for (int n : subtree(raw.json["nodes"], spring_roots(raw.json)))
    names.insert(raw.json["nodes"][size_t(n)]["name"].get<std::string>());
  EXPECT_TRUE(names.count("Ribbon") && names.count("Ribbon_end") && names.count("HairBall_L") &&
              names.count("FrontHair_L"));
}

TEST(VrmAvatar, AVrm1AvatarWithNamesNoConventionKnowsMapsThroughVrmcVrm) {
  Glb raw = read_glb(kGodette);
  const std::map<std::string, int> bones = human_bones(raw.json);
  const std::vector<int> roots = spring_roots(raw.json);
  // VRM 1.0: humanBones as {bone: {node}}, springs listing every joint; nodes renamed "n<i>".
  nlohmann::json human = nlohmann::json::object();
  for (const auto& [bone, node] : bones) human[bone] = {{"node", node}};
  nlohmann::json springs = nlohmann::json::array();
  for (int r : roots) {
    nlohmann::json joints = nlohmann::json::array();
    for (int n = r;;) {
      joints.push_back({{"node", n}});
      const auto children = raw.json["nodes"][size_t(n)].value("children", nlohmann::json::array());
      if (children.empty()) break;
      n = children[0].get<int>();
    }
    springs.push_back({{"joints", joints}});
  }
  raw.json["extensions"].erase("VRM");
  raw.json["extensions"]["VRMC_vrm"] = {{"specVersion", "1.0"}, {"humanoid", {{"humanBones", human}}}};
  raw.json["extensions"]["VRMC_springBone"] = {{"specVersion", "1.0"}, {"springs", springs}};
  raw.json["extensionsUsed"] = {"VRMC_vrm", "VRMC_springBone"};
  for (size_t n = 0; n < raw.json["nodes"].size(); ++n) raw.json["nodes"][n]["name"] = "n" + std::to_string(n);
  const std::string path = (test::temp_dir("vrm1") / "avatar.vrm").string();
  write_glb(raw, path);
  // Without the humanoid map nothing would match these names.
  Glb plain = raw;
  plain.json["extensions"].erase("VRMC_vrm");
  const std::string plain_path = (test::temp_dir("vrm1_plain") / "avatar.glb").string();
  write_glb(plain, plain_path);
  EXPECT_NE(test::error_of([&] {
              load_character({plain_path, "", ""});
            }).find("could not match canonical joints"),
            std::string::npos);

  const RuntimeCharacter c = load_character({path, "", ""});
  EXPECT_EQ(c.file_kind, "VRM 1.0");
  expect_godette(c, raw, subtree(raw.json["nodes"], roots));
}

TEST(VrmAvatar, MalformedHumanoidMapsAreOneLineErrorsNamingTheField) {
  const auto error_for = [](const std::function<void(nlohmann::json&)>& edit, const std::string& name) {
    Glb raw = read_glb(kGodette);
    edit(raw.json);
    const std::string path = (test::temp_dir("vrm_bad") / name).string();
    write_glb(raw, path);
    return test::error_of([&] { load_character({path, "", ""}); });
  };
  const size_t nodes = read_glb(kGodette).json["nodes"].size();
  std::string e = error_for(
      [](nlohmann::json& j) { j["extensions"]["VRM"]["humanoid"]["humanBones"][2]["node"] = 99999; }, "far.vrm");
  EXPECT_NE(e.find("far.vrm: extensions.VRM.humanoid.humanBones[2].node: expected a node index in [0, " +
                   std::to_string(nodes) + "), found 99999"),
            std::string::npos)
      << e;
  e = error_for([](nlohmann::json& j) { j["extensions"]["VRM"]["humanoid"]["humanBones"][0]["node"] = "hips"; },
                "text.vrm");
  EXPECT_NE(e.find("humanBones[0].node: expected a node index, found a string"), std::string::npos) << e;
  e = error_for([](nlohmann::json& j) { j["extensions"]["VRM"]["humanoid"]["humanBones"] = 3; }, "shape.vrm");
  EXPECT_NE(e.find("extensions.VRM.humanoid.humanBones: expected an array of {bone, node}"), std::string::npos) << e;
  e = error_for(
      [](nlohmann::json& j) { j["extensions"]["VRM"]["secondaryAnimation"]["boneGroups"][1]["bones"][0] = -4; },
      "spring.vrm");
  EXPECT_NE(e.find("extensions.VRM.secondaryAnimation.boneGroups[1].bones[0]: expected a node index in [0, "),
            std::string::npos)
      << e;
  EXPECT_EQ(e.find('\n'), std::string::npos);
}

// The joint of `character` on node n, or -1.
int joint_on(const GltfCharacter& character, int n) {
  for (size_t j = 0; j < character.joint_nodes.size(); ++j)
    if (character.joint_nodes[j] == n) return int(j);
  return -1;
}

TEST(VrmAvatar, Vrm0SpringBonesAreEveryNodeUnderTheirRootsWithTheirGroupsParametersAndMirroredColliders) {
  const Glb raw = read_glb(kGodette);
  const nlohmann::json& secondary = raw.json["extensions"]["VRM"]["secondaryAnimation"];
  const nlohmann::json& nodes = raw.json["nodes"];
  const GltfAsset asset = read_gltf(kGodette);
  const GltfCharacter g = gltf_character(asset);
  const SpringRig rig = gltf_vrm_spring_rig(asset, g);
  size_t expected = 0;
  for (size_t group = 0; group < secondary["boneGroups"].size(); ++group) {
    const nlohmann::json& bg = secondary["boneGroups"][group];
    for (const int n : subtree(nodes, bg["bones"].get<std::vector<int>>())) {
      const int j = joint_on(g, n);
      if (j < 0) continue;
      ++expected;
      const auto it =
          std::find_if(rig.joints.begin(), rig.joints.end(), [&](const SpringJoint& s) { return s.joint == j; });
      ASSERT_NE(it, rig.joints.end()) << "node " << n;
      EXPECT_EQ(it->spring, int(group));
      EXPECT_FLOAT_EQ(it->stiffness, bg["stiffiness"].get<float>());
      EXPECT_FLOAT_EQ(it->drag, bg["dragForce"].get<float>());
      EXPECT_FLOAT_EQ(it->hit_radius, bg["hitRadius"].get<float>());
      EXPECT_FLOAT_EQ(it->gravity_power, bg["gravityPower"].get<float>());
      const Eigen::Vector3f head = g.skeleton.rest_joints.row(j).transpose();
      const auto children = nodes[size_t(n)].value("children", nlohmann::json::array());
      if (!children.empty()) {  // the tail is the first child
        const int c = joint_on(g, children[0].get<int>());
        ASSERT_GE(c, 0);
        EXPECT_LT((it->tail - g.skeleton.rest_joints.row(c).transpose()).norm(), 1e-6f) << "node " << n;
      } else {  // 7 cm on along the bone from its parent
        const Eigen::Vector3f parent = g.skeleton.rest_joints.row(g.skeleton.parents[size_t(j)]).transpose();
        EXPECT_LT((it->tail - (head + 0.07f * (head - parent).normalized())).norm(), 1e-6f) << "node " << n;
      }
    }
  }
  EXPECT_EQ(size_t(rig.num_joints()), expected);
  EXPECT_GE(rig.num_joints(), 10);
  // Colliders: both groups' spheres, on their nodes' joints, with z mirrored; each spring sees its groups' only.
  ASSERT_EQ(rig.colliders.size(), 4u);
  const nlohmann::json& first = secondary["colliderGroups"][0];
  const int j3 = joint_on(g, first["node"].get<int>());
  ASSERT_GE(j3, 0);
  const nlohmann::json& offset = first["colliders"][1]["offset"];
  const Eigen::Vector3f expected_centre =
      g.skeleton.rest_joints.row(j3).transpose() +
      Eigen::Vector3f(offset["x"].get<float>(), offset["y"].get<float>(), -offset["z"].get<float>());
  EXPECT_EQ(rig.colliders[1].joint, j3);
  EXPECT_LT((rig.colliders[1].center - expected_centre).norm(), 1e-5f);
  EXPECT_FLOAT_EQ(rig.colliders[1].radius, first["colliders"][1]["radius"].get<float>());
  EXPECT_EQ(rig.spring_colliders, (std::vector<std::vector<int>>{{2, 3}, {0, 1}, {}}));
  EXPECT_TRUE(rig.notes.empty());
}

// Godette rewritten as VRM 1.0 with per-joint parameters, a sphere and a capsule collider and a centre node.
Glb godette_vrm1(const std::function<void(nlohmann::json& spring_bone)>& edit = {}) {
  Glb raw = read_glb(kGodette);
  nlohmann::json springs = nlohmann::json::array();
  float stiffness = 1.0f;
  for (const int r : spring_roots(raw.json)) {
    nlohmann::json joints = nlohmann::json::array();
    for (int n = r;;) {
      joints.push_back({{"node", n},
                        {"stiffness", stiffness},
                        {"dragForce", 0.25},
                        {"gravityPower", 0.5},
                        {"gravityDir", {1.0, 0.0, 0.0}},
                        {"hitRadius", 0.01}});
      stiffness += 0.5f;
      const auto children = raw.json["nodes"][size_t(n)].value("children", nlohmann::json::array());
      if (children.empty()) break;
      n = children[0].get<int>();
    }
    springs.push_back({{"joints", joints}, {"colliderGroups", {0}}});
  }
  springs[0]["center"] = 3;
  nlohmann::json colliders = {
      {{"node", 5}, {"shape", {{"sphere", {{"offset", {0.0, 0.1, 0.2}}, {"radius", 0.15}}}}}},
      {{"node", 5},
       {"shape", {{"capsule", {{"offset", {0.0, 0.0, 0.0}}, {"radius", 0.05}, {"tail", {0.0, 0.3, 0.0}}}}}}}};
  raw.json["extensions"]["VRMC_springBone"] = {{"specVersion", "1.0"},
                                               {"colliders", colliders},
                                               {"colliderGroups", {{{"colliders", {0, 1}}}}},
                                               {"springs", springs}};
  nlohmann::json human = nlohmann::json::object();
  for (const auto& [bone, node] : human_bones(raw.json)) human[bone] = {{"node", node}};
  raw.json["extensions"].erase("VRM");
  raw.json["extensions"]["VRMC_vrm"] = {{"specVersion", "1.0"}, {"humanoid", {{"humanBones", human}}}};
  raw.json["extensionsUsed"] = {"VRMC_vrm", "VRMC_springBone"};
  if (edit) edit(raw.json["extensions"]["VRMC_springBone"]);
  return raw;
}

TEST(VrmAvatar, Vrm1SpringsAreSegmentsFromEachJointToTheNextWithTheJointsOwnParameters) {
  const Glb raw = godette_vrm1();
  const std::string path = (test::temp_dir("vrm1_springs") / "avatar.vrm").string();
  write_glb(raw, path);
  const GltfAsset asset = read_gltf(path);
  const GltfCharacter g = gltf_character(asset);
  const SpringRig rig = gltf_vrm_spring_rig(asset, g);
  int expected = 0;
  for (const auto& spring : raw.json["extensions"]["VRMC_springBone"]["springs"]) {
    const auto& joints = spring["joints"];
    for (size_t k = 0; k + 1 < joints.size(); ++k) {
      const int j = joint_on(g, joints[k]["node"].get<int>()), next = joint_on(g, joints[k + 1]["node"].get<int>());
      ASSERT_GE(j, 0);
      ++expected;
      const auto it =
          std::find_if(rig.joints.begin(), rig.joints.end(), [&](const SpringJoint& s) { return s.joint == j; });
      ASSERT_NE(it, rig.joints.end());
      EXPECT_FLOAT_EQ(it->stiffness, joints[k]["stiffness"].get<float>());
      EXPECT_FLOAT_EQ(it->drag, 0.25f);
      EXPECT_FLOAT_EQ(it->gravity_power, 0.5f);
      EXPECT_EQ(it->gravity_dir, Eigen::Vector3f(1.0f, 0.0f, 0.0f));
      EXPECT_FLOAT_EQ(it->hit_radius, 0.01f);
      EXPECT_LT((it->tail - g.skeleton.rest_joints.row(next).transpose()).norm(), 1e-6f);
    }
    // The last joint of a spring has no segment of its own.
    const int last = joint_on(g, joints.back()["node"].get<int>());
    EXPECT_TRUE(
        std::none_of(rig.joints.begin(), rig.joints.end(), [&](const SpringJoint& s) { return s.joint == last; }));
  }
  EXPECT_EQ(rig.num_joints(), expected);
  // A sphere 0.1 up and 0.2 on from node 5 (no VRM 0.x mirroring), and a capsule 0.3 long.
  ASSERT_EQ(rig.colliders.size(), 2u);
  const Eigen::Vector3f at5 = g.skeleton.rest_joints.row(joint_on(g, 5)).transpose();
  EXPECT_LT((rig.colliders[0].center - (at5 + Eigen::Vector3f(0.0f, 0.1f, 0.2f))).norm(), 1e-5f);
  EXPECT_FALSE(rig.colliders[0].capsule);
  EXPECT_TRUE(rig.colliders[1].capsule);
  EXPECT_LT((rig.colliders[1].tail - (at5 + Eigen::Vector3f(0.0f, 0.3f, 0.0f))).norm(), 1e-5f);
  EXPECT_EQ(rig.notes, (std::vector<std::string>{"1 spring(s) name a centre node: simulated in world space instead"}));
}

TEST(VrmAvatar, MalformedSpringBonesAreOneLineErrorsNamingTheField) {
  const auto error_for = [](const std::function<void(nlohmann::json&)>& edit, const std::string& name) {
    const std::string path = (test::temp_dir("vrm_bad_springs") / name).string();
    write_glb(godette_vrm1(edit), path);
    const GltfAsset asset = read_gltf(path);
    return test::error_of([&] { gltf_vrm_spring_rig(asset, gltf_character(asset)); });
  };
  EXPECT_EQ(
      error_for([](nlohmann::json& e) { e["springs"][0]["joints"][0]["gravityPower"] = "strong"; }, "text.vrm"),
      (test::temp_dir("vrm_bad_springs") / "text.vrm").string() +
          ": extensions.VRMC_springBone.springs[0].joints[0].gravityPower: expected a number, found another type");
  std::string e = error_for([](nlohmann::json& e) { e["springs"][1]["joints"][0]["dragForce"] = 3; }, "drag.vrm");
  EXPECT_NE(e.find("drag.vrm: spring bone "), std::string::npos) << e;
  EXPECT_NE(e.find("dragForce: expected a value in [0, 1], found 3"), std::string::npos) << e;
  e = error_for([](nlohmann::json& e) { e["springs"][0]["colliderGroups"] = {4}; }, "group.vrm");
  EXPECT_NE(e.find("springs[0].colliderGroups[0]: expected a collider group index in [0, 1)"), std::string::npos) << e;
  e = error_for([](nlohmann::json& e) { e["colliders"][0]["shape"]["sphere"]["radius"] = -1; }, "radius.vrm");
  EXPECT_NE(e.find("colliders[0].shape.sphere.radius: expected [0, 100) metres, found -1"), std::string::npos) << e;
  e = error_for([](nlohmann::json& e) { e["springs"][0]["joints"][1]["node"] = 100000; }, "node.vrm");
  EXPECT_NE(e.find("springs[0].joints[1].node: expected a node index in [0, "), std::string::npos) << e;
  for (const std::string& message : {e}) EXPECT_EQ(message.find('\n'), std::string::npos);
}

// Apparel vertex positions of `amt animate --apparel spring-bones` on Godette with CMU 05_01 at `fps`.
std::vector<MatrixX3f> spring_run(const std::filesystem::path& dir, int fps, int frames) {
  const std::string out = "springs_" + std::to_string(fps) + ".h5";
  const test::CommandResult run = test::run_command(
      "cd '" + dir.string() + "' && " +
      test::shell_command(AMT_BINARY, {"animate", "--character", kGodette, "--motion",
                                       std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh", "--apparel", "spring-bones",
                                       "--fps", std::to_string(fps), "--frames", std::to_string(frames), "--out", out,
                                       "--threads", "1", "--quiet"}));
  EXPECT_EQ(run.status, 0) << run.err;
  std::vector<MatrixX3f> V;
  if (run.status != 0) return V;
  const DatasetReader reader((dir / out).string());
  for (int t = 0; t < frames; ++t) V.push_back(reader.read_vertices(reader.clip_names().at(0), t, 1));
  return V;
}

TEST(VrmAvatar, SpringBonesMoveTheHairTheSameWayAt30And60Fps) {
  const std::filesystem::path dir = test::temp_dir("vrm_spring_fps");
  const std::vector<MatrixX3f> a = spring_run(dir, 30, 45), b = spring_run(dir, 60, 90);
  ASSERT_EQ(a.size(), 45u);
  ASSERT_EQ(b.size(), 90u);
  const RuntimeCharacter c = load_character({kGodette, "", ""});
  double between = 0.0, moved = 0.0;
  int count = 0;
  for (int t = 0; t < 45; ++t) {
    for (int i = 0; i < c.mesh.num_vertices(); ++i) {
      if (!c.rig_apparel_mask[size_t(i)]) continue;
      between += (a[size_t(t)].row(i) - b[size_t(2 * t)].row(i)).norm();
      if (t > 0) moved += (a[size_t(t)].row(i) - a[size_t(t - 1)].row(i)).norm();
      ++count;
    }
  }
  between /= count, moved /= count;
  std::cout << "apparel: mean " << 100.0 * between << " cm apart between the 30 and 60 fps runs, moving "
            << 100.0 * moved << " cm a frame\n";
  // The hair moves with the walk (centimetres a frame) and the two rates agree to well under the 0.5 cm target.
  EXPECT_GT(moved, 0.001);
  EXPECT_LT(between, 0.002) << "mean apparel distance between the 30 and 60 fps runs, metres";
}

// Godette under frames [0, frames) of CMU 05_01 at 30 fps, skinned by the file's own weights, computed from the
// public pieces: the canonical joint transforms of the motion on the character, their skinning transforms, each file
// joint carried by its canonical joint, the file's weights.
std::vector<MatrixX3f> godette_file_skinning(const RuntimeCharacter& c, int frames) {
  MotionSpec spec;
  spec.spec = std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh";
  PlaybackOptions playback;
  playback.fps = 30.0f;
  const MotionPlayer player(load_motion(spec), c, playback);
  std::vector<MatrixX3f> out(static_cast<size_t>(frames));
  for (int t = 0; t < frames; ++t) {
    const Transforms M = skinning_matrices(c.skeleton, player.frame(t));
    Transforms file(c.rest.carrier.size());
    for (size_t b = 0; b < file.size(); ++b) file[b] = M.at(size_t(c.rest.carrier[b]));
    linear_blend_skinning(c.mesh.V, c.file_weights, file, out[size_t(t)]);
  }
  return out;
}

// Every vertex the springs do not move is the file's own skinning under the motion, computed here from the public
// pieces: the canonical joint transforms of the motion on the character, their skinning transforms, each file joint
// carried by its canonical joint, the file's weights. (A pose handed to the springs as joint transforms instead of
// skinning transforms moves each vertex by its joint's rest position: the head by a metre.)
TEST(VrmAvatar, SpringBonesLeaveTheBodyToTheFilesOwnSkinning) {
  const std::filesystem::path dir = test::temp_dir("vrm_spring_body");
  const std::vector<MatrixX3f> out = spring_run(dir, 30, 12);
  ASSERT_EQ(out.size(), 12u);
  const RuntimeCharacter c = load_character({kGodette, "", ""});
  const std::vector<MatrixX3f> skinned = godette_file_skinning(c, 12);
  double worst = 0.0, apparel_moved = 0.0;
  int apparel = 0;
  for (int t = 0; t < 12; ++t) {
    const MatrixX3f& expected = skinned[size_t(t)];
    for (int i = 0; i < c.mesh.num_vertices(); ++i) {
      const double d = (out[size_t(t)].row(i) - expected.row(i)).norm();
      if (c.rig_apparel_mask[size_t(i)]) {
        apparel_moved += d, ++apparel;
      } else {
        worst = std::max(worst, d);
      }
    }
  }
  EXPECT_LT(worst, 1e-5) << "metres: a vertex the springs do not move, against the file's skinning";
  ASSERT_GT(apparel, 0);
  EXPECT_GT(apparel_moved / apparel, 1e-3) << "the spring-driven vertices move away from rigid skinning";
  EXPECT_LT(apparel_moved / apparel, 0.2) << "... by centimetres, not by a body's height";
}

// The learned path skins the body with the avatar's own weights by default (the file has a skin): every vertex the
// output's apparel mask leaves to the body is the file's own skinning under the motion, as on the spring path. With
// --skin-weights model the skinning predictor's weights move it differently.
TEST(VrmAvatar, TheLearnedPathSkinsTheBodyWithTheAvatarsOwnWeights) {
  const std::filesystem::path dir = test::temp_dir("vrm_own_weights");
  const std::string model = std::filesystem::path(AMT_ASSET_DIR).parent_path().string() + "/models/pretrained";
  const auto run = [&](const std::string& weights, const std::string& out) {
    return test::run_command("cd '" + dir.string() + "' && " +
                             test::shell_command(AMT_BINARY, {"animate", "--character", kGodette, "--motion",
                                                              std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh",
                                                              "--model", model, "--skin-weights", weights, "--frames",
                                                              "6", "--out", out, "--bind", "none", "--threads", "1"}));
  };
  const test::CommandResult own = run("auto", "own.h5"), predicted = run("model", "predicted.h5");
  ASSERT_EQ(own.status, 0) << own.err;
  ASSERT_EQ(predicted.status, 0) << predicted.err;
  EXPECT_NE(own.out.find("skinning weights: the character's own skin ("), std::string::npos) << own.out;
  EXPECT_NE(own.out.find("--skin-weights auto: the file has one)"), std::string::npos) << own.out;
  EXPECT_NE(predicted.out.find("skinning weights: the skinning predictor\n"), std::string::npos) << predicted.out;

  const RuntimeCharacter c = load_character({kGodette, "", ""});
  const std::vector<MatrixX3f> skinned = godette_file_skinning(c, 6);
  const DatasetReader a((dir / "own.h5").string()), b((dir / "predicted.h5").string());
  const std::vector<uint8_t> mask = a.read_character(a.clip_info(a.clip_names()[0]).character).apparel_mask;
  double worst_own = 0.0, mean_predicted = 0.0;
  int body = 0;
  for (int t = 0; t < 6; ++t) {
    const MatrixX3f& expected = skinned[size_t(t)];
    const MatrixX3f Va = a.read_vertices(a.clip_names()[0], t, 1), Vb = b.read_vertices(b.clip_names()[0], t, 1);
    for (int i = 0; i < c.mesh.num_vertices(); ++i) {
      if (mask[size_t(i)]) continue;
      worst_own = std::max(worst_own, double((Va.row(i) - expected.row(i)).norm()));
      mean_predicted += (Vb.row(i) - expected.row(i)).norm();
      ++body;
    }
  }
  ASSERT_GT(body, 0);
  std::cout << "body: own weights at most " << 100 * worst_own << " cm from the file's skinning, predicted weights "
            << 100 * mean_predicted / body << " cm on average\n";
  EXPECT_LT(worst_own, 1e-4) << "metres";
  EXPECT_GT(mean_predicted / body, 1e-3) << "metres: the predicted weights are not the file's";
}

TEST(VrmAvatar, SpringBonesOnACharacterWithoutThemIsAOneLineError) {
  const std::filesystem::path dir = test::temp_dir("vrm_spring_none");
  const test::CommandResult run =
      test::run_command("cd '" + dir.string() + "' && " +
                        test::shell_command(AMT_BINARY, {"animate", "--character", "generated:3", "--motion",
                                                         std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh",
                                                         "--apparel", "spring-bones", "--out", "g.glb", "--quiet"}));
  EXPECT_NE(run.status, 0);
  EXPECT_NE(run.err.find("generated:3: --apparel spring-bones: expected a VRM avatar with spring bones"),
            std::string::npos)
      << run.err;
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "g.glb"));
}

}  // namespace
}  // namespace amt
