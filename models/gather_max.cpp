#include "models/gather_max.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <torch/csrc/autograd/custom_function.h>

#include <algorithm>
#include <atomic>
#include <vector>

namespace amt {

namespace {

void check_inputs(const at::Tensor& values, const at::Tensor& neighbors) {
  TORCH_CHECK(values.dim() == 3, "gather_max: values must be (B, N_src, C) or (N_src, C), got ", values.sizes());
  TORCH_CHECK(neighbors.dim() == 2 && neighbors.size(1) >= 1 && neighbors.scalar_type() == at::kLong,
              "gather_max: neighbors must be (N, K) int64 with K >= 1, got ", neighbors.sizes(), " ",
              neighbors.scalar_type());
  const at::Tensor n = neighbors;
  if (n.numel() > 0) {
    TORCH_CHECK(n.min().item<int64_t>() >= 0 && n.max().item<int64_t>() < values.size(1),
                "gather_max: neighbour indices must be in [0, ", values.size(1), ")");
  }
}

// out (B, N, C) = max over neighbours; argmax (B, N, C) int64 source rows, when `argmax` is defined.
template <typename scalar_t>
void gather_max_kernel(const at::Tensor& values, const at::Tensor& neighbors, at::Tensor& out, at::Tensor* argmax) {
  const int64_t B = values.size(0), S = values.size(1), C = values.size(2);
  const int64_t N = neighbors.size(0), K = neighbors.size(1);
  const scalar_t* v = values.data_ptr<scalar_t>();
  const int64_t* nbr = neighbors.data_ptr<int64_t>();
  scalar_t* o = out.data_ptr<scalar_t>();
  int64_t* am = argmax ? argmax->data_ptr<int64_t>() : nullptr;
  at::parallel_for(0, B * N, 64, [&](int64_t begin, int64_t end) {
    for (int64_t bi = begin; bi < end; ++bi) {
      const int64_t b = bi / N, i = bi % N;
      const int64_t* row = nbr + i * K;
      const scalar_t* src = v + b * S * C;
      scalar_t* dst = o + bi * C;
      std::copy(src + row[0] * C, src + row[0] * C + C, dst);
      if (am) std::fill(am + bi * C, am + bi * C + C, row[0]);
      for (int64_t k = 1; k < K; ++k) {
        const scalar_t* x = src + row[k] * C;
        if (am) {
          int64_t* a = am + bi * C;
          for (int64_t c = 0; c < C; ++c) {
            if (x[c] > dst[c]) {
              dst[c] = x[c];
              a[c] = row[k];
            }
          }
        } else {
          for (int64_t c = 0; c < C; ++c) dst[c] = std::max(dst[c], x[c]);
        }
      }
    }
  });
}

// grad_values (B, S, C) += grad_out (B, N, C) scattered to the argmax rows. Parallel over channel
// blocks so that no two threads write the same entry.
template <typename scalar_t>
void scatter_argmax_kernel(const at::Tensor& grad_out, const at::Tensor& argmax, at::Tensor& grad_values) {
  const int64_t B = grad_out.size(0), N = grad_out.size(1), C = grad_out.size(2), S = grad_values.size(1);
  const scalar_t* g = grad_out.data_ptr<scalar_t>();
  const int64_t* am = argmax.data_ptr<int64_t>();
  scalar_t* gv = grad_values.data_ptr<scalar_t>();
  at::parallel_for(0, C, 16, [&](int64_t c0, int64_t c1) {
    for (int64_t b = 0; b < B; ++b) {
      for (int64_t i = 0; i < N; ++i) {
        const int64_t off = (b * N + i) * C;
        for (int64_t c = c0; c < c1; ++c) gv[(b * S + am[off + c]) * C + c] += g[off + c];
      }
    }
  });
}

class GatherMaxFunction : public torch::autograd::Function<GatherMaxFunction> {
 public:
  static at::Tensor forward(torch::autograd::AutogradContext* ctx, const at::Tensor& values,
                            const at::Tensor& neighbors) {
    const at::Tensor v = values.contiguous(), n = neighbors.contiguous();
    at::Tensor out = at::empty({v.size(0), n.size(0), v.size(2)}, v.options());
    at::Tensor argmax = at::empty({v.size(0), n.size(0), v.size(2)}, v.options().dtype(at::kLong));
    AT_DISPATCH_FLOATING_TYPES(v.scalar_type(), "gather_max", [&] { gather_max_kernel<scalar_t>(v, n, out, &argmax); });
    ctx->save_for_backward({argmax});
    ctx->saved_data["num_sources"] = v.size(1);
    return out;
  }

