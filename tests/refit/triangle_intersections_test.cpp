#include "refit/triangle_intersections.h"

#include <gtest/gtest.h>

#include <random>

#include "data_tools/geometry/error.h"
#include "exact_intersection.h"
#include "refit/garment_fit.h"
#include "refit/inflation.h"
#include "test_meshes.h"

namespace amt::refit {
namespace {

TEST(CrossingTrianglePairs, AgreesWithCgalOnRandomTriangles) {
  // Separate random triangles (no shared vertices): every intersecting pair is a crossing one.
  std::mt19937 rng(19);
  std::uniform_real_distribution<double> u(0.0, 1.0), d(-0.25, 0.25);
  for (int trial = 0; trial < 5; ++trial) {
    const int m = 40;
    Positions x(3 * m, 3);
    MatrixX3i F(m, 3);
    for (int f = 0; f < m; ++f) {
      const Eigen::RowVector3d c(u(rng), u(rng), u(rng));
      for (int k = 0; k < 3; ++k) x.row(3 * f + k) = c + Eigen::RowVector3d(d(rng), d(rng), d(rng));
      F.row(f) << 3 * f, 3 * f + 1, 3 * f + 2;
    }
    const CollisionMesh mesh = make_collision_mesh(x, F);
    const int exact = test::count_intersecting_triangle_pairs(x, F, {});
    EXPECT_GT(exact, 0);
    EXPECT_EQ(static_cast<int>(crossing_triangle_pairs(mesh, x, 0).size()), exact) << "trial " << trial;
  }
}

TEST(CrossingTrianglePairs, AgreesWithCgalOnASleeveCrossingAnArm) {
  // The sleeve's flat facets make coplanar neighbours, which rounding must not turn into crossings.
  Positions sleeve, body;
  MatrixX3i sleeve_F, body_F;
  test::tube(6, 10, 0.02, 0.28, 0.06, &sleeve, &sleeve_F);
  test::tube(8, 8, 0.0, 0.3, 0.05, &body, &body_F);
  body.col(1).array() += 0.05;  // the arm half out of the sleeve
  const CollisionMesh mesh = make_garment_avatar_mesh(sleeve, sleeve_F, body, body_F);
  Positions x(mesh.num_vertices, 3);
  x << sleeve, body;
  const int exact = test::count_intersecting_triangle_pairs(x, mesh.F, mesh.vertex_obstacle);
  EXPECT_GT(exact, 0);
  EXPECT_EQ(static_cast<int>(crossing_triangle_pairs(mesh, x, 0).size()), exact);
  body.col(1).array() -= 0.05;  // back inside: nothing crosses
  x << sleeve, body;
  EXPECT_TRUE(crossing_triangle_pairs(mesh, x, 0).empty());
}

TEST(CrossingTrianglePairs, AGarmentCrossingTheAvatarIsAnError) {
  const MatrixX2i bones = skeleton_bones({-1, 0, 1});
  Positions joints(3, 3);
  joints << 0, 0, 0, 0.15, 0, 0, 0.3, 0, 0;
  Positions sleeve, body;
  MatrixX3i sleeve_F, body_F;
  test::tube(6, 10, 0.02, 0.28, 0.06, &sleeve, &sleeve_F);
  test::tube(8, 8, 0.0, 0.3, 0.05, &body, &body_F);
  body.col(1).array() += 0.05;  // the arm half out of the sleeve
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  Positions fitted;
  const std::string fit = message([&] {
    fit_garment(sleeve, sleeve_F, sleeve, body, body_F, joints, joints, bones, &fitted);
  });
  EXPECT_NE(fit.find("garment fit: garment face "), std::string::npos) << fit;
  EXPECT_NE(fit.find(" crosses the avatar's face "), std::string::npos) << fit;
  // A source skeleton that leaves the sleeve: the shrunk avatar pokes through it.
  Positions slanted = joints;
  slanted.col(1) << -0.1, 0.0, 0.1;
  const ShrunkAvatar shrunk = shrink_to_skeleton(body, body_F, joints, slanted, bones, nearest_bones(body, joints, bones));
  const std::string inflation = message([&] { inflate_avatar(sleeve, sleeve_F, shrunk, slanted, joints, bones); });
  EXPECT_NE(inflation.find("inflation: garment face "), std::string::npos) << inflation;
  EXPECT_NE(inflation.find(" crosses the shrunk avatar's face "), std::string::npos) << inflation;
}

}  // namespace
}  // namespace amt::refit
