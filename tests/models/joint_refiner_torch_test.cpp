// The joint refiner f_j (eq. 16) and the tiling of apparel and body results into mesh order.
#include "models/joint_refiner.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <vector>

namespace amt {
namespace {

TEST(TileApparelBody, PutsRowsBackInMeshOrder) {
  const at::Tensor mask = at::tensor({0, 1, 1, 0, 1}, at::kByte);
  const at::Tensor A = at::tensor(std::vector<float>{1, 1, 1, 2, 2, 2, 4, 4, 4}).view({3, 3});
  const at::Tensor B = at::tensor(std::vector<float>{0, 0, 0, 3, 3, 3}).view({2, 3});
  const at::Tensor tiled = tile_apparel_body(A, B, mask);
  EXPECT_TRUE(at::equal(tiled.select(1, 0), at::tensor(std::vector<float>{0, 1, 2, 3, 4})));
  // Frame dimension and gradients.
  const at::Tensor As = A.unsqueeze(0).repeat({2, 1, 1}).requires_grad_();
  const at::Tensor out = tile_apparel_body(As, B.unsqueeze(0).repeat({2, 1, 1}), mask);
  ASSERT_EQ(out.sizes(), (at::IntArrayRef{2, 5, 3}));
  out.sum().backward();
  EXPECT_TRUE(at::equal(As.grad(), at::ones_like(As)));
  EXPECT_THROW(tile_apparel_body(A, A, mask), c10::Error);
}

TEST(JointRefiner, StartsAsIdentityAndKeepsShapes) {
  torch::manual_seed(1);
  JointRefiner net;
  const at::Tensor tiled = at::randn({20, 3}), rest = at::randn({20, 3}), prob = at::rand({20});
  const RefinerOutput out = net->forward(tiled, rest, prob);
  ASSERT_EQ(out.V_hat.sizes(), (at::IntArrayRef{20, 3}));
  ASSERT_EQ(out.delta.sizes(), (at::IntArrayRef{20, 3}));
  EXPECT_TRUE(at::equal(out.V_hat, tiled));  // zero-initialised last layer: ΔV = 0
  EXPECT_TRUE(at::equal(out.delta, at::zeros_like(tiled)));

  const RefinerOutput batch = net->forward(at::stack({tiled, tiled}), rest, prob);
  ASSERT_EQ(batch.V_hat.sizes(), (at::IntArrayRef{2, 20, 3}));
}

TEST(JointRefiner, RefinesWithNonZeroWeightsAndPassesGradients) {
  torch::manual_seed(2);
  JointRefinerOptions options;
  options.zero_init = false;
  JointRefiner net(options);
  const at::Tensor tiled = at::randn({2, 20, 3}).requires_grad_();
  const at::Tensor rest = at::randn({20, 3});
  const at::Tensor mask = at::tensor({1, 0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 0}, at::kByte);
  const RefinerOutput out = net->forward(tiled, rest, mask);
  EXPECT_TRUE(at::allclose(out.V_hat, tiled + out.delta));  // eq. (16)
  EXPECT_GT(out.delta.abs().max().item<float>(), 0.0f);
  out.V_hat.square().sum().backward();
  EXPECT_TRUE(tiled.grad().defined());
  for (const auto& p : net->parameters()) EXPECT_TRUE(p.grad().defined());
  // The correction does not depend on where the character stands (positions are centred per frame).
  const at::Tensor moved = (tiled.detach() + at::tensor({1.0f, 2.0f, 3.0f}));
  EXPECT_LT((net->forward(moved, rest, mask).delta - out.delta).abs().max().item<float>(), 1e-5f);
}

TEST(JointRefiner, RejectsBadShapes) {
  JointRefiner net;
  EXPECT_THROW(net->forward(at::randn({20, 3}), at::randn({19, 3}), at::rand({20})), c10::Error);
  EXPECT_THROW(net->forward(at::randn({20, 3}), at::randn({20, 3}), at::rand({19})), c10::Error);
}

}  // namespace
}  // namespace amt
