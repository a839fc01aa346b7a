// Mesh validation: the plausibility bounds that stop finite but absurd positions (one vertex at 1e15
// from a flipped byte) before anything is computed from them.
#include "data_tools/geometry/mesh.h"

#include <gtest/gtest.h>

#include "data_tools/geometry/shapes.h"
#include "tests/test_support.h"

namespace amt {
namespace {

using test::error_of;

TEST(PlausibleExtent, AcceptsMeshesOfAnyReasonableScale) {
  for (const float radius : {1e-3f, 1.0f, 4e3f}) {
    EXPECT_NO_THROW(validate_mesh(uv_sphere(Eigen::Vector3f(radius, 0, 0), radius, 8, 6), "sphere")) << radius;
  }
}

TEST(PlausibleExtent, RejectsACoordinateBeyondTenKilometres) {
  // Uniformly absurd: every edge is long too, so only the absolute bound can catch it.
  TriMesh mesh = uv_sphere(Eigen::Vector3f::Zero(), 1.0f, 8, 6);
  mesh.V *= 2e4f;
  const std::string error = error_of([&] { validate_mesh(mesh, "huge.obj"); });
  EXPECT_EQ(error.rfind("huge.obj: vertices: expected coordinates within 10000 of the origin, found ", 0), 0u) << error;
  EXPECT_NE(error.find(" at vertex 0"), std::string::npos) << error;
}

TEST(PlausibleExtent, RejectsOneVertexFarFromTheRestOfTheMesh) {
  // A 1 cm sphere: its sides are about 4 mm, so the bound is about 40 m; a vertex 100 m away is absurd,
  // one 10 m away is not, and one at 1e15 fails the absolute bound first.
  TriMesh mesh = uv_sphere(Eigen::Vector3f::Zero(), 0.01f, 8, 6);
  mesh.V.row(5) << 10.0f, 0.0f, 0.0f;
  EXPECT_NO_THROW(validate_mesh(mesh, "fine.obj"));
  mesh.V.row(5) << 100.0f, 0.0f, 0.0f;
  const std::string error = error_of([&] { validate_mesh(mesh, "flipped.obj"); });
  EXPECT_EQ(error.rfind("flipped.obj: vertices: expected positions within 10000 median edge lengths (", 0), 0u) << error;
  EXPECT_NE(error.find("found 100 0 0 at vertex 5 (100 from the centre)"), std::string::npos) << error;
  mesh.V.row(5) << 1e15f, 0.0f, 0.0f;
  EXPECT_NE(error_of([&] { validate_mesh(mesh, "flipped.obj"); }).find("found 1e+15 0 0 at vertex 5"), std::string::npos);
}

TEST(PlausibleExtent, DegenerateMeshesFallBackToTheAbsoluteBound) {
  // All vertices on one point: the median side is 0, so only the absolute bound applies.
  TriMesh mesh = uv_sphere(Eigen::Vector3f::Zero(), 1.0f, 8, 6);
  mesh.V.setConstant(3.0f);
  EXPECT_NO_THROW(check_plausible_extent(mesh, "point.obj"));
  mesh.V(0, 2) = -2e4f;
  EXPECT_NE(error_of([&] { check_plausible_extent(mesh, "point.obj"); }).find("at vertex 0"), std::string::npos);
}

}  // namespace
}  // namespace amt

namespace amt {
namespace {

TEST(Submesh, KeepsTheListedVerticesInOrderAndTheFacesAmongThem) {
  // Two triangles sharing the edge 1-2 and a third one apart; keep vertices 2, 1, 3, 4 (in that order).
  MatrixX3f V(6, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 5, 5, 5, 6, 5, 5;
  MatrixX3i F(3, 3);
  F << 0, 1, 2, 1, 3, 2, 3, 4, 5;
  const TriMesh part = submesh(V, F, {2, 1, 3, 4});
  ASSERT_EQ(part.V.rows(), 4);
  EXPECT_EQ(part.V.row(0), V.row(2));
  EXPECT_EQ(part.V.row(3), V.row(4));
  ASSERT_EQ(part.F.rows(), 1);  // only face 1-3-2 has its three corners listed
  EXPECT_EQ(part.F.row(0), Eigen::RowVector3i(1, 2, 0));
  EXPECT_THROW(submesh(V, F, {0, 6}), Error);
}

}  // namespace
}  // namespace amt
