#include "models/edge_conv.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <vector>

#include "models/gather_max.h"

namespace amt {

at::Tensor neighbor_table(int64_t num_vertices, const at::Tensor& edges) {
  TORCH_CHECK(num_vertices >= 0, "neighbor_table: num_vertices must be non-negative");
  TORCH_CHECK(edges.dim() == 2 && edges.size(1) == 2, "neighbor_table: edges must be (E, 2), got ", edges.sizes());
  const at::Tensor e = edges.to(at::kLong).contiguous();
  const int64_t* ep = e.data_ptr<int64_t>();
  std::vector<std::vector<int64_t>> adjacency(static_cast<size_t>(num_vertices));
  for (int64_t k = 0; k < e.size(0); ++k) {
    const int64_t a = ep[2 * k], b = ep[2 * k + 1];
    TORCH_CHECK(a >= 0 && a < num_vertices && b >= 0 && b < num_vertices, "neighbor_table: edge ", k, " = (", a,
                ", ", b, ") is outside [0, ", num_vertices, ")");
    if (a == b) continue;
    adjacency[a].push_back(b);
    adjacency[b].push_back(a);
  }
  size_t width = 1;
  for (auto& row : adjacency) {
    std::sort(row.begin(), row.end());
    row.erase(std::unique(row.begin(), row.end()), row.end());
    width = std::max(width, row.size() + 1);
  }
  at::Tensor table = at::empty({num_vertices, static_cast<int64_t>(width)}, at::kLong);
  int64_t* t = table.data_ptr<int64_t>();
  for (int64_t i = 0; i < num_vertices; ++i) {
    int64_t* row = t + i * static_cast<int64_t>(width);
    std::fill(row, row + width, i);  // self first, and self as padding
    std::copy(adjacency[i].begin(), adjacency[i].end(), row + 1);
  }
  return table;
}

at::Tensor induced_edges(int64_t num_vertices, const at::Tensor& edges, const at::Tensor& vertex_ids) {
  TORCH_CHECK(edges.dim() == 2 && edges.size(1) == 2, "induced_edges: edges must be (E, 2), got ", edges.sizes());
  TORCH_CHECK(vertex_ids.dim() == 1, "induced_edges: vertex_ids must be (M), got ", vertex_ids.sizes());
  const at::Tensor ids = vertex_ids.to(at::kLong);
  at::Tensor position = at::full({num_vertices}, -1, at::kLong);
  position.index_put_({ids}, at::arange(ids.size(0), at::kLong));
  const at::Tensor mapped = position.index_select(0, edges.to(at::kLong).reshape({-1})).view({-1, 2});
  const at::Tensor keep = (mapped >= 0).all(1);
  return mapped.index({keep}).contiguous();
}

at::Tensor mesh_edges(const at::Tensor& faces) {
  TORCH_CHECK(faces.dim() == 2 && faces.size(1) == 3, "mesh_edges: faces must be (F, 3), got ", faces.sizes());
  if (faces.size(0) == 0) return at::zeros({0, 2}, at::kLong);
  const at::Tensor f = faces.to(at::kLong);
  const at::Tensor pairs = at::cat({f.index_select(1, at::tensor({0, 1}, at::kLong)),
                                    f.index_select(1, at::tensor({1, 2}, at::kLong)),
                                    f.index_select(1, at::tensor({2, 0}, at::kLong))},
                                   0);
  const at::Tensor ordered = at::stack({std::get<0>(pairs.min(1)), std::get<0>(pairs.max(1))}, 1);
  return std::get<0>(at::unique_dim(ordered, 0, /*sorted=*/true)).contiguous();
}

EdgeConvImpl::EdgeConvImpl(EdgeConvOptions options_) : options(options_) {
  TORCH_CHECK(options.in_channels > 0 && options.out_channels > 0, "EdgeConv: channels must be positive");
  TORCH_CHECK(options.negative_slope >= 0, "EdgeConv: negative_slope must be >= 0 to keep sigma monotonic");
  edge = register_module("edge", torch::nn::Linear(2 * options.in_channels, options.out_channels));
}

at::Tensor EdgeConvImpl::forward(const at::Tensor& h, const at::Tensor& neighbors) {
  return options.naive ? forward_naive(h, neighbors) : forward_factorized(h, neighbors);
}

at::Tensor EdgeConvImpl::forward_factorized(const at::Tensor& h, const at::Tensor& neighbors) {
  TORCH_CHECK(h.size(-1) == options.in_channels, "EdgeConv: h must have ", options.in_channels, " channels, got ",
              h.sizes());
  const int64_t C = options.in_channels;
  if (!at::GradMode::is_enabled() && h.scalar_type() == at::kFloat) {
    const at::Tensor& w = edge->weight;
    const at::Tensor& b = edge->bias;
    if (!inference_weights_.defined() || cached_weight_ != w.data_ptr() || cached_bias_ != b.data_ptr() ||
        cached_weight_version_ != int64_t(w._version()) || cached_bias_version_ != int64_t(b._version())) {
      const at::Tensor W1 = w.narrow(1, 0, C), W2 = w.narrow(1, C, C);
      inference_weights_ = at::cat({W1 - W2, W2}, 0).contiguous();
      inference_bias_ = at::cat({b, at::zeros_like(b)}, 0).contiguous();
      cached_weight_ = w.data_ptr(), cached_bias_ = b.data_ptr();
      cached_weight_version_ = int64_t(w._version()), cached_bias_version_ = int64_t(b._version());
    }
    return inference_block(h, inference_weights_, inference_bias_, neighbors);
  }
  const at::Tensor W1 = edge->weight.narrow(1, 0, C), W2 = edge->weight.narrow(1, C, C);  // (O, C) each
  return factorized(h, W1 - W2, W2, edge->bias, neighbors);
}

at::Tensor EdgeConvImpl::forward_with_constant(const at::Tensor& h, const at::Tensor& constant,
                                               const at::Tensor& neighbors) {
  TORCH_CHECK(h.dim() == 2 || h.dim() == 3, "EdgeConv: h must be (N, C) or (B, N, C), got ", h.sizes());
  const at::Tensor c = constant.dim() == 1 ? constant.unsqueeze(0) : constant;  // (B or 1, C_const)
  const int64_t C = options.in_channels, C_h = h.size(-1), B = h.dim() == 3 ? h.size(0) : 1;
  TORCH_CHECK(c.dim() == 2 && C_h > 0 && C_h + c.size(1) == C && (c.size(0) == B || c.size(0) == 1),
              "EdgeConv: h ", h.sizes(), " and constant ", constant.sizes(), " must have ", C,
              " channels together, h at least one, and constant one row or one per batch");
  if (options.naive) {  // the reference: broadcast the constant channels to every vertex
    const at::Tensor x = h.dim() == 3 ? h : h.unsqueeze(0);
    const at::Tensor full = at::cat({x, c.unsqueeze(1).expand({B, x.size(1), c.size(1)})}, 2);
    const at::Tensor out = forward_naive(full, neighbors);
    return h.dim() == 3 ? out : out.squeeze(0);
  }
  // W [h_i, h_j - h_i] + b with h = [v, c]: the c channels of h_j - h_i vanish, W1c c + b is per frame.
  const at::Tensor W1 = edge->weight.narrow(1, 0, C), W2 = edge->weight.narrow(1, C, C);  // (O, C) each
  const at::Tensor W2v = W2.narrow(1, 0, C_h);
  const at::Tensor shift = at::linear(c, W1.narrow(1, C_h, C - C_h), edge->bias);  // (B or 1, O)
  return factorized(h, W1.narrow(1, 0, C_h) - W2v, W2v, shift.size(0) == 1 ? shift.squeeze(0) : shift, neighbors);
}

at::Tensor EdgeConvImpl::factorized(const at::Tensor& h, const at::Tensor& Wa, const at::Tensor& W2,
                                    const at::Tensor& shift, const at::Tensor& neighbors) {
  if (!at::GradMode::is_enabled() && shift.dim() == 1 && h.scalar_type() == at::kFloat)
    return inference_block(h, at::cat({Wa, W2}, 0), at::cat({shift, at::zeros_like(shift)}, 0), neighbors);
  // (..., N, O): Wa h_i + shift, the shift as the product's bias when it is one vector, else one row per batch.
  at::Tensor a = shift.dim() == 1 ? at::linear(h, Wa, shift) : at::linear(h, Wa) + shift.unsqueeze(-2);
  const at::Tensor b = at::linear(h, W2);                                       // (..., N, O): W2 h_j, gathered below
  return at::leaky_relu(a + gather_max(b, neighbors), options.negative_slope);  // eq. (13)
}

at::Tensor EdgeConvImpl::inference_block(const at::Tensor& h, const at::Tensor& weights, const at::Tensor& bias,
                                         const at::Tensor& neighbors) const {
  const at::Tensor x = h.dim() == 2 ? h.unsqueeze(0) : h;
  const at::Tensor out = gather_max_add_leaky(at::linear(x, weights, bias), neighbors, options.negative_slope);
  return h.dim() == 2 ? out.squeeze(0) : out;
}

at::Tensor EdgeConvImpl::forward_naive(const at::Tensor& h, const at::Tensor& neighbors) {
  TORCH_CHECK(h.size(-1) == options.in_channels, "EdgeConv: h must have ", options.in_channels, " channels, got ",
              h.sizes());
  const at::Tensor x = h.dim() == 2 ? h.unsqueeze(0) : h;  // (B, N, C)
  const int64_t B = x.size(0), N = neighbors.size(0), K = neighbors.size(1), C = x.size(2);
  const at::Tensor hj = x.index_select(1, neighbors.reshape({-1})).view({B, N, K, C});
  const at::Tensor hi = x.unsqueeze(2).expand({B, N, K, C});
  const at::Tensor e = at::leaky_relu(edge->forward(at::cat({hi, hj - hi}, -1)), options.negative_slope);
  const at::Tensor out = e.amax(2);  // eq. (13): max over j in N(i)
  return h.dim() == 2 ? out.squeeze(0) : out;
}

}  // namespace amt
