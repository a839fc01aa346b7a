// Linear blend skinning of a 2-bone bar against positions worked out by hand, and the sparse/dense
// weight conversions.
#include "data_tools/geometry/lbs.h"

#include <gtest/gtest.h>

#include <random>

#include "data_tools/geometry/motion.h"

namespace amt {
namespace {

// A bar along +X: joint 0 at the origin, joint 1 at (1,0,0). Five vertices at x = 0, 0.5, 1, 1.5, 2.
struct Bar {
  Skeleton skeleton;
  MatrixX3f V;
  MatrixXfR W;
};

Bar two_bone_bar() {
  Bar bar;
  bar.skeleton.names = {"upper", "lower"};
  bar.skeleton.parents = {-1, 0};
  bar.skeleton.rest_joints.resize(2, 3);
  bar.skeleton.rest_joints << 0, 0, 0, 1, 0, 0;
  bar.V.resize(5, 3);
  bar.V << 0, 0, 0, 0.5, 0, 0, 1, 0, 0, 1.5, 0, 0, 2, 0, 0;
  bar.W.resize(5, 2);
  bar.W << 1, 0, 1, 0, 0.5, 0.5, 0.5, 0.5, 0, 1;
  return bar;
}

TEST(LinearBlendSkinning, TwoBoneBarByHand) {
  const Bar bar = two_bone_bar();
  Motion m = rest_motion(bar.skeleton, 1);
  // The lower bone bends 90 degrees about +Z: points past the elbow turn from +X to +Y.
  m.rotation(0, 1) = Eigen::Quaternionf(Eigen::AngleAxisf(float(M_PI) / 2, Eigen::Vector3f::UnitZ()));
  const Transforms M = skinning_matrices(bar.skeleton, forward_kinematics(bar.skeleton, m, 0));

  MatrixX3f expected(5, 3);
  expected << 0, 0, 0,     // upper bone only
      0.5, 0, 0,           // upper bone only
      1, 0, 0,             // the elbow itself: both bones agree
      1.25, 0.25, 0,       // halfway: 0.5 (1.5,0,0) + 0.5 (1,0.5,0)
      1, 1, 0;             // lower bone only: R (x - J1) + t1 = (0,1,0) + (1,0,0)

  MatrixX3f dense_out, sparse_out;
  linear_blend_skinning(bar.V, bar.W, M, dense_out);
  linear_blend_skinning(bar.V, sparsify_weights(bar.W), M, sparse_out);
  EXPECT_TRUE(dense_out.isApprox(expected, 1e-6f)) << dense_out;
  EXPECT_LT((sparse_out - expected).cwiseAbs().maxCoeff(), 1e-6f) << sparse_out;
}

TEST(LinearBlendSkinning, SparsifyKeepsFourLargestAndRenormalises) {
  MatrixXfR W(2, 6);
  W << 0.05f, 0.4f, 0.3f, 0.15f, 0.1f, 0.0f,  // drops 0.05 and 0: the kept four sum to 0.95
      0, 0, 0, 0, 0, 0;                       // no influence binds to joint 0
  const SparseWeights s = sparsify_weights(W);
  EXPECT_EQ(s.indices(0, 0), 1);
  EXPECT_EQ(s.indices(0, 1), 2);
  EXPECT_EQ(s.indices(0, 2), 3);
  EXPECT_EQ(s.indices(0, 3), 4);
  EXPECT_NEAR(s.weights(0, 0), 0.4f / 0.95f, 1e-6f);
  EXPECT_NEAR(s.weights.row(0).sum(), 1.0f, 1e-6f);
  EXPECT_EQ(s.indices(1, 0), 0);
  EXPECT_EQ(s.weights(1, 0), 1.0f);
  const MatrixXfR back = densify_weights(s, 6);
  EXPECT_NEAR(back(0, 1), 0.4f / 0.95f, 1e-6f);
  EXPECT_EQ(back(0, 0), 0.0f);
  EXPECT_EQ(back(1, 0), 1.0f);
}

TEST(LinearBlendSkinning, SparseEqualsDenseOnRandomFourInfluenceWeights) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1, 1);
  const Skeleton s = canonical_skeleton();
  Motion m = rest_motion(s, 1);
  for (int j = 0; j < s.num_joints(); ++j) {
    m.rotation(0, j) = Eigen::Quaternionf(1, 0.3f * u(rng), 0.3f * u(rng), 0.3f * u(rng)).normalized();
  }
  const Transforms M = skinning_matrices(s, forward_kinematics(s, m, 0));
  const int N = 200;
  MatrixX3f V(N, 3);
  MatrixXfR W = MatrixXfR::Zero(N, s.num_joints());
  for (int i = 0; i < N; ++i) {
    V.row(i) << u(rng), u(rng) + 1, u(rng);
    for (int k = 0; k < 4; ++k) W(i, (i * 5 + k * 3) % s.num_joints()) = 0.1f + std::abs(u(rng));
    W.row(i) /= W.row(i).sum();
  }
  MatrixX3f a, b;
  linear_blend_skinning(V, W, M, a);
  linear_blend_skinning(V, sparsify_weights(W), M, b);
  EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 1e-5f);
}

}  // namespace
}  // namespace amt
