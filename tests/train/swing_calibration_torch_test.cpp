// The learned apparel's swing calibrated on the character's own physics (models/pipeline.h, swing_calibration): the
// pieces and their rigs' swing on hand-made inputs, the gains and the training data's reference, the stepper's output
// S + gain (Â - S) with the module's own state kept, the bind, and the reference measured on a dataset and stored in
// a checkpoint.
#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/optim/adamw.h>
#include <torch/utils.h>

#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/lbs_torch.h"
#include "fresh_model.h"
#include "micro_dataset.h"
#include "models/apparel_handles.h"
#include "models/module_options.h"
#include "models/pipeline.h"
#include "tests/test_support.h"
#include "train/trainer.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

// Rows [share, swing during, swing after] of a response.
at::Tensor response_rows(const std::vector<std::vector<float>>& rows) {
  at::Tensor r = at::empty({int64_t(rows.size()), kApparelResponseChannels}, at::kFloat);
  for (size_t i = 0; i < rows.size(); ++i)
    for (int64_t k = 0; k < kApparelResponseChannels; ++k) r[int64_t(i)][k] = rows[i][size_t(k)];
  return r;
}

TEST(SwingCalibration, PiecesAreTheApparelsConnectedPartsWithTheirRigsMeanSwing) {
  // Five apparel vertices: a strip 0-1-2 and a pair 3-4.
  const at::Tensor response =
      response_rows({{1, 0.2f, 0.1f}, {1, 0.4f, 0.2f}, {0.5f, 0.6f, 0.0f}, {1, 0.05f, 0.05f}, {0, 0, 0}});
  const at::Tensor edges = at::tensor({0, 1, 1, 2, 3, 4}, at::kLong).view({3, 2});
  const SwingCalibration s = apparel_piece_swing(response, edges);
  EXPECT_TRUE(at::equal(s.piece_of, at::tensor({0, 0, 0, 1, 1}, at::kLong)));
  EXPECT_TRUE(at::equal(s.piece_vertices, at::tensor({3, 2}, at::kLong)));
  // share x (during + after), averaged over the piece: (0.3 + 0.6 + 0.3) / 3 and (0.1 + 0) / 2.
  EXPECT_NEAR(s.piece_swing[0].item<float>(), 0.4f, 1e-6f);
  EXPECT_NEAR(s.piece_swing[1].item<float>(), 0.05f, 1e-6f);
  EXPECT_FALSE(s.gain.defined());

  EXPECT_THROW(apparel_piece_swing(response.narrow(1, 0, 2), edges), Error);
  EXPECT_THROW(apparel_piece_swing(response, at::tensor({0, 5}, at::kLong).view({1, 2})), Error);
}

