// A rig's own bones as the apparel module's handles (issue 35, item 2): a PMX model's physics-driven hair bones
// become one handle each at the vertex the bone weighs most, the bind carries them, and `amt animate` takes them
// with --apparel-handles rig and names them beside the automatic handles it uses by default.
#include <gtest/gtest.h>
#include <torch/utils.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "data_tools/formats/pmx_export.h"
#include "infer/bind_cache_torch.h"
#include "infer/character_input.h"
#include "infer/runtime_torch.h"
#include "models/pipeline.h"
#include "tests/data_tools/builder/pmx_humanoid.h"
#include "tests/test_support.h"
#include "tests/train/fresh_model.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

struct RiggedPmx {
  fs::path dir;
  std::string pmx, model;
  RuntimeCharacter character;
};

RiggedPmx rigged_pmx(const std::string& name) {
  RiggedPmx r;
  r.dir = test::temp_dir(name);
  r.pmx = (r.dir / "humanoid.pmx").string();
  write_pmx(test::pmx_humanoid(), r.pmx);
  r.model = test::write_fresh_model(r.dir / "model", 5, canonical_joint_names(), /*local_apparel=*/true,
                                    /*handle_spacing=*/0.05);
  CharacterSpec spec;
  spec.spec = r.pmx;
  r.character = load_character(spec);
  return r;
}

