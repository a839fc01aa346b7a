#include "refit/distance.h"

#include <gtest/gtest.h>

#include <random>

#include "finite_difference.h"

namespace amt::refit {
namespace {

using Eigen::Vector3d;

// The triangle of the hand-computed cases: the unit right triangle in the z = 0 plane.
const Vector3d T0(0, 0, 0), T1(1, 0, 0), T2(0, 1, 0);

struct PointTriangleCase {
  Vector3d p;
  PointTriangleType type;
  double distance_sq;
};

TEST(PointTriangleDistance, HandComputedForEveryClosestFeature) {
  const PointTriangleCase cases[] = {
      {{0.25, 0.25, 0.5}, PointTriangleType::P_T, 0.25},  // above the face: the height, 0.5²
      {{-1, -1, 0.5}, PointTriangleType::P_T0, 2.25},     // 1 + 1 + 0.25
      {{2, -1, 0}, PointTriangleType::P_T1, 2.0},         // to (1,0,0): 1 + 1
      {{-1, 2, 0}, PointTriangleType::P_T2, 2.0},         // to (0,1,0): 1 + 1
      {{0.5, -1, 1}, PointTriangleType::P_E0, 2.0},       // to (0.5,0,0) on t0t1: 1 + 1
      {{1, 1, 0}, PointTriangleType::P_E1, 0.5},          // to the line x + y = 1: (1/√2)²
      {{-2, 0.5, 0}, PointTriangleType::P_E2, 4.0},       // to (0,0.5,0) on t2t0: 2²
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(::testing::Message() << "p = " << c.p.transpose());
    EXPECT_EQ(point_triangle_type(c.p, T0, T1, T2), c.type);
    EXPECT_NEAR(point_triangle_distance_sq(c.p, T0, T1, T2), c.distance_sq, 1e-14);
    EXPECT_NEAR(point_triangle_distance_sq(c.p, T0, T1, T2, c.type), c.distance_sq, 1e-14);
    EXPECT_NEAR(point_triangle_distance_sq_derivatives(c.p, T0, T1, T2, c.type).value, c.distance_sq, 1e-14);
  }
}

TEST(PointTriangleDistance, DegenerateTriangleUsesItsEdges) {
  // Collinear corners: the "face" has no interior; the closest feature is on the segment from t0 to t2.
  const Vector3d a(0, 0, 0), b(1, 0, 0), c(2, 0, 0);
  const Vector3d p(0.5, 0, 1);
  const PointTriangleType type = point_triangle_type(p, a, b, c);
  EXPECT_NE(type, PointTriangleType::P_T);
  EXPECT_NEAR(point_triangle_distance_sq(p, a, b, c), 1.0, 1e-14);
  // A repeated corner: a zero-length edge is never the closest edge interior.
  const Vector3d q(-1, -1, 0);
  EXPECT_EQ(point_triangle_type(q, a, a, c), PointTriangleType::P_T0);
  EXPECT_NEAR(point_triangle_distance_sq(q, a, a, c), 2.0, 1e-14);
}

struct EdgeEdgeCase {
  Vector3d eb0, eb1;
  EdgeEdgeType type;
  double distance_sq;
};

TEST(EdgeEdgeDistance, HandComputedForEveryClosestFeature) {
  // Edge a runs from (0,0,0) to (1,0,0).
  const Vector3d ea0(0, 0, 0), ea1(1, 0, 0);
  const EdgeEdgeCase cases[] = {
      {{0.5, -1, 1}, {0.5, 1, 1}, EdgeEdgeType::EA_EB, 1.0},     // crossing above: height 1
      {{-1, -1, 1}, {-1, 1, 1}, EdgeEdgeType::EA0_EB, 2.0},      // ea0 to (-1,0,1)
      {{2, -1, 1}, {2, 1, 1}, EdgeEdgeType::EA1_EB, 2.0},        // ea1 to (2,0,1)
      {{0.5, 0, 1}, {0.5, 0, 2}, EdgeEdgeType::EA_EB0, 1.0},     // eb0 above the middle of a
      {{0.5, 0, 2}, {0.5, 0, 1}, EdgeEdgeType::EA_EB1, 1.0},     // eb1 above the middle of a
      {{-1, -1, 0}, {-2, -2, 0}, EdgeEdgeType::EA0_EB0, 2.0},    // ea0 to eb0
      {{-2, -2, 0}, {-1, -1, 0}, EdgeEdgeType::EA0_EB1, 2.0},    // ea0 to eb1
      {{2, -1, 0}, {3, -2, 0}, EdgeEdgeType::EA1_EB0, 2.0},      // ea1 to eb0
      {{3, -2, 0}, {2, -1, 0}, EdgeEdgeType::EA1_EB1, 2.0},      // ea1 to eb1
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(::testing::Message() << "eb = " << c.eb0.transpose() << " -> " << c.eb1.transpose());
    EXPECT_EQ(edge_edge_type(ea0, ea1, c.eb0, c.eb1), c.type);
    EXPECT_NEAR(edge_edge_distance_sq(ea0, ea1, c.eb0, c.eb1), c.distance_sq, 1e-14);
    EXPECT_NEAR(edge_edge_distance_sq(ea0, ea1, c.eb0, c.eb1, c.type), c.distance_sq, 1e-14);
    EXPECT_NEAR(edge_edge_distance_sq_derivatives(ea0, ea1, c.eb0, c.eb1, c.type).value, c.distance_sq, 1e-14);
  }
}

TEST(EdgeEdgeDistance, ParallelEdgesAvoidTheSingularLineLineCase) {
  const Vector3d ea0(0, 0, 0), ea1(1, 0, 0), eb0(0.5, 1, 0), eb1(1.5, 1, 0);
  const EdgeEdgeType type = edge_edge_type(ea0, ea1, eb0, eb1);
  EXPECT_NE(type, EdgeEdgeType::EA_EB);
  EXPECT_NEAR(edge_edge_distance_sq(ea0, ea1, eb0, eb1), 1.0, 1e-14);
  EXPECT_NEAR(edge_edge_distance_sq(ea0, ea1, eb0, eb1, type), 1.0, 1e-14);
}

// The derivatives of every piece against central differences, at random non-degenerate points.
template <typename Piece>
void check_derivatives(Piece piece, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::VectorXd x(12);
    for (int i = 0; i < 12; ++i) x[i] = u(rng);
    auto f = [&](const Eigen::VectorXd& y) { return piece(y).value; };
    auto g = [&](const Eigen::VectorXd& y) { return Eigen::VectorXd(piece(y).gradient); };
    const Derivatives12 d = piece(x);
    EXPECT_LT(test::relative_error(d.gradient, test::fd_gradient(f, x, 1e-6)), 1e-6);
    EXPECT_LT(test::relative_error(d.hessian, test::fd_jacobian(g, x, 1e-6)), 1e-5);
    EXPECT_LT((d.hessian - d.hessian.transpose()).cwiseAbs().maxCoeff(), 1e-10);
  }
}

TEST(DistanceDerivatives, MatchFiniteDifferencesForEveryPiece) {
  std::mt19937 rng(14);
  for (int t = 0; t <= static_cast<int>(PointTriangleType::P_T); ++t) {
    SCOPED_TRACE(::testing::Message() << "point-triangle type " << t);
    check_derivatives(
        [t](const Eigen::VectorXd& y) {
          return point_triangle_distance_sq_derivatives(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6),
                                                        y.segment<3>(9), static_cast<PointTriangleType>(t));
        },
        rng);
  }
  for (int t = 0; t <= static_cast<int>(EdgeEdgeType::EA_EB); ++t) {
    SCOPED_TRACE(::testing::Message() << "edge-edge type " << t);
    check_derivatives(
        [t](const Eigen::VectorXd& y) {
          return edge_edge_distance_sq_derivatives(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6),
                                                   y.segment<3>(9), static_cast<EdgeEdgeType>(t));
        },
        rng);
  }
}