TEST(SwingCalibration, FittedGainIsEachPiecesLeastSquaresScaleClampedToZeroAndTheLargestGain) {
  // Four pieces of two vertices each (edges 0-1, 2-3, 4-5, 6-7), three frames. The module's offsets d = Â - S are
  // arbitrary; the simulation's G - S is 0.5 d on piece 0 (gain 0.5), 2 d on piece 1 (clamped to kMaxSwingGain), -d on
  // piece 2
  // (clamped to 0); piece 3 the module leaves on its anchor (gain 1, nothing to scale).
  at::manual_seed(7);
  const int64_t T = 3, N_a = 8;
  const at::Tensor S = at::randn({T, N_a, 3});
  at::Tensor d = at::randn({T, N_a, 3});
  d.narrow(1, 6, 2).zero_();
  at::Tensor g = d.clone();
  g.narrow(1, 0, 2).mul_(0.5);
  g.narrow(1, 2, 2).mul_(2.0);
  g.narrow(1, 4, 2).mul_(-1.0);
  g.narrow(1, 6, 2).copy_(at::randn({T, 2, 3}));
  const at::Tensor edges = at::tensor({0, 1, 2, 3, 4, 5, 6, 7}, at::kLong).view({4, 2});
  const SwingCalibration fit = fit_swing_calibration(S + d, S, S + g, edges);
  ASSERT_EQ(fit.piece_gain.size(0), 4);
  EXPECT_NEAR(fit.piece_gain[0].item<float>(), 0.5f, 1e-5f);
  EXPECT_FLOAT_EQ(fit.piece_gain[1].item<float>(), float(kMaxSwingGain));
  EXPECT_FLOAT_EQ(fit.piece_gain[2].item<float>(), 0.0f);
  EXPECT_FLOAT_EQ(fit.piece_gain[3].item<float>(), 1.0f);
  // Per vertex: its piece's gain.
  ASSERT_EQ(fit.gain.size(0), N_a);
  for (int64_t v = 0; v < N_a; ++v)
    EXPECT_FLOAT_EQ(fit.gain[v].item<float>(), fit.piece_gain[fit.piece_of[v].item<int64_t>()].item<float>());
  // A partial match: G - S = 0.5 d + e with e orthogonal to d over the piece keeps the least-squares scale 0.5.
  at::Tensor h = g.clone();
  const at::Tensor dp = d.narrow(1, 0, 2);
  at::Tensor e = at::randn({T, 2, 3});
  e -= dp * ((e * dp).sum() / (dp * dp).sum());
  h.narrow(1, 0, 2).add_(e);
  EXPECT_NEAR(fit_swing_calibration(S + d, S, S + h, edges).piece_gain[0].item<float>(), 0.5f, 1e-4f);
  // Scales above 1/2 (the module beats rigid skinning): 0.6 -> 2 x 0.6 - 0.5 = 0.7, 0.8 -> 1; 0.3 stays; above 1
  // the module swings in step but less far: 1.1 stays (livened), 1.4 -> kMaxSwingGain = 1.25.
  ASSERT_EQ(kMaxSwingGain, 1.25);
  for (const auto& [scale, gain] : std::vector<std::pair<double, float>>{
           {0.3, 0.3f}, {0.6, 0.7f}, {0.8, 1.0f}, {1.0, 1.0f}, {1.1, 1.1f}, {1.4, 1.25f}}) {
    at::Tensor k = g.clone();
    k.narrow(1, 0, 2).copy_(d.narrow(1, 0, 2) * scale);
    EXPECT_NEAR(fit_swing_calibration(S + d, S, S + k, edges).piece_gain[0].item<float>(), gain, 1e-4f) << scale;
  }

  // Bad input: shapes that do not match, an edge out of range, a non-finite position.
  EXPECT_THROW(fit_swing_calibration(S + d, S.narrow(0, 0, 2), S + g, edges), Error);
  EXPECT_THROW(fit_swing_calibration(S + d, S, S + g, at::tensor({0, 8}, at::kLong).view({1, 2})), Error);
  at::Tensor bad = S + g;
  bad[1][3][0] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(fit_swing_calibration(S + d, S, bad, edges), Error);
}

TEST(SwingCalibration, TheReferenceIsTheLeastLivelyPieceOfTheTrainingCharacters) {
  // Pieces of swing 0.9 and 0.1 in one character, 0.3 in another, and a character without pieces.
  SwingCalibration a, b, none;
  a.piece_swing = at::tensor({0.9f, 0.1f});
  b.piece_swing = at::tensor({0.3f});
  EXPECT_FLOAT_EQ(float(swing_reference({a, b, none})), 0.1f);
  EXPECT_FLOAT_EQ(float(swing_reference({none, b})), 0.3f);
  EXPECT_EQ(swing_reference({}), 0.0);
  EXPECT_EQ(swing_reference({none}), 0.0);
}

// A micro character bound to a fresh local module whose decoder is not zero (so the module swings), and a motion.
struct Bound {
  ModelBundle bundle;
  BoundCharacter character;
  at::Tensor motion;
};

