#include "refit/barrier.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "finite_difference.h"

namespace amt::refit {
namespace {

TEST(Barrier, ValuesByHand) {
  const double s_hat = 1e-6;
  EXPECT_EQ(barrier(s_hat, s_hat).value, 0.0);
  EXPECT_EQ(barrier(2 * s_hat, s_hat).value, 0.0);
  EXPECT_TRUE(std::isinf(barrier(0.0, s_hat).value));
  EXPECT_TRUE(std::isinf(barrier(-1.0, s_hat).value));
  // s = ŝ/2: -(ŝ/2)² ln(1/2) = (ŝ²/4) ln 2.
  EXPECT_NEAR(barrier(0.5 * s_hat, s_hat).value, 0.25 * s_hat * s_hat * std::log(2.0), 1e-25);
  // Decreasing towards ŝ and growing without bound (logarithmically) towards 0: near 0 it is about
  // -ŝ² ln(s/ŝ), 27.63 ŝ² at s = 10⁻¹² ŝ.
  EXPECT_GT(barrier(1e-3 * s_hat, s_hat).value, barrier(1e-1 * s_hat, s_hat).value);
  EXPECT_NEAR(barrier(1e-12 * s_hat, s_hat).value, -s_hat * s_hat * std::log(1e-12), 1e-9 * s_hat * s_hat);
  EXPECT_GT(barrier(1e-300, s_hat).value, 20 * barrier(1e-1 * s_hat, s_hat).value);
}

TEST(Barrier, DerivativesMatchFiniteDifferencesAndVanishAtTheThreshold) {
  const double s_hat = 4e-6;
  for (double r : {0.01, 0.1, 0.3, 0.5, 0.9, 0.999}) {
    const double s = r * s_hat, h = 1e-4 * std::min(s, s_hat - s);
    const ScalarDerivatives b = barrier(s, s_hat);
    const double fd1 = (barrier(s + h, s_hat).value - barrier(s - h, s_hat).value) / (2 * h);
    const double fd2 = (barrier(s + h, s_hat).first - barrier(s - h, s_hat).first) / (2 * h);
    EXPECT_NEAR(b.first, fd1, 1e-6 * std::max(1e-12, std::abs(fd1))) << "s = " << r << " ŝ";
    EXPECT_NEAR(b.second, fd2, 1e-6 * std::max(1.0, std::abs(fd2))) << "s = " << r << " ŝ";
    EXPECT_LT(b.first, 0.0);
    EXPECT_GT(b.second, 0.0);
  }
  // C²: value, slope and curvature all tend to 0 at ŝ from below.
  const ScalarDerivatives near = barrier(s_hat * (1 - 1e-6), s_hat);
  EXPECT_NEAR(near.value, 0.0, 1e-20);
  EXPECT_NEAR(near.first, 0.0, 1e-16);
  EXPECT_NEAR(near.second, 0.0, 1e-5);  // b'' ≈ 6 (1 - s/ŝ)
}

TEST(Mollifier, OneAwayFromParallelZeroWhenParallel) {
  const Eigen::Vector3d a0(0, 0, 0), a1(1, 0, 0);
  const double eps = edge_edge_mollifier_threshold(1.0, 1.0);
  EXPECT_DOUBLE_EQ(eps, 1e-3);
  const Mollifier crossing = edge_edge_mollifier(a0, a1, {0.5, -0.5, 1}, {0.5, 0.5, 1}, eps);
  EXPECT_FALSE(crossing.active);
  EXPECT_EQ(crossing.value, 1.0);
  const Mollifier parallel = edge_edge_mollifier(a0, a1, {0, 1, 0}, {1, 1, 0}, eps);
  EXPECT_TRUE(parallel.active);
  EXPECT_EQ(parallel.value, 0.0);
}

TEST(Mollifier, DerivativesMatchFiniteDifferences) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.004, 0.004);
  for (int trial = 0; trial < 20; ++trial) {
    // Nearly parallel edges, so that c = |ea × eb|² is below ε and the mollifier is active.
    Eigen::VectorXd x(12);
    x << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0;
    for (int i = 0; i < 12; ++i) x[i] += u(rng);
    const double eps = 1e-3;
    auto eval = [eps](const Eigen::VectorXd& y) {
      return edge_edge_mollifier(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6), y.segment<3>(9), eps);
    };
    const Mollifier m = eval(x);
    ASSERT_TRUE(m.active);
    auto f = [&](const Eigen::VectorXd& y) { return eval(y).value; };
    auto g = [&](const Eigen::VectorXd& y) { return Eigen::VectorXd(eval(y).gradient); };
    EXPECT_LT(test::relative_error(m.gradient, test::fd_gradient(f, x, 1e-7)), 1e-5);
    EXPECT_LT(test::relative_error(m.hessian, test::fd_jacobian(g, x, 1e-7)), 1e-4);
  }
}

}  // namespace
}  // namespace amt::refit
