// The C++ neighbour max and its custom backward against PyTorch's gather + amax and against finite
// differences.
#include "models/gather_max.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include "tests/models/finite_difference.h"

namespace amt {
namespace {

const auto kDouble = at::TensorOptions().dtype(at::kDouble);

// (N, K) random neighbour rows into [0, S), each row starting with its own index (like neighbor_table).
at::Tensor random_neighbors(int64_t N, int64_t K, int64_t S) {
  at::Tensor n = at::randint(S, {N, K}, at::kLong);
  n.select(1, 0).copy_(at::arange(N, at::kLong) % S);
  return n;
}

TEST(GatherMax, ValuesMatchReference) {
  at::manual_seed(3);
  const at::Tensor values = at::randn({50, 16});
  const at::Tensor nbr = random_neighbors(40, 7, 50);
  EXPECT_TRUE(at::equal(gather_max(values, nbr), gather_max_reference(values, nbr)));
  const at::Tensor batch = at::randn({3, 50, 16});
  const at::Tensor out = gather_max(batch, nbr);
  ASSERT_EQ(out.sizes(), (at::IntArrayRef{3, 40, 16}));
  EXPECT_TRUE(at::equal(out, gather_max_reference(batch, nbr)));
}

TEST(GatherMax, GradientsMatchReferenceAutograd) {
  at::manual_seed(4);
  for (const bool batch : {false, true}) {
    const at::Tensor values = batch ? at::randn({2, 30, 8}, kDouble) : at::randn({30, 8}, kDouble);
    const at::Tensor nbr = random_neighbors(25, 5, 30);
    const at::Tensor weights = at::randn(batch ? at::IntArrayRef{2, 25, 8} : at::IntArrayRef{25, 8}, kDouble);
    const auto fast = [&](const at::Tensor& x) { return (gather_max(x, nbr) * weights).sum(); };
    const auto reference = [&](const at::Tensor& x) { return (gather_max_reference(x, nbr) * weights).sum(); };
    const at::Tensor difference = test::analytic_gradient(fast, values) - test::analytic_gradient(reference, values);
    EXPECT_LT(difference.abs().max().item<double>(), 1e-12)
        << "batch " << batch;
  }
}

TEST(GatherMax, GradientsMatchFiniteDifferencesWhereTheMaxIsUnique) {
  at::manual_seed(5);
  // Distinct values in every channel (a permutation), so every max is unique with a wide margin.
  const at::Tensor values = at::randperm(20 * 6, kDouble).view({20, 6}) * 0.1;
  const at::Tensor nbr = random_neighbors(15, 4, 20);
  const at::Tensor weights = at::randn({15, 6}, kDouble);
  EXPECT_LT(test::max_gradient_error([&](const at::Tensor& x) { return (gather_max(x, nbr) * weights).sum(); }, values),
            1e-6);
}

TEST(GatherMax, PaddingByRepeatingAnEntryIsExact) {
  at::manual_seed(6);
  const at::Tensor values = at::randn({6, 4}, kDouble).requires_grad_();
  const at::Tensor short_rows = at::tensor({0, 1, 1, 2}, at::kLong).view({2, 2});
  const at::Tensor padded = at::tensor({0, 1, 0, 0, 1, 2, 1, 1}, at::kLong).view({2, 4});
  const at::Tensor a = gather_max(values, short_rows), b = gather_max(values, padded);
  EXPECT_TRUE(at::equal(a, b));
  const at::Tensor ga = torch::autograd::grad({a.sum()}, {values})[0];
  const at::Tensor gb = torch::autograd::grad({b.sum()}, {values})[0];
  EXPECT_TRUE(at::equal(ga, gb));
  // Each output gradient lands on exactly one source row per channel.
  EXPECT_NEAR(ga.sum().item<double>(), 2 * 4, 1e-12);
}

TEST(GatherMax, WorksWithoutAutograd) {
  const at::Tensor values = at::randn({10, 3});
  const at::Tensor nbr = random_neighbors(10, 3, 10);
  at::Tensor out;
  {
    c10::InferenceMode guard;
    out = gather_max(values, nbr);
  }
  EXPECT_TRUE(at::equal(out, gather_max_reference(values, nbr)));
}

// The fused inference form of a factorised EdgeConv block: exactly LeakyReLU(a_i + max_k b_{n(i, k)}) as
// separate ops compute it, batched, with padded rows and a channel count that is not a multiple of four.
TEST(GatherMax, AddLeakyEqualsTheSeparateOpsExactly) {
  at::manual_seed(8);
  at::Tensor nbr = random_neighbors(40, 6, 40);
  nbr.narrow(1, 4, 2).copy_(nbr.select(1, 0).unsqueeze(1).expand({40, 2}));  // padding repeats the first entry
  for (const int64_t C : {13, 48}) {
    const at::Tensor products = at::randn({2, 40, 2 * C});
    const at::Tensor a = products.narrow(2, 0, C), b = products.narrow(2, C, C).contiguous();
    const at::Tensor expected = at::leaky_relu(a + gather_max_reference(b, nbr), 0.2);
    const at::Tensor fused = gather_max_add_leaky(products, nbr, 0.2);
    ASSERT_EQ(fused.sizes(), expected.sizes());
    EXPECT_TRUE(at::equal(fused, expected)) << "C " << C << ": max difference " << (fused - expected).abs().max();
    EXPECT_GT((fused < 0).sum().item<int64_t>(), 0);  // both sides of the LeakyReLU are exercised
  }
  // Out-of-range indices, odd widths and mismatched tables are errors, not reads out of bounds.
  at::Tensor bad = nbr.clone();
  bad[7][2] = 40;
  EXPECT_THROW(gather_max_add_leaky(at::randn({1, 40, 8}), bad, 0.2), c10::Error);
  EXPECT_THROW(gather_max_add_leaky(at::randn({1, 40, 7}), nbr, 0.2), c10::Error);
  EXPECT_THROW(gather_max_add_leaky(at::randn({1, 39, 8}), nbr, 0.2), c10::Error);
}

TEST(GatherMax, RejectsBadNeighbors) {
  const at::Tensor values = at::randn({5, 3});
  EXPECT_THROW(gather_max(values, at::tensor({0, 5}, at::kLong).view({1, 2})), c10::Error);
  EXPECT_THROW(gather_max(values, at::tensor({0, 1}, at::kInt).view({1, 2})), c10::Error);
  EXPECT_THROW(gather_max(values, at::zeros({3, 0}, at::kLong)), c10::Error);
}

}  // namespace
}  // namespace amt
