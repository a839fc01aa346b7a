// The skinning predictor f_s (eq. 5-7): shapes, normalised weights and attention, the Table 4
// ablations, and a small overfitting run through differentiable LBS.
#include "models/skinning_predictor.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "models/skinning_overfit.h"

namespace amt {
namespace {

struct Inputs {
  at::Tensor V, joints, G;
};

Inputs random_inputs(int64_t N, int64_t J) {
  Inputs in;
  in.V = at::rand({N, 3}) * at::tensor({0.4f, 1.7f, 0.3f});
  in.joints = at::rand({J, 3}) * at::tensor({0.4f, 1.7f, 0.3f});
  in.G = (in.V.unsqueeze(1) - in.joints.unsqueeze(0)).norm(2, -1) * 1.3;  // (N, J), geodesic >= euclidean
  return in;
}

void expect_rows_sum_to_one(const at::Tensor& X) {
  EXPECT_LT((X.sum(-1) - 1).abs().max().item<float>(), 1e-5f);
  EXPECT_TRUE((X >= 0).all().item<bool>());
}

TEST(SkinningPredictor, WeightsAndAttentionAreDistributionsOverJoints) {
  torch::manual_seed(1);
  SkinningPredictorOptions options;
  options.num_joints = 22;
  SkinningPredictor net(options);
  const Inputs in = random_inputs(20, 22);
  const SkinningOutput out = net->forward_detailed(in.V, in.joints, in.G);
  ASSERT_EQ(out.W.sizes(), (at::IntArrayRef{20, 22}));
  ASSERT_EQ(out.M.sizes(), (at::IntArrayRef{20, 22}));
  ASSERT_EQ(out.logits.sizes(), (at::IntArrayRef{20, 22}));
  expect_rows_sum_to_one(out.W);
  expect_rows_sum_to_one(out.M);
  EXPECT_TRUE(at::allclose(out.W, net->forward(in.V, in.joints, in.G)));
}

TEST(SkinningPredictor, BatchedInputGivesTheSameRows) {
  torch::manual_seed(2);
  SkinningPredictorOptions options;
  options.num_joints = 5;
  SkinningPredictor net(options);
  const Inputs a = random_inputs(20, 5), b = random_inputs(20, 5);
  const at::Tensor W = net->forward(at::stack({a.V, b.V}), at::stack({a.joints, b.joints}), at::stack({a.G, b.G}));
  ASSERT_EQ(W.sizes(), (at::IntArrayRef{2, 20, 5}));
  EXPECT_LT((W[1] - net->forward(b.V, b.joints, b.G)).abs().max().item<float>(), 1e-5f);
}

TEST(SkinningPredictor, AblationVariantsGiveValidWeights) {
  torch::manual_seed(3);
  const Inputs in = random_inputs(20, 5);
  for (const SkinningVariant variant : {SkinningVariant::kNoGeodesic, SkinningVariant::kSortByGeodesic}) {
    SkinningPredictorOptions options;
    options.num_joints = 5;
    options.variant = variant;
    options.sort_k = 3;
    SkinningPredictor net(options);
    const SkinningOutput out = net->forward_detailed(in.V, in.joints, in.G);
    ASSERT_EQ(out.W.sizes(), (at::IntArrayRef{20, 5}));
    expect_rows_sum_to_one(out.W);
    if (variant == SkinningVariant::kNoGeodesic) {
      EXPECT_TRUE(at::allclose(out.M, at::full({20, 5}, 0.2f)));
      // G is not an input: an undefined G works and changing G changes nothing.
      EXPECT_TRUE(at::allclose(net->forward(in.V, in.joints, at::Tensor()), out.W));
    } else {
      EXPECT_FALSE(out.M.defined());
      // The sorted variant depends on G.
      EXPECT_FALSE(at::allclose(net->forward(in.V, in.joints, in.G.flip(1)), out.W));
    }
  }
  // k larger than J is clamped.
  SkinningPredictorOptions options;
  options.num_joints = 5;
  options.variant = SkinningVariant::kSortByGeodesic;
  options.sort_k = 9;
  expect_rows_sum_to_one(SkinningPredictor(options)->forward(in.V, in.joints, in.G));
}

// softmax over joints of -k g, by hand: the attention a hand-made f_m(g) = -k g gives one row.
std::vector<double> softmax_of_minus(double k, const std::vector<double>& g) {
  double sum = 0;
  std::vector<double> out;
  for (double x : g) out.push_back(std::exp(-k * x)), sum += out.back();
  for (double& x : out) x /= sum;
  return out;
}

TEST(SkinningPredictor, AttentionFollowsGeodesicDistances) {
  torch::manual_seed(4);
  SkinningPredictorOptions options;
  options.num_joints = 5;
  SkinningPredictor net(options);
  const Inputs in = random_inputs(20, 5);
  const at::Tensor M1 = net->forward_detailed(in.V, in.joints, in.G).M;
  const at::Tensor M2 = net->forward_detailed(in.V, in.joints, in.G.flip(1)).M;
  EXPECT_TRUE(at::allclose(M1.flip(1), M2, 1e-5, 1e-6));  // f_m is per entry (with row context)
  EXPECT_THROW(net->forward(in.V, in.joints, at::Tensor()), c10::Error);
  EXPECT_THROW(net->forward(in.V, in.joints.narrow(0, 0, 4), in.G), c10::Error);

  // A hand-made f_m: its hidden unit is 0.5 G_ij + 0.5 (G_ij - min_k G_ik) >= 0 (LeakyReLU passes it) and
  // its output -k times that, so M_i = softmax_j(-k G_ij) (the row's constant cancels): attention falls
  // off with the geodesic distance at a rate we know. Inputs unnormalised, so G is used as given.
  SkinningPredictorOptions hand;
  hand.num_joints = 3;
  hand.attention_widths = {1};
  hand.normalize_input = false;
  SkinningPredictor h(hand);
  const double k = 10.0;  // per metre
  {
    torch::NoGradGuard no_grad;
    auto p = h->named_parameters();
    p["attention.linear0.weight"].copy_(at::tensor({0.5f, 0.5f}).view({1, 2}));
    p["attention.linear0.bias"].zero_();
    p["attention.linear1.weight"].fill_(-k);
    p["attention.linear1.bias"].zero_();
  }
  // A hip (0), an elbow (1) and a wrist (2); one vertex 5 cm from the hip, 25 cm from the wrist. As the
  // thigh's skin it is geodesically nearest the hip; as a fingertip hanging beside the thigh the same
  // point is geodesically nearest the wrist, the hip far along the arm and torso.
  const at::Tensor joints = at::tensor({0.0f, 1.0f, 0.0f, 0.3f, 1.3f, 0.0f, 0.3f, 1.0f, 0.0f}).view({3, 3});
  const at::Tensor V = at::tensor({0.05f, 1.0f, 0.0f}).view({1, 3});
  const std::vector<double> thigh = {0.05, 0.6, 0.9}, fingertip = {0.9, 0.3, 0.25};
  const auto attention = [&](const std::vector<double>& g) {
    return h->forward_detailed(V, joints, at::tensor(std::vector<float>(g.begin(), g.end())).view({1, 3}));
  };
  const SkinningOutput on_thigh = attention(thigh), on_finger = attention(fingertip);
  for (const auto& [g, out] : {std::pair{thigh, on_thigh}, std::pair{fingertip, on_finger}}) {
    const std::vector<double> expected = softmax_of_minus(k, g);
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(out.M[0][j].item<double>(), expected[size_t(j)], 1e-6) << "joint " << j;
  }
  EXPECT_EQ(on_thigh.M.argmax(-1).item<int64_t>(), 0);
  EXPECT_EQ(on_finger.M.argmax(-1).item<int64_t>(), 2);  // the wrist, though the hip is nearer in space
  // 5 cm more to one joint scales its attention against the others' by exp(-k 0.05).
  std::vector<double> farther = fingertip;
  farther[2] += 0.05;
  const at::Tensor M3 = attention(farther).M;
  EXPECT_NEAR((M3[0][2] / M3[0][1]).item<double>(), (on_finger.M[0][2] / on_finger.M[0][1]).item<double>() * std::exp(-k * 0.05),
              1e-5);
  // Geodesics alone (same point, same joints) change the predicted weights.
  EXPECT_FALSE(at::allclose(on_thigh.W, on_finger.W, 0.0, 1e-6));
}

// The fixed run of models/skinning_overfit.h; its wall time is a benchmark (amt bench --suite skinning),
// not asserted here.
TEST(SkinningPredictor, OverfitsOneSyntheticCharacterThroughLbs) {
  const int threads = at::get_num_threads();
  at::set_num_threads(1);  // tiny tensors: extra threads only add synchronisation
  const SkinningOverfit run = overfit_skinning_on_a_bar(500);
  at::set_num_threads(threads);
  EXPECT_LT(run.final_loss, run.initial_loss / 10) << "initial " << run.initial_loss << " final " << run.final_loss;
  RecordProperty("initial_loss", std::to_string(run.initial_loss));
  RecordProperty("final_loss", std::to_string(run.final_loss));
  std::printf("skinning overfit: L1 %.5f -> %.5f\n", run.initial_loss, run.final_loss);
}

}  // namespace
}  // namespace amt
