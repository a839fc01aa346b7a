// The runtime end to end on tiny inputs: bind cache hit and invalidation, frame count and fps of the
// output, equality with the pipeline's forward pass (composed independently of the stepper), and the
// bad inputs of issue 6 (clear one-line errors, nothing written).
#include "infer/runtime_torch.h"

#include <gtest/gtest.h>
#include <torch/utils.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/obj_io.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/shapes.h"
#include "models/checkpoint.h"
#include "models/module_options.h"
#include "tests/infer/runtime_fixture.h"
#include "tests/test_support.h"
#include "tests/train/fresh_model.h"
#include "tests/train/micro_dataset.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

using Fixture = test::RuntimeFixture;

Fixture make_fixture(const std::string& name) {
  return test::make_runtime_fixture(name);
}

AnimateOptions options_for(const Fixture& f, const std::string& out) {
  return test::runtime_options(f, out);
}

std::vector<fs::path> files_in(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename());
  std::sort(out.begin(), out.end());
  return out;
}

// The capsules, the fixture's model and a bind cache path in a fresh fixture `name`.
struct BindInputs {
  Fixture f;
  ModelBundle bundle;
  CharacterData c;
  std::string cache;
};

BindInputs bind_inputs(const std::string& name) {
  Fixture f = make_fixture(name);
  ModelBundle bundle = load_model_bundle(f.model);
  CharacterData c = DatasetReader(f.data).read_character("capsules");
  const std::string cache = (f.dir / "capsules.bind").string();
  return {std::move(f), std::move(bundle), std::move(c), cache};
}

TEST(BindCache, HitOnTheSameInputsAndInvalidatedByAChangedMeshOrModel) {
  const auto [f, bundle, c, cache] = bind_inputs("bind_cache");
  const BindResult first = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.apparel_mask, cache);
  EXPECT_FALSE(first.cache_hit);
  EXPECT_EQ(first.reason, "no cache file");
  ASSERT_TRUE(fs::exists(cache));
  const BindResult second = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.apparel_mask, cache);
  EXPECT_TRUE(second.cache_hit) << second.reason;
  EXPECT_TRUE(at::equal(first.bound.body_weights, second.bound.body_weights));
  EXPECT_TRUE(at::equal(first.bound.apparel_neighbors, second.bound.apparel_neighbors));
  EXPECT_TRUE(at::equal(first.bound.apparel_ids, second.bound.apparel_ids));
  EXPECT_TRUE(at::equal(first.bound.G_body, second.bound.G_body));
  // A moved vertex: another key, recomputed, and the file now holds the new bind.
  TriMesh moved = c.mesh;
  moved.V(0, 1) += 0.01f;
  const BindResult third = bind_cached(bundle, moved, c.skeleton.rest_joints, c.apparel_mask, cache);
  EXPECT_FALSE(third.cache_hit);
  EXPECT_NE(third.reason.find("another mesh or model"), std::string::npos) << third.reason;
  EXPECT_TRUE(bind_cached(bundle, moved, c.skeleton.rest_joints, c.apparel_mask, cache).cache_hit);
  // Another mask override, and another model (same architecture, other weights): misses.
  std::vector<uint8_t> other_mask = c.apparel_mask;
  other_mask[0] ^= 1;
  EXPECT_FALSE(bind_cached(bundle, moved, c.skeleton.rest_joints, other_mask, cache).cache_hit);
  test::write_fresh_model(f.dir / "model", 8);
  const ModelBundle retrained = load_model_bundle(f.model);
  EXPECT_FALSE(bind_cached(retrained, moved, c.skeleton.rest_joints, other_mask, cache).cache_hit);
}