TEST(RigHandles, APmxModelsPhysicsDrivenBonesBecomeTheHandles) {
  const RiggedPmx r = rigged_pmx("rig_handles_pmx");
  const RuntimeCharacter& c = r.character;
  // The humanoid's hair: 髪1 髪2 髪3 on simulated bodies, a box of 8 vertices each skinned BDEF1 to its bone.
  ASSERT_NE(c.rig_bones, nullptr);
  EXPECT_EQ(c.rig_bones->names, (std::vector<std::string>{"髪1", "髪2", "髪3"}));
  EXPECT_EQ(c.rig_bones->parents, (std::vector<int32_t>{-1, 0, 1}));
  ASSERT_EQ(c.rig_apparel_mask.size(), size_t(c.mesh.num_vertices()));
  EXPECT_EQ(std::count(c.rig_apparel_mask.begin(), c.rig_apparel_mask.end(), uint8_t(1)), 24);

  const ModelBundle bundle = load_model_bundle(r.model);
  const int64_t N = c.mesh.num_vertices();
  const at::Tensor V = torch::from_blob(const_cast<float*>(c.mesh.V.data()), {N, 3}, torch::kFloat).clone();
  const at::Tensor F = torch::from_blob(const_cast<int32_t*>(c.mesh.F.data()), {c.mesh.num_faces(), 3}, torch::kInt)
                           .to(torch::kLong);
  const int64_t J = c.skeleton.num_joints();
  const at::Tensor joints =
      torch::from_blob(const_cast<float*>(c.skeleton.rest_joints.data()), {J, 3}, torch::kFloat).clone();
  BindOptions o;
  o.apparel_mask = torch::tensor(std::vector<int64_t>(c.rig_apparel_mask.begin(), c.rig_apparel_mask.end())).to(torch::kBool);
  ASSERT_TRUE(c.rig_bones_with_response);
  o.apparel_bones = c.rig_bones_with_response();
  const BoundCharacter bound = bind_character(bundle, V, F, joints, o);
  ASSERT_EQ(bound.num_apparel(), 24);
  ASSERT_EQ(bound.handle_rows.size(0), 3);  // one handle per bone
  const at::Tensor ids = bound.apparel_ids;
  const ApparelBones& plain = *c.rig_bones;
  EXPECT_EQ(plain.response.rows(), 0);  // measured only when asked for: the probe simulates the rig
  const std::shared_ptr<const ApparelBones> measured = c.rig_bones_with_response();
  const ApparelBones& bones = *measured;
  EXPECT_EQ(bones.names, plain.names);
  EXPECT_EQ(bones.weights, plain.weights);
  for (int h = 0; h < 3; ++h) {
    // The handle's vertex weighs bone h fully (BDEF1), and of the box's 8 such vertices it is the nearest to the
    // bone's head.
    const int64_t v = ids[bound.handle_rows[h].item<int64_t>()].item<int64_t>();
    EXPECT_EQ(bones.indices(v, 0), h) << "handle " << h;
    EXPECT_FLOAT_EQ(bones.weights(v, 0), 1.0f);
    const float own = (c.mesh.V.row(v) - bones.heads.row(h)).norm();
    for (int64_t r2 = 0; r2 < bound.num_apparel(); ++r2) {
      const int64_t u = ids[r2].item<int64_t>();
      if (bones.indices(u, 0) == h) {
        EXPECT_LE(own, (c.mesh.V.row(u) - bones.heads.row(h)).norm() + 1e-6f);
      }
    }
  }
  // Every apparel vertex follows its own bone's handle alone, weights summing to 1.
  const at::Tensor sums = bound.handle_vertex_weights.sum(1);
  EXPECT_LT((sums - 1).abs().max().item<float>(), 1e-6f);
  for (int64_t r2 = 0; r2 < bound.num_apparel(); ++r2) {
    const int64_t v = ids[r2].item<int64_t>();
    EXPECT_EQ(bound.handle_vertex_handles[r2][0].item<int64_t>(), bones.indices(v, 0)) << "vertex " << v;
    EXPECT_FLOAT_EQ(bound.handle_vertex_weights[r2][0].item<float>(), 1.0f);
  }
  // The graph over the handles: the chain 髪1-髪2-髪3.
  ASSERT_EQ(bound.handle_edges.size(0), 2);
  // The bones' physics response, measured on the model's own rigid bodies: all three simulated, and every apparel
  // vertex (BDEF1) reads its own bone's row.
  ASSERT_EQ(bones.response.rows(), 3);
  for (int b = 0; b < 3; ++b) EXPECT_EQ(bones.response(b, 0), 1.0f) << "bone " << b;
  EXPECT_GT(bones.response.col(1).maxCoeff(), 0.0f);
  ASSERT_TRUE(bound.apparel_response.defined());
  ASSERT_EQ(bound.apparel_response.sizes(), (std::vector<int64_t>{24, kApparelResponseChannels}));
  for (int64_t r2 = 0; r2 < bound.num_apparel(); ++r2) {
    const int64_t v = ids[r2].item<int64_t>();
    for (int64_t k = 0; k < kApparelResponseChannels; ++k)
      EXPECT_FLOAT_EQ(bound.apparel_response[r2][k].item<float>(), bones.response(bones.indices(v, 0), k))
          << "vertex " << v << " channel " << k;
  }
  // Without the bones the same bind picks handles automatically along the hair, at the module's spacing, and reads
  // the physics only when given the bones for it.
  o.apparel_bones = nullptr;
  const BoundCharacter automatic = bind_character(bundle, V, F, joints, o);
  EXPECT_GT(automatic.handle_rows.size(0), 0);
  EXPECT_FALSE(automatic.apparel_response.defined());
  o.physics_bones = measured;
  const BoundCharacter with_physics = bind_character(bundle, V, F, joints, o);
  EXPECT_TRUE(at::equal(with_physics.handle_rows, automatic.handle_rows));
  ASSERT_TRUE(with_physics.apparel_response.defined());
  EXPECT_TRUE(at::equal(with_physics.apparel_response, bound.apparel_response));
}

