// glTF import: the Khronos Fox (structure, skin weights, clip lengths, and joint positions at a
// keyframe checked against the file's node graph evaluated here by hand from the raw GLB chunks),
// small assets written in the test (every JOINTS / WEIGHTS component type, joint reordering, several
// root joints, sparse accessors, external buffers, STEP / LINEAR / CUBICSPLINE interpolation, the
// rest-frame rotation conversion, animated scale), and bad input (one-line errors naming the field).
#include "tests/test_support.h"
#include "data_tools/formats/gltf_import.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/motion.h"

namespace amt {
namespace {

using test::error_of;
using test::temp_dir;

const std::string kFox = std::string(AMT_ASSET_DIR) + "/characters/Fox.glb";

std::vector<uint8_t> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void write_bytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// === A minimal GLB reader and node-graph evaluator, independent of the importer

struct RawGlb {
  nlohmann::json json;
  std::vector<uint8_t> bin;
};

RawGlb read_raw_glb(const std::string& path) {
  const std::vector<uint8_t> bytes = read_bytes(path);
  auto u32 = [&](size_t at) {
    uint32_t v;
    std::memcpy(&v, &bytes[at], 4);
    return v;
  };
  RawGlb glb;
  const uint32_t json_length = u32(12);
  glb.json = nlohmann::json::parse(bytes.begin() + 20, bytes.begin() + 20 + json_length);
  const size_t bin_at = 20 + json_length;
  glb.bin.assign(bytes.begin() + long(bin_at) + 8, bytes.begin() + long(bin_at) + 8 + u32(bin_at));
  return glb;
}

// Element e of a FLOAT accessor (components values).
std::vector<double> raw_element(const RawGlb& glb, int accessor, size_t e) {
  const nlohmann::json& acc = glb.json["accessors"][size_t(accessor)];
  const nlohmann::json& view = glb.json["bufferViews"][acc["bufferView"].get<size_t>()];
  const std::map<std::string, int> widths = {{"SCALAR", 1}, {"VEC3", 3}, {"VEC4", 4}, {"MAT4", 16}};
  const int n = widths.at(acc["type"].get<std::string>());
  const size_t stride = view.value("byteStride", size_t(4 * n));
  const size_t at = view.value("byteOffset", size_t(0)) + acc.value("byteOffset", size_t(0)) + e * stride;
  std::vector<double> out(static_cast<size_t>(n));
  for (int c = 0; c < n; ++c) {
    float v;
    std::memcpy(&v, &glb.bin[at + 4 * size_t(c)], 4);
    out[size_t(c)] = v;
  }
  return out;
}

// Global position of every node at keyframe `key` of animation `clip` (the rest pose for clip < 0),
// composing T * R * S down each node's parent chain.
std::vector<Eigen::Vector3d> raw_node_positions(const RawGlb& glb, int clip, size_t key) {
  const nlohmann::json& nodes = glb.json["nodes"];
  std::vector<Eigen::Vector3d> t(nodes.size(), Eigen::Vector3d::Zero()), s(nodes.size(), Eigen::Vector3d::Ones());
  std::vector<Eigen::Quaterniond> r(nodes.size(), Eigen::Quaterniond::Identity());
  std::vector<int> parent(nodes.size(), -1);
  for (size_t n = 0; n < nodes.size(); ++n) {
    const auto& node = nodes[n];
    auto vec3 = [&](const char* key) {
      return Eigen::Vector3d(node[key][0].get<double>(), node[key][1].get<double>(), node[key][2].get<double>());
    };
    if (node.contains("translation")) t[n] = vec3("translation");
    if (node.contains("rotation")) {
      const auto& q = node["rotation"];
      r[n] = Eigen::Quaterniond(q[3].get<double>(), q[0].get<double>(), q[1].get<double>(), q[2].get<double>());
    }
    if (node.contains("scale")) s[n] = vec3("scale");
    for (int c : node.value("children", std::vector<int>())) parent[size_t(c)] = int(n);
  }
  if (clip >= 0) {
    const nlohmann::json& anim = glb.json["animations"][size_t(clip)];
    for (const auto& channel : anim["channels"]) {
      const auto& sampler = anim["samplers"][channel["sampler"].get<size_t>()];
      const std::vector<double> v = raw_element(glb, sampler["output"], key);
      const size_t n = channel["target"]["node"];
      const std::string path = channel["target"]["path"];
      if (path == "translation") t[n] = Eigen::Vector3d(v[0], v[1], v[2]);
      if (path == "rotation") r[n] = Eigen::Quaterniond(v[3], v[0], v[1], v[2]);
      if (path == "scale") s[n] = Eigen::Vector3d(v[0], v[1], v[2]);
    }
  }
  std::vector<Eigen::Vector3d> positions(nodes.size());
  for (size_t n = 0; n < nodes.size(); ++n) {
    Eigen::Affine3d world = Eigen::Affine3d::Identity();
    for (int m = int(n); m >= 0; m = parent[size_t(m)]) {
      const Eigen::Affine3d local =
          Eigen::Translation3d(t[size_t(m)]) * r[size_t(m)].normalized() * Eigen::Scaling(s[size_t(m)]);
      world = local * world;
    }
    positions[n] = world.translation();
  }
  return positions;
}

int raw_clip_index(const RawGlb& glb, const std::string& name) {
  for (size_t i = 0; i < glb.json["animations"].size(); ++i) {
    if (glb.json["animations"][i]["name"] == name) return int(i);
  }
  return -1;
}

// === The Fox

TEST(GltfImport, FoxCharacterStructure) {
  const GltfAsset asset = read_gltf(kFox);
  const GltfCharacter fox = gltf_character(asset);
  EXPECT_EQ(fox.skeleton.num_joints(), 24);
  EXPECT_EQ(fox.mesh.num_vertices(), 1728);
  EXPECT_EQ(fox.mesh.num_faces(), 576);  // no indices: sequential triangles
  EXPECT_EQ(fox.skin, 0);
  EXPECT_EQ(fox.skeleton.names[0], "_rootJoint");
  EXPECT_EQ(fox.skeleton.parents[0], -1);
  EXPECT_EQ(fox.skeleton.index_of("b_Head_05") >= 0, true);
  // The skin lists its joints parents first, so the order is the file's.
  for (int k = 0; k < 24; ++k) EXPECT_EQ(fox.skin_joint_to_joint[size_t(k)], k);
  ASSERT_EQ(fox.weights.num_vertices(), 1728);
  for (int i = 0; i < 1728; ++i) {
    EXPECT_NEAR(fox.weights.weights.row(i).sum(), 1.0f, 1e-6f) << "vertex " << i;
    for (int s = 0; s < kMaxInfluences; ++s) {
      EXPECT_GE(fox.weights.weights(i, s), 0.0f);
      EXPECT_TRUE(fox.weights.indices(i, s) >= 0 && fox.weights.indices(i, s) < 24);
    }
  }
}

TEST(GltfImport, FoxRestPoseMatchesTheFile) {
  const RawGlb raw = read_raw_glb(kFox);
  const GltfCharacter fox = gltf_character(read_gltf(kFox));
  // The inverse bind matrices are those of the rest pose: rest vertices are the POSITION data.
  const int position = raw.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"];
  for (int i = 0; i < 1728; i += 97) {
    const std::vector<double> p = raw_element(raw, position, size_t(i));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(fox.mesh.V(i, c), p[size_t(c)], 1e-3) << "vertex " << i;
  }
  const std::vector<Eigen::Vector3d> rest = raw_node_positions(raw, -1, 0);
  for (int j = 0; j < 24; ++j) {
    const Eigen::Vector3d expected = rest[size_t(fox.joint_nodes[size_t(j)])];
    EXPECT_LT((fox.skeleton.rest_joints.row(j).transpose().cast<double>() - expected).norm(), 1e-3)
        << fox.skeleton.names[size_t(j)];
  }
}

TEST(GltfImport, FoxClips) {
  const GltfAsset asset = read_gltf(kFox);
  ASSERT_EQ(asset.animations().size(), 3u);
  EXPECT_EQ(asset.animations()[0].name, "Survey");
  EXPECT_EQ(asset.animations()[1].name, "Walk");
  EXPECT_EQ(asset.animations()[2].name, "Run");
  // The Walk clip's times accessor: 18 keys from 0 to 0.7083333 s (17 / 24 s).
  EXPECT_FLOAT_EQ(asset.animations()[1].start, 0.0f);
  EXPECT_NEAR(asset.animations()[1].duration(), 17.0 / 24.0, 1e-6);
  EXPECT_EQ(asset.animations()[1].num_channels, 21);
  const GltfMotion walk = gltf_motion(asset, gltf_character(asset), "Walk", 30.0f);
  EXPECT_EQ(walk.clip, "Walk");
  EXPECT_NEAR(walk.duration, 17.0 / 24.0, 1e-6);
  EXPECT_EQ(walk.motion.num_frames(), 22);  // floor(0.7083 * 30) + 1
  EXPECT_EQ(walk.motion.fps, 30.0f);
}

// Joint positions of amt's forward kinematics at a keyframe time against the node graph evaluated by
// hand from the GLB's own JSON and BIN chunks.
TEST(GltfImport, FoxWalkJointPositionsAtAKeyframeMatchTheNodeGraph) {
  const RawGlb raw = read_raw_glb(kFox);
  const int clip = raw_clip_index(raw, "Walk");
  ASSERT_GE(clip, 0);
  const int times = raw.json["animations"][size_t(clip)]["samplers"][0]["input"];
  const size_t key = 12;
  const double key_time = raw_element(raw, times, key)[0];
  ASSERT_NEAR(key_time, 0.5, 1e-6);  // keys every 1/24 s; 0.5 s is also frame 15 at 30 fps
  const std::vector<Eigen::Vector3d> expected = raw_node_positions(raw, clip, key);

  const GltfAsset asset = read_gltf(kFox);
  const GltfCharacter fox = gltf_character(asset);
  const GltfMotion walk = gltf_motion(asset, fox, "Walk", 30.0f);
  const Transforms T = forward_kinematics(fox.skeleton, walk.motion, 15);
  // The walk translates b_Hip_01, below the joints _rootJoint and b_Root_00, which carry no skin
  // weight: every joint with skin weight is exact; those two drift with the hips (gltf_import.h).
  const MatrixXfR W = densify_weights(fox.weights, 24);
  for (int j = 0; j < fox.skeleton.num_joints(); ++j) {
    const Eigen::Vector3d p = T[size_t(j)].col(3).cast<double>();
    const double distance = (p - expected[size_t(fox.joint_nodes[size_t(j)])]).norm();
    if (W.col(j).sum() > 0) {
      EXPECT_LT(distance, 2e-3) << fox.skeleton.names[size_t(j)];
    } else {
      EXPECT_TRUE(fox.skeleton.names[size_t(j)] == "_rootJoint" || fox.skeleton.names[size_t(j)] == "b_Root_00");
    }
  }
  // One joint by name, at the end of a chain of 7 animated nodes: the left hind foot.
  const int foot = fox.skeleton.index_of("b_LeftFoot02_018");
  ASSERT_GE(foot, 0);
  EXPECT_LT((T[size_t(foot)].col(3).cast<double>() - expected[21]).norm(), 2e-3);
  // The foot moves during the walk: the check above is not the rest pose.
  const std::vector<Eigen::Vector3d> rest = raw_node_positions(raw, -1, 0);
  EXPECT_GT((expected[21] - rest[21]).norm(), 1.0);
  // Over every frame.
  EXPECT_LT(walk.skinned_joint_position_error, 1e-3f);
  EXPECT_GT(walk.joint_position_error, 1.0f);  // the two helper joints
}

// The whole chain (rest mesh, motion, weights, amt's skinning) against the importer's glTF playback.
TEST(GltfImport, FoxSkinnedByAmtMatchesGltfPlayback) {
  const GltfAsset asset = read_gltf(kFox);
  const GltfCharacter fox = gltf_character(asset);
  for (const char* clip : {"Survey", "Walk", "Run"}) {
    const GltfMotion motion = gltf_motion(asset, fox, clip, 30.0f);
    const GltfVertexAnimation playback = gltf_vertex_animation(asset, clip, 30.0f);
    ASSERT_EQ(int(playback.frames.size()), motion.motion.num_frames());
    ASSERT_EQ(playback.faces, fox.mesh.F);
    double worst = 0.0;
    for (int t = 0; t < motion.motion.num_frames(); ++t) {
      const Transforms M = skinning_matrices(fox.skeleton, forward_kinematics(fox.skeleton, motion.motion, t));
      MatrixX3f V;
      linear_blend_skinning(fox.mesh.V, fox.weights, M, V);
      worst = std::max(worst, double((V - playback.frames[size_t(t)]).rowwise().norm().maxCoeff()));
    }
    EXPECT_LT(worst, 2e-3) << clip;  // the Fox is ~80 units tall: float rounding
  }
}

TEST(GltfImport, FoxFromMemoryEqualsFromFile) {
  const std::vector<uint8_t> bytes = read_bytes(kFox);
  const GltfAsset asset = parse_gltf(bytes.data(), bytes.size(), "Fox in memory");
  EXPECT_EQ(asset.source(), "Fox in memory");
  const GltfCharacter a = gltf_character(asset);
  const GltfCharacter b = gltf_character(read_gltf(kFox));
  EXPECT_EQ(a.mesh.V, b.mesh.V);
  EXPECT_EQ(a.skeleton.names, b.skeleton.names);
}

TEST(GltfImport, UnknownClipNamesTheClips) {
  const GltfAsset asset = read_gltf(kFox);
  const std::string message = error_of([&] { gltf_motion(asset, gltf_character(asset), "Jump"); });
  EXPECT_NE(message.find("Jump"), std::string::npos) << message;
  EXPECT_NE(message.find("Survey, Walk, Run"), std::string::npos) << message;
}

// === Small assets written here

std::string base64(const std::vector<uint8_t>& data) {
  static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < data.size(); i += 3) {
    const uint32_t n = (uint32_t(data[i]) << 16) | (i + 1 < data.size() ? uint32_t(data[i + 1]) << 8 : 0) |
                       (i + 2 < data.size() ? uint32_t(data[i + 2]) : 0);
    out += table[(n >> 18) & 63];
    out += table[(n >> 12) & 63];
    out += i + 1 < data.size() ? table[(n >> 6) & 63] : '=';
    out += i + 2 < data.size() ? table[n & 63] : '=';
  }
  return out;
}

// Builds a glTF JSON document with one buffer; each add() appends a buffer view and an accessor.
struct AssetBuilder {
  nlohmann::json doc = {{"asset", {{"version", "2.0"}}}};
  std::vector<uint8_t> bin;

