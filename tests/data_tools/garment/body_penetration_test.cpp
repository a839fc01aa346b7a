// BodyPenetration against the measure it replaces: a winding-number tree built anew on every posed
// body. A sphere "body" with a hole, and a smaller sphere of "apparel" sunk into it, bent, stretched,
// turned and moved pose after pose; the refitted tree must give the same inside verdicts and depths.
#include "data_tools/garment/body_penetration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/shapes.h"
#include "data_tools/geometry/winding_number.h"

namespace amt {
namespace {

// A body sphere whose cap on the +x side is apparel too (a hole in the body surface, as where a
// garment was cut out of a character's mesh), merged with an apparel sphere half inside the body.
struct Scene {
  TriMesh mesh;
  std::vector<uint8_t> mask;
};

Scene scene() {
  Scene s;
  const TriMesh body = uv_sphere(Eigen::Vector3f(0, 0, 0), 0.5f, 48, 24);
  const TriMesh apparel = uv_sphere(Eigen::Vector3f(0.3f, 0.1f, 0.25f), 0.25f, 24, 12);
  std::vector<int32_t> part;
  s.mesh = merge_meshes({body, apparel}, &part);
  for (size_t i = 0; i < part.size(); ++i) s.mask.push_back(part[i] == 1 || s.mesh.V(i, 0) > 0.45f ? 1 : 0);
  return s;
}

// Pose k of the rest positions V: a bend growing with height, a stretch, a turn about z and a move.
MatrixX3f pose(const MatrixX3f& V, int k) {
  const float a = 0.3f * k;
  MatrixX3f P(V.rows(), 3);
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    const float x = V(i, 0) + 0.4f * k * V(i, 1) * V(i, 1), y = V(i, 1) * (1.0f + 0.15f * k), z = V(i, 2);
    P.row(i) << std::cos(a) * x - std::sin(a) * y + 0.2f * k, std::sin(a) * x + std::cos(a) * y - 0.1f * k,
        z + 0.05f * k;
  }
  return P;
}

// The measure that BodyPenetration replaces: a tree built anew on the posed body (the faces with
// three body vertices), and the apparel vertices tested against it. `near_half` receives how many
// apparel vertices have a winding number within 0.05 of 0.5.
Penetration rebuilt(const Scene& s, const MatrixX3f& P, int* near_half) {
  std::vector<int32_t> index(s.mask.size(), -1);
  MatrixX3f body(0, 3), apparel(0, 3);
  for (size_t i = 0; i < s.mask.size(); ++i) {
    MatrixX3f& part = s.mask[i] ? apparel : body;
    if (!s.mask[i]) index[i] = static_cast<int32_t>(body.rows());
    part.conservativeResize(part.rows() + 1, 3);
    part.row(part.rows() - 1) = P.row(i);
  }
  MatrixX3i faces(0, 3);
  for (Eigen::Index f = 0; f < s.mesh.F.rows(); ++f) {
    const Eigen::RowVector3i face(index[s.mesh.F(f, 0)], index[s.mesh.F(f, 1)], index[s.mesh.F(f, 2)]);
    if (face.minCoeff() < 0) continue;
    faces.conservativeResize(faces.rows() + 1, 3);
    faces.row(faces.rows() - 1) = face;
  }
  const WindingNumberTree tree(body, faces);
  *near_half = 0;
  for (Eigen::Index i = 0; i < apparel.rows(); ++i)
    *near_half += std::abs(tree.winding_number(apparel.row(i).transpose()) - 0.5) < 0.05;
  return penetration(apparel, tree);
}

TEST(BodyPenetration, RefittedTreeMeasuresAsATreeBuiltOnEachPose) {
  const Scene s = scene();
  BodyPenetration meter(s.mesh.V, s.mesh.F, s.mask);
  ASSERT_TRUE(meter.active());
  EXPECT_EQ(meter.apparel_vertices().size() + meter.body_vertices().size(), static_cast<size_t>(s.mesh.V.rows()));
  EXPECT_GT(meter.apparel_vertices().size(), 24u * 11 + 2);  // the apparel sphere and the body's cap
  std::vector<Penetration> first;
  int near_half = 0;
  for (int k = 0; k < 6; ++k) {
    const MatrixX3f P = pose(s.mesh.V, k);
    const std::optional<Penetration> measured = meter.measure(P);
    ASSERT_TRUE(measured.has_value()) << k;
    int near = 0;
    const Penetration expected = rebuilt(s, P, &near);
    near_half += near;
    EXPECT_EQ(measured->total, expected.total) << k;
    EXPECT_EQ(measured->inside, expected.inside) << k;
    EXPECT_NEAR(measured->depth_sum_cm, expected.depth_sum_cm, 1e-9 * expected.depth_sum_cm) << k;
    // Part of the apparel sphere is inside the body, a few cm deep (the body's radius is 50 cm).
    EXPECT_GT(measured->share(), 0.1) << k;
    EXPECT_LT(measured->share(), 0.6) << k;
    EXPECT_GT(measured->mean_depth_cm(), 1.0) << k;
    EXPECT_LT(measured->mean_depth_cm(), 20.0) << k;
    first.push_back(*measured);
  }
  // The hole in the body makes some verdicts close calls, which the meter settles as a fresh tree does.
  EXPECT_GT(near_half, 0);
  // The answer depends on the pose only, not on the poses measured before.
  for (int k = 5; k >= 0; --k) {
    const std::optional<Penetration> again = meter.measure(pose(s.mesh.V, k));
    ASSERT_TRUE(again.has_value());
    EXPECT_EQ(again->inside, first[k].inside) << k;
    EXPECT_EQ(again->depth_sum_cm, first[k].depth_sum_cm) << k;
  }
}

TEST(BodyPenetration, NothingToMeasureAndBadInput) {
  const Scene s = scene();
  BodyPenetration meter(s.mesh.V, s.mesh.F, s.mask);
  // A non-finite body position: no surface to test against. An apparel one is simply outside.
  MatrixX3f P = pose(s.mesh.V, 1);
  const int32_t body_vertex = meter.body_vertices()[3], apparel_vertex = meter.apparel_vertices()[0];
  P(body_vertex, 1) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(meter.measure(P).has_value());
  P = pose(s.mesh.V, 1);
  const int inside = meter.measure(P)->inside;
  P(apparel_vertex, 0) = std::numeric_limits<float>::quiet_NaN();
  ASSERT_TRUE(meter.measure(P).has_value());
  EXPECT_LE(meter.measure(P)->inside, inside);
  EXPECT_THROW(meter.measure(P.topRows(10)), Error);
  // No apparel, or no face with three body vertices: inactive.
  BodyPenetration bare(s.mesh.V, s.mesh.F, std::vector<uint8_t>(s.mask.size(), 0));
  EXPECT_FALSE(bare.active());
  EXPECT_FALSE(bare.measure(s.mesh.V).has_value());
  BodyPenetration dressed(s.mesh.V, s.mesh.F, std::vector<uint8_t>(s.mask.size(), 1));
  EXPECT_FALSE(dressed.active());
  EXPECT_THROW(BodyPenetration(s.mesh.V, s.mesh.F, std::vector<uint8_t>(5, 0)), Error);
  MatrixX3i bad = s.mesh.F;
  bad(0, 1) = static_cast<int32_t>(s.mesh.V.rows());
  EXPECT_THROW(BodyPenetration(s.mesh.V, bad, s.mask), Error);
}

}  // namespace
}  // namespace amt