// The module for given weights (apparel_own_weights.ckpt) sets the swing calibration of a character bound with them:
// it is part of the key, as the four required checkpoints are.
TEST(BindCache, TheKeyCoversTheApparelModuleForGivenWeights) {
  const auto [f, bundle, c, cache] = bind_inputs("bind_cache_own_weights");
  const fs::path dir = f.dir / "local";
  test::write_fresh_model(dir, 3, canonical_joint_names(), /*local_apparel=*/true);
  const std::string plain = bind_key(c.mesh, c.skeleton.rest_joints, {}, load_model_bundle(dir.string()));
  fs::copy_file(dir / kApparelCheckpoint, dir / kApparelOwnWeightsCheckpoint);
  const std::string own = bind_key(c.mesh, c.skeleton.rest_joints, {}, load_model_bundle(dir.string()));
  EXPECT_NE(own, plain);
  test::write_fresh_model(f.dir / "other", 4, canonical_joint_names(), /*local_apparel=*/true);
  fs::copy_file(f.dir / "other" / kApparelCheckpoint, dir / kApparelOwnWeightsCheckpoint,
                fs::copy_options::overwrite_existing);
  const std::string retrained = bind_key(c.mesh, c.skeleton.rest_joints, {}, load_model_bundle(dir.string()));
  EXPECT_NE(retrained, own);
  EXPECT_NE(retrained, plain);
  EXPECT_EQ(bind_key(c.mesh, c.skeleton.rest_joints, {}, load_model_bundle(dir.string())), retrained);
}

TEST(BindCache, AFlippedByteIsRecomputedAndSaidSo) {
  const auto [f, bundle, c, cache] = bind_inputs("bind_cache_damaged");
  const BindResult first = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.apparel_mask, cache);
  // One flipped bit in the stored rest positions (found by their bytes), as a damaged disk gives.
  std::string bytes = test::read_file_bytes(cache);
  const at::Tensor V = first.bound.V.contiguous();
  const size_t at = bytes.find(std::string(static_cast<const char*>(V.data_ptr()), 36));
  ASSERT_NE(at, std::string::npos);
  bytes[at + 10] ^= 0x10;
  std::ofstream(cache, std::ios::binary) << bytes;
  testing::internal::CaptureStderr();
  const BindResult second = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.apparel_mask, cache);
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_FALSE(second.cache_hit);
  EXPECT_EQ(second.reason, "damaged cache file (checksum mismatch)");
  EXPECT_EQ(said, "amt: " + cache + ": bind cache: damaged cache file (checksum mismatch), recomputing it\n");
  EXPECT_TRUE(at::equal(second.bound.body_weights, first.bound.body_weights));
  // The recomputed cache replaced the damaged one.
  EXPECT_TRUE(bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.apparel_mask, cache).cache_hit);
}

// A swing fitted on the bind rides in its file: read back as written, covered by the checksum (a flipped bit of the
// gain is a damaged file), absent from a file written without one, and refused at write time with the wrong length.
TEST(BindCache, KeepsTheSwingFittedOnTheBindUnderItsChecksum) {
  const auto [f, bundle, c, cache] = bind_inputs("bind_cache_swing");
  const BoundCharacter bound = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.apparel_mask, "").bound;
  const int64_t N_a = bound.num_apparel();
  ASSERT_GT(N_a, 0);
  const at::Tensor gain = at::linspace(0.125, 0.875, N_a, at::kFloat);
  save_bind(cache, "key", bound, CachedSwingFit{"fit-key", "fitted on the rig's own physics", gain});
  BoundCharacter loaded;
  CachedSwingFit fit;
  std::string reason;
  ASSERT_TRUE(load_bind(cache, "key", loaded, &reason, &fit)) << reason;
  EXPECT_EQ(fit.key, "fit-key");
  EXPECT_EQ(fit.text, "fitted on the rig's own physics");
  EXPECT_TRUE(at::equal(fit.gain, gain));
  EXPECT_TRUE(at::equal(loaded.apparel_ids, bound.apparel_ids));
  // One flipped bit in the stored gain (found by its bytes): the checksum no longer matches.
  std::string bytes = test::read_file_bytes(cache);
  const size_t at = bytes.find(std::string(static_cast<const char*>(gain.data_ptr()), 16));
  ASSERT_NE(at, std::string::npos);
  bytes[at + 5] ^= 0x04;
  std::ofstream(cache, std::ios::binary) << bytes;
  EXPECT_FALSE(load_bind(cache, "key", loaded, &reason, &fit));
  EXPECT_EQ(reason, "damaged cache file (checksum mismatch)");
  // Written without a fit: none read back.
  save_bind(cache, "key", bound);
  fit = CachedSwingFit{"stale", "", gain};
  ASSERT_TRUE(load_bind(cache, "key", loaded, &reason, &fit)) << reason;
  EXPECT_TRUE(fit.empty());
  EXPECT_THROW(save_bind(cache, "key", bound, CachedSwingFit{"fit-key", "", gain.narrow(0, 0, N_a - 1)}), Error);
}

