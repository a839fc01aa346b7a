// Cloth retargeting on constructed cases: a sphere (body) with a sheet of apparel in a shell around it.
// Zero detail vectors on an unmoved source, exact transfer of a rigid motion, a vertex put inside the
// body coming out at its depth along the body's normal, the shortening of 3.1, the relaxation against a
// reference implementation, and the connectivity check naming both characters.
#include "data_tools/garment/cloth_retarget.h"

#include <gtest/gtest.h>

#include <cmath>

#include "data_tools/geometry/shapes.h"
#include "data_tools/geometry/winding_number.h"
#include "tests/test_support.h"

namespace amt {
namespace {

using Eigen::Vector3f;
using test::error_of;

constexpr float kRadius = 0.3f;

// A sphere of radius 0.3 at `centre`, then a 6 x 6 sheet bent onto the sphere of radius `shell` around
// the same centre, on the +z side (apparel).
ClothCharacter sphere_with_sheet(const std::string& name, const Vector3f& centre = Vector3f(0, 0, 0),
                                 float shell = 0.33f) {
  ClothCharacter c;
  c.name = name;
  const TriMesh sphere = uv_sphere(centre, kRadius, 32, 16);
  TriMesh sheet = grid(6, 6, 0.04f);
  for (Eigen::Index i = 0; i < sheet.V.rows(); ++i) {
    const Vector3f p(sheet.V(i, 0) - 0.1f, sheet.V(i, 1) - 0.1f, 0.3f);
    sheet.V.row(i) = (centre + shell * p.normalized()).transpose();
  }
  c.mesh = merge_meshes({sphere, sheet});
  c.apparel_mask.assign(size_t(c.mesh.V.rows()), 0);
  for (Eigen::Index i = sphere.V.rows(); i < c.mesh.V.rows(); ++i) c.apparel_mask[size_t(i)] = 1;
  return c;
}

MatrixX3f apparel_rows(const MatrixX3f& V, const std::vector<int32_t>& ids) {
  MatrixX3f out(Eigen::Index(ids.size()), 3);
  for (size_t k = 0; k < ids.size(); ++k) out.row(Eigen::Index(k)) = V.row(ids[k]);
  return out;
}

TEST(ClothRetarget, DetailVectorsOfAnUnmovedSourceAreZero) {
  const ClothCharacter source = sphere_with_sheet("a.h5:source");
  const ClothCharacter target = sphere_with_sheet("b.h5:target", Vector3f::Zero(), 0.34f);
  ClothRetargeter r(source, target);
  ASSERT_EQ(r.num_apparel(), 36);
  EXPECT_LT(r.detail_vectors(source.mesh.V).cwiseAbs().maxCoeff(), 1e-5f);
  // Unmoved source and target: the target's own rest apparel comes out, nothing inside the body.
  MatrixX3f out = target.mesh.V;
  out.bottomRows(36).setZero();
  const ClothRetargetReport report = r.retarget(source.mesh.V, out);
  EXPECT_LT((out - target.mesh.V).cwiseAbs().maxCoeff(), 1e-5f);
  EXPECT_EQ(report.before.inside, 0);
  EXPECT_EQ(report.after.total, 36);
  EXPECT_EQ(report.shortened, 0);
}

TEST(ClothRetarget, CarriesTheSourceDetailOntoARigidlyMovedTarget) {
  const ClothCharacter source = sphere_with_sheet("source"), target = sphere_with_sheet("target", {0.5f, 1, 0});
  ClothRetargeter r(source, target);
  // The source apparel moves 2 cm along +x over an unmoved body: detail (0.02, 0, 0) everywhere.
  MatrixX3f s = source.mesh.V;
  for (const int32_t i : r.source_apparel()) s(i, 0) += 0.02f;
  const MatrixX3f d = r.detail_vectors(s);
  EXPECT_LT((d.rowwise() - Eigen::RowVector3f(0.02f, 0, 0)).cwiseAbs().maxCoeff(), 1e-5f);
  // The target body rotated and moved: its body-oriented apparel follows rigidly, plus the detail.
  const Eigen::Matrix3f R = Eigen::AngleAxisf(0.6f, Vector3f(0, 1, 0)).toRotationMatrix();
  const Eigen::RowVector3f t(0.1f, -0.2f, 0.3f), c(0.5f, 1, 0);
  MatrixX3f moved = ((target.mesh.V.rowwise() - c) * R.transpose()).rowwise() + (c + t);
  const MatrixX3f oriented = r.body_oriented_target(moved);
  EXPECT_LT((oriented - apparel_rows(moved, r.target_apparel())).cwiseAbs().maxCoeff(), 1e-5f);
  r.retarget(s, moved);
  const MatrixX3f expected = oriented.rowwise() + Eigen::RowVector3f(0.02f, 0, 0);
  EXPECT_LT((apparel_rows(moved, r.target_apparel()) - expected).cwiseAbs().maxCoeff(), 1e-5f);
}

TEST(ClothRetarget, AVertexInsideTheBodyComesOutAtItsDepthAlongTheNormal) {
  const ClothCharacter c = sphere_with_sheet("character");
  ClothRetargetOptions options;
  options.detail_clearance = 0;  // no 3.1: the detail carries the vertex inside
  options.relax_iterations = 0;  // nor do its edges pull it back
  options.penetration.margin = 0.001f;  // 1 mm beyond the surface, so that the re-test says outside
  options.penetration.smoothing_rings = 0;
  ClothRetargeter r(c, c, options);
  const int32_t v = r.source_apparel()[14];
  MatrixX3f s = c.mesh.V;
  const Vector3f direction = s.row(v).transpose().normalized();
  s.row(v) = (0.26f * direction).transpose();  // 4 cm deep into the sphere
  const TriMesh sphere = uv_sphere(Vector3f::Zero(), kRadius, 32, 16);
  const WindingNumberTree body(sphere.V, sphere.F);
  Vector3f closest;
  const Vector3f inside = s.row(v).transpose();
  const float depth = body.distance(inside, &closest);
  ASSERT_TRUE(body.inside(inside));
  ASSERT_GT(depth, 0.035f);
  MatrixX3f out = c.mesh.V;
  const ClothRetargetReport report = r.retarget(s, out);
  EXPECT_EQ(report.before.inside, 1);
  EXPECT_NEAR(report.before.depth_sum_cm, 100.0 * depth, 1e-3);
  EXPECT_EQ(report.after.inside, 0);
  const Vector3f p = out.row(v).transpose();
  EXPECT_NEAR((p - inside).norm(), depth + 0.001f, 1e-5f);     // moved by its depth (and the margin)
  EXPECT_GT((p - inside).normalized().dot(direction), 0.99f);  // along the body's outward normal
  EXPECT_NEAR(body.distance(p), 0.001f, 1e-5f);                // onto the surface, plus the margin
  EXPECT_FALSE(body.inside(p));
  for (const int32_t i : r.target_apparel()) {  // the others stay
    if (i != v) {
      EXPECT_LT((out.row(i) - s.row(i)).norm(), 1e-5f);
    }
  }
}

TEST(ClothRetarget, ShortensADetailVectorThatWouldCrossTheBodyOrientedApparel) {
  const ClothCharacter c = sphere_with_sheet("character");
  ClothRetargetOptions options;
  options.resolve = false;
  options.relax_iterations = 0;
  options.detail_clearance = 0.8f;
  ClothRetargeter r(c, c, options);
  const int32_t v = r.source_apparel()[14];
  MatrixX3f s = c.mesh.V;
  const Vector3f direction = s.row(v).transpose().normalized();
  s.row(v) = (0.2f * direction).transpose();  // 13 cm inward, its clearance is about 3 cm
  MatrixX3f out = c.mesh.V;
  const ClothRetargetReport report = r.retarget(s, out);
  EXPECT_EQ(report.shortened, 1);
  // Shortened to 0.8 of the clearance: the vertex ends just above the body's faces, not inside it.
  EXPECT_GT(out.row(v).norm(), 0.29f);
  EXPECT_EQ(report.after.inside, 0);
}

TEST(ClothRetarget, RelaxationPullsAStretchedEdgeBackTowardsItsRestLength) {
  const ClothCharacter c = sphere_with_sheet("character");
  ClothRetargetOptions options;
  options.resolve = false;
  options.detail_clearance = 0;
  MatrixX3f s = c.mesh.V;
  s.row(c.mesh.V.rows() - 1) += Eigen::RowVector3f(0.05f, 0.05f, 0);  // a corner pulled 7 cm away
  MatrixX3f relaxed = c.mesh.V, kept = c.mesh.V;
  ClothRetargeter(c, c, options).retarget(s, relaxed);
  options.relax_iterations = 0;
  ClothRetargeter(c, c, options).retarget(s, kept);
  EXPECT_LT((kept - s).cwiseAbs().maxCoeff(), 1e-5f);
  const Eigen::Index corner = c.mesh.V.rows() - 1;
  EXPECT_LT((relaxed.row(corner) - c.mesh.V.row(corner)).norm(), 0.5f * (s.row(corner) - c.mesh.V.row(corner)).norm());
}

// The relaxation as first written (data_tools/garment/cloth_retarget.cpp before it moved to flat arrays and vector
// lanes): Jacobi sweeps over the apparel edges of `c`, rest lengths from its rest mesh, a square root and
// a division per edge. The retargeter's sweeps sum each vertex's corrections in another order and, with
// SSE, take 1 / length from the hardware's estimate and a Newton step: the same positions within
// rounding (3e-8 m here, 1.8e-7 m on the bench's 6318 apparel vertices over 20 sweeps), checked to 1e-6 m.
void reference_relaxation(const ClothCharacter& c, const std::vector<int32_t>& apparel, int iterations, MatrixX3f& A) {
  std::vector<int32_t> position(c.apparel_mask.size(), -1);
  for (size_t k = 0; k < apparel.size(); ++k) position[size_t(apparel[k])] = int32_t(k);
  std::vector<Eigen::Vector2i> edges;
  std::vector<float> rest;
  const MatrixX2i all = unique_edges(c.mesh.F);
  for (Eigen::Index e = 0; e < all.rows(); ++e) {
    if (position[size_t(all(e, 0))] < 0 || position[size_t(all(e, 1))] < 0) continue;
    edges.emplace_back(position[size_t(all(e, 0))], position[size_t(all(e, 1))]);
    rest.push_back((c.mesh.V.row(all(e, 0)) - c.mesh.V.row(all(e, 1))).norm());
  }
  for (int it = 0; it < iterations; ++it) {
    MatrixX3f move = MatrixX3f::Zero(A.rows(), 3);
    Eigen::VectorXf count = Eigen::VectorXf::Zero(A.rows());
    for (size_t e = 0; e < edges.size(); ++e) {
      const Eigen::RowVector3f v = A.row(edges[e][1]) - A.row(edges[e][0]);
      const float length = v.norm();
      if (!(length > 1e-9f)) continue;
      const Eigen::RowVector3f d = (0.5f * (length - rest[e]) / length) * v;
      move.row(edges[e][0]) += d, move.row(edges[e][1]) -= d;
      count[edges[e][0]] += 1, count[edges[e][1]] += 1;
    }
    for (Eigen::Index k = 0; k < A.rows(); ++k)
      if (count[k] > 0) A.row(k) += move.row(k) / count[k];
  }
}

TEST(ClothRetarget, RelaxationGivesTheReferenceJacobiResult) {
  const ClothCharacter c = sphere_with_sheet("character");
  ClothRetargetOptions options;
  options.resolve = false;
  options.measure = false;
  options.detail_clearance = 0;
  MatrixX3f s = c.mesh.V;
  int n = 0;
  for (Eigen::Index i = 0; i < s.rows(); ++i) {  // every apparel vertex moved by up to 3 cm, no two alike
    if (!c.apparel_mask[size_t(i)]) continue;
    const float x = float(n);
    s.row(i) += 0.03f * Eigen::RowVector3f(std::sin(1.7f * x), std::cos(2.3f * x), std::sin(0.9f * x + 1));
    ++n;
  }
  options.relax_iterations = 0;
  ClothRetargeter unrelaxed(c, c, options);
  MatrixX3f expected = c.mesh.V;
  unrelaxed.retarget(s, expected);
  MatrixX3f A = apparel_rows(expected, unrelaxed.target_apparel());
  const float before = (A - apparel_rows(c.mesh.V, unrelaxed.target_apparel())).cwiseAbs().maxCoeff();
  reference_relaxation(c, unrelaxed.target_apparel(), 20, A);
  options.relax_iterations = 20;
  MatrixX3f out = c.mesh.V;
  ClothRetargeter(c, c, options).retarget(s, out);
  const MatrixX3f relaxed = apparel_rows(out, unrelaxed.target_apparel());
  // It did move the apparel, and as the reference did.
  EXPECT_GT((relaxed - apparel_rows(expected, unrelaxed.target_apparel())).cwiseAbs().maxCoeff(), 0.1f * before);
  EXPECT_LT((relaxed - A).cwiseAbs().maxCoeff(), 1e-6f);
}

TEST(ClothRetarget, DifferentApparelConnectivityNamesBothCharacters) {
  const ClothCharacter source = sphere_with_sheet("src.h5:a");
  ClothCharacter fewer = sphere_with_sheet("dst.h5:b");
  fewer.apparel_mask.back() = 0;
  std::string message = error_of([&] { ClothRetargeter r(source, fewer); });
  EXPECT_NE(message.find("dst.h5:b against src.h5:a: apparel connectivity differs: expected 36 apparel vertices"),
            std::string::npos)
      << message;
  ClothCharacter flipped = sphere_with_sheet("dst.h5:b");
  const Eigen::Index f = flipped.mesh.F.rows() - 1;
  std::swap(flipped.mesh.F(f, 1), flipped.mesh.F(f, 2));
  message = error_of([&] { ClothRetargeter r(source, flipped); });
  EXPECT_NE(message.find("dst.h5:b against src.h5:a: apparel connectivity differs: apparel face 49"), std::string::npos)
      << message;
  ClothCharacter short_mask = sphere_with_sheet("dst.h5:b");
  short_mask.apparel_mask.pop_back();
  EXPECT_NE(error_of([&] { ClothRetargeter r(source, short_mask); }).find("dst.h5:b: apparel mask: expected"),
            std::string::npos);
}

}  // namespace
}  // namespace amt
