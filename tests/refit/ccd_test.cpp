#include "refit/ccd.h"

#include <gtest/gtest.h>

#include <random>

#include "refit/distance.h"

namespace amt::refit {
namespace {

using Eigen::Vector3d;

const Vector3d T0(0, 0, 0), T1(1, 0, 0), T2(0, 1, 0);
const Vector3d Z(0, 0, 0);

TEST(PointTriangleCcd, CatchesAPointFallingThroughTheFace) {
  // From height 1 to height -1: contact at t = 0.5. With s = 0.1 the reported time keeps a tenth of the
  // initial gap: the relative speed bound is l_p = 1.5 + 0.5 (the mean motion removed), the first step
  // 0.9 · 1 / 2 = 0.45 leaves exactly 0.1, the next would leave 0.01: toi = 0.45.
  double toi = -1;
  ASSERT_TRUE(point_triangle_ccd({0.25, 0.25, 1}, T0, T1, T2, {0, 0, -2}, Z, Z, Z, 1.0, &toi));
  EXPECT_NEAR(toi, 0.45, 1e-12);
  EXPECT_LE(toi, 0.5);
}

TEST(PointTriangleCcd, CatchesAVeryFastPointAndReportsASafeTime) {
  for (double speed : {10.0, 1e3, 1e6}) {
    double toi = -1;
    const Vector3d p(0.2, 0.3, 0.01), dp(0, 0, -speed);
    ASSERT_TRUE(point_triangle_ccd(p, T0, T1, T2, dp, Z, Z, Z, 1.0, &toi)) << speed;
    const double contact = 0.01 / speed;
    EXPECT_LE(toi, contact) << speed;
    EXPECT_GT(toi, 0.5 * contact) << speed;
    const Vector3d at = p + toi * dp;
    EXPECT_GE(point_triangle_distance_sq(at, T0, T1, T2), 0.1 * 0.1 * 0.01 * 0.01 * (1 - 1e-9)) << speed;
  }
}

TEST(PointTriangleCcd, CatchesAMovingTriangleSweepingOverAStillPoint) {
  double toi = -1;
  const Vector3d d(0, 0, 2);
  ASSERT_TRUE(point_triangle_ccd({0.25, 0.25, 1}, T0, T1, T2, Z, d, d, d, 1.0, &toi));
  EXPECT_NEAR(toi, 0.45, 1e-12);
}

TEST(PointTriangleCcd, MissesWhatPassesBesideOrStopsShort) {
  double toi = -1;
  // Sliding parallel to the face at height 0.5.
  EXPECT_FALSE(point_triangle_ccd({0.2, 0.2, 0.5}, T0, T1, T2, {0.3, 0.1, 0}, Z, Z, Z, 1.0, &toi));
  // Falling beside the triangle (x + y > 1 stays outside it) all the way down.
  EXPECT_FALSE(point_triangle_ccd({2, 2, 1}, T0, T1, T2, {0, 0, -2}, Z, Z, Z, 1.0, &toi));
  // Falling towards the face but stopping at a third of the gap: farther than s of it, no report.
  EXPECT_FALSE(point_triangle_ccd({0.25, 0.25, 1}, T0, T1, T2, {0, 0, -0.66}, Z, Z, Z, 1.0, &toi));
  // Not moving relative to each other: a common translation.
  const Vector3d d(5, -3, 7);
  EXPECT_FALSE(point_triangle_ccd({0.25, 0.25, 0.001}, T0, T1, T2, d, d, d, d, 1.0, &toi));
}

TEST(PointTriangleCcd, GrazingAnEdgeIsCaught) {
  // The point passes exactly through the edge t0t1 at t = 0.5 (a touch, not a crossing).
  double toi = -1;
  ASSERT_TRUE(point_triangle_ccd({0.5, -1, 1}, T0, T1, T2, {0, 2, -2}, Z, Z, Z, 1.0, &toi));
  EXPECT_LE(toi, 0.5);
  EXPECT_GT(toi, 0.0);
}

TEST(PointTriangleCcd, TouchingAtTheStartReportsZero) {
  double toi = -1;
  ASSERT_TRUE(point_triangle_ccd({0.25, 0.25, 0}, T0, T1, T2, {0, 0, 1}, Z, Z, Z, 1.0, &toi));
  EXPECT_EQ(toi, 0.0);
}

TEST(EdgeEdgeCcd, CatchesAnEdgeCrossingAnEdge) {
  // Edge b, crossing edge a from height 1 to -1: contact at t = 0.5; l_p = 1 + 1, first step 0.45.
  const Vector3d a0(0, 0, 0), a1(1, 0, 0), b0(0.5, -1, 1), b1(0.5, 1, 1), d(0, 0, -2);
  double toi = -1;
  ASSERT_TRUE(edge_edge_ccd(a0, a1, b0, b1, Z, Z, d, d, 1.0, &toi));
  EXPECT_NEAR(toi, 0.45, 1e-12);
  // Very fast.
  ASSERT_TRUE(edge_edge_ccd(a0, a1, b0, b1, Z, Z, 1e5 * d, 1e5 * d, 1.0, &toi));
  EXPECT_LE(toi, 0.5e-5);
  EXPECT_GT(toi, 0.0);
  // Passing beyond the end of edge a: no contact.
  const Vector3d far(2, 0, 0);
  EXPECT_FALSE(edge_edge_ccd(a0, a1, b0 + far, b1 + far, Z, Z, d, d, 1.0, &toi));
}

TEST(EdgeEdgeCcd, CatchesParallelEdgesMeeting) {
  const Vector3d a0(0, 0, 0), a1(1, 0, 0), b0(0.2, 1, 0), b1(1.2, 1, 0), d(0, -2, 0);
  double toi = -1;
  ASSERT_TRUE(edge_edge_ccd(a0, a1, b0, b1, Z, Z, d, d, 1.0, &toi));
  EXPECT_LE(toi, 0.5);
  EXPECT_GT(toi, 0.4);
}

// Random crossings with a known contact: a point of one primitive meets a point of the other at t*.
// The first contact can only be earlier, so CCD must report a time ≤ t* at which both are still apart.
TEST(Ccd, NeverReportsATimeAfterAConstructedContact) {
  std::mt19937 rng(2021);
  std::uniform_real_distribution<double> u(-1.0, 1.0), unit(0.0, 1.0);
  auto rand3 = [&] { return Vector3d(u(rng), u(rng), u(rng)); };
  int checked = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const double t_star = 0.05 + 0.9 * unit(rng);
    // Point-triangle: the triangle moves arbitrarily; the point passes through its barycentric point w.
    Vector3d t[3], dt[3];
    for (int k = 0; k < 3; ++k) t[k] = rand3(), dt[k] = rand3();
    double w1 = unit(rng), w2 = unit(rng);
    if (w1 + w2 > 1) w1 = 1 - w1, w2 = 1 - w2;
    const double w[3] = {1 - w1 - w2, w1, w2};
    Vector3d meet = Vector3d::Zero();
    for (int k = 0; k < 3; ++k) meet += w[k] * (t[k] + t_star * dt[k]);
    const Vector3d dp = 3.0 * rand3();
    const Vector3d p = meet - t_star * dp;
    if (point_triangle_distance_sq(p, t[0], t[1], t[2]) < 1e-8) continue;  // starts touching
    double toi = -1;
    ASSERT_TRUE(point_triangle_ccd(p, t[0], t[1], t[2], dp, dt[0], dt[1], dt[2], 1.0, &toi)) << trial;
    EXPECT_LE(toi, t_star) << trial;
    EXPECT_GT(point_triangle_distance_sq(p + toi * dp, t[0] + toi * dt[0], t[1] + toi * dt[1], t[2] + toi * dt[2]),
              0.0)
        << trial;
    // Edge-edge: edge b passes through the point of edge a at parameter s, with its own parameter r.
    Vector3d a0 = rand3(), a1 = rand3(), da0 = rand3(), da1 = rand3();
    const double s = unit(rng), r = unit(rng);
    const Vector3d on_a = (1 - s) * (a0 + t_star * da0) + s * (a1 + t_star * da1);
    const Vector3d db0 = rand3(), db1 = rand3(), span = rand3();
    // b(t*) = on_a + (1 - r)·(−span) + r·(... ) chosen so that (1 - r) b0(t*) + r b1(t*) = on_a.
    const Vector3d b0_star = on_a - r * span, b1_star = on_a + (1 - r) * span;
    const Vector3d b0 = b0_star - t_star * db0, b1 = b1_star - t_star * db1;
    if (edge_edge_distance_sq(a0, a1, b0, b1) < 1e-8) continue;
    ASSERT_TRUE(edge_edge_ccd(a0, a1, b0, b1, da0, da1, db0, db1, 1.0, &toi)) << trial;
    EXPECT_LE(toi, t_star) << trial;
    EXPECT_GT(edge_edge_distance_sq(a0 + toi * da0, a1 + toi * da1, b0 + toi * db0, b1 + toi * db1), 0.0) << trial;
    ++checked;
  }
  EXPECT_GT(checked, 400);
}

}  // namespace
}  // namespace amt::refit