  template <typename T>
  int add(const std::vector<T>& values, int component_type, const std::string& type, size_t count,
          const nlohmann::json& extra = nlohmann::json::object()) {
    while (bin.size() % 4) bin.push_back(0);
    const size_t offset = bin.size();
    const auto* p = reinterpret_cast<const uint8_t*>(values.data());
    bin.insert(bin.end(), p, p + values.size() * sizeof(T));
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", values.size() * sizeof(T)}});
    nlohmann::json acc = {{"bufferView", doc["bufferViews"].size() - 1},
                          {"componentType", component_type},
                          {"type", type},
                          {"count", count}};
    acc.update(extra);
    doc["accessors"].push_back(acc);
    return int(doc["accessors"].size()) - 1;
  }
  int floats(const std::vector<float>& v, const std::string& type, size_t count,
             const nlohmann::json& extra = nlohmann::json::object()) {
    return add(v, 5126, type, count, extra);
  }
  // The document with the buffer embedded as a data URI.
  std::string text() const {
    nlohmann::json d = doc;
    d["buffers"] = {{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}};
    return d.dump();
  }
  GltfAsset parse(const std::string& name = "test.gltf") const {
    const std::string t = text();
    return parse_gltf(reinterpret_cast<const uint8_t*>(t.data()), t.size(), name);
  }
};

// A two-triangle strip of 4 vertices along +Y (y = 0, 1, 2, 3) on a chain skeleton.
void add_strip(AssetBuilder& b, const nlohmann::json& attributes_extra) {
  const std::vector<float> positions = {0, 0, 0, 1, 1, 0, 0, 2, 0, 1, 3, 0};
  const int pos = b.floats(positions, "VEC3", 4, {{"min", {0, 0, 0}}, {"max", {1, 3, 0}}});
  const std::vector<uint16_t> indices = {0, 1, 2, 1, 3, 2};
  const int idx = b.add(indices, 5123, "SCALAR", 6);
  nlohmann::json attributes = {{"POSITION", pos}};
  attributes.update(attributes_extra);
  b.doc["meshes"] = {{{"primitives", {{{"attributes", attributes}, {"indices", idx}}}}}};
}

TEST(GltfImport, JointAndWeightComponentTypesAndJointReordering) {
  // Joints: node 1 "root" (parent of node 2 "tip"); the skin lists the tip first.
  for (const int joints_type : {5121, 5123}) {
    for (const int weights_type : {5126, 5121, 5123}) {
      AssetBuilder b;
      std::vector<uint8_t> j8 = {0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
      std::vector<uint16_t> j16(j8.begin(), j8.end());
      const int joints = joints_type == 5121 ? b.add(j8, 5121, "VEC4", 4) : b.add(j16, 5123, "VEC4", 4);
      // Skin joint 0 is the tip, 1 the root. Vertex 0: 0.25 tip + 0.75 root; 1: 0.5 + 0.5; 2: tip (in the
      // second slot); 3: root.
      const std::vector<double> w = {0.25, 0.75, 0, 0, 0.5, 0.5, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0};
      int weights;
      if (weights_type == 5126) {
        weights = b.floats(std::vector<float>(w.begin(), w.end()), "VEC4", 4);
      } else if (weights_type == 5121) {
        std::vector<uint8_t> q;
        for (double x : w) q.push_back(uint8_t(std::lround(x * 255)));
        weights = b.add(q, 5121, "VEC4", 4, {{"normalized", true}});
      } else {
        std::vector<uint16_t> q;
        for (double x : w) q.push_back(uint16_t(std::lround(x * 65535)));
        weights = b.add(q, 5123, "VEC4", 4, {{"normalized", true}});
      }
      add_strip(b, {{"JOINTS_0", joints}, {"WEIGHTS_0", weights}});
      const std::vector<float> ibm = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -2, 0, 1,   // tip at y = 2
                                      1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0,  0, 1};  // root at 0
      const int ibms = b.floats(ibm, "MAT4", 2);
      b.doc["nodes"] = {{{"mesh", 0}, {"skin", 0}},
                        {{"name", "root"}, {"children", {2}}},
                        {{"name", "tip"}, {"translation", {0, 2, 0}}}};
      b.doc["skins"] = {{{"joints", {2, 1}}, {"inverseBindMatrices", ibms}}};
      b.doc["scenes"] = {{{"nodes", {0, 1}}}};
      const GltfCharacter ch = gltf_character(b.parse());
      ASSERT_EQ(ch.skeleton.names, (std::vector<std::string>{"root", "tip"}));
      EXPECT_EQ(ch.skeleton.parents, (std::vector<int32_t>{-1, 0}));
      EXPECT_EQ(ch.skin_joint_to_joint, (std::vector<int>{1, 0}));
      EXPECT_EQ(ch.joint_nodes, (std::vector<int>{1, 2}));
      EXPECT_TRUE(ch.skeleton.rest_joints.row(1).isApprox(Eigen::RowVector3f(0, 2, 0)));
      const double tolerance = weights_type == 5126 ? 1e-6 : 3e-3;
      const MatrixXfR W = densify_weights(ch.weights, 2);  // columns: root, tip
      EXPECT_NEAR(W(0, 0), 0.75, tolerance);
      EXPECT_NEAR(W(0, 1), 0.25, tolerance);
      EXPECT_NEAR(W(1, 0), 0.5, tolerance);
      EXPECT_NEAR(W(2, 1), 1.0, tolerance);
      EXPECT_NEAR(W(3, 0), 1.0, tolerance);
      for (int i = 0; i < 4; ++i) EXPECT_NEAR(W.row(i).sum(), 1.0, 1e-6);
      // The inverse bind matrices are those of the rest pose: rest vertices are the mesh positions.
      EXPECT_TRUE(ch.mesh.V.row(3).isApprox(Eigen::RowVector3f(1, 3, 0), 1e-6f));
    }
  }
}

TEST(GltfImport, MoreThanFourInfluencesKeepTheFourLargest) {
  AssetBuilder b;
  // One vertex set with JOINTS_0/1 and WEIGHTS_0/1: weights 0.3 0.05 0.2 0.1 | 0.25 0.1 0 0 on joints 0..5.
  const std::vector<uint8_t> j0 = {0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3};
  const std::vector<uint8_t> j1 = {4, 5, 0, 0, 4, 5, 0, 0, 4, 5, 0, 0, 4, 5, 0, 0};
  const std::vector<float> w0 = {0.3f, 0.05f, 0.2f, 0.1f, 0.3f, 0.05f, 0.2f, 0.1f,
                                 0.3f, 0.05f, 0.2f, 0.1f, 0.3f, 0.05f, 0.2f, 0.1f};
  const std::vector<float> w1 = {0.25f, 0.1f, 0, 0, 0.25f, 0.1f, 0, 0, 0.25f, 0.1f, 0, 0, 0.25f, 0.1f, 0, 0};
  add_strip(b, {{"JOINTS_0", b.add(j0, 5121, "VEC4", 4)},
                {"WEIGHTS_0", b.floats(w0, "VEC4", 4)},
                {"JOINTS_1", b.add(j1, 5121, "VEC4", 4)},
                {"WEIGHTS_1", b.floats(w1, "VEC4", 4)}});
  b.doc["nodes"] = {{{"mesh", 0}, {"skin", 0}},
                    {{"name", "j0"}, {"children", {2, 3, 4, 5, 6}}},
                    {{"name", "j1"}},
                    {{"name", "j2"}},
                    {{"name", "j3"}},
                    {{"name", "j4"}},
                    {{"name", "j5"}}};
  b.doc["skins"] = {{{"joints", {1, 2, 3, 4, 5, 6}}}};
  const GltfCharacter ch = gltf_character(b.parse());
  const MatrixXfR W = densify_weights(ch.weights, 6);
  // Kept: 0.3 (j0), 0.25 (j4), 0.2 (j2), 0.1 (j3 or j5: equal, the first listed wins), sum 0.85.
  EXPECT_NEAR(W(0, 0), 0.3 / 0.85, 1e-6);
  EXPECT_NEAR(W(0, 4), 0.25 / 0.85, 1e-6);
  EXPECT_NEAR(W(0, 2), 0.2 / 0.85, 1e-6);
  EXPECT_NEAR(W(0, 1), 0.0, 1e-6);
  EXPECT_NEAR(W(0, 3) + W(0, 5), 0.1 / 0.85, 1e-6);
}

TEST(GltfImport, SeveralRootJointsGetTheirCommonAncestorAsRoot) {
  AssetBuilder b;
  add_strip(b, {{"JOINTS_0", b.add(std::vector<uint8_t>(16, 0), 5121, "VEC4", 4)},
                {"WEIGHTS_0", b.floats({1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0}, "VEC4", 4)}});
  // Node 1 "armature" (not a joint, scale 0.5) holds the two root joints, legs "l" and "r".
  b.doc["nodes"] = {{{"mesh", 0}, {"skin", 0}},
                    {{"name", "armature"}, {"children", {2, 3}}, {"scale", {0.5, 0.5, 0.5}}},
                    {{"name", "l"}, {"translation", {1, 0, 0}}},
                    {{"name", "r"}, {"translation", {-1, 0, 0}}}};
  b.doc["skins"] = {{{"joints", {2, 3}}}};
  const GltfCharacter ch = gltf_character(b.parse());
  EXPECT_EQ(ch.skeleton.names, (std::vector<std::string>{"armature", "l", "r"}));
  EXPECT_EQ(ch.skeleton.parents, (std::vector<int32_t>{-1, 0, 0}));
  EXPECT_EQ(ch.joint_nodes, (std::vector<int>{1, 2, 3}));
  EXPECT_TRUE(ch.skeleton.rest_joints.row(1).isApprox(Eigen::RowVector3f(0.5f, 0, 0)));

  // Roots in two separate trees: a "gltf_scene_root" joint at the origin.
  b.doc["nodes"] = {{{"mesh", 0}, {"skin", 0}}, {{"name", "l"}}, {{"name", "r"}}};
  b.doc["skins"] = {{{"joints", {1, 2}}}};
  const GltfCharacter separate = gltf_character(b.parse());
  EXPECT_EQ(separate.skeleton.names, (std::vector<std::string>{"gltf_scene_root", "l", "r"}));
  EXPECT_EQ(separate.joint_nodes, (std::vector<int>{-1, 1, 2}));
}

TEST(GltfImport, NodeMatricesInTheHierarchy) {
  AssetBuilder b;
  add_strip(b, {{"JOINTS_0", b.add(std::vector<uint8_t>(16, 0), 5121, "VEC4", 4)},
                {"WEIGHTS_0", b.floats({1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0}, "VEC4", 4)}});
  // "armature": translate (1, 2, 3), turn 90 degrees about Y, scale 2, as a column-major matrix.
  b.doc["nodes"] = {
      {{"mesh", 0}, {"skin", 0}},
      {{"name", "armature"}, {"children", {2}}, {"matrix", {0, 0, -2, 0, 0, 2, 0, 0, 2, 0, 0, 0, 1, 2, 3, 1}}},
      {{"name", "hip"}, {"translation", {1, 0, 0}}}};
  b.doc["skins"] = {{{"joints", {2}}}};
  const GltfCharacter ch = gltf_character(b.parse());
  EXPECT_TRUE(ch.skeleton.rest_joints.row(0).isApprox(Eigen::RowVector3f(1, 2, 1))) << ch.skeleton.rest_joints;

  // A matrix node may not be animated (glTF 2.0 section 3.5.2).
  const int times = b.floats({0.0f}, "SCALAR", 1, {{"min", {0}}, {"max", {0}}});
  const int values = b.floats({0, 0, 0}, "VEC3", 1);
  b.doc["animations"] = {{{"samplers", {{{"input", times}, {"output", values}}}},
                          {"channels", {{{"sampler", 0}, {"target", {{"node", 1}, {"path", "translation"}}}}}}}};
  EXPECT_EQ(error_of([&] { b.parse("matrix.gltf"); }),
            "matrix.gltf: animations[0].channels[0].target.node: expected an animated node to have TRS properties, "
            "found node 1 with a matrix");
}

// A skin of two joints, "base" (rest rotation 90 degrees about X) and its child "arm" (translation
// (0, 1, 0), rest rotation 30 degrees about Y), whose rotation is animated over keys at t = 0 and 1.
AssetBuilder rotating_arm(const std::string& interpolation, const std::vector<float>& rotations) {
  AssetBuilder b;
  add_strip(b, {{"JOINTS_0", b.add(std::vector<uint8_t>(16, 1), 5121, "VEC4", 4)},
                {"WEIGHTS_0", b.floats({1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0}, "VEC4", 4)}});
  const double s45 = std::sqrt(0.5), s15 = std::sin(M_PI / 12), c15 = std::cos(M_PI / 12);
  b.doc["nodes"] = {{{"mesh", 0}, {"skin", 0}},
                    {{"name", "base"}, {"children", {2}}, {"rotation", {s45, 0, 0, s45}}},
                    {{"name", "arm"}, {"translation", {0, 1, 0}}, {"rotation", {0, s15, 0, c15}}},
                    {{"name", "hand"}, {"translation", {0, 1, 0}}}};
  b.doc["nodes"][2]["children"] = {3};
  b.doc["skins"] = {{{"joints", {1, 2, 3}}}};
  const int times = b.floats({0.0f, 1.0f}, "SCALAR", 2, {{"min", {0}}, {"max", {1}}});
  const int values = b.floats(rotations, "VEC4", rotations.size() / 4);
  b.doc["animations"] = {{{"name", "turn"},
                          {"samplers", {{{"input", times}, {"output", values}, {"interpolation", interpolation}}}},
                          {"channels", {{{"sampler", 0}, {"target", {{"node", 2}, {"path", "rotation"}}}}}}}};
  return b;
}

Eigen::Quaterniond gltf_quaternion(const float* v) {
  return Eigen::Quaterniond(v[3], v[0], v[1], v[2]);
}

// amt's local rotation for a glTF local rotation q of "arm": G (q_rest^-1 q) G^-1, G = the arm's
// global rest rotation (see gltf_import.h).
Eigen::Quaterniond expected_local(const Eigen::Quaterniond& q) {
  const double s45 = std::sqrt(0.5), s15 = std::sin(M_PI / 12), c15 = std::cos(M_PI / 12);
  const Eigen::Quaterniond base(s45, s45, 0, 0), arm_rest(c15, 0, s15, 0);
  const Eigen::Quaterniond G = base * arm_rest;
  return G * (arm_rest.conjugate() * q.normalized()) * G.conjugate();
}

void expect_same_rotation(const Eigen::Quaternionf& a, const Eigen::Quaterniond& b, const std::string& what) {
  EXPECT_GT(std::abs(a.cast<double>().coeffs().dot(b.normalized().coeffs())), 1.0 - 1e-6) << what;
}

// Position of the hand by glTF's node graph for a local rotation q of the arm.
Eigen::Vector3d expected_hand(const Eigen::Quaterniond& q) {
  const double s45 = std::sqrt(0.5);
  const Eigen::Quaterniond base(s45, s45, 0, 0);
  return base * (Eigen::Vector3d(0, 1, 0) + q.normalized() * Eigen::Vector3d(0, 1, 0));
}

TEST(GltfImport, StepLinearAndCubicSplineRotations) {
  const float s45 = float(std::sqrt(0.5));
  // Key 0: the arm's rest rotation (30 degrees about Y); key 1: 90 degrees about Z.
  const float s15 = float(std::sin(M_PI / 12)), c15 = float(std::cos(M_PI / 12));
  const std::vector<float> keys = {0, s15, 0, c15, 0, 0, s45, s45};
  const Eigen::Quaterniond q0 = gltf_quaternion(&keys[0]), q1 = gltf_quaternion(&keys[4]);
  const float fps = 4.0f;  // frames at t = 0, 0.25, 0.5, 0.75, 1

  {
    const AssetBuilder b = rotating_arm("STEP", keys);
    const GltfAsset asset = b.parse();
    const GltfCharacter ch = gltf_character(asset);
    const GltfMotion m = gltf_motion(asset, ch, "turn", fps);
    ASSERT_EQ(m.motion.num_frames(), 5);
    expect_same_rotation(m.motion.rotation(2, 1), expected_local(q0), "STEP at t = 0.5");
    expect_same_rotation(m.motion.rotation(4, 1), expected_local(q1), "STEP at t = 1");
    expect_same_rotation(m.motion.rotation(0, 1), Eigen::Quaterniond::Identity(), "rest at t = 0");
  }
  {
    const AssetBuilder b = rotating_arm("LINEAR", keys);
    const GltfAsset asset = b.parse();
    const GltfCharacter ch = gltf_character(asset);
    const GltfMotion m = gltf_motion(asset, ch, "turn", fps);
    for (int t = 0; t < 5; ++t) {
      const Eigen::Quaterniond q = q0.slerp(t / 4.0, q1);
      expect_same_rotation(m.motion.rotation(t, 1), expected_local(q), "LINEAR frame " + std::to_string(t));
      const Transforms T = forward_kinematics(ch.skeleton, m.motion, t);
      EXPECT_LT((T[2].col(3).cast<double>() - expected_hand(q)).norm(), 1e-5) << "frame " << t;
    }
    EXPECT_LT(m.joint_position_error, 1e-5f);
  }
  {
    // Cubic spline: per key in-tangent, value, out-tangent.
    const std::vector<float> tangent0 = {0.3f, -0.2f, 0.5f, 0.1f}, tangent1 = {-0.4f, 0.1f, 0.2f, -0.3f};
    std::vector<float> cubic;
    for (float v : {0.f, 0.f, 0.f, 0.f}) cubic.push_back(v);      // in-tangent of key 0 (unused)
    cubic.insert(cubic.end(), keys.begin(), keys.begin() + 4);    // value 0
    cubic.insert(cubic.end(), tangent0.begin(), tangent0.end());  // out-tangent b0
    cubic.insert(cubic.end(), tangent1.begin(), tangent1.end());  // in-tangent a1
    cubic.insert(cubic.end(), keys.begin() + 4, keys.end());      // value 1
    for (float v : {0.f, 0.f, 0.f, 0.f}) cubic.push_back(v);      // out-tangent of key 1 (unused)
    const AssetBuilder b = rotating_arm("CUBICSPLINE", cubic);
    const GltfAsset asset = b.parse();
    const GltfCharacter ch = gltf_character(asset);
    const GltfMotion m = gltf_motion(asset, ch, "turn", fps);
    for (int t = 0; t < 5; ++t) {
      const double s = t / 4.0, s2 = s * s, s3 = s2 * s;  // dt = 1
      Eigen::Vector4d p = Eigen::Vector4d::Zero();
      for (int c = 0; c < 4; ++c) {
        p[c] = (2 * s3 - 3 * s2 + 1) * keys[size_t(c)] + (s3 - 2 * s2 + s) * tangent0[size_t(c)] +
               (-2 * s3 + 3 * s2) * keys[4 + size_t(c)] + (s3 - s2) * tangent1[size_t(c)];
      }
      const Eigen::Quaterniond q(p[3], p[0], p[1], p[2]);
      expect_same_rotation(m.motion.rotation(t, 1), expected_local(q), "CUBICSPLINE frame " + std::to_string(t));
    }
  }
}

TEST(GltfImport, AnimatedScaleIsIgnoredAndReported) {
  AssetBuilder b = rotating_arm("LINEAR", {0, 0, 0, 1, 0, 0, 0, 1});
  // Scale the arm to 2 at t = 1: glTF moves the hand 1 unit further; amt keeps the bone.
  const int times = b.floats({0.0f, 1.0f}, "SCALAR", 2, {{"min", {0}}, {"max", {1}}});
  const int scales = b.floats({1, 1, 1, 2, 2, 2}, "VEC3", 2);
  b.doc["animations"][0]["samplers"].push_back({{"input", times}, {"output", scales}});
  b.doc["animations"][0]["channels"].push_back({{"sampler", 1}, {"target", {{"node", 2}, {"path", "scale"}}}});
  const GltfAsset asset = b.parse();
  const GltfMotion m = gltf_motion(asset, gltf_character(asset), "turn", 2.0f);
  EXPECT_NEAR(m.joint_position_error, 1.0f, 1e-5f);
}

TEST(GltfImport, SparseAccessorsAndMorphTargets) {
  AssetBuilder b;
  // POSITION: a zero base with two vertices replaced through a sparse accessor.
  const std::vector<float> base(12, 0.0f);
  b.floats(base, "VEC3", 4);  // accessor 0: plain zeros (unused)
  const std::vector<uint16_t> sparse_indices = {1, 3};
  const std::vector<float> sparse_values = {1, 1, 0, 1, 3, 0};
  b.add(sparse_indices, 5123, "SCALAR", 2);  // accessor 1 (for its buffer view)
  b.floats(sparse_values, "VEC3", 2);        // accessor 2 (for its buffer view)
  nlohmann::json position = {
      {"componentType", 5126},
      {"type", "VEC3"},
      {"count", 4},
      {"min", {0, 0, 0}},
      {"max", {1, 3, 0}},
      {"sparse",
       {{"count", 2}, {"indices", {{"bufferView", 1}, {"componentType", 5123}}}, {"values", {{"bufferView", 2}}}}}};
  b.doc["accessors"].push_back(position);  // accessor 3, without a buffer view of its own
  const int target =
      b.floats({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}, "VEC3", 4, {{"min", {0, 0, 1}}, {"max", {0, 0, 1}}});
  const std::vector<uint16_t> indices = {0, 1, 2, 1, 3, 2};
  const int idx = b.add(indices, 5123, "SCALAR", 6);
  b.doc["meshes"] = {
      {{"primitives", {{{"attributes", {{"POSITION", 3}}}, {"indices", idx}, {"targets", {{{"POSITION", target}}}}}}},
       {"weights", {0.5}}}};
  b.doc["nodes"] = {{{"mesh", 0}, {"translation", {10, 0, 0}}}};
  const int times = b.floats({0.0f, 1.0f}, "SCALAR", 2, {{"min", {0}}, {"max", {1}}});
  const int weights = b.floats({0.0f, 2.0f}, "SCALAR", 2);
  b.doc["animations"] = {{{"samplers", {{{"input", times}, {"output", weights}}}},
                          {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "weights"}}}}}}}};
  const GltfAsset asset = b.parse();
  EXPECT_EQ(asset.animations()[0].name, "animation_0");
  const GltfVertexAnimation anim = gltf_vertex_animation(asset, "", 2.0f);
  ASSERT_EQ(anim.frames.size(), 3u);  // t = 0, 0.5, 1: weight 0, 1, 2
  for (int t = 0; t < 3; ++t) {
    EXPECT_TRUE(anim.frames[size_t(t)].row(0).isApprox(Eigen::RowVector3f(10, 0, float(t)))) << t;
    EXPECT_TRUE(anim.frames[size_t(t)].row(3).isApprox(Eigen::RowVector3f(11, 3, float(t)))) << t;
  }
}