Bound bound_micro(const std::string& name, double handle_spacing) {
  test::use_one_thread();
  Bound b;
  const std::string dir =
      test::write_fresh_model(test::test_directory(name + "_model"), 5, canonical_joint_names(), true, handle_spacing);
  const std::string data = test::test_directory(name + "_data") + "/micro.h5";
  test::write_micro_dataset(data, {200, 12, 1, {}});
  b.bundle = load_model_bundle(dir);
  DatasetReader reader(data);
  const CharacterData c = reader.read_character(reader.character_names().front());
  const int64_t N = c.mesh.num_vertices(), J = c.skeleton.num_joints();
  BindOptions o;
  o.apparel_mask = at::from_blob(const_cast<uint8_t*>(c.apparel_mask.data()), {N}, at::kByte).to(at::kBool);
  b.character =
      bind_character(b.bundle, at::from_blob(const_cast<float*>(c.mesh.V.data()), {N, 3}, at::kFloat).clone(),
                     at::from_blob(const_cast<int32_t*>(c.mesh.F.data()), {c.mesh.F.rows(), 3}, at::kInt).to(at::kLong),
                     at::from_blob(const_cast<float*>(c.skeleton.rest_joints.data()), {J, 3}, at::kFloat).clone(), o);
  const Transforms T = reader.read_joint_transforms("walk0", 0, 6);
  b.motion = at::empty({6, J, 3, 4});
  for (int64_t i = 0; i < 6 * J; ++i)
    std::memcpy(b.motion.data_ptr<float>() + 12 * i, T[size_t(i)].data(), 12 * sizeof(float));
  return b;
}

// The stepper shows S + gain (Â - S) and keeps the module's own Â as its state: gain 0 is the anchor (rigid
// skinning by the anchor weights), gain 1 the module as trained, and the history equals the ungained stepper's. A gain
// above 1 scales the handles' offsets, and the vertices follow them turning (follow_turning_handles); a module that
// moves vertices is not livened (a gain above 1 shows the module as trained).
void check_gained_stepper(const Bound& b) {
  ASSERT_GT(b.character.num_apparel(), 0);
  const int64_t N_a = b.character.num_apparel();
  const bool handles = b.character.handle_rows.defined();
  BoundCharacter zero = b.character, third = b.character, lively = b.character;
  zero.apparel_swing_gain = at::zeros({N_a});
  third.apparel_swing_gain = at::full({N_a}, 0.3f);
  lively.apparel_swing_gain = at::full({N_a}, 1.5f);
  const at::Tensor history = rest_apparel_history(b.character);
  PipelineStepper plain(b.bundle, b.character, history, PipelineStages::kBodyApparel);
  PipelineStepper rigid(b.bundle, zero, history, PipelineStages::kBodyApparel);
  PipelineStepper calm(b.bundle, third, history, PipelineStages::kBodyApparel);
  PipelineStepper live(b.bundle, lively, history, PipelineStages::kBodyApparel);
  // Without the stretch limit the shown positions are the gains' exactly.
  for (PipelineStepper* s : {&plain, &rigid, &calm, &live}) s->set_strain_limit(0.0f);
  const ApparelRig rig = handles ? b.character.rig() : ApparelRig();
  const at::Tensor A_rest = b.character.V.index_select(0, b.character.apparel_ids);
  float largest_swing = 0;
  for (int64_t t = 0; t < b.motion.size(0); ++t) {
    const at::Tensor T = b.motion[t];
    const StepOutput P = plain.step_detailed(T), R = rigid.step_detailed(T), C = calm.step_detailed(T),
                     L = live.step_detailed(T);
    const at::Tensor& A = P.A_hat;
    const at::Tensor S =
        linear_blend_skinning(A_rest, b.character.apparel_anchor_weights, T.unsqueeze(0), b.character.joints)
            .squeeze(0);
    EXPECT_LT((R.A_hat - S).abs().max().item<float>(), 1e-5f) << "frame " << t;
    EXPECT_LT((C.A_hat - (S + 0.3f * (A - S))).abs().max().item<float>(), 1e-5f) << "frame " << t;
    EXPECT_TRUE(at::allclose(rigid.history(), plain.history(), 0.0, 1e-6)) << "frame " << t;
    EXPECT_TRUE(at::allclose(calm.history(), plain.history(), 0.0, 1e-6)) << "frame " << t;
    if (!handles) {
      EXPECT_FALSE(P.A_handles.defined());
      EXPECT_TRUE(at::equal(L.A_hat, A)) << "frame " << t;
      EXPECT_TRUE(at::allclose(live.history(), plain.history(), 0.0, 1e-6)) << "frame " << t;
    } else {
      // The module's own handles are the same in every stepper; the livened ones swing 1.5 times as far.
      ASSERT_TRUE(P.A_handles.defined());
      const at::Tensor S_h = S.index_select(0, rig.rows), A_h = P.A_handles;
      for (const StepOutput* out : {&R, &C, &L}) EXPECT_TRUE(at::allclose(out->A_handles, A_h, 0.0, 1e-6));
      const at::Tensor expected = follow_turning_handles(S_h + 1.5f * (A_h - S_h), S_h, S, rig);
      EXPECT_LT((L.A_hat - expected).abs().max().item<float>(), 1e-5f) << "frame " << t;
      // A livened piece swings further than the module's own.
      if ((A - S).norm().item<float>() > 1e-4f) {
        EXPECT_GT((L.A_hat - S).norm().item<float>(), 1.2f * (A - S).norm().item<float>()) << "frame " << t;
      }
    }
    largest_swing = std::max(largest_swing, (A - S).abs().max().item<float>());
  }
  EXPECT_GT(largest_swing, 1e-3f);  // the module swings: the gains are measurable
}

