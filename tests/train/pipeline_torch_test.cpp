// Tests of models/pipeline.h: bundle loading errors, bind equal to the trainer's per-character tensors,
// the stepper equal to the networks run on whole sequences, the motion lead-in.
#include "models/pipeline.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/utils.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <tuple>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/lbs_torch.h"
#include "data_tools/geometry/segmentation_features.h"
#include "data_tools/geometry/skeleton.h"
#include "fresh_model.h"
#include "micro_dataset.h"
#include "models/module_options.h"
#include "train/samples.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

// === Helpers

// A model folder of freshly initialised (seeded) modules in the test's scratch folder.
std::string write_fresh_bundle(const std::string& name,
                               const std::vector<std::string>& joints = canonical_joint_names()) {
  return test::write_fresh_model(test::test_directory(name), 7, joints);
}

struct MicroCharacter {
  CharacterData data;
  at::Tensor V, F, joints, mask;
};

// The first `frames` frames of the micro dataset's clip walk0: joint transforms (T, J, 3, 4) and
// ground-truth vertices (T, N, 3).
std::pair<at::Tensor, at::Tensor> read_walk(const std::string& path, int frames) {
  DatasetReader reader(path);
  const int J = reader.num_joints();
  const Transforms transforms = reader.read_joint_transforms("walk0", 0, frames);
  at::Tensor motion = at::empty({frames, J, 3, 4});
  for (int i = 0; i < frames * J; ++i)
    std::memcpy(motion.data_ptr<float>() + 12 * i, transforms[i].data(), 12 * sizeof(float));
  const MatrixX3f gt = reader.read_vertices("walk0", 0, frames);
  const int64_t N = gt.rows() / frames;
  return {motion, at::from_blob(const_cast<float*>(gt.data()), {frames, N, 3}, at::kFloat).clone()};
}

MicroCharacter read_micro(const std::string& path) {
  DatasetReader reader(path);
  MicroCharacter c;
  c.data = reader.read_character(reader.character_names().front());
  const int64_t N = c.data.mesh.num_vertices(), J = c.data.skeleton.num_joints();
  c.V = at::from_blob(c.data.mesh.V.data(), {N, 3}, at::kFloat).clone();
  c.F = at::from_blob(c.data.mesh.F.data(), {c.data.mesh.F.rows(), 3}, at::kInt).clone();
  c.joints = at::from_blob(c.data.skeleton.rest_joints.data(), {J, 3}, at::kFloat).clone();
  c.mask = at::from_blob(c.data.apparel_mask.data(), {N}, at::kByte).to(at::kBool);
  return c;
}

// === Loading

TEST(PipelineBundle, LoadsFourModulesInEvalMode) {
  test::use_one_thread();
  const std::string dir = write_fresh_bundle("bundle_ok");
  const ModelBundle bundle = load_model_bundle(dir);
  EXPECT_EQ(bundle.num_joints(), 22);
  EXPECT_EQ(bundle.infos.size(), 4u);
  EXPECT_FALSE(bundle.segmenter->is_training());
  EXPECT_FALSE(bundle.refiner->is_training());
  EXPECT_TRUE(bundle.skinning_no_geodesic.is_empty());
  EXPECT_NE(test::error_of([&] { bundle.skinning_for(SkinningVariant::kSortByGeodesic); }).find("skinning_sorted.ckpt"),
            std::string::npos);
}

