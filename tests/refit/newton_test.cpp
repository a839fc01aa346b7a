#include "refit/newton.h"

#include <gtest/gtest.h>

#include <cmath>

#include "exact_intersection.h"
#include "refit/barrier.h"

namespace amt::refit {
namespace {

// --- Test energies: an implicit Euler step of a mass-spring cloth (IPC's incremental potential)

// ½ m/h² |x - x̃|² over the free vertices, x̃ = x_n + h v_n + h² g: inertia and gravity of one step.
class InertiaTerm : public Objective {
 public:
  InertiaTerm(Positions predicted, double mass, double dt, std::vector<uint8_t> fixed)
      : predicted_(std::move(predicted)), k_(mass / (dt * dt)), fixed_(std::move(fixed)) {}
  double value(const Positions& x) const override { return derivatives(x, nullptr, nullptr); }
  double derivatives(const Positions& x, Eigen::VectorXd* g, std::vector<Eigen::Triplet<double>>* H) const override {
    double e = 0;
    for (int v = 0; v < x.rows(); ++v) {
      if (fixed_[v]) continue;
      const Eigen::RowVector3d d = x.row(v) - predicted_.row(v);
      e += 0.5 * k_ * d.squaredNorm();
      if (g) g->segment<3>(3 * v) += k_ * d.transpose();
      if (H)
        for (int a = 0; a < 3; ++a) H->emplace_back(3 * v + a, 3 * v + a, k_);
    }
    return e;
  }

 private:
  Positions predicted_;
  double k_;
  std::vector<uint8_t> fixed_;
};

// Σ ½ k (|x_i - x_j| - L)² over edges, each 6 by 6 Hessian projected to PSD (the (1 - L/l) transverse
// stiffness is clamped at 0 for compressed springs, the standard projection of a spring).
class SpringTerm : public Objective {
 public:
  SpringTerm(const MatrixX2i& E, const Positions& rest, double k) : E_(E), k_(k), L_(E.rows()) {
    for (int e = 0; e < E.rows(); ++e) L_[e] = (rest.row(E(e, 0)) - rest.row(E(e, 1))).norm();
  }
  double value(const Positions& x) const override { return derivatives(x, nullptr, nullptr); }
  double derivatives(const Positions& x, Eigen::VectorXd* g, std::vector<Eigen::Triplet<double>>* H) const override {
    double energy = 0;
    for (int e = 0; e < E_.rows(); ++e) {
      const int i = E_(e, 0), j = E_(e, 1);
      const Eigen::Vector3d d = (x.row(i) - x.row(j)).transpose();
      const double l = d.norm();
      energy += 0.5 * k_ * (l - L_[e]) * (l - L_[e]);
      const Eigen::Vector3d u = d / l;
      if (g) {
        g->segment<3>(3 * i) += k_ * (l - L_[e]) * u;
        g->segment<3>(3 * j) -= k_ * (l - L_[e]) * u;
      }
      if (H) {
        const Eigen::Matrix3d uu = u * u.transpose();
        const Eigen::Matrix3d K = k_ * (uu + std::max(0.0, 1.0 - L_[e] / l) * (Eigen::Matrix3d::Identity() - uu));
        const int v[2] = {i, j};
        for (int a = 0; a < 2; ++a)
          for (int b = 0; b < 2; ++b)
            for (int r = 0; r < 3; ++r)
              for (int c = 0; c < 3; ++c) H->emplace_back(3 * v[a] + r, 3 * v[b] + c, (a == b ? 1 : -1) * K(r, c));
      }
    }
    return energy;
  }

