// Neighbour tables of the apparel graph and the factorised EdgeConv against a per-edge evaluation
// of the same weights.
#include "models/edge_conv.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

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
