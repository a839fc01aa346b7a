// Neighbour tables of the apparel graph and the factorised EdgeConv against a per-edge evaluation
// of the same weights.
#include "models/edge_conv.h"

#include <ATen/ATen.h>
#include <c10/core/InferenceMode.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>
#include <torch/utils.h>

#include <vector>

#include "tests/models/finite_difference.h"

namespace amt {
namespace {

at::Tensor edges_of(std::initializer_list<int64_t> flat) {
  return at::tensor(std::vector<int64_t>(flat), at::kLong).view({-1, 2});
}

// Triangulated grid of rows x cols vertices: interior vertices have 6 neighbours.
at::Tensor grid_edges(int64_t rows, int64_t cols) {
  std::vector<int64_t> e;
  for (int64_t r = 0; r < rows; ++r) {
    for (int64_t c = 0; c < cols; ++c) {
      const int64_t v = r * cols + c;
      if (c + 1 < cols) e.insert(e.end(), {v, v + 1});
      if (r + 1 < rows) e.insert(e.end(), {v, v + cols});
      if (r + 1 < rows && c + 1 < cols) e.insert(e.end(), {v, v + cols + 1});
    }
  }
  return at::tensor(e, at::kLong).view({-1, 2});
}

TEST(NeighborTable, SelfFirstThenNeighboursPaddedWithSelf) {
  // Two components: a triangle {0, 1, 2} and an edge {3, 4}; vertex 5 is isolated. Duplicates ignored.
  const at::Tensor table = neighbor_table(6, edges_of({0, 1, 1, 2, 2, 0, 1, 0, 3, 4, 4, 4}));
  const at::Tensor expected =
      at::tensor({0, 1, 2, 1, 0, 2, 2, 0, 1, 3, 4, 3, 4, 3, 4, 5, 5, 5}, at::kLong).view({6, 3});
  EXPECT_TRUE(at::equal(table, expected)) << table;
  EXPECT_THROW(neighbor_table(3, edges_of({0, 3})), c10::Error);
}

TEST(NeighborTable, InducedEdgesRenumberTheSelectedVertices) {
  const at::Tensor edges = edges_of({0, 1, 1, 2, 2, 3, 3, 4});
  const at::Tensor sub = induced_edges(5, edges, at::tensor({1, 2, 4, 3}, at::kLong));
  // Kept: (1,2) -> (0,1), (2,3) -> (1,3), (3,4) -> (3,2).
  EXPECT_TRUE(at::equal(sub, edges_of({0, 1, 1, 3, 3, 2}))) << sub;
}

TEST(EdgeConv, FactorizedEqualsPerEdgeEvaluation) {
  at::manual_seed(8);
  EdgeConv conv(EdgeConvOptions(12, 16));
  const at::Tensor nbr = neighbor_table(30, grid_edges(5, 6));
  for (const bool batch : {false, true}) {
    const at::Tensor h = batch ? at::randn({2, 30, 12}) : at::randn({30, 12});
    const at::Tensor fast = conv->forward_factorized(h, nbr);
    const at::Tensor naive = conv->forward_naive(h, nbr);
    ASSERT_EQ(fast.sizes(), naive.sizes());
    EXPECT_EQ(fast.size(-1), 16);
    EXPECT_LT((fast - naive).abs().max().item<float>(), 1e-5f) << "batch " << batch;
  }
}

TEST(EdgeConv, FactorizedGradientsEqualPerEdgeGradients) {
  at::manual_seed(9);
  EdgeConv conv(EdgeConvOptions(5, 7));
  conv->to(at::kDouble);
  const at::Tensor nbr = neighbor_table(12, grid_edges(3, 4));
  const at::Tensor h = at::randn({12, 5}, at::kDouble).requires_grad_();
  const at::Tensor w = at::randn({12, 7}, at::kDouble);
  const std::vector<at::Tensor> inputs = {h, conv->edge->weight, conv->edge->bias};
  const auto fast = torch::autograd::grad({(conv->forward_factorized(h, nbr) * w).sum()}, inputs);
  const auto naive = torch::autograd::grad({(conv->forward_naive(h, nbr) * w).sum()}, inputs);
  for (size_t k = 0; k < inputs.size(); ++k) {
    EXPECT_LT((fast[k] - naive[k]).abs().max().item<double>(), 1e-10) << "input " << k;
  }
  EXPECT_LT(test::max_gradient_error([&](const at::Tensor& x) { return (conv->forward_factorized(x, nbr) * w).sum(); },
                                     h),
            1e-7);
}

TEST(EdgeConv, InferenceFormMatchesAHandComputedBlock) {
  // One channel in and out, W = [w1 | w2] = [3 | 2], b = -1, slope 0.5, path graph 0 - 1 - 2:
  // out_i = sigma((w1 - w2) h_i + b + max_{j in N(i)} w2 h_j) = sigma(h_i - 1 + 2 max_j h_j).
  EdgeConvOptions options(1, 1);
  options.negative_slope = 0.5;
  EdgeConv conv(options);
  {
    torch::NoGradGuard no_grad;
    conv->edge->weight.copy_(at::tensor({3.0f, 2.0f}).view({1, 2}));
    conv->edge->bias.fill_(-1.0f);
  }
  const at::Tensor nbr = neighbor_table(3, edges_of({0, 1, 1, 2}));
  const at::Tensor h = at::tensor({1.0f, -2.0f, -4.0f}).view({3, 1});
  // Vertex 0: 1 - 1 + 2 max(1, -2) = 2. Vertex 1: -2 - 1 + 2 max(-2, 1, -4) = -1 -> -0.5.
  // Vertex 2: -4 - 1 + 2 max(-4, -2) = -9 -> -4.5.
  const at::Tensor expected = at::tensor({2.0f, -0.5f, -4.5f}).view({3, 1});
  c10::InferenceMode inference;
  EXPECT_TRUE(at::allclose(conv->forward(h, nbr), expected, 0, 1e-6)) << conv->forward(h, nbr);
}

TEST(EdgeConv, InferenceFormEqualsPerEdgeEvaluation) {
  // Without autograd (no_grad, inference mode) the factorised block is one product and gather_max_add_leaky.
  at::manual_seed(11);
  EdgeConv conv(EdgeConvOptions(12, 16));
  const at::Tensor nbr = neighbor_table(30, grid_edges(5, 6));
  for (const bool batch : {false, true}) {
    const at::Tensor h = batch ? at::randn({3, 30, 12}) : at::randn({30, 12});
    const at::Tensor naive = conv->forward_naive(h, nbr);
    const at::Tensor autograd_form = conv->forward_factorized(h, nbr);
    at::Tensor no_grad_form, inference_form;
    {
      torch::NoGradGuard no_grad;
      no_grad_form = conv->forward_factorized(h, nbr);
    }
    {
      c10::InferenceMode inference;
      inference_form = conv->forward(h, nbr);
    }
    ASSERT_EQ(inference_form.sizes(), naive.sizes());
    EXPECT_GT(naive.abs().max().item<float>(), 0.1f);
    EXPECT_LT((no_grad_form - naive).abs().max().item<float>(), 1e-5f) << "batch " << batch;
    EXPECT_LT((inference_form - naive).abs().max().item<float>(), 1e-5f) << "batch " << batch;
    EXPECT_LT((inference_form - autograd_form).abs().max().item<float>(), 1e-5f) << "batch " << batch;
  }
  // A neighbour index outside the vertices is an error there too, not a read out of bounds.
  torch::NoGradGuard no_grad;
  at::Tensor bad = nbr.clone();
  bad[4][1] = 30;
  EXPECT_THROW(conv->forward(at::randn({30, 12}), bad), c10::Error);
}

// The inference form keeps its combined weights between calls; an optimizer-like in-place change of the
// edge layer, or a new weight tensor, is seen at the next call.
TEST(EdgeConv, InferenceWeightsFollowTheEdgeLayer) {
  at::manual_seed(12);
  EdgeConv conv(EdgeConvOptions(5, 7));
  const at::Tensor nbr = neighbor_table(12, grid_edges(3, 4));
  const at::Tensor h = at::randn({12, 5});
  const auto inference = [&] {
    c10::InferenceMode mode;
    return conv->forward(h, nbr);
  };
  const at::Tensor first = inference();
  EXPECT_LT((first - conv->forward_naive(h, nbr)).abs().max().item<float>(), 1e-5f);
  {
    torch::NoGradGuard no_grad;
    conv->edge->weight.mul_(-0.5);
    conv->edge->bias.add_(0.25);
  }
  const at::Tensor second = inference();
  EXPECT_GT((second - first).abs().max().item<float>(), 0.1f);
  EXPECT_LT((second - conv->forward_naive(h, nbr)).abs().max().item<float>(), 1e-5f);
  conv->edge->weight = conv->edge->weight.detach().clone().mul_(3.0);
  EXPECT_LT((inference() - conv->forward_naive(h, nbr)).abs().max().item<float>(), 1e-4f);
}

TEST(EdgeConv, ConstantChannelsEqualTheBroadcastInput) {
  // forward_with_constant(v, c) is the block on [v, c broadcast to every vertex]: same values in every
  // form (autograd, no grad, per edge), batched or not, with one shared or one per-batch constant row.
  at::manual_seed(12);
  EdgeConv conv(EdgeConvOptions(5 + 4, 16));
  EdgeConvOptions naive_options(5 + 4, 16);
  naive_options.naive = true;
  EdgeConv naive(naive_options);
  {
    torch::NoGradGuard no_grad;
    naive->edge->weight.copy_(conv->edge->weight);
    naive->edge->bias.copy_(conv->edge->bias);
  }
  const at::Tensor nbr = neighbor_table(30, grid_edges(5, 6));
  const at::Tensor v = at::randn({2, 30, 5}), c = at::randn({2, 4});
  const at::Tensor full = at::cat({v, c.unsqueeze(1).expand({2, 30, 4})}, 2);
  const at::Tensor reference = conv->forward_naive(full, nbr);
  EXPECT_GT(reference.abs().max().item<float>(), 0.1f);
  EXPECT_LT((conv->forward_with_constant(v, c, nbr) - reference).abs().max().item<float>(), 1e-5f);
  EXPECT_LT((naive->forward_with_constant(v, c, nbr) - reference).abs().max().item<float>(), 1e-6f);
  {
    torch::NoGradGuard no_grad;
    EXPECT_LT((conv->forward_with_constant(v, c, nbr) - reference).abs().max().item<float>(), 1e-5f);
  }
  // Unbatched with a 1-D constant, and a batch sharing one constant row.
  EXPECT_LT((conv->forward_with_constant(v[1], c[1], nbr) - reference[1]).abs().max().item<float>(), 1e-5f);
  const at::Tensor shared = conv->forward_naive(at::cat({v, c[0].expand({2, 30, 4})}, 2), nbr);
  EXPECT_LT((conv->forward_with_constant(v, c[0], nbr) - shared).abs().max().item<float>(), 1e-5f);
  {
    c10::InferenceMode inference;
    EXPECT_LT((conv->forward_with_constant(v, c[0], nbr) - shared).abs().max().item<float>(), 1e-5f);
  }
  EXPECT_THROW(conv->forward_with_constant(v, at::randn({2, 3}), nbr), c10::Error);   // 5 + 3 != 9 channels
  EXPECT_THROW(conv->forward_with_constant(v, at::randn({3, 4}), nbr), c10::Error);   // 3 rows for a batch of 2
}

TEST(EdgeConv, ConstantChannelGradientsEqualPerEdgeGradients) {
  // Gradients in the per-vertex channels, the constant ones and the weights equal those of the
  // per-edge block on the broadcast input.
  at::manual_seed(13);
  EdgeConv conv(EdgeConvOptions(4 + 3, 6));
  conv->to(at::kDouble);
  const at::Tensor nbr = neighbor_table(12, grid_edges(3, 4));
  const at::Tensor v = at::randn({2, 12, 4}, at::kDouble).requires_grad_();
  const at::Tensor c = at::randn({2, 3}, at::kDouble).requires_grad_();
  const at::Tensor w = at::randn({2, 12, 6}, at::kDouble);
  const std::vector<at::Tensor> inputs = {v, c, conv->edge->weight, conv->edge->bias};
  const auto fast = torch::autograd::grad({(conv->forward_with_constant(v, c, nbr) * w).sum()}, inputs);
  const at::Tensor full = at::cat({v, c.unsqueeze(1).expand({2, 12, 3})}, 2);
  const auto naive = torch::autograd::grad({(conv->forward_naive(full, nbr) * w).sum()}, inputs);
  for (size_t k = 0; k < inputs.size(); ++k) {
    EXPECT_GT(naive[k].abs().max().item<double>(), 1e-3) << "input " << k;
    EXPECT_LT((fast[k] - naive[k]).abs().max().item<double>(), 1e-10) << "input " << k;
  }
  EXPECT_LT(test::max_gradient_error(
                [&](const at::Tensor& x) { return (conv->forward_with_constant(v.detach(), x, nbr) * w).sum(); },
                c.detach()),
            1e-7);
}

TEST(EdgeConv, ComponentsDoNotMix) {
  at::manual_seed(10);
  EdgeConv conv(EdgeConvOptions(4, 8));
  // Components {0, 1, 2} and {3, 4}: changing component 2's features leaves component 1's output.
  const at::Tensor nbr = neighbor_table(5, edges_of({0, 1, 1, 2, 3, 4}));
  at::Tensor h = at::randn({5, 4});
  const at::Tensor before = conv->forward(h, nbr);
  h.narrow(0, 3, 2).add_(10.0);
  const at::Tensor after = conv->forward(h, nbr);
  EXPECT_TRUE(at::equal(before.narrow(0, 0, 3), after.narrow(0, 0, 3)));
}

}  // namespace
}  // namespace amt
