#include "models/apparel_displacement.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <string>

#include "data_tools/geometry/geodesic.h"

#include "models/pointnet.h"

namespace amt {

ApparelDisplacementNetImpl::ApparelDisplacementNetImpl(ApparelDisplacementOptions options_)
    : options(std::move(options_)) {
  TORCH_CHECK(options.num_joints > 0 && options.motion_code > 0, "ApparelDisplacementNet: num_joints and "
              "motion_code must be positive");
  TORCH_CHECK(!options.edge_widths.empty(), "ApparelDisplacementNet: needs at least one EdgeConv block");
  std::vector<int64_t> motion = {options.num_joints * 12};
  motion.insert(motion.end(), options.motion_widths.begin(), options.motion_widths.end());
  motion.push_back(options.motion_code);
  MlpOptions motion_options(motion);
  motion_options.negative_slope = options.negative_slope;
  motion_options.activate_last = true;
  motion_encoder_ = register_module("motion_encoder", Mlp(motion_options));

  int64_t channels = 9 + (options.skinned_anchor ? 3 : 0) + options.motion_code;
  for (size_t l = 0; l < options.edge_widths.size(); ++l) {
    EdgeConvOptions block(channels, options.edge_widths[l]);
    block.negative_slope = options.negative_slope;
    block.naive = options.naive_edge_conv;
    blocks_.push_back(register_module("edge_conv" + std::to_string(l), EdgeConv(block)));
    channels = options.edge_widths[l];
  }

  std::vector<int64_t> decoder = {channels};
  decoder.insert(decoder.end(), options.decoder_widths.begin(), options.decoder_widths.end());
  decoder.push_back(3);
  MlpOptions decoder_options(decoder);
  decoder_options.negative_slope = options.negative_slope;
  decoder_options.zero_last = options.skinned_anchor && options.zero_init;
  decoder_ = register_module("decoder", Mlp(decoder_options));
}

namespace {

// The features H of eq. 12 in two parts: the per-vertex channels (B, N_a, 9 [+ 3]) and the global
// motion code f_t(T^(t)) (B, K), which H broadcasts to every vertex as its last K channels.
struct FeatureParts {
  at::Tensor per_vertex, code;
};

FeatureParts feature_parts(const ApparelDisplacementOptions& options, Mlp& motion_encoder, const at::Tensor& history,
                           const at::Tensor& joint_transforms, const at::Tensor& anchor) {
  const int64_t B = history.size(0), J = options.num_joints;
  const at::Tensor a3 = history.select(1, 0), a2 = history.select(1, 1), a1 = history.select(1, 2);  // A^(t-3..t-1)
  const at::Tensor velocity = a1 - a2;                  // discrete Ȧ^(t-1)
  const at::Tensor acceleration = a1 - 2.0 * a2 + a3;  // discrete Ä^(t-1)
  at::Tensor position = a1;
  at::Tensor motion = joint_transforms;  // (B, J, 3, 4)
  if (options.root_relative) {
    const at::Tensor root = joint_transforms.select(1, 0).select(2, 3);  // (B, 3) root position at frame t
    position = a1 - root.unsqueeze(1);
    motion = at::cat({joint_transforms.narrow(3, 0, 3),
                      (joint_transforms.select(3, 3) - root.unsqueeze(1)).unsqueeze(3)}, 3);
  }
  FeatureParts parts;
  parts.code = motion_encoder->forward(motion.reshape({B, J * 12}));  // f_t(T^(t)), (B, K)
  // eq. (12): H = A ⊕ Ȧ ⊕ Ä [⊕ S - A] ⊕ f_t(T); here the channels that differ between vertices.
  std::vector<at::Tensor> channels = {position, options.velocity_scale * velocity,
                                      options.velocity_scale * acceleration};
  if (options.skinned_anchor) channels.push_back(options.velocity_scale * (anchor - a1));
  parts.per_vertex = at::cat(channels, 2);
  return parts;
}

}  // namespace

at::Tensor ApparelDisplacementNetImpl::features(const at::Tensor& history, const at::Tensor& joint_transforms,
                                                const at::Tensor& anchor) {
  const FeatureParts parts = feature_parts(options, motion_encoder_, history, joint_transforms, anchor);
  const int64_t B = history.size(0), N = history.size(2);
  // eq. (12): the global code broadcast to every apparel vertex.
  return at::cat({parts.per_vertex, parts.code.unsqueeze(1).expand({B, N, options.motion_code})}, 2);
}

at::Tensor ApparelDisplacementNetImpl::forward(const at::Tensor& history, const at::Tensor& joint_transforms,
                                               const at::Tensor& neighbors, const at::Tensor& anchor) {
  const bool unbatched = history.dim() == 3;
  const at::Tensor h = batched(history, 3), T = batched(joint_transforms, 3);
  at::Tensor S;
  if (options.skinned_anchor) {
    TORCH_CHECK(anchor.defined(), "ApparelDisplacementNet: this network needs the skinned anchor S^(t)");
    S = batched(anchor, 2);
    TORCH_CHECK(S.dim() == 3 && S.size(0) == h.size(0) && S.size(1) == h.size(2) && S.size(2) == 3,
                "ApparelDisplacementNet: anchor must be (", h.size(2), ", 3) or (", h.size(0), ", ", h.size(2),
                ", 3), got ", anchor.sizes());
  }
  const int64_t J = options.num_joints;
  TORCH_CHECK(h.dim() == 4 && h.size(1) == 3 && h.size(3) == 3, "ApparelDisplacementNet: history must be (3, N_a, 3) "
              "or (B, 3, N_a, 3), got ", history.sizes());
  TORCH_CHECK(T.dim() == 4 && T.size(0) == h.size(0) && T.size(1) == J && T.size(2) == 3 && T.size(3) == 4,
              "ApparelDisplacementNet: joint_transforms must be (", J, ", 3, 4) or (", h.size(0), ", ", J,
              ", 3, 4), got ", joint_transforms.sizes());
  TORCH_CHECK(neighbors.dim() == 2 && neighbors.size(0) == h.size(2), "ApparelDisplacementNet: neighbors must be (",
              h.size(2), ", K_max), got ", neighbors.sizes());
  // H (eq. 12) as its per-vertex channels (B, N_a, 9 [+ 3]) and the code (B, K): the first block takes
  // the code once per frame instead of broadcasting it to every vertex (EdgeConv::forward_with_constant).
  const FeatureParts H = feature_parts(options, motion_encoder_, h, T, S);
  at::Tensor x = blocks_.front()->forward_with_constant(H.per_vertex, H.code, neighbors);  // eq. (13)
  for (size_t l = 1; l < blocks_.size(); ++l) x = blocks_[l]->forward(x, neighbors);       // eq. (13)
  at::Tensor delta = options.output_scale * decoder_->forward(x);  // (B, N_a, 3)
  if (options.skinned_anchor) delta = delta + (S - h.select(1, 2));
  return unbatched ? delta.squeeze(0) : delta;
}

at::Tensor ApparelDisplacementNetImpl::step(const at::Tensor& history, const at::Tensor& joint_transforms,
                                            const at::Tensor& neighbors, const at::Tensor& anchor) {
  return history.select(-3, 2) + forward(history, joint_transforms, neighbors, anchor);  // eq. (11)
}

at::Tensor ApparelDisplacementNetImpl::rollout(const at::Tensor& initial, const at::Tensor& joint_transforms,
                                               const at::Tensor& neighbors, const at::Tensor& anchors) {
  const bool unbatched = initial.dim() == 3;
  at::Tensor history = batched(initial, 3);        // (B, 3, N_a, 3)
  const at::Tensor T = batched(joint_transforms, 4);  // (B, T, J, 3, 4)
  TORCH_CHECK(history.dim() == 4 && history.size(1) == 3, "ApparelDisplacementNet::rollout: initial must be "
              "(3, N_a, 3) or (B, 3, N_a, 3), got ", initial.sizes());
  TORCH_CHECK(T.dim() == 5 && T.size(0) == history.size(0), "ApparelDisplacementNet::rollout: joint_transforms must "
              "be (T, J, 3, 4) or (B, T, J, 3, 4), got ", joint_transforms.sizes());
  TORCH_CHECK(T.size(1) > 0, "ApparelDisplacementNet::rollout: needs at least one frame");
  at::Tensor S;
  if (options.skinned_anchor) {
    TORCH_CHECK(anchors.defined(), "ApparelDisplacementNet::rollout: this network needs the skinned anchors");
    S = batched(anchors, 3);
    TORCH_CHECK(S.dim() == 4 && S.size(0) == T.size(0) && S.size(1) == T.size(1), "ApparelDisplacementNet::rollout: "
                "anchors must be (T, N_a, 3) or (B, T, N_a, 3) like joint_transforms, got ", anchors.sizes());
  }
  std::vector<at::Tensor> frames;
  frames.reserve(static_cast<size_t>(T.size(1)));
  for (int64_t t = 0; t < T.size(1); ++t) {
    const at::Tensor next = step(history, T.select(1, t), neighbors, S.defined() ? S.select(1, t) : S);  // (B, N_a, 3)
    frames.push_back(next);
    history = at::cat({history.narrow(1, 1, 2), next.unsqueeze(1)}, 1);
  }
  const at::Tensor out = at::stack(frames, 1);  // (B, T, N_a, 3)
  return unbatched ? out.squeeze(0) : out;
}

at::Tensor apparel_anchor_weights(const at::Tensor& V, const at::Tensor& apparel_ids, const at::Tensor& body_ids,
                                  const at::Tensor& body_weights) {
  TORCH_CHECK(V.dim() == 2 && V.size(1) == 3, "apparel_anchor_weights: V must be (N, 3), got ", V.sizes());
  TORCH_CHECK(body_weights.dim() == 2 && body_weights.size(0) == body_ids.size(0),
              "apparel_anchor_weights: body_weights must be (", body_ids.size(0), ", J), got ", body_weights.sizes());
  const int64_t N_a = apparel_ids.size(0), J = body_weights.size(1);
  if (body_ids.size(0) == 0) {
    at::Tensor W = at::zeros({N_a, J}, body_weights.options());
    if (J > 0) W.select(1, 0).fill_(1.0);
    return W;
  }
  const at::Tensor Vc = V.to(at::kFloat).contiguous();
  const MatrixX3f V_e = Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      Vc.data_ptr<float>(), Vc.size(0), 3);
  const auto ids = [](const at::Tensor& t) {
    const at::Tensor c = t.to(at::kLong).contiguous();
    return std::vector<int32_t>(c.data_ptr<int64_t>(), c.data_ptr<int64_t>() + c.numel());
  };
  const std::vector<int32_t> body = ids(body_ids);
  const std::vector<int32_t> nearest = nearest_listed_vertices(V_e, body, ids(apparel_ids));
  // nearest holds vertex indices; body_weights rows are positions in body_ids (ascending).
  std::vector<int64_t> rows(nearest.size());
  for (size_t i = 0; i < nearest.size(); ++i)
    rows[i] = std::lower_bound(body.begin(), body.end(), nearest[i]) - body.begin();
  return body_weights.index_select(0, at::tensor(rows, at::kLong));
}

}  // namespace amt
