#include "refit/inflation.h"

#include <cmath>
#include <limits>
#include <memory>

#include "data_tools/geometry/error.h"
#include "refit/curve_shape.h"
#include "refit/positional.h"
#include "refit/surface_shape.h"
#include "refit/triangle_intersections.h"

namespace amt::refit {
namespace {

// The unknowns q = [garment coordinates (3 #Vˢ), t].

// L_pos with the skeleton at V^b(t) (section 3.4.3 with 3.5), as a function of q.
class PositionalInflationTerm : public ParameterObjective {
 public:
  PositionalInflationTerm(const PositionalTerm& term, int garment_vertices, const Positions& source_joints,
                          const Positions& target_joints)
      : term_(term), n_(garment_vertices), source_(source_joints), delta_(target_joints - source_joints) {}

  double value(const Eigen::VectorXd& q) const override { return evaluate(q, nullptr, nullptr); }
  double derivatives(const Eigen::VectorXd& q, Eigen::VectorXd* gradient,
                     std::vector<Eigen::Triplet<double>>* hessian) const override {
    return evaluate(q, gradient, hessian);
  }

 private:
  double evaluate(const Eigen::VectorXd& q, Eigen::VectorXd* gradient, std::vector<Eigen::Triplet<double>>* hessian) const {
    const double t = q[3 * n_];
    const Positions x = Eigen::Map<const Positions>(q.data(), n_, 3);
    const Positions joints = source_ + t * delta_;
    Eigen::VectorXd g_x = Eigen::VectorXd::Zero(3 * n_);
    double g_t = 0.0;
    std::vector<Eigen::Matrix4d> blocks;
    const double e = term_.inflation_derivatives(x, joints, delta_, gradient ? &g_x : nullptr,
                                                 gradient ? &g_t : nullptr, hessian ? &blocks : nullptr);
    if (gradient) {
      gradient->head(3 * n_) += g_x;
      (*gradient)[3 * n_] += g_t;
    }
    if (hessian) {
      const std::vector<int>& held = term_.boundary_vertices();
      for (size_t i = 0; i < held.size(); ++i) {
        const int index[4] = {3 * held[i], 3 * held[i] + 1, 3 * held[i] + 2, 3 * n_};
        for (int r = 0; r < 4; ++r)
          for (int c = 0; c < 4; ++c) hessian->emplace_back(index[r], index[c], blocks[i](r, c));
      }
    }
    return e;
  }

  const PositionalTerm& term_;
  int n_;
  Positions source_, delta_;
};

// L_AL = λ1/2 (1 - t)² + λ2 (1 - t) (section 3.5) on the unknown t = q[index].
class AugmentedLagrangianTerm : public ParameterObjective {
 public:
  AugmentedLagrangianTerm(int index, double lambda1, double lambda2) : index_(index), l1_(lambda1), l2_(lambda2) {}
  double value(const Eigen::VectorXd& q) const override {
    const double c = 1.0 - q[index_];
    return 0.5 * l1_ * c * c + l2_ * c;
  }
  double derivatives(const Eigen::VectorXd& q, Eigen::VectorXd* gradient,
                     std::vector<Eigen::Triplet<double>>* hessian) const override {
    const double c = 1.0 - q[index_];
    if (gradient) (*gradient)[index_] += -l1_ * c - l2_;
    if (hessian) hessian->emplace_back(index_, index_, l1_);
    return value(q);
  }

