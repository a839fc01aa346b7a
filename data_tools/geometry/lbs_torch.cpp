#include "data_tools/geometry/lbs_torch.h"

#include <ATen/ATen.h>

namespace amt {

at::Tensor skinning_matrices(const at::Tensor& joint_transforms, const at::Tensor& rest_joints) {
  TORCH_CHECK(joint_transforms.dim() == 4 && joint_transforms.size(2) == 3 && joint_transforms.size(3) == 4,
              "skinning_matrices: joint_transforms must be (T, J, 3, 4), got ", joint_transforms.sizes());
  TORCH_CHECK(rest_joints.dim() == 2 && rest_joints.size(0) == joint_transforms.size(1) && rest_joints.size(1) == 3,
              "skinning_matrices: rest_joints must be (J, 3) with J = ", joint_transforms.size(1), ", got ",
              rest_joints.sizes());
  const at::Tensor R = joint_transforms.narrow(3, 0, 3);                         // (T, J, 3, 3)
  const at::Tensor t = joint_transforms.select(3, 3);                            // (T, J, 3)
  const at::Tensor b = t - at::matmul(R, rest_joints.unsqueeze(-1)).squeeze(-1);  // (T, J, 3)
  return at::cat({R, b.unsqueeze(-1)}, 3);
}

at::Tensor linear_blend_skinning(const at::Tensor& V_rest, const at::Tensor& W, const at::Tensor& joint_transforms,
                                 const at::Tensor& rest_joints) {
  TORCH_CHECK(V_rest.dim() == 2 && V_rest.size(1) == 3, "linear_blend_skinning: V_rest must be (N, 3), got ",
              V_rest.sizes());
  TORCH_CHECK(W.dim() == 2 && W.size(0) == V_rest.size(0) && W.size(1) == joint_transforms.size(1),
              "linear_blend_skinning: W must be (N, J) = (", V_rest.size(0), ", ", joint_transforms.size(1), "), got ",
              W.sizes());
  const int64_t T = joint_transforms.size(0), J = joint_transforms.size(1), N = V_rest.size(0);
  const at::Tensor M = skinning_matrices(joint_transforms, rest_joints).reshape({T, J, 12});
  const at::Tensor blended = at::matmul(W, M).reshape({T, N, 3, 4});  // (N,J) x (T,J,12) -> (T,N,12)
  const at::Tensor A = blended.narrow(3, 0, 3);                       // (T, N, 3, 3)
  const at::Tensor b = blended.select(3, 3);                          // (T, N, 3)
  return at::matmul(A, V_rest.unsqueeze(-1)).squeeze(-1) + b;         // (T,N,3,3) x (N,3,1)
}

}  // namespace amt