TEST(SwingCalibration, TheStepperScalesWhatTheModuleShowsNotItsState) {
  check_gained_stepper(bound_micro("swing_stepper_vertices", 0.0));
  check_gained_stepper(bound_micro("swing_stepper_handles", 0.05));
}

// fit_swing_on_motion rolls the module out as the stepper does, its own gain set aside: against its own rollout the
// gain is 1, against the anchor skinning 0, against S + 0.4 (Â - S) 0.4, on every piece the module moves; in the
// paper protocol's windows started from the truth, the same.
TEST(SwingCalibration, FittedOnAMotionRecoversTheScaleOfTheModulesOwnRollout) {
  const Bound b = bound_micro("swing_fit_motion", 0.05);
  const int64_t T = b.motion.size(0), N_a = b.character.num_apparel();
  ASSERT_GT(N_a, 0);
  const at::Tensor lead = motion_lead_in(b.motion[0], b.character.joints, 3);
  PipelineStepper stepper(b.bundle, b.character, rest_apparel_history(b.character), PipelineStages::kBodyApparel);
  for (int64_t k = 0; k < lead.size(0); ++k) stepper.step(lead[k]);
  const at::Tensor A_rest = b.character.V.index_select(0, b.character.apparel_ids);
  at::Tensor A = at::empty({T, N_a, 3}), S = at::empty({T, N_a, 3});
  for (int64_t t = 0; t < T; ++t) {
    A[t] = stepper.step_detailed(b.motion[t]).A_hat;
    S[t] = linear_blend_skinning(A_rest, b.character.apparel_anchor_weights, b.motion[t].unsqueeze(0),
                                 b.character.joints)[0];
  }
  const SwingCalibration own = fit_swing_on_motion(b.bundle, b.character, lead, b.motion, A);
  ASSERT_EQ(own.gain.size(0), N_a);
  EXPECT_GT(own.gain.min().item<float>(), 0.9999f);
  // The pieces the module moves (offsets of more than 1e-4 m somewhere): the truth between S and Â scales them.
  const at::Tensor moved = (A - S).abs().amax({0, 2}).gt(1e-4f);
  ASSERT_TRUE(moved.any().item<bool>());
  const SwingCalibration part = fit_swing_on_motion(b.bundle, b.character, lead, b.motion, S + 0.4f * (A - S));
  const SwingCalibration none = fit_swing_on_motion(b.bundle, b.character, lead, b.motion, S);
  EXPECT_LT((part.gain.masked_select(moved) - 0.4f).abs().max().item<float>(), 1e-3f);
  EXPECT_LT(none.gain.masked_select(moved).abs().max().item<float>(), 1e-3f);
  // Windows of 4 frames (1 predicted each, stride 1) started from the truth's 3 frames before: a truth whose every
  // frame from the 4th on is the module's prediction from the truth before it gives gain 1; the anchor skinning as
  // truth, 0 on every piece the module moves away from it.
  at::Tensor chained = A.clone();
  PipelineStepper one_step(b.bundle, b.character, A.narrow(0, 0, 3), PipelineStages::kBodyApparel);
  for (int64_t t = 3; t < T; ++t) {
    one_step.reset(chained.narrow(0, t - 3, 3), b.motion.narrow(0, t - 3, 3));
    chained[t] = one_step.step_detailed(b.motion[t]).A_hat;
  }
  EXPECT_GT(fit_swing_on_motion(b.bundle, b.character, lead, b.motion, chained, kDefaultStrainLimit, 4)
                .gain.min()
                .item<float>(),
            0.9999f);
  const at::Tensor on_anchor =
      fit_swing_on_motion(b.bundle, b.character, lead, b.motion, S, kDefaultStrainLimit, 4).gain;
  EXPECT_TRUE(on_anchor.lt(1e-3f).any().item<bool>());
  EXPECT_TRUE((on_anchor.lt(1e-3f) | on_anchor.eq(1.0f)).all().item<bool>());
  EXPECT_THROW(fit_swing_on_motion(b.bundle, b.character, lead, b.motion, S, kDefaultStrainLimit, 3), Error);
  EXPECT_THROW(fit_swing_on_motion(b.bundle, b.character, lead, b.motion, S, kDefaultStrainLimit, T + 1), Error);
  // The character's own gain (here 0: what it shows is S) does not enter the fit: the module runs as trained.
  BoundCharacter calmed = b.character;
  calmed.apparel_swing_gain = at::zeros({N_a});
  EXPECT_TRUE(at::allclose(fit_swing_on_motion(b.bundle, calmed, lead, b.motion, S + 0.4f * (A - S)).gain, part.gain,
                           0.0, 1e-6));
  // Bad input: a truth of other frames or vertices, a motion without frames.
  EXPECT_THROW(fit_swing_on_motion(b.bundle, b.character, lead, b.motion, A.narrow(0, 0, T - 1)), Error);
  EXPECT_THROW(fit_swing_on_motion(b.bundle, b.character, lead, b.motion, A.narrow(1, 0, N_a - 1)), Error);
  EXPECT_THROW(fit_swing_on_motion(b.bundle, b.character, lead, b.motion.narrow(0, 0, 0), A.narrow(0, 0, 0)), Error);

  // Several motions pool their frames into one scale per piece: the module's own rollout beside the anchor skinning
  // halves every piece it moves (sum <d, d> / (2 sum |d|^2)); a motion given twice is the motion once.
  const SwingCalibration half = fit_swing_on_motions(b.bundle, b.character, {{lead, b.motion, A}, {lead, b.motion, S}});
  EXPECT_LT((half.gain.masked_select(moved) - 0.5f).abs().max().item<float>(), 1e-3f);
  const at::Tensor partial = S + 0.4f * (A - S);
  EXPECT_TRUE(at::allclose(
      fit_swing_on_motions(b.bundle, b.character, {{lead, b.motion, partial}, {lead, b.motion, partial}}).gain,
      part.gain, 0.0, 1e-6));
  EXPECT_THROW(fit_swing_on_motions(b.bundle, b.character, {}), Error);
  EXPECT_THROW(fit_swing_on_motions(b.bundle, b.character, {{lead, b.motion, A}, {lead, b.motion, A.narrow(1, 0, 1)}}),
               Error);
}

