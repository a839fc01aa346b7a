// Shapes and invariances of the apparel segmenter f_c (eq. 2), on positions and shape features.
#include "models/apparel_segmenter.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

namespace amt {
namespace {

TEST(ApparelSegmenter, LogitsPerVertexBatchedAndUnbatched) {
  torch::manual_seed(1);
  ApparelSegmenter net;
  const at::Tensor V = at::rand({20, 3}), X = at::rand({20, 6});
  const at::Tensor logits = net->forward(V, X);
  ASSERT_EQ(logits.sizes(), (at::IntArrayRef{20}));
  const at::Tensor p = net->probabilities(V, X);
  EXPECT_TRUE(((p > 0) & (p < 1)).all().item<bool>());
  EXPECT_TRUE(at::allclose(p, at::sigmoid(logits)));

  const at::Tensor batch = net->forward(at::stack({V, V * 2}), at::stack({X, X}));
  ASSERT_EQ(batch.sizes(), (at::IntArrayRef{2, 20}));
  EXPECT_TRUE(at::allclose(batch[0], logits, 1e-5, 1e-5));
  EXPECT_TRUE(at::allclose(batch[1], logits, 1e-5, 1e-5));  // the positions are normalised, the features are not
}

TEST(ApparelSegmenter, InvariantToTranslationAndScaleOfTheCharacter) {
  torch::manual_seed(2);
  ApparelSegmenter net;
  const at::Tensor V = at::rand({30, 3}) * at::tensor({0.5f, 1.6f, 0.3f}), X = at::rand({30, 6});
  const at::Tensor moved = V * 1.7 + at::tensor({3.0f, -1.0f, 2.0f});
  EXPECT_LT((net->forward(V, X) - net->forward(moved, X)).abs().max().item<float>(), 1e-4f);
}

TEST(ApparelSegmenter, ReadsEveryFeatureChannel) {
  torch::manual_seed(4);
  ApparelSegmenter net;
  const at::Tensor V = at::rand({15, 3}), X = at::rand({15, 6});
  const at::Tensor base = net->forward(V, X);
  for (int64_t c = 0; c < 6; ++c) {
    at::Tensor changed = X.clone();
    changed.select(1, c).add_(1.0);
    EXPECT_GT((net->forward(V, changed) - base).abs().max().item<float>(), 1e-4f) << "channel " << c;
  }
}

TEST(ApparelSegmenter, PermutingVerticesPermutesLogits) {
  torch::manual_seed(3);
  ApparelSegmenter net;
  const at::Tensor V = at::rand({25, 3}), X = at::rand({25, 6});
  const at::Tensor order = at::randperm(25, at::kLong);
  EXPECT_LT((net->forward(V, X).index_select(0, order) - net->forward(V.index_select(0, order), X.index_select(0, order)))
                .abs()
                .max()
                .item<float>(),
            1e-5f);
}

TEST(ApparelSegmenter, EverySubmoduleIsRegistered) {
  ApparelSegmenterOptions options;
  options.encoder_widths = {8, 16};
  options.decoder_widths = {8};
  ApparelSegmenter net(options);
  // local (3+6)->8, global 8->16, decoder (8+16)->8->1: 4 Linear layers, 8 tensors.
  EXPECT_EQ(net->parameters().size(), 8u);
  int64_t count = 0;
  for (const auto& p : net->parameters()) count += p.numel();
  EXPECT_EQ(count, (9 * 8 + 8) + (8 * 16 + 16) + (24 * 8 + 8) + (8 + 1));
  // The paper's input: positions alone, local 3->8.
  options.inputs = "positions";
  ApparelSegmenter positions(options);
  count = 0;
  for (const auto& p : positions->parameters()) count += p.numel();
  EXPECT_EQ(count, (3 * 8 + 8) + (8 * 16 + 16) + (24 * 8 + 8) + (8 + 1));
  EXPECT_EQ(positions->forward(at::rand({20, 3})).sizes(), (at::IntArrayRef{20}));
}

TEST(ApparelSegmenter, RejectsBadShapes) {
  ApparelSegmenter net;
  EXPECT_THROW(net->forward(at::rand({20, 2}), at::rand({20, 6})), c10::Error);
  EXPECT_THROW(net->forward(at::rand({20, 3})), c10::Error);                     // features missing
  EXPECT_THROW(net->forward(at::rand({20, 3}), at::rand({20, 5})), c10::Error);  // a channel short
  EXPECT_THROW(net->forward(at::rand({20, 3}), at::rand({19, 6})), c10::Error);  // a vertex short
  ApparelSegmenterOptions options;
  options.inputs = "colours";
  EXPECT_THROW(ApparelSegmenter{options}, c10::Error);
}

}  // namespace
}  // namespace amt
