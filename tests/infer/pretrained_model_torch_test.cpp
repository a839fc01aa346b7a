// Every checkpoint shipped in models/pretrained (issue 19) loads and runs on a tiny generated character:
// the segmenter's probabilities, each skinning predictor's weights (the paper's and the two Table 4
// variants) and the full pipeline (LBS, apparel module, refiner) over a few frames of a walk, all finite
// and of the expected shapes. A checkpoint added to the folder without a place here fails the test.
#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/utils.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "data_tools/builder/apparel.h"
#include "data_tools/builder/body_generator.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/retarget.h"
#include "data_tools/geometry/skeleton.h"
#include "infer/runtime_torch.h"
#include "models/checkpoint.h"
#include "models/pipeline.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

const fs::path kPretrained = fs::path(AMT_ASSET_DIR).parent_path() / "models" / "pretrained";

// A dressed generated character of about 2000 vertices (the runtime's smallest generated size).
const DressedCharacter& tiny_character() {
  static const DressedCharacter character = [] {
    const GeneratedBody body = generate_body(sample_body_params(uint64_t(3)), 1400);
    return dress_character(body, uint64_t(3));
  }();
  return character;
}

void expect_finite(const at::Tensor& x, const std::string& what) {
  ASSERT_TRUE(x.defined()) << what;
  EXPECT_TRUE(at::isfinite(x).all().item<bool>()) << what;
}

void expect_weights(const at::Tensor& W, int64_t rows, int64_t J, const std::string& what) {
  ASSERT_TRUE(W.defined()) << what;
  ASSERT_EQ(W.sizes(), (at::IntArrayRef{rows, J})) << what;
  expect_finite(W, what);
  EXPECT_TRUE((W >= 0).all().item<bool>()) << what;
  EXPECT_LT((W.sum(-1) - 1).abs().max().item<float>(), 1e-4f) << what;
}

// Every shipped checkpoint carries payload_crc32, so a flipped bit in a shipped file is an error on load instead of
// a silently different animation.
TEST(PretrainedModel, EveryShippedCheckpointCarriesItsChecksum) {
  int count = 0;
  for (const auto& e : fs::directory_iterator(kPretrained)) {
    if (e.path().extension() != ".ckpt") continue;
    EXPECT_TRUE(read_checkpoint_info(e.path().string()).checksummed) << e.path().filename().string();
    ++count;
  }
  EXPECT_GE(count, 4);
}

