// The local apparel module (models/apparel_dynamics.h): its input channels by value against an
// independent per-vertex computation, invariance to a rigid motion of the whole animation about the
// gravity axis (and not to a tilt, since gravity is an input), the fresh network as the hold_offset
// rule, the zero-network rules on a hand-computed example, the normaliser's statistics and freeze,
// the attachment distances on a hand-made mesh, and the inertia fit.
#include "models/apparel_dynamics.h"

#include "data_tools/geometry/error.h"
#include "models/edge_conv.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/utils.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

namespace amt {
namespace {

// A rotation (3, 3) about a unit axis.
at::Tensor rotation(Eigen::Vector3f axis, float angle) {
  const Eigen::Matrix3f R = Eigen::AngleAxisf(angle, axis.normalized()).toRotationMatrix();
  at::Tensor out = at::empty({3, 3}, at::kFloat);
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) out[a][b] = R(a, b);
  return out;
}

Eigen::Matrix3f matrix(const at::Tensor& R) {
  Eigen::Matrix3f M;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) M(a, b) = R[a][b].item<float>();
  return M;
}

Eigen::Vector3f vec(const at::Tensor& v) { return {v[0].item<float>(), v[1].item<float>(), v[2].item<float>()}; }

// (F, J, 3, 4) transforms with random proper rotations and positions.
at::Tensor random_transforms(int64_t F, int64_t J) {
  at::Tensor T = at::zeros({F, J, 3, 4}, at::kFloat);
  for (int64_t f = 0; f < F; ++f) {
    for (int64_t j = 0; j < J; ++j) {
      const at::Tensor axis = at::randn({3});
      T[f][j].narrow(1, 0, 3).copy_(rotation(vec(axis), 0.3f * at::randn({1}).item<float>() + 0.5f));
      T[f][j].select(1, 3).copy_(at::randn({3}));
    }
  }
  return T;
}

// A small apparel graph: a strip of N vertices (a chain), frame joints cycling over J.
ApparelGraph chain_graph(int64_t N, int64_t J) {
  std::vector<int64_t> e;
  for (int64_t i = 0; i + 1 < N; ++i) e.insert(e.end(), {i, i + 1});
  ApparelGraph g;
  g.neighbors = neighbor_table(N, at::tensor(e, at::kLong).view({-1, 2}));
  g.frame_joints = at::arange(N, at::kLong).remainder(J);
  g.rest_features = at::randn({N, kApparelRestChannels});
  g.contact_rest = at::randn({N, 3});
  g.contact_weights = at::softmax(at::randn({N, J}), 1);
  // The strip hangs from vertex 0: vertex i's ancestor 2^l hops up is max(i - 2^l, 0).
  g.ancestors = at::empty({N, kApparelReachLevels}, at::kLong);
  for (int64_t i = 0; i < N; ++i)
    for (int64_t l = 0; l < kApparelReachLevels; ++l) g.ancestors[i][l] = std::max<int64_t>(i - (int64_t(1) << l), 0);
  return g;
}

// A network whose every layer matters (random last layer) and whose normalisers hold statistics.
ApparelDynamicsNet lively_network(int64_t J, const ApparelGraph& g) {
  ApparelDynamicsOptions o;
  o.num_joints = J;
  o.edge_widths = {16, 16};
  o.decoder_widths = {16};
  o.inertia = 0.5;
  ApparelDynamicsNet net(o);
  const int64_t N = g.frame_joints.size(0);
  for (int k = 0; k < 4; ++k)
    net->observe(at::randn({3, N, 3}), random_transforms(4, J), at::randn({4, N, 3}), g, at::randn({N, 3}));
  net->freeze_normalizers();
  torch::NoGradGuard no_grad;
  for (auto& p : net->parameters()) p.copy_(0.3 * at::randn(p.sizes()));
  return net;
}