// The bind cache keys on the bones: switching --apparel-handles recomputes the bind instead of loading the other.
TEST(RigHandles, TheBindCacheTellsRigHandlesFromAutomaticOnes) {
  const RiggedPmx r = rigged_pmx("rig_handles_cache");
  const ModelBundle bundle = load_model_bundle(r.model);
  const std::string cache = (r.dir / "humanoid.bind").string();
  const auto& c = r.character;
  const BindResult rig = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.rig_apparel_mask, cache, c.rig_bones);
  EXPECT_FALSE(rig.cache_hit);
  EXPECT_EQ(rig.bound.handle_rows.size(0), 3);
  const BindResult automatic = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.rig_apparel_mask, cache, nullptr);
  EXPECT_FALSE(automatic.cache_hit);
  EXPECT_NE(automatic.bound.handle_rows.size(0), 3);
  const BindResult again = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.rig_apparel_mask, cache, nullptr);
  EXPECT_TRUE(again.cache_hit);
  EXPECT_TRUE(at::equal(again.bound.handle_rows, automatic.bound.handle_rows));
  // The physics response is part of the key, and the cache keeps it.
  const std::shared_ptr<const ApparelBones> measured = c.rig_bones_with_response();
  const BindResult physics =
      bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.rig_apparel_mask, cache, nullptr, {}, measured);
  EXPECT_FALSE(physics.cache_hit);
  ASSERT_TRUE(physics.bound.apparel_response.defined());
  const BindResult physics_again =
      bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.rig_apparel_mask, cache, nullptr, {}, measured);
  EXPECT_TRUE(physics_again.cache_hit);
  EXPECT_TRUE(at::equal(physics_again.bound.apparel_response, physics.bound.apparel_response));
}

TEST(RigHandles, AnimateTakesTheRigsBonesWhenAskedAndNamesThemOtherwise) {
  const RiggedPmx r = rigged_pmx("rig_handles_animate");
  const std::string motion = std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh";
  const auto run = [&](const std::string& handles, const std::string& mask) {
    return test::run_command("cd '" + r.dir.string() + "' && " +
                             test::shell_command(AMT_BINARY, {"animate", "--character", "humanoid.pmx", "--motion",
                                                              motion, "--model", "model", "--frames", "4", "--out",
                                                              "out-" + handles + "-" + mask + ".glb", "--threads", "1",
                                                              "--bind", "none", "--apparel-handles", handles,
                                                              "--apparel-mask", mask}));
  };
  const test::CommandResult automatic = run("auto", "auto");
  ASSERT_EQ(automatic.status, 0) << automatic.err;
  // auto: handles picked automatically (they measure better than the rig's bones), and the rig's bones named.
  EXPECT_NE(automatic.out.find("picked automatically (the rig's 3 apparel bones: --apparel-handles rig)"),
            std::string::npos)
      << automatic.out;
  const test::CommandResult model = run("model", "auto");
  ASSERT_EQ(model.status, 0) << model.err;
  EXPECT_NE(model.out.find("picked automatically"), std::string::npos) << model.out;
  const test::CommandResult rig = run("rig", "rig");
  ASSERT_EQ(rig.status, 0) << rig.err;
  EXPECT_NE(rig.out.find("apparel on 3 handles (8.0 apparel vertices each), the rig's 3 apparel bones "
                         "(--apparel-handles rig)"),
            std::string::npos)
      << rig.out;
  const test::CommandResult bad = run("bones", "auto");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.err.find("--apparel-handles"), std::string::npos) << bad.err;
}