TEST(PretrainedModel, EveryShippedCheckpointLoadsAndRunsOnAGeneratedCharacter) {
  at::set_num_threads(1);
  // The folder's checkpoints, each with the bundle member that holds it.
  std::set<std::string> shipped;
  for (const auto& e : fs::directory_iterator(kPretrained)) {
    if (e.path().extension() == ".ckpt") shipped.insert(e.path().filename().string());
  }
  // apparel_vertices.ckpt: the per-vertex apparel module the shipped one (on handles) was fine-tuned from, run
  // below in place of apparel.ckpt.
  const std::string kApparelVertices = "apparel_vertices.ckpt";
  // segmenter_base.ckpt: the segmenter before its artist-style fine-tune (the before picture's), run below alone.
  const std::string kSegmenterBase = "segmenter_base.ckpt";
  const std::set<std::string> covered = {
      kSegmenterCheckpoint,          kSkinningCheckpoint,       kApparelCheckpoint, kRefinerCheckpoint,
      kSkinningNoGeodesicCheckpoint, kSkinningSortedCheckpoint, kApparelVertices,   kSegmenterBase,
      kApparelOwnWeightsCheckpoint};
  for (const std::string& name : shipped) {
    EXPECT_TRUE(covered.count(name)) << kPretrained.string() << "/" << name
                                     << ": a shipped checkpoint this test does not run: add it here";
  }
  const ModelBundle bundle = load_model_bundle(kPretrained.string());
  const std::map<std::string, bool> loaded = {
      {kSegmenterCheckpoint, !bundle.segmenter.is_empty()},
      {kSkinningCheckpoint, !bundle.skinning.is_empty()},
      {kApparelCheckpoint, bundle.apparel_module() != nullptr},
      {kRefinerCheckpoint, !bundle.refiner.is_empty()},
      {kSkinningNoGeodesicCheckpoint, !bundle.skinning_no_geodesic.is_empty()},
      {kSkinningSortedCheckpoint, !bundle.skinning_sorted.is_empty()},
      {kApparelOwnWeightsCheckpoint, !bundle.apparel_dynamics_own_weights.is_empty()}};
  for (const std::string& name : shipped) {
    if (loaded.count(name)) {
      EXPECT_TRUE(loaded.at(name)) << name << " is in the folder but was not loaded";
    }
  }
  ASSERT_EQ(bundle.joint_names, canonical_joint_names());
  const int64_t J = bundle.num_joints();

  const DressedCharacter& c = tiny_character();
  const int64_t N = c.mesh.num_vertices();
  ASSERT_GE(N, 1500);
  ASSERT_LE(N, 3000);
  const at::Tensor V = at::from_blob(const_cast<float*>(c.mesh.V.data()), {N, 3}, at::kFloat).clone();
  const at::Tensor F = at::from_blob(const_cast<int32_t*>(c.mesh.F.data()), {c.mesh.F.rows(), 3}, at::kInt).clone();
  const MatrixX3f& rest_joints = c.body.skeleton.rest_joints;
  const at::Tensor joints = at::from_blob(const_cast<float*>(rest_joints.data()), {J, 3}, at::kFloat).clone();
  at::Tensor mask = at::empty({N}, at::kBool);
  for (int64_t i = 0; i < N; ++i) mask[i] = bool(c.apparel_mask[size_t(i)]);
  const int64_t Na = mask.sum().item<int64_t>();
  ASSERT_GT(Na, 0);
  ASSERT_LT(Na, N);

  const float diagonal = (std::get<0>(V.max(0)) - std::get<0>(V.min(0))).norm().item<float>();
  // Four frames of a walk on the character's skeleton.
  const Motion walk = retarget_motion(walk_motion(4), canonical_skeleton(), c.body.skeleton);
  std::vector<at::Tensor> frames;
  for (int t = 0; t < 4; ++t) frames.push_back(transforms_tensor(forward_kinematics(c.body.skeleton, walk, t)));

  if (shipped.count(kSegmenterBase)) {
    const ModelBundle base = load_segmenter_bundle((kPretrained / kSegmenterBase).string());
    const at::Tensor p = apparel_probabilities(base, c.mesh.V, c.mesh.F, rest_joints);
    ASSERT_EQ(p.sizes(), (at::IntArrayRef{N}));
    expect_finite(p, "segmenter_base probabilities");
    EXPECT_TRUE(((p >= 0) & (p <= 1)).all().item<bool>());
    // It finds the dressed character's apparel (a fresh network would not: about half its answers wrong).
    const double agree = ((p > 0.5) == mask).to(at::kFloat).mean().item<double>();
    EXPECT_GT(agree, 0.9);
  }

  // The shipped module moves handles; the per-vertex one every apparel vertex (the same folder with it as
  // apparel.ckpt).
  ASSERT_TRUE(bundle.local_apparel());
  EXPECT_GT(bundle.apparel_dynamics->options.handle_spacing, 0.0);
  if (shipped.count(kApparelVertices)) {
    const fs::path per_vertex = test::temp_dir("pretrained_per_vertex");
    for (const std::string& name : shipped) {
      if (name == kApparelCheckpoint || name == kApparelVertices || name == kApparelOwnWeightsCheckpoint) continue;
      fs::copy_file(kPretrained / name, per_vertex / name, fs::copy_options::overwrite_existing);
    }
    fs::copy_file(kPretrained / kApparelVertices, per_vertex / kApparelCheckpoint,
                  fs::copy_options::overwrite_existing);
    const ModelBundle vertices = load_model_bundle(per_vertex.string());
    ASSERT_TRUE(vertices.local_apparel());
    EXPECT_EQ(vertices.apparel_dynamics->options.handle_spacing, 0.0);
    BindOptions options;
    options.apparel_mask = mask;
    const BoundCharacter bound = bind_character(vertices, V, F, joints, options);
    EXPECT_FALSE(bound.handle_rows.defined());
    PipelineStepper stepper(vertices, bound, rest_apparel_history(bound));
    for (size_t t = 0; t < frames.size(); ++t) {
      const at::Tensor out = stepper.step(frames[t]);
      expect_finite(out, "per-vertex module, frame " + std::to_string(t));
      EXPECT_LT((out - frames[t][0].select(1, 3)).norm(2, -1).max().item<float>(), diagonal) << "frame " << t;
    }
  }

  if (shipped.count(kApparelOwnWeightsCheckpoint)) {
    // apparel_own_weights.ckpt: a character bound with given weights (here all on the pelvis) steps with it.
    BindOptions options;
    options.apparel_mask = mask;
    options.weights = at::zeros({N, J});
    options.weights.select(1, 0).fill_(1.0f);
    const BoundCharacter bound = bind_character(bundle, V, F, joints, options);
    ASSERT_TRUE(bound.given_weights);
    PipelineStepper stepper(bundle, bound, rest_apparel_history(bound));
    for (size_t t = 0; t < frames.size(); ++t) {
      const at::Tensor out = stepper.step(frames[t]);
      expect_finite(out, "own-weights module, frame " + std::to_string(t));
      EXPECT_LT((out - frames[t][0].select(1, 3)).norm(2, -1).max().item<float>(), diagonal) << "frame " << t;
    }
  }

  const std::vector<std::pair<SkinningVariant, std::string>> variants = {
      {SkinningVariant::kGeodesicAttention, kSkinningCheckpoint},
      {SkinningVariant::kNoGeodesic, kSkinningNoGeodesicCheckpoint},
      {SkinningVariant::kSortByGeodesic, kSkinningSortedCheckpoint}};
  for (const auto& [variant, checkpoint] : variants) {
    if (!shipped.count(checkpoint)) continue;
    SCOPED_TRACE(checkpoint);
    BindOptions options;
    options.apparel_mask = mask;  // the dressed character's own mask: the apparel module has vertices to move
    options.skinning_variant = variant;
    options.all_vertex_weights = true;
    const BoundCharacter bound = bind_character(bundle, V, F, joints, options);
    // segmenter.ckpt: a probability per vertex.
    ASSERT_EQ(bound.apparel_prob.sizes(), (at::IntArrayRef{N}));
    expect_finite(bound.apparel_prob, "apparel probabilities");
    EXPECT_TRUE(((bound.apparel_prob >= 0) & (bound.apparel_prob <= 1)).all().item<bool>());
    // The skinning checkpoint of this variant: a distribution over the joints per vertex.
    ASSERT_EQ(bound.num_apparel(), Na);
    expect_weights(bound.body_weights, N - Na, J, "body weights");
    expect_weights(bound.vertex_weights, N, J, "vertex weights");
    ASSERT_TRUE(bound.handle_rows.defined());
    EXPECT_GT(bound.handle_rows.size(0), 0);
    EXPECT_LT(bound.handle_rows.size(0), Na);
    // apparel.ckpt and refiner.ckpt: the full pipeline, frame by frame from the rest history.
    PipelineStepper stepper(bundle, bound, rest_apparel_history(bound));
    for (size_t t = 0; t < frames.size(); ++t) {
      const StepOutput out = stepper.step_detailed(frames[t]);
      ASSERT_EQ(out.A_hat.sizes(), (at::IntArrayRef{Na, 3})) << "frame " << t;
      ASSERT_EQ(out.B_hat.sizes(), (at::IntArrayRef{N - Na, 3})) << "frame " << t;
      ASSERT_EQ(out.V_hat.sizes(), (at::IntArrayRef{N, 3})) << "frame " << t;
      expect_finite(out.A_hat, "apparel frame " + std::to_string(t));
      expect_finite(out.V_hat, "frame " + std::to_string(t));
      // Nothing exploded: every vertex nearer the frame's root joint than the rest mesh's diagonal (the
      // bones keep their lengths).
      const at::Tensor root = frames[t][0].select(1, 3);
      EXPECT_LT((out.V_hat - root).norm(2, -1).max().item<float>(), diagonal) << "frame " << t;
    }
  }
}

}  // namespace
}  // namespace amt
