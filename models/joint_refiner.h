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

/// What the JointRefiner's first layer makes of one character's constant inputs, computed once by
/// JointRefinerImpl::prepare so that a frame multiplies only its 3 posed channels. Valid for that
/// character while the refiner's parameters are unchanged.
struct RefinerCharacter {
  /// rest_term (N, H_1): W_rest rest_n + w_prob p + b, the first layer (W = [W_posed | W_rest | w_prob],
  /// bias b) on the normalised rest positions and the apparel probabilities.
  at::Tensor rest_term;
  /// scale (1, 1, 1): the rest height that divides positions, character_frame(rest).scale.
  at::Tensor scale;

  int64_t num_vertices() const { return rest_term.size(0); }
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

  /// The per-character part of forward, for a runtime that refines many frames of one character:
  ///   rest (N, 3), apparel_prob (N) as in forward -> the first layer's constant term and the scale.
  /// Differentiable in the parameters when computed with autograd on.
  RefinerCharacter prepare(const at::Tensor& rest, const at::Tensor& apparel_prob);

  /// forward(tiled, rest, apparel_prob) with `character` = prepare(rest, apparel_prob): the same
  /// result up to float rounding, with the first layer's product over 3 channels instead of 7.
  ///   tiled (B, N, 3) or (N, 3) -> V̂ and ΔV, shaped like `tiled`.
  RefinerOutput forward(const at::Tensor& tiled, const RefinerCharacter& character);

  JointRefinerOptions options;

 private:
  Mlp mlp_{nullptr};
};
TORCH_MODULE(JointRefiner);

}  // namespace amt