TEST(PipelineBundle, ClearErrors) {
  test::use_one_thread();
  const std::string dir = write_fresh_bundle("bundle_errors");
  EXPECT_NE(test::error_of([&] { load_model_bundle(dir + "/nowhere"); }).find("no such model folder"),
            std::string::npos);

  fs::rename(dir + "/apparel.ckpt", dir + "/apparel.bak");
  EXPECT_EQ(test::error_of([&] { load_model_bundle(dir); }),
            dir + "/apparel.ckpt: no such checkpoint (train it with amt train apparel)");

  fs::copy_file(dir + "/segmenter.ckpt", dir + "/apparel.ckpt");  // another kind
  EXPECT_EQ(test::error_of([&] { load_model_bundle(dir); }),
            dir + "/apparel.ckpt: kind: expected 'apparel', found 'segmenter'");
  fs::remove(dir + "/apparel.ckpt");
  fs::rename(dir + "/apparel.bak", dir + "/apparel.ckpt");

  // A refiner trained on another skeleton.
  std::vector<std::string> other = canonical_joint_names();
  other[3] = "chest";
  const std::string other_dir = write_fresh_bundle("bundle_other", other);
  fs::copy_file(other_dir + "/refiner.ckpt", dir + "/refiner.ckpt", fs::copy_options::overwrite_existing);
  const std::string message = test::error_of([&] { load_model_bundle(dir); });
  EXPECT_NE(message.find(dir + "/refiner.ckpt: skeleton: trained on 22 joints"), std::string::npos) << message;
  EXPECT_NE(message.find("must share one skeleton"), std::string::npos) << message;
}

TEST(PipelineBundle, SegmenterCheckpointsOfEachInputsLoadAndReadTheirOwnFeatures) {
  // Old checkpoints (positions alone, "shape" features: the shipped segmenter) load as they were
  // written and are scored on the features they were trained on, as are new ("welded") ones.
  test::use_one_thread();
  const std::string dir = test::test_directory("segmenter_inputs");
  const Skeleton skeleton = canonical_skeleton();
  MatrixX3f V(6, 3);
  V << 0, 0, 0, 0.3f, 0, 0, 0, 1.7f, 0, 0.5f, 1, 0.1f, 0.7f, 1, 0.1f, 0.6f, 1.2f, 0.1f;
  MatrixX3i F(2, 3);
  F << 0, 1, 2, 3, 4, 5;
  for (const std::string inputs : {"positions", "shape", "welded"}) {
    torch::manual_seed(3);
    ApparelSegmenterOptions so;
    so.encoder_widths = {8, 16};
    so.decoder_widths = {8};
    so.inputs = inputs;
    const std::string path = dir + "/" + inputs + ".ckpt";
    ApparelSegmenter net(so);
    test::save_fresh_checkpoint(path, ModuleKind::kSegmenter, net, options_to_json(so), canonical_joint_names());
    const ModelBundle bundle = load_segmenter_bundle(path);
    EXPECT_EQ(bundle.segmenter->options.inputs, inputs);
    EXPECT_FALSE(bundle.segmenter->is_training());
    const MatrixXfR X = segmenter_input_features(inputs, V, F, skeleton.rest_joints, canonical_joint_parents());
    EXPECT_EQ(X.cols(), inputs == "positions" ? 0 : kSegmentationFeatures);
    const at::Tensor V_t = at::from_blob(V.data(), {6, 3}, at::kFloat);
    const at::Tensor X_t = at::from_blob(const_cast<float*>(X.data()), {6, X.cols()}, at::kFloat);
    torch::NoGradGuard no_grad;
    const at::Tensor expected = net->probabilities(V_t, inputs == "positions" ? at::Tensor() : X_t);
    EXPECT_TRUE(at::allclose(apparel_probabilities(bundle, V, F, skeleton.rest_joints), expected, 1e-5, 1e-6))
        << inputs;
  }
  EXPECT_NE(test::error_of([&] { load_segmenter_bundle(dir + "/nowhere.ckpt"); }).find("no such checkpoint"),
            std::string::npos);
}

// === Bind

