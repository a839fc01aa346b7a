#include "models/mlp.h"

#include <ATen/ATen.h>
#include <torch/utils.h>

#include <string>

namespace amt {

MlpImpl::MlpImpl(MlpOptions options_) : options(std::move(options_)) {
  TORCH_CHECK(options.widths.size() >= 2, "Mlp: needs at least an input and an output width, got ",
              options.widths.size(), " widths");
  for (size_t l = 0; l + 1 < options.widths.size(); ++l) {
    TORCH_CHECK(options.widths[l] > 0 && options.widths[l + 1] > 0, "Mlp: widths must be positive");
    layers_.push_back(register_module("linear" + std::to_string(l),
                                      torch::nn::Linear(options.widths[l], options.widths[l + 1])));
  }
  if (options.zero_last) {
    torch::NoGradGuard no_grad;
    layers_.back()->weight.zero_();
    layers_.back()->bias.zero_();
  }
}

at::Tensor MlpImpl::forward(const at::Tensor& x) {
  // Without autograd (inference, validation) the activations run in place on the fresh layer outputs:
  // the same values, one allocation and one pass over memory fewer per layer.
  const bool in_place = !at::GradMode::is_enabled();
  at::Tensor h = x;
  for (size_t l = 0; l < layers_.size(); ++l) {
    h = layers_[l]->forward(h);
    if (l + 1 < layers_.size() || options.activate_last) {
      if (in_place) {
        if (options.negative_slope == 0.0) {
          h.relu_();
        } else {
          at::leaky_relu_(h, options.negative_slope);
        }
      } else {
        h = options.negative_slope == 0.0 ? at::relu(h) : at::leaky_relu(h, options.negative_slope);
      }
    }
  }
  return h;
}

}  // namespace amt
