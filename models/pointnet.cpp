#include "models/pointnet.h"

#include <ATen/ATen.h>

namespace amt {

at::Tensor CharacterFrame::apply(const at::Tensor& x) const { return (x - centre) / scale; }

CharacterFrame character_frame(const at::Tensor& V) {
  TORCH_CHECK(V.dim() == 3 && V.size(2) == 3 && V.size(1) > 0, "character_frame: V must be (B, N, 3), got ",
              V.sizes());
  const at::Tensor v = V.detach();
  const at::Tensor lo = std::get<0>(v.min(1, /*keepdim=*/true));  // (B, 1, 3)
  const at::Tensor hi = std::get<0>(v.max(1, /*keepdim=*/true));
  CharacterFrame frame;
  frame.centre = 0.5 * (lo + hi);
  frame.scale = (hi - lo).narrow(2, 1, 1).clamp_min(1e-6);  // Y extent: the height
  return frame;
}

at::Tensor batched(const at::Tensor& x, int64_t unbatched_dims) {
  return x.dim() == unbatched_dims ? x.unsqueeze(0) : x;
}

PointNetImpl::PointNetImpl(PointNetOptions options_) : options(std::move(options_)) {
  TORCH_CHECK(!options.encoder_widths.empty(), "PointNet: encoder_widths must not be empty");
  MlpOptions local({options.in_channels, options.encoder_widths.front()});
  local.activate_last = true;
  local.negative_slope = options.negative_slope;
  local_ = register_module("local", Mlp(local));

  std::vector<int64_t> global_widths(options.encoder_widths.begin(), options.encoder_widths.end());
  if (global_widths.size() == 1) global_widths.push_back(global_widths.front());
  MlpOptions global(global_widths);
  global.activate_last = true;
  global.negative_slope = options.negative_slope;
  global_ = register_module("global_mlp", Mlp(global));  // not "global": a Python keyword breaks torch::save

  std::vector<int64_t> decoder_widths = {options.encoder_widths.front() + global_widths.back()};
  decoder_widths.insert(decoder_widths.end(), options.decoder_widths.begin(), options.decoder_widths.end());
  decoder_widths.push_back(options.out_channels);
  MlpOptions decoder(decoder_widths);
  decoder.negative_slope = options.negative_slope;
  decoder_ = register_module("decoder", Mlp(decoder));
}

at::Tensor PointNetImpl::forward(const at::Tensor& x) {
  TORCH_CHECK(x.dim() == 3 && x.size(2) == options.in_channels, "PointNet: input must be (B, N, ",
              options.in_channels, "), got ", x.sizes());
  const at::Tensor local = local_->forward(x);                                   // (B, N, C0)
  const at::Tensor global = std::get<0>(global_->forward(local).max(1, true));  // (B, 1, C_g)
  const at::Tensor joined = at::cat({local, global.expand({-1, x.size(1), -1})}, 2);
  return decoder_->forward(joined);  // (B, N, out_channels)
}

}  // namespace amt
