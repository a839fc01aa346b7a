#pragma once
// Linear blend skinning as a differentiable, frame-batched LibTorch operation, for training
// (paper eq. 4). The CPU runtime uses data_tools/geometry/lbs.h; both compute the same thing.
#include <ATen/core/Tensor.h>

namespace amt {

/// Skins rest vertices through every frame of a motion:
///   V_rest           (N, 3) rest positions
///   W                (N, J) skinning weights (rows sum to 1; not checked, so partial sums work)
///   joint_transforms (T, J, 3, 4) [R_j | t_j] per frame (the dataset's joint_transforms)
///   rest_joints      (J, 3) rest joint positions J_j
/// returns            (T, N, 3) with v = sum_j W_ij (R_j (v_rest - J_j) + t_j).
/// Differentiable in every input. Memory is O(T N 12): weights blend the 12 matrix entries first.
at::Tensor linear_blend_skinning(const at::Tensor& V_rest, const at::Tensor& W, const at::Tensor& joint_transforms,
                                 const at::Tensor& rest_joints);

/// Converts joint transforms to skinning matrices [R_j | t_j - R_j J_j]:
///   joint_transforms (T, J, 3, 4), rest_joints (J, 3) -> (T, J, 3, 4).
at::Tensor skinning_matrices(const at::Tensor& joint_transforms, const at::Tensor& rest_joints);

}  // namespace amt