TEST(ApparelDynamics, FeaturesMatchAnIndependentPerVertexComputation) {
  torch::manual_seed(3);
  const int64_t N = 5, J = 3;
  const ApparelGraph g = chain_graph(N, J);
  const at::Tensor T = random_transforms(4, J), A = at::randn({3, N, 3}), S = at::randn({4, N, 3});
  ApparelDynamicsNet net(ApparelDynamicsOptions{"local", J});
  const at::Tensor H = net->features(A.unsqueeze(0), T.unsqueeze(0), S.unsqueeze(0), g).squeeze(0);
  ASSERT_EQ(H.size(1), ApparelDynamicsNetImpl::kChannels + ApparelDynamicsNetImpl::kContactChannels);
  for (int64_t i = 0; i < N; ++i) {
    const int64_t j = g.frame_joints[i].item<int64_t>();
    Eigen::Matrix3f R[4];
    for (int k = 0; k < 4; ++k) R[k] = matrix(T[k][j].narrow(1, 0, 3));
    const auto a = [&](int k) { return vec(A[k][i]); };
    const auto s = [&](int k) { return vec(S[k][i]); };
    Eigen::Vector3f d[3];
    for (int k = 0; k < 3; ++k) d[k] = R[k].transpose() * (a(k) - s(k));
    const auto skew = [](const Eigen::Matrix3f& M) -> Eigen::Vector3f {
      return Eigen::Vector3f(M(2, 1) - M(1, 2), M(0, 2) - M(2, 0), M(1, 0) - M(0, 1)) / 2;
    };
    const std::vector<Eigen::Vector3f> expected = {d[2],
                                                   d[2] - d[1],
                                                   d[1] - d[0],
                                                   R[2].transpose() * (s(3) - s(2)),
                                                   R[2].transpose() * (s(2) - s(1)),
                                                   R[2].transpose() * (s(1) - s(0)),
                                                   R[2].transpose() * (a(2) - a(1)),
                                                   skew(R[2].transpose() * R[3]),
                                                   skew(R[1].transpose() * R[2]),
                                                   R[3].transpose() * Eigen::Vector3f(0, -1, 0)};
    for (size_t c = 0; c < expected.size(); ++c)
      for (int x = 0; x < 3; ++x)
        EXPECT_NEAR(H[i][3 * c + x].item<float>(), expected[c](x), 1e-5) << "vertex " << i << " group " << c;
    for (int64_t x = 0; x < kApparelRestChannels; ++x)
      EXPECT_EQ(H[i][30 + x].item<float>(), g.rest_features[i][x].item<float>());
    // The contact point: the rest point skinned by hand, sum_j w_j (R_j p + t_j), at t-1 and t.
    const auto contact = [&](int k) {
      Eigen::Vector3f P = Eigen::Vector3f::Zero();
      for (int64_t b = 0; b < J; ++b) {
        P += g.contact_weights[i][b].item<float>() *
             (matrix(T[k][b].narrow(1, 0, 3)) * vec(g.contact_rest[i]) + vec(T[k][b].select(1, 3)));
      }
      return P;
    };
    const Eigen::Vector3f to_contact = R[2].transpose() * (contact(3) - a(2));
    const Eigen::Vector3f contact_move = R[2].transpose() * (contact(3) - contact(2));
    for (int x = 0; x < 3; ++x) {
      EXPECT_NEAR(H[i][37 + x].item<float>(), to_contact(x), 1e-5) << "vertex " << i;
      EXPECT_NEAR(H[i][40 + x].item<float>(), contact_move(x), 1e-5) << "vertex " << i;
    }
  }
}

