// `amt animate --out X.glb` writes a skinned animation (the canonical joints and the apparel's handles as joints,
// node-transform channels) instead of a per-frame vertex cache (`--vertex-cache`). Checked on each apparel path
// (the shipped learned module, a PMX model's own physics, a VRM avatar's spring bones): the file passes the Khronos
// validator, glTF's own skinning of it (gltf_vertex_animation, the importer's independent playback) lands near the
// vertex cache of the same run, frame by frame, and it is many times smaller.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/pmx_export.h"
#include "tests/data_tools/builder/pmx_humanoid.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

// `amt args...` with `dir` as the current folder.
test::CommandResult amt_in(const fs::path& dir, const std::vector<std::string>& args) {
  return test::run_command("cd " + test::shell_command(dir.string(), {}) + " && " +
                           test::shell_command(AMT_BINARY, args));
}

struct Comparison {
  double apparel_p95 = 0, apparel_max = 0, body_p95 = 0, moved = 0;
  double size_ratio = 0;
  std::string printed;
};

// The JSON chunk of a GLB file and the apparel mask its COLOR_0 tint carries (blue above red; empty without one).
struct GlbInfo {
  nlohmann::json json;
  std::vector<uint8_t> mask;
};
GlbInfo glb_info(const fs::path& path) {
  const std::string bytes = test::read_file_bytes(path.string());
  uint32_t json_length = 0, bin_length = 0;
  std::memcpy(&json_length, bytes.data() + 12, 4);
  std::memcpy(&bin_length, bytes.data() + 20 + json_length, 4);
  GlbInfo info{nlohmann::json::parse(bytes.substr(20, json_length)), {}};
  const std::string bin = bytes.substr(28 + json_length, bin_length);
  const nlohmann::json& attributes = info.json["meshes"][0]["primitives"][0]["attributes"];
  if (!attributes.contains("COLOR_0")) return info;
  const nlohmann::json& accessor = info.json["accessors"][attributes["COLOR_0"].get<int>()];
  const nlohmann::json& view = info.json["bufferViews"][accessor["bufferView"].get<int>()];
  const size_t offset = view["byteOffset"].get<size_t>(), count = accessor["count"].get<size_t>();
  for (size_t i = 0; i < count; ++i) {
    const auto* rgba = reinterpret_cast<const uint8_t*>(bin.data() + offset + 4 * i);
    info.mask.push_back(rgba[2] > rgba[0] ? 1 : 0);
  }
  return info;
}

double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  const size_t k = std::min(values.size() - 1, size_t(q * double(values.size())));
  std::nth_element(values.begin(), values.begin() + std::ptrdiff_t(k), values.end());
  return values[k];
}

