// The wrap deformer against hand-computed distances and weights, exact reproduction of the rest
// shape, invariance under rigid motion, brute-force nearest faces, the prepared deformer reading a
// whole frame, and bad input.
#include "data_tools/garment/wrap_deformer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/shapes.h"
#include "tests/test_support.h"

namespace amt {
namespace {

using Eigen::Vector3f;
using test::error_of;

TEST(WrapDeformer, PointTriangleDistanceByRegion) {
  const Vector3f a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_FLOAT_EQ(point_triangle_distance2({0.25f, 0.25f, 2}, a, b, c), 4.0f);     // above the inside
  EXPECT_FLOAT_EQ(point_triangle_distance2({-1, -1, 0}, a, b, c), 2.0f);           // beyond vertex a
  EXPECT_FLOAT_EQ(point_triangle_distance2({2, -1, 1}, a, b, c), 3.0f);            // beyond vertex b
  EXPECT_FLOAT_EQ(point_triangle_distance2({0.5f, -1, 0}, a, b, c), 1.0f);         // beyond edge ab
  EXPECT_FLOAT_EQ(point_triangle_distance2({-2, 0.5f, 0}, a, b, c), 4.0f);         // beyond edge ac
  EXPECT_NEAR(point_triangle_distance2({1, 1, 0}, a, b, c), 0.5f, 1e-6f);          // beyond edge bc
  EXPECT_FLOAT_EQ(point_triangle_distance2({0.2f, 0.3f, 0}, a, b, c), 0.0f);       // on it
}

TEST(WrapDeformer, FaceFrameIsTheEdgeTheNormalAndTheirCross) {
  TriMesh m;
  m.V.resize(3, 3);
  m.V << 1, 1, 0, 1, 3, 0, 0, 1, 0;  // e1 along +y, normal (0,2,0) x (-1,0,0) = (0,0,2): +z
  m.F.resize(1, 3);
  m.F << 0, 1, 2;
  Eigen::Matrix3f R;
  Vector3f c;
  ASSERT_TRUE(face_frame(m.V, m.F, 0, R, c));
  EXPECT_TRUE(R.row(0).isApprox(Eigen::RowVector3f(0, 1, 0)));
  EXPECT_TRUE(R.row(2).isApprox(Eigen::RowVector3f(0, 0, 1)));
  EXPECT_TRUE(R.row(1).isApprox(Eigen::RowVector3f(-1, 0, 0)));  // n x e1
  EXPECT_TRUE(c.isApprox(Vector3f(2.0f / 3, 5.0f / 3, 0)));
  m.V.row(2) << 1, 2, 0;  // on the line through the other two
  EXPECT_FALSE(face_frame(m.V, m.F, 0, R, c));
}

// A unit triangle in z = 0 and its copy moved by `shift` (mesh), and the point (0.25, 0.25, 1) bound to both.
WrapBinding two_triangles(const Vector3f& shift, bool triangle_weights, TriMesh& m) {
  m.V.resize(6, 3);
  m.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0;
  m.V.bottomRows(3).rowwise() += shift.transpose();
  m.F.resize(2, 3);
  m.F << 0, 1, 2, 3, 4, 5;
  MatrixX3f p(1, 3);
  p << 0.25f, 0.25f, 1.0f;
  WrapOptions o;
  o.faces = 2;
  o.triangle_distance_weights = triangle_weights;
  return wrap_register(m.V, m.F, p, o);
}

TEST(WrapDeformer, WeightsAreInverseToThePlaneDistances) {
  // Two parallel unit triangles, at z = 0 and z = 4; a point at z = 1 above both: plane distances 1
  // and 3, weights 3/4 and 1/4.
  TriMesh m;
  const WrapBinding b = two_triangles(Vector3f(0, 0, 4), false, m);
  ASSERT_EQ(b.k, 2);
  EXPECT_EQ(b.face(0, 0), 0);  // the nearer first
  EXPECT_EQ(b.face(0, 1), 1);
  EXPECT_NEAR(b.weight(0, 0), 0.75f, 1e-6f);
  EXPECT_NEAR(b.weight(0, 1), 0.25f, 1e-6f);
  EXPECT_NEAR(b.local(0, 2), 1.0f, 1e-6f);   // signed distance along the first face's normal (+z)
  EXPECT_NEAR(b.local(1, 2), -3.0f, 1e-6f);  // below the second
  // The second triangle lifted by 2 moves the point by its weight's share: 0.25 * 2.
  MatrixX3f moved = m.V;
  moved.bottomRows(3).col(2).array() += 2.0f;
  EXPECT_NEAR(wrap_deform(b, moved, m.F)(0, 2), 1.5f, 1e-5f);
}

struct Scene {
  TriMesh body;
  MatrixX3f points;
};

// A sphere and points scattered in a shell around it.
Scene sphere_scene(int points, uint32_t seed) {
  Scene s;
  s.body = uv_sphere(Vector3f(0.1f, 1.0f, -0.2f), 0.3f, 16, 10);
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal;
  std::uniform_real_distribution<float> radius(0.31f, 0.4f);
  s.points.resize(points, 3);
  for (int i = 0; i < points; ++i) {
    Vector3f d(normal(rng), normal(rng), normal(rng));
    s.points.row(i) = (Vector3f(0.1f, 1.0f, -0.2f) + radius(rng) * d.normalized()).transpose();
  }
  return s;
}

TEST(WrapDeformer, RestShapeIsReproducedAndRigidMotionCarriedExactly) {
  const Scene s = sphere_scene(200, 3);
  for (const bool triangle : {false, true}) {
    WrapOptions o;
    o.triangle_distance_weights = triangle;
    const WrapBinding b = wrap_register(s.body.V, s.body.F, s.points, o);
    ASSERT_EQ(b.num_points(), 200);
    for (int i = 0; i < 200; ++i) EXPECT_NEAR(b.weight.row(i).sum(), 1.0f, 1e-5f);
    EXPECT_LT((wrap_deform(b, s.body.V, s.body.F) - s.points).cwiseAbs().maxCoeff(), 1e-5f);
    const Eigen::Matrix3f R = Eigen::AngleAxisf(0.7f, Vector3f(1, 2, -0.5f).normalized()).toRotationMatrix();
    const Eigen::RowVector3f t(0.4f, -1.2f, 2.0f);
    const MatrixX3f moved = (s.body.V * R.transpose()).rowwise() + t;
    const MatrixX3f expected = (s.points * R.transpose()).rowwise() + t;
    EXPECT_LT((wrap_deform(b, moved, s.body.F) - expected).cwiseAbs().maxCoeff(), 1e-5f);
  }
}

TEST(WrapDeformer, PreparedDeformerReadsTheFacesFromAWholeFrame) {
  // The sphere's vertices at odd rows of a frame twice as long: the prepared deformer with its faces
  // renumbered gives wrap_deform's points, and the sphere's outward normals under them.
  const Scene s = sphere_scene(50, 5);
  const WrapBinding b = wrap_register(s.body.V, s.body.F, s.points);
  const Eigen::Matrix3f R = Eigen::AngleAxisf(0.4f, Vector3f(0, 1, 0)).toRotationMatrix();
  const MatrixX3f moved = s.body.V * R.transpose();
  MatrixX3f frame = MatrixX3f::Constant(2 * moved.rows(), 3, 7.0f);
  for (Eigen::Index i = 0; i < moved.rows(); ++i) frame.row(2 * i + 1) = moved.row(i);
  const MatrixX3i corners = 2 * s.body.F.array() + 1;
  const WrapDeformer deformer(b, corners);
  MatrixX3f out, normals;
  WrapDeformer::Frames frames;
  deformer.deform(frame, out, &normals, frames);
  EXPECT_LT((out - wrap_deform(b, moved, s.body.F)).cwiseAbs().maxCoeff(), 1e-6f);
  const Vector3f centre = R * Vector3f(0.1f, 1.0f, -0.2f);
  for (Eigen::Index i = 0; i < out.rows(); ++i) {
    EXPECT_NEAR(normals.row(i).norm(), 1.0f, 1e-5f);
    EXPECT_GT(normals.row(i).dot((out.row(i) - centre.transpose()).normalized()), 0.95f);
  }
  EXPECT_NE(error_of([&] { WrapDeformer(b, corners.topRows(3)); }).find("binding: expected faces in [0, 3)"),
            std::string::npos);
}

TEST(WrapDeformer, TriangleDistanceWeightsAreInverseToTheDistancesToTheFaces) {
  // The copy moved by (3, 0, 0.5): the point is 1 from the first face and sqrt(2.75^2 + 0.5^2) from the
  // second (beyond its edge), though only 0.5 from its plane.
  TriMesh m;
  const WrapBinding b = two_triangles(Vector3f(3, 0, 0.5f), true, m);
  const float d2 = std::sqrt(2.75f * 2.75f + 0.5f * 0.5f);
  EXPECT_EQ(b.face(0, 0), 0);
  EXPECT_NEAR(b.weight(0, 0), d2 / (1 + d2), 1e-5f);
  EXPECT_NEAR(b.weight(0, 1), 1 / (1 + d2), 1e-5f);
}

TEST(WrapDeformer, BindsTheNearestFacesByBruteForce) {
  const Scene s = sphere_scene(100, 5);
  WrapOptions o;
  o.faces = 3;
  o.candidates = 64;
  const WrapBinding b = wrap_register(s.body.V, s.body.F, s.points, o);
  for (int i = 0; i < 100; ++i) {
    std::vector<std::pair<float, int>> all;
    for (int f = 0; f < s.body.F.rows(); ++f) {
      Eigen::Matrix3f R;
      Vector3f c;
      if (!face_frame(s.body.V, s.body.F, f, R, c)) continue;
      all.emplace_back(point_triangle_distance2(s.points.row(i).transpose(), s.body.V.row(s.body.F(f, 0)).transpose(),
                                                s.body.V.row(s.body.F(f, 1)).transpose(),
                                                s.body.V.row(s.body.F(f, 2)).transpose()),
                       f);
    }
    std::sort(all.begin(), all.end());
    // The bound faces' distances equal the three smallest (ties may pick either face).
    for (int slot = 0; slot < 3; ++slot) {
      const int f = b.face(i, slot);
      const float d2 = point_triangle_distance2(s.points.row(i).transpose(), s.body.V.row(s.body.F(f, 0)).transpose(),
                                                s.body.V.row(s.body.F(f, 1)).transpose(),
                                                s.body.V.row(s.body.F(f, 2)).transpose());
      EXPECT_NEAR(d2, all[static_cast<size_t>(slot)].first, 1e-7f) << "point " << i << " slot " << slot;
    }
  }
}

TEST(WrapDeformer, CollapsedFaceFollowsItsCentroid) {
  TriMesh m;
  m.V.resize(3, 3);
  m.V << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  m.F.resize(1, 3);
  m.F << 0, 1, 2;
  MatrixX3f p(1, 3);
  p << 0.2f, 0.2f, 0.5f;
  const WrapBinding b = wrap_register(m.V, m.F, p);
  MatrixX3f flat = m.V;
  flat.row(2) << 0.5f, 0, 0;  // all three on the x axis: centroid (0.5, 0, 0)
  const MatrixX3f q = wrap_deform(b, flat, m.F);
  // The rest offset from the rest centroid (1/3, 1/3, 0), added to the new centroid.
  EXPECT_TRUE(q.row(0).isApprox(Eigen::RowVector3f(0.5f + 0.2f - 1.0f / 3, 0.2f - 1.0f / 3, 0.5f), 1e-5f));
}

TEST(WrapDeformer, BadInputGivesOneClearError) {
  const Scene s = sphere_scene(4, 1);
  MatrixX3i bad = s.body.F;
  bad(3, 1) = static_cast<int32_t>(s.body.V.rows());
  EXPECT_NE(error_of([&] { wrap_register(s.body.V, bad, s.points); }).find("deformer face 3: expected vertex indices"),
            std::string::npos);
  MatrixX3f nan = s.points;
  nan(2, 1) = std::nanf("");
  EXPECT_NE(error_of([&] { wrap_register(s.body.V, s.body.F, nan); }).find("points: expected finite values"),
            std::string::npos);
  WrapOptions zero;
  zero.faces = 0;
  EXPECT_NE(error_of([&] { wrap_register(s.body.V, s.body.F, s.points, zero); }).find("faces: expected >= 1"),
            std::string::npos);
  MatrixX3i none(0, 3);
  EXPECT_NE(error_of([&] { wrap_register(s.body.V, none, s.points); }).find("at least one face"), std::string::npos);
}

}  // namespace
}  // namespace amt
