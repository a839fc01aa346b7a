// The differentiable skinning equals the CPU runtime's and its gradients match finite differences.
#include "data_tools/geometry/lbs_torch.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/motion.h"

namespace amt {
namespace {

at::Tensor to_tensor(const Transforms& T, int frames, int joints) {
  at::Tensor out = at::empty({frames, joints, 3, 4}, at::kFloat);
  std::memcpy(out.data_ptr<float>(), T.data(), sizeof(float) * 12 * T.size());
  return out;
}

TEST(LinearBlendSkinningTorch, MatchesCpuSkinningOverFrames) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  const Skeleton s = canonical_skeleton();
  const int T = 3, J = s.num_joints(), N = 64;
  Motion m = rest_motion(s, T);
  for (int t = 0; t < T; ++t) {
    for (int j = 0; j < J; ++j) m.rotation(t, j) = Eigen::Quaternionf(1, 0.4f * u(rng), 0.4f * u(rng), 0.4f * u(rng)).normalized();
    m.root_translation.row(t) << u(rng), u(rng), u(rng);
  }
  const Transforms joint_transforms = forward_kinematics(s, m);
  MatrixX3f V(N, 3);
  MatrixXfR W(N, J);
  for (int i = 0; i < N; ++i) {
    V.row(i) << u(rng), u(rng) + 1, u(rng);
    for (int j = 0; j < J; ++j) W(i, j) = std::exp(3 * u(rng));
    W.row(i) /= W.row(i).sum();
  }
  const at::Tensor out = linear_blend_skinning(at::from_blob(V.data(), {N, 3}, at::kFloat),
                                               at::from_blob(W.data(), {N, J}, at::kFloat),
                                               to_tensor(joint_transforms, T, J),
                                               at::from_blob(const_cast<float*>(s.rest_joints.data()), {J, 3}, at::kFloat).clone());
  ASSERT_EQ(out.sizes(), (at::IntArrayRef{T, N, 3}));
  for (int t = 0; t < T; ++t) {
    const Transforms frame(joint_transforms.begin() + t * J, joint_transforms.begin() + (t + 1) * J);
    MatrixX3f expected;
    linear_blend_skinning(V, W, skinning_matrices(s, frame), expected);
    const at::Tensor got = out[t].contiguous();
    const Eigen::Map<const MatrixX3f> got_map(got.data_ptr<float>(), N, 3);
    EXPECT_LT((got_map - expected).cwiseAbs().maxCoeff(), 1e-5f) << "frame " << t;
  }
}

TEST(LinearBlendSkinningTorch, GradientsMatchFiniteDifferences) {
  at::manual_seed(11);
  const auto opts = at::TensorOptions().dtype(at::kDouble);
  const int64_t T = 2, J = 3, N = 5;
  const at::Tensor V = at::randn({N, 3}, opts).requires_grad_();
  const at::Tensor W = at::softmax(at::randn({N, J}, opts), 1).detach().requires_grad_();
  // Random rotations from normalised quaternions, random translations.
  const at::Tensor q = at::randn({T, J, 4}, opts);
  const at::Tensor qn = q / q.norm(2, -1, true);
  const at::Tensor w = qn.select(2, 0), x = qn.select(2, 1), y = qn.select(2, 2), z = qn.select(2, 3);
  const at::Tensor R = at::stack({1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
                                  2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                                  2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}, -1)
                           .reshape({T, J, 3, 3});
  const at::Tensor transforms = at::cat({R, at::randn({T, J, 3, 1}, opts)}, 3).detach().requires_grad_();
  const at::Tensor joints = at::randn({J, 3}, opts).requires_grad_();
  const at::Tensor probe = at::randn({T, N, 3}, opts);  // a random linear functional of the output

  auto loss = [&](const at::Tensor& v, const at::Tensor& wt, const at::Tensor& tr, const at::Tensor& jt) {
    return (linear_blend_skinning(v, wt, tr, jt) * probe).sum();
  };
  loss(V, W, transforms, joints).backward();
  const double eps = 1e-6;
  for (const at::Tensor* input : {&V, &W, &transforms, &joints}) {
    const at::Tensor analytic = input->grad().reshape(-1);
    at::Tensor flat = input->detach().clone().reshape(-1);
    for (int64_t k = 0; k < flat.numel(); k += 3) {
      at::Tensor plus = flat.clone(), minus = flat.clone();
      plus[k] += eps;
      minus[k] -= eps;
      auto eval = [&](const at::Tensor& f) {
        const at::Tensor shaped = f.reshape(input->sizes());
        return loss(input == &V ? shaped : V.detach(), input == &W ? shaped : W.detach(),
                    input == &transforms ? shaped : transforms.detach(), input == &joints ? shaped : joints.detach())
            .item<double>();
      };
      const double numeric = (eval(plus) - eval(minus)) / (2 * eps);
      EXPECT_NEAR(analytic[k].item<double>(), numeric, 1e-6 * (1 + std::abs(numeric)));
    }
  }
}

}  // namespace
}  // namespace amt