// Each piece hangs from one place: a piece the mask calls apparel from end to end is held by its vertices of lowest
// p̂ (ceil(share * size) of them, ties by index); a piece held in several places keeps its largest body island; a
// part mostly body, and a mesh with no body at all, keep their masks.
TEST(PipelineBind, ApparelPiecesHangFromOnePlace) {
  // Four chains: 0-3 body but vertex 2 (two body islands, but mostly body); 4-23 all apparel, p̂ falling from
  // 0.99 to 0.80 but for vertices 10 and 11 at 0.55; 24-27 apparel but vertex 24; 28-39 apparel but 28, 29 and
  // 34 (two islands: {28, 29} and the nail {34}).
  std::vector<std::pair<int, int>> chain;
  for (const auto& [first, last] : {std::pair{0, 3}, std::pair{4, 23}, std::pair{24, 27}, std::pair{28, 39}})
    for (int i = first; i < last; ++i) chain.emplace_back(i, i + 1);
  MatrixX2i E(static_cast<Eigen::Index>(chain.size()), 2);
  for (size_t k = 0; k < chain.size(); ++k) E.row(Eigen::Index(k)) << chain[k].first, chain[k].second;
  at::Tensor mask = at::ones({40}, at::kBool), prob = at::full({40}, 0.9f);
  for (const int i : {0, 1, 3, 24, 28, 29, 34}) mask[i] = false, prob[i] = 0.2f;
  prob[34] = 0.45f;
  for (int i = 4; i < 24; ++i) prob[i] = 0.99f - 0.01f * float(i - 4);
  prob[10] = prob[11] = 0.55f;

  HungPieces hung;
  const at::Tensor one = hang_apparel_pieces(mask, prob, E, 0.05, &hung);  // ceil(0.05 * 20) = 1
  EXPECT_EQ(hung.pinned, 1);
  EXPECT_EQ(hung.unnailed, 1);
  at::Tensor expected = mask.clone();
  expected[10] = false;  // 0.55 twice: the lower index
  expected[34] = true;   // the nail
  EXPECT_TRUE(at::equal(one, expected)) << one;
  const at::Tensor three = hang_apparel_pieces(mask, prob, E, 0.15);  // 0.15 * 20 = 3: 10, 11, then 23 (0.80)
  expected[11] = expected[23] = false;
  EXPECT_TRUE(at::equal(three, expected)) << three;
  EXPECT_TRUE(at::equal(hang_apparel_pieces(at::ones({40}, at::kBool), prob, E, 0.05), at::ones({40}, at::kBool)))
      << "no body anywhere: nothing to hang from";
  EXPECT_NE(test::error_of([&] { hang_apparel_pieces(mask, prob.narrow(0, 0, 5), E); }).find("hang_apparel_pieces"),
            std::string::npos);
}

