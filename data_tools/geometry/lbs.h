#pragma once
// Linear blend skinning on the CPU (the runtime's form; the differentiable batched form for
// training is in data_tools/geometry/lbs_torch.h): v = sum_j W_ij M_j [v_rest; 1]  (paper eq. 4).
#include "data_tools/geometry/types.h"

namespace amt {

/// Maximum influences per vertex kept by the sparse form.
constexpr int kMaxInfluences = 4;

/// Sparse skinning weights, at most kMaxInfluences per vertex.
///   indices #V by 4 joint (or bone) indices; unused slots hold 0 with weight 0.
///   weights #V by 4, each row sums to 1.
struct SparseWeights {
  Eigen::Matrix<int32_t, Eigen::Dynamic, kMaxInfluences, Eigen::RowMajor> indices;
  Eigen::Matrix<float, Eigen::Dynamic, kMaxInfluences, Eigen::RowMajor> weights;

  int num_vertices() const { return static_cast<int>(indices.rows()); }
};

/// Keeps the kMaxInfluences largest weights of each row of W (#V by J, non-negative) and
/// renormalises them to sum to 1. A row of zeros binds to joint 0.
SparseWeights sparsify_weights(const MatrixXfR& W);

/// Dense #V by J weights of a sparse set.
MatrixXfR densify_weights(const SparseWeights& weights, int num_joints);

/// Skins rest positions V_rest (#V by 3) with skinning matrices M (one [A | b] per joint, see
/// skinning_matrices in data_tools/geometry/motion.h) into out (#V by 3, resized). Runs on the OpenMP threads.
void linear_blend_skinning(const MatrixX3f& V_rest, const SparseWeights& weights, const Transforms& M, MatrixX3f& out);

/// The same with dense weights W (#V by J); rows need not be sparse.
void linear_blend_skinning(const MatrixX3f& V_rest, const MatrixXfR& W, const Transforms& M, MatrixX3f& out);

}  // namespace amt
