#pragma once
// The skinning weight predictor f_s of the body deformation module (paper section 4.2): per
// vertex-joint features P (eq. 5-6 inputs), the geodesic attention M = softmax_j(f_m(G)) (eq. 5),
// the fused feature P' = sum_j M_ij P_ij (eq. 6) and a PointNet head W = softmax(f_s(P')) (eq. 7).
// The two ablations of Table 4 are variants of the same module.
#include <torch/nn/module.h>
#include <torch/nn/pimpl.h>

#include <cstdint>
#include <utility>
#include <vector>

#include "models/mlp.h"
#include "models/pointnet.h"

namespace amt {

/// How per-joint information is aggregated per vertex (paper Table 4).
enum class SkinningVariant {
  /// G + Attention (the paper's method): pair features include G_ij; M = softmax_j(f_m(G)), eq. 5-6.
  kGeodesicAttention,
  /// w/o G: G is used nowhere; pair features without G_ij are averaged uniformly over joints.
  kNoGeodesic,
  /// Sort by G (RigNet [34] style): per vertex, the k joints of smallest G_ij are sorted by G and
  /// their features (position, offset, G_ij, one-hot joint index) concatenated into one vector.
  kSortByGeodesic,
};

/// Configuration of the SkinningPredictor.
struct SkinningPredictorOptions {
  /// Number of joints J of the skeleton (the canonical body skeleton has 22); fixes the output width.
  int64_t num_joints = 22;
  /// Widths of the pair-feature MLP after its input layer; the last one is D, the width of P and P'.
  std::vector<int64_t> feature_widths = {64, 64};
  /// Hidden widths of f_m, the per-entry attention MLP on geodesic distances (eq. 5).
  std::vector<int64_t> attention_widths = {16, 16};
  /// Give f_m the row context G_ij - min_k G_ik besides G_ij (the distance relative to the vertex's
  /// nearest joint); false gives f_m only G_ij.
  bool attention_row_context = true;
  /// PointNet head (eq. 7): per-point encoder widths (last = global feature) and decoder widths.
  std::vector<int64_t> head_encoder_widths = {64, 128, 256};
  std::vector<int64_t> head_decoder_widths = {128, 64};
  /// Which aggregation of Table 4 to use.
  SkinningVariant variant = SkinningVariant::kGeodesicAttention;
  /// k, the number of nearest joints concatenated by kSortByGeodesic (clamped to J).
  int64_t sort_k = 4;
  /// LeakyReLU slope of every MLP (0 = ReLU). Without batch normalisation, ReLU units of small
  /// networks die easily and can freeze a joint's logit; a leaky slope keeps them trainable.
  double negative_slope = 0.2;
  /// Map V and J into the frame of the body vertices (bounding-box centre, divided by their height)
  /// and divide G by the same height, so callers pass metres. When false, callers must normalise.
  bool normalize_input = true;
};

/// Outputs of the SkinningPredictor; batched like the input.
struct SkinningOutput {
  /// W (B, N_b, J) or (N_b, J): skinning weights, rows sum to 1 (eq. 7).
  at::Tensor W;
  /// logits (B, N_b, J) or (N_b, J): W = softmax(logits).
  at::Tensor logits;
  /// M (B, N_b, J) or (N_b, J): attention over joints, rows sum to 1 (eq. 5); uniform 1/J for
  /// kNoGeodesic; undefined for kSortByGeodesic, which has no attention.
  at::Tensor M;
};

/// f_s: body rest vertices, rest joints and geodesic distances -> skinning weights.
class SkinningPredictorImpl : public torch::nn::Module {
 public:
  explicit SkinningPredictorImpl(SkinningPredictorOptions options = {});

  /// V (B, N_b, 3) or (N_b, 3) body rest positions, metres;
  /// joints (B, J, 3) or (J, 3) rest joint positions, metres;
  /// G (B, N_b, J) or (N_b, J) vertex-joint geodesic distances, metres (may be undefined for kNoGeodesic)
  /// -> W (B, N_b, J) or (N_b, J).
  at::Tensor forward(const at::Tensor& V, const at::Tensor& joints, const at::Tensor& G);

  /// As forward, with the logits and the attention map.
  SkinningOutput forward_detailed(const at::Tensor& V, const at::Tensor& joints, const at::Tensor& G);

  SkinningPredictorOptions options;

 private:
  // (B, N, 3), (B, J, 3), (B, N, J) normalised -> P' (B, N, D) and M (B, N, J) or undefined.
  std::pair<at::Tensor, at::Tensor> fused_features(const at::Tensor& V, const at::Tensor& joints, const at::Tensor& G);

  Mlp pair_features_{nullptr};  // P_ij = MLP(v_i, J_j, v_i - J_j, |v_i - J_j|, G_ij); per-vertex MLP for sort
  Mlp attention_{nullptr};      // f_m, eq. (5); only for kGeodesicAttention
  PointNet head_{nullptr};      // eq. (7)
};
TORCH_MODULE(SkinningPredictor);

}  // namespace amt
