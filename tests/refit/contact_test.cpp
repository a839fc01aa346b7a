#include "refit/contact.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#include <array>
#include <cmath>
#include <random>

#include "data_tools/geometry/error.h"
#include "refit/barrier.h"
#include "refit/distance.h"
#include "finite_difference.h"

namespace amt::refit {
namespace {

Positions rows(std::initializer_list<Eigen::RowVector3d> list) {
  Positions x(static_cast<int>(list.size()), 3);
  int i = 0;
  for (const auto& r : list) x.row(i++) = r;
  return x;
}

MatrixX3i faces(std::initializer_list<std::array<int, 3>> list) {
  MatrixX3i F(static_cast<int>(list.size()), 3);
  int i = 0;
  for (const auto& f : list) F.row(i++) << f[0], f[1], f[2];
  return F;
}

TEST(Candidates, LeaveOutIncidentAdjacentAndObstaclePairs) {
  // A free quad (two triangles sharing the edge 1-2) just above an obstacle quad.
  const Positions x = rows({{0, 0.001, 0}, {1, 0.001, 0}, {0, 0.001, 1}, {1, 0.001, 1},
                            {0, 0, 0}, {1, 0, 0}, {0, 0, 1}, {1, 0, 1}});
  const MatrixX3i F = faces({{0, 2, 1}, {1, 2, 3}, {4, 6, 5}, {5, 6, 7}});
  const CollisionMesh mesh = make_collision_mesh(x, F, {0, 0, 0, 0, 1, 1, 1, 1});
  const Candidates c = proximity_candidates(mesh, x, 0.01);
  ASSERT_FALSE(c.point_triangle.empty());
  ASSERT_FALSE(c.edge_edge.empty());
  bool free_against_obstacle = false;
  for (const auto& [v, f] : c.point_triangle) {
    EXPECT_FALSE(F(f, 0) == v || F(f, 1) == v || F(f, 2) == v);
    EXPECT_FALSE(mesh.vertex_obstacle[v] && mesh.face_obstacle[f]);
    free_against_obstacle |= !mesh.vertex_obstacle[v] && mesh.face_obstacle[f];
  }
  EXPECT_TRUE(free_against_obstacle);
  for (const auto& [a, b] : c.edge_edge) {
    EXPECT_LT(a, b);
    EXPECT_FALSE(mesh.E(a, 0) == mesh.E(b, 0) || mesh.E(a, 0) == mesh.E(b, 1) || mesh.E(a, 1) == mesh.E(b, 0) ||
                 mesh.E(a, 1) == mesh.E(b, 1));
    EXPECT_FALSE(mesh.edge_obstacle[a] && mesh.edge_obstacle[b]);
  }
  // Lifted far away: no pair between the two quads is left.
  Positions far = x;
  far.topRows(4).col(1).array() += 1.0;
  for (const auto& [v, f] : proximity_candidates(mesh, far, 0.01).point_triangle)
    EXPECT_EQ(mesh.vertex_obstacle[v], mesh.face_obstacle[f]);
}

TEST(Candidates, BadFaceIndexIsAnError) {
  const Positions x = rows({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  try {
    make_collision_mesh(x, faces({{0, 1, 3}}));
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("face 0 has vertex index 3"), std::string::npos) << e.what();
  }
}

// Free triangles within d̂ of an obstacle triangle O = (3, 4, 5) in the plane y = 0: triangle A = (0, 1, 2)
// hovers over O's face (point-face pairs); triangle B = (6, 7, 8) rises away from O's edge 3-4 with
// vertex 6 beside that edge (point-edge), vertex 7 beside the corner 3 (point-point) and its edge 6-7
// nearly parallel to edge 3-4 (edge-edge with the mollifier active).
struct Scene {
  Positions x;
  CollisionMesh mesh;
};

Scene hovering_scene(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Positions x = rows({{0.1, 0.0006, 0.1}, {0.6, 0.0009, 0.15}, {0.2, 0.0007, 0.7},     // A
                      {0, 0, 0}, {1, 0, 0}, {0, 0, 1},                                // O (obstacle)
                      {0.5, 0.0005, -0.0007}, {-0.0006, 0.0004, -0.0005}, {0.25, 0.3, -0.3}});  // B
  for (int i = 0; i < x.rows(); ++i)
    if (i < 3 || i > 5) x.row(i) += 1e-4 * Eigen::RowVector3d(u(rng), u(rng), u(rng));
  const MatrixX3i F = faces({{0, 2, 1}, {3, 5, 4}, {6, 7, 8}});
  return Scene{x, make_collision_mesh(x, F, {0, 0, 0, 1, 1, 1, 0, 0, 0})};
}

TEST(BarrierPotential, GradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 5; ++trial) {
    const Scene s = hovering_scene(rng);
    const BarrierPotential barrier(s.mesh, 2e-3, 1e3);
    const int n = 3 * s.mesh.num_vertices;
    auto f = [&](const Positions& y) { return barrier.value(y); };
    auto g = [&](const Positions& y) {
      Eigen::VectorXd grad = Eigen::VectorXd::Zero(n);
      barrier.derivatives(y, &grad, nullptr);
      return grad;
    };
    Eigen::VectorXd grad = Eigen::VectorXd::Zero(n);
    std::vector<Eigen::Triplet<double>> triplets;
    const double e = barrier.derivatives(s.x, &grad, &triplets, /*project_psd=*/false);
    ASSERT_GT(e, 0.0);
    EXPECT_NEAR(e, barrier.value(s.x), 1e-12 * e);
    EXPECT_LT(test::relative_error(grad, test::fd_position_gradient(f, s.x, 1e-8)), 1e-5);
    EXPECT_LT(test::relative_error(test::dense(triplets, n), test::fd_position_jacobian(g, s.x, 1e-8)), 1e-4);
  }
}

TEST(BarrierPotential, ProjectedHessianIsPositiveSemiDefinite) {
  std::mt19937 rng(6);
  const Scene s = hovering_scene(rng);
  const BarrierPotential barrier(s.mesh, 2e-3, 1e3);
  std::vector<Eigen::Triplet<double>> raw, projected;
  barrier.derivatives(s.x, nullptr, &raw, false);
  barrier.derivatives(s.x, nullptr, &projected, true);
  const int n = 3 * s.mesh.num_vertices;
  const Eigen::VectorXd raw_eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(test::dense(raw, n)).eigenvalues();
  const Eigen::VectorXd eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(test::dense(projected, n)).eigenvalues();
  EXPECT_LT(raw_eig.minCoeff(), 0.0) << "the scene should exercise the projection";
  EXPECT_GE(eig.minCoeff(), -1e-9 * eig.cwiseAbs().maxCoeff());
}

TEST(BarrierPotential, APointAboveARidgeCountsItsEdgeOnce) {
  // Two obstacle triangles folded along the edge 1-2 like a roof; the free point 0 hovers above the
  // ridge, closest to the edge for both triangles: one point-edge constraint, κ b(h², d̂²).
  const double h = 1e-3, d_hat = 2e-3, kappa = 10.0;
  const Positions x = rows({{0.5, h, 0}, {0, 0, 0}, {1, 0, 0}, {0.5, -1, -1}, {0.5, -1, 1}});
  const CollisionMesh mesh = make_collision_mesh(x, faces({{1, 2, 3}, {2, 1, 4}}), {0, 1, 1, 1, 1});
  const BarrierPotential potential(mesh, d_hat, kappa);
  EXPECT_EQ(point_triangle_type(x.row(0).transpose(), x.row(1).transpose(), x.row(2).transpose(), x.row(3).transpose()),
            PointTriangleType::P_E0);
  EXPECT_NEAR(potential.value(x), kappa * barrier(h * h, d_hat * d_hat).value, 1e-18);
}

TEST(BarrierPotential, InfiniteWhenTouching) {
  const Positions x = rows({{0.2, 0, 0.2}, {0, 0, 0}, {1, 0, 0}, {0, 0, 1}});
  const CollisionMesh mesh = make_collision_mesh(x, faces({{1, 3, 2}}), {0, 1, 1, 1});
  EXPECT_TRUE(std::isinf(BarrierPotential(mesh, 1e-3, 1.0).value(x)));
}

TEST(MaxCollisionFreeStep, StopsAFallingQuadBeforeAThinTriangle) {
  // A free quad 0.1 above a fixed triangle, moved 1 down: contact at t = 0.1.
  const Positions x = rows({{0.2, 0.1, 0.2}, {0.4, 0.1, 0.2}, {0.2, 0.1, 0.4}, {0.4, 0.1, 0.4},
                            {0, 0, 0}, {1, 0, 0}, {0, 0, 1}});
  const CollisionMesh mesh = make_collision_mesh(x, faces({{0, 2, 1}, {1, 2, 3}, {4, 6, 5}}), {0, 0, 0, 0, 1, 1, 1});
  Positions dx = Positions::Zero(7, 3);
  dx.topRows(4).col(1).setConstant(-1.0);
  const double t = max_collision_free_step(mesh, x, dx);
  EXPECT_LT(t, 0.1);
  EXPECT_GT(t, 0.05);
  const Positions end = x + t * dx;
  EXPECT_GT(min_distance_sq(mesh, end, proximity_candidates(mesh, end, 1.0)), 0.0);
  // Moving sideways, parallel to the triangle: the whole step is free.
  dx.setZero();
  dx.topRows(4).col(0).setConstant(0.3);
  EXPECT_EQ(max_collision_free_step(mesh, x, dx), 1.0);
}

}  // namespace
}  // namespace amt::refit