TEST(BindCache, StoresWhatHangingChangedInTheMaskAndAnimatePrintsIt) {
  const auto [f, bundle, c, cache] = bind_inputs("bind_cache_hung");
  BoundCharacter bound = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.apparel_mask, "").bound;
  EXPECT_EQ(bound.hung.pinned, 0);  // a given mask is used as it is
  EXPECT_EQ(bound.hung.unnailed, 0);
  bound.hung = HungPieces{2, 1};
  save_bind(cache, "key", bound);
  BoundCharacter loaded;
  std::string reason;
  ASSERT_TRUE(load_bind(cache, "key", loaded, &reason)) << reason;
  EXPECT_EQ(loaded.hung.pinned, 2);
  EXPECT_EQ(loaded.hung.unnailed, 1);
  AnimateSummary summary;
  EXPECT_EQ(describe(summary).find("made to hang"), std::string::npos);
  summary.hung = loaded.hung;
  EXPECT_NE(describe(summary).find("apparel mask made to hang from the body: 2 floating pieces pinned by their "
                                   "lowest-probability vertices, 1 extra body island made apparel\n"),
            std::string::npos)
      << describe(summary);
}

TEST(RuntimeSession, ExplodedOutputNamesTheFrameAndTheStage) {
  const auto [f, bundle, c, cache] = bind_inputs("runtime_exploded");
  const BindResult bind = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.apparel_mask, "");
  const Transforms T = DatasetReader(f.data).read_joint_transforms("walk0", 0, 2);
  const Transforms first(T.begin(), T.begin() + 22), second(T.begin() + 22, T.end());
  MatrixX3f V;
  {
    RuntimeSession healthy(bundle, bind.bound, c.mesh.F, true);
    EXPECT_NO_THROW(healthy.step(first, V));
    EXPECT_TRUE(V.allFinite());
  }
  // A broken apparel module (NaN weights): its output is the first one that is wrong.
  ModelBundle broken = load_model_bundle(f.model);
  torch::NoGradGuard no_grad;
  const auto apparel = broken.local_apparel() ? broken.apparel_dynamics->parameters() : broken.apparel->parameters();
  for (auto p : apparel) p.fill_(std::nanf(""));
  {
    RuntimeSession session(broken, bind.bound, c.mesh.F, false);
    const std::string e = test::error_of([&] { session.step(first, V); });
    EXPECT_EQ(e.rfind("frame 0: apparel module: expected finite positions within ", 0), 0u) << e;
    EXPECT_NE(e.find("found nan nan nan at vertex 0"), std::string::npos) << e;
  }
  // A refiner that moves everything by 1 km: finite, but exploded; frame 1 is named.
  broken = load_model_bundle(f.model);
  {
    RuntimeSession session(broken, bind.bound, c.mesh.F, false);
    session.step(first, V);
    for (auto p : broken.refiner->parameters()) p.fill_(1e3f);
    const std::string e = test::error_of([&] { session.step(second, V); });
    EXPECT_EQ(e.rfind("frame 1: refiner: expected finite positions within ", 0), 0u) << e;
  }
}

