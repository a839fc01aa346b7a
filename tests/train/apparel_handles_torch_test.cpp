// The apparel module on handles through bind and the stepper (models/pipeline.h, models/apparel_handles.h):
// the stepper equals the module run on the handles plus follow_handles; with a zero network it is the rule
// on the handles, exactly; a mesh with split seams binds as one surface and its copies move as one.
#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/utils.h>

#include <cmath>
#include <cstring>
#include <string>
#include <tuple>
#include <vector>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs_torch.h"
#include "fresh_model.h"
#include "micro_dataset.h"
#include "models/apparel_handles.h"
#include "models/pipeline.h"

namespace amt {
namespace {

constexpr double kSpacing = 0.05;

struct Micro {
  at::Tensor V, F, joints, mask, motion, V_gt;
};

Micro read_micro(const std::string& path, int frames) {
  DatasetReader reader(path);
  const CharacterData data = reader.read_character(reader.character_names().front());
  const int64_t N = data.mesh.num_vertices(), J = data.skeleton.num_joints();
  Micro m;
  m.V = at::from_blob(const_cast<float*>(data.mesh.V.data()), {N, 3}, at::kFloat).clone();
  m.F = at::from_blob(const_cast<int32_t*>(data.mesh.F.data()), {data.mesh.F.rows(), 3}, at::kInt).to(at::kLong);
  m.joints = at::from_blob(const_cast<float*>(data.skeleton.rest_joints.data()), {J, 3}, at::kFloat).clone();
  m.mask = at::from_blob(const_cast<uint8_t*>(data.apparel_mask.data()), {N}, at::kByte).to(at::kBool);
  const Transforms transforms = reader.read_joint_transforms("walk0", 0, frames);
  m.motion = at::empty({frames, J, 3, 4});
  for (int i = 0; i < frames * J; ++i)
    std::memcpy(m.motion.data_ptr<float>() + 12 * i, transforms[size_t(i)].data(), 12 * sizeof(float));
  const MatrixX3f gt = reader.read_vertices("walk0", 0, frames);
  m.V_gt = at::from_blob(const_cast<float*>(gt.data()), {frames, N, 3}, at::kFloat).clone();
  return m;
}

struct Fixture {
  ModelBundle bundle;
  Micro micro;
};

Fixture fixture(const std::string& name, int frames) {
  test::use_one_thread();
  const std::string dir = test::write_fresh_model(test::test_directory(name + "_bundle"), 5, canonical_joint_names(),
                                                  /*local_apparel=*/true, kSpacing);
  const std::string data = test::test_directory(name + "_data") + "/micro.h5";
  test::write_micro_dataset(data, {200, 12, 1, {}});
  return {load_model_bundle(dir), read_micro(data, frames)};
}

TEST(ApparelHandlesPipeline, StepperIsTheModuleOnTheHandlesFollowedByTheVertices) {
  Fixture f = fixture("handles_step", 10);
  const Micro& m = f.micro;
  BindOptions options;
  options.apparel_mask = m.mask;
  const BoundCharacter b = bind_character(f.bundle, m.V, m.F, m.joints, options);
  ASSERT_TRUE(b.handle_rows.defined());
  const int64_t H = b.handle_rows.size(0), N_a = b.num_apparel();
  EXPECT_GT(H, 1);
  EXPECT_LT(H, N_a) << "handles are a subset";
  EXPECT_TRUE(at::allclose(b.handle_vertex_weights.sum(1), at::ones({N_a}), 1e-6, 1e-6));

  const int T = 10;
  const at::Tensor history = m.V_gt.index_select(1, b.apparel_ids).narrow(0, 0, 3);
  // The anchors as the stepper skins them: one call over the body and then the apparel.
  const int64_t N_b = b.num_body();
  const at::Tensor S =
      linear_blend_skinning(at::cat({m.V.index_select(0, b.body_ids), m.V.index_select(0, b.apparel_ids)}),
                            at::cat({b.body_weights, b.apparel_anchor_weights}), m.motion, m.joints)
          .narrow(1, N_b, N_a)
          .contiguous();  // (T, N_a, 3)
  PipelineStepper stepper(f.bundle, b, history, PipelineStages::kBodyApparel);
  stepper.set_strain_limit(0.0f);  // the module's raw output
  stepper.reset(history, m.motion.narrow(0, 0, 3));
  std::vector<at::Tensor> A_hat;
  for (int t = 3; t < T; ++t) A_hat.push_back(stepper.step_detailed(m.motion[t]).A_hat.clone());

  torch::NoGradGuard no_grad;
  const ApparelRig rig = b.rig();
  const ApparelGraph g = handle_graph(b.apparel_graph(), rig);
  const at::Tensor S_h = S.index_select(1, rig.rows);
  const at::Tensor A_h = f.bundle.apparel_dynamics.ptr()->rollout(history.index_select(1, rig.rows), m.motion, S_h, g);
  const at::Tensor A_ref = follow_turning_handles(A_h, S_h.narrow(0, 3, T - 3), S.narrow(0, 3, T - 3), rig);
  EXPECT_TRUE(at::allclose(at::stack(A_hat), A_ref, 1e-5, 1e-6));
  EXPECT_GT((A_ref - S.narrow(0, 3, T - 3)).abs().max().item<float>(), 1e-4f);  // the network acts

  // A zero network is the rule it is built around, on the handles (the per-vertex rule differs by centimetres).
  for (auto& p : f.bundle.apparel_dynamics->parameters()) p.zero_();
  PipelineStepper zero(f.bundle, b, history, PipelineStages::kBodyApparel);
  zero.set_strain_limit(0.0f);
  zero.reset(history, m.motion.narrow(0, 0, 3));
  at::Tensor h = history.index_select(1, rig.rows).unsqueeze(0);
  const double inertia = f.bundle.apparel_dynamics->options.inertia;
  for (int t = 3; t < T; ++t) {
    const at::Tensor got = zero.step_detailed(m.motion[t]).A_hat;
    const at::Tensor rule_h = detail_rule_step(h, m.motion.narrow(0, t - 3, 4).unsqueeze(0),
                                               S_h.narrow(0, t - 3, 4).unsqueeze(0), g.frame_joints, inertia);
    const at::Tensor expected = follow_turning_handles(rule_h.squeeze(0), S_h[t], S[t], rig);
    // To float rounding: the stepper skins the history's anchors and the new frame's in separate calls.
    EXPECT_LT((got - expected).abs().max().item<float>(), 1e-6f) << t;
    h = at::cat({h.narrow(1, 1, 2), rule_h.unsqueeze(1)}, 1);
  }
}

// The stepper's vertices follow the handles turning by default; set_turning_handles(false) gives follow_handles.
TEST(ApparelHandlesPipeline, TheStepperFollowsTurningHandlesUnlessToldNot) {
  Fixture f = fixture("handles_turning", 8);
  const Micro& m = f.micro;
  const BoundCharacter b = bind_character(f.bundle, m.V, m.F, m.joints, [&] {
    BindOptions o;
    o.apparel_mask = m.mask;
    return o;
  }());
  const at::Tensor history = m.V_gt.index_select(1, b.apparel_ids).narrow(0, 0, 3);
  // A history off the rest place by a few centimetres, varying over the piece, so that the handles turn.
  const at::Tensor A_rest = m.V.index_select(0, b.apparel_ids);
  const at::Tensor bent =
      history + 0.03 * at::stack({at::sin(31 * A_rest.select(1, 1)), at::zeros_like(A_rest.select(1, 0)),
                                  at::cos(17 * A_rest.select(1, 1))},
                                 1);
  std::vector<at::Tensor> got[2];
  for (const bool turning : {true, false}) {
    PipelineStepper stepper(f.bundle, b, bent, PipelineStages::kBodyApparel);
    EXPECT_TRUE(stepper.turning_handles());
    stepper.set_turning_handles(turning);
    stepper.set_strain_limit(0.0f);
    stepper.reset(bent, m.motion.narrow(0, 0, 3));
    for (int t = 3; t < 8; ++t) got[turning].push_back(stepper.step_detailed(m.motion[t]).A_hat.clone());
  }
  EXPECT_GT((at::stack(got[1]) - at::stack(got[0])).abs().max().item<float>(), 1e-4f);
}

// The micro character with its apparel cut along a seam, as an artist's UV split leaves it: the apparel faces
// beyond the apparel's mean x take their own copies (same positions) of every vertex they use.
struct Seamed {
  at::Tensor V, F, mask, source;  // source (N') the original vertex of each
};

Seamed split_apparel(const Micro& m) {
  const int64_t N = m.V.size(0);
  std::vector<int64_t> source;
  for (int64_t i = 0; i < N; ++i) source.push_back(i);
  const float cut = m.V.index_select(0, at::nonzero(m.mask).flatten()).select(1, 0).mean().item<float>();
  at::Tensor F = m.F.clone();
  auto f = F.accessor<int64_t, 2>();
  const auto mask = m.mask.accessor<bool, 1>();
  const auto V = m.V.accessor<float, 2>();
  std::vector<int64_t> copy(static_cast<size_t>(N), -1);
  for (int64_t k = 0; k < F.size(0); ++k) {
    if (!(mask[f[k][0]] && mask[f[k][1]] && mask[f[k][2]])) continue;
    if ((V[f[k][0]][0] + V[f[k][1]][0] + V[f[k][2]][0]) / 3 <= cut) continue;
    for (int c = 0; c < 3; ++c) {
      const int64_t v = f[k][c];
      if (copy[size_t(v)] < 0) {
        source.push_back(v);
        copy[size_t(v)] = static_cast<int64_t>(source.size()) - 1;
      }
      f[k][c] = copy[size_t(v)];
    }
  }
  // A vertex only the copied faces used stays, in no face, where its copy is (the weld links the two).
  const at::Tensor s = at::tensor(source, at::kLong);
  return {m.V.index_select(0, s), F, m.mask.index_select(0, s), s};
}

// bind_character with the given apparel mask.
BoundCharacter bind_masked(const ModelBundle& bundle, const at::Tensor& V, const at::Tensor& F,
                           const at::Tensor& joints, const at::Tensor& mask) {
  BindOptions options;
  options.apparel_mask = mask;
  return bind_character(bundle, V, F, joints, options);
}

TEST(ApparelHandlesPipeline, SplitSeamsBindAsOneSurfaceAndTheCopiesMoveAsOne) {
  Fixture f = fixture("handles_seams", 12);
  const Micro& m = f.micro;
  const Seamed seamed = split_apparel(m);
  const int64_t N = m.V.size(0), copies = seamed.V.size(0) - N;
  ASSERT_GT(copies, 10);
  const BoundCharacter b = bind_masked(f.bundle, seamed.V, seamed.F, m.joints, seamed.mask);
  const BoundCharacter original = bind_masked(f.bundle, m.V, m.F, m.joints, m.mask);
  // The micro character's capsules already touch at a few points: the cut adds its copies to those.
  const TopologyCounts t = b.topology(), before = original.topology();
  EXPECT_EQ(t.seam_links, before.seam_links + copies);
  EXPECT_EQ(t.refused_welds, before.refused_welds);
  EXPECT_GT(t.parts, before.parts);
  EXPECT_EQ(t.welded_parts, before.welded_parts);
  EXPECT_EQ(b.handle_rows.size(0), original.handle_rows.size(0));

  // From a history whose apparel is off its rest place by a field that varies a few centimetres over the piece
  // (the micro character's apparel moves rigidly, and from rest a fresh network's changes are too small to tell),
  // so that each vertex's result depends on which handles it follows: every copy equal to the vertex it copies,
  // to 1e-6.
  const at::Tensor gt = m.V_gt.index_select(1, seamed.source);
  const at::Tensor A_rest = seamed.V.index_select(0, b.apparel_ids);
  const at::Tensor field = 0.02 * at::stack({at::sin(37 * A_rest.select(1, 0)), at::cos(23 * A_rest.select(1, 1)),
                                             at::sin(29 * A_rest.select(1, 2))},
                                            1);
  const at::Tensor history = gt.index_select(1, b.apparel_ids).narrow(0, 0, 3) + field;
  PipelineStepper stepper(f.bundle, b, history, PipelineStages::kBodyApparel);
  stepper.reset(history, m.motion.narrow(0, 0, 3));
  const at::Tensor copy_ids = at::arange(N, N + copies, at::kLong);
  const at::Tensor original_ids = seamed.source.narrow(0, N, copies);
  float worst = 0;
  for (int t = 3; t < 12; ++t) {
    const at::Tensor V_hat = stepper.step(m.motion[t]);
    worst = std::max(worst,
                     (V_hat.index_select(0, copy_ids) - V_hat.index_select(0, original_ids)).abs().max().item<float>());
  }
  EXPECT_LE(worst, 1e-6f);
}

TEST(ApparelHandlesPipeline, AWeldChainLongerThanTheToleranceStaysOnePointUnderTheStretchLimit) {
  // The split seams' copies moved 1.4 mm off their originals (past the 1 mm weld tolerance), each joined to its
  // original by a faceless vertex half way: a weld group chained through it, whose seam link from the copy to the
  // original is 1.4 mm long. From an apparel history stretched to twice its size, the stretch limit works on every
  // edge; each copy and its middle vertex come out exactly where the original does.
  Fixture f = fixture("handles_chain", 6);
  const Micro& m = f.micro;
  const Seamed seamed = split_apparel(m);
  const int64_t N = m.V.size(0), copies = seamed.V.size(0) - N;
  ASSERT_GT(copies, 10);
  const at::Tensor shift = at::tensor({0.0014f, 0.0f, 0.0f});
  const at::Tensor originals = seamed.source.narrow(0, N, copies);
  at::Tensor V = seamed.V.clone();
  V.narrow(0, N, copies) += shift;
  V = at::cat({V, m.V.index_select(0, originals) + 0.5f * shift}, 0);  // the middle vertices
  const at::Tensor mask = at::cat({seamed.mask, seamed.mask.narrow(0, N, copies)}, 0);
  const BoundCharacter b = bind_masked(f.bundle, V, seamed.F, m.joints, mask);
  EXPECT_EQ(b.topology().seam_links,
            bind_masked(f.bundle, seamed.V, seamed.F, m.joints, seamed.mask).topology().seam_links + copies);
  const at::Tensor A_rest = V.index_select(0, b.apparel_ids);
  const at::Tensor centre = A_rest.mean(0, true);
  const at::Tensor stretched = (centre + 2.0f * (A_rest - centre)).unsqueeze(0).repeat({3, 1, 1});
  PipelineStepper stepper(f.bundle, b, stretched, PipelineStages::kBodyApparel);
  ASSERT_EQ(stepper.strain_limit(), kDefaultStrainLimit);
  const at::Tensor V_hat = stepper.step(m.motion[3]);
  const at::Tensor at_original = V_hat.index_select(0, originals);
  EXPECT_TRUE(at::equal(V_hat.narrow(0, N, copies), at_original));
  EXPECT_TRUE(at::equal(V_hat.narrow(0, N + copies, copies), at_original));
  // Without the limit, the copies follow their handles from their own rest places: 1.4 mm apart, turned.
  PipelineStepper raw(f.bundle, b, stretched, PipelineStages::kBodyApparel);
  raw.set_strain_limit(0.0f);
  const at::Tensor R_hat = raw.step(m.motion[3]);
  EXPECT_GT((R_hat.narrow(0, N, copies) - R_hat.index_select(0, originals)).norm(2, 1).min().item<float>(), 5e-4f);
}

TEST(ApparelHandlesPipeline, AGivenMaskThatSplitsAWeldIsKeptAndCounted) {
  Fixture f = fixture("handles_refused", 4);
  const Micro& m = f.micro;
  Seamed seamed = split_apparel(m);
  const int64_t N = m.V.size(0);
  seamed.mask[N] = false;  // one copy called body, its original apparel
  const BoundCharacter b = bind_masked(f.bundle, seamed.V, seamed.F, m.joints, seamed.mask);
  const BoundCharacter original = bind_masked(f.bundle, m.V, m.F, m.joints, m.mask);
  EXPECT_EQ(b.topology().refused_welds, original.topology().refused_welds + 1);
  EXPECT_FALSE(b.apparel_mask[N].item<bool>());
}

// A hand-made rig of four handles (a tetrahedron, every pair linked) and six vertices between them.
ApparelRig tetrahedron_rig() {
  ApparelRig rig;
  rig.rows = at::arange(4, at::kLong);
  rig.vertex_handles = at::tensor({0, 1, 1, 2, 2, 3, 3, 0, 0, 2, 1, 3}, at::kLong).view({6, 2});
  rig.vertex_weights =
      at::tensor({0.5f, 0.5f, 0.7f, 0.3f, 0.2f, 0.8f, 0.6f, 0.4f, 0.9f, 0.1f, 0.5f, 0.5f}).view({6, 2});
  rig.edges = at::tensor({0, 1, 0, 2, 0, 3, 1, 2, 1, 3, 2, 3}, at::kLong).view({6, 2});
  return rig;
}

at::Tensor rotation(double angle, std::vector<double> axis) {
  const double n = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
  const double x = axis[0] / n, y = axis[1] / n, z = axis[2] / n, c = std::cos(angle), s = std::sin(angle);
  return at::tensor({c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s,  //
                     y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s,  //
                     z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)},
                    at::kDouble)
      .view({3, 3})
      .to(at::kFloat);
}

// A piece moved rigidly (turned 50 degrees and shifted): every handle's turn is the rotation (to the pull towards no
// turn: a few thousandths), and the vertices following the turning handles are the piece moved rigidly to a fraction
// of a millimetre; following the offsets alone misses by centimetres. Not moved: the anchors exactly.
TEST(ApparelHandles, TurningHandlesCarryARigidlyMovedPieceExactly) {
  const ApparelRig rig = tetrahedron_rig();
  const at::Tensor S_h =
      at::tensor({0.0f, 0.0f, 0.0f, 0.1f, 0.0f, 0.0f, 0.0f, 0.12f, 0.0f, 0.0f, 0.0f, 0.09f}).view({4, 3});
  // Each vertex at its handles' weighted mean plus a few centimetres off it.
  const at::Tensor S = at::tensor({0.05f, 0.01f, 0.0f, 0.07f, 0.04f, 0.02f, 0.0f, 0.1f, 0.07f,  //
                                   0.01f, 0.0f, 0.03f, 0.02f, 0.02f, -0.01f, 0.06f, 0.01f, 0.05f})
                           .view({6, 3});
  const at::Tensor R = rotation(50.0 * M_PI / 180.0, {0.3, -1.0, 0.4});
  const at::Tensor shift = at::tensor({0.02f, -0.05f, 0.01f});
  const at::Tensor A_h = at::matmul(S_h, R.t()) + shift;
  const at::Tensor turns = handle_turns(A_h, S_h, rig);
  ASSERT_EQ(turns.sizes(), (std::vector<int64_t>{4, 3, 3}));
  for (int h = 0; h < 4; ++h) EXPECT_LT((turns[h] - R).abs().max().item<float>(), 6e-3f) << "handle " << h;
  const at::Tensor rigid = at::matmul(S, R.t()) + shift;
  EXPECT_LT((follow_turning_handles(A_h, S_h, S, rig) - rigid).abs().max().item<float>(), 3e-4f);
  EXPECT_GT((follow_handles(A_h, S_h, S, rig) - rigid).abs().max().item<float>(), 0.01f);
  EXPECT_TRUE(at::equal(follow_turning_handles(S_h, S_h, S, rig), S));
  // Batched over frames as over one, and differentiable in A_h with the turns held (the offsets' gradient).
  const at::Tensor frames = at::stack({A_h, S_h, A_h + 0.01});
  const at::Tensor anchors = at::stack({S_h, S_h, S_h});
  const at::Tensor batched = follow_turning_handles(frames, anchors, at::stack({S, S, S}), rig);
  EXPECT_TRUE(at::allclose(batched[0], follow_turning_handles(A_h, S_h, S, rig), 1e-6, 1e-7));
  EXPECT_TRUE(at::allclose(batched[2], follow_turning_handles(A_h + 0.01, S_h, S, rig), 1e-6, 1e-7));
  const at::Tensor x = A_h.clone().requires_grad_(true), y = A_h.clone().requires_grad_(true);
  const at::Tensor probe = at::linspace(-1.0, 1.0, 18).view({6, 3});
  (follow_turning_handles(x, S_h, S, rig) * probe).sum().backward();
  (follow_handles(y, S_h, S, rig) * probe).sum().backward();
  EXPECT_TRUE(at::allclose(x.grad(), y.grad(), 1e-6, 1e-7));
  EXPECT_THROW(handle_turns(A_h.narrow(0, 0, 3), S_h.narrow(0, 0, 3), rig), Error);
}

// Handles along one line (a chain) fix no turn about it: each turns the least way that lines the chain up (about
// the axis across the old and new directions), not twisting it.
TEST(ApparelHandles, AChainTurnsTheLeastWayThatLinesItUp) {
  ApparelRig rig;
  rig.rows = at::arange(3, at::kLong);
  rig.vertex_handles = at::tensor({0, 1, 1, 2}, at::kLong).view({2, 2});
  rig.vertex_weights = at::full({2, 2}, 0.5f);
  rig.edges = at::tensor({0, 1, 1, 2}, at::kLong).view({2, 2});
  const at::Tensor S_h = at::tensor({0.0f, 0.0f, 0.0f, 0.1f, 0.0f, 0.0f, 0.2f, 0.0f, 0.0f}).view({3, 3});
  const at::Tensor A_h = at::tensor({0.0f, 0.0f, 0.0f, 0.0f, 0.1f, 0.0f, 0.0f, 0.2f, 0.0f}).view({3, 3});  // x -> y
  const at::Tensor turns = handle_turns(A_h, S_h, rig);
  for (int h = 0; h < 3; ++h) {
    const at::Tensor x = at::matmul(turns[h], at::tensor({1.0f, 0.0f, 0.0f}));
    const at::Tensor z = at::matmul(turns[h], at::tensor({0.0f, 0.0f, 1.0f}));
    // The slight pull towards no turn leaves it a thousandth of a radian short of the quarter turn.
    EXPECT_LT((x - at::tensor({0.0f, 1.0f, 0.0f})).abs().max().item<float>(), 5e-3f) << h;
    EXPECT_LT((z - at::tensor({0.0f, 0.0f, 1.0f})).abs().max().item<float>(), 1e-5f) << h;
  }
  // A handle with no neighbours does not turn.
  ApparelRig alone = rig;
  alone.edges = at::zeros({0, 2}, at::kLong);
  EXPECT_TRUE(at::allclose(handle_turns(A_h, S_h, alone), at::eye(3).expand({3, 3, 3}), 0, 0));
}

}  // namespace
}  // namespace amt
