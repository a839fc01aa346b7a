#include "data_tools/geometry/lbs.h"

#include <algorithm>
#include <array>
#include <numeric>

namespace amt {

SparseWeights sparsify_weights(const MatrixXfR& W) {
  const Eigen::Index N = W.rows(), J = W.cols();
  SparseWeights out;
  out.indices.setZero(N, kMaxInfluences);
  out.weights.setZero(N, kMaxInfluences);
  std::vector<int> order(static_cast<size_t>(J));
  for (Eigen::Index i = 0; i < N; ++i) {
    std::iota(order.begin(), order.end(), 0);
    const int k = static_cast<int>(std::min<Eigen::Index>(kMaxInfluences, J));
    std::partial_sort(order.begin(), order.begin() + k, order.end(),
                      [&](int a, int b) { return W(i, a) > W(i, b) || (W(i, a) == W(i, b) && a < b); });
    float sum = 0;
    for (int s = 0; s < k; ++s) sum += std::max(0.0f, W(i, order[s]));
    if (sum <= 0) {
      out.weights(i, 0) = 1.0f;  // indices already 0
      continue;
    }
    for (int s = 0; s < k; ++s) {
      out.indices(i, s) = order[s];
      out.weights(i, s) = std::max(0.0f, W(i, order[s])) / sum;
    }
  }
  return out;
}

MatrixXfR densify_weights(const SparseWeights& w, int num_joints) {
  MatrixXfR W = MatrixXfR::Zero(w.num_vertices(), num_joints);
  for (int i = 0; i < w.num_vertices(); ++i) {
    for (int s = 0; s < kMaxInfluences; ++s) W(i, w.indices(i, s)) += w.weights(i, s);
  }
  return W;
}

void linear_blend_skinning(const MatrixX3f& V_rest, const SparseWeights& w, const Transforms& M, MatrixX3f& out) {
  const Eigen::Index N = V_rest.rows();
  out.resize(N, 3);
#pragma omp parallel for schedule(static)
  for (Eigen::Index i = 0; i < N; ++i) {
    // Blend the four 3x4 matrices, then apply once: 4 * 12 + 12 multiply-adds per vertex.
    Transform34 B = w.weights(i, 0) * M[w.indices(i, 0)];
    for (int s = 1; s < kMaxInfluences; ++s) B += w.weights(i, s) * M[w.indices(i, s)];
    out.row(i) = (B.leftCols<3>() * V_rest.row(i).transpose() + B.col(3)).transpose();
  }
}

void linear_blend_skinning(const MatrixX3f& V_rest, const MatrixXfR& W, const Transforms& M, MatrixX3f& out) {
  const Eigen::Index N = V_rest.rows(), J = W.cols();
  out.resize(N, 3);
#pragma omp parallel for schedule(static)
  for (Eigen::Index i = 0; i < N; ++i) {
    Transform34 B = Transform34::Zero();
    for (Eigen::Index j = 0; j < J; ++j) {
      if (W(i, j) != 0.0f) B += W(i, j) * M[static_cast<size_t>(j)];
    }
    out.row(i) = (B.leftCols<3>() * V_rest.row(i).transpose() + B.col(3)).transpose();
  }
}

}  // namespace amt