// The per-frame check every apparel path runs before writing (the learned path through RuntimeSession, the PMX
// physics through check_frame_output directly): a NaN or a vertex beyond the bound names the frame, the stage and
// the vertex; a frame within it passes.
TEST(CheckFrameOutput, NamesTheFrameTheStageAndTheVertex) {
  MatrixX3f V(3, 3);
  V << 0, 1, 0, 0.5f, 1, 0, 0, 2, 0;
  const Eigen::Vector3f root(0, 1, 0);
  EXPECT_NO_THROW(check_frame_output(V, root, 2.0f, 4, "PMX physics"));
  V(2, 1) = 1e29f;
  EXPECT_EQ(test::error_of([&] { check_frame_output(V, root, 2.0f, 4, "PMX physics"); })
                .rfind("frame 4: PMX physics: expected finite positions within 2 m of the root joint (10 rest sizes), "
                       "found 0 1e+29 0 at vertex 2",
                       0),
            0u);
  V(2, 1) = 2;
  V(1, 0) = std::nanf("");
  EXPECT_NE(test::error_of([&] { check_frame_output(V, root, 2.0f, 0, "PMX physics"); }).find("at vertex 1"),
            std::string::npos);
}

TEST(Animate, GlbHasTheMotionsFramesAndFpsAndPassesTheValidator) {
  const Fixture f = make_fixture("animate_glb");
  AnimateOptions o = options_for(f, (f.dir / "out" / "walk.glb").string());
  const AnimateSummary s = animate(o);
  EXPECT_EQ(s.frames, 30);
  EXPECT_FLOAT_EQ(s.fps, 30.0f);
  EXPECT_TRUE(s.exact_motion);
  EXPECT_FALSE(s.bind_cache_hit);
  EXPECT_EQ(s.bind_path, (f.dir / "out" / "walk.bind").string());
  EXPECT_EQ(s.after.total, 30 * s.apparel_vertices);
  EXPECT_LE(s.after.inside, s.before.inside);
  const GltfAsset asset = read_gltf(o.out);
  EXPECT_EQ(gltf_vertex_animation(asset, "", 30.0f).frames.size(), 30u);
  ASSERT_EQ(asset.animations().size(), 1u);
  EXPECT_NEAR(asset.animations()[0].duration(), 29.0f / 30.0f, 1e-5f);
  test::expect_valid_gltf(o.out);
  // Again: the bind comes from the cache. Resampled to 15 fps and cut to 7 frames.
  o.playback.fps = 15.0f;
  o.playback.frames = 7;
  const AnimateSummary again = animate(o);
  EXPECT_TRUE(again.bind_cache_hit);
  EXPECT_FALSE(again.exact_motion);
  EXPECT_EQ(again.frames, 7);
  const GltfAsset short_asset = read_gltf(o.out);
  EXPECT_EQ(gltf_vertex_animation(short_asset, "", 15.0f).frames.size(), 7u);
  EXPECT_NEAR(short_asset.animations()[0].duration(), 6.0f / 15.0f, 1e-5f);
  EXPECT_EQ(files_in(f.dir / "out"), (std::vector<fs::path>{"walk.bind", "walk.glb"}));
}

// (rows, cols) float tensor -> row-major Eigen matrix.
MatrixXfR to_eigen(const at::Tensor& X) {
  const at::Tensor x = X.to(at::kFloat).contiguous();
  MatrixXfR out(x.size(0), x.size(1));
  std::memcpy(out.data(), x.data_ptr<float>(), size_t(out.size()) * sizeof(float));
  return out;
}

// Rows `ids` (int64 tensor) of V.
MatrixX3f rows_of(const MatrixX3f& V, const at::Tensor& ids) {
  MatrixX3f out(ids.size(0), 3);
  for (int64_t k = 0; k < ids.size(0); ++k) out.row(k) = V.row(ids[k].item<int64_t>());
  return out;
}

