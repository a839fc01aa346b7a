// Penetration resolution on a constructed case: a flat sheet (apparel) cut through a closed sphere
// (body). Every sheet vertex inside the sphere must end outside it, at the surface plus the margin.
#include "data_tools/garment/penetration_resolution.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/shapes.h"
#include "data_tools/geometry/winding_number.h"

namespace amt {
namespace {

struct SheetThroughSphere {
  TriMesh mesh;
  std::vector<uint8_t> mask;
  int body_vertices = 0;
};

// Sphere of radius 0.3 at the origin (body), then a 21 x 21 sheet of 1.2 m in the plane z = 0.1
// centred on the origin (apparel): the sheet's middle is inside the sphere.
SheetThroughSphere sheet_through_sphere() {
  SheetThroughSphere c;
  const TriMesh sphere = uv_sphere(Eigen::Vector3f::Zero(), 0.3f, 32, 16);
  TriMesh sheet = grid(21, 21, 0.06f);
  sheet.V.rowwise() += Eigen::RowVector3f(-0.6f, -0.6f, 0.1f);
  c.mesh = merge_meshes({sphere, sheet});
  c.body_vertices = sphere.num_vertices();
  c.mask.assign(size_t(c.mesh.num_vertices()), 0);
  for (int i = c.body_vertices; i < c.mesh.num_vertices(); ++i) c.mask[size_t(i)] = 1;
  return c;
}

TEST(PenetrationResolver, PushesASheetOutOfASphere) {
  const SheetThroughSphere c = sheet_through_sphere();
  PenetrationOptions options;
  options.margin = 0.005f;
  PenetrationResolver resolver(c.mesh.F, c.mask, options);
  EXPECT_EQ(resolver.num_apparel(), 441);
  EXPECT_EQ(resolver.num_body_faces(), c.mesh.num_faces() - 800);
  MatrixX3f V = c.mesh.V;
  const Penetration before = resolver.measure(V);
  // Sheet points with x^2 + y^2 < 0.3^2 - 0.1^2 = 0.08 are inside: on the 0.06 grid that is 69 points
  // (counted by hand over |i|, |j| <= 4 with 0.0036 (i^2 + j^2) < 0.08, i.e. i^2 + j^2 <= 22).
  EXPECT_EQ(before.inside, 69);
  EXPECT_EQ(before.total, 441);
  const PenetrationReport report = resolver.resolve(V);
  EXPECT_EQ(report.before.inside, 69);
  EXPECT_EQ(report.pushed, 69);
  EXPECT_GT(report.smoothed, 0);
  EXPECT_EQ(report.after.inside, 0);
  EXPECT_EQ(resolver.measure(V).inside, 0);
  // Pushed vertices sit at the sphere's surface plus the margin (the 32 x 16 polygonal sphere is within
  // 6 mm of the round one); the body did not move; far sheet vertices did not move.
  for (int i = c.body_vertices; i < c.mesh.num_vertices(); ++i) {
    const float r0 = c.mesh.V.row(i).norm(), r1 = V.row(i).norm();
    if (r0 < 0.3f - 0.003f) {
      EXPECT_NEAR(r1, 0.3f + options.margin, 0.007f) << "vertex " << i;
    }
    if (r0 > 0.45f) {
      EXPECT_EQ(V.row(i), c.mesh.V.row(i)) << "vertex " << i;
    }
  }
  EXPECT_EQ(V.topRows(c.body_vertices), c.mesh.V.topRows(c.body_vertices));
  // No spikes: no sheet edge grew beyond the push depth plus one grid spacing.
  const MatrixX2i E = unique_edges(c.mesh.F);
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    if (E(e, 0) < c.body_vertices) continue;
    EXPECT_LT((V.row(E(e, 0)) - V.row(E(e, 1))).norm(), 0.06f * 1.4143f + 0.3f) << "edge " << e;
  }
}

TEST(PenetrationResolver, SmoothingMovesTheFirstRingByHalfThePush) {
  const SheetThroughSphere c = sheet_through_sphere();
  PenetrationOptions options;
  options.smoothing_rings = 1;
  options.falloff = 0.5f;
  PenetrationResolver resolver(c.mesh.F, c.mask, options);
  MatrixX3f V = c.mesh.V;
  const PenetrationReport report = resolver.resolve(V);
  EXPECT_EQ(report.after.inside, 0);
  // Sheet vertex (i, j) = (15, 10) is outside (5^2 + 0^2 = 25 > 22); its inside neighbours are (14, 10)
  // and (14, 9) (16 and 17 <= 22), so it moves by half (the falloff) the mean of their pushes. A pushed
  // vertex moves by its push alone, so the pushes are the inside neighbours' displacements.
  const int ring = c.body_vertices + 10 * 21 + 15, inner = c.body_vertices + 10 * 21 + 14;
  const int inner_below = c.body_vertices + 9 * 21 + 14;
  std::vector<int> inside_neighbors;
  const MatrixX2i E = unique_edges(c.mesh.F);
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    for (int side = 0; side < 2; ++side) {
      const int q = E(e, 1 - side);
      if (E(e, side) == ring && c.mesh.V.row(q).norm() < 0.3f) inside_neighbors.push_back(q);
    }
  }
  std::sort(inside_neighbors.begin(), inside_neighbors.end());
  ASSERT_EQ(inside_neighbors, (std::vector<int>{inner_below, inner}));
  const Eigen::RowVector3f push_inner = V.row(inner) - c.mesh.V.row(inner);
  const Eigen::RowVector3f push_below = V.row(inner_below) - c.mesh.V.row(inner_below);
  const Eigen::RowVector3f moved = V.row(ring) - c.mesh.V.row(ring);
  const Eigen::RowVector3f half_mean = 0.5f * (push_inner + push_below) / 2.0f;
  EXPECT_GT(half_mean.norm(), 0.01f);  // the pushes are centimetres: "half" is measurable
  EXPECT_LT((moved - half_mean).norm(), 1e-6f) << "moved " << moved << ", half the mean push " << half_mean;
  // Ring 2 does not move with one ring of smoothing.
  const int far = c.body_vertices + 10 * 21 + 16;
  EXPECT_EQ(V.row(far), c.mesh.V.row(far));
}