TEST(SwingCalibration, BindCalmsEachPieceOfARigStifferThanTheReference) {
  Bound b = bound_micro("swing_bind", 0.05);
  const int64_t N = b.character.num_vertices();
  // One simulated bone under every vertex, swinging 0.1 during the sway and 0.05 after it: share x swing = 0.15.
  auto bones = std::make_shared<ApparelBones>();
  bones->names = {"skirt"};
  bones->heads = MatrixX3f::Zero(1, 3);
  bones->parents = {-1};
  bones->indices = Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>::Zero(N, 1);
  bones->weights = MatrixXfR::Ones(N, 1);
  bones->response = MatrixXfR(1, 3);
  bones->response << 1.0f, 0.1f, 0.05f;
  BindOptions o;
  o.apparel_mask = b.character.apparel_mask;
  o.physics_bones = bones;
  const auto bind = [&](const ModelBundle& bundle) {
    return bind_character(bundle, b.character.V, b.character.faces, b.character.joints, o);
  };
  // A module that does not know its training data's reference: no calibration.
  EXPECT_FALSE(bind(b.bundle).apparel_swing_gain.defined());
  b.bundle.apparel_dynamics->options.swing_reference = 0.6;
  const BoundCharacter calmed = bind(b.bundle);
  ASSERT_TRUE(calmed.apparel_swing_gain.defined());
  ASSERT_EQ(calmed.apparel_swing_gain.size(0), calmed.num_apparel());
  EXPECT_LT((calmed.apparel_swing_gain - 0.25f).abs().max().item<float>(), 1e-6f);  // 0.15 / 0.6
  const SwingCalibration s = swing_calibration(calmed, 0.6);
  EXPECT_TRUE(at::equal(s.gain, calmed.apparel_swing_gain));
  // As lively as the reference or more: gain 1. Asked not to, or without the physics: no gain.
  b.bundle.apparel_dynamics->options.swing_reference = 0.1;
  EXPECT_TRUE(at::equal(bind(b.bundle).apparel_swing_gain, at::ones({calmed.num_apparel()})));
  o.calibrate_swing = false;
  EXPECT_FALSE(bind(b.bundle).apparel_swing_gain.defined());
  o.calibrate_swing = true;
  o.physics_bones = nullptr;
  EXPECT_FALSE(bind(b.bundle).apparel_swing_gain.defined());
  EXPECT_THROW(swing_calibration(bind(b.bundle), 0.6), Error);  // the response is unknown
  EXPECT_THROW(swing_calibration(calmed, 0.0), Error);
}