// The runtime's dataset output against the paper's forward pass composed here from its parts, without
// the PipelineStepper the runtime runs (and run_pipeline wraps): per frame, B̂ and the apparel anchor S
// by the CPU skinning of data_tools/geometry/lbs.h (eq. 4), Â by the apparel module's own rollout from the rest
// history (eq. 11, the trainer's path), tiled by the mask in mesh order and refined by the refiner's
// unprepared forward over all frames at once (eq. 16). Only the bind (weights, mask, apparel graph) is
// shared.
TEST(Animate, DatasetOutputEqualsThePipelinesForwardPass) {
  const Fixture f = make_fixture("animate_equal");
  AnimateOptions o = options_for(f, (f.dir / "pred.h5").string());
  o.refine = true;  // --refiner
  o.playback.lead_in = 0;
  o.resolve_penetration = false;
  o.bind_path = "none";
  const AnimateSummary s = animate(o);
  ASSERT_EQ(s.frames, 30);
  const ModelBundle bundle = load_model_bundle(f.model);
  ASSERT_FALSE(bundle.local_apparel());  // the fixture's model: the global form, anchored on the skinned body
  ASSERT_TRUE(bundle.apparel->options.skinned_anchor);
  DatasetReader truth(f.data);
  const CharacterData c = truth.read_character("capsules");
  const BindResult bind = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.apparel_mask, "");
  const BoundCharacter& b = bind.bound;
  const int64_t N = b.num_vertices(), Na = b.num_apparel(), Nb = b.num_body(), J = 22;
  ASSERT_GT(Na, 0);
  ASSERT_GT(Nb, 0);
  const Transforms T = truth.read_joint_transforms("walk0", 0, 30);
  const MatrixX3f body_rest = rows_of(c.mesh.V, b.body_ids), apparel_rest = rows_of(c.mesh.V, b.apparel_ids);
  const MatrixXfR body_weights = to_eigen(b.body_weights), anchor_weights = to_eigen(b.apparel_anchor_weights);
  at::Tensor transforms = at::empty({30, J, 3, 4}), body = at::empty({30, Nb, 3}), anchors = at::empty({30, Na, 3});
  for (int t = 0; t < 30; ++t) {
    const Transforms frame(T.begin() + J * t, T.begin() + J * (t + 1));
    for (int j = 0; j < J; ++j)
      std::memcpy(transforms[t][j].data_ptr<float>(), frame[size_t(j)].data(), 12 * sizeof(float));
    const Transforms M = skinning_matrices(c.skeleton, frame);
    MatrixX3f B, S;
    linear_blend_skinning(body_rest, body_weights, M, B);
    linear_blend_skinning(apparel_rest, anchor_weights, M, S);
    std::memcpy(body[t].data_ptr<float>(), B.data(), size_t(B.size()) * sizeof(float));
    std::memcpy(anchors[t].data_ptr<float>(), S.data(), size_t(S.size()) * sizeof(float));
  }
  torch::NoGradGuard no_grad;
  const at::Tensor A_rest = at::from_blob(const_cast<float*>(apparel_rest.data()), {Na, 3}, at::kFloat).clone();
  const at::Tensor A =
      bundle.apparel.ptr()->rollout(A_rest.unsqueeze(0).repeat({3, 1, 1}), transforms, b.apparel_neighbors,
                                    anchors);  // (30, N_a, 3)
  at::Tensor tiled = at::empty({30, N, 3});
  const std::vector<uint8_t>& mask = c.apparel_mask;
  int64_t next_apparel = 0, next_body = 0;
  for (int64_t i = 0; i < N; ++i) {
    tiled.select(1, i).copy_(mask[size_t(i)] ? A.select(1, next_apparel++) : body.select(1, next_body++));
  }
  ASSERT_EQ(next_apparel, Na);
  const at::Tensor expected = bundle.refiner.ptr()->forward(tiled, b.V, b.refiner_prob).V_hat;

  DatasetReader predicted(o.out);
  EXPECT_EQ(predicted.clip_names(), std::vector<std::string>{"walk0"});
  EXPECT_EQ(predicted.character_names(), std::vector<std::string>{"capsules"});
  EXPECT_EQ(predicted.read_character("capsules").apparel_mask, c.apparel_mask);
  const MatrixX3f V = predicted.read_vertices("walk0", 0, 30);
  const at::Tensor got = at::from_blob(const_cast<float*>(V.data()), {30, V.rows() / 30, 3}, at::kFloat);
  EXPECT_LT((got - expected).abs().max().item<float>(), 1e-5f);
  // Evaluation's path (run_pipeline) gives the runtime's frames too.
  const at::Tensor pipeline = run_pipeline(bundle, b, rest_apparel_history(b), transforms);
  EXPECT_LT((got - pipeline).abs().max().item<float>(), 1e-6f);
  // Apparel really moved away from rigid skinning (the model ran): the refiner and apparel step act.
  EXPECT_GT((got[29] - got[0]).abs().max().item<float>(), 0.01f);
  EXPECT_EQ(files_in(f.dir), (std::vector<fs::path>{"mask.txt", "micro.h5", "model", "pred.h5"}));

  // Without --refiner (the default) the output is tile(Â, B̂), the refiner's input, and differs from its output.
  o.refine = false;
  o.out = (f.dir / "plain.h5").string();
  animate(o);
  const MatrixX3f P = DatasetReader(o.out).read_vertices("walk0", 0, 30);
  const at::Tensor plain = at::from_blob(const_cast<float*>(P.data()), {30, P.rows() / 30, 3}, at::kFloat);
  EXPECT_LT((plain - tiled).abs().max().item<float>(), 1e-5f);
  EXPECT_GT((plain - expected).abs().max().item<float>(), 1e-4f);
}