 private:
  MatrixX2i E_;
  double k_;
  std::vector<double> L_;
};

// A square cloth of n by n vertices, side `size`, at height y, over a fixed thin square plate (two
// triangles of zero thickness, half-width `plate`) at y = 0. Cloth vertices first, plate last.
struct DropScene {
  Positions x;
  MatrixX3i F;
  std::vector<uint8_t> fixed;
  int cloth_vertices = 0;
};

DropScene drop_scene(int n, double size, double y, double plate) {
  DropScene s;
  s.cloth_vertices = n * n;
  s.x.resize(n * n + 4, 3);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      s.x.row(i * n + j) << size * (double(j) / (n - 1) - 0.5), y, size * (double(i) / (n - 1) - 0.5);
  const int p = n * n;
  s.x.row(p + 0) << -plate, 0, -plate;
  s.x.row(p + 1) << plate, 0, -plate;
  s.x.row(p + 2) << -plate, 0, plate;
  s.x.row(p + 3) << plate, 0, plate;
  s.F.resize(2 * (n - 1) * (n - 1) + 2, 3);
  int f = 0;
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j + 1 < n; ++j) {
      const int a = i * n + j, b = a + 1, c = a + n, d = c + 1;
      s.F.row(f++) << a, c, b;
      s.F.row(f++) << b, c, d;
    }
  s.F.row(f++) << p + 0, p + 2, p + 1;
  s.F.row(f++) << p + 1, p + 2, p + 3;
  s.fixed.assign(n * n + 4, 0);
  for (int k = 0; k < 4; ++k) s.fixed[p + k] = 1;
  return s;
}

struct StepLog {
  int steps = 0;
  int crossings = 0;       // root-finding check over every accepted step
  int intersections = 0;   // exact static check after every accepted step
  double min_ccd_bound = 1.0;
};

// Runs implicit Euler steps of the falling cloth, checking every accepted Newton step independently.
StepLog simulate(DropScene& s, double speed, int time_steps, bool ccd_filter, NewtonResult* last = nullptr) {
  const double dt = 1.0 / 30.0, mass = 0.01, d_hat = 2e-3;
  const CollisionMesh mesh = make_collision_mesh(s.x, s.F, s.fixed);
  // κ: the barrier's push 2κ d̂⁴/d balances the inertia of the impact step (about 2 N a vertex) near
  // d = 3e-4 m.
  const BarrierPotential potential(mesh, d_hat, 1e7);
  const BarrierObjective contact(potential);
  const SpringTerm springs(mesh.E, s.x, 50.0);
  Positions velocity = Positions::Zero(s.x.rows(), 3);
  for (int v = 0; v < s.cloth_vertices; ++v) velocity(v, 1) = -speed;
  StepLog log;
  NewtonOptions options;
  options.ccd_filter = ccd_filter;
  options.max_iterations = 100;
  for (int step = 0; step < time_steps; ++step) {
    Positions predicted = s.x + dt * velocity;
    for (int v = 0; v < s.cloth_vertices; ++v) predicted(v, 1) -= dt * dt * 9.8;
    const InertiaTerm inertia(predicted, mass, dt, s.fixed);
    const Positions start = s.x;
    const NewtonResult result = projected_newton(
        {&inertia, &springs, &contact}, &mesh, s.fixed, &s.x, options, [&](const NewtonStep& st) {
          ++log.steps;
          log.min_ccd_bound = std::min(log.min_ccd_bound, st.ccd_bound);
          log.crossings += test::count_crossings(mesh, *st.before, *st.after);
          log.intersections += test::count_intersecting_triangle_pairs(*st.after, s.F, s.fixed);
        });
    if (last) *last = result;
    velocity = (s.x - start) / dt;
  }
  return log;
}

TEST(ProjectedNewton, NoAcceptedStepPassesThroughAThinPlate) {
  // Falling at 6 m/s: one time step of 1/30 s would carry the cloth 0.2 m, through the plate 0.03 below.
  DropScene s = drop_scene(7, 0.4, 0.03, 0.1);
  NewtonResult result;
  const StepLog log = simulate(s, 6.0, 3, /*ccd_filter=*/true, &result);
  EXPECT_GT(log.steps, 3);
  EXPECT_LT(log.min_ccd_bound, 1.0) << "CCD should have shortened some step";
  EXPECT_EQ(log.crossings, 0);
  EXPECT_EQ(log.intersections, 0);
  EXPECT_TRUE(result.converged) << result.stop_reason;
  // The cloth over the plate rests on it, above it and closer than d̂.
  const int centre = 3 * 7 + 3;
  EXPECT_GT(s.x(centre, 1), 0.0);
  EXPECT_LT(s.x(centre, 1), 2e-3);
}

TEST(ProjectedNewton, WithoutTheCcdFilterTheSameDropTunnels) {
  // The checks have teeth: the unfiltered line search accepts the full Newton step through the plate.
  DropScene s = drop_scene(7, 0.4, 0.03, 0.1);
  const StepLog log = simulate(s, 6.0, 1, /*ccd_filter=*/false);
  EXPECT_GT(log.crossings, 0);
  EXPECT_LT(s.x(3 * 7 + 3, 1), 0.0) << "the cloth ends below the plate";
}

TEST(ProjectedNewton, PullPastATriangleStopsInFrontOfIt) {
  // One free point pulled by a spring towards a target 1 m below a fixed triangle: the minimiser with
  // the barrier sits just above the triangle (0 < y < d̂); the first Newton step (straight to the target)
  // is cut by CCD.
  Positions x(4, 3);
  x << 0.2, 0.5, 0.2, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  MatrixX3i F(1, 3);
  F << 1, 3, 2;
  const std::vector<uint8_t> fixed = {0, 1, 1, 1};
  const CollisionMesh mesh = make_collision_mesh(x, F, fixed);
  // κ = 1e4: the barrier's push 2κ d̂⁴/y balances the pull of 0.5 near y = 4e-4.
  const BarrierPotential potential(mesh, 1e-2, 1e4);
  const BarrierObjective contact(potential);
  Positions target = x;
  target(0, 1) = -0.5;
  const InertiaTerm pull(target, 1.0, 1.0, fixed);
  int steps = 0, crossings = 0;
  NewtonOptions options;
  options.tolerance = 1e-10;  // solved tightly, to compare with the balance of forces below
  const NewtonResult result = projected_newton({&pull, &contact}, &mesh, fixed, &x, options, [&](const NewtonStep& st) {
    ++steps;
    crossings += test::count_crossings(mesh, *st.before, *st.after);
  });
  EXPECT_TRUE(result.converged) << result.stop_reason;
  EXPECT_EQ(crossings, 0);
  EXPECT_GT(x(0, 1), 0.0);
  EXPECT_LT(x(0, 1), 1e-2);
  EXPECT_NEAR(x(0, 0), 0.2, 1e-9);
  EXPECT_NEAR(x(0, 2), 0.2, 1e-9);
  // At the minimiser the barrier's push balances the pull: d/dy [½ (y + 0.5)² + b(y², d̂²)] = 0.
  const double y = x(0, 1);
  const double slope = (y + 0.5) + 1e4 * barrier(y * y, 1e-4).first * 2 * y;
  EXPECT_NEAR(slope, 0.0, 1e-6);
}

TEST(ExactIntersection, CountsACrossingPairAndIgnoresSharedEdges) {
  Positions V(7, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 1,  // a flat quad of two triangles sharing the edge 1-2
      0.3, -0.5, 0.3, 0.3, 0.5, 0.3, 0.8, 0.5, 0.2;  // a triangle piercing the quad
  MatrixX3i F(3, 3);
  F << 0, 2, 1, 1, 2, 3, 4, 5, 6;
  EXPECT_EQ(test::count_intersecting_triangle_pairs(V, F.topRows(2), {}), 0);
  EXPECT_GE(test::count_intersecting_triangle_pairs(V, F, {}), 1);
  // Left out when both triangles are obstacles.
  EXPECT_EQ(test::count_intersecting_triangle_pairs(V, F, {1, 1, 1, 1, 1, 1, 1}), 0);
}

// k/2 (1 - q_i)²: a quadratic pull of one unknown towards 1 (the shape of the inflation's augmented
// Lagrangian on t).
class PullToOne : public ParameterObjective {
 public:
  PullToOne(int index, double k) : index_(index), k_(k) {}
  double value(const Eigen::VectorXd& q) const override { return 0.5 * k_ * (1 - q[index_]) * (1 - q[index_]); }
  double derivatives(const Eigen::VectorXd& q, Eigen::VectorXd* g, std::vector<Eigen::Triplet<double>>* H) const override {
    (*g)[index_] -= k_ * (1 - q[index_]);
    H->emplace_back(index_, index_, k_);
    return value(q);
  }

 private:
  int index_;
  double k_;
};

TEST(ProjectedNewton, AnObstacleMovedByAnUnknownPushesAFreePointWithoutPassingIt) {
  // The inflation in miniature: a triangle moved by an unknown t from y = 0 (t = 0) to y = 0.5 (t = 1),
  // pulled towards t = 1, under a free point at y = 0.2 tied to where it starts by a weak spring. The
  // triangle cannot pass the point: it pushes it up ahead of itself.
  Positions x(4, 3);
  x << 0.2, 0.2, 0.2, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  MatrixX3i F(1, 3);
  F << 1, 3, 2;
  const CollisionMesh mesh = make_collision_mesh(x, F, {0, 1, 1, 1});
  LinearPositions map;
  map.base = x;
  map.base.row(0).setZero();
  std::vector<Eigen::Triplet<double>> j;
  for (int a = 0; a < 3; ++a) j.emplace_back(a, a, 1.0);      // q[0..2]: the point
  for (int v = 1; v <= 3; ++v) j.emplace_back(3 * v + 1, 3, 0.5);  // q[3] = t: the triangle's height 0.5 t
  map.J.resize(12, 4);
  map.J.setFromTriplets(j.begin(), j.end());
  Eigen::VectorXd q(4);
  q << 0.2, 0.2, 0.2, 0.0;
  const BarrierPotential potential(mesh, 1e-2, 1e4);
  const BarrierObjective contact(potential);
  const InertiaTerm spring(x, 0.1, 1.0, {0, 1, 1, 1});
  const PullToOne pull(3, 100.0);
  int crossings = 0, steps = 0;
  const NewtonResult result = projected_newton({&spring, &contact}, {&pull}, &mesh, map, &q, {}, [&](const NewtonStep& st) {
    ++steps;
    crossings += test::count_crossings(mesh, *st.before, *st.after);
  });
  EXPECT_TRUE(result.converged) << result.stop_reason;
  EXPECT_GT(steps, 1);
  EXPECT_EQ(crossings, 0);
  EXPECT_GT(q[3], 0.9);                     // the triangle got most of the way
  EXPECT_GT(q[1], 0.5 * q[3]);              // and the point is above it
  EXPECT_LT(q[1] - 0.5 * q[3], 1e-2);       // in contact (within d̂)
}

}  // namespace
}  // namespace amt::refit
