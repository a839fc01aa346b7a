#pragma once
// The joint refinement module f_j (paper section 4.4): a light per-vertex MLP that corrects the
// tiled body and apparel results, ΔV = f_j(Â, B̂), V̂ = tile(Â, B̂) + ΔV (eq. 16).
#include <torch/nn/module.h>
#include <torch/nn/pimpl.h>

#include <cstdint>
#include <vector>

#include "models/mlp.h"

namespace amt {

/// Merges apparel and body results into mesh order (the "tile" of eq. 16):
///   A_hat (..., N_a, 3), B_hat (..., N_b, 3), apparel_mask (N) bool with N_a true entries
/// -> (..., N, 3) with the apparel rows in order at the mask's true positions, body rows at the rest.
/// Differentiable in A_hat and B_hat.
at::Tensor tile_apparel_body(const at::Tensor& A_hat, const at::Tensor& B_hat, const at::Tensor& apparel_mask);

/// Configuration of the JointRefiner.
struct JointRefinerOptions {
  /// Hidden widths of the per-vertex MLP.
  std::vector<int64_t> hidden_widths = {64, 64};
  /// Factor on the MLP output: ΔV = output_scale * MLP(...), metres.
  double output_scale = 0.1;
  /// Start as the identity (ΔV = 0) by zero-initialising the last layer.
  bool zero_init = true;
};

/// Outputs of the JointRefiner.
struct RefinerOutput {
  /// V_hat (B, N, 3) or (N, 3): tile + ΔV (eq. 16).
  at::Tensor V_hat;
  /// ΔV (B, N, 3) or (N, 3), for the L2 regulariser.
  at::Tensor delta;
};

/// f_j: a per-vertex MLP on 7 inputs: the tiled position relative to the frame's mean vertex and the
/// rest position relative to the rest mesh's mean (both divided by the rest height), and the apparel
/// probability (or 0/1 mask) that says which module produced the vertex.
class JointRefinerImpl : public torch::nn::Module {
 public:
  explicit JointRefinerImpl(JointRefinerOptions options = {});

  /// tiled        (B, N, 3) or (N, 3): tile(Â, B̂), metres
  /// rest         (N, 3): rest positions V, metres
  /// apparel_prob (N): p̂ from the segmenter, or the 0/1 apparel mask
  /// -> V̂ and ΔV, shaped like `tiled`.
  RefinerOutput forward(const at::Tensor& tiled, const at::Tensor& rest, const at::Tensor& apparel_prob);

  JointRefinerOptions options;

 private:
  Mlp mlp_{nullptr};
};
TORCH_MODULE(JointRefiner);

}  // namespace amt