// An artist's model tucks apparel into the body at rest (hair roots in the scalp): with keep_rest_penetration the
// vertices inside on the rest pose stay where they are in every frame, and only apparel that moved in is pushed.
TEST(PenetrationResolver, LeavesApparelInsideAtRestWhereItIs) {
  const SheetThroughSphere c = sheet_through_sphere();
  PenetrationOptions options;
  options.keep_rest_penetration = true;
  PenetrationResolver resolver(c.mesh.F, c.mask, options);
  resolver.prepare(c.mesh.V);
  ASSERT_EQ(resolver.rest_inside().size(), size_t(441));
  EXPECT_EQ(std::count(resolver.rest_inside().begin(), resolver.rest_inside().end(), uint8_t(1)), 69);
  // The rest pose itself: all 69 tucked, nothing moves.
  MatrixX3f V = c.mesh.V;
  PenetrationReport report = resolver.resolve(V);
  EXPECT_EQ(report.before.inside, 69);
  EXPECT_EQ(report.tucked, 69);
  EXPECT_EQ(report.pushed, 0);
  EXPECT_EQ(report.after.inside, 69);
  EXPECT_EQ(V, c.mesh.V);
  // The sheet slid 12 cm along x: vertices inside now and at rest stay put; those that slid in are pushed out.
  MatrixX3f slid = c.mesh.V;
  slid.bottomRows(441).col(0).array() += 0.12f;
  V = slid;
  report = resolver.resolve(V);
  EXPECT_EQ(report.pushed + report.tucked, report.before.inside);
  EXPECT_GT(report.pushed, 10);
  EXPECT_GT(report.tucked, 10);
  EXPECT_EQ(report.after.inside, report.tucked);
  // Every vertex inside at rest is left alone (not pushed, and no push spreads to it); the others inside are out.
  for (int k = 0; k < 441; ++k) {
    const int i = c.body_vertices + k;
    if (resolver.rest_inside()[size_t(k)]) EXPECT_EQ(V.row(i), slid.row(i)) << "vertex " << i;
  }
  EXPECT_EQ(resolver.measure(V).inside, report.tucked);
  // Without the option every vertex inside is pushed out.
  PenetrationResolver plain(c.mesh.F, c.mask, PenetrationOptions());
  plain.prepare(c.mesh.V);
  EXPECT_TRUE(plain.rest_inside().empty());
  V = slid;
  report = plain.resolve(V);
  EXPECT_EQ(report.tucked, 0);
  EXPECT_EQ(report.after.inside, 0);
}