TEST(GltfImport, ExternalBufferBesideTheFile) {
  const auto dir = temp_dir("external");
  const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  std::vector<uint8_t> bin(positions.size() * 4);
  std::memcpy(bin.data(), positions.data(), bin.size());
  write_bytes((dir / "tri angle.bin").string(), bin);
  write_text((dir / "triangle.gltf").string(), R"({
    "asset": {"version": "2.0"},
    "buffers": [{"uri": "tri%20angle.bin", "byteLength": 36}],
    "bufferViews": [{"buffer": 0, "byteLength": 36}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                   "min": [0, 0, 0], "max": [1, 1, 0]}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
    "nodes": [{"mesh": 0}],
    "scenes": [{"nodes": [0]}]
  })");
  const GltfVertexAnimation anim = gltf_vertex_animation(read_gltf((dir / "triangle.gltf").string()));
  ASSERT_EQ(anim.frames.size(), 1u);
  EXPECT_EQ(anim.faces.rows(), 1);
  EXPECT_TRUE(anim.frames[0].row(1).isApprox(Eigen::RowVector3f(1, 0, 0)));

  // The same asset parsed from memory without a folder may not read the file.
  const std::vector<uint8_t> text = read_bytes((dir / "triangle.gltf").string());
  const std::string message = error_of([&] { parse_gltf(text.data(), text.size(), "memory.gltf"); });
  EXPECT_NE(message.find("memory.gltf: buffers[0].uri"), std::string::npos) << message;
}

