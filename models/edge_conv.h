#pragma once
// Edge convolution [31] over a fixed mesh graph (paper eq. 13), as one affine edge layer followed
// by a LeakyReLU (DGCNN's block):
//   H'_i = max_{j in N(i)} sigma(W [H_i, H_j - H_i] + b).
// Factorised (docs/runtime.md, "What makes it fast"): with W = [W1 | W2], W [h_i, h_j - h_i] + b = (W1 - W2) h_i + b
// + W2 h_j, so both terms are per-vertex matrix products; and since sigma is monotonic,
// max_j sigma(a_i + b_j) = sigma(a_i + max_j b_j), a per-vertex product plus one neighbour max.
// Channels that are the same for every vertex (a global code broadcast to all of them) cancel in
// h_j - h_i: with h = [v, c] and W1 = [W1v | W1c], W2 = [W2v | W2c], the block is
// sigma((W1v - W2v) v_i + max_j W2v v_j + W1c c + b), where W1c c + b is one vector per frame
// (forward_with_constant).
#include <torch/nn/module.h>
#include <torch/nn/modules/linear.h>
#include <torch/nn/pimpl.h>

#include <cstdint>

namespace amt {

// === Neighbour tables

/// The neighbour table of a graph of `num_vertices` vertices with undirected edges (E, 2) int64:
/// (N, K_max) int64 where row i is i itself followed by its neighbours (ascending), padded by
/// repeating i. The self term belongs to N(i) in eq. 13 (the edge (i, i) contributes
/// sigma(W1 h_i + b)), so padding with i is exact for the max. K_max = 1 + the largest degree.
/// Duplicate edges and self-loops in `edges` are ignored. Isolated vertices get the row [i].
at::Tensor neighbor_table(int64_t num_vertices, const at::Tensor& edges);

/// Edges (E, 2) int64 of the subgraph induced by the vertices `vertex_ids` (M) int64 (for example
/// the apparel vertices): keeps the edges with both ends selected and renumbers their ends to
/// positions in `vertex_ids`. `num_vertices` is the size of the full graph.
at::Tensor induced_edges(int64_t num_vertices, const at::Tensor& edges, const at::Tensor& vertex_ids);

/// The unique edges (E, 2) int64 (i < j, rows in ascending order) of triangles `faces` (F, 3).
at::Tensor mesh_edges(const at::Tensor& faces);

// === EdgeConv

/// Configuration of an EdgeConv block.
struct EdgeConvOptions {
  EdgeConvOptions(int64_t in, int64_t out) : in_channels(in), out_channels(out) {}
  /// Channels of H (per vertex, input).
  int64_t in_channels;
  /// Channels of H' (per vertex, output).
  int64_t out_channels;
  /// Slope of the LeakyReLU sigma (DGCNN uses 0.2). Any slope >= 0 keeps sigma monotonic.
  double negative_slope = 0.2;
  /// Evaluate per edge (reference) instead of the factorised per-vertex form. Same weights, same result.
  bool naive = false;
};

/// One EdgeConv block over a fixed neighbour table. Its edge layer is a Linear(2 C_in, C_out)
/// on [h_i, h_j - h_i], whichever form evaluates it.
class EdgeConvImpl : public torch::nn::Module {
 public:
  explicit EdgeConvImpl(EdgeConvOptions options);

  /// h (B, N, C_in) or (N, C_in); neighbors (N, K) int64 from neighbor_table -> (B, N, C_out) or (N, C_out).
  at::Tensor forward(const at::Tensor& h, const at::Tensor& neighbors);

  /// The factorised form: two per-vertex products and gather_max. Shapes as forward.
  at::Tensor forward_factorized(const at::Tensor& h, const at::Tensor& neighbors);

  /// The block on H = [h, c] whose last C_const channels c are the same for every vertex, without
  /// broadcasting c: the same result as forward(cat(h, c expanded to every vertex)) up to float
  /// rounding, and the same gradients (in h, c and the weights).
  ///   h         (B, N, C_in - C_const) or (N, C_in - C_const): the per-vertex channels
  ///   constant  (B, C_const), or (1, C_const) or (C_const) shared by the batch: C_const in [0, C_in)
  ///   neighbors (N, K) int64 from neighbor_table
  /// -> (B, N, C_out) or (N, C_out), batched like h. The naive form broadcasts c and runs forward_naive.
  at::Tensor forward_with_constant(const at::Tensor& h, const at::Tensor& constant, const at::Tensor& neighbors);

  /// The per-edge form: gathers [h_i, h_j - h_i] for every (i, k), applies the edge layer and
  /// sigma, then the max over k. Shapes as forward.
  at::Tensor forward_naive(const at::Tensor& h, const at::Tensor& neighbors);

  /// The edge layer: weight (C_out, 2 C_in) = [W1 | W2], bias (C_out).
  torch::nn::Linear edge{nullptr};

  EdgeConvOptions options;

 private:
  // Inference (no autograd) weights of the factorised form, [W1 - W2; W2] (2 C_out, C_in) and [bias; 0], kept
  // while the edge layer's tensors are the same ones at the same version (an optimizer step or a load
  // changes the version), so that run-time frames do not rebuild them.
  at::Tensor inference_weights_, inference_bias_;
  const void* cached_weight_ = nullptr;
  const void* cached_bias_ = nullptr;
  int64_t cached_weight_version_ = -1, cached_bias_version_ = -1;

  // Inference (no autograd): one product [Wa; W2] h + [shift; 0] (weights (2 C_out, C_h), bias (2 C_out)), then
  // the neighbour max, the sum and sigma in one pass (gather_max_add_leaky). h (B, N, C_h) or (N, C_h).
  at::Tensor inference_block(const at::Tensor& h, const at::Tensor& weights, const at::Tensor& bias,
                             const at::Tensor& neighbors) const;

  // sigma(h Wa^T + shift + max_j h_j W2^T): Wa (C_out, C_h), W2 (C_out, C_h), shift (C_out) or (B, C_out).
  at::Tensor factorized(const at::Tensor& h, const at::Tensor& Wa, const at::Tensor& W2, const at::Tensor& shift,
                        const at::Tensor& neighbors);
};
TORCH_MODULE(EdgeConv);

}  // namespace amt