// The default form of the apparel module (local, on handles) through `amt animate` equals, frame for frame, what
// evaluation scores for it (run_pipeline on the same bind): the runtime's lead-in, streaming and writer add nothing.
// The module is fresh with a random last layer, so the apparel moves away from the rule it is built around.
TEST(Animate, TheLocalModuleOnHandlesWritesWhatEvaluationScores) {
  const Fixture f = make_fixture("animate_local_equal");
  const std::string model = test::write_fresh_model(f.dir / "local", 7, canonical_joint_names(),
                                                    /*local_apparel=*/true, /*handle_spacing=*/0.03);
  AnimateOptions o = options_for(f, (f.dir / "pred.h5").string());
  o.model_dir = model;
  o.playback.lead_in = 0;
  o.resolve_penetration = false;
  o.bind_path = "none";
  const AnimateSummary s = animate(o);
  ASSERT_EQ(s.frames, 30);
  EXPECT_GT(s.handles, 0);
  const ModelBundle bundle = load_model_bundle(model);
  ASSERT_TRUE(bundle.local_apparel());
  DatasetReader truth(f.data);
  const CharacterData c = truth.read_character("capsules");
  const BindResult bind = bind_cached(bundle, c.mesh, c.skeleton.rest_joints, c.apparel_mask, "");
  ASSERT_GT(bind.bound.handle_rows.size(0), 0);
  const int64_t J = 22;
  const Transforms T = truth.read_joint_transforms("walk0", 0, 30);
  at::Tensor transforms = at::empty({30, J, 3, 4});
  for (int t = 0; t < 30; ++t)
    for (int j = 0; j < J; ++j)
      std::memcpy(transforms[t][j].data_ptr<float>(), T[size_t(t * J + j)].data(), 12 * sizeof(float));
  torch::NoGradGuard no_grad;
  const at::Tensor expected =
      run_pipeline(bundle, bind.bound, rest_apparel_history(bind.bound), transforms, PipelineStages::kBodyApparel);
  const MatrixX3f V = DatasetReader(o.out).read_vertices("walk0", 0, 30);
  const at::Tensor got = at::from_blob(const_cast<float*>(V.data()), {30, V.rows() / 30, 3}, at::kFloat);
  EXPECT_LT((got - expected).abs().max().item<float>(), 1e-5f);
  // The apparel moved with the walk, and away from where rigid skinning by its anchors would put it.
  const MatrixXfR anchor = anchor_skinning_weights(bind.bound);
  MatrixX3f rigid;
  linear_blend_skinning(c.mesh.V, anchor,
                        skinning_matrices(c.skeleton, Transforms(T.begin() + 29 * J, T.begin() + 30 * J)), rigid);
  const at::Tensor rigid_t = at::from_blob(rigid.data(), {rigid.rows(), 3}, at::kFloat);
  EXPECT_GT((got[29] - got[0]).abs().max().item<float>(), 0.01f);
  EXPECT_GT((got[29] - rigid_t).abs().max().item<float>(), 1e-3f);
}