// One resolver over frames whose body moves (its tree refitted per frame) gives what a fresh resolver
// (a tree built on that frame) gives.
TEST(PenetrationResolver, FollowsAMovingBodyAcrossFrames) {
  const SheetThroughSphere c = sheet_through_sphere();
  PenetrationResolver resolver(c.mesh.F, c.mask);
  for (int frame = 0; frame < 4; ++frame) {
    MatrixX3f V = c.mesh.V;
    const Eigen::RowVector3f shift(0.02f * float(frame), -0.01f * float(frame), 0.03f * float(frame));
    const float stretch = 1.0f + 0.1f * float(frame);
    for (int i = 0; i < c.body_vertices; ++i) V.row(i) = Eigen::RowVector3f(stretch * V(i, 0), V(i, 1), V(i, 2)) + shift;
    PenetrationResolver fresh(c.mesh.F, c.mask);
    const Penetration expected = fresh.measure(V);
    EXPECT_GT(expected.inside, 40) << "frame " << frame;
    EXPECT_EQ(resolver.measure(V).inside, expected.inside) << "frame " << frame;
    MatrixX3f V_fresh = V;
    const PenetrationReport want = fresh.resolve(V_fresh);
    const PenetrationReport got = resolver.resolve(V);
    EXPECT_EQ(got.before.inside, want.before.inside) << "frame " << frame;
    EXPECT_EQ(got.pushed, want.pushed) << "frame " << frame;
    EXPECT_EQ(got.after.inside, 0) << "frame " << frame;
    EXPECT_LT((V - V_fresh).cwiseAbs().maxCoeff(), 1e-5f) << "frame " << frame;
  }
}

// Verdicts carried over between frames (the body is closed) are those of a fresh tree on every frame,
// while the sheet sweeps through the moving sphere so that its vertices enter and leave it; the far
// part of the sheet carries its verdicts, the part near the sphere is tested again.
TEST(PenetrationResolver, CarriedVerdictsEqualFreshOnesWhileASheetSweepsThroughTheBody) {
  const SheetThroughSphere c = sheet_through_sphere();
  PenetrationResolver resolver(c.mesh.F, c.mask), resolving(c.mesh.F, c.mask);
  ASSERT_TRUE(resolver.closed_body());
  int carried_total = 0, entered = 0, left = 0, previous_inside = -1;
  for (int frame = 0; frame < 40; ++frame) {
    MatrixX3f V = c.mesh.V;
    V.rowwise() += Eigen::RowVector3f(0.01f * float(frame), 0.0f, 0.0f);  // body and sheet drift together
    for (int i = c.body_vertices; i < c.mesh.num_vertices(); ++i) V(i, 2) += 0.3f - 0.02f * float(frame);  // sheet sinks
    PenetrationResolver fresh(c.mesh.F, c.mask);
    const Penetration expected = fresh.measure(V);
    int carried = 0;
    const Penetration got = resolver.measure(V, &carried);
    EXPECT_EQ(got.inside, expected.inside) << "frame " << frame;
    EXPECT_NEAR(got.depth_sum_cm, expected.depth_sum_cm, 1e-3) << "frame " << frame;
    MatrixX3f V_resolved = V;
    const PenetrationReport report = resolving.resolve(V_resolved);
    EXPECT_EQ(report.before.inside, expected.inside) << "frame " << frame;
    EXPECT_EQ(report.after.inside, 0) << "frame " << frame;
    EXPECT_EQ(report.carried, carried) << "frame " << frame;
    carried_total += carried;
    if (frame == 0) {
      EXPECT_EQ(carried, 0);
    }
    if (previous_inside >= 0) entered += expected.inside > previous_inside, left += expected.inside < previous_inside;
    previous_inside = expected.inside;
  }
  // The sheet crosses the whole sphere (z from 0.4 to -0.38): vertices enter, then leave.
  EXPECT_GT(entered, 3);
  EXPECT_GT(left, 3);
  EXPECT_GT(carried_total, 39 * 441 / 2);
  EXPECT_LT(carried_total, 39 * 441);
}