TEST(DistanceClassification, AgreesWithBruteForceClosestPoints) {
  // The classified distance is the true distance: compare against a dense sampling of the triangle and
  // of the segment pairs (the sampled minimum can only be larger).
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 50; ++trial) {
    Vector3d q[4];
    for (auto& v : q) v = Vector3d(u(rng), u(rng), u(rng));
    double best_pt = 1e300, best_ee = 1e300;
    const int n = 60;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= n; ++j) {
        const double a = double(i) / n, b = double(j) / n;
        if (a + b <= 1.0) best_pt = std::min(best_pt, (q[0] - (q[1] + a * (q[2] - q[1]) + b * (q[3] - q[1]))).squaredNorm());
        best_ee = std::min(best_ee, ((q[0] + a * (q[1] - q[0])) - (q[2] + b * (q[3] - q[2]))).squaredNorm());
      }
    const double pt = point_triangle_distance_sq(q[0], q[1], q[2], q[3]);
    const double ee = edge_edge_distance_sq(q[0], q[1], q[2], q[3]);
    EXPECT_LE(pt, best_pt + 1e-12);
    EXPECT_LE(ee, best_ee + 1e-12);
    EXPECT_NEAR(std::sqrt(pt), std::sqrt(best_pt), 0.05);
    EXPECT_NEAR(std::sqrt(ee), std::sqrt(best_ee), 0.05);
    // The piece of the classified type gives the same value.
    EXPECT_NEAR(point_triangle_distance_sq(q[0], q[1], q[2], q[3], point_triangle_type(q[0], q[1], q[2], q[3])), pt,
                1e-12);
    EXPECT_NEAR(edge_edge_distance_sq(q[0], q[1], q[2], q[3], edge_edge_type(q[0], q[1], q[2], q[3])), ee, 1e-12);
  }
}

}  // namespace
}  // namespace amt::refit
