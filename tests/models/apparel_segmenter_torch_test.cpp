// Shapes and invariances of the apparel segmenter f_c (eq. 2).
#include "models/apparel_segmenter.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

namespace amt {
namespace {

TEST(ApparelSegmenter, LogitsPerVertexBatchedAndUnbatched) {
  torch::manual_seed(1);
  ApparelSegmenter net;
  const at::Tensor V = at::rand({20, 3});
  const at::Tensor logits = net->forward(V);
  ASSERT_EQ(logits.sizes(), (at::IntArrayRef{20}));
  const at::Tensor p = net->probabilities(V);
  EXPECT_TRUE(((p > 0) & (p < 1)).all().item<bool>());
  EXPECT_TRUE(at::allclose(p, at::sigmoid(logits)));

  const at::Tensor batch = net->forward(at::stack({V, V * 2}));
  ASSERT_EQ(batch.sizes(), (at::IntArrayRef{2, 20}));
  EXPECT_TRUE(at::allclose(batch[0], logits, 1e-5, 1e-5));
}

TEST(ApparelSegmenter, InvariantToTranslationAndScaleOfTheCharacter) {
  torch::manual_seed(2);
  ApparelSegmenter net;
  const at::Tensor V = at::rand({30, 3}) * at::tensor({0.5f, 1.6f, 0.3f});
  const at::Tensor moved = V * 1.7 + at::tensor({3.0f, -1.0f, 2.0f});
  EXPECT_LT((net->forward(V) - net->forward(moved)).abs().max().item<float>(), 1e-4f);
}

TEST(ApparelSegmenter, PermutingVerticesPermutesLogits) {
  torch::manual_seed(3);
  ApparelSegmenter net;
  const at::Tensor V = at::rand({25, 3});
  const at::Tensor order = at::randperm(25, at::kLong);
  EXPECT_LT((net->forward(V).index_select(0, order) - net->forward(V.index_select(0, order))).abs().max().item<float>(),
            1e-5f);
}

TEST(ApparelSegmenter, EverySubmoduleIsRegistered) {
  ApparelSegmenterOptions options;
  options.encoder_widths = {8, 16};
  options.decoder_widths = {8};
  ApparelSegmenter net(options);
  // local 3->8, global 8->16, decoder (8+16)->8->1: 4 Linear layers, 8 tensors.
  EXPECT_EQ(net->parameters().size(), 8u);
  int64_t count = 0;
  for (const auto& p : net->parameters()) count += p.numel();
  EXPECT_EQ(count, (3 * 8 + 8) + (8 * 16 + 16) + (24 * 8 + 8) + (8 + 1));
}

TEST(ApparelSegmenter, RejectsBadShapes) {
  ApparelSegmenter net;
  EXPECT_THROW(net->forward(at::rand({20, 2})), c10::Error);
}

}  // namespace
}  // namespace amt