// An open body (the lower half of the sphere, a bowl) is closed by a fan over its rim: inside means
// inside the half ball. A sheet at z = -0.1 then has as many vertices inside as the whole sphere has at
// z = +0.1 (69, see above), one at z = +0.1 none; verdicts carry over as on a closed body.
TEST(PenetrationResolver, FillsTheHolesOfAnOpenBody) {
  SheetThroughSphere c = sheet_through_sphere();
  std::vector<Eigen::Vector3i> kept;
  for (Eigen::Index f = 0; f < c.mesh.F.rows(); ++f) {
    const bool body = c.mesh.F(f, 0) < c.body_vertices;
    const float z = (c.mesh.V.row(c.mesh.F(f, 0)) + c.mesh.V.row(c.mesh.F(f, 1)) + c.mesh.V.row(c.mesh.F(f, 2)))(2) / 3.0f;
    if (!body || z < 0.0f) kept.push_back(c.mesh.F.row(f).transpose());
  }
  MatrixX3i F(Eigen::Index(kept.size()), 3);
  for (size_t f = 0; f < kept.size(); ++f) F.row(Eigen::Index(f)) = kept[f].transpose();
  PenetrationResolver resolver(F, c.mask);
  EXPECT_TRUE(resolver.closed_body());
  EXPECT_EQ(resolver.num_filled_holes(), 1);
  MatrixX3f below = c.mesh.V;
  for (int i = c.body_vertices; i < c.mesh.num_vertices(); ++i) below(i, 2) -= 0.2f;
  EXPECT_EQ(resolver.measure(c.mesh.V).inside, 0);
  int carried = -1;
  EXPECT_EQ(resolver.measure(below, &carried).inside, 69);
  EXPECT_LE(carried, 441 - 69);  // the 69 that went inside were tested again
  EXPECT_GT(carried, 100);       // the sheet's far corners were not
  EXPECT_EQ(resolver.measure(below, &carried).inside, 69);
  EXPECT_EQ(carried, 441);  // nothing moved
  PenetrationResolver unfilled_sphere(c.mesh.F, c.mask);
  EXPECT_EQ(unfilled_sphere.num_filled_holes(), 0);
}