// Inference (no autograd) computes the features and the output in fused per-vertex loops: the same
// prediction and detail vectors as the tensor path, to float rounding, batched, with and without the
// contact inputs, over enough vertices for several parallel chunks.
TEST(ApparelDynamics, FusedInferencePathEqualsTheTensorPath) {
  torch::manual_seed(11);
  const int64_t N = 700, J = 5, B = 2;
  for (const bool contact : {true, false}) {
    const ApparelGraph g = chain_graph(N, J);
    ApparelDynamicsNet net = lively_network(J, g);
    if (!contact) {
      ApparelDynamicsOptions o = net->options;
      o.contact = false;
      net = ApparelDynamicsNet(o);
      torch::NoGradGuard no_grad;
      for (auto& p : net->parameters()) p.copy_(0.3 * at::randn(p.sizes()));
    }
    const at::Tensor T = at::stack({random_transforms(4, J), random_transforms(4, J)});
    const at::Tensor A = 0.1 * at::randn({B, 3, N, 3}), S = 0.1 * at::randn({B, 4, N, 3});
    at::Tensor d_tensor, d_fused;
    const at::Tensor tensor_path = net->step(A, T, S, g, &d_tensor).detach();
    at::Tensor fused_path;
    {
      c10::InferenceMode inference;
      fused_path = net->step(A, T, S, g, &d_fused);
    }
    ASSERT_EQ(fused_path.sizes(), tensor_path.sizes());
    EXPECT_TRUE(at::allclose(fused_path, tensor_path, 1e-5, 1e-5))
        << "contact " << contact << ": max difference " << (fused_path - tensor_path).abs().max().item<float>();
    EXPECT_TRUE(at::allclose(d_fused, d_tensor.detach(), 1e-5, 1e-5)) << "contact " << contact;
    // The network's correction is far from zero here, so every feature feeds the comparison.
    const at::Tensor rule = detail_rule_step(A, T, S, g.frame_joints, net->options.inertia);
    EXPECT_GT((tensor_path - rule).abs().max().item<float>(), 1e-2) << "contact " << contact;
  }
}

TEST(ApparelDynamics, WithoutContactTheFeaturesAreTheFirstChannels) {
  torch::manual_seed(6);
  const int64_t N = 4, J = 2;
  ApparelGraph g = chain_graph(N, J);
  const at::Tensor T = random_transforms(4, J).unsqueeze(0), A = at::randn({1, 3, N, 3}), S = at::randn({1, 4, N, 3});
  ApparelDynamicsOptions o{"local", J};
  const at::Tensor with = ApparelDynamicsNet(o)->features(A, T, S, g);
  o.contact = false;
  const at::Tensor without = ApparelDynamicsNet(o)->features(A, T, S, g);
  ASSERT_EQ(without.size(2), ApparelDynamicsNetImpl::kChannels);
  EXPECT_TRUE(at::equal(without, with.narrow(2, 0, ApparelDynamicsNetImpl::kChannels)));
  // A contact module on a graph without contact inputs is refused with a message, not misread.
  g.contact_rest = at::Tensor();
  try {
    ApparelDynamicsNet(ApparelDynamicsOptions{"local", J})->features(A, T, S, g);
    FAIL() << "expected an error";
  } catch (const c10::Error& e) {
    EXPECT_NE(std::string(e.what()).find("contact_rest"), std::string::npos) << e.what();
  }
}