 private:
  int index_;
  double l1_, l2_;
};

}  // namespace

InflationResult inflate_avatar(const Positions& source_garment, const MatrixX3i& F_garment, const ShrunkAvatar& avatar,
                               const Positions& source_joints, const Positions& target_joints, const MatrixX2i& bones,
                               const InflationOptions& options,
                               const std::function<void(const InflationProgress&)>& progress,
                               const std::function<void(const NewtonStep&)>& step_observer) {
  const int n_g = static_cast<int>(source_garment.rows());
  const int n_a = static_cast<int>(avatar.shrunk.rows());
  AMT_CHECK(avatar.target.rows() == n_a, "inflation: the shrunk avatar has ", n_a, " shrunk and ",
            avatar.target.rows(), " target positions");
  AMT_CHECK(target_joints.rows() == source_joints.rows(), "inflation: the source skeleton has ", source_joints.rows(),
            " joints, the target ", target_joints.rows());

  const CollisionMesh mesh = make_garment_avatar_mesh(source_garment, F_garment, avatar.target, avatar.F);
  Positions start(n_g + n_a, 3);
  start << source_garment, avatar.shrunk;
  check_garment_avatar_start(mesh, start, static_cast<int>(F_garment.rows()), "inflation",
                             "the shrunk avatar's");

  // x(q) = base + J q: the garment as it is, the avatar at shrunk + t (target - shrunk).
  LinearPositions map;
  map.base = Positions::Zero(n_g + n_a, 3);
  map.base.bottomRows(n_a) = avatar.shrunk;
  std::vector<Eigen::Triplet<double>> j;
  for (int c = 0; c < 3 * n_g; ++c) j.emplace_back(c, c, 1.0);
  const Positions delta = avatar.target - avatar.shrunk;
  for (int v = 0; v < n_a; ++v)
    for (int a = 0; a < 3; ++a)
      if (delta(v, a) != 0.0) j.emplace_back(3 * (n_g + v) + a, 3 * n_g, delta(v, a));
  map.J.resize(3 * (n_g + n_a), 3 * n_g + 1);
  map.J.setFromTriplets(j.begin(), j.end());
  Eigen::VectorXd q(3 * n_g + 1);
  q.head(3 * n_g) = Eigen::Map<const Eigen::VectorXd>(source_garment.data(), 3 * n_g);
  q[3 * n_g] = 0.0;

  // Eq. 6: L_AL + L_surf + w_pos L_pos + w_contact L_contact + L_curve.
  const SurfaceShapeTerm surface(source_garment, F_garment, options.weights.surface_weight);
  const CurveShapeTerm curve(source_garment, F_garment, options.weights.curve_weight);
  const PositionalTerm positional(source_garment, F_garment, source_joints, bones, options.weights.positional_weight);
  const PositionalInflationTerm positional_t(positional, n_g, source_joints, target_joints);
  const BarrierPotential potential(mesh, options.weights.d_hat, options.weights.contact_weight);
  const BarrierObjective contact(potential);

  InflationResult result;
  double lambda1 = options.lambda1, lambda2 = 0.0;
  for (int outer = 0; outer < options.max_outer_iterations; ++outer) {
    const AugmentedLagrangianTerm al(3 * n_g, lambda1, lambda2);
    const NewtonResult newton =
        projected_newton({&surface, &curve, &contact}, {&positional_t, &al}, &mesh, map, &q, options.newton, step_observer);
    const double t = q[3 * n_g];
    const Positions x = map.at(q);
    result.outer_iterations = outer + 1;
    if (progress) {
      InflationProgress p;
      p.outer_iteration = outer;
      p.t = t;
      p.energy = newton.energy;
      p.min_distance = std::sqrt(min_distance_sq(mesh, x, proximity_candidates(mesh, x, 10 * options.weights.d_hat)));
      p.newton_iterations = newton.iterations;
      progress(p);
    }
    // Snap to t = 1 once CCD certifies the rest of the inflation (the garment held still).
    Eigen::VectorXd dq = Eigen::VectorXd::Zero(q.size());
    dq[3 * n_g] = 1.0 - t;
    const Eigen::VectorXd dx_flat = map.J * dq;
    const Positions dx = Eigen::Map<const Positions>(dx_flat.data(), n_g + n_a, 3);
    if (max_collision_free_step(mesh, x, dx, options.newton.ccd) >= 1.0) {
      q[3 * n_g] = 1.0;
      result.snapped = true;
      result.stop_reason = "snapped to t = 1";
      break;
    }
    // Multiplier and penalty updates of the augmented Lagrangian for the constraint 1 - t = 0.
    lambda2 += lambda1 * (1.0 - t);
    lambda1 *= 2.0;
  }
  if (!result.snapped) result.stop_reason = "outer iteration limit before t could snap to 1";
  result.t = q[3 * n_g];
  result.garment = map.at(q).topRows(n_g);
  return result;
}

}  // namespace amt::refit