// Through a rig (set_rig) the pushes move pieces: with one handle carrying the whole sheet every sheet vertex moves by
// the same vector (the mean push of the inside vertices, round after round), so no sheet edge changes length, where
// the per-vertex pushes bend the sheet over the sphere. Two handles (left and right halves) move each half as one.
TEST(PenetrationResolver, ARigPushesItsPiecesOutAsWholes) {
  const SheetThroughSphere c = sheet_through_sphere();
  const int Na = c.mesh.num_vertices() - c.body_vertices;
  using Handles = Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const MatrixX2i E = unique_edges(c.mesh.F);
  const auto edge_change = [&](const MatrixX3f& V) {
    float worst = 0;
    for (Eigen::Index e = 0; e < E.rows(); ++e)
      if (E(e, 0) >= c.body_vertices)
        worst = std::max(worst, std::abs((V.row(E(e, 0)) - V.row(E(e, 1))).norm() -
                                         (c.mesh.V.row(E(e, 0)) - c.mesh.V.row(E(e, 1))).norm()));
    return worst;
  };
  {
    PenetrationOptions whole;
    whole.length_iterations = 0;  // the handle's rounds alone
    PenetrationResolver resolver(c.mesh.F, c.mask, whole);
    resolver.set_rig(Handles::Zero(Na, 1), MatrixXfR::Ones(Na, 1), 1);
    MatrixX3f V = c.mesh.V;
    const PenetrationReport report = resolver.resolve(V);
    EXPECT_EQ(report.before.inside, 69);
    EXPECT_EQ(report.smoothed, Na - 69);  // every other sheet vertex moved with the handle
    const Eigen::RowVector3f move = V.row(c.body_vertices) - c.mesh.V.row(c.body_vertices);
    EXPECT_GT(move.z(), 0.1f);  // out of the top of the sphere, centimetres
    for (int i = c.body_vertices; i < c.mesh.num_vertices(); ++i)
      EXPECT_LT((V.row(i) - c.mesh.V.row(i) - move).norm(), 1e-5f) << "vertex " << i;
    EXPECT_LT(edge_change(V), 1e-5f);
    EXPECT_EQ(report.after.inside, resolver.measure(V).inside);
    EXPECT_LT(report.after.inside, 69);
    EXPECT_EQ(V.topRows(c.body_vertices), c.mesh.V.topRows(c.body_vertices));
    // Without the rig the same sheet bends: its edges change by centimetres.
    PenetrationResolver per_vertex(c.mesh.F, c.mask);
    MatrixX3f W = c.mesh.V;
    per_vertex.resolve(W);
    EXPECT_GT(edge_change(W), 0.02f);
  }
  {
    // Two halves (x < 0 on handle 0, x >= 0 on handle 1), spread off: each half moves as one, by its own push.
    PenetrationOptions options;
    options.smoothing_rings = 0;
    options.length_iterations = 0;
    PenetrationResolver resolver(c.mesh.F, c.mask, options);
    Handles h(Na, 1);
    for (int k = 0; k < Na; ++k) h(k, 0) = c.mesh.V(c.body_vertices + k, 0) < 0.0f ? 0 : 1;
    resolver.set_rig(h, MatrixXfR::Ones(Na, 1), 2);
    MatrixX3f V = c.mesh.V;
    resolver.resolve(V);
    for (int side = 0; side < 2; ++side) {
      int first = -1;
      for (int k = 0; k < Na; ++k) {
        if (h(k, 0) != side) continue;
        const int i = c.body_vertices + k;
        if (first < 0) first = i;
        EXPECT_LT((V.row(i) - c.mesh.V.row(i) - (V.row(first) - c.mesh.V.row(first))).norm(), 1e-5f) << i;
      }
      EXPECT_GT((V.row(first) - c.mesh.V.row(first)).norm(), 0.05f) << "side " << side;
    }
  }
  // A rig that does not match the apparel is refused.
  PenetrationResolver resolver(c.mesh.F, c.mask);
  EXPECT_THROW(resolver.set_rig(Handles::Zero(Na - 1, 1), MatrixXfR::Ones(Na - 1, 1), 1), Error);
  EXPECT_THROW(resolver.set_rig(Handles::Constant(Na, 1, 3), MatrixXfR::Ones(Na, 1), 2), Error);
  EXPECT_THROW(resolver.set_rig(Handles::Zero(Na, 1), MatrixXfR::Constant(Na, 1, std::nanf("")), 1), Error);
}

// The edge-length passes after a push through the rig: with the sheet's two halves on two handles, the halves part
// where they meet (each pushed by its own mean); the passes give the edges back most of their length, and the
// apparel still ends outside the body.
TEST(PenetrationResolver, LengthPassesMendWhatThePushThroughTheRigStretched) {
  const SheetThroughSphere c = sheet_through_sphere();
  const int Na = c.mesh.num_vertices() - c.body_vertices;
  using Handles = Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  Handles h(Na, 1);
  for (int k = 0; k < Na; ++k) h(k, 0) = c.mesh.V(c.body_vertices + k, 0) < 0.05f ? 0 : 1;  // off-centre split
  const MatrixX2i E = unique_edges(c.mesh.F);
  const auto worst_change = [&](const MatrixX3f& V) {
    float worst = 0;
    for (Eigen::Index e = 0; e < E.rows(); ++e)
      if (E(e, 0) >= c.body_vertices)
        worst = std::max(worst, std::abs((V.row(E(e, 0)) - V.row(E(e, 1))).norm() /
                                             (c.mesh.V.row(E(e, 0)) - c.mesh.V.row(E(e, 1))).norm() -
                                         1.0f));
    return worst;
  };
  float change[2];
  for (const int passes : {0, 8}) {
    PenetrationOptions options;
    options.smoothing_rings = 0;
    options.length_iterations = passes;
    PenetrationResolver resolver(c.mesh.F, c.mask, options);
    resolver.set_rig(h, MatrixXfR::Ones(Na, 1), 2);
    MatrixX3f V = c.mesh.V;
    const PenetrationReport report = resolver.resolve(V);
    EXPECT_EQ(report.after.inside, resolver.measure(V).inside) << passes;
    EXPECT_EQ(V.topRows(c.body_vertices), c.mesh.V.topRows(c.body_vertices));
    change[passes > 0] = worst_change(V);
  }
  EXPECT_GT(change[0], 0.5f);  // the halves' pushes differ: the edges across the split tear
  EXPECT_LT(change[1], 0.5f * change[0]);
}