TEST(PipelineBind, MatchesTheTrainersCharacterTensors) {
  test::use_one_thread();
  const std::string dir = write_fresh_bundle("bind_bundle");
  const std::string data = test::test_directory("bind_data") + "/micro.h5";
  test::write_micro_dataset(data, {200, 12, 1, {}});
  const ModelBundle bundle = load_model_bundle(dir);
  const MicroCharacter c = read_micro(data);

  BindOptions options;
  options.apparel_mask = c.mask;  // the ground truth, as the trainer uses
  options.all_vertex_weights = true;
  const BoundCharacter b = bind_character(bundle, c.V, c.F, c.joints, options);

  SampleSourceOptions so;
  so.kind = ModuleKind::kSkinning;
  so.frames = 4;
  SampleSource source({data}, so);
  const auto t = source.character(0);
  EXPECT_TRUE(at::equal(b.apparel_ids, t->apparel_ids));
  EXPECT_TRUE(at::equal(b.body_ids, t->body_ids));
  EXPECT_TRUE(at::equal(b.edges, t->edges));
  EXPECT_TRUE(at::equal(b.body_edges, t->body_edges));
  EXPECT_TRUE(at::equal(b.apparel_edges, t->apparel_edges));
  EXPECT_TRUE(at::equal(b.apparel_neighbors, t->apparel_neighbors));
  EXPECT_TRUE(at::equal(b.G_body, t->G_body));
  torch::NoGradGuard no_grad;
  const at::Tensor W = bundle.skinning.ptr()->forward(t->V.index_select(0, t->body_ids), t->joints, t->G_body);
  EXPECT_TRUE(at::equal(b.body_weights, W));

  // Shapes, probabilities, weights of every vertex (body rows = the body part's).
  const int64_t N = c.V.size(0), N_a = b.num_apparel(), N_b = b.num_body();
  EXPECT_GT(N_a, 0);
  EXPECT_EQ(N_a + N_b, N);
  EXPECT_EQ(b.apparel_prob.sizes(), (at::IntArrayRef{N}));
  EXPECT_TRUE(at::all(b.apparel_prob.ge(0) & b.apparel_prob.le(1)).item<bool>());
  EXPECT_EQ(b.vertex_weights.sizes(), (at::IntArrayRef{N, 22}));
  EXPECT_TRUE(at::allclose(b.vertex_weights.sum(1), at::ones({N}), 1e-5, 1e-5));
  EXPECT_TRUE(at::equal(b.vertex_weights.index_select(0, b.body_ids), b.body_weights));
  EXPECT_TRUE(at::equal(b.refiner_prob, c.mask.to(at::kFloat)));

  // Without an override the mask is p̂ > 0.5.
  const BoundCharacter predicted = bind_character(bundle, c.V, c.F, c.joints);
  EXPECT_TRUE(at::equal(predicted.apparel_mask, predicted.apparel_prob.gt(0.5)));

  EXPECT_EQ(test::error_of([&] { bind_character(bundle, c.V, c.F, c.joints.narrow(0, 0, 21)); }),
            "bind: joints: expected (22, 3) rest joints (the model's skeleton), found [21, 3]");
  BindOptions bad;
  bad.apparel_mask = c.mask.narrow(0, 0, 10);
  EXPECT_EQ(test::error_of([&] { bind_character(bundle, c.V, c.F, c.joints, bad); }),
            "bind: apparel mask: expected " + std::to_string(c.V.size(0)) + " values (one per vertex), found 10");
}

// === Stepping

TEST(PipelineStepper, EqualsRolloutPlusRefinerOnTheSameInputs) {
  test::use_one_thread();
  const std::string dir = write_fresh_bundle("step_bundle");
  const std::string data = test::test_directory("step_data") + "/micro.h5";
  test::write_micro_dataset(data, {200, 12, 1, {}});
  const ModelBundle bundle = load_model_bundle(dir);
  const MicroCharacter c = read_micro(data);
  BindOptions options;
  options.apparel_mask = c.mask;
  const BoundCharacter b = bind_character(bundle, c.V, c.F, c.joints, options);

  const int T = 10;
  const int64_t N = c.V.size(0);
  at::Tensor motion, V_gt;
  std::tie(motion, V_gt) = read_walk(data, T);
  const at::Tensor history = V_gt.index_select(1, b.apparel_ids).narrow(0, 0, 3);

  PipelineStepper stepper(bundle, b, history);
  std::vector<at::Tensor> V_hat, A_hat, B_hat;
  for (int t = 3; t < T; ++t) {
    const StepOutput out = stepper.step_detailed(motion[t]);
    EXPECT_EQ(out.V_hat.sizes(), (at::IntArrayRef{N, 3}));
    V_hat.push_back(out.V_hat.clone());
    A_hat.push_back(out.A_hat.clone());
    B_hat.push_back(out.B_hat.clone());
  }
  EXPECT_EQ(stepper.frames(), T - 3);

  // The same through the networks' sequence forms, as the trainer runs them.
  torch::NoGradGuard no_grad;
  const at::Tensor future = motion.narrow(0, 3, T - 3);
  const at::Tensor anchors =
      linear_blend_skinning(c.V.index_select(0, b.apparel_ids), b.apparel_anchor_weights, future, c.joints);
  const at::Tensor A_ref = bundle.apparel.ptr()->rollout(history, future, b.apparel_neighbors, anchors);
  const at::Tensor B_ref = linear_blend_skinning(c.V.index_select(0, b.body_ids), b.body_weights, future, c.joints);
  const at::Tensor V_ref =
      bundle.refiner.ptr()->forward(tile_apparel_body(A_ref, B_ref, b.apparel_mask), c.V, c.mask.to(at::kFloat)).V_hat;
  EXPECT_TRUE(at::allclose(at::stack(A_hat), A_ref, 1e-5, 1e-6));
  EXPECT_TRUE(at::allclose(at::stack(B_hat), B_ref, 1e-5, 1e-6));
  EXPECT_TRUE(at::allclose(at::stack(V_hat), V_ref, 1e-5, 1e-6));
  // The refiner changed something (it is not the identity), so the comparison covers it.
  EXPECT_GT((V_ref - tile_apparel_body(A_ref, B_ref, b.apparel_mask)).abs().max().item<float>(), 1e-4f);

  // run_pipeline is the same loop; body + apparel is the tiled result.
  EXPECT_TRUE(at::allclose(run_pipeline(bundle, b, history, future), V_ref, 1e-5, 1e-6));
  EXPECT_TRUE(at::allclose(run_pipeline(bundle, b, history, future, PipelineStages::kBodyApparel),
                           tile_apparel_body(A_ref, B_ref, b.apparel_mask), 1e-5, 1e-6));
  EXPECT_EQ(test::error_of([&] { PipelineStepper(bundle, b, history, PipelineStages::kBodyOnly); }),
            "pipeline: body only needs weights of every vertex (bind with BindOptions::all_vertex_weights or "
            "BindOptions::weights)");
  EXPECT_EQ(test::error_of([&] { PipelineStepper(bundle, b, history.narrow(0, 0, 2)); }),
            "pipeline: apparel history: expected (3, " + std::to_string(b.num_apparel()) + ", 3), found [2, " +
                std::to_string(b.num_apparel()) + ", 3]");
}