// The physics inputs (options.response) are the last channels, zeros where the graph has none; a module
// widened from one without them computes what it did, on both inference paths, until training moves the new
// weights, and once they move the fused path still equals the tensor path.
TEST(ApparelDynamics, ResponseInputsAreTheLastChannelsAndAWidenedModuleComputesItsSource) {
  torch::manual_seed(12);
  const int64_t N = 300, J = 4;
  ApparelGraph g = chain_graph(N, J);
  const at::Tensor T = random_transforms(4, J).unsqueeze(0), A = 0.1 * at::randn({1, 3, N, 3}),
                   S = 0.1 * at::randn({1, 4, N, 3});
  ApparelDynamicsNet source = lively_network(J, g);
  ApparelDynamicsOptions o = source->options;
  o.response = true;
  ApparelDynamicsNet widened(o);
  ASSERT_EQ(widened->channels(), source->channels() + kApparelResponseChannels);
  const int64_t C = source->channels();

  // Undefined: zeros; defined: the graph's values, after the other channels unchanged.
  const at::Tensor none = widened->features(A, T, S, g);
  EXPECT_TRUE(at::equal(none.narrow(2, 0, C), source->features(A, T, S, g)));
  EXPECT_TRUE(at::equal(none.narrow(2, C, kApparelResponseChannels), at::zeros({1, N, kApparelResponseChannels})));
  g.response = at::rand({N, kApparelResponseChannels});
  const at::Tensor with = widened->features(A, T, S, g);
  EXPECT_TRUE(at::equal(with.narrow(2, C, kApparelResponseChannels).squeeze(0), g.response));

  widened->widen_from(*source);
  const at::Tensor expected = source->step(A, T, S, g).detach();
  EXPECT_TRUE(at::allclose(widened->step(A, T, S, g).detach(), expected, 1e-6, 1e-6));
  {
    c10::InferenceMode inference;
    // To float rounding: the fused path sums in another order (7.6e-6 apart on one CPU, 1e-6 on another).
    EXPECT_LT((widened->step(A, T, S, g) - expected).abs().max().item<float>(), 5e-5f);
  }
  // Moved weights: the response now changes the output, the same on both paths.
  {
    torch::NoGradGuard no_grad;
    for (auto& p : widened->parameters()) p.add_(0.1 * at::randn(p.sizes()));
  }
  const at::Tensor tensor_path = widened->step(A, T, S, g).detach();
  at::Tensor fused_path;
  {
    c10::InferenceMode inference;
    fused_path = widened->step(A, T, S, g);
  }
  EXPECT_TRUE(at::allclose(fused_path, tensor_path, 1e-5, 1e-5))
      << "max difference " << (fused_path - tensor_path).abs().max().item<float>();
  ApparelGraph calm = g;
  calm.response = at::zeros({N, kApparelResponseChannels});
  EXPECT_GT((widened->step(A, T, S, calm).detach() - tensor_path).abs().max().item<float>(), 1e-3);

  // Refused: widening a module that has the inputs, or into one that differs otherwise; a response of
  // the wrong shape.
  EXPECT_THROW(widened->widen_from(*widened), Error);
  ApparelDynamicsOptions other = o;
  other.edge_widths = {8, 8};
  EXPECT_THROW(ApparelDynamicsNet(other)->widen_from(*source), Error);
  g.response = at::zeros({N, 2});
  EXPECT_THROW(widened->features(A, T, S, g), c10::Error);
}

TEST(ApparelDynamics, RigidMotionAboutGravityLeavesDetailVectorsUnchanged) {
  torch::manual_seed(4);
  const int64_t N = 6, J = 3;
  const ApparelGraph g = chain_graph(N, J);
  ApparelDynamicsNet net = lively_network(J, g);
  const at::Tensor T = random_transforms(4, J), A = at::randn({3, N, 3}), S = at::randn({4, N, 3});
  // The same animation moved rigidly: x -> G x + c for every point, so R -> G R and t -> G t + c.
  const auto moved = [&](const at::Tensor& G, const at::Tensor& c) {
    at::Tensor T2 = T.clone();
    T2.narrow(3, 0, 3).copy_(at::matmul(G, T.narrow(3, 0, 3)));
    T2.select(3, 3).copy_(at::matmul(T.select(3, 3), G.t()) + c);
    const at::Tensor A2 = at::matmul(A, G.t()) + c, S2 = at::matmul(S, G.t()) + c;
    at::Tensor detail;
    const at::Tensor next = net->step(A2, T2, S2, g, &detail);
    return std::make_pair(next, detail);
  };
  torch::NoGradGuard no_grad;
  const at::Tensor I = at::eye(3), zero = at::zeros({3});
  const auto [next, detail] = moved(I, zero);
  EXPECT_GT(detail.abs().max().item<float>(), 1e-2);  // the network does something
  const at::Tensor yaw = rotation({0, 1, 0}, 1.1f), shift = at::tensor({0.4f, -0.2f, 2.0f});
  const auto [next_yaw, detail_yaw] = moved(yaw, shift);
  EXPECT_LT((detail_yaw - detail).abs().max().item<float>(), 1e-5);
  EXPECT_LT((next_yaw - (at::matmul(next, yaw.t()) + shift)).abs().max().item<float>(), 1e-5);
  // Gravity is an input: a tilt of the whole animation is a different situation.
  const auto [next_tilt, detail_tilt] = moved(rotation({1, 0, 0}, 0.8f), zero);
  EXPECT_GT((detail_tilt - detail).abs().max().item<float>(), 1e-4);
}