// A sheet split along a seam (two grids sharing the column x = 0, each with its own copy of it, as an artist's UV
// split leaves a mesh), both copies on the same handle: the push and the length passes move the copies as one,
// although each copy's edges lie on its own side; so do the rings without a rig.
TEST(PenetrationResolver, TheLengthPassesKeepASplitSeamClosed) {
  const TriMesh sphere = uv_sphere(Eigen::Vector3f::Zero(), 0.3f, 32, 16);
  TriMesh left = grid(11, 21, 0.06f), right = grid(11, 21, 0.06f);
  left.V.rowwise() += Eigen::RowVector3f(-0.6f, -0.6f, 0.1f);
  right.V.rowwise() += Eigen::RowVector3f(0.0f, -0.6f, 0.1f);
  for (int j = 0; j < 21; ++j) right.V.row(j * 11) = left.V.row(j * 11 + 10);  // the copies, bit for bit
  const TriMesh mesh = merge_meshes({sphere, left, right});
  const int body = sphere.num_vertices(), Na = mesh.num_vertices() - body;
  std::vector<uint8_t> mask(size_t(mesh.num_vertices()), 0);
  for (int i = body; i < mesh.num_vertices(); ++i) mask[size_t(i)] = 1;
  using Handles = Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  Handles h(Na, 1);
  for (int k = 0; k < Na; ++k) h(k, 0) = mesh.V(body + k, 0) < 0.05f ? 0 : 1;
  PenetrationOptions options;
  options.smoothing_rings = 0;
  options.length_iterations = 8;
  PenetrationResolver resolver(mesh.F, mask, options);
  resolver.set_rig(h, MatrixXfR::Ones(Na, 1), 2);
  MatrixX3f V = mesh.V;
  const PenetrationReport report = resolver.resolve(V);
  EXPECT_GT(report.pushed, 0);
  int pairs = 0;
  float gap = 0, moved = 0;
  for (int j = 0; j < 21; ++j) {
    const int a = body + j * 11 + 10, b = body + 11 * 21 + j * 11;  // left's last column, right's first
    ASSERT_EQ(mesh.V.row(a), mesh.V.row(b));
    gap = std::max(gap, (V.row(a) - V.row(b)).norm());
    moved = std::max(moved, (V.row(a) - mesh.V.row(a)).norm());
    ++pairs;
  }
  EXPECT_EQ(pairs, 21);
  EXPECT_GT(moved, 0.05f);  // the seam crosses the sphere: it was pushed
  EXPECT_EQ(gap, 0.0f);
  // Without a rig the rings spread the pushes over each copy's own side; the copies still take one push.
  PenetrationResolver rings(mesh.F, mask);
  MatrixX3f W = mesh.V;
  rings.resolve(W);
  float ring_gap = 0, ring_moved = 0;
  for (int j = 0; j < 21; ++j) {
    const int a = body + j * 11 + 10, b = body + 11 * 21 + j * 11;
    ring_gap = std::max(ring_gap, (W.row(a) - W.row(b)).norm());
    ring_moved = std::max(ring_moved, (W.row(a) - mesh.V.row(a)).norm());
  }
  EXPECT_GT(ring_moved, 0.05f);
  EXPECT_EQ(ring_gap, 0.0f);
}

TEST(PenetrationResolver, NothingToDoWithoutApparelOrBody) {
  const TriMesh sphere = uv_sphere(Eigen::Vector3f::Zero(), 0.3f, 8, 6);
  PenetrationResolver body_only(sphere.F, std::vector<uint8_t>(size_t(sphere.num_vertices()), 0));
  MatrixX3f V = sphere.V;
  EXPECT_EQ(body_only.resolve(V).after.inside, 0);
  PenetrationResolver apparel_only(sphere.F, std::vector<uint8_t>(size_t(sphere.num_vertices()), 1));
  EXPECT_EQ(apparel_only.resolve(V).pushed, 0);
  EXPECT_EQ(V, sphere.V);
}

}  // namespace
}  // namespace amt