TEST(PipelineStepper, LocalModuleAndRulesMeasureDetailsFromTheHistorysFrames) {
  test::use_one_thread();
  const std::string dir = test::write_fresh_model(test::test_directory("step_local_bundle"), 5, canonical_joint_names(),
                                                  /*local_apparel=*/true);
  const std::string data = test::test_directory("step_local_data") + "/micro.h5";
  test::write_micro_dataset(data, {200, 12, 1, {}});
  const ModelBundle bundle = load_model_bundle(dir);
  ASSERT_TRUE(bundle.local_apparel());
  const MicroCharacter c = read_micro(data);
  BindOptions options;
  options.apparel_mask = c.mask;
  const BoundCharacter b = bind_character(bundle, c.V, c.F, c.joints, options);
  ASSERT_GT(b.num_apparel(), 0);
  EXPECT_EQ(b.apparel_frame_joints.sizes(), (at::IntArrayRef{b.num_apparel()}));
  EXPECT_EQ(b.apparel_rest_features.sizes(), (at::IntArrayRef{b.num_apparel(), kApparelRestChannels}));

  const int T = 10;
  at::Tensor motion, V_gt;
  std::tie(motion, V_gt) = read_walk(data, T);
  const at::Tensor history = V_gt.index_select(1, b.apparel_ids).narrow(0, 0, 3);
  const at::Tensor anchors =
      linear_blend_skinning(c.V.index_select(0, b.apparel_ids), b.apparel_anchor_weights, motion, c.joints);

  // The stepper, reset on ground-truth states with their frames' motion, equals the module's rollout
  // over the same frames (an off-by-one in the stepper's motion or anchor history would not).
  PipelineStepper stepper(bundle, b, history, PipelineStages::kBodyApparel);
  stepper.set_strain_limit(0.0f);  // the module's raw output
  stepper.reset(history, motion.narrow(0, 0, 3));
  std::vector<at::Tensor> A_hat;
  for (int t = 3; t < T; ++t) A_hat.push_back(stepper.step_detailed(motion[t]).A_hat.clone());
  torch::NoGradGuard no_grad;
  const at::Tensor A_ref = bundle.apparel_dynamics.ptr()->rollout(history, motion, anchors, b.apparel_graph());
  EXPECT_TRUE(at::allclose(at::stack(A_hat), A_ref, 1e-5, 1e-6));
  EXPECT_GT((A_ref - anchors.narrow(0, 3, T - 3)).abs().max().item<float>(), 1e-4f);  // the network acts

  // hold_offset from the rest pose: every detail vector is 0, so the apparel is exactly its anchor.
  PipelineStepper hold(bundle, b, rest_apparel_history(b), PipelineStages::kBodyApparel, ApparelSource::kHoldOffset);
  for (int t = 0; t < 4; ++t) {
    const at::Tensor A = hold.step_detailed(motion[t]).A_hat;
    EXPECT_LT((A - anchors[t]).abs().max().item<float>(), 1e-5f) << t;
  }
  // Without the history's motion the detail vectors are measured against the rest pose: different.
  PipelineStepper unaware(bundle, b, history, PipelineStages::kBodyApparel, ApparelSource::kHoldOffset);
  PipelineStepper aware(bundle, b, history, PipelineStages::kBodyApparel, ApparelSource::kHoldOffset);
  aware.reset(history, motion.narrow(0, 0, 3));
  EXPECT_GT((unaware.step_detailed(motion[3]).A_hat - aware.step_detailed(motion[3]).A_hat).abs().max().item<float>(),
            1e-4f);
}

