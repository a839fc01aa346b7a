#pragma once
// The apparel segmentation module f_c (paper section 4.1): a PointNet on the rest vertex positions
// (the paper's input) and, by default, per-vertex shape features of the mesh and skeleton
// (data_tools/geometry/segmentation_features.h), that predicts, per vertex, the logit of the vertex
// being apparel (eq. 2).
#include <torch/nn/module.h>
#include <torch/nn/pimpl.h>

#include <cstdint>
#include <string>
#include <vector>

#include "models/pointnet.h"

namespace amt {

/// Configuration of the ApparelSegmenter.
struct ApparelSegmenterOptions {
  /// Shared per-point encoder widths; the last is the global feature (paper: 64/128/1024).
  std::vector<int64_t> encoder_widths = {64, 128, 256};
  /// Hidden widths of the per-point decoder.
  std::vector<int64_t> decoder_widths = {128, 64};
  /// LeakyReLU slope of the MLPs (0 = ReLU; leaky keeps units of a small network without batch
  /// normalisation from dying).
  double negative_slope = 0.2;
  /// Normalise V inside the network (centre on its bounding box, divide by its height), so callers
  /// pass rest positions in metres. When false, callers must normalise.
  bool normalize_input = true;
  /// "welded": the rest positions and the kSegmentationFeatures shape features of each vertex computed
  /// on the welded mesh (welded_segmentation_features: the same values however the mesh is split into
  /// open parts); "shape": the same columns on the mesh as given (segmentation_features: checkpoints
  /// written before "welded"); "positions": the paper's input, the rest positions alone (checkpoints
  /// written before the shape features).
  std::string inputs = "welded";
};

/// Channels the segmenter reads per vertex beside its rest position (0 for "positions").
int64_t segmenter_feature_channels(const ApparelSegmenterOptions& options);

/// f_c: rest vertex positions -> apparel logits. p̂ = sigmoid(logits) (eq. 2).
class ApparelSegmenterImpl : public torch::nn::Module {
 public:
  explicit ApparelSegmenterImpl(ApparelSegmenterOptions options = {});

  /// V (B, N, 3) or (N, 3) rest positions, metres, and with inputs "shape" their features (B, N, 6)
  /// or (N, 6) (segmenter_input_features(options.inputs, ...); ignored with "positions") -> logits (B, N) or (N).
  at::Tensor forward(const at::Tensor& V, const at::Tensor& features = {});

  /// V (B, N, 3) or (N, 3) [, features] -> p̂ (B, N) or (N), the probability of each vertex being
  /// apparel (eq. 2).
  at::Tensor probabilities(const at::Tensor& V, const at::Tensor& features = {});

  ApparelSegmenterOptions options;

 private:
  PointNet pointnet_{nullptr};
};
TORCH_MODULE(ApparelSegmenter);

}  // namespace amt
