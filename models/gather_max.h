#pragma once
// The neighbour max of graph convolutions: out[b, i, c] = max_k values[b, neighbors[i, k], c].
// A plain C++ loop (parallel over vertices) with a custom autograd backward that routes each
// output's gradient to the row that won the max. Measured when it was written: PyTorch's eager gather + max
// over a (6000, 7, 128) neighbourhood takes ~19 ms, this loop a few ms.
#include <ATen/core/Tensor.h>

namespace amt {

/// values    (B, N_src, C) or (N_src, C) float or double
/// neighbors (N, K) int64, entries in [0, N_src), K >= 1; pad short rows by repeating an entry
/// returns   (B, N, C) or (N, C): the max over each row's neighbours, per channel.
/// Differentiable in values: the gradient of out[b, i, c] goes to values[b, argmax, c], where the
/// argmax is the first neighbour (in row order) attaining the max. NaNs are not propagated.
at::Tensor gather_max(const at::Tensor& values, const at::Tensor& neighbors);

/// The same by PyTorch ops (index_select + amax), the reference for tests and benchmarks.
/// Gradients of tied maxima are shared equally between the tied entries.
at::Tensor gather_max_reference(const at::Tensor& values, const at::Tensor& neighbors);

/// The inference form of a factorised EdgeConv block (no autograd), in one pass after its one product:
///   products  (B, N, 2 C) float: per vertex [a_i | b_i], a = the centre term with its bias, b = the neighbour term
///   neighbors (N, K) int64, entries in [0, N)
/// returns (B, N, C): LeakyReLU(a_i + max_k b_{neighbors[i, k]}) with the given negative slope. Throws c10::Error
/// for an index out of range.
at::Tensor gather_max_add_leaky(const at::Tensor& products, const at::Tensor& neighbors, double negative_slope);

}  // namespace amt