// The largest length over rest length of the linked edges with an apparel end (rest at least 1 mm) in V (N, 3).
// The smallest and largest length over rest length of the mesh edges with an apparel end (rest above 1 mm), the
// edges the stepper's strain limit bounds.
std::pair<float, float> stretch_range(const BoundCharacter& b, const at::Tensor& V) {
  const at::Tensor E = b.edges.to(at::kLong);
  const at::Tensor apparel = b.apparel_mask.to(at::kBool);
  const at::Tensor keep = apparel.index_select(0, E.select(1, 0)).logical_or(apparel.index_select(0, E.select(1, 1)));
  const at::Tensor kept = E.index({keep});
  const at::Tensor rest = (b.V.index_select(0, kept.select(1, 0)) - b.V.index_select(0, kept.select(1, 1))).norm(2, 1);
  const at::Tensor now = (V.index_select(0, kept.select(1, 0)) - V.index_select(0, kept.select(1, 1))).norm(2, 1);
  const at::Tensor long_enough = rest.gt(1e-3);
  const at::Tensor ratio = now.index({long_enough}) / rest.index({long_enough});
  return {ratio.min().item<float>(), ratio.max().item<float>()};
}

TEST(PipelineStepper, TheStrainLimitBoundsTheModulesStretchAndLeavesTheRulesAlone) {
  test::use_one_thread();
  const std::string dir = test::write_fresh_model(test::test_directory("strain_bundle"), 5, canonical_joint_names(),
                                                  /*local_apparel=*/true);
  const std::string data = test::test_directory("strain_data") + "/micro.h5";
  test::write_micro_dataset(data, {200, 12, 1, {}});
  const ModelBundle bundle = load_model_bundle(dir);
  const MicroCharacter c = read_micro(data);
  BindOptions options;
  options.apparel_mask = c.mask;
  const BoundCharacter b = bind_character(bundle, c.V, c.F, c.joints, options);
  ASSERT_GT(b.num_apparel(), 0);
  at::Tensor motion, V_gt;
  std::tie(motion, V_gt) = read_walk(data, 4);
  // A history of the apparel stretched to twice its size about its centre: the module carries the stretch on.
  const at::Tensor A_rest = b.V.index_select(0, b.apparel_ids);
  const at::Tensor centre = A_rest.mean(0, true);
  const at::Tensor stretched = (centre + 2.0f * (A_rest - centre)).unsqueeze(0).repeat({3, 1, 1});

  PipelineStepper raw(bundle, b, stretched, PipelineStages::kBodyApparel);
  raw.set_strain_limit(0.0f);
  PipelineStepper limited(bundle, b, stretched, PipelineStages::kBodyApparel);
  EXPECT_EQ(raw.strain_limit(), 0.0f);
  EXPECT_EQ(limited.strain_limit(), kDefaultStrainLimit);
  const StepOutput r = raw.step_detailed(motion[3]);
  const StepOutput l = limited.step_detailed(motion[3]);
  const float before = stretch_range(b, r.V_hat).second, after = stretch_range(b, l.V_hat).second;
  EXPECT_GT(before, 1.5f);
  EXPECT_LT(after, before - 0.2f) << before << " -> " << after;
  // Only apparel vertices move; the body is the same.
  EXPECT_TRUE(at::equal(r.B_hat, l.B_hat));
  // The limited output is the history: the next step starts from it (differs from the raw stepper's).
  EXPECT_TRUE(at::equal(limited.history()[2], l.A_hat));

  // Squashed to 0.3 of its size: a floor of 0.7 opens the edges back towards it.
  const at::Tensor squashed = (centre + 0.3f * (A_rest - centre)).unsqueeze(0).repeat({3, 1, 1});
  PipelineStepper raw_squashed(bundle, b, squashed, PipelineStages::kBodyApparel);
  raw_squashed.set_strain_limit(0.0f);
  PipelineStepper floored(bundle, b, squashed, PipelineStages::kBodyApparel);
  floored.set_strain_limit(kDefaultStrainLimit, kStrainLimitIterations, 0.7f);
  const float least_raw = stretch_range(b, raw_squashed.step_detailed(motion[3]).V_hat).first;
  const float least = stretch_range(b, floored.step_detailed(motion[3]).V_hat).first;
  EXPECT_LT(least_raw, 0.5f);
  EXPECT_GT(least, least_raw + 0.2f) << least_raw << " -> " << least;
  // Without a floor only the stretch is bounded: the squash stays as the module made it.
  PipelineStepper stretch_only(bundle, b, squashed, PipelineStages::kBodyApparel);
  stretch_only.set_strain_limit(kDefaultStrainLimit, kStrainLimitIterations, 0.0f);
  EXPECT_LT(stretch_range(b, stretch_only.step_detailed(motion[3]).V_hat).first, least_raw + 0.05f);

  // The rules are not limited: hold_offset is its anchor-carried detail whatever the setting.
  PipelineStepper hold(bundle, b, stretched, PipelineStages::kBodyApparel, ApparelSource::kHoldOffset);
  PipelineStepper hold_raw(bundle, b, stretched, PipelineStages::kBodyApparel, ApparelSource::kHoldOffset);
  hold_raw.set_strain_limit(0.0f);
  EXPECT_EQ(hold.strain_limit(), 0.0f);
  EXPECT_TRUE(at::equal(hold.step_detailed(motion[3]).A_hat, hold_raw.step_detailed(motion[3]).A_hat));
}

