// The joint refiner f_j (eq. 16) and the tiling of apparel and body results into mesh order.
#include "models/joint_refiner.h"

#include <ATen/ATen.h>
#include <c10/core/InferenceMode.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>
#include <torch/utils.h>

#include <string>
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
  // ΔV of single vertices computed by hand from the parameters: the per-vertex MLP (ReLU between its layers) on
  // [(x_i - mean x) / h, (r_i - mean r) / h, p_i], h the rest mesh's height (Y extent), times output_scale.
  {
    const at::NoGradGuard no_grad;
    const at::Tensor x = tiled.detach();
    const float h = (rest.select(1, 1).max() - rest.select(1, 1).min()).item<float>();
    const std::vector<at::Tensor> params = net->parameters();  // weight, bias of each layer in order
    ASSERT_EQ(params.size(), 2 * (options.hidden_widths.size() + 1));
    for (const auto& [b, i] : {std::pair<int64_t, int64_t>{0, 3}, {1, 4}, {1, 17}}) {
      at::Tensor in = at::cat(
          {(x[b][i] - x[b].mean(0)) / h, (rest[i] - rest.mean(0)) / h, at::full({1}, float(mask[i].item<uint8_t>()))});
      for (size_t l = 0; l < params.size(); l += 2) {
        in = at::mv(params[l], in) + params[l + 1];
        if (l + 2 < params.size()) in = in.clamp_min(0);
      }
      const at::Tensor expected = float(options.output_scale) * in;
      EXPECT_TRUE(at::allclose(out.delta[b][i], expected, 1e-5, 1e-6))
          << "batch " << b << " vertex " << i << ": " << out.delta[b][i] << " against " << expected;
    }
  }
  out.V_hat.square().sum().backward();
  EXPECT_TRUE(tiled.grad().defined());
  for (const auto& p : net->parameters()) EXPECT_TRUE(p.grad().defined());
  // The correction does not depend on where the character stands (positions are centred per frame).
  const at::Tensor moved = (tiled.detach() + at::tensor({1.0f, 2.0f, 3.0f}));
  EXPECT_LT((net->forward(moved, rest, mask).delta - out.delta).abs().max().item<float>(), 1e-5f);
}

TEST(JointRefiner, PreparedCharacterEqualsThePlainForward) {
  // prepare() runs the first layer on the constant inputs (rest position, mask) once; a frame then
  // multiplies only its 3 posed channels. Same V̂, ΔV and gradients as forward(tiled, rest, prob).
  for (const std::vector<int64_t>& hidden : {std::vector<int64_t>{16, 8}, std::vector<int64_t>{}}) {
    torch::manual_seed(3);
    JointRefinerOptions options;
    options.zero_init = false;
    options.hidden_widths = hidden;
    JointRefiner net(options);
    net->to(at::kDouble);
    const std::string what = "hidden layers: " + std::to_string(hidden.size());
    const at::Tensor rest = at::randn({20, 3}, at::kDouble) + at::tensor({0.0, 1.0, 0.0}, at::kDouble);
    const at::Tensor prob = at::rand({20}, at::kDouble);
    const at::Tensor tiled = (rest + 0.1 * at::randn({2, 20, 3}, at::kDouble)).requires_grad_();
    const RefinerCharacter character = net->prepare(rest, prob);
    ASSERT_EQ(character.rest_term.sizes(), (at::IntArrayRef{20, hidden.empty() ? 3 : 16})) << what;
    const RefinerOutput plain = net->forward(tiled, rest, prob);
    const RefinerOutput fast = net->forward(tiled, character);
    EXPECT_GT(plain.delta.abs().max().item<double>(), 1e-3) << what;
    EXPECT_LT((fast.V_hat - plain.V_hat).abs().max().item<double>(), 1e-12) << what;
    EXPECT_LT((fast.delta - plain.delta).abs().max().item<double>(), 1e-12) << what;
    // Unbatched, and one frame of the batch.
    const RefinerOutput one = net->forward(tiled[1], character);
    ASSERT_EQ(one.V_hat.sizes(), (at::IntArrayRef{20, 3})) << what;
    EXPECT_LT((one.V_hat - plain.V_hat[1]).abs().max().item<double>(), 1e-12) << what;
    // Gradients in the input and every parameter (the prepared term carries the first layer's).
    std::vector<at::Tensor> inputs = {tiled};
    for (const auto& p : net->parameters()) inputs.push_back(p);
    const at::Tensor w = at::randn({2, 20, 3}, at::kDouble);
    const auto plain_grad = torch::autograd::grad({(plain.V_hat * w).sum()}, inputs);
    const auto fast_grad = torch::autograd::grad({(fast.V_hat * w).sum()}, inputs);
    for (size_t k = 0; k < inputs.size(); ++k) {
      EXPECT_GT(plain_grad[k].abs().max().item<double>(), 0.0) << what << ", input " << k;
      EXPECT_LT((fast_grad[k] - plain_grad[k]).abs().max().item<double>(), 1e-10) << what << ", input " << k;
    }
    // Inference in float, as the runtime runs it (in place).
    net->to(at::kFloat);
    const at::Tensor rest_f = rest.to(at::kFloat), prob_f = prob.to(at::kFloat), x = tiled.detach()[0].to(at::kFloat);
    c10::InferenceMode inference;
    const RefinerOutput expected = net->forward(x, rest_f, prob_f);
    const RefinerOutput runtime = net->forward(x, net->prepare(rest_f, prob_f));
    EXPECT_LT((runtime.V_hat - expected.V_hat).abs().max().item<float>(), 1e-6f) << what;
    EXPECT_LT((runtime.delta - expected.delta).abs().max().item<float>(), 1e-6f) << what;
  }
}

TEST(JointRefiner, RejectsBadShapes) {
  JointRefiner net;
  EXPECT_THROW(net->forward(at::randn({20, 3}), at::randn({19, 3}), at::rand({20})), c10::Error);
  EXPECT_THROW(net->forward(at::randn({20, 3}), at::randn({20, 3}), at::rand({19})), c10::Error);
  EXPECT_THROW(net->prepare(at::randn({20, 3}), at::rand({19})), c10::Error);
  EXPECT_THROW(net->forward(at::randn({19, 3}), net->prepare(at::randn({20, 3}), at::rand({20}))), c10::Error);
}

}  // namespace
}  // namespace amt