// tests/assets/gltf/two_bone_strip.{gltf,glb}: the same hand-made asset as JSON with a data URI and as
// GLB. A 6-vertex strip on two joints (UNSIGNED_BYTE indices and joints, normalized UNSIGNED_SHORT
// weights, zero weights with non-zero joint indices), a sparse morph target, and a clip "bend" with a
// CUBICSPLINE rotation of the tip, a STEP translation of the root and a LINEAR morph weight.
TEST(GltfImport, HandMadeAssetWithEveryFeature) {
  for (const char* name : {"two_bone_strip.gltf", "two_bone_strip.glb"}) {
    const GltfAsset asset = read_gltf(std::string(AMT_TEST_ASSETS_DIR) + "/gltf/" + name);
    const GltfCharacter ch = gltf_character(asset);
    EXPECT_EQ(ch.skeleton.names, (std::vector<std::string>{"root", "tip"})) << name;
    EXPECT_EQ(ch.mesh.num_faces(), 4);
    const MatrixXfR W = densify_weights(ch.weights, 2);
    EXPECT_NEAR(W(0, 0), 1.0, 1e-6);
    EXPECT_NEAR(W(2, 0), 32768.0 / 65535.0, 1e-6);
    EXPECT_NEAR(W(5, 1), 1.0, 1e-6);
    EXPECT_TRUE(ch.mesh.V.row(4).isApprox(Eigen::RowVector3f(0, 2, 0)));  // morph weight 0 at rest

    const GltfMotion m = gltf_motion(asset, ch, "bend", 4.0f);
    ASSERT_EQ(m.motion.num_frames(), 5);
    EXPECT_FLOAT_EQ(m.motion.root_translation(1, 0), 0.0f);  // STEP: key 0 until t = 0.5
    EXPECT_FLOAT_EQ(m.motion.root_translation(2, 0), 0.5f);
    EXPECT_FLOAT_EQ(m.motion.root_translation(3, 0), 0.5f);
    EXPECT_LT(m.joint_position_error, 1e-6f);
    // At t = 0.5 the tip is turned 90 degrees about Z (the middle key's value).
    const Eigen::Quaternionf tip = m.motion.rotation(2, 1);
    EXPECT_NEAR(std::abs(tip.coeffs().dot(Eigen::Quaternionf(std::sqrt(0.5f), 0, 0, std::sqrt(0.5f)).coeffs())), 1.0,
                1e-6);

    const GltfVertexAnimation playback = gltf_vertex_animation(asset, "bend", 4.0f);
    ASSERT_EQ(playback.frames.size(), 5u);
    EXPECT_NEAR(playback.frames[2](4, 2), 0.5f, 1e-6f);  // morph weight 1 at t = 0.5
    EXPECT_NEAR(playback.frames[1](4, 2), 0.25f, 1e-6f);
    for (const int t : {0, 4}) {  // morph weight 0: amt's skinning of the motion is the playback
      MatrixX3f V;
      linear_blend_skinning(ch.mesh.V, ch.weights,
                            skinning_matrices(ch.skeleton, forward_kinematics(ch.skeleton, m.motion, t)), V);
      EXPECT_LT((V - playback.frames[size_t(t)]).cwiseAbs().maxCoeff(), 1e-5f) << name << " frame " << t;
    }
  }
}

