// The losses of models/losses.h against hand-computed values on tiny meshes, and their gradients
// against finite differences.
#include "models/losses.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>

#include "tests/models/finite_difference.h"

namespace amt {
namespace {

const auto kDouble = at::TensorOptions().dtype(at::kDouble);

at::Tensor edges_of(std::initializer_list<int64_t> flat) {
  return at::tensor(std::vector<int64_t>(flat), at::kLong).view({-1, 2});
}

at::Tensor points(std::initializer_list<double> flat) {
  return at::tensor(std::vector<double>(flat), kDouble).view({-1, 3});
}

TEST(Losses, ApparelBceIsStandardBinaryCrossEntropy) {
  const at::Tensor logits = at::tensor({0.0, std::log(3.0)}, kDouble);
  const at::Tensor mask = at::tensor({1, 0}, at::kByte);
  // -log(0.5) for the apparel vertex, -log(1 - 0.75) for the body vertex.
  const double expected = 0.5 * (-std::log(0.5) - std::log(0.25));
  EXPECT_NEAR(apparel_bce_loss(logits, mask).item<double>(), expected, 1e-12);
  // pos_weight scales the apparel term only.
  EXPECT_NEAR(apparel_bce_loss(logits, mask, 3.0).item<double>(), 0.5 * (-3 * std::log(0.5) - std::log(0.25)), 1e-12);
  // Per-vertex weights scale each term; the mean stays over the vertices.
  const at::Tensor weights = at::tensor({1.0, 4.0}, logits.options());
  EXPECT_NEAR(apparel_bce_loss(logits, mask, 1.0, weights).item<double>(), 0.5 * (-std::log(0.5) - 4 * std::log(0.25)),
              1e-12);
  EXPECT_THROW(apparel_bce_loss(logits, mask, 1.0, at::ones({3}, logits.options())), c10::Error);
}

TEST(Losses, VertexL1SumsXyzAndAveragesVertices) {
  const at::Tensor pred = points({1, -2, 0.5, 4, 4, 4});
  const at::Tensor gt = points({0, 0, 0, 4, 4, 4});
  EXPECT_NEAR(vertex_l1_loss(pred, gt).item<double>(), (1 + 2 + 0.5) / 2.0, 1e-12);
  // A frame dimension is averaged like vertices.
  EXPECT_NEAR(vertex_l1_loss(at::stack({pred, gt}), at::stack({gt, gt})).item<double>(), 3.5 / 4.0, 1e-12);
}

TEST(Losses, EdgeLengthOfStretchedTwoEdgeMeshAgainstRestLengths) {
  const at::Tensor rest = points({0, 0, 0, 1, 0, 0, 2, 0, 0});
  const at::Tensor pred = points({0, 0, 0, 2, 0, 0, 3, 0, 0});  // first edge stretched 1 -> 2, second kept
  const at::Tensor edges = edges_of({0, 1, 1, 2});
  EXPECT_NEAR(edge_length_loss(pred, rest, edges).item<double>(), 0.5, 1e-9);
  // Rigid motion of the rest mesh costs nothing.
  const at::Tensor moved = points({5, 1, 0, 5, 2, 0, 5, 3, 0});
  EXPECT_NEAR(edge_length_loss(moved, rest, edges).item<double>(), 0.0, 1e-9);
  // Compression counts like stretching.
  const at::Tensor squeezed = points({0, 0, 0, 0.5, 0, 0, 1.0, 0, 0});
  EXPECT_NEAR(edge_length_loss(squeezed, rest, edges).item<double>(), 0.5, 1e-9);
}

TEST(Losses, WeightSmoothnessIsMeanEdgeNorm) {
  const at::Tensor W = at::tensor({1.0, 0.0, 0.0, 1.0, 0.0, 1.0}, kDouble).view({3, 2});
  const at::Tensor edges = edges_of({0, 1, 1, 2});
  EXPECT_NEAR(weight_smoothness_loss(W, edges).item<double>(), std::sqrt(2.0) / 2.0, 1e-6);
}

TEST(Losses, WeightSmoothnessGradientIsFiniteAtEqualRows) {
  const at::Tensor W = at::full({2, 3}, 1.0 / 3.0, kDouble).requires_grad_();
  const at::Tensor loss = weight_smoothness_loss(W, edges_of({0, 1}));
  loss.backward();
  EXPECT_TRUE(W.grad().isfinite().all().item<bool>());
  EXPECT_NEAR(W.grad().abs().max().item<double>(), 0.0, 1e-12);
}

TEST(Losses, DisplacementL2IsMeanSquaredNorm) {
  EXPECT_NEAR(displacement_l2_loss(points({1, 2, 2, 0, 0, 0})).item<double>(), 4.5, 1e-12);
}

TEST(Losses, WeightedSumsUseThePaperWeights) {
  at::manual_seed(1);
  const at::Tensor rest = at::randn({4, 3}, kDouble), pred = at::randn({2, 4, 3}, kDouble);
  const at::Tensor gt = at::randn({2, 4, 3}, kDouble), delta = at::randn({2, 4, 3}, kDouble);
  const at::Tensor W = at::softmax(at::randn({4, 5}, kDouble), 1);
  const at::Tensor edges = edges_of({0, 1, 1, 2, 2, 3, 3, 0});
  const LossWeights w;
  EXPECT_EQ(w.vertex, 1.0);
  EXPECT_EQ(w.edge, 100.0);
  EXPECT_EQ(w.smoothness, 0.01);
  EXPECT_EQ(w.regularizer, 0.01);

  const LossTerms body = body_loss(pred, gt, rest, edges, W);
  EXPECT_NEAR(body.total.item<double>(),
              body.vertex.item<double>() + 100 * body.edge.item<double>() + 0.01 * body.smoothness.item<double>(),
              1e-9);
  EXPECT_NEAR(body.vertex.item<double>(), vertex_l1_loss(pred, gt).item<double>(), 1e-12);

  const LossTerms apparel = apparel_loss(pred, gt, rest, edges);
  EXPECT_NEAR(apparel.total.item<double>(), apparel.vertex.item<double>() + 100 * apparel.edge.item<double>(), 1e-9);
  EXPECT_FALSE(apparel.smoothness.defined());

  LossWeights custom;
  custom.regularizer = 2.0;
  const LossTerms refiner = refiner_loss(pred, gt, rest, edges, delta, custom);
  EXPECT_NEAR(refiner.total.item<double>(),
              refiner.vertex.item<double>() + 100 * refiner.edge.item<double>() +
                  2.0 * displacement_l2_loss(delta).item<double>(),
              1e-9);
}

TEST(Losses, GradientsMatchFiniteDifferences) {
  at::manual_seed(7);
  const at::Tensor rest = at::randn({5, 3}, kDouble);
  const at::Tensor gt = at::randn({2, 5, 3}, kDouble);
  const at::Tensor pred = at::randn({2, 5, 3}, kDouble);
  const at::Tensor edges = edges_of({0, 1, 1, 2, 2, 3, 3, 4, 4, 0, 0, 2});
  const at::Tensor mask = at::tensor({1, 0, 1, 1, 0}, at::kByte);

  EXPECT_LT(test::max_gradient_error([&](const at::Tensor& x) { return apparel_bce_loss(x, mask, 2.0); },
                                     at::randn({5}, kDouble)),
            1e-7);
  const at::Tensor vertex_weights = at::tensor({1.0, 5.0, 1.0, 0.5, 2.0}, kDouble);
  EXPECT_LT(test::max_gradient_error(
                [&](const at::Tensor& x) { return apparel_bce_loss(x, mask, 2.0, vertex_weights); },
                at::randn({5}, kDouble)),
            1e-7);
  EXPECT_LT(test::max_gradient_error([&](const at::Tensor& x) { return vertex_l1_loss(x, gt); }, pred), 1e-7);
  EXPECT_LT(test::max_gradient_error([&](const at::Tensor& x) { return edge_length_loss(x, rest, edges); }, pred),
            1e-7);
  EXPECT_LT(test::max_gradient_error([&](const at::Tensor& x) { return weight_smoothness_loss(x, edges); },
                                     at::softmax(at::randn({5, 4}, kDouble), 1)),
            1e-7);
  EXPECT_LT(test::max_gradient_error([&](const at::Tensor& x) { return displacement_l2_loss(x); }, pred), 1e-7);
  const at::Tensor W = at::softmax(at::randn({5, 4}, kDouble), 1);
  EXPECT_LT(test::max_gradient_error([&](const at::Tensor& x) { return body_loss(x, gt, rest, edges, W).total; },
                                     pred),
            1e-6);
}

TEST(Losses, SkinningWeightKlIsHandComputedAndZeroAtTheTruth) {
  // One vertex, two joints: logits (0, ln 3) give W = (1/4, 3/4); W̄ = (1/2, 1/2):
  // KL = 1/2 ln(2) + 1/2 ln(2/3) = 1/2 ln(4/3).
  const at::Tensor logits = at::tensor({0.0, std::log(3.0)}, kDouble).view({1, 2});
  const at::Tensor half = at::full({1, 2}, 0.5, kDouble);
  EXPECT_NEAR(skinning_weight_kl_loss(logits, half).item<double>(), 0.5 * std::log(4.0 / 3.0), 1e-12);
  // A one-hot ground truth: 0 log 0 counts 0, KL = -ln(3/4).
  const at::Tensor one_hot = at::tensor({0.0, 1.0}, kDouble).view({1, 2});
  EXPECT_NEAR(skinning_weight_kl_loss(logits, one_hot).item<double>(), -std::log(0.75), 1e-12);
  // Zero at the truth; the mean over vertices.
  at::manual_seed(3);
  const at::Tensor many = at::randn({6, 4}, kDouble);
  EXPECT_NEAR(skinning_weight_kl_loss(many, at::softmax(many, -1)).item<double>(), 0.0, 1e-12);
  const at::Tensor two = at::cat({logits, logits}), two_gt = at::cat({half, one_hot});
  EXPECT_NEAR(skinning_weight_kl_loss(two, two_gt).item<double>(),
              0.5 * (0.5 * std::log(4.0 / 3.0) - std::log(0.75)), 1e-12);
  // Gradient by finite differences, and the weighted term in body_loss.
  const at::Tensor target = at::softmax(at::randn({6, 4}, kDouble), 1);
  EXPECT_LT(test::max_gradient_error([&](const at::Tensor& x) { return skinning_weight_kl_loss(x, target); }, many),
            1e-7);
  const at::Tensor rest = at::randn({6, 3}, kDouble), pred = at::randn({2, 6, 3}, kDouble);
  const at::Tensor edges = edges_of({0, 1, 1, 2, 2, 3, 3, 4, 4, 5});
  LossWeights w;
  w.skinning_weights = 0.5;
  const LossTerms body = body_loss(pred, pred, rest, edges, at::softmax(many, 1), w, many, target);
  EXPECT_NEAR(body.total.item<double>(),
              100 * body.edge.item<double>() + 0.01 * body.smoothness.item<double>() +
                  0.5 * skinning_weight_kl_loss(many, target).item<double>(),
              1e-9);
  EXPECT_THROW(skinning_weight_kl_loss(many, target.narrow(0, 0, 5)), c10::Error);
}

TEST(Losses, RejectsMismatchedShapes) {
  EXPECT_THROW(vertex_l1_loss(at::zeros({4, 3}), at::zeros({5, 3})), c10::Error);
  EXPECT_THROW(edge_length_loss(at::zeros({4, 3}), at::zeros({5, 3}), edges_of({0, 1})), c10::Error);
  EXPECT_THROW(apparel_bce_loss(at::zeros({4}), at::zeros({3})), c10::Error);
}

}  // namespace
}  // namespace amt
