#pragma once
// PointNet [21] per-point prediction: a shared per-point MLP encoder, a global max-pooled feature,
// and an MLP decoder on the per-point feature concatenated with the global one. Used by the
// apparel segmenter (eq. 2) and as the head of the skinning predictor (eq. 7). Also the character
// frame in which the networks see rest geometry.
#include <torch/nn/module.h>
#include <torch/nn/pimpl.h>

#include <cstdint>
#include <vector>

#include "models/mlp.h"

namespace amt {

// === Character frame

/// Centre and scale that map a character to a height-normalised frame: x' = (x - centre) / scale.
struct CharacterFrame {
  /// centre (B, 1, 3): the centre of the bounding box of the vertices.
  at::Tensor centre;
  /// scale (B, 1, 1): the character height (extent along Y, the up axis), at least 1e-6.
  at::Tensor scale;

  /// x (B, M, 3) in metres -> (B, M, 3) in the normalised frame.
  at::Tensor apply(const at::Tensor& x) const;
};

/// The frame of the vertices V (B, N, 3): centred on their bounding box, scaled by their height.
/// Detached: the frame is a fixed property of the input, not something gradients flow through.
CharacterFrame character_frame(const at::Tensor& V);

/// Adds a leading batch dimension to x when x.dim() == unbatched_dims; returns x otherwise.
at::Tensor batched(const at::Tensor& x, int64_t unbatched_dims);

// === PointNet

/// Configuration of a PointNet.
struct PointNetOptions {
  /// Channels of each input point.
  int64_t in_channels = 3;
  /// Widths of the shared per-point encoder; the last one is the global (max-pooled) feature width.
  /// The paper's PointNet uses 64/128/1024; these defaults suit CPU training.
  std::vector<int64_t> encoder_widths = {64, 128, 256};
  /// Hidden widths of the decoder on [per-point feature of the first encoder layer, global feature].
  std::vector<int64_t> decoder_widths = {128, 64};
  /// Channels of the output per point.
  int64_t out_channels = 1;
  /// LeakyReLU slope in all MLPs (0 = ReLU).
  double negative_slope = 0.0;
};

/// Per-point outputs of a PointNet segmentation network.
class PointNetImpl : public torch::nn::Module {
 public:
  explicit PointNetImpl(PointNetOptions options);

  /// x (B, N, in_channels) -> (B, N, out_channels). All B point sets must have the same N; callers
  /// pad a smaller set by repeating one of its points, which leaves the max pool unchanged.
  at::Tensor forward(const at::Tensor& x);

  PointNetOptions options;

 private:
  Mlp local_{nullptr};   // in_channels -> encoder_widths[0]
  Mlp global_{nullptr};  // encoder_widths[0] -> ... -> encoder_widths.back(), max-pooled over points
  Mlp decoder_{nullptr};
};
TORCH_MODULE(PointNet);

}  // namespace amt