// === Bad input

TEST(GltfImport, TruncatedGlbIsAnErrorAtEveryLength) {
  const std::vector<uint8_t> fox = read_bytes(kFox);
  const auto dir = temp_dir("truncated");
  for (const size_t length : {size_t(0), size_t(3), size_t(11), size_t(12), size_t(19), size_t(20), size_t(100),
                              size_t(5000), fox.size() / 2, fox.size() - 4, fox.size() - 1}) {
    const std::string path = (dir / ("Fox_" + std::to_string(length) + ".glb")).string();
    write_bytes(path, std::vector<uint8_t>(fox.begin(), fox.begin() + long(length)));
    const std::string message = error_of([&] { read_gltf(path); });
    ASSERT_FALSE(message.empty()) << "length " << length;
    EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    if (length >= 12) {
      EXPECT_NE(message.find("GLB header length"), std::string::npos) << message;
    }
  }
}

TEST(GltfImport, GlbWithBadChunkLengthsFromMemory) {
  std::vector<uint8_t> fox = read_bytes(kFox);
  // A JSON chunk claiming more bytes than the file holds.
  std::vector<uint8_t> bad = fox;
  const uint32_t huge = 0xFFFFFF00u;
  std::memcpy(&bad[12], &huge, 4);
  std::string message = error_of([&] { parse_gltf(bad.data(), bad.size(), "long_json.glb"); });
  EXPECT_NE(message.find("long_json.glb: GLB JSON chunk length"), std::string::npos) << message;
  // A BIN chunk claiming more bytes than the file holds (tinygltf's own bound is 8 bytes short).
  uint32_t json_length;
  std::memcpy(&json_length, &fox[12], 4);
  bad = fox;
  uint32_t bin_length;
  std::memcpy(&bin_length, &bad[20 + json_length], 4);
  bin_length += 8;
  std::memcpy(&bad[20 + json_length], &bin_length, 4);
  message = error_of([&] { parse_gltf(bad.data(), bad.size(), "long_bin.glb"); });
  EXPECT_NE(message.find("long_bin.glb: GLB BIN chunk length"), std::string::npos) << message;
}

