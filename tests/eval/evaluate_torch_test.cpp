// Tests of eval/evaluate.h and eval/report.h: the skinning baseline scores zero on a dataset whose
// ground truth is LBS, predictions files are scored with the same code, the report has the tables.
#include "eval/evaluate.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/utils.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "data_tools/builder/artist_style.h"
#include "data_tools/builder/dataset_builder.h"
#include "data_tools/builder/example_dataset.h"
#include "data_tools/builder/segmenter_augmentation.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/gltf_import.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/skeleton.h"
#include "eval/evaluation_viewer.h"
#include "eval/report.h"
#include "models/module_options.h"
#include "models/pipeline.h"
#include "tests/data_tools/builder/tiny_build.h"
#include "tests/predictions_file.h"
#include "tests/train/fresh_model.h"
#include "tests/train/micro_dataset.h"

namespace amt {
namespace {

// Freshly initialised small modules in a model folder, with a training log to plot.
std::string write_fresh_bundle(const std::string& name) {
  const std::string dir = test::write_fresh_model(test::test_directory(name), 3);
  std::ofstream(dir + "/apparel.csv") << "step,loss,vertex,edge,val_loss\n1,0.5,0.4,0.001,\n2,0.25,0.2,0.0005,0.3\n";
  return dir;
}

// A dataset whose ground truth IS LBS with the ground-truth weights (apparel included): one test
// character with one walk (or `test_characters` of them with `test_clips` walks each, named
// capsules_test, capsules_test1, ...), one train character with a train walk and a test walk.
// `shift` (metres, along x) moves every vertex of every frame (with `apparel_only`, the apparel vertices
// alone): a prediction off by a known amount.
void write_lbs_dataset(const std::string& path, int frames, int test_characters = 1, int test_clips = 1,
                       float shift = 0.0f, bool apparel_only = false) {
  const Skeleton skeleton = canonical_skeleton();
  DatasetWriter writer(path, 30.0f, skeleton.names);
  std::vector<std::pair<std::string, std::string>> characters;  // (name, split)
  for (int k = 0; k < test_characters; ++k)
    characters.emplace_back("capsules_test" + (k == 0 ? std::string() : std::to_string(k)), "test");
  characters.emplace_back("capsules_train", "train");
  for (const auto& [name, split] : characters) {
    CharacterData character = capsule_example_character(skeleton, 160);
    character.name = name;
    character.split = split;
    for (int i = 0; i < character.mesh.num_vertices(); ++i)
      character.apparel_mask[i] = character.body_weights(i, kPelvis) == 1.0f ? 1 : 0;
    writer.add_character(character);
    const SparseWeights weights = sparsify_weights(character.body_weights);
    for (int c = 0; c < (split == "train" ? 2 : test_clips); ++c) {
      Motion walk = walk_motion(frames, 30.0f, 1.0f + 0.3f * c);
      ClipInfo clip;
      clip.name = "walk_" + name + "_" + std::to_string(c);
      clip.character = character.name;
      clip.motion = "procedural_walk";
      clip.split = c == 0 ? "test" : "train";
      writer.begin_clip(clip);
      for (int t = 0; t < frames; ++t) {
        const Transforms joints = forward_kinematics(skeleton, walk, t);
        MatrixX3f posed;
        linear_blend_skinning(character.mesh.V, weights, skinning_matrices(skeleton, joints), posed);
        for (int i = 0; i < posed.rows(); ++i) {
          if (!apparel_only || character.apparel_mask[size_t(i)]) posed(i, 0) += shift;
        }
        writer.append_frame(joints, posed);
      }
      writer.end_clip();
    }
  }
  writer.commit();
}

TEST(Evaluate, SkinningBaselineIsZeroWhenTheGroundTruthIsLbs) {
  test::use_one_thread();
  const std::string data = test::test_directory("eval_lbs") + "/lbs.h5";
  write_lbs_dataset(data, 17);
  const ModelBundle bundle = load_model_bundle(write_fresh_bundle("eval_bundle"));
  EvaluateOptions options;
  options.methods = {"skinning_baseline", "full"};
  options.progress = false;
  const EvaluationResult result = evaluate_model(bundle, {data}, options);
  EXPECT_EQ(result.clips.at(kHeldOutCharacters), 1);
  EXPECT_EQ(result.clips.at(kHeldOutClips), 1);
  for (const char* subset : {kHeldOutCharacters, kHeldOutClips}) {
    const MethodScores* paper = result.find("skinning_baseline", "paper", subset);
    ASSERT_NE(paper, nullptr) << subset;
    // 17 frames: windows start at 0 and 7, each predicting 7 frames.
    EXPECT_EQ(paper->scores.frames, 14);
    EXPECT_EQ(paper->scores.clips, 1);
    EXPECT_NEAR(paper->scores.pmd, 0.0, 1e-3);
    EXPECT_NEAR(paper->scores.pmd_a, 0.0, 1e-3);
    EXPECT_NEAR(paper->scores.pmd_b, 0.0, 1e-3);
    EXPECT_NEAR(paper->scores.els, 1.0, 1e-4);
    const MethodScores* rollout = result.find("skinning_baseline", "rollout", subset);
    ASSERT_NE(rollout, nullptr);
    EXPECT_EQ(rollout->scores.frames, 17);
    EXPECT_NEAR(rollout->scores.pmd, 0.0, 1e-3);
    // The untrained full model is not LBS: it must score worse than zero.
    const MethodScores* full = result.find("full", "paper", subset);
    ASSERT_NE(full, nullptr);
    EXPECT_GT(full->scores.pmd_a, 0.01);
  }
  EXPECT_EQ(result.characters.size(), 2u);
  ASSERT_FALSE(result.curves.empty());
  EXPECT_EQ(result.curves.front().pmd_a.size(), 17u);
}

// amt eval --viewer: the worst, median and best clip of each subset by the full model's rollout PMD_a,
// each as prediction, ground truth and skinning GLBs in a viewer folder. On LBS ground truth the
// skinning baseline's GLB is the ground truth's.
TEST(EvaluationViewer, PicksWorstMedianAndBestAndWritesTheirThreeSequences) {
  test::use_one_thread();
  const std::string dir = test::test_directory("eval_viewer");
  write_lbs_dataset(dir + "/lbs.h5", 9, /*test_characters=*/3, /*test_clips=*/1);
  const ModelBundle bundle = load_model_bundle(write_fresh_bundle("eval_viewer_bundle"));
  EvaluateOptions options;
  options.methods = {"full"};
  options.paper = false;
  options.penetration = false;
  options.progress = false;
  const EvaluationResult result = evaluate_model(bundle, {dir + "/lbs.h5"}, options);
  const std::vector<ViewerPick> picks = viewer_picks(result);
  // 3 held-out characters' clips (worst, median, best), 1 held-out clip (worst only: it is all three).
  ASSERT_EQ(picks.size(), 4u);
  EXPECT_EQ(picks[0].score.subset, kHeldOutCharacters);
  EXPECT_EQ(picks[0].pick, "worst");
  EXPECT_EQ(picks[1].pick, "median");
  EXPECT_EQ(picks[2].pick, "best");
  EXPECT_GE(picks[0].score.pmd_a, picks[1].score.pmd_a);
  EXPECT_GE(picks[1].score.pmd_a, picks[2].score.pmd_a);
  EXPECT_EQ(picks[3].score.subset, kHeldOutClips);
  for (const ViewerPick& p : picks) EXPECT_EQ(p.score.protocol, "rollout");
  // The clip's mean PMD_a is the subset row's when the subset has one clip.
  EXPECT_NEAR(picks[3].score.pmd_a, result.find("full", "rollout", kHeldOutClips)->scores.pmd_a, 1e-4);

  const std::string viewer_dir =
      (std::filesystem::path(AMT_TEST_ASSETS_DIR).parent_path().parent_path() / "viewer").string();
  const std::string out = dir + "/viewer";
  const EvaluationViewer written = write_evaluation_viewer(bundle, result, out, viewer_dir, 6);
  EXPECT_EQ(written.clips, 4);
  std::ifstream manifest(out + "/viewer.json");
  std::stringstream text;
  text << manifest.rdbuf();
  EXPECT_NE(text.str().find("held-out characters, worst clip"), std::string::npos) << text.str();
  const std::string stem = out + "/held_out_characters_worst_";
  const GltfVertexAnimation gt = gltf_vertex_animation(read_gltf(stem + "ground_truth.glb"), "", 30.0f);
  const GltfVertexAnimation skinning = gltf_vertex_animation(read_gltf(stem + "skinning.glb"), "", 30.0f);
  const GltfVertexAnimation prediction = gltf_vertex_animation(read_gltf(stem + "prediction.glb"), "", 30.0f);
  ASSERT_EQ(gt.frames.size(), 6u);
  ASSERT_EQ(prediction.frames.size(), 6u);
  ASSERT_EQ(skinning.frames.size(), 6u);
  for (size_t t = 0; t < 6; ++t) EXPECT_LT((gt.frames[t] - skinning.frames[t]).cwiseAbs().maxCoeff(), 1e-4f) << t;
  // The ground truth is the dataset's clip.
  const DatasetReader reader(dir + "/lbs.h5");
  const MatrixX3f first = reader.read_vertices(picks[0].score.clip, 0, 1);
  EXPECT_LT((gt.frames[0] - first).cwiseAbs().maxCoeff(), 1e-5f);
  // A folder of the user's is refused.
  std::filesystem::create_directories(dir + "/mine");
  std::ofstream(dir + "/mine/notes.txt") << "x";
  EXPECT_NE(test::error_of([&] {
              write_evaluation_viewer(bundle, result, dir + "/mine", viewer_dir, 6);
            }).find("expected an empty folder or a viewer folder amt wrote"),
            std::string::npos);
}

TEST(Evaluate, CappedEvaluationTakesClipsRoundRobinOverCharacters) {
  test::use_one_thread();
  const std::string data = test::test_directory("eval_round_robin") + "/lbs.h5";
  write_lbs_dataset(data, 12, /*test_characters=*/3, /*test_clips=*/3);
  const ModelBundle bundle = load_model_bundle(write_fresh_bundle("eval_round_robin_bundle"));
  EvaluateOptions options;
  options.methods = {"skinning_baseline"};
  options.progress = false;
  options.max_clips = 4;  // 3 characters x 3 clips: the first clip of each, then capsules_test's second
  const EvaluationResult capped = evaluate_model(bundle, {data}, options);
  EXPECT_EQ(capped.clips.at(kHeldOutCharacters), 4);
  EXPECT_EQ(capped.clips.at(kHeldOutClips), 1);
  std::set<std::string> seen;
  for (const CharacterScores& c : capped.characters)
    if (c.subset == kHeldOutCharacters) seen.insert(c.character);
  EXPECT_EQ(seen, (std::set<std::string>{"capsules_test", "capsules_test1", "capsules_test2"}));
  options.max_clips = 0;
  EXPECT_EQ(evaluate_model(bundle, {data}, options).clips.at(kHeldOutCharacters), 9);
}

// Methods that share computation score as if run alone: body_apparel from the full model's steps,
// and the body-only methods' paper frames, which are their rollout frames 4..T (LBS needs no history).
TEST(Evaluate, SharedStepsScoreAsSeparateRuns) {
  test::use_one_thread();
  const std::string data = test::test_directory("eval_shared") + "/lbs.h5";
  write_lbs_dataset(data, 17);
  const ModelBundle bundle = load_model_bundle(write_fresh_bundle("eval_shared_bundle"));
  EvaluateOptions options;
  options.progress = false;
  options.methods = {"lbs_predicted", "body_apparel", "full"};
  const EvaluationResult together = evaluate_model(bundle, {data}, options);
  options.methods = {"body_apparel"};
  const EvaluationResult alone = evaluate_model(bundle, {data}, options);
  for (const char* subset : {kHeldOutCharacters, kHeldOutClips}) {
    for (const char* protocol : {"paper", "rollout"}) {
      const MethodScores* a = together.find("body_apparel", protocol, subset);
      const MethodScores* b = alone.find("body_apparel", protocol, subset);
      ASSERT_NE(a, nullptr);
      ASSERT_NE(b, nullptr);
      EXPECT_EQ(a->scores.frames, b->scores.frames);
      EXPECT_DOUBLE_EQ(a->scores.pmd, b->scores.pmd) << subset << protocol;
      EXPECT_DOUBLE_EQ(a->scores.pmd_a, b->scores.pmd_a) << subset << protocol;
      EXPECT_DOUBLE_EQ(a->scores.els, b->scores.els) << subset << protocol;
      EXPECT_DOUBLE_EQ(a->scores.penetration_share, b->scores.penetration_share) << subset << protocol;
      EXPECT_DOUBLE_EQ(a->scores.penetration_depth_cm, b->scores.penetration_depth_cm) << subset << protocol;
      // The untrained refiner moves vertices: the full model's rows are its own.
      EXPECT_NE(together.find("full", protocol, subset)->scores.pmd, a->scores.pmd);
    }
    // One clip per subset: the paper protocol's PMD_a is the mean of the rollout curve over frames 4..17.
    const MethodScores* paper = together.find("lbs_predicted", "paper", subset);
    ASSERT_NE(paper, nullptr);
    EXPECT_EQ(paper->scores.frames, 14);
    const RolloutCurve* curve = nullptr;
    for (const RolloutCurve& c : together.curves)
      if (c.subset == subset && c.method == "lbs_predicted") curve = &c;
    ASSERT_NE(curve, nullptr);
    ASSERT_EQ(curve->pmd_a.size(), 17u);
    double sum = 0;
    for (int t = 3; t < 17; ++t) sum += curve->pmd_a[t];
    EXPECT_GT(paper->scores.pmd_a, 0.01);
    EXPECT_NEAR(paper->scores.pmd_a, sum / 14, 1e-9 * paper->scores.pmd_a);
  }
}

TEST(Evaluate, PredictionsFileOfTheGroundTruthScoresZero) {
  test::use_one_thread();
  const std::string dir = test::test_directory("eval_predictions");
  write_lbs_dataset(dir + "/lbs.h5", 12);
  EvaluateOptions options;
  options.progress = false;
  options.penetration = false;
  const std::string truth_as_predictions = test::copy_as_predictions(dir + "/lbs.h5", dir + "/lbs_predicted.h5");
  const EvaluationResult result = evaluate_predictions({dir + "/lbs.h5"}, truth_as_predictions, options);
  const MethodScores* row = result.find("predictions", "file", kHeldOutClips);
  ASSERT_NE(row, nullptr);
  EXPECT_EQ(row->scores.frames, 12);
  EXPECT_DOUBLE_EQ(row->scores.pmd, 0.0);
  EXPECT_DOUBLE_EQ(row->scores.els, 1.0);
  // The zero comes from the predictions: the same file with its apparel vertices 1 cm off (the body
  // exact) scores PMD_a 1 cm, PMD_b 0 and PMD 1 cm times the apparel share, on both subsets.
  write_lbs_dataset(dir + "/apparel_shifted.h5", 12, 1, 1, 0.01f, /*apparel_only=*/true);
  const CharacterData c = DatasetReader(dir + "/lbs.h5").read_character("capsules_test");
  const double apparel_share =
      double(std::count(c.apparel_mask.begin(), c.apparel_mask.end(), uint8_t(1))) / double(c.apparel_mask.size());
  ASSERT_GT(apparel_share, 0.05);
  ASSERT_LT(apparel_share, 0.95);
  test::copy_as_predictions(dir + "/apparel_shifted.h5", dir + "/apparel_shifted.h5");
  const EvaluationResult shifted = evaluate_predictions({dir + "/lbs.h5"}, dir + "/apparel_shifted.h5", options);
  for (const char* subset : {kHeldOutCharacters, kHeldOutClips}) {
    const MethodScores* r = shifted.find("predictions", "file", subset);
    ASSERT_NE(r, nullptr) << subset;
    EXPECT_EQ(r->scores.frames, 12) << subset;
    EXPECT_NEAR(r->scores.pmd_a, 1.0, 1e-4) << subset;
    EXPECT_NEAR(r->scores.pmd_b, 0.0, 1e-9) << subset;
    EXPECT_NEAR(r->scores.pmd, apparel_share, 1e-4) << subset;
  }
  EXPECT_NE(test::error_of([&] {
              evaluate_predictions({dir + "/lbs.h5"}, dir + "/none.h5", options);
            }).find("none.h5: no such predictions file"),
            std::string::npos);
  // The ground truth itself (no mark of predictions) is refused: it would score as perfect.
  EXPECT_NE(test::error_of([&] {
              evaluate_predictions({dir + "/lbs.h5"}, dir + "/lbs.h5", options);
            }).find("lbs.h5: attribute 'predictions': missing: the file holds ground truth"),
            std::string::npos);
}

// The rows of a predicted rest mesh that hold the ground truth's vertices: the identity within the tolerance, a
// reordering matched by position (copies of one position in index order), nothing for other positions.
TEST(Evaluate, RestVertexMatchFindsAReorderingOfTheSameMesh) {
  MatrixX3f truth(4, 3), predicted(4, 3);
  const Eigen::RowVector3f a(0, 1, 0), b(0.5f, 0, 0), c(0, 0, -2);
  truth << a, b, a, c;
  predicted << c, a, b, a;
  EXPECT_EQ(rest_vertex_match(truth, predicted), (std::vector<int32_t>{1, 2, 3, 0}));
  MatrixX3f nudged = truth;
  nudged(3, 2) += 5e-6f;  // within 1e-5 m
  EXPECT_EQ(rest_vertex_match(truth, nudged), (std::vector<int32_t>{0, 1, 2, 3}));
  predicted(0, 1) = 0.01f;  // c moved by 1 cm: not the same mesh
  EXPECT_TRUE(rest_vertex_match(truth, predicted).empty());
  EXPECT_TRUE(rest_vertex_match(truth, MatrixX3f(truth.topRows(3))).empty());
}

TEST(Evaluate, PredictionShiftedByOneCentimetreScoresOneCentimetre) {
  test::use_one_thread();
  const std::string dir = test::test_directory("eval_shifted");
  write_lbs_dataset(dir + "/lbs.h5", 12);
  write_lbs_dataset(dir + "/shifted.h5", 12, 1, 1, 0.01f);
  test::copy_as_predictions(dir + "/shifted.h5", dir + "/shifted.h5");
  EvaluateOptions options;
  options.progress = false;
  options.penetration = false;
  const EvaluationResult result = evaluate_predictions({dir + "/lbs.h5"}, dir + "/shifted.h5", options);
  for (const char* subset : {kHeldOutCharacters, kHeldOutClips}) {
    const MethodScores* row = result.find("predictions", "file", subset);
    ASSERT_NE(row, nullptr) << subset;
    EXPECT_NEAR(row->scores.pmd_a, 1.0, 1e-4) << subset;
    EXPECT_NEAR(row->scores.pmd, 1.0, 1e-4) << subset;
    EXPECT_NEAR(row->scores.els, 1.0, 1e-5) << subset;  // a translation keeps every edge
  }
  // Dynamics amplitude against a ground truth that lags 1 cm behind skinning: the skinned frames
  // have none of it (0), the ground truth itself all of it (1).
  const EvaluationResult glued = evaluate_predictions(
      {dir + "/shifted.h5"}, test::copy_as_predictions(dir + "/lbs.h5", dir + "/lbs_predicted.h5"), options);
  const EvaluationResult lively = evaluate_predictions({dir + "/shifted.h5"}, dir + "/shifted.h5", options);
  EXPECT_NEAR(glued.find("predictions", "file", kHeldOutClips)->amplitude, 0.0, 1e-4);
  EXPECT_NEAR(lively.find("predictions", "file", kHeldOutClips)->amplitude, 1.0, 1e-4);
}

TEST(Evaluate, ZeroNetworkRulesPerHorizonAndAmplitudeWithTheLocalModule) {
  test::use_one_thread();
  const std::string data = test::test_directory("eval_rules") + "/lbs.h5";
  write_lbs_dataset(data, 17);
  const std::string dir = test::write_fresh_model(test::test_directory("eval_local_bundle"), 3, canonical_joint_names(),
                                                  /*local_apparel=*/true);
  const ModelBundle bundle = load_model_bundle(dir);
  ASSERT_TRUE(bundle.local_apparel());
  EvaluateOptions options;
  options.methods = {"skinning_baseline", "hold_offset", "inertial", "body_apparel", "inertial_predicted", "full"};
  options.progress = false;
  const EvaluationResult result = evaluate_model(bundle, {data}, options);
  // inertial_predicted runs the rule on the full model's bind: its body is skinned by the predicted weights of
  // a fresh network, not by the ground-truth weights `inertial` uses (exact on this skinned data), and its
  // apparel (the predicted mask's) comes from the rule, not from the fresh apparel module of body_apparel.
  const MethodScores* rule_predicted = result.find("inertial_predicted", "paper", kHeldOutCharacters);
  ASSERT_NE(rule_predicted, nullptr);
  EXPECT_LT(result.find("inertial", "paper", kHeldOutCharacters)->scores.pmd_b, 1e-3);
  EXPECT_GT(
      std::fabs(rule_predicted->scores.pmd_a - result.find("body_apparel", "paper", kHeldOutCharacters)->scores.pmd_a),
      0.1);
  EXPECT_GT(rule_predicted->scores.pmd_b, result.find("inertial", "paper", kHeldOutCharacters)->scores.pmd_b + 0.1);
  // The inertia is fitted on the train character's train clip.
  EXPECT_EQ(result.inertia_clips, 1);
  EXPECT_GE(result.inertia, 0.0);
  EXPECT_LE(result.inertia, 1.0);
  for (const char* method : {"hold_offset", "inertial", "body_apparel", "inertial_predicted", "full"}) {
    const MethodScores* paper = result.find(method, "paper", kHeldOutCharacters);
    ASSERT_NE(paper, nullptr) << method;
    EXPECT_EQ(paper->scores.frames, 14) << method;
    EXPECT_TRUE(std::isfinite(paper->scores.pmd_a)) << method;
    EXPECT_TRUE(std::isnan(paper->amplitude)) << method;  // the ground truth is skinning: no dynamics to match
    // Per horizon: 7 predicted frames per window, 2 windows each; their mean is the paper PMD_a.
    const auto horizon = std::find_if(result.horizons.begin(), result.horizons.end(), [&](const RolloutCurve& c) {
      return c.method == method && c.subset == kHeldOutCharacters;
    });
    ASSERT_NE(horizon, result.horizons.end()) << method;
    ASSERT_EQ(horizon->pmd_a.size(), 7u) << method;
    double sum = 0;
    for (size_t k = 0; k < 7; ++k) EXPECT_EQ(horizon->clips[k], 2) << method;
    for (double v : horizon->pmd_a) sum += v;
    EXPECT_NEAR(sum / 7, paper->scores.pmd_a, 1e-6 * paper->scores.pmd_a + 1e-9) << method;
    ASSERT_NE(result.find(method, "rollout", kHeldOutCharacters), nullptr) << method;
  }
}

// --swing-calibration on: each character's swing is fitted on its other clips (the train character's unscored
// train walk; the test character's two scored walks on each other). The ground truth is rigid skinning, so the
// fitted gains calm a fresh module's swing towards its anchors; probe (no rig response here) runs it as trained.
TEST(Evaluate, SwingFittedOnAnotherClipOfEachCharacter) {
  test::use_one_thread();
  const std::string data = test::test_directory("eval_fit_swing") + "/lbs.h5";
  write_lbs_dataset(data, 17, 1, 2);
  const std::string dir = test::write_fresh_model(test::test_directory("eval_fit_swing_bundle"), 3,
                                                  canonical_joint_names(), /*local_apparel=*/true);
  const ModelBundle bundle = load_model_bundle(dir);
  EvaluateOptions options;
  options.methods = {"skinning_baseline", "body_apparel"};
  options.paper = false;
  options.progress = false;
  options.penetration = false;
  const EvaluationResult fitted = evaluate_model(bundle, {data}, options);
  options.fit_swing = false;
  const EvaluationResult probe = evaluate_model(bundle, {data}, options);
  const auto has_note = [](const EvaluationResult& r) {
    return std::any_of(r.notes.begin(), r.notes.end(), [](const std::string& note) {
      return note.find("apparel swing: fitted on other clips of each character") != std::string::npos &&
             note.find("for 2 character(s)") != std::string::npos;
    });
  };
  EXPECT_TRUE(has_note(fitted));
  EXPECT_FALSE(has_note(probe));
  for (const char* subset : {kHeldOutCharacters, kHeldOutClips}) {
    const double as_trained = probe.find("body_apparel", "rollout", subset)->scores.pmd_a;
    const double calmed = fitted.find("body_apparel", "rollout", subset)->scores.pmd_a;
    EXPECT_GT(as_trained, 0.01) << subset;
    EXPECT_LT(calmed, 0.5 * as_trained) << subset;
    // The rule is not the module's: the skinning baseline scores the same either way.
    EXPECT_DOUBLE_EQ(fitted.find("skinning_baseline", "rollout", subset)->scores.pmd_a,
                     probe.find("skinning_baseline", "rollout", subset)->scores.pmd_a)
        << subset;
  }
}

// A test character with two more apparel triangles beside its first apparel vertex v, 1 cm sides: T1 = (v, v + x,
// v + y) and T2 = (v + x, v + y, v + x + y) on copies of T1's two far corners (a seam of two pairs), skinned as v;
// a 4-frame walk; the ground truth is LBS. With `predicted`, T2 is scaled by 1.6 about its first corner in frame 1
// (its three edges 60 % longer: torn) and moved 10 cm along +x in frame 2.
void write_seam_dataset(const std::string& path, bool predicted) {
  const Skeleton skeleton = canonical_skeleton();
  CharacterData character = capsule_example_character(skeleton, 160);
  character.name = "seams";
  character.split = "test";
  int N = character.mesh.num_vertices();
  for (int i = 0; i < N; ++i) character.apparel_mask[i] = character.body_weights(i, kPelvis) == 1.0f ? 1 : 0;
  const int v =
      int(std::find(character.apparel_mask.begin(), character.apparel_mask.end(), 1) - character.apparel_mask.begin());
  const Eigen::RowVector3f x(0.01f, 0, 0), y(0, 0.01f, 0), p = character.mesh.V.row(v);
  character.mesh.V.conservativeResize(N + 6, 3);
  character.mesh.V.bottomRows(6) << p, p + x, p + y, p + x, p + y, p + x + y;
  character.body_weights.conservativeResize(N + 6, Eigen::NoChange);
  for (int k = 0; k < 6; ++k) character.body_weights.row(N + k) = character.body_weights.row(v);
  character.apparel_mask.resize(size_t(N + 6), 1);
  character.mesh.F.conservativeResize(character.mesh.F.rows() + 2, 3);
  character.mesh.F.bottomRows(2) << N, N + 1, N + 2, N + 3, N + 5, N + 4;
  N += 6;
  DatasetWriter writer(path, 30.0f, skeleton.names);
  writer.add_character(character);
  const SparseWeights weights = sparsify_weights(character.body_weights);
  const Motion walk = walk_motion(4, 30.0f, 1.0f);
  writer.begin_clip({"seams_walk", character.name, "procedural_walk", "test", 30.0f, 0, GroundTruth::kVertices});
  for (int t = 0; t < 4; ++t) {
    const Transforms joints = forward_kinematics(skeleton, walk, t);
    MatrixX3f posed;
    linear_blend_skinning(character.mesh.V, weights, skinning_matrices(skeleton, joints), posed);
    if (predicted && t == 1)
      for (int k = 4; k < 6; ++k)
        posed.row(N - 6 + k) = posed.row(N - 3) + 1.6f * (posed.row(N - 6 + k) - posed.row(N - 3));
    if (predicted && t == 2)
      for (int k = 3; k < 6; ++k) posed(N - 6 + k, 0) += 0.1f;
    writer.append_frame(joints, posed);
  }
  writer.end_clip();
  writer.commit();
}

// Tearing, seam gap and apparel ELS of a hand-made prediction, through the whole scoring path of amt eval.
TEST(Evaluate, FallingApartMeasuresOfAHandMadePrediction) {
  test::use_one_thread();
  const std::string dir = test::test_directory("eval_seams");
  write_seam_dataset(dir + "/truth.h5", false);
  write_seam_dataset(dir + "/predicted.h5", true);
  test::copy_as_predictions(dir + "/predicted.h5", dir + "/predicted.h5");
  const CharacterData c = DatasetReader(dir + "/truth.h5").read_character("seams");
  const int64_t apparel_edges_count = apparel_edges(unique_edges(c.mesh.F), c.apparel_mask).rows();
  const int64_t pairs = coincident_pairs(c.mesh.V, c.mesh.F).rows();
  ASSERT_EQ(pairs, 2);  // the seam of T1 and T2 (the capsules are closed: no seams)
  EvaluateOptions options;
  options.progress = false;
  options.penetration = false;
  const std::string truth_as_predictions = test::copy_as_predictions(dir + "/truth.h5", dir + "/truth_predicted.h5");
  const EvaluationResult same = evaluate_predictions({dir + "/truth.h5"}, truth_as_predictions, options);
  const MethodScores* exact = same.find("predictions", "file", kHeldOutCharacters);
  ASSERT_NE(exact, nullptr);
  EXPECT_EQ(exact->separation.tearing, 0.0);
  EXPECT_EQ(exact->separation.seam_gap_max_cm, 0.0);
  EXPECT_NEAR(exact->separation.apparel_els, 1.0, 1e-6);

  const EvaluationResult result = evaluate_predictions({dir + "/truth.h5"}, dir + "/predicted.h5", options);
  const MethodScores* r = result.find("predictions", "file", kHeldOutCharacters);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->separation.pairs, pairs);
  EXPECT_EQ(r->separation.edge_frames, 4 * apparel_edges_count);
  // 3 torn edge-frames; in frame 1 their ELS terms are 1 - 0.6 each, every other term 1.
  EXPECT_NEAR(r->separation.tearing, 3.0 / (4.0 * apparel_edges_count), 1e-12);
  EXPECT_NEAR(r->separation.apparel_els, 1.0 - 3 * 0.6 / (4.0 * apparel_edges_count), 1e-5);
  // Against rest lengths: the same 3 edge-frames (the ground truth keeps them at rest), none of the ground
  // truth's own, so none torn where the ground truth deforms.
  EXPECT_NEAR(r->separation.rest_tearing, 3.0 / (4.0 * apparel_edges_count), 1e-12);
  EXPECT_EQ(r->separation.ground_truth_rest_tearing, 0.0);
  EXPECT_EQ(r->separation.tearing_ground_truth_deformed, 0.0);
  // Roles swapped: a ground truth that stretches those edges by 1.6 in frame 1 against a prediction at rest
  // length: 1 / 1.6 is off by 37.5 %, not torn; the ground truth's own deformation is counted.
  const EvaluationResult swapped = evaluate_predictions({dir + "/predicted.h5"}, truth_as_predictions, options);
  const MethodScores* w = swapped.find("predictions", "file", kHeldOutCharacters);
  ASSERT_NE(w, nullptr);
  EXPECT_EQ(w->separation.tearing, 0.0);
  EXPECT_EQ(w->separation.rest_tearing, 0.0);
  EXPECT_NEAR(w->separation.ground_truth_rest_tearing, 3.0 / (4.0 * apparel_edges_count), 1e-12);
  EXPECT_EQ(w->separation.tearing_ground_truth_deformed, 0.0);
  // Gaps: frame 1 one pair 0.6 cm (T2's third corner pulled off its twin), frame 2 both pairs 10 cm: of 8
  // pair-frames the nearest-rank 95th percentile is the 8th, 10 cm.
  EXPECT_NEAR(r->separation.seam_gap_max_cm, 10.0, 1e-3);
  EXPECT_NEAR(r->separation.seam_gap_p95_cm, 10.0, 1e-3);
  EXPECT_EQ(r->worst_seam_gap_max, "seams");
  EXPECT_NEAR(r->worst.tearing, r->separation.tearing, 1e-12);  // one character: the mean is the worst
  ASSERT_EQ(result.characters.size(), 1u);
  const SeparationScores& per_character = result.characters[0].separation.at("predictions").at("file");
  EXPECT_NEAR(per_character.tearing, r->separation.tearing, 1e-12);
  EXPECT_NEAR(per_character.seam_gap_p95_cm, r->separation.seam_gap_p95_cm, 1e-12);