  static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                 torch::autograd::variable_list grad_outputs) {
    const at::Tensor argmax = ctx->get_saved_variables()[0];
    const at::Tensor g = grad_outputs[0].contiguous();
    at::Tensor grad_values = at::zeros({g.size(0), ctx->saved_data["num_sources"].toInt(), g.size(2)}, g.options());
    AT_DISPATCH_FLOATING_TYPES(g.scalar_type(), "gather_max_backward",
                               [&] { scatter_argmax_kernel<scalar_t>(g, argmax, grad_values); });
    return {grad_values, at::Tensor()};
  }
};

}  // namespace

at::Tensor gather_max(const at::Tensor& values, const at::Tensor& neighbors) {
  const at::Tensor v = values.dim() == 2 ? values.unsqueeze(0) : values;
  check_inputs(v, neighbors);
  at::Tensor out;
  if (at::GradMode::is_enabled() && values.requires_grad()) {
    out = GatherMaxFunction::apply(v, neighbors);
  } else {  // no autograd: skip recording the argmax
    const at::Tensor vc = v.contiguous(), n = neighbors.contiguous();
    out = at::empty({vc.size(0), n.size(0), vc.size(2)}, vc.options());
    AT_DISPATCH_FLOATING_TYPES(vc.scalar_type(), "gather_max",
                               [&] { gather_max_kernel<scalar_t>(vc, n, out, nullptr); });
  }
  return values.dim() == 2 ? out.squeeze(0) : out;
}

at::Tensor gather_max_add_leaky(const at::Tensor& products, const at::Tensor& neighbors, double negative_slope) {
  TORCH_CHECK(products.dim() == 3 && products.size(2) % 2 == 0 && products.scalar_type() == at::kFloat,
              "gather_max_add_leaky: products must be (B, N, 2 C) float, got ", products.sizes(), " ",
              products.scalar_type());
  TORCH_CHECK(neighbors.dim() == 2 && neighbors.size(1) >= 1 && neighbors.size(0) == products.size(1) &&
                  neighbors.scalar_type() == at::kLong,
              "gather_max_add_leaky: neighbors must be (", products.size(1), ", K) int64 with K >= 1, got ",
              neighbors.sizes());
  const at::Tensor p = products.contiguous(), n = neighbors.contiguous();
  const int64_t B = p.size(0), N_ = p.size(1), C_ = p.size(2) / 2, K_ = n.size(1);
  at::Tensor out = at::empty({B, N_, C_}, p.options());
  const float* v = p.data_ptr<float>();
  const int64_t* nbr = n.data_ptr<int64_t>();
  float* o = out.data_ptr<float>();
  const float slope = static_cast<float>(negative_slope);
  std::atomic<bool> out_of_range{false};
  at::parallel_for(0, B * N_, 64, [&](int64_t begin, int64_t end) {
    // Locals, not the captured references: stores through dst could alias those, which kept the loops
    // below scalar and branchy.
    const float negative = slope;
    const int64_t C = C_, N = N_, K = K_;
    for (int64_t bi = begin; bi < end; ++bi) {
      const int64_t b = bi / N, i = bi % N;
      const int64_t* row = nbr + i * K;
      const float* src = v + b * N * 2 * C;
      bool bad = false;
      for (int64_t k = 0; k < K; ++k) bad |= row[k] < 0 || row[k] >= N;
      if (bad) {
        out_of_range = true;
        continue;
      }
      float* __restrict dst = o + bi * C;
      const float* __restrict first = src + row[0] * 2 * C + C;
      for (int64_t c = 0; c < C; ++c) dst[c] = first[c];
      for (int64_t k = 1; k < K; ++k) {
        const float* __restrict x = src + row[k] * 2 * C + C;
        for (int64_t c = 0; c < C; ++c) dst[c] = std::max(dst[c], x[c]);
      }
      // max / min arithmetic, not a branch: the signs are random, and a mispredicted branch per channel cost
      // more than the whole gather. Exactly at::leaky_relu's values (one of the two terms is an exact zero).
      const float* __restrict a = src + i * 2 * C;
      for (int64_t c = 0; c < C; ++c) {
        const float y = a[c] + dst[c];
        dst[c] = std::max(y, 0.0f) + negative * std::min(y, 0.0f);
      }
    }
  });
  TORCH_CHECK(!out_of_range, "gather_max_add_leaky: neighbour indices must be in [0, ", N_, ")");
  return out;
}

at::Tensor gather_max_reference(const at::Tensor& values, const at::Tensor& neighbors) {
  const at::Tensor v = values.dim() == 2 ? values.unsqueeze(0) : values;
  check_inputs(v, neighbors);
  const int64_t N = neighbors.size(0), K = neighbors.size(1);
  const at::Tensor gathered = v.index_select(1, neighbors.reshape({-1})).view({v.size(0), N, K, v.size(2)});
  const at::Tensor out = gathered.amax(2);
  return values.dim() == 2 ? out.squeeze(0) : out;
}

}  // namespace amt
