#include "models/joint_refiner.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <algorithm>

#include "models/pointnet.h"

namespace amt {
namespace {

// dst = r + p0 w0 + p1 w1 + p2 w2, then sigma (max(v, 0) + slope min(v, 0), the Mlp's LeakyReLU or ReLU
// in a form the compiler vectorises) when `activate`, over n entries.
template <typename scalar_t>
void first_layer_row(scalar_t* __restrict__ dst, const scalar_t* __restrict__ r, const scalar_t* __restrict__ w0,
                     const scalar_t* __restrict__ w1, const scalar_t* __restrict__ w2, scalar_t p0, scalar_t p1,
                     scalar_t p2, int64_t n, bool activate, scalar_t slope) {
  for (int64_t c = 0; c < n; ++c) dst[c] = r[c] + p0 * w0[c] + p1 * w1[c] + p2 * w2[c];
  if (!activate) return;
  for (int64_t c = 0; c < n; ++c) dst[c] = std::max(dst[c], scalar_t(0)) + slope * std::min(dst[c], scalar_t(0));
}

// The refiner's first layer on a prepared character without autograd, in one pass over the vertices:
//   h[b, i, :] = sigma(rest_term[i, :] + W_posed^T (x[b, i] - mean[b]) / scale)
// x (B, N, 3) and mean (B, 3) contiguous, W_posed_t (3, H) = W_posed^T contiguous, rest_term (N, H),
// out (B, N, H); sigma is the Mlp's activation (ReLU for slope 0) when `activate`, else the identity.
template <typename scalar_t>
void first_layer_kernel(const at::Tensor& x, const at::Tensor& mean, scalar_t scale, const at::Tensor& W_posed_t,
                        const at::Tensor& rest_term, bool activate, scalar_t negative_slope, at::Tensor& out) {
  const int64_t B = x.size(0), N = x.size(1), H = rest_term.size(1);
  const scalar_t* xp = x.data_ptr<scalar_t>();
  const scalar_t* mp = mean.data_ptr<scalar_t>();
  const scalar_t* w0 = W_posed_t.data_ptr<scalar_t>();
  const scalar_t* w1 = w0 + H;
  const scalar_t* w2 = w1 + H;
  const scalar_t* rt = rest_term.data_ptr<scalar_t>();
  scalar_t* o = out.data_ptr<scalar_t>();
  at::parallel_for(0, B * N, 256, [&](int64_t begin, int64_t end) {
    for (int64_t bi = begin; bi < end; ++bi) {
      const int64_t b = bi / N, i = bi % N;
      const scalar_t p0 = (xp[3 * bi] - mp[3 * b]) / scale;  // posed, as (x - mean) / scale
      const scalar_t p1 = (xp[3 * bi + 1] - mp[3 * b + 1]) / scale;
      const scalar_t p2 = (xp[3 * bi + 2] - mp[3 * b + 2]) / scale;
      first_layer_row(o + bi * H, rt + i * H, w0, w1, w2, p0, p1, p2, H, activate, negative_slope);
    }
  });
}

}  // namespace

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

RefinerCharacter JointRefinerImpl::prepare(const at::Tensor& rest, const at::Tensor& apparel_prob) {
  TORCH_CHECK(rest.dim() == 2 && rest.size(0) > 0 && rest.size(1) == 3, "JointRefiner: rest must be (N, 3) with N > 0, "
              "got ", rest.sizes());
  const int64_t N = rest.size(0);
  TORCH_CHECK(apparel_prob.dim() == 1 && apparel_prob.size(0) == N, "JointRefiner: apparel_prob must be (", N,
              "), got ", apparel_prob.sizes());
  // The constant inputs of forward: rest_n and prob, and what the first layer makes of them.
  const at::Tensor rest_b = rest.unsqueeze(0);
  const CharacterFrame frame = character_frame(rest_b);
  const at::Tensor rest_n = ((rest_b - rest_b.mean(1, /*keepdim=*/true)) / frame.scale).squeeze(0);  // (N, 3)
  const at::Tensor prob = apparel_prob.to(rest.scalar_type()).view({N, 1});
  const torch::nn::Linear& first = mlp_->layers().front();
  RefinerCharacter character;
  character.rest_term = at::linear(at::cat({rest_n, prob}, 1), first->weight.narrow(1, 3, 4), first->bias);
  character.scale = frame.scale;
  return character;
}

RefinerOutput JointRefinerImpl::forward(const at::Tensor& tiled, const RefinerCharacter& character) {
  TORCH_CHECK((tiled.dim() == 2 || tiled.dim() == 3) && tiled.size(-1) == 3, "JointRefiner: tiled must be (N, 3) or "
              "(B, N, 3), got ", tiled.sizes());
  const at::Tensor x = batched(tiled, 2);  // (B, N, 3)
  const int64_t B = x.size(0), N = x.size(1);
  TORCH_CHECK(character.rest_term.defined() && character.num_vertices() == N, "JointRefiner: the prepared character has ",
              (character.rest_term.defined() ? character.num_vertices() : 0), " vertices, tiled has ", N);
  const std::vector<torch::nn::Linear>& layers = mlp_->layers();
  const MlpOptions& mlp = mlp_->options;
  const bool in_place = !at::GradMode::is_enabled();
  const bool activate_first = layers.size() > 1 || mlp.activate_last;
  const at::Tensor W_posed = layers.front()->weight.narrow(1, 0, 3);
  const at::Tensor mean = x.mean(1, /*keepdim=*/true);  // (B, 1, 3)
  // The first layer: W_posed posed + the prepared W_rest rest_n + w_prob p + b (f_j, eq. 16).
  at::Tensor h;
  if (in_place) {  // inference: one pass over the vertices for posed, the product, the sum and sigma
    const at::Tensor xc = x.contiguous(), rest_term = character.rest_term.contiguous();
    h = at::empty({B, N, rest_term.size(1)}, x.options());
    AT_DISPATCH_FLOATING_TYPES(x.scalar_type(), "refiner_first_layer", [&] {
      first_layer_kernel<scalar_t>(xc, mean.contiguous(), character.scale.item<scalar_t>(), W_posed.t().contiguous(),
                                   rest_term, activate_first, static_cast<scalar_t>(mlp.negative_slope), h);
    });
  } else {
    const at::Tensor posed = (x - mean) / character.scale;  // (B, N, 3)
    h = B == 1 ? at::addmm(character.rest_term, posed.reshape({N, 3}), W_posed.t()).unsqueeze(0)
               : at::linear(posed, W_posed) + character.rest_term;
  }
  // The other layers as Mlp::forward runs them (activation after every layer but the last, in place
  // without autograd).
  for (size_t l = 0; l < layers.size(); ++l) {
    if (l > 0) h = at::linear(h, layers[l]->weight, layers[l]->bias);  // as Linear::forward
    if (l == 0 && in_place) continue;                                   // sigma is in the kernel
    if (l + 1 < layers.size() || mlp.activate_last) {
      if (in_place) {
        h = mlp.negative_slope == 0.0 ? h.relu_() : at::leaky_relu_(h, mlp.negative_slope);
      } else {
        h = mlp.negative_slope == 0.0 ? at::relu(h) : at::leaky_relu(h, mlp.negative_slope);
      }
    }
  }
  RefinerOutput out;
  out.delta = in_place ? h.mul_(options.output_scale) : options.output_scale * h;
  out.V_hat = x + out.delta;  // eq. (16)
  if (tiled.dim() == 2) {
    out.V_hat = out.V_hat.squeeze(0);
    out.delta = out.delta.squeeze(0);
  }
  return out;
}

}  // namespace amt
