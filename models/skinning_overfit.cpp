#include "models/skinning_overfit.h"

#include <ATen/ATen.h>
#include <torch/optim/adamw.h>
#include <torch/utils.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "data_tools/geometry/lbs_torch.h"
#include "models/losses.h"
#include "models/skinning_predictor.h"

namespace amt {
namespace {

// Rotation matrix (3, 3) of the axis-angle vector w (3): exp of its skew matrix.
at::Tensor rotation(const at::Tensor& w) {
  const at::Tensor zero = at::zeros({});
  const at::Tensor skew = at::stack({zero, -w[2], w[1], w[2], zero, -w[0], -w[1], w[0], zero}).view({3, 3});
  return at::linalg_matrix_exp(skew);
}

}  // namespace

SkinningOverfit overfit_skinning_on_a_bar(int steps, uint64_t seed) {
  torch::manual_seed(seed);
  const int64_t rows = 11, J = 3;
  std::vector<float> v, w;
  for (int64_t r = 0; r < rows; ++r) {
    for (const float x : {-0.05f, 0.05f}) {
      const float y = static_cast<float>(r) / (rows - 1);
      v.insert(v.end(), {x, y, 0.0f});
      w.insert(w.end(),
               {std::max(0.0f, 1 - y / 0.5f), 1 - std::abs(y - 0.5f) / 0.5f, std::max(0.0f, (y - 0.5f) / 0.5f)});
    }
  }
  const int64_t N = 2 * rows;
  const at::Tensor V = at::tensor(v).view({N, 3}), W_gt = at::tensor(w).view({N, J});
  const at::Tensor joints = at::tensor({0.0f, 0.0f, 0.0f, 0.0f, 0.5f, 0.0f, 0.0f, 1.0f, 0.0f}).view({J, 3});
  const at::Tensor G = (V.unsqueeze(1) - joints.unsqueeze(0)).norm(2, -1);

  // Frames of a two-link chain: joint 0 fixed, joints 1 and 2 turn by random rotations of about 1 rad.
  std::vector<at::Tensor> frames;
  for (int f = 0; f < 8; ++f) {
    const at::Tensor R1 = rotation(0.6 * at::randn({3})), R2 = at::matmul(R1, rotation(0.6 * at::randn({3})));
    const at::Tensor t1 = joints[1];
    const at::Tensor t2 = t1 + at::matmul(R1, joints[2] - joints[1]);
    frames.push_back(at::stack({at::cat({at::eye(3), joints[0].view({3, 1})}, 1), at::cat({R1, t1.view({3, 1})}, 1),
                                at::cat({R2, t2.view({3, 1})}, 1)}));
  }
  const at::Tensor transforms = at::stack(frames);  // (T, J, 3, 4)
  const at::Tensor target = linear_blend_skinning(V, W_gt, transforms, joints);

  SkinningPredictorOptions options;
  options.num_joints = J;
  options.feature_widths = {32, 32};
  options.attention_widths = {8};
  options.head_encoder_widths = {32, 64};
  options.head_decoder_widths = {32};
  SkinningPredictor net(options);
  torch::optim::AdamW optimizer(net->parameters(), torch::optim::AdamWOptions(2e-3).weight_decay(0.0));
  const auto loss_of = [&] {
    return vertex_l1_loss(linear_blend_skinning(V, net->forward(V, joints, G), transforms, joints), target);  // eq. (8)
  };
  SkinningOverfit result;
  result.steps = steps;
  result.initial_loss = loss_of().item<double>();
  for (int step = 0; step < steps; ++step) {
    optimizer.zero_grad();
    const at::Tensor loss = loss_of();
    loss.backward();
    optimizer.step();
  }
  result.final_loss = loss_of().item<double>();
  return result;
}

}  // namespace amt
