#include "models/joint_refiner.h"

#include <ATen/ATen.h>

#include "models/pointnet.h"

namespace amt {

at::Tensor tile_apparel_body(const at::Tensor& A_hat, const at::Tensor& B_hat, const at::Tensor& apparel_mask) {
  TORCH_CHECK(apparel_mask.dim() == 1, "tile_apparel_body: apparel_mask must be (N), got ", apparel_mask.sizes());
  const at::Tensor mask = apparel_mask.to(at::kBool);
  const at::Tensor apparel = mask.nonzero().squeeze(1), body = mask.logical_not().nonzero().squeeze(1);
  TORCH_CHECK(A_hat.dim() >= 2 && A_hat.size(-2) == apparel.size(0) && B_hat.size(-2) == body.size(0) &&
                  A_hat.dim() == B_hat.dim(),
              "tile_apparel_body: A_hat ", A_hat.sizes(), " and B_hat ", B_hat.sizes(), " do not match the mask's ",
              apparel.size(0), " apparel and ", body.size(0), " body vertices");
  std::vector<int64_t> shape = A_hat.sizes().vec();
  shape[shape.size() - 2] = mask.size(0);
  const int64_t dim = A_hat.dim() - 2;
  return at::zeros(shape, A_hat.options()).index_copy(dim, apparel, A_hat).index_copy(dim, body, B_hat);
}

JointRefinerImpl::JointRefinerImpl(JointRefinerOptions options_) : options(std::move(options_)) {
  std::vector<int64_t> widths = {7};
  widths.insert(widths.end(), options.hidden_widths.begin(), options.hidden_widths.end());
  widths.push_back(3);
  MlpOptions mlp(widths);
  mlp.zero_last = options.zero_init;
  mlp_ = register_module("mlp", Mlp(mlp));
}

RefinerOutput JointRefinerImpl::forward(const at::Tensor& tiled, const at::Tensor& rest,
                                        const at::Tensor& apparel_prob) {
  TORCH_CHECK((tiled.dim() == 2 || tiled.dim() == 3) && tiled.size(-1) == 3, "JointRefiner: tiled must be (N, 3) or "
              "(B, N, 3), got ", tiled.sizes());
  const at::Tensor x = batched(tiled, 2);  // (B, N, 3)
  const int64_t B = x.size(0), N = x.size(1);
  TORCH_CHECK(rest.dim() == 2 && rest.size(0) == N && rest.size(1) == 3, "JointRefiner: rest must be (", N,
              ", 3), got ", rest.sizes());
  TORCH_CHECK(apparel_prob.dim() == 1 && apparel_prob.size(0) == N, "JointRefiner: apparel_prob must be (", N,
              "), got ", apparel_prob.sizes());
  const at::Tensor rest_b = rest.unsqueeze(0);
  const CharacterFrame frame = character_frame(rest_b);
  const at::Tensor posed = (x - x.mean(1, /*keepdim=*/true)) / frame.scale;
  const at::Tensor rest_n = ((rest_b - rest_b.mean(1, /*keepdim=*/true)) / frame.scale).expand({B, N, 3});
  const at::Tensor prob = apparel_prob.to(x.scalar_type()).view({1, N, 1}).expand({B, N, 1});
  const at::Tensor delta = options.output_scale * mlp_->forward(at::cat({posed, rest_n, prob}, 2));  // f_j, eq. (16)
  RefinerOutput out;
  out.V_hat = x + delta;  // eq. (16)
  out.delta = delta;
  if (tiled.dim() == 2) {
    out.V_hat = out.V_hat.squeeze(0);
    out.delta = out.delta.squeeze(0);
  }
  return out;
}

}  // namespace amt