// With apparel_own_weights.ckpt in the model folder, a character bound with given weights (its own skin) steps with
// that module and one with predicted weights with apparel.ckpt: each output equals that of a model folder holding
// only the module it should use.
TEST(PipelineStepper, GivenWeightsStepWithTheOwnWeightsModule) {
  test::use_one_thread();
  namespace fs = std::filesystem;
  const fs::path root = test::test_directory("own_weights_bundle");
  const std::string a = test::write_fresh_model(root / "a", 5, canonical_joint_names(), /*local_apparel=*/true);
  const std::string b = test::write_fresh_model(root / "b", 6, canonical_joint_names(), /*local_apparel=*/true);
  fs::create_directories(root / "both");
  for (const auto& entry : fs::directory_iterator(a))
    fs::copy_file(entry.path(), root / "both" / entry.path().filename(), fs::copy_options::overwrite_existing);
  fs::copy_file(fs::path(b) / kApparelCheckpoint, root / "both" / kApparelOwnWeightsCheckpoint,
                fs::copy_options::overwrite_existing);
  const ModelBundle only_a = load_model_bundle(a), only_b = load_model_bundle(b);
  const ModelBundle both = load_model_bundle((root / "both").string());
  ASSERT_FALSE(both.apparel_dynamics_own_weights.is_empty());
  EXPECT_TRUE(only_a.apparel_dynamics_own_weights.is_empty());

  const std::string data = test::test_directory("own_weights_data") + "/micro.h5";
  test::write_micro_dataset(data, {200, 12, 1, {}});
  const MicroCharacter c = read_micro(data);
  const at::Tensor motion = read_walk(data, 3).first;
  const auto run = [&](const ModelBundle& bundle, bool given) {
    BindOptions options;
    options.apparel_mask = c.mask;
    if (given)
      options.weights =
          at::from_blob(const_cast<float*>(c.data.body_weights.data()), {c.V.size(0), 22}, at::kFloat).clone();
    const BoundCharacter bound = bind_character(bundle, c.V, c.F, c.joints, options);
    EXPECT_EQ(bound.given_weights, given);
    PipelineStepper stepper(bundle, bound, rest_apparel_history(bound), PipelineStages::kBodyApparel);
    at::Tensor out;
    for (int t = 0; t < 3; ++t) out = stepper.step(motion[t]);
    return out;
  };
  const at::Tensor given = run(both, true), predicted = run(both, false);
  EXPECT_TRUE(at::equal(given, run(only_b, true)));
  EXPECT_TRUE(at::equal(predicted, run(only_a, false)));
  EXPECT_FALSE(at::equal(given, run(only_a, true)));  // the two modules differ

  // An own-weights module of other handles is refused, naming the file and both settings.
  test::write_fresh_model(root / "c", 7, canonical_joint_names(), /*local_apparel=*/true, /*handle_spacing=*/0.03);
  fs::copy_file(root / "c" / kApparelCheckpoint, root / "both" / kApparelOwnWeightsCheckpoint,
                fs::copy_options::overwrite_existing);
  const std::string e = test::error_of([&] { load_model_bundle((root / "both").string()); });
  EXPECT_NE(e.find("apparel_own_weights.ckpt: options: expected the handles (0 m)"), std::string::npos) << e;
}