TEST(GltfImport, WrongMagic) {
  std::vector<uint8_t> fox = read_bytes(kFox);
  fox[3] = 'X';
  const auto dir = temp_dir("magic");
  const std::string path = (dir / "Fox.glb").string();
  write_bytes(path, fox);
  const std::string message = error_of([&] { read_gltf(path); });
  EXPECT_EQ(message, path +
                         ": magic: expected a GLB file (magic 'glTF') or glTF JSON (starting with '{'), found "
                         "bytes 67 6c 54 58");
}

TEST(GltfImport, WrongGlbVersion) {
  std::vector<uint8_t> fox = read_bytes(kFox);
  fox[4] = 1;
  const std::string message = error_of([&] { parse_gltf(fox.data(), fox.size(), "v1.glb"); });
  EXPECT_EQ(message, "v1.glb: GLB header version: expected 2, found 1");
}

const char* kAccessorPastBuffer = R"({
  "asset": {"version": "2.0"},
  "buffers": [{"byteLength": 36,
               "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
  "bufferViews": [{"buffer": 0, "byteLength": 36}],
  "accessors": [{"bufferView": 0, "byteOffset": 12, "componentType": 5126, "count": 3, "type": "VEC3"}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
  "nodes": [{"mesh": 0}]
})";

GltfVertexAnimation parse_text(const std::string& text, const std::string& name) {
  return gltf_vertex_animation(parse_gltf(reinterpret_cast<const uint8_t*>(text.data()), text.size(), name));
}

TEST(GltfImport, AccessorPastItsBufferView) {
  const std::string message = error_of([] { parse_text(kAccessorPastBuffer, "past.gltf"); });
  EXPECT_EQ(message,
            "past.gltf: accessors[0] (meshes[0].primitives[0].attributes.POSITION): expected its bytes "
            "within bufferViews[0] (36 bytes), found bytes 12 to 48");
  // Fixed, the same file reads.
  std::string fixed = kAccessorPastBuffer;
  fixed.replace(fixed.find("\"byteOffset\": 12"), 16, "\"byteOffset\": 0");
  EXPECT_EQ(parse_text(fixed, "fixed.gltf").frames[0].rows(), 3);
}

TEST(GltfImport, BufferViewPastItsBuffer) {
  std::string text = kAccessorPastBuffer;
  const std::string view = "\"bufferViews\": [{\"buffer\": 0, \"byteLength\": 36}]";
  text.replace(text.find(view), view.size(), "\"bufferViews\": [{\"buffer\": 0, \"byteLength\": 40}]");
  const std::string message = error_of([&] { parse_text(text, "view.gltf"); });
  EXPECT_EQ(message,
            "view.gltf: bufferViews[0]: expected byteOffset + byteLength within buffers[0] (36 bytes), "
            "found 0 + 40");
}

TEST(GltfImport, PointsPrimitive) {
  std::string text = kAccessorPastBuffer;
  text.replace(text.find("\"byteOffset\": 12"), 16, "\"byteOffset\": 0");
  text.replace(text.find("{\"POSITION\": 0}"), 15, "{\"POSITION\": 0}, \"mode\": 0");
  text.replace(text.find("{\"primitives\""), 13, "{\"name\": \"dots\", \"primitives\"");
  const std::string message = error_of([&] { parse_text(text, "points.gltf"); });
  EXPECT_EQ(message, "points.gltf: meshes[0] 'dots'.primitives[0].mode: expected 4 (TRIANGLES), found 0 (POINTS)");
}

TEST(GltfImport, IndexPastTheVertexCount) {
  AssetBuilder b;
  const int pos = b.floats({0, 0, 0, 1, 0, 0, 0, 1, 0}, "VEC3", 3);
  const int idx = b.add(std::vector<uint16_t>{0, 1, 5}, 5123, "SCALAR", 3);
  b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", pos}}}, {"indices", idx}}}}}};
  b.doc["nodes"] = {{{"mesh", 0}}};
  const std::string message = error_of([&] { gltf_vertex_animation(b.parse("index.gltf")); });
  EXPECT_EQ(message,
            "index.gltf: meshes[0].primitives[0].indices: expected vertex indices below the vertex count 3, "
            "found 5 at index 2");
}

TEST(GltfImport, NanPosition) {
  AssetBuilder b;
  const int pos = b.floats({0, 0, 0, 1, std::nanf(""), 0, 0, 1, 0}, "VEC3", 3);
  b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", pos}}}}}}}};
  b.doc["nodes"] = {{{"mesh", 0}}};
  const std::string message = error_of([&] { gltf_vertex_animation(b.parse("nan.gltf")); });
  EXPECT_EQ(message,
            "nan.gltf: accessors[0] (meshes[0].primitives[0].attributes.POSITION): expected finite values, "
            "found nan at element 1");
}

TEST(GltfImport, AbsurdPositionIsRejected) {
  // Finite, so the accessor reader lets it through; the plausibility bound of data_tools/geometry/mesh.h does not.
  AssetBuilder b;
  const int pos = b.floats({0, 0, 0, 1, 1e15f, 0, 0, 1, 0}, "VEC3", 3);
  b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", pos}}}}}}}};
  b.doc["nodes"] = {{{"mesh", 0}}};
  const std::string message = error_of([&] { gltf_vertex_animation(b.parse("huge.gltf")); });
  EXPECT_EQ(message.rfind("huge.gltf: animation \"", 0), 0u) << message;
  EXPECT_NE(message.find("frame 0: vertices: expected coordinates within 10000 of the origin, found 1 1e+15 0 at vertex 1"),
            std::string::npos)
      << message;
}

TEST(GltfImport, MissingExternalBuffer) {
  const auto dir = temp_dir("missing");
  const std::string path = (dir / "scene.gltf").string();
  write_text(path, R"({"asset": {"version": "2.0"}, "buffers": [{"uri": "missing.bin", "byteLength": 36}]})");
  const std::string message = error_of([&] { read_gltf(path); });
  EXPECT_EQ(message, path + ": buffers[0].uri: expected the external buffer file 'missing.bin' at " +
                         (dir / "missing.bin").string() + ", found no such file");
}

TEST(GltfImport, ExternalFilesOutsideTheAssetFolderAreRefused) {
  const auto dir = temp_dir("outside");
  std::filesystem::create_directories(dir / "asset");
  write_text((dir / "secret.bin").string(), std::string(36, 's'));
  const std::string path = (dir / "asset" / "scene.gltf").string();
  for (const std::string& uri :
       std::vector<std::string>{"../secret.bin", "../../../../etc/passwd", (dir / "secret.bin").string()}) {
    write_text(path, R"({"asset": {"version": "2.0"}, "buffers": [{"uri": ")" + uri + R"(", "byteLength": 36}]})");
    const std::string message = error_of([&] { read_gltf(path); });
    EXPECT_EQ(
        message.rfind(path + ": buffers[0].uri: expected a file inside the asset's folder, found '" + uri + "'", 0), 0u)
        << message;
  }
  // A link inside the folder that points out of it, and an image (tinygltf reads image files too).
  std::filesystem::create_symlink(dir / "secret.bin", dir / "asset" / "link.bin");
  write_text(path, R"({"asset": {"version": "2.0"}, "buffers": [{"uri": "link.bin", "byteLength": 36}]})");
  EXPECT_NE(error_of([&] { read_gltf(path); }).find("buffers[0].uri: expected a file inside the asset's folder"),
            std::string::npos);
  write_text(path, R"({"asset": {"version": "2.0"}, "images": [{"uri": "../secret.bin"}]})");
  EXPECT_NE(error_of([&] { read_gltf(path); })
                .find("images[0].uri: expected a file inside the asset's folder, found "
                      "'../secret.bin'"),
            std::string::npos);
}

// Inputs found by tests/fuzz/gltf_fuzz.cpp that once escaped as something other than amt::Error.
TEST(GltfImport, FuzzFindingsAreOneLineErrors) {
  // JSON whose number overflows a double: nlohmann throws out_of_range, not parse_error.
  const std::string path = std::string(AMT_TEST_ASSETS_DIR) + "/gltf/bad/fuzz_number_overflow.gltf";
  const std::string message = error_of([&] { read_gltf(path); });
  EXPECT_EQ(message.rfind(path + ": JSON: expected valid JSON, found [json.exception.out_of_range.406] number "
                                 "overflow parsing '220726490285019e87457'",
                          0),
            0u)
      << message;
}

TEST(GltfImport, OtherBadInput) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"not json {", "bad.gltf: magic: expected a GLB file"},
      {"{\"asset\": {\"version\": \"2.0\"}", "bad.gltf: JSON: expected valid JSON, found a syntax error at byte"},
      {"{\"asset\": {\"version\": \"1.0\"}}", "bad.gltf: asset.version: expected \"2.0\", found \"1.0\""},
      {"{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [{\"children\": [1]}, {\"children\": [0]}]}",
       "bad.gltf: nodes: expected a hierarchy without cycles, found a cycle through node 0"},
      {"{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [{\"children\": [7]}]}",
       "bad.gltf: nodes[0].children: expected node indices in [0, 1) other than 0, found 7"},
      {"{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [{\"rotation\": [0, 0, 0, 0]}]}",
       "bad.gltf: nodes[0].rotation: expected a unit quaternion, found norm 0"},
      {"{\"asset\": {\"version\": \"2.0\"}, \"buffers\": [{\"byteLength\": 8, \"uri\": "
       "\"data:application/octet-stream;base64,AAAA\"}]}",
       "bad.gltf: buffers[0].uri: expected a data URI holding byteLength = 8 bytes, found 3 bytes"},
      {"{\"asset\": {\"version\": \"2.0\"}, \"extras\": " + std::string(300, '[') + std::string(300, ']') + "}",
       "bad.gltf: JSON: expected nesting at most 256 deep, found 301"},
      {"{\"asset\": {\"version\": \"2.0\"}}", "bad.gltf: nodes: expected a node with a mesh and a skin, found none"},
  };
  for (const auto& [text, expected] : cases) {
    const std::string message = error_of([&, &text = text] {
      gltf_character(parse_gltf(reinterpret_cast<const uint8_t*>(text.data()), text.size(), "bad.gltf"));
    });
    EXPECT_EQ(message.rfind(expected, 0), 0u) << "got: " << message << "\nexpected: " << expected;
  }
}

}  // namespace
}  // namespace amt