TEST(Animate, BadInputGivesOneLineErrorsAndWritesNothing) {
  const Fixture f = make_fixture("animate_bad");
  const fs::path out_dir = f.dir / "out";
  // A character without joints and no joints file.
  {
    AnimateOptions o = options_for(f, (out_dir / "a.glb").string());
    o.character.spec = (f.dir / "blob.obj").string();
    write_obj(o.character.spec, uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 8, 6));
    const std::string e = test::error_of([&] { animate(o); });
    EXPECT_NE(e.find("blob.obj: joints: the character has no skeleton"), std::string::npos) << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  }
  // A motion whose skeleton cannot be mapped.
  {
    AnimateOptions o = options_for(f, (out_dir / "b.glb").string());
    o.motion.spec = (f.dir / "tentacle.bvh").string();
    std::ofstream(o.motion.spec) << "HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n"
                                    " JOINT b\n {\n  OFFSET 0 10 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
                                    "  End Site\n  {\n   OFFSET 0 10 0\n  }\n }\n}\nMOTION\nFrames: 2\n"
                                    "Frame Time: 0.0333333\n0 0 0 0 0 0\n0 0 0 0 10 0\n";
    const std::string e = test::error_of([&] { animate(o); });
    EXPECT_NE(e.find("tentacle.bvh"), std::string::npos) << e;
    EXPECT_NE(e.find("--motion-joint-map"), std::string::npos) << e;
  }
  // A model trained on another skeleton.
  {
    std::vector<std::string> names;
    for (int j = 0; j < 22; ++j) names.push_back("bone" + std::to_string(j));
    AnimateOptions o = options_for(f, (out_dir / "c.glb").string());
    o.model_dir = test::write_fresh_model(f.dir / "other_model", 7, names);
    const std::string e = test::error_of([&] { animate(o); });
    EXPECT_NE(e.find("other_model"), std::string::npos) << e;
    EXPECT_NE(e.find("bone0"), std::string::npos) << e;
  }
  // An unwritable output: a folder below a regular file.
  {
    std::ofstream(f.dir / "plain_file") << "x";
    AnimateOptions o = options_for(f, (f.dir / "plain_file" / "d.glb").string());
    const std::string e = test::error_of([&] { animate(o); });
    EXPECT_NE(e.find("d.glb: --out: expected a writable location"), std::string::npos) << e;
  }
  // Output names that are not an output kind.
  {
    AnimateOptions o = options_for(f, (out_dir / "e.gltf").string());
    EXPECT_NE(test::error_of([&] { animate(o); }).find("expected .glb"), std::string::npos);
  }
  EXPECT_FALSE(fs::exists(out_dir) && !fs::is_empty(out_dir));
}

TEST(Animate, ObjFolderHasOneFilePerFrame) {
  const Fixture f = make_fixture("animate_obj");
  AnimateOptions o = options_for(f, (f.dir / "frames").string());
  o.playback.frames = 3;
  const AnimateSummary s = animate(o);
  EXPECT_EQ(s.frames, 3);
  EXPECT_EQ(files_in(f.dir / "frames"),
            (std::vector<fs::path>{".amt-output", "frame_0000.obj", "frame_0001.obj", "frame_0002.obj"}));
  EXPECT_EQ(read_obj((f.dir / "frames" / "frame_0002.obj").string()).num_vertices(), s.vertices);
  EXPECT_TRUE(fs::exists(f.dir / "frames.bind"));
}

}  // namespace
}  // namespace amt
