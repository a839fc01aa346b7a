#include "models/apparel_segmenter.h"

#include <ATen/ATen.h>

#include "data_tools/geometry/segmentation_features.h"

namespace amt {

int64_t segmenter_feature_channels(const ApparelSegmenterOptions& options) {
  TORCH_CHECK(options.inputs == "shape" || options.inputs == "welded" || options.inputs == "positions",
              "ApparelSegmenter: inputs: expected \"shape\", \"welded\" or \"positions\", got \"", options.inputs,
              "\"");
  return options.inputs == "positions" ? 0 : kSegmentationFeatures;
}

ApparelSegmenterImpl::ApparelSegmenterImpl(ApparelSegmenterOptions options_) : options(std::move(options_)) {
  PointNetOptions pn;
  pn.in_channels = 3 + segmenter_feature_channels(options);
  pn.encoder_widths = options.encoder_widths;
  pn.decoder_widths = options.decoder_widths;
  pn.out_channels = 1;
  pn.negative_slope = options.negative_slope;
  pointnet_ = register_module("pointnet", PointNet(pn));
}

at::Tensor ApparelSegmenterImpl::forward(const at::Tensor& V, const at::Tensor& features) {
  TORCH_CHECK((V.dim() == 2 || V.dim() == 3) && V.size(-1) == 3,
              "ApparelSegmenter: V must be (N, 3) or (B, N, 3), got ", V.sizes());
  at::Tensor x = batched(V, 2);  // (B, N, 3)
  if (options.normalize_input) x = character_frame(x).apply(x);
  if (const int64_t C = segmenter_feature_channels(options); C > 0) {
    TORCH_CHECK(features.defined() && features.dim() == V.dim() && features.size(-1) == C &&
                    features.size(-2) == V.size(-2) && (V.dim() == 2 || features.size(0) == V.size(0)),
                "ApparelSegmenter: features: expected (", (V.dim() == 3 ? std::to_string(V.size(0)) + ", " : ""),
                V.size(-2), ", ", C, ") shape features (segmenter_input_features), got ",
                (features.defined() ? features.sizes() : at::IntArrayRef{}));
    x = at::cat({x, batched(features, 2).to(x.dtype())}, 2);
  }
  const at::Tensor logits = pointnet_->forward(x).squeeze(2);  // (B, N)
  return V.dim() == 2 ? logits.squeeze(0) : logits;
}

at::Tensor ApparelSegmenterImpl::probabilities(const at::Tensor& V, const at::Tensor& features) {
  return at::sigmoid(forward(V, features));  // eq. (2)
}

}  // namespace amt