TEST(PipelineStart, RestHistoryAndLeadIn) {
  // One joint rotated 90 degrees about Y and moved from (0, 1, 0) to (2, 1, 0): the middle lead-in frame
  // is rotated 45 degrees and halfway there; the first, at s = 1/4 eased to s^2 (3 - 2 s) = 5/32, 0.3125 along.
  at::Tensor first = at::zeros({1, 3, 4});
  first[0][0][2] = 1;
  first[0][1][1] = 1;
  first[0][2][0] = -1;
  first[0][0][3] = 2;
  first[0][1][3] = 1;
  const at::Tensor rest = at::tensor({0.0f, 1.0f, 0.0f}).reshape({1, 3});
  const at::Tensor lead = motion_lead_in(first, rest, 3);
  ASSERT_EQ(lead.sizes(), (at::IntArrayRef{3, 1, 3, 4}));
  const float h = std::sqrt(0.5f);
  const at::Tensor expected = at::tensor({h, 0.0f, h, 1.0f, 0.0f, 1.0f, 0.0f, 1.0f, -h, 0.0f, h, 0.0f}).reshape({3, 4});
  EXPECT_TRUE(at::allclose(lead[1][0], expected, 1e-5, 1e-6)) << lead[1][0];
  EXPECT_NEAR(lead[0][0][0][3].item<float>(), 0.3125f, 1e-6);
  EXPECT_NEAR(lead[2][0][0][3].item<float>(), 1.6875f, 1e-6);  // s = 3/4: 27/32
  EXPECT_EQ(motion_lead_in(first, rest, 0).size(0), 0);

  BoundCharacter b;
  b.V = at::arange(12, at::kFloat).reshape({4, 3});
  b.apparel_ids = at::tensor({1, 3}, at::kLong);
  const at::Tensor history = rest_apparel_history(b);
  ASSERT_EQ(history.sizes(), (at::IntArrayRef{3, 2, 3}));
  EXPECT_TRUE(at::equal(history[2], b.V.index_select(0, b.apparel_ids)));
}

}  // namespace
}  // namespace amt
