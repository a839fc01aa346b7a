#include "models/skinning_predictor.h"

#include <ATen/ATen.h>

#include <algorithm>

namespace amt {

namespace {

// Input width of the pair-feature MLP for each variant.
int64_t feature_input_width(const SkinningPredictorOptions& o) {
  switch (o.variant) {
    case SkinningVariant::kGeodesicAttention:
      return 11;  // v_i, J_j, v_i - J_j, |v_i - J_j|, G_ij
    case SkinningVariant::kNoGeodesic:
      return 10;  // without G_ij
    case SkinningVariant::kSortByGeodesic:
      return 3 + std::min(o.sort_k, o.num_joints) * (7 + o.num_joints);  // v_i, k x (J_j, v_i - J_j, G_ij, one-hot)
  }
  return 0;
}

}  // namespace

SkinningPredictorImpl::SkinningPredictorImpl(SkinningPredictorOptions options_) : options(std::move(options_)) {
  TORCH_CHECK(options.num_joints > 0, "SkinningPredictor: num_joints must be positive");
  TORCH_CHECK(!options.feature_widths.empty(), "SkinningPredictor: feature_widths must not be empty");
  TORCH_CHECK(options.sort_k > 0, "SkinningPredictor: sort_k must be positive");
  std::vector<int64_t> widths = {feature_input_width(options)};
  widths.insert(widths.end(), options.feature_widths.begin(), options.feature_widths.end());
  MlpOptions features(widths);
  features.activate_last = true;
  features.negative_slope = options.negative_slope;
  pair_features_ = register_module("pair_features", Mlp(features));

  if (options.variant == SkinningVariant::kGeodesicAttention) {
    std::vector<int64_t> att = {options.attention_row_context ? 2 : 1};
    att.insert(att.end(), options.attention_widths.begin(), options.attention_widths.end());
    att.push_back(1);
    MlpOptions attention(att);
    attention.negative_slope = options.negative_slope;
    attention_ = register_module("attention", Mlp(attention));
  }

  PointNetOptions head;
  head.in_channels = options.feature_widths.back();
  head.encoder_widths = options.head_encoder_widths;
  head.decoder_widths = options.head_decoder_widths;
  head.out_channels = options.num_joints;
  head.negative_slope = options.negative_slope;
  head_ = register_module("head", PointNet(head));
}

std::pair<at::Tensor, at::Tensor> SkinningPredictorImpl::fused_features(const at::Tensor& V, const at::Tensor& joints,
                                                                        const at::Tensor& G) {
  const int64_t B = V.size(0), N = V.size(1), J = joints.size(1);
  const at::Tensor v = V.unsqueeze(2).expand({B, N, J, 3});       // (B, N, J, 3)
  const at::Tensor j = joints.unsqueeze(1).expand({B, N, J, 3});  // (B, N, J, 3)
  const at::Tensor offset = v - j;                                 // v_i - J_j
  const at::Tensor distance = offset.norm(2, -1, /*keepdim=*/true);

  switch (options.variant) {
    case SkinningVariant::kGeodesicAttention: {
      // P (B, N, J, D)
      const at::Tensor P = pair_features_->forward(at::cat({v, j, offset, distance, G.unsqueeze(-1)}, -1));
      at::Tensor att_in = G.unsqueeze(-1);
      if (options.attention_row_context) {
        const at::Tensor nearest = std::get<0>(G.min(-1, /*keepdim=*/true));  // (B, N, 1)
        att_in = at::cat({att_in, (G - nearest).unsqueeze(-1)}, -1);          // (B, N, J, 2)
      }
      const at::Tensor M = at::softmax(attention_->forward(att_in).squeeze(-1), -1);  // eq. (5), (B, N, J)
      const at::Tensor fused = at::matmul(M.unsqueeze(2), P).squeeze(2);             // eq. (6), (B, N, D)
      return {fused, M};
    }
    case SkinningVariant::kNoGeodesic: {
      const at::Tensor P = pair_features_->forward(at::cat({v, j, offset, distance}, -1));  // (B, N, J, D)
      const at::Tensor M = at::full({B, N, J}, 1.0 / static_cast<double>(J), P.options());
      return {P.mean(2), M};
    }
    case SkinningVariant::kSortByGeodesic: {
      const int64_t k = std::min(options.sort_k, J);
      const at::Tensor order = std::get<1>(G.topk(k, -1, /*largest=*/false, /*sorted=*/true));  // (B, N, k)
      const at::Tensor order3 = order.unsqueeze(-1).expand({B, N, k, 3});
      const at::Tensor slot = at::cat({j.gather(2, order3), offset.gather(2, order3), G.gather(2, order).unsqueeze(-1),
                                       at::one_hot(order, J).to(V.scalar_type())},
                                      -1);  // (B, N, k, 7 + J)
      const at::Tensor per_vertex = at::cat({V, slot.reshape({B, N, k * (7 + J)})}, -1);
      return {pair_features_->forward(per_vertex), at::Tensor()};
    }
  }
  return {};
}

SkinningOutput SkinningPredictorImpl::forward_detailed(const at::Tensor& V, const at::Tensor& joints,
                                                       const at::Tensor& G) {
  TORCH_CHECK((V.dim() == 2 || V.dim() == 3) && V.size(-1) == 3,
              "SkinningPredictor: V must be (N_b, 3) or (B, N_b, 3), got ", V.sizes());
  const bool unbatched = V.dim() == 2;
  at::Tensor v = batched(V, 2), j = batched(joints, 2);
  const int64_t B = v.size(0), N = v.size(1), J = options.num_joints;
  TORCH_CHECK(j.dim() == 3 && j.size(0) == B && j.size(1) == J && j.size(2) == 3, "SkinningPredictor: joints must be (",
              J, ", 3) or (", B, ", ", J, ", 3), got ", joints.sizes());
  at::Tensor g;
  if (options.variant != SkinningVariant::kNoGeodesic) {
    TORCH_CHECK(G.defined(), "SkinningPredictor: this variant needs the geodesic distances G");
    g = batched(G, 2);
    TORCH_CHECK(g.dim() == 3 && g.size(0) == B && g.size(1) == N && g.size(2) == J, "SkinningPredictor: G must be (",
                N, ", ", J, ") or (", B, ", ", N, ", ", J, "), got ", G.sizes());
  }
  if (options.normalize_input) {
    const CharacterFrame frame = character_frame(v);
    v = frame.apply(v);
    j = frame.apply(j);
    if (g.defined()) g = g / frame.scale;
  }
  const auto [fused, M] = fused_features(v, j, g);
  SkinningOutput out;
  out.logits = head_->forward(fused);       // (B, N, J)
  out.W = at::softmax(out.logits, -1);      // eq. (7)
  out.M = M;
  if (unbatched) {
    out.W = out.W.squeeze(0);
    out.logits = out.logits.squeeze(0);
    if (out.M.defined()) out.M = out.M.squeeze(0);
  }
  return out;
}

at::Tensor SkinningPredictorImpl::forward(const at::Tensor& V, const at::Tensor& joints, const at::Tensor& G) {
  return forward_detailed(V, joints, G).W;
}

}  // namespace amt
