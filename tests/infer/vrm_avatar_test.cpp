// VRM avatars: the committed artist-made avatar data/characters/Godette.vrm (VRM 0.x, CC-BY) is mapped by its
// humanoid bone map without a joint map, turned to face +Z, and its spring bones name its apparel; the same avatar
// rewritten as VRM 1.0 with renamed nodes (no naming convention can match them) maps through VRMC_vrm and
// VRMC_springBone; malformed maps are one-line errors naming the field.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>

#include "data_tools/formats/gltf_import.h"
#include "data_tools/geometry/error.h"
#include "infer/character_input.h"
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
  const std::vector<std::pair<std::string, int>> expected = {
      {"hips", kPelvis},          {"leftUpperLeg", kLeftHip},    {"rightLowerLeg", kRightKnee},
      {"leftFoot", kLeftAnkle},   {"rightToes", kRightFoot},     {"neck", kNeck},
      {"head", kHead},            {"leftShoulder", kLeftCollar}, {"rightUpperArm", kRightShoulder},
      {"leftLowerArm", kLeftElbow}, {"rightHand", kRightWrist}};
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
  EXPECT_NE(test::error_of([&] { load_character({plain_path, "", ""}); }).find("could not match canonical joints"),
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
  std::string e = error_for([](nlohmann::json& j) { j["extensions"]["VRM"]["humanoid"]["humanBones"][2]["node"] = 99999; },
                            "far.vrm");
  EXPECT_NE(e.find("far.vrm: extensions.VRM.humanoid.humanBones[2].node: expected a node index in [0, " +
                   std::to_string(nodes) + "), found 99999"),
            std::string::npos)
      << e;
  e = error_for([](nlohmann::json& j) { j["extensions"]["VRM"]["humanoid"]["humanBones"][0]["node"] = "hips"; },
                "text.vrm");
  EXPECT_NE(e.find("humanBones[0].node: expected a node index, found a string"), std::string::npos) << e;
  e = error_for([](nlohmann::json& j) { j["extensions"]["VRM"]["humanoid"]["humanBones"] = 3; }, "shape.vrm");
  EXPECT_NE(e.find("extensions.VRM.humanoid.humanBones: expected an array of {bone, node}"), std::string::npos) << e;
  e = error_for([](nlohmann::json& j) { j["extensions"]["VRM"]["secondaryAnimation"]["boneGroups"][1]["bones"][0] = -4; },
                "spring.vrm");
  EXPECT_NE(e.find("extensions.VRM.secondaryAnimation.boneGroups[1].bones[0]: expected a node index in [0, "),
            std::string::npos)
      << e;
  EXPECT_EQ(e.find('\n'), std::string::npos);
}

}  // namespace
}  // namespace amt