TEST(ApparelDynamics, FreshNetworkIsTheHoldOffsetRule) {
  torch::manual_seed(5);
  const int64_t N = 7, J = 2;
  const ApparelGraph g = chain_graph(N, J);
  ApparelDynamicsNet net(ApparelDynamicsOptions{"local", J});
  for (int k = 0; k < 3; ++k)
    net->observe(at::randn({3, N, 3}), random_transforms(4, J), at::randn({4, N, 3}), g, at::randn({N, 3}));
  net->freeze_normalizers();
  const at::Tensor T = random_transforms(4, J), A = at::randn({3, N, 3}), S = at::randn({4, N, 3});
  torch::NoGradGuard no_grad;
  const at::Tensor next = net->step(A, T, S, g);
  const at::Tensor rule =
      detail_rule_step(A.unsqueeze(0), T.unsqueeze(0), S.unsqueeze(0), g.frame_joints, 0.0).squeeze(0);
  EXPECT_EQ((next - rule).abs().max().item<float>(), 0.0f);
  // By hand: A_t = S_t + R_t R_{t-1}^T (A_{t-1} - S_{t-1}).
  for (int64_t i = 0; i < N; ++i) {
    const int64_t j = g.frame_joints[i].item<int64_t>();
    const Eigen::Vector3f expected = vec(S[3][i]) + matrix(T[3][j].narrow(1, 0, 3)) *
                                                        matrix(T[2][j].narrow(1, 0, 3)).transpose() *
                                                        (vec(A[2][i]) - vec(S[2][i]));
    for (int x = 0; x < 3; ++x) EXPECT_NEAR(next[i][x].item<float>(), expected(x), 1e-5);
  }
}

TEST(ApparelDynamics, ZeroNetworkRulesOnAHandComputedExample) {
  // One joint turning 90 degrees about y per frame, anchors at the origin: the detail vector of a
  // vertex that moved from (1, 0, 0) at frame 0 to (0, 0, -1.5) at frame 1 (= R_1 (1.5, 0, 0)).
  at::Tensor T = at::zeros({1, 4, 1, 3, 4});
  for (int k = 0; k < 4; ++k) T[0][k][0].narrow(1, 0, 3).copy_(rotation({0, 1, 0}, 1.5707963f * k));
  const at::Tensor S = at::zeros({1, 4, 1, 3});
  const at::Tensor A = at::tensor({0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 0.f, -1.5f}).view({1, 3, 1, 3});
  // Frame t-3: d = (0, 0, 0). Frame t-2: R_1 = 90 deg, A = (1, 0, 0) -> d = R_1^T (1,0,0) = (0, 0, 1).
  // Frame t-1: R_2 = 180 deg, A = (0, 0, -1.5) -> d = R_2^T (0, 0, -1.5) = (0, 0, 1.5).
  const at::Tensor frames = at::zeros({1}, at::kLong);
  const at::Tensor d = detail_vectors(A.squeeze(0), S.squeeze(0).narrow(0, 0, 3), T.squeeze(0).narrow(0, 0, 3), frames);
  EXPECT_NEAR(d[1][0][2].item<float>(), 1.0f, 1e-6);
  EXPECT_NEAR(d[2][0][2].item<float>(), 1.5f, 1e-6);
  // hold_offset: d_t = (0, 0, 1.5), R_3 = 270 deg about y: R_3 (0, 0, 1.5) = (-1.5, 0, 0).
  const at::Tensor hold = detail_rule_step(A, T, S, frames, 0.0);
  EXPECT_NEAR(hold[0][0][0].item<float>(), -1.5f, 1e-5);
  EXPECT_NEAR(hold[0][0][2].item<float>(), 0.0f, 1e-5);
  // inertial with 0.5: d_t = 1.5 + 0.5 (1.5 - 1) = 1.75 -> (-1.75, 0, 0).
  const at::Tensor inertial = detail_rule_step(A, T, S, frames, 0.5);
  EXPECT_NEAR(inertial[0][0][0].item<float>(), -1.75f, 1e-5);
}