TEST(SwingCalibration, TheReferenceIsMeasuredOnTheTrainingCharactersAndStoredInTheCheckpoint) {
  test::use_one_thread();
  // Two characters whose rig swings share x (during + after) = 0.3 (train) and 0.05 (test: not counted).
  const std::string data = test::test_directory("swing_reference_data") + "/rigged.h5";
  {
    const Skeleton skeleton = canonical_skeleton();
    DatasetWriter writer(data, 30.0f, skeleton.names);
    for (const auto& [name, split, during] : std::vector<std::tuple<std::string, std::string, float>>{
             {"lively", "train", 0.2f}, {"stiff", "test", 0.03f}}) {
      CharacterData c = capsule_example_character(skeleton, 200);
      c.name = name;
      c.split = split;
      const int N = c.mesh.num_vertices();
      for (int i = 0; i < N; ++i) c.apparel_mask[size_t(i)] = c.body_weights(i, kPelvis) == 1.0f ? 1 : 0;
      Rig rig;
      rig.bone_names = {"skirt"};
      rig.bone_parents = {-1};
      rig.rest_transforms = {make_transform(Eigen::Matrix3f::Identity(), Eigen::Vector3f::Zero())};
      rig.skin_indices = MatrixXiR::Zero(N, 1);
      rig.skin_weights = MatrixXfR::Ones(N, 1);
      rig.response = MatrixXfR(1, 3);
      rig.response << 1.0f, during, during / 2;
      c.rig = rig;
      writer.add_character(c);
    }
    writer.commit();
  }
  EXPECT_NEAR(measure_swing_reference({data}), 0.3, 1e-6);

  const fs::path model = test::write_fresh_model(test::test_directory("swing_reference_model"), 5,
                                                 canonical_joint_names(), /*local_apparel=*/true, 0.05);
  const std::string ckpt = (model / kApparelCheckpoint).string();
  const ModelBundle before = load_model_bundle(model.string());
  EXPECT_EQ(set_swing_reference(ckpt, 0.3), 0.0);
  const ModelBundle after = load_model_bundle(model.string());
  EXPECT_DOUBLE_EQ(after.apparel_dynamics->options.swing_reference, 0.3);
  // Everything else as it was: the parameters and buffers, the other options.
  const auto p0 = before.apparel_dynamics->named_parameters(), p1 = after.apparel_dynamics->named_parameters();
  ASSERT_EQ(p0.size(), p1.size());
  for (size_t i = 0; i < p0.size(); ++i) EXPECT_TRUE(at::equal(p0[i].value(), p1[i].value())) << p0[i].key();
  EXPECT_EQ(after.apparel_dynamics->options.handle_spacing, 0.05);
  EXPECT_EQ(set_swing_reference(ckpt, 0.25), 0.3);
  EXPECT_THROW(set_swing_reference(ckpt, 0.0), Error);
  // A checkpoint that can resume keeps its optimizer's state: one more AdamW step from the rewritten file moves the
  // parameters exactly as from the original (a fresh state would not: its step count and moments differ).
  {
    ApparelDynamicsOptions options;
    options_from_json(read_checkpoint_info(ckpt).options_json, ckpt, options);
    const auto step = [](ApparelDynamicsNet& net, torch::optim::AdamW& optimizer) {
      for (at::Tensor& p : net->parameters()) p.mutable_grad() = at::full_like(p, 0.5f);
      optimizer.step();
    };
    ApparelDynamicsNet net(options);
    const CheckpointInfo info = load_checkpoint(ckpt, ModuleKind::kApparel, *net, nullptr);
    torch::optim::AdamW optimizer(net->parameters(), torch::optim::AdamWOptions(1e-2));
    step(net, optimizer);
    const std::string resumable = (model / "resumable.ckpt").string();
    save_checkpoint(resumable, info, *net, &optimizer);
    EXPECT_EQ(set_swing_reference(resumable, 0.5), 0.25);
    ASSERT_TRUE(read_checkpoint_info(resumable).has_optimizer);
    ApparelDynamicsNet again(options);
    torch::optim::AdamW reloaded(again->parameters(), torch::optim::AdamWOptions(1e-2));
    EXPECT_EQ(load_checkpoint(resumable, ModuleKind::kApparel, *again, &reloaded).step, info.step);
    step(net, optimizer);
    step(again, reloaded);
    const auto a = net->parameters(), b = again->parameters();
    for (size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(at::equal(a[i], b[i])) << "parameter " << i;
  }
  // The global form has no such setting.
  const fs::path global = test::write_fresh_model(test::test_directory("swing_reference_global"), 5);
  const std::string e = test::error_of([&] { set_swing_reference((global / kApparelCheckpoint).string(), 0.3); });
  EXPECT_NE(e.find("expected the local apparel module"), std::string::npos) << e;
}

}  // namespace
}  // namespace amt
