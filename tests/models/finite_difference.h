#pragma once
// Central finite differences of a scalar function of one tensor, for gradient checks in the
// models tests (double precision).
#include <ATen/ATen.h>
#include <torch/csrc/autograd/autograd.h>

#include <functional>

namespace amt::test {

/// d f / d x by central differences: x any shape, double; f returns a 0-dim tensor.
inline at::Tensor numeric_gradient(const std::function<at::Tensor(const at::Tensor&)>& f, const at::Tensor& x,
                                   double eps = 1e-6) {
  at::NoGradGuard no_grad;
  at::Tensor base = x.detach().clone().contiguous();
  at::Tensor grad = at::zeros_like(base);
  double* p = base.data_ptr<double>();
  double* g = grad.data_ptr<double>();
  for (int64_t k = 0; k < base.numel(); ++k) {
    const double keep = p[k];
    p[k] = keep + eps;
    const double up = f(base).item<double>();
    p[k] = keep - eps;
    const double down = f(base).item<double>();
    p[k] = keep;
    g[k] = (up - down) / (2 * eps);
  }
  return grad;
}

/// d f / d x by autograd.
inline at::Tensor analytic_gradient(const std::function<at::Tensor(const at::Tensor&)>& f, const at::Tensor& x) {
  const at::Tensor leaf = x.detach().clone().requires_grad_();
  return torch::autograd::grad({f(leaf)}, {leaf})[0];
}

/// Largest absolute difference between the autograd and finite-difference gradients.
inline double max_gradient_error(const std::function<at::Tensor(const at::Tensor&)>& f, const at::Tensor& x,
                                 double eps = 1e-6) {
  return (analytic_gradient(f, x) - numeric_gradient(f, x, eps)).abs().max().item<double>();
}

}  // namespace amt::test
