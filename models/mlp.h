#pragma once
// A plain multi-layer perceptron over the last dimension, the building block of every network in
// models/: per-point MLPs of PointNet, the vertex-joint feature encoder, decoders.
#include <torch/nn/module.h>
#include <torch/nn/modules/linear.h>
#include <torch/nn/pimpl.h>

#include <cstdint>
#include <vector>

namespace amt {

// === Mlp

/// Configuration of an Mlp.
struct MlpOptions {
  /// Layer widths including input and output: {3, 64, 128} is Linear(3, 64), act, Linear(64, 128).
  std::vector<int64_t> widths;
  /// Negative slope of the LeakyReLU between layers; 0 gives ReLU.
  double negative_slope = 0.0;
  /// Whether the activation also follows the last layer (true for encoders, false for decoders).
  bool activate_last = false;
  /// Initialise the last layer to zero (weights and bias), so that the MLP starts as the zero map.
  bool zero_last = false;

  MlpOptions() = default;
  explicit MlpOptions(std::vector<int64_t> w) : widths(std::move(w)) {}
};

/// Linear layers with LeakyReLU between them, applied to the last dimension of any tensor.
class MlpImpl : public torch::nn::Module {
 public:
  explicit MlpImpl(MlpOptions options);

  /// x (..., widths.front()) -> (..., widths.back())
  at::Tensor forward(const at::Tensor& x);

  /// The layers, in order (layer l maps widths[l] to widths[l + 1]).
  const std::vector<torch::nn::Linear>& layers() const { return layers_; }

  MlpOptions options;

 private:
  std::vector<torch::nn::Linear> layers_;
};
TORCH_MODULE(Mlp);

}  // namespace amt
