#include "models/losses.h"

#include <ATen/ATen.h>

namespace amt {

namespace {

void check_edges(const at::Tensor& edges, const char* name) {
  TORCH_CHECK(edges.dim() == 2 && edges.size(1) == 2 && edges.size(0) > 0, name, ": edges must be (E, 2) with E > 0, "
              "got ", edges.sizes());
}

// Differentiable |x| over the last dimension: sqrt(|x|^2 + eps).
at::Tensor safe_norm(const at::Tensor& x, double eps) { return (x.square().sum(-1) + eps).sqrt(); }

}  // namespace

at::Tensor apparel_bce_loss(const at::Tensor& logits, const at::Tensor& mask, double pos_weight,
                            const at::Tensor& vertex_weights) {
  TORCH_CHECK(logits.sizes() == mask.sizes(), "apparel_bce_loss: logits ", logits.sizes(), " and mask ", mask.sizes(),
              " differ");
  TORCH_CHECK(pos_weight > 0, "apparel_bce_loss: pos_weight must be positive");
  const at::Tensor target = mask.to(logits.scalar_type());
  const at::Tensor weight = pos_weight == 1.0 ? at::Tensor() : at::full({}, pos_weight, logits.options());
  TORCH_CHECK(!vertex_weights.defined() || vertex_weights.sizes() == logits.sizes(), "apparel_bce_loss: vertex ",
              "weights ", vertex_weights.sizes(), " and logits ", logits.sizes(), " differ");
  return at::binary_cross_entropy_with_logits(logits, target, vertex_weights, weight, at::Reduction::Mean);  // eq. (3)
}

at::Tensor vertex_l1_loss(const at::Tensor& pred, const at::Tensor& gt) {
  TORCH_CHECK(pred.sizes() == gt.sizes() && pred.dim() >= 2 && pred.size(-1) == 3, "vertex_l1_loss: pred ",
              pred.sizes(), " and gt ", gt.sizes(), " must both be (..., N, 3)");
  return (pred - gt).abs().sum(-1).mean();  // eq. (8), (14)
}

at::Tensor edge_length_loss(const at::Tensor& pred, const at::Tensor& rest, const at::Tensor& edges) {
  check_edges(edges, "edge_length_loss");
  TORCH_CHECK(pred.dim() >= 2 && pred.size(-1) == 3 && rest.dim() == 2 && rest.size(0) == pred.size(-2) &&
                  rest.size(1) == 3,
              "edge_length_loss: pred must be (..., N, 3) and rest (N, 3), got ", pred.sizes(), " and ", rest.sizes());
  const at::Tensor i = edges.select(1, 0).to(at::kLong), j = edges.select(1, 1).to(at::kLong);
  const int64_t d = pred.dim() - 2;
  const at::Tensor l_pred = safe_norm(pred.index_select(d, i) - pred.index_select(d, j), 1e-12);  // (..., E)
  const at::Tensor l_rest = (rest.index_select(0, i) - rest.index_select(0, j)).norm(2, -1);       // (E)
  return (l_pred - l_rest).abs().mean();  // eq. (9), (15)
}

at::Tensor weight_smoothness_loss(const at::Tensor& W, const at::Tensor& edges, double eps) {
  check_edges(edges, "weight_smoothness_loss");
  TORCH_CHECK(W.dim() == 2 || W.dim() == 3, "weight_smoothness_loss: W must be (N, J) or (B, N, J), got ", W.sizes());
  const at::Tensor i = edges.select(1, 0).to(at::kLong), j = edges.select(1, 1).to(at::kLong);
  const int64_t d = W.dim() - 2;
  return safe_norm(W.index_select(d, i) - W.index_select(d, j), eps).mean();  // eq. (10)
}

at::Tensor displacement_l2_loss(const at::Tensor& delta) {
  TORCH_CHECK(delta.dim() >= 2 && delta.size(-1) == 3, "displacement_l2_loss: delta must be (..., N, 3), got ",
              delta.sizes());
  return delta.square().sum(-1).mean();
}

LossTerms body_loss(const at::Tensor& B_hat, const at::Tensor& B_gt, const at::Tensor& B_rest, const at::Tensor& edges,
                    const at::Tensor& W, const LossWeights& weights, const at::Tensor& logits,
                    const at::Tensor& W_gt) {
  LossTerms out;
  out.vertex = vertex_l1_loss(B_hat, B_gt);
  out.edge = edge_length_loss(B_hat, B_rest, edges);
  out.smoothness = weight_smoothness_loss(W, edges);
  out.total = weights.vertex * out.vertex + weights.edge * out.edge + weights.smoothness * out.smoothness;
  if (logits.defined() && W_gt.defined()) {
    out.weights = skinning_weight_kl_loss(logits, W_gt);
    out.total = out.total + weights.skinning_weights * out.weights;
  }
  return out;
}

at::Tensor skinning_weight_kl_loss(const at::Tensor& logits, const at::Tensor& W_gt) {
  TORCH_CHECK(logits.sizes() == W_gt.sizes(), "skinning_weight_kl_loss: logits ", logits.sizes(), " and W_gt ",
              W_gt.sizes(), " differ");
  const at::Tensor target = W_gt.to(logits.scalar_type());
  // xlogy gives 0 log 0 = 0, so joints without ground-truth weight cost nothing.
  return (at::xlogy(target, target) - target * at::log_softmax(logits, -1)).sum(-1).mean();
}

LossTerms apparel_loss(const at::Tensor& A_hat, const at::Tensor& A_gt, const at::Tensor& A_rest,
                       const at::Tensor& edges, const LossWeights& weights) {
  LossTerms out;
  out.vertex = vertex_l1_loss(A_hat, A_gt);
  out.edge = edge_length_loss(A_hat, A_rest, edges);
  out.total = weights.vertex * out.vertex + weights.edge * out.edge;
  return out;
}

LossTerms refiner_loss(const at::Tensor& V_hat, const at::Tensor& V_gt, const at::Tensor& V_rest,
                       const at::Tensor& edges, const at::Tensor& delta, const LossWeights& weights) {
  LossTerms out;
  out.vertex = vertex_l1_loss(V_hat, V_gt);
  out.edge = edge_length_loss(V_hat, V_rest, edges);
  out.regularizer = displacement_l2_loss(delta);
  out.total = weights.vertex * out.vertex + weights.edge * out.edge + weights.regularizer * out.regularizer;
  return out;
}

}  // namespace amt