// Runs `amt animate args` twice in dir, to skinned.glb and with --vertex-cache to cache.glb, and compares their
// playback.
Comparison skinned_against_cache(const fs::path& dir, std::vector<std::string> args, const char* what) {
  Comparison c;
  args.insert(args.begin(), "animate");
  for (const char* a : {"--frames", "150", "--threads", "1"}) args.emplace_back(a);
  std::vector<std::string> skinned = args, cache = args;
  for (const char* a : {"--out", "skinned.glb"}) skinned.emplace_back(a);
  for (const char* a : {"--out", "cache.glb", "--vertex-cache"}) cache.emplace_back(a);
  const test::CommandResult a = amt_in(dir, skinned);
  const test::CommandResult b = amt_in(dir, cache);
  EXPECT_EQ(a.status, 0) << a.err;
  EXPECT_EQ(b.status, 0) << b.err;
  if (a.status != 0 || b.status != 0) return c;
  c.printed = a.out;
  test::expect_valid_gltf(dir / "skinned.glb");
  EXPECT_EQ(glb_info(dir / "skinned.glb").json["asset"]["extras"]["amt_format"], "skinned-animation");
  const GltfVertexAnimation x = gltf_vertex_animation(read_gltf((dir / "skinned.glb").string()), "", 30.0f);
  const GltfVertexAnimation y = gltf_vertex_animation(read_gltf((dir / "cache.glb").string()), "", 30.0f);
  EXPECT_EQ(x.frames.size(), 150u);
  EXPECT_EQ(y.frames.size(), 150u);
  if (x.frames.size() != y.frames.size() || x.frames.empty()) return c;
  // The apparel, from the tint of the vertex cache.
  const std::vector<uint8_t> mask = glb_info(dir / "cache.glb").mask;
  EXPECT_EQ(mask.size(), size_t(y.frames[0].rows()));
  std::vector<double> apparel, body;
  int64_t moved_count = 0;
  for (size_t t = 0; t < x.frames.size(); ++t) {
    for (Eigen::Index i = 0; i < x.frames[t].rows(); ++i) {
      const double d = (x.frames[t].row(i) - y.frames[t].row(i)).norm();
      (mask[size_t(i)] ? apparel : body).push_back(d);
      if (mask[size_t(i)] && t > 0) c.moved += (y.frames[t].row(i) - y.frames[t - 1].row(i)).norm(), ++moved_count;
    }
  }
  c.moved /= double(std::max<int64_t>(moved_count, 1));
  c.apparel_max = apparel.empty() ? 0 : *std::max_element(apparel.begin(), apparel.end());
  c.apparel_p95 = quantile(apparel, 0.95), c.body_p95 = quantile(body, 0.95);
  c.size_ratio = double(fs::file_size(dir / "cache.glb")) / double(fs::file_size(dir / "skinned.glb"));
  std::cout << what << ": skinned GLB " << fs::file_size(dir / "skinned.glb") << " bytes, vertex cache "
            << fs::file_size(dir / "cache.glb") << " bytes (" << c.size_ratio << "x); skinned playback off the cache "
            << "by " << 100 * c.apparel_p95 << " cm at p95 and " << 100 * c.apparel_max << " cm at most on the "
            << "apparel (moving " << 100 * c.moved << " cm a frame), " << 100 * c.body_p95
            << " cm at p95 on the body\n";
  return c;
}

