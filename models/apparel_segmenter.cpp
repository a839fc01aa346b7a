#include "models/apparel_segmenter.h"

#include <ATen/ATen.h>

namespace amt {

ApparelSegmenterImpl::ApparelSegmenterImpl(ApparelSegmenterOptions options_) : options(std::move(options_)) {
  PointNetOptions pn;
  pn.in_channels = 3;
  pn.encoder_widths = options.encoder_widths;
  pn.decoder_widths = options.decoder_widths;
  pn.out_channels = 1;
  pn.negative_slope = options.negative_slope;
  pointnet_ = register_module("pointnet", PointNet(pn));
}

at::Tensor ApparelSegmenterImpl::forward(const at::Tensor& V) {
  TORCH_CHECK((V.dim() == 2 || V.dim() == 3) && V.size(-1) == 3,
              "ApparelSegmenter: V must be (N, 3) or (B, N, 3), got ", V.sizes());
  at::Tensor x = batched(V, 2);  // (B, N, 3)
  if (options.normalize_input) x = character_frame(x).apply(x);
  const at::Tensor logits = pointnet_->forward(x).squeeze(2);  // (B, N)
  return V.dim() == 2 ? logits.squeeze(0) : logits;
}

at::Tensor ApparelSegmenterImpl::probabilities(const at::Tensor& V) { return at::sigmoid(forward(V)); }  // eq. (2)

}  // namespace amt
