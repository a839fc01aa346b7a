#pragma once
// Training losses of the four modules (paper eq. 3, 8-10, 14-15 and section 4.4) and their weighted
// sums with the paper's weights (section 5.2). All return 0-dim tensors, differentiable in the
// predictions. Leading frame or batch dimensions (written "...") are averaged like vertices.
#include <ATen/core/Tensor.h>

namespace amt {

// === Single terms

/// eq. (3), apparel segmentation: the standard binary cross entropy of the logits against the
/// ground-truth mask, mean over vertices. (The paper's eq. 3 swaps p̂ and p̄ and drops the minus
/// sign; this is the usual -[p̄ log p̂ + (1 - p̄) log(1 - p̂)], computed stably from the logits.)
///   logits (..., N), mask (..., N) 0/1 (any dtype); pos_weight > 0 scales the apparel (positive) terms;
///   vertex_weights (..., N), when defined, scales each vertex's term (the mean stays over vertices).
at::Tensor apparel_bce_loss(const at::Tensor& logits, const at::Tensor& mask, double pos_weight = 1.0,
                            const at::Tensor& vertex_weights = {});

/// eq. (8) and (14), vertex loss: the L1 norm of each vertex's error (|dx| + |dy| + |dz|), averaged
/// over vertices (and frames). pred, gt (..., N, 3).
at::Tensor vertex_l1_loss(const at::Tensor& pred, const at::Tensor& gt);

/// eq. (9) and (15), edge-length loss: mean over edges (and frames) of | |p_i - p_j| - |r_i - r_j| |,
/// against the REST edge lengths as the paper writes (rest body mesh B, rest apparel A or the whole
/// rest mesh V), not the posed ground truth.
///   pred (..., N, 3); rest (N, 3); edges (E, 2) int64.
/// |p_i - p_j| is computed as sqrt(|.|^2 + 1e-12) so the gradient stays finite for collapsed edges.
at::Tensor edge_length_loss(const at::Tensor& pred, const at::Tensor& rest, const at::Tensor& edges);

/// eq. (10), skinning weight smoothness: mean over edges of ||W_i - W_j||_2, with the safe norm
/// sqrt(|.|^2 + eps) (differentiable, zero gradient, at equal rows).
///   W (N, J) or (B, N, J); edges (E, 2) int64.
at::Tensor weight_smoothness_loss(const at::Tensor& W, const at::Tensor& edges, double eps = 1e-12);

/// Direct supervision of the skinning weights (not in the paper, which supervises W only through
/// LBS, eq. 8-10): mean over vertices of KL(W̄_i || W_i) = sum_j W̄_ij (log W̄_ij - log W_ij), from
/// the logits (W = softmax(logits)); 0 when the prediction equals the ground truth.
///   logits (..., N, J); W_gt (..., N, J) rows summing to 1.
at::Tensor skinning_weight_kl_loss(const at::Tensor& logits, const at::Tensor& W_gt);

/// Section 4.4, the refiner's L2 regulariser L_r: mean over vertices (and frames) of |ΔV_i|^2.
///   delta (..., N, 3).
at::Tensor displacement_l2_loss(const at::Tensor& delta);

// === Weighted sums

/// The loss weights of section 5.2.
struct LossWeights {
  /// λ_v: vertex L1 losses (eq. 8, 14, refiner).
  double vertex = 1.0;
  /// λ_e: edge-length losses (eq. 9, 15, refiner).
  double edge = 100.0;
  /// λ_s: skinning weight smoothness (eq. 10).
  double smoothness = 0.01;
  /// λ_r: the refiner's L2 regulariser on ΔV.
  double regularizer = 0.01;
  /// λ_w: direct skinning weight supervision (skinning_weight_kl_loss). 0, the paper's setting,
  /// supervises the weights only through the skinned vertices. The indirect loss sees a joint's
  /// weights only where that joint bends in the window, so it learns slowly; a small λ_w gives
  /// every vertex a dense signal from the dataset's ground-truth weights.
  double skinning_weights = 0.0;
};

/// A weighted sum and its unweighted terms (terms a module does not use are undefined).
struct LossTerms {
  at::Tensor total;
  at::Tensor vertex;
  at::Tensor edge;
  at::Tensor smoothness;
  at::Tensor regularizer;
  at::Tensor weights;
};

/// L_b = λ_v L_vb + λ_e L_eb + λ_s L_s (section 4.2), plus λ_w times the weight KL when logits and
/// W_gt are given (the weights term is always computed then, so logs show it even at λ_w = 0):
///   B_hat, B_gt (T, N_b, 3) skinned and ground-truth body; B_rest (N_b, 3); edges (E_b, 2) among
///   body vertices; W (N_b, J) predicted weights; logits (N_b, J) with W = softmax(logits) and
///   W_gt (N_b, J) ground-truth weights, or both undefined.
LossTerms body_loss(const at::Tensor& B_hat, const at::Tensor& B_gt, const at::Tensor& B_rest, const at::Tensor& edges,
                    const at::Tensor& W, const LossWeights& weights = {}, const at::Tensor& logits = {},
                    const at::Tensor& W_gt = {});

/// L_a = λ_v L_va + λ_e L_ea (section 4.3):
///   A_hat, A_gt (..., N_a, 3); A_rest (N_a, 3); edges (E_a, 2) of the apparel graph.
LossTerms apparel_loss(const at::Tensor& A_hat, const at::Tensor& A_gt, const at::Tensor& A_rest,
                       const at::Tensor& edges, const LossWeights& weights = {});

/// L_j = λ_v L_v + λ_e L_e + λ_r L_r (section 4.4), over the whole mesh:
///   V_hat, V_gt (..., N, 3); V_rest (N, 3); edges (E, 2) of the whole mesh; delta (..., N, 3) = ΔV.
LossTerms refiner_loss(const at::Tensor& V_hat, const at::Tensor& V_gt, const at::Tensor& V_rest,
                       const at::Tensor& edges, const at::Tensor& delta, const LossWeights& weights = {});

}  // namespace amt