TEST(SkinnedOutput, TheShippedLearnedApparelAsHandlesPlaysTheComputedFrames) {
  const std::string model = fs::path(AMT_ASSET_DIR).parent_path().string() + "/models/pretrained";
  const Comparison c =
      skinned_against_cache(test::temp_dir("skinned_learned"),
                            {"--character", "generated:3", "--motion",
                             std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh", "--model", model, "--bind", "none"},
                            "learned apparel");
  EXPECT_NE(c.printed.find("skinned: 22 joints and "), std::string::npos) << c.printed;
  EXPECT_GT(c.moved, 0.005);                    // the apparel moves centimetres a frame ...
  EXPECT_LT(c.apparel_p95, 0.005) << "metres";  // ... and the skin follows it to millimetres
  // The body's 4 largest predicted weights, renormalised (glTF players read 4).
  EXPECT_LT(c.body_p95, 0.004) << "metres";
  // An 8k-vertex character over 5 s: 10.0x (the mesh, its weights and the JSON are paid once; the ratio grows
  // with the clip and the vertex count, 16x on Godette below). Sizes depend on counts alone, not on the motion.
  EXPECT_GT(c.size_ratio, 10.0);
}

TEST(SkinnedOutput, APmxModelsOwnPhysicsAsHandlesPlaysTheComputedFrames) {
  const fs::path dir = test::temp_dir("skinned_pmx");
  write_pmx(test::pmx_humanoid(), (dir / "humanoid.pmx").string());
  const Comparison c =
      skinned_against_cache(dir,
                            {"--character", "humanoid.pmx", "--motion",
                             std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh", "--apparel", "physics"},
                            "PMX physics");
  EXPECT_GT(c.moved, 0.005);
  EXPECT_LT(c.apparel_p95, 0.005) << "metres";
  EXPECT_LT(c.body_p95, 0.002) << "metres";
  EXPECT_GT(c.size_ratio, 2.0);  // a test model of a few hundred vertices: the joints weigh more than on a real one
}

TEST(SkinnedOutput, AVrmAvatarsSpringBonesAsHandlesPlayTheComputedFrames) {
  const Comparison c =
      skinned_against_cache(test::temp_dir("skinned_springs"),
                            {"--character", std::string(AMT_ASSET_DIR) + "/characters/Godette.vrm", "--motion",
                             std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh", "--apparel", "spring-bones"},
                            "spring bones");
  EXPECT_LT(c.apparel_p95, 0.005) << "metres";
  EXPECT_LT(c.body_p95, 0.002) << "metres";
  EXPECT_GT(c.size_ratio, 10.0);
}

// `--out X.vrm` from a VRM avatar with its spring bones: the avatar's own file again (humanoid map, spring bones,
// materials kept) with one clip moving its own joints; read back by amt, its map and springs are the source's, and
// glTF's skinning of the clip plays the vertex cache of the same run.
TEST(SkinnedOutput, AVrmOutputKeepsTheAvatarsMapAndSpringsAndPlaysItsFrames) {
  const fs::path dir = test::temp_dir("skinned_vrm");
  const std::string godette = std::string(AMT_ASSET_DIR) + "/characters/Godette.vrm";
  std::vector<std::string> args = {
      "animate",   "--character",  godette,    "--motion", std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh",
      "--apparel", "spring-bones", "--frames", "40"};
  std::vector<std::string> vrm = args, cache = args;
  for (const char* a : {"--out", "godette.vrm"}) vrm.emplace_back(a);
  for (const char* a : {"--out", "cache.glb", "--vertex-cache"}) cache.emplace_back(a);
  const test::CommandResult a = amt_in(dir, vrm);
  const test::CommandResult b = amt_in(dir, cache);
  ASSERT_EQ(a.status, 0) << a.err;
  ASSERT_EQ(b.status, 0) << b.err;
  EXPECT_NE(a.out.find("its VRM extensions kept"), std::string::npos) << a.out;
  test::expect_valid_gltf(dir / "godette.vrm");

  const GltfAsset source = read_gltf(godette), back = read_gltf((dir / "godette.vrm").string());
  const GltfCharacter sc = gltf_character(source), bc = gltf_character(back);
  EXPECT_EQ(gltf_vrm_version(back), gltf_vrm_version(source));
  ASSERT_TRUE(gltf_vrm_joint_map(back, bc).has_value());
  EXPECT_EQ(gltf_vrm_joint_map(back, bc)->entries, gltf_vrm_joint_map(source, sc)->entries);
  const SpringRig springs = gltf_vrm_spring_rig(back, bc), original = gltf_vrm_spring_rig(source, sc);
  EXPECT_GT(springs.num_joints(), 0);
  EXPECT_EQ(springs.num_joints(), original.num_joints());
  EXPECT_EQ(springs.colliders.size(), original.colliders.size());
  EXPECT_EQ(back.animations().size(), 1u);

  // The playback against the vertex cache (in amt's frame: a VRM 0.x avatar faces -Z in its file and is turned).
  const GltfVertexAnimation x = gltf_vertex_animation(back, "", 30.0f);
  const GltfVertexAnimation y = gltf_vertex_animation(read_gltf((dir / "cache.glb").string()), "", 30.0f);
  ASSERT_EQ(x.frames.size(), 40u);
  ASSERT_EQ(y.frames.size(), 40u);
  const bool turned = gltf_vrm_version(source) == "0";
  double worst = 0, moved = 0;
  for (size_t t = 0; t < x.frames.size(); ++t) {
    MatrixX3f X = x.frames[t];
    if (turned) X.col(0) *= -1.0f, X.col(2) *= -1.0f;
    worst = std::max(worst, double((X - y.frames[t]).rowwise().norm().maxCoeff()));
    moved = std::max(moved, double((y.frames[t] - y.frames[0]).rowwise().norm().maxCoeff()));
  }
  std::cout << "VRM output: playback off the vertex cache by " << 100 * worst << " cm at most (the clip moves "
            << 100 * moved << " cm)\n";
  EXPECT_GT(moved, 0.1);
  EXPECT_LT(worst, 1e-3) << "metres";
}

TEST(SkinnedOutput, AVrmOutputIsRefusedOnThePathsThatCannotWriteOne) {
  const fs::path dir = test::temp_dir("skinned_vrm_refused");
  const std::string model = fs::path(AMT_ASSET_DIR).parent_path().string() + "/models/pretrained";
  const test::CommandResult r = test::run_command(test::shell_command(
      AMT_BINARY,
      {"animate", "--character", std::string(AMT_ASSET_DIR) + "/characters/Godette.vrm", "--motion",
       std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh", "--model", model, "--out", (dir / "x.vrm").string()}));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("x.vrm: --out: expected .glb, .h5 or a folder with --apparel learned"), std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "x.vrm"));
}

}  // namespace
}  // namespace amt