TEST(ApparelDynamics, InertiaFitIsTheLeastSquaresFactor) {
  // d_t along x: 0, 1, 1.5, 1.75 (each step half the last): lambda = 0.5 exactly.
  const at::Tensor d = at::tensor({0.f, 1.f, 1.5f, 1.75f}).view({4, 1, 1}) * at::tensor({1.f, 0.f, 0.f}).view({1, 1, 3});
  InertiaFit fit;
  fit.add(d);
  EXPECT_NEAR(fit.inertia(), 0.5, 1e-9);
  InertiaFit none;
  EXPECT_EQ(none.inertia(), 0.0);
}

TEST(ApparelDynamics, NormalizerStatisticsAndFreeze) {
  RunningNormalizer centred(2, true), uncentred(2, false);
  const at::Tensor x = at::tensor({1.f, 10.f, 3.f, 10.f, 5.f, 10.f}).view({3, 2});
  // Before freeze the normaliser is the identity.
  EXPECT_TRUE(centred->normalize(x).equal(x));
  centred->accumulate(x);
  uncentred->accumulate(x);
  EXPECT_EQ(centred->count(), 3.0);
  centred->freeze();
  uncentred->freeze();
  EXPECT_NEAR(centred->mean[0].item<float>(), 3.0f, 1e-6);
  EXPECT_NEAR(centred->scale[0].item<float>(), std::sqrt(8.0f / 3.0f), 1e-6);
  EXPECT_NEAR(centred->scale[1].item<float>(), RunningNormalizerImpl::kMinScale, 1e-9);  // constant channel
  EXPECT_EQ(uncentred->mean[0].item<float>(), 0.0f);
  EXPECT_NEAR(uncentred->scale[0].item<float>(), std::sqrt(35.0f / 3.0f), 1e-5);  // rms
  EXPECT_LT((centred->denormalize(centred->normalize(x)) - x).abs().max().item<float>(), 1e-5);
  EXPECT_THROW(centred->accumulate(x), c10::Error);
}

TEST(ApparelDynamics, ObservedTargetIsTheChangeOfTheDetailVector) {
  // One vertex, one joint: the target normaliser's rms after one observation is |d_t - d_{t-1}| per
  // channel, with each d in its own frame (an off-by-one frame would change it).
  ApparelGraph g = chain_graph(1, 1);
  ApparelDynamicsNet net(ApparelDynamicsOptions{"local", 1});
  at::Tensor T = at::zeros({4, 1, 3, 4});
  for (int k = 0; k < 4; ++k) T[k][0].narrow(1, 0, 3).copy_(rotation({0, 1, 0}, 1.5707963f * k));
  const at::Tensor S = at::zeros({4, 1, 3});
  const at::Tensor A = at::tensor({0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, -1.5f}).view({3, 1, 3});
  // d_{t-1} = (0, 0, 1.5); the target A_t = (-2, 0, 0) at R_3 = 270 deg: d_t = R_3^T (-2, 0, 0) = (0, 0, 2).
  net->observe(A, T, S, g, at::tensor({-2.f, 0.f, 0.f}).view({1, 3}));
  net->freeze_normalizers();
  EXPECT_NEAR(net->target_normalizer->scale[2].item<float>(), 0.5f, 1e-5);
  EXPECT_NEAR(net->target_normalizer->scale[0].item<float>(), RunningNormalizerImpl::kMinScale, 1e-6);
}