  ReportOptions report;
  report.out_dir = dir + "/out";
  report.plots = false;
  const ReportFiles files = write_report(result, report);
  std::stringstream md, json;
  md << std::ifstream(files.markdown).rdbuf();
  json << std::ifstream(files.json).rdbuf();
  EXPECT_NE(md.str().find("## Falling apart"), std::string::npos);
  EXPECT_NE(md.str().find("| 10.000 (seams) |"), std::string::npos) << md.str();
  EXPECT_NE(json.str().find("\"falling_apart\""), std::string::npos);
  EXPECT_NE(json.str().find("\"seam_gap_max_cm\""), std::string::npos);
}

// amt eval --artist-style: the held-out characters remade, bound and scored as their own subset; rigid skinning
// keeps every seam closed (the generated body's legs touch at one point, which the remake's cuts make a pair of
// boundary vertices; the ground truth parts them as skinning does, so that pair adds no gap).
TEST(Evaluate, ArtistStyleSubsetScoresTheRemadeCharacters) {
  test::use_one_thread();
  const std::string dir = test::test_directory("eval_artist_style");
  build_dataset(test::tiny_build_options(dir + "/proc", 2));  // one of the two characters is held out
  std::string shard;
  CharacterData source;
  for (const char* name : {"character-0000", "character-0001"}) {
    const std::string path = dir + "/proc/" + name + ".h5";
    CharacterData c = DatasetReader(path).read_character(name);
    if (c.split == "test") shard = path, source = std::move(c);
  }
  ASSERT_FALSE(shard.empty());
  const ModelBundle bundle = load_model_bundle(write_fresh_bundle("eval_artist_style_bundle"));
  EvaluateOptions options;
  options.progress = false;
  options.penetration = false;
  options.methods = {"skinning_baseline", "full"};
  options.artist_style = true;
  const EvaluationResult result = evaluate_model(bundle, {shard}, options);
  EXPECT_EQ(result.clips.count(kHeldOutCharacters), 0u);
  ASSERT_EQ(result.clips.count(kHeldOutArtistStyle), 1u);
  const ArtistStyleCharacter remake = artist_style_character(source, options.artist_style_options);
  ASSERT_EQ(result.characters.size(), 1u);
  const CharacterScores& c = result.characters[0];
  EXPECT_TRUE(c.artist_style);
  EXPECT_EQ(c.subset, kHeldOutArtistStyle);
  EXPECT_EQ(c.num_vertices, remake.character.mesh.num_vertices());
  EXPECT_GT(c.construction.coincident_share, 0.6);
  for (const char* protocol : {"paper", "rollout"}) {
    const MethodScores* skinning = result.find("skinning_baseline", protocol, kHeldOutArtistStyle);
    ASSERT_NE(skinning, nullptr) << protocol;
    EXPECT_GT(skinning->separation.pairs, 0);
    EXPECT_LT(skinning->separation.seam_gap_max_cm, 1e-3) << protocol;  // float rounding of the two partings
    EXPECT_LT(skinning->scores.pmd_b, 0.05) << protocol;                // the body's ground truth is skinning, remade
    ASSERT_NE(result.find("full", protocol, kHeldOutArtistStyle), nullptr) << protocol;
  }
  ReportOptions report;
  report.out_dir = dir + "/out";
  report.plots = false;
  std::stringstream md;
  md << std::ifstream(write_report(result, report).markdown).rdbuf();
  EXPECT_NE(md.str().find("Subset **held-out characters, artist-style**"), std::string::npos);
  EXPECT_NE(md.str().find("| held-out characters, artist-style | Skinning baseline"), std::string::npos);
  EXPECT_NE(evaluation_json(result).find("\"subset\": \"held-out characters, artist-style\""), std::string::npos);
  // A predictions file is of the characters as built.
  EXPECT_NE(
      test::error_of([&] { evaluate_predictions({shard}, shard, options); }).find("artist style: expected a model"),
      std::string::npos);
}

TEST(Evaluate, SkeletonMismatchAndUnknownMethod) {
  test::use_one_thread();
  const std::string dir = test::test_directory("eval_errors");
  std::vector<std::string> names = canonical_joint_names();
  names[0] = "hips";
  test::MicroDatasetOptions micro;
  micro.vertices = 120;
  micro.frames = 4;
  micro.clips = 1;
  micro.joint_names = names;
  test::write_micro_dataset(dir + "/other.h5", micro);
  const ModelBundle bundle = load_model_bundle(write_fresh_bundle("eval_errors_bundle"));
  EvaluateOptions options;
  options.progress = false;
  const std::string message = test::error_of([&] { evaluate_model(bundle, {dir + "/other.h5"}, options); });
  EXPECT_NE(message.find(dir + "/other.h5: skeleton: the model"), std::string::npos) << message;
  options.methods = {"magic"};
  EXPECT_NE(test::error_of([&] { evaluate_model(bundle, {dir + "/other.h5"}, options); }).find("found 'magic'"),
            std::string::npos);
}

TEST(Report, WritesTablesJsonAndPlots) {
  test::use_one_thread();
  const std::string dir = test::test_directory("report");
  write_lbs_dataset(dir + "/lbs.h5", 12);
  const std::string model = write_fresh_bundle("report_bundle");
  const ModelBundle bundle = load_model_bundle(model);
  EvaluateOptions options;
  options.progress = false;
  options.penetration = false;
  const EvaluationResult result = evaluate_model(bundle, {dir + "/lbs.h5"}, options);
  // No ablation checkpoints in the folder: the report says so; the inertial rule's fitted inertia, the
  // anchor of the module, which the rules share, and the cloth retargeting of the held-out clip whose
  // character shares its apparel connectivity with a training character (every character of this
  // dataset is dressed alike).
  ASSERT_EQ(result.notes.size(), 5u);
  EXPECT_NE(result.notes[0].find("skinning_no_geodesic.ckpt is not in the model folder"), std::string::npos);
  EXPECT_NE(result.notes[2].find("inertial rule: inertia"), std::string::npos);
  EXPECT_EQ(result.notes[3].rfind("apparel anchor: " + bundle.apparel_anchor() + " (", 0), 0u) << result.notes[3];
  EXPECT_EQ(result.notes[4].rfind("cloth_retarget: 1 held-out clip(s)", 0), 0u) << result.notes[4];

  ReportOptions report;
  report.out_dir = dir + "/out";
  report.model_dir = model;
  report.command = "amt eval --data lbs.h5";
  const ReportFiles files = write_report(result, report);
  std::stringstream md;
  md << std::ifstream(files.markdown).rdbuf();
  for (const char* heading : {"## Table 2 analogue", "## Table 3 analogue", "## Table 4 analogue", "## Rollout drift",
                              "## Per character", "## Targets", "capsules_test", "skinning_sorted.ckpt"}) {
    EXPECT_NE(md.str().find(heading), std::string::npos) << heading;
  }
  EXPECT_NE(md.str().find("| held-out clips | Skinning baseline (LBS, GT body weights) | 0.00 | 0.00 | 0.00 | 1.000 |"),
            std::string::npos)
      << md.str();
  std::stringstream json;
  json << std::ifstream(files.json).rdbuf();
  EXPECT_NE(json.str().find("\"format\": \"amt-eval\""), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(files.json + ".amt-tmp"));
  if (!gnuplot_png_terminal().empty()) {
    ASSERT_EQ(files.plots.size(), 2u) << md.str();
    EXPECT_EQ(files.plots[0], "loss_apparel.png");
    EXPECT_EQ(files.plots[1], "rollout_pmd_a.png");
    for (const std::string& plot : files.plots)
      EXPECT_GT(std::filesystem::file_size(report.out_dir + "/" + plot), 1000u);
  }
  const std::vector<TrainingLog> logs = read_training_logs(model);
  ASSERT_EQ(logs.size(), 1u);
  EXPECT_EQ(logs[0].column("val_loss"), 4);
  EXPECT_TRUE(std::isnan(logs[0].rows[0][4]));
  EXPECT_DOUBLE_EQ(logs[0].rows[1][1], 0.25);
}

// The report's open-parts columns: each character remade of open parts (open_parts_example) and segmented as
// `amt bench --suite segmenter` does, dressed (IoU against the remade mask) and bare (share called apparel); the
// subset's figures are the means over its characters, and the tables show them.
TEST(Report, OpenPartsSegmentationIsScoredPerCharacterAndSubset) {
  test::use_one_thread();
  const std::string dir = test::test_directory("report_open_parts");
  build_dataset(test::tiny_build_options(dir + "/proc", 1));  // one small dressed procedural character
  const CharacterData character = DatasetReader(dir + "/proc/character-0000.h5").read_character("character-0000");
  const std::string model = write_fresh_bundle("report_open_parts_bundle");
  const ModelBundle bundle = load_model_bundle(model);
  EvaluateOptions options;
  options.progress = false;
  options.penetration = false;
  options.methods = {"full"};
  const EvaluationResult result = evaluate_model(bundle, {dir + "/proc/character-0000.h5"}, options);
  ASSERT_EQ(result.characters.size(), 1u);

  const SegmenterExample example{character.mesh, character.skeleton, character.body_weights, character.apparel_mask};
  const SegmenterExample open = open_parts_example(example), bare = open_parts_example(example, true);
  const auto called = [&](const SegmenterExample& e) {
    const at::Tensor p = apparel_probabilities(bundle, e.mesh.V, e.mesh.F, e.skeleton.rest_joints);
    std::vector<uint8_t> mask(size_t(p.size(0)));
    for (int64_t i = 0; i < p.size(0); ++i) mask[size_t(i)] = p[i].item<float>() > 0.5f;
    return mask;
  };
  const std::vector<uint8_t> p = called(open), q = called(bare);
  double inter = 0, uni = 0;
  for (size_t i = 0; i < p.size(); ++i) inter += p[i] && open.apparel_mask[i], uni += p[i] || open.apparel_mask[i];
  const double iou = uni > 0 ? inter / uni : 1.0;
  const double bare_share = double(std::count(q.begin(), q.end(), 1)) / double(q.size());
  const CharacterScores& c = result.characters[0];
  EXPECT_NEAR(c.open_parts_iou, iou, 1e-9);
  EXPECT_NEAR(c.bare_open_parts_share, bare_share, 1e-9);
  ASSERT_EQ(result.open_parts.count(c.subset), 1u);
  EXPECT_NEAR(result.open_parts.at(c.subset).first, iou, 1e-9);
  EXPECT_NEAR(result.open_parts.at(c.subset).second, bare_share, 1e-9);

  ReportOptions report;
  report.out_dir = dir + "/out";
  report.model_dir = model;
  report.command = "amt eval --data proc.h5";
  std::stringstream md;
  md << std::ifstream(write_report(result, report).markdown).rdbuf();
  char row[64];
  std::snprintf(row, sizeof row, " | %.3f | %.1f %% |\n", iou, 100 * bare_share);
  EXPECT_NE(md.str().find(row), std::string::npos) << row << md.str();
}

// The report's Runtime section: hand-set figures appear in the table, each checked against its own
// target on its target thread count (met and missed), the bind against its bound, and metrics.json
// carries them.
TEST(Report, RuntimeFiguresAreTabledAndCheckedAgainstTheirTargets) {
  const std::string dir = test::test_directory("report_runtime");
  EvaluationResult result;
  RuntimeFigures real;
  real.label = "stand-in";
  real.character = "a body of open parts";
  real.mask = "the segmenter";
  real.vertices = 1000, real.faces = 1900, real.repeats = 3, real.apparel_vertices = 150,
  real.true_apparel_vertices = 160;
  real.bind_seconds = 6.5, real.peak_resident_mb = 300;
  real.target_ms = 16, real.target_bind_seconds = 5, real.target_threads = 2;
  RuntimeThreadFigures one, two;
  one.threads = 1, one.median_ms = 20.25, one.p95_ms = 30, one.model_ms = 10, one.lbs_ms = 1, one.apparel_ms = 7;
  one.refiner_ms = 2, one.penetration_ms = 9, one.output_ms = 0.25, one.inside_before = 0.01, one.inside_after = 0;
  one.carried_share = 0.96;
  two = one;
  two.threads = 2, two.median_ms = 7.5;
  real.per_thread = {one, two};
  RuntimeFigures dressed = real;
  dressed.label = "dressed";
  dressed.target_ms = 12, dressed.target_bind_seconds = 0;
  dressed.per_thread[1].median_ms = 13;
  dressed.target_apparel_reference_ratio = 1.5;
  dressed.per_thread[0].reference_apparel_ms = 5;
  result.runtime = {real, dressed};

  ReportOptions report;
  report.out_dir = dir + "/out";
  report.plots = false;
  const ReportFiles files = write_report(result, report);
  std::stringstream md;
  md << std::ifstream(files.markdown).rdbuf();
  const std::string text = md.str();
  EXPECT_NE(text.find("## Runtime"), std::string::npos) << text;
  EXPECT_NE(text.find("apparel mask from the segmenter: 150 vertices (15.0 %; as built 160, 16.0 %); bind 6.50 s"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("| 1 | 20.25 | 30.00 | 1.00 | 7.00 | 2.00 | 9.00 | 0.25 | 1.0 % -> 0.0 % | 96.0 % |"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("- runtime, stand-in: per frame on 2 threads = 7.50 ms (target <= 16 ms): met\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("- runtime, stand-in: bind = 6.50 s (target <= 5 s): NOT met\n"), std::string::npos) << text;
  EXPECT_NE(text.find("- runtime, dressed: per frame on 2 threads = 13.00 ms (target <= 12 ms): NOT met\n"),
            std::string::npos)
      << text;
  EXPECT_EQ(text.find("- runtime, dressed: bind"), std::string::npos) << text;  // no bind target
  // 7 ms against the global form's 5 ms timed beside it, which the Runtime section also states.
  EXPECT_NE(text.find("- runtime, dressed: apparel network / the global form's timed beside it on 1 thread = 1.40 "
                      "(target <= 1.50): met\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("frame by frame on the same character and mask: 5.00 ms on 1 thread (the apparel network 1.40x "
                      "it).\n"),
            std::string::npos)
      << text;
  EXPECT_EQ(text.find("- runtime, stand-in: apparel network"), std::string::npos) << text;  // no ratio target
  EXPECT_EQ(text.find("per frame on 1 thread ="), std::string::npos) << text;  // the target is on 2 threads
  std::stringstream json;
  json << std::ifstream(files.json).rdbuf();
  const std::string j = json.str();
  EXPECT_NE(j.find("\"runtime\": ["), std::string::npos) << j;
  EXPECT_NE(j.find("\"median_ms\": 7.5"), std::string::npos) << j;
  EXPECT_NE(j.find("\"true_apparel_vertices\": 160"), std::string::npos) << j;
}

}  // namespace
}  // namespace amt
