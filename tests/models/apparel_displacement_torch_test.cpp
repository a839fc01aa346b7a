// The apparel displacement network f_d (eq. 11-13): step and rollout shapes, determinism, the
// skinned anchor (features, the skip to S, nearest-body weights), the factorised EdgeConv against
// the per-edge one inside the network, the network against eq. 12-13 as written (values and
// gradients), and a benchmark (disabled; run
// with --gtest_also_run_disabled_tests --gtest_filter='*Benchmark*').
#include "models/apparel_displacement.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <c10/core/InferenceMode.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>
#include <torch/utils.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "models/gather_max.h"

namespace amt {
namespace {

// Triangulated grid of rows x cols vertices (interior vertices have 6 neighbours), vertex ids
// shuffled by `order` (N) when given so that neighbours are scattered in memory.
at::Tensor grid_edges(int64_t rows, int64_t cols, const at::Tensor& order = {}) {
  std::vector<int64_t> e;
  for (int64_t r = 0; r < rows; ++r) {
    for (int64_t c = 0; c < cols; ++c) {
      const int64_t v = r * cols + c;
      if (c + 1 < cols) e.insert(e.end(), {v, v + 1});
      if (r + 1 < rows) e.insert(e.end(), {v, v + cols});
      if (r + 1 < rows && c + 1 < cols) e.insert(e.end(), {v, v + cols + 1});
    }
  }
  const at::Tensor edges = at::tensor(e, at::kLong).view({-1, 2});
  return order.defined() ? order.index_select(0, edges.reshape({-1})).view({-1, 2}) : edges;
}

// (T, J, 3, 4) random joint transforms: rotations near identity, positions near the origin.
at::Tensor random_transforms(int64_t T, int64_t J) {
  const at::Tensor R = at::eye(3).expand({T, J, 3, 3}) + 0.1 * at::randn({T, J, 3, 3});
  return at::cat({R, at::randn({T, J, 3, 1})}, 3);
}

ApparelDisplacementOptions small_options(int64_t J) {
  ApparelDisplacementOptions o;
  o.num_joints = J;
  o.motion_widths = {32};
  o.motion_code = 8;
  o.edge_widths = {16, 16, 32};
  o.decoder_widths = {16};
  // A zero last layer would make ΔA = S - A^(t-1) whatever the other layers do; random weights
  // there make the tests see those layers.
  o.zero_init = false;
  return o;
}

TEST(ApparelDisplacementNet, StepShapesAndResidualUpdate) {
  torch::manual_seed(1);
  ApparelDisplacementNet net(small_options(5));
  const at::Tensor nbr = neighbor_table(20, grid_edges(4, 5));
  const at::Tensor history = at::randn({3, 20, 3});
  const at::Tensor T = random_transforms(1, 5)[0];
  const at::Tensor S = at::randn({20, 3});
  const at::Tensor delta = net->forward(history, T, nbr, S);
  ASSERT_EQ(delta.sizes(), (at::IntArrayRef{20, 3}));
  const at::Tensor next = net->step(history, T, nbr, S);
  ASSERT_EQ(next.sizes(), (at::IntArrayRef{20, 3}));
  EXPECT_TRUE(at::allclose(next, history[2] + delta));  // eq. (11)

  // H has 9 + 3 + K channels (eq. 12 and the anchor offset S - A^(t-1)).
  EXPECT_EQ(net->features(history.unsqueeze(0), T.unsqueeze(0), S.unsqueeze(0)).sizes(),
            (at::IntArrayRef{1, 20, 12 + 8}));

  // Batched step gives the same rows.
  const at::Tensor other = at::randn({3, 20, 3});
  const at::Tensor batch = net->step(at::stack({history, other}), at::stack({T, T}), nbr, at::stack({S, S}));
  ASSERT_EQ(batch.sizes(), (at::IntArrayRef{2, 20, 3}));
  EXPECT_LT((batch[0] - next).abs().max().item<float>(), 1e-5f);
}

TEST(ApparelDisplacementNet, RolloutShapeAndDeterminism) {
  const int64_t T = 6, N = 20, J = 5;
  const at::Tensor nbr = neighbor_table(N, grid_edges(4, 5));
  const auto run = [&] {
    torch::manual_seed(2);
    ApparelDisplacementNet net(small_options(J));
    const at::Tensor initial = at::randn({3, N, 3});
    const at::Tensor motion = random_transforms(T, J);
    const at::Tensor anchors = at::randn({T, N, 3});
    return std::make_pair(net->rollout(initial, motion, nbr, anchors), net->step(initial, motion[0], nbr, anchors[0]));
  };
  const auto [first, first_step] = run();
  const auto [second, second_step] = run();
  ASSERT_EQ(first.sizes(), (at::IntArrayRef{T, N, 3}));
  EXPECT_TRUE(at::equal(first, second));
  EXPECT_TRUE(at::allclose(first[0], first_step));
  EXPECT_TRUE(first.isfinite().all().item<bool>());
}

TEST(ApparelDisplacementNet, RolloutFeedsPredictionsBackAndIsDifferentiable) {
  torch::manual_seed(3);
  const int64_t T = 4, N = 12, J = 4;
  ApparelDisplacementNet net(small_options(J));
  const at::Tensor nbr = neighbor_table(N, grid_edges(3, 4));
  const at::Tensor initial = at::randn({3, N, 3});
  const at::Tensor motion = random_transforms(T, J);
  const at::Tensor anchors = at::randn({T, N, 3});
  const at::Tensor out = net->rollout(initial, motion, nbr, anchors);
  // Frame 2 equals a step from [initial[2], out[0], out[1]].
  const at::Tensor history = at::stack({initial[2], out[0], out[1]});
  EXPECT_LT((out[2] - net->step(history, motion[2], nbr, anchors[2])).abs().max().item<float>(), 1e-5f);
  // Batched rollout (B, T, N_a, 3).
  const at::Tensor batch =
      net->rollout(initial.unsqueeze(0).expand({2, 3, N, 3}), motion.unsqueeze(0).expand({2, T, J, 3, 4}), nbr,
                   anchors.unsqueeze(0).expand({2, T, N, 3}));
  ASSERT_EQ(batch.sizes(), (at::IntArrayRef{2, T, N, 3}));
  EXPECT_LT((batch[1] - out).abs().max().item<float>(), 1e-5f);
  // Gradients reach every parameter through time.
  out.abs().sum().backward();
  for (const auto& p : net->named_parameters()) {
    ASSERT_TRUE(p.value().grad().defined()) << p.key();
    EXPECT_GT(p.value().grad().abs().sum().item<float>(), 0.0f) << p.key();
  }
}

TEST(ApparelDisplacementNet, FactorizedAndPerEdgeNetworksAgree) {
  torch::manual_seed(4);
  ApparelDisplacementOptions options = small_options(5);
  ApparelDisplacementNet fast(options);
  options.naive_edge_conv = true;
  ApparelDisplacementNet naive(options);
  {
    torch::NoGradGuard no_grad;
    const auto src = fast->named_parameters();
    for (auto& p : naive->named_parameters()) p.value().copy_(src[p.key()]);
  }
  const at::Tensor nbr = neighbor_table(20, grid_edges(4, 5));
  const at::Tensor history = at::randn({3, 20, 3});
  const at::Tensor T = random_transforms(1, 5)[0];
  const at::Tensor S = at::randn({20, 3});
  EXPECT_LT((fast->forward(history, T, nbr, S) - naive->forward(history, T, nbr, S)).abs().max().item<float>(), 1e-5f);
}

// H of eq. 12 from its definition, from the network's parameters and PyTorch ops (not features()): per vertex
// A^(t-1) relative to the root joint, velocity_scale * (Ȧ, Ä, S - A^(t-1)) by finite differences of the history,
// then the motion code f_t(T^(t)), the motion encoder (every layer activated) on the root-relative transforms
// flattened row-major, broadcast to every vertex. (1, N, 12 + K).
at::Tensor features_as_written(ApparelDisplacementNet& net, const at::Tensor& history, const at::Tensor& T,
                               const at::Tensor& S) {
  const auto params = net->named_parameters();
  const ApparelDisplacementOptions& o = net->options;
  EXPECT_TRUE(o.root_relative);
  const at::Tensor root = T[0].select(1, 3);  // (3) the root joint's position
  const at::Tensor a3 = history[0], a2 = history[1], a1 = history[2];
  const int64_t N = a1.size(0);
  at::Tensor motion = T.clone();
  motion.select(2, 3).sub_(root);
  at::Tensor code = motion.reshape({1, -1});
  for (size_t l = 0; l < o.motion_widths.size() + 1; ++l) {
    const std::string linear = "motion_encoder.linear" + std::to_string(l) + ".";
    code = at::leaky_relu(at::linear(code, params[linear + "weight"], params[linear + "bias"]), o.negative_slope);
  }
  EXPECT_EQ(code.size(1), o.motion_code);
  const double v = o.velocity_scale;
  return at::cat({a1 - root, v * (a1 - a2), v * ((a1 - a2) - (a2 - a3)), v * (S - a1), code.expand({N, o.motion_code})},
                 1)
      .unsqueeze(0);
}

// ΔA (N_a, 3) by eq. 11-13 as written, from the network's parameters and PyTorch ops: H by
// features_as_written, each EdgeConv block evaluated per edge on [h_i, h_j - h_i], the decoder,
// ΔA = output_scale * decoder + S - A^(t-1).
at::Tensor delta_as_written(ApparelDisplacementNet& net, const at::Tensor& history, const at::Tensor& T,
                            const at::Tensor& nbr, const at::Tensor& S) {
  const auto params = net->named_parameters();
  const ApparelDisplacementOptions& o = net->options;
  at::Tensor x = features_as_written(net, history, T, S);  // (1, N, 12 + K)
  const at::Tensor network_features = net->features(history.unsqueeze(0), T.unsqueeze(0), S.unsqueeze(0));
  EXPECT_LT((x - network_features).abs().max().item<double>(), 1e-5 * (1.0 + x.abs().max().item<double>()));
  const int64_t N = x.size(1), K = nbr.size(1);
  for (size_t l = 0; l < o.edge_widths.size(); ++l) {
    const std::string edge = "edge_conv" + std::to_string(l) + ".edge.";
    const int64_t C = x.size(2);
    const at::Tensor hj = x.index_select(1, nbr.reshape({-1})).view({1, N, K, C});
    const at::Tensor hi = x.unsqueeze(2).expand({1, N, K, C});
    const at::Tensor e = at::linear(at::cat({hi, hj - hi}, -1), params[edge + "weight"], params[edge + "bias"]);
    x = at::leaky_relu(e, o.negative_slope).amax(2);  // eq. (13)
  }
  for (size_t l = 0; l <= o.decoder_widths.size(); ++l) {
    const std::string linear = "decoder.linear" + std::to_string(l) + ".";
    x = at::linear(x, params[linear + "weight"], params[linear + "bias"]);
    if (l < o.decoder_widths.size()) x = at::leaky_relu(x, o.negative_slope);
  }
  return o.output_scale * x.squeeze(0) + (S - history[2]);
}

TEST(ApparelDisplacementNet, EqualsEquations12And13AsWrittenWithGradients) {
  // The network takes the motion code once per frame in its first block (the code's channels cancel in
  // h_j - h_i) and evaluates the blocks factorised; values and gradients must be those of the blocks
  // written per edge on H with the code broadcast to every vertex.
  torch::manual_seed(8);
  ApparelDisplacementNet net(small_options(5));  // zero_init = false: a non-zero decoder
  net->to(at::kDouble);
  const at::Tensor nbr = neighbor_table(20, grid_edges(4, 5));
  const at::Tensor history = at::randn({3, 20, 3}, at::kDouble).requires_grad_();
  const at::Tensor S = at::randn({20, 3}, at::kDouble).requires_grad_();
  const at::Tensor T = random_transforms(1, 5)[0].to(at::kDouble);
  const at::Tensor w = at::randn({20, 3}, at::kDouble);
  const at::Tensor fast = net->forward(history, T, nbr, S);
  const at::Tensor written = delta_as_written(net, history, T, nbr, S);
  // The decoder's part of ΔA is not negligible, so the comparison sees the blocks.
  EXPECT_GT((written - (S - history[2])).abs().max().item<double>(), 1e-3);
  EXPECT_LT((fast - written).abs().max().item<double>(), 1e-12);

  std::vector<at::Tensor> inputs = {history, S};
  std::vector<std::string> names = {"history", "anchor"};
  for (const auto& p : net->named_parameters()) {
    inputs.push_back(p.value());
    names.push_back(p.key());
  }
  const auto fast_grad = torch::autograd::grad({(fast * w).sum()}, inputs);
  const auto written_grad = torch::autograd::grad({(written * w).sum()}, inputs);
  for (size_t k = 0; k < inputs.size(); ++k) {
    const double scale = written_grad[k].abs().max().item<double>();
    EXPECT_GT(scale, 0.0) << names[k];
    EXPECT_LT((fast_grad[k] - written_grad[k]).abs().max().item<double>(), 1e-10 * (1.0 + scale)) << names[k];
  }

  // Inference in float: the stacked-product form against the same formula.
  net->to(at::kFloat);
  const at::Tensor h = history.detach().to(at::kFloat), S_f = S.detach().to(at::kFloat), T_f = T.to(at::kFloat);
  at::Tensor reference;
  {
    torch::NoGradGuard no_grad;
    reference = delta_as_written(net, h, T_f, nbr, S_f);
  }
  c10::InferenceMode inference;
  EXPECT_LT((net->forward(h, T_f, nbr, S_f) - reference).abs().max().item<float>(), 1e-5f);
  // Batched: each row equals its own frame.
  const at::Tensor batch = net->forward(at::stack({h, 2.0f * h}), at::stack({T_f, T_f}), nbr, at::stack({S_f, S_f}));
  EXPECT_LT((batch[0] - reference).abs().max().item<float>(), 1e-5f);
}

TEST(ApparelDisplacementNet, RootRelativeFeaturesIgnoreWhereTheCharacterIs) {
  torch::manual_seed(5);
  ApparelDisplacementNet net(small_options(4));
  const at::Tensor nbr = neighbor_table(12, grid_edges(3, 4));
  const at::Tensor history = at::randn({3, 12, 3});
  const at::Tensor T = random_transforms(1, 4)[0];
  const at::Tensor shift = at::tensor({2.0f, 0.0f, -3.0f});
  at::Tensor T_moved = T.clone();
  T_moved.select(2, 3).add_(shift);
  const at::Tensor S = at::randn({12, 3});
  const at::Tensor a = net->forward(history, T, nbr, S), b = net->forward(history + shift, T_moved, nbr, S + shift);
  EXPECT_LT((a - b).abs().max().item<float>(), 1e-5f);
}

TEST(ApparelDisplacementNet, ZeroDecoderFollowsTheSkinnedAnchor) {
  // With the decoder's last layer zeroed, ΔA = S - A^(t-1): the apparel moves exactly with the body.
  torch::manual_seed(7);
  ApparelDisplacementOptions options = small_options(4);
  options.zero_init = true;
  ApparelDisplacementNet net(options);
  {
    // A fresh network starts that way (zero-initialised last layer); check that, then the skip alone.
    torch::NoGradGuard no_grad;
    for (auto& p : net->named_parameters()) {
      if (p.key().rfind("decoder.", 0) == 0 && p.value().size(0) == 3) {
        EXPECT_EQ(p.value().abs().max().item<float>(), 0.0f) << p.key();
      }
    }
  }
  const at::Tensor nbr = neighbor_table(12, grid_edges(3, 4));
  const at::Tensor history = at::randn({3, 12, 3}), S = at::randn({12, 3});
  EXPECT_LT((net->step(history, random_transforms(1, 4)[0], nbr, S) - S).abs().max().item<float>(), 1e-6f);
}

TEST(ApparelDisplacementNet, WithoutAnchorFeaturesAreEquation12) {
  ApparelDisplacementOptions options = small_options(4);
  options.skinned_anchor = false;
  ApparelDisplacementNet net(options);
  const at::Tensor history = at::randn({1, 3, 12, 3});
  EXPECT_EQ(net->features(history, random_transforms(1, 4)).sizes(), (at::IntArrayRef{1, 12, 9 + 8}));
  const at::Tensor nbr = neighbor_table(12, grid_edges(3, 4));
  EXPECT_EQ(net->step(history[0], random_transforms(1, 4)[0], nbr).sizes(), (at::IntArrayRef{12, 3}));
}

TEST(ApparelDisplacementNet, AnchorWeightsComeFromTheNearestBodyVertex) {
  // Body vertices 0, 2, 3 at x = 0, 1, 2; apparel vertices 1 (x = 1.9) and 4 (x = 0.4).
  at::Tensor V = at::zeros({5, 3});
  V.select(1, 0).copy_(at::tensor({0.0f, 1.9f, 1.0f, 2.0f, 0.4f}));
  const at::Tensor body_ids = at::tensor({0, 2, 3}, at::kLong), apparel_ids = at::tensor({1, 4}, at::kLong);
  const at::Tensor W_b = at::tensor({1.0f, 0.0f, 0.25f, 0.75f, 0.0f, 1.0f}).view({3, 2});
  const at::Tensor W_a = apparel_anchor_weights(V, apparel_ids, body_ids, W_b);
  ASSERT_EQ(W_a.sizes(), (at::IntArrayRef{2, 2}));
  EXPECT_TRUE(at::equal(W_a[0], W_b[2]));  // 1.9 is nearest to 2.0 (vertex 3)
  EXPECT_TRUE(at::equal(W_a[1], W_b[0]));  // 0.4 is nearest to 0.0 (vertex 0)
  // Without body vertices the apparel follows the root.
  const at::Tensor root = apparel_anchor_weights(V, apparel_ids, at::zeros({0}, at::kLong), at::zeros({0, 2}));
  EXPECT_TRUE(at::equal(root, at::tensor({1.0f, 0.0f, 1.0f, 0.0f}).view({2, 2})));
}

TEST(ApparelDisplacementNet, RejectsBadShapes) {
  ApparelDisplacementNet net(small_options(5));
  const at::Tensor nbr = neighbor_table(20, grid_edges(4, 5));
  const at::Tensor S = at::randn({20, 3});
  EXPECT_THROW(net->forward(at::randn({2, 20, 3}), random_transforms(1, 5)[0], nbr, S), c10::Error);
  EXPECT_THROW(net->forward(at::randn({3, 20, 3}), random_transforms(1, 4)[0], nbr, S), c10::Error);
  EXPECT_THROW(net->forward(at::randn({3, 19, 3}), random_transforms(1, 5)[0], nbr, S), c10::Error);
  EXPECT_THROW(net->forward(at::randn({3, 20, 3}), random_transforms(1, 5)[0], nbr), c10::Error);  // no anchor
  EXPECT_THROW(net->forward(at::randn({3, 20, 3}), random_transforms(1, 5)[0], nbr, at::randn({19, 3})), c10::Error);
}

// Median wall time of `fn` in milliseconds.
template <typename Fn>
double median_ms(Fn&& fn, int repeats) {
  std::vector<double> ms;
  fn();  // warm-up
  for (int r = 0; r < repeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    fn();
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

// Not a test: forward time of one apparel step for 6000 vertices (interior valence 6, self included
// K = 7) and widths 64/64/128 on one thread, factorised vs per-edge, and the neighbour max alone.
TEST(ApparelDisplacementNet, DISABLED_BenchmarkStep) {
  at::set_num_threads(1);
  torch::manual_seed(6);
  const int64_t rows = 60, cols = 100, N = rows * cols, J = 22;
  const at::Tensor nbr = neighbor_table(N, grid_edges(rows, cols, at::randperm(N, at::kLong)));
  ApparelDisplacementOptions options;
  ApparelDisplacementNet fast(options);
  options.naive_edge_conv = true;
  ApparelDisplacementNet naive(options);
  const at::Tensor history = at::randn({3, N, 3});
  const at::Tensor T = random_transforms(1, J)[0];
  const at::Tensor S = at::randn({N, 3});
  double fast_ms = 0, naive_ms = 0, loop_ms = 0, eager_ms = 0;
  const at::Tensor values = at::randn({N, 128});
  {
    c10::InferenceMode guard;
    fast_ms = median_ms([&] { fast->step(history, T, nbr, S); }, 20);
    naive_ms = median_ms([&] { naive->step(history, T, nbr, S); }, 5);
    loop_ms = median_ms([&] { gather_max(values, nbr); }, 50);
    eager_ms = median_ms([&] { gather_max_reference(values, nbr); }, 50);
  }
  // Training cost: forward + backward of one step.
  const double fast_train_ms = median_ms([&] { fast->step(history, T, nbr, S).sum().backward(); }, 10);
  const double naive_train_ms = median_ms([&] { naive->step(history, T, nbr, S).sum().backward(); }, 3);
  std::printf("apparel step, N_a = %lld, K_max = %lld, widths 64/64/128, 1 thread:\n", static_cast<long long>(N),
              static_cast<long long>(nbr.size(1)));
  std::printf("  forward    factorised + C++ gather-max: %8.2f ms   per-edge (eager): %8.2f ms\n", fast_ms, naive_ms);
  std::printf("  fwd + bwd  factorised + C++ gather-max: %8.2f ms   per-edge (eager): %8.2f ms\n", fast_train_ms,
              naive_train_ms);
  std::printf("  neighbour max (%lld, %lld, 128): C++ loop %.2f ms, eager index_select + amax %.2f ms\n",
              static_cast<long long>(N), static_cast<long long>(nbr.size(1)), loop_ms, eager_ms);
}

}  // namespace
}  // namespace amt