TEST(ApparelDynamics, AttachmentDistancesAlongTheApparel) {
  // Body vertex 0 at the origin; a chain 1-2-3 along x hanging from it (edges 0-1, 1-2, 2-3, unit
  // steps), and a separate piece 4-5 whose vertex 4 is 0.5 from the body.
  const at::Tensor V = at::tensor({0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 2.f, 0.f, 0.f, 3.f, 0.f, 0.f,
                                   0.f, 0.5f, 0.f, 0.f, 2.5f, 0.f}).view({6, 3});
  const at::Tensor E = at::tensor({0, 1, 1, 2, 2, 3, 4, 5}, at::kLong).view({4, 2});
  const at::Tensor d = attachment_distances(V, E, at::tensor({1, 2, 3, 4, 5}, at::kLong), at::tensor({0}, at::kLong));
  const std::vector<float> expected = {1.f, 2.f, 3.f, 0.5f, 2.5f};
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(d[i].item<float>(), expected[i], 1e-6) << i;
}

TEST(ApparelDynamics, ChainAncestorsArePowersOfTwoHopsTowardsTheAttachment) {
  // Body vertex 0; a chain of 9 apparel vertices 1..9 along x hanging from it, and a separate piece
  // 10-11 whose vertex 10 is nearest the body. Positions in apparel_ids: vertex v at v - 1.
  std::vector<float> v = {0.f, 0.f, 0.f};
  for (int i = 1; i <= 9; ++i) v.insert(v.end(), {float(i), 0.f, 0.f});
  v.insert(v.end(), {0.f, 0.5f, 0.f, 0.f, 2.5f, 0.f});
  std::vector<int64_t> e;
  for (int64_t i = 0; i < 9; ++i) e.insert(e.end(), {i, i + 1});
  e.insert(e.end(), {10, 11});
  const at::Tensor V = at::tensor(v).view({12, 3}), E = at::tensor(e, at::kLong).view({-1, 2});
  const at::Tensor apparel = at::arange(1, 12, at::kLong), body = at::tensor({0}, at::kLong);
  const at::Tensor up = chain_ancestors(V, E, apparel, body, 4);
  ASSERT_EQ(up.sizes(), (at::IntArrayRef{11, 4}));
  // Chain position p (vertex p + 1) is p hops below the first apparel vertex (position 0).
  for (int64_t p = 0; p < 9; ++p)
    for (int64_t l = 0; l < 4; ++l) EXPECT_EQ(up[p][l].item<int64_t>(), std::max<int64_t>(p - (1 << l), 0)) << p << " " << l;
  // The separate piece hangs from its vertex nearest the body (position 9): both point there.
  for (int64_t l = 0; l < 4; ++l) {
    EXPECT_EQ(up[9][l].item<int64_t>(), 9);
    EXPECT_EQ(up[10][l].item<int64_t>(), 9);
  }
  EXPECT_EQ(chain_ancestors(V, E, apparel, body, 0).size(1), 0);
}

TEST(ApparelDynamics, ReachLevelsLetTheTipSeeTheChainAbove) {
  // A 40-vertex strip with one block: without reach the tip's output depends only on its 1-ring; with
  // 6 reach levels it also moves when the chain 32 hops above it changes.
  torch::manual_seed(8);
  const int64_t N = 40, J = 2;
  const ApparelGraph g = chain_graph(N, J);
  const at::Tensor T = random_transforms(4, J), A = at::randn({3, N, 3}), S = at::randn({4, N, 3});
  at::Tensor A2 = A.clone();
  A2.select(1, N - 1 - 32).add_(0.5);
  for (int64_t reach : {int64_t(0), kApparelReachLevels}) {
    ApparelDynamicsOptions o{"local", J};
    o.edge_widths = {16};
    o.reach_levels = reach;
    ApparelDynamicsNet net(o);
    net->freeze_normalizers();
    torch::NoGradGuard no_grad;
    for (auto& p : net->parameters()) p.copy_(0.3 * at::randn(p.sizes()));
    const float change = (net->step(A2, T, S, g) - net->step(A, T, S, g))[N - 1].abs().max().item<float>();
    if (reach == 0) EXPECT_EQ(change, 0.0f);
    else EXPECT_GT(change, 1e-4f);
  }
}

