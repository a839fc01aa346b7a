#include "refit/fit_term.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>

#include "data_tools/geometry/error.h"
#include "finite_difference.h"
#include "test_meshes.h"

namespace amt::refit {
namespace {

// A sphere of radius 10 cm at (0.3, 1.0, -0.2), 48 by 96 (its faces are within 0.6 mm of the true sphere's
// surface: the chord sag r (1 - cos(π/48))).
struct Ball {
  Positions V;
  MatrixX3i F;
  Eigen::Vector3d center{0.3, 1.0, -0.2};
  double radius = 0.10;
  Ball() { test::sphere(48, 96, radius, center.transpose(), &V, &F); }
};

TEST(AvatarDistanceField, IsTheSignedDistanceToASphere) {
  const Ball ball;
  const AvatarDistanceField field(ball.V, ball.F, 0.004, 0.03);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d dir = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized();
    const double r = 0.08 + 0.045 * (unit(rng) + 1.0);  // 8 to 17 cm: 2 cm in, 7 cm out
    const Eigen::Vector3d p = ball.center + r * dir;
    // Beyond the band the field holds its background value, a voxel and a bit further: 9 voxels, 3.6 cm.
    const double expected = std::clamp(r - ball.radius, -0.036, 0.036);
    Eigen::Vector3d g;
    const double d = field.distance(p, &g);
    EXPECT_NEAR(d, expected, 1.5e-3) << "at radius " << r;
    if (std::abs(r - ball.radius) < 0.02) {
      EXPECT_GT(g.dot(dir), 0.9) << "at radius " << r;  // ∇D: the outward normal
    }
  }
  // Far beyond the band, the background value and no gradient.
  Eigen::Vector3d g;
  EXPECT_NEAR(field.distance(ball.center + Eigen::Vector3d(0.2, 0, 0), &g), 0.036, 1e-6);
  EXPECT_EQ(g.norm(), 0.0);
  EXPECT_LT(field.distance(ball.center), -0.03);
}

TEST(AvatarDistanceField, BadInputIsAnError) {
  const Ball ball;
  EXPECT_THROW(AvatarDistanceField(ball.V, ball.F, 0.0, 0.03), Error);
  EXPECT_THROW(AvatarDistanceField(ball.V, ball.F, 0.004, 0.001), Error);
  MatrixX3i F = ball.F;
  F(5, 1) = int(ball.V.rows());
  EXPECT_THROW(AvatarDistanceField(ball.V, F, 0.004, 0.03), Error);
  Positions V = ball.V;
  V(2, 0) = std::nan("");
  EXPECT_THROW(AvatarDistanceField(V, ball.F, 0.004, 0.03), Error);
}

// A small garment patch around the ball: a tube of 3 rings (24 vertices) at radius 11 to 13 cm.
struct Patch {
  Positions V;
  MatrixX3i F;
  Patch(const Eigen::Vector3d& center) {
    test::tube(3, 8, -0.03, 0.03, 0.115, &V, &F, 0.004, /*staggered=*/true);
    V.rowwise() += center.transpose();
    // Move every vertex to the middle of its voxel cell (4 mm), so that finite differences do not cross a cell.
    for (int v = 0; v < V.rows(); ++v)
      for (int a = 0; a < 3; ++a) V(v, a) = 0.004 * (std::floor(V(v, a) / 0.004) + 0.37 + 0.05 * (a + v % 3));
  }
};

TEST(FitTerm, GradientAndHessianMatchFiniteDifferences) {
  const Ball ball;
  const AvatarDistanceField field(ball.V, ball.F, 0.004, 0.03);
  const Patch patch(ball.center);
  std::vector<uint8_t> fit(patch.V.rows(), 1);
  fit[3] = 0;  // one vertex outside G_fit: no derivatives
  const FitTerm term(field, patch.V, patch.F, fit, 2.0);
  ASSERT_EQ(term.vertices().size(), patch.V.rows() - 1);
  const int n = 3 * int(patch.V.rows());
  Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
  const double e = term.derivatives(patch.V, &g, nullptr);
  EXPECT_GT(e, 0.0);
  EXPECT_NEAR(e, term.value(patch.V), 1e-15);
  const Eigen::VectorXd fd =
      test::fd_position_gradient([&](const Positions& x) { return term.value(x); }, patch.V, 1e-7);
  EXPECT_LT(test::relative_error(g, fd), 1e-6);
  EXPECT_EQ(g.segment<3>(9).norm(), 0.0);
  // The exact Hessian of the interpolant against differences of the gradient.
  std::vector<Eigen::Triplet<double>> exact;
  term.exact_hessian(patch.V, &exact);
  const Eigen::MatrixXd H = test::dense(exact, n);
  const Eigen::MatrixXd fd_H = test::fd_position_jacobian(
      [&](const Positions& x) {
        Eigen::VectorXd gx = Eigen::VectorXd::Zero(n);
        term.derivatives(x, &gx, nullptr);
        return gx;
      },
      patch.V, 1e-7);
  EXPECT_LT(test::relative_error(H, fd_H), 1e-6);
  // The Hessian Newton uses: the same blocks projected to positive semi-definite.
  std::vector<Eigen::Triplet<double>> projected;
  term.derivatives(patch.V, nullptr, &projected);
  const Eigen::MatrixXd P = test::dense(projected, n);
  EXPECT_GE(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(P).eigenvalues().minCoeff(), -1e-12);
  EXPECT_LT(test::relative_error(P, H), 0.5);  // close to the exact one: D ∇²D is small beside ∇D ∇Dᵀ here
}

TEST(FitTerm, IsTheAreaWeightedSquaredDistance) {
  // A flat square of side 2 cm (two triangles) 5 mm above the top of a 10 cm cube: D = 5 mm at every
  // corner (the field of a plane is linear, so its interpolation is exact), and
  // L_fit = w Σ A_v D² = 2 (4e-4 m²) (5e-3 m)² = 2e-8.
  Positions cube(8, 3);
  for (int v = 0; v < 8; ++v)
    cube.row(v) << 0.05 * ((v & 1) ? 1 : -1), 0.05 * ((v & 2) ? 1 : -1), 0.05 * ((v & 4) ? 1 : -1);
  MatrixX3i cube_F(12, 3);
  cube_F << 0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3;
  const AvatarDistanceField field(cube, cube_F, 0.002, 0.01);
  Positions V(4, 3);
  V << -0.01, 0.055, -0.01, 0.01, 0.055, -0.01, 0.01, 0.055, 0.01, -0.01, 0.055, 0.01;
  MatrixX3i F(2, 3);
  F << 0, 2, 1, 0, 3, 2;
  const FitTerm term(field, V, F, std::vector<uint8_t>(4, 1), 2.0);
  EXPECT_NEAR(term.value(V), 2e-8, 1e-12);
  EXPECT_NEAR(term.mean_fit_distance(V), 0.005, 1e-6);
  EXPECT_NEAR(field.distance(Eigen::Vector3d(0, 0, 0)), -0.012, 1e-6);  // inside, beyond the band: -6 voxels
}

TEST(FitRegion, KeepsTheVerticesNearTheSourceAvatar) {
  const Ball ball;
  const AvatarDistanceField field(ball.V, ball.F, 0.004, 0.03);
  Positions V(3, 3);
  V.rowwise() = ball.center.transpose();
  V(0, 0) += 0.11;   // 1 cm out
  V(1, 0) += 0.125;  // 2.5 cm out
  V(2, 1) += 0.2;    // beyond the band
  const std::vector<uint8_t> fit = fit_region(V, field, 0.02);
  EXPECT_EQ(fit, (std::vector<uint8_t>{1, 0, 0}));
}

}  // namespace
}  // namespace amt::refit