// A model whose training data swung more than this rig does calms the learned apparel, and says so.
TEST(RigHandles, AnimateCalmsTheLearnedSwingOfARigStifferThanTheModelsTrainingData) {
  const RiggedPmx r = rigged_pmx("rig_handles_swing");
  const std::string motion = std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh";
  const auto run = [&](const std::string& out, const std::vector<std::string>& extra, const std::string& bind) {
    std::vector<std::string> args = {
        "animate", "--character", "humanoid.pmx", "--motion", motion,   "--model", "model", "--frames", "4",
        "--out",   out,           "--threads",    "1",        "--bind", bind};
    args.insert(args.end(), extra.begin(), extra.end());
    return test::run_command("cd '" + r.dir.string() + "' && " + test::shell_command(AMT_BINARY, args));
  };
  // Each run succeeds and prints `line` (its "apparel swing:" line or a part of it); its output.
  const auto expect_says = [&](const std::string& out, const std::vector<std::string>& extra, const std::string& line,
                               const std::string& bind = "none") {
    const test::CommandResult result = run(out, extra, bind);
    EXPECT_EQ(result.status, 0) << result.err;
    EXPECT_NE(result.out.find(line), std::string::npos) << result.out;
    return result.out;
  };
  // The fresh model does not know its training data's reference: the module runs as trained.
  expect_says("unknown.glb", {},
              "apparel swing: as trained (--swing-calibration auto: the apparel module does not know");
  // Its training data swung at least 100 times the sway (no rig does): every piece of the hair is calmed.
  const std::string path = (r.dir / "model" / kApparelCheckpoint).string();
  CheckpointInfo info;
  ApparelDynamicsNet net =
      load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(path, ModuleKind::kApparel, info);
  net->options.swing_reference = 100.0;
  test::save_fresh_checkpoint(path, ModuleKind::kApparel, net, options_to_json(net->options), info.joint_names);
  const std::string calmed =
      "apparel swing: calibrated on the rig's own physics (--swing-calibration auto): 100 % of "
      "the apparel calmed";
  expect_says("calmed.glb", {}, calmed);
  // With a calibration motion in the model folder the swing is fitted on the rig's own physics over it instead.
  fs::copy_file(motion, r.dir / "model" / kCalibrationMotion);
  expect_says("fitted.glb", {},
              "apparel swing: fitted on the rig's own physics over 4.0 s of the calibration motion ("
              "calibration_motion.bvh; --swing-calibration auto)");
  // Every calibration_motion*.bvh of the folder joins the fit, in name order.
  fs::copy_file(std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_04.bvh", r.dir / "model" / "calibration_motion_2.bvh");
  const std::string two =
      "apparel swing: fitted on the rig's own physics over 8.0 s of the calibration motions (calibration_motion.bvh, "
      "calibration_motion_2.bvh; --swing-calibration auto)";
  // The bind cache keeps the fit: the second run reads it, and animates exactly as the first; a changed calibration
  // motion is fitted again.
  const std::string first = expect_says("cached.glb", {}, two, "swing.bind");
  EXPECT_EQ(first.find("(from the bind cache)"), std::string::npos) << first;
  const std::string again = expect_says("cached-again.glb", {}, two, "swing.bind");
  EXPECT_NE(again.find("(from the bind cache)"), std::string::npos) << again;
  EXPECT_EQ(test::read_file_bytes(r.dir / "cached.glb"), test::read_file_bytes(r.dir / "cached-again.glb"));
  fs::copy_file(std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_05.bvh", r.dir / "model" / "calibration_motion_2.bvh",
                fs::copy_options::overwrite_existing);
  const std::string changed = expect_says("cached-changed.glb", {}, "apparel swing: fitted", "swing.bind");
  EXPECT_EQ(changed.find("(from the bind cache)"), std::string::npos) << changed;
  fs::remove(r.dir / "model" / "calibration_motion_2.bvh");
  // A damaged calibration motion leaves the probe's calibration, and the run names the file.
  std::ofstream(r.dir / "model" / kCalibrationMotion, std::ios::trunc) << "HIERARCHY\nROOT Hips\n{\n";
  expect_says("damaged.glb", {}, calmed);
  expect_says("damaged.glb", {},
              "(not fitted on the rig's own physics: model/" + std::string(kCalibrationMotion) +
                  ":3: joint 'Hips': expected OFFSET");
  expect_says("off.glb", {"--swing-calibration", "off"}, "apparel swing: as trained (--swing-calibration off)");
  const test::CommandResult bad = run("bad.glb", {"--swing-calibration", "maybe"}, "none");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.err.find("--swing-calibration"), std::string::npos) << bad.err;
}

}  // namespace
}  // namespace amt