TEST(ApparelDynamics, AttachmentAnchorsFollowWhereThePieceHangsFrom) {
  // Body vertices 0 (all weight on joint 0) and 6 (joint 1). Chain 1-2-3 hangs from 0 by edge 0-1 while
  // its tip 3 lies next to body vertex 6; the separate piece 4-5 is nearest the body at 4, which is
  // next to 6, while 5 lies next to 0.
  const at::Tensor V = at::tensor({0.f, 0.f, 0.f,  1.f, 0.f, 0.f,  2.f, 0.f, 0.f,  3.f, 0.f, 0.f,
                                   3.f, 0.2f, 0.f, 0.3f, 0.1f, 0.f, 3.f, 0.1f, 0.f}).view({7, 3});
  const at::Tensor E = at::tensor({0, 1, 1, 2, 2, 3, 4, 5}, at::kLong).view({4, 2});
  const at::Tensor apparel = at::tensor({1, 2, 3, 4, 5}, at::kLong), body = at::tensor({0, 6}, at::kLong);
  const at::Tensor W_b = at::tensor({1.f, 0.f, 0.f, 1.f}).view({2, 2});
  const at::Tensor attached = attachment_anchor_weights(V, E, apparel, body, W_b);
  const at::Tensor nearest = apparel_anchor_weights_for("nearest", V, E, apparel, body, W_b);
  // By attachment: 1, 2, 3 with vertex 0's joint, the piece 4-5 with vertex 6's.
  const std::vector<int64_t> joint = {0, 0, 0, 1, 1}, nearest_joint = {0, 1, 1, 1, 0};
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(attached[i][joint[i]].item<float>(), 1.0f) << i;
    EXPECT_EQ(nearest[i][nearest_joint[i]].item<float>(), 1.0f) << i;
  }
  EXPECT_TRUE(apparel_anchor_weights_for("attachment", V, E, apparel, body, W_b).equal(attached));
  EXPECT_THROW(apparel_anchor_weights_for("farthest", V, E, apparel, body, W_b), Error);
}

TEST(ApparelDynamics, MeshEdgesAreUniqueAndOrdered) {
  // Two triangles sharing the edge 1-2: five edges.
  const at::Tensor edges = mesh_edges(at::tensor({0, 1, 2, 2, 1, 3}, at::kInt).view({2, 3}));
  EXPECT_TRUE(edges.equal(at::tensor({0, 1, 0, 2, 1, 2, 1, 3, 2, 3}, at::kLong).view({5, 2}))) << edges;
  EXPECT_EQ(mesh_edges(at::zeros({0, 3}, at::kLong)).size(0), 0);
}

TEST(ApparelDynamics, RolloutFeedsPredictionsBack) {
  torch::manual_seed(6);
  const int64_t N = 4, J = 2, frames = 3;
  const ApparelGraph g = chain_graph(N, J);
  ApparelDynamicsNet net = lively_network(J, g);
  const at::Tensor T = random_transforms(3 + frames, J), S = at::randn({3 + frames, N, 3});
  const at::Tensor initial = at::randn({3, N, 3});
  torch::NoGradGuard no_grad;
  const at::Tensor out = net->rollout(initial, T, S, g);
  ASSERT_EQ(out.sizes(), (std::vector<int64_t>{frames, N, 3}));
  at::Tensor history = initial;
  for (int64_t t = 0; t < frames; ++t) {
    const at::Tensor next = net->step(history, T.narrow(0, t, 4), S.narrow(0, t, 4), g);
    EXPECT_LT((next - out[t]).abs().max().item<float>(), 1e-6);
    history = at::cat({history.narrow(0, 1, 2), next.unsqueeze(0)}, 0);
  }
}

}  // namespace
}  // namespace amt
