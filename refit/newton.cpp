#include "refit/newton.h"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <limits>

#include "data_tools/geometry/error.h"

namespace amt::refit {
namespace {

double total_value(const std::vector<const Objective*>& terms,
                   const std::vector<const ParameterObjective*>& parameter_terms, const LinearPositions& map,
                   const Eigen::VectorXd& q) {
  const Positions x = map.at(q);
  double e = 0.0;
  for (const Objective* term : terms) {
    e += term->value(x);
    if (!std::isfinite(e)) return std::numeric_limits<double>::infinity();
  }
  for (const ParameterObjective* term : parameter_terms) {
    e += term->value(q);
    if (!std::isfinite(e)) return std::numeric_limits<double>::infinity();
  }
  return e;
}

// Solves H p = -g. H is positive semi-definite: a failed factorisation or a singular H gets a growing
// multiple of the identity added, and plain gradient descent is the last resort, so p is a descent
// direction whenever g ≠ 0.
Eigen::VectorXd newton_direction(const Eigen::SparseMatrix<double>& H, const Eigen::VectorXd& g) {
  const int n = static_cast<int>(g.size());
  const Eigen::VectorXd rhs = -g;
  const double scale = std::max(1e-12, Eigen::VectorXd(H.diagonal()).cwiseAbs().maxCoeff());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  Eigen::SparseMatrix<double> I(n, n);
  I.setIdentity();
  solver.analyzePattern(H + I);  // the pattern of every shifted matrix below
  for (double mu = 0.0; mu < 1e6 * scale; mu = mu == 0.0 ? 1e-8 * scale : 10.0 * mu) {
    solver.factorize(H + mu * I);
    if (solver.info() != Eigen::Success) continue;
    const Eigen::VectorXd p = solver.solve(rhs);
    if (solver.info() == Eigen::Success && p.allFinite() && p.dot(rhs) > 0.0) return p;
  }
  return rhs / scale;
}

}  // namespace

Positions LinearPositions::at(const Eigen::VectorXd& q) const {
  Positions x = base;
  Eigen::Map<Eigen::VectorXd>(x.data(), x.size()) += J * q;
  return x;
}

LinearPositions LinearPositions::free_vertices(const Positions& x, const std::vector<uint8_t>& fixed,
                                               Eigen::VectorXd* q) {
  const int n = static_cast<int>(x.rows());
  AMT_CHECK(fixed.empty() || static_cast<int>(fixed.size()) == n, "newton: ", fixed.size(), " fixed flags for ", n,
            " vertices");
  LinearPositions map;
  map.base = x;
  std::vector<Eigen::Triplet<double>> select;
  std::vector<double> values;
  for (int v = 0; v < n; ++v) {
    if (!fixed.empty() && fixed[v]) continue;
    for (int a = 0; a < 3; ++a) {
      select.emplace_back(3 * v + a, static_cast<int>(values.size()), 1.0);
      values.push_back(x(v, a));
      map.base(v, a) = 0.0;
    }
  }
  map.J.resize(3 * n, static_cast<int>(values.size()));
  map.J.setFromTriplets(select.begin(), select.end());
  *q = Eigen::Map<const Eigen::VectorXd>(values.data(), static_cast<int>(values.size()));
  return map;
}

NewtonResult projected_newton(const std::vector<const Objective*>& terms, const CollisionMesh* collisions,
                              const std::vector<uint8_t>& fixed, Positions* x, const NewtonOptions& options,
                              const std::function<void(const NewtonStep&)>& observer) {
  Eigen::VectorXd q;
  const LinearPositions map = LinearPositions::free_vertices(*x, fixed, &q);
  const NewtonResult result = projected_newton(terms, {}, collisions, map, &q, options, observer);
  *x = map.at(q);
  return result;
}

NewtonResult projected_newton(const std::vector<const Objective*>& terms,
                              const std::vector<const ParameterObjective*>& parameter_terms,
                              const CollisionMesh* collisions, const LinearPositions& map, Eigen::VectorXd* q,
                              const NewtonOptions& options, const std::function<void(const NewtonStep&)>& observer) {
  const int n = static_cast<int>(map.base.rows());
  const int num_q = static_cast<int>(q->size());
  AMT_CHECK(map.J.rows() == 3 * n && map.J.cols() == num_q, "newton: a ", map.J.rows(), " by ", map.J.cols(),
            " position map for ", n, " vertices and ", num_q, " unknowns");
  AMT_CHECK(!collisions || collisions->num_vertices == n, "newton: the collision mesh has ",
            collisions ? collisions->num_vertices : 0, " vertices, the positions ", n);
  const Eigen::SparseMatrix<double> Jt = map.J.transpose();

  NewtonResult result;
  double energy = total_value(terms, parameter_terms, map, *q);
  AMT_CHECK(std::isfinite(energy), "newton: the starting positions have infinite energy (touching or crossing "
                                   "primitives?)");
  result.energy = energy;
  if (num_q == 0) {
    result.converged = true;
    result.stop_reason = "converged";
    return result;
  }
  std::vector<Eigen::Triplet<double>> triplets;
  int stalled = 0;  // consecutive iterations with a negligible decrease
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const Positions x = map.at(*q);
    // Derivatives in x, carried to q: g_q = Jᵀ g_x, H_q = Jᵀ H_x J (PSD when H_x is).
    Eigen::VectorXd g_x = Eigen::VectorXd::Zero(3 * n);
    triplets.clear();
    for (const Objective* term : terms) term->derivatives(x, &g_x, &triplets);
    Eigen::SparseMatrix<double> H_x(3 * n, 3 * n);
    H_x.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::VectorXd g = Jt * g_x;
    Eigen::SparseMatrix<double> H = Jt * H_x * map.J;
    if (!parameter_terms.empty()) {
      triplets.clear();
      for (const ParameterObjective* term : parameter_terms) term->derivatives(*q, &g, &triplets);
      Eigen::SparseMatrix<double> H_q(num_q, num_q);
      H_q.setFromTriplets(triplets.begin(), triplets.end());
      H += H_q;
    }
    const Eigen::VectorXd dq = newton_direction(H, g);
    const Eigen::VectorXd dx_flat = map.J * dq;
    const Positions dx = Eigen::Map<const Positions>(dx_flat.data(), n, 3);
    result.direction_inf_norm = dx_flat.lpNorm<Eigen::Infinity>();
    result.iterations = iteration;
    if (result.direction_inf_norm < options.tolerance) {
      result.converged = true;
      result.stop_reason = "converged";
      return result;
    }
    // IPC Algorithm 1: start from the CCD-certified step, then backtrack until the energy decreases.
    double alpha = 1.0, ccd_bound = 1.0;
    if (collisions && options.ccd_filter) alpha = ccd_bound = max_collision_free_step(*collisions, x, dx, options.ccd);
    Eigen::VectorXd trial;
    double trial_energy = std::numeric_limits<double>::infinity();
    bool accepted = false;
    for (int k = 0; k <= options.max_backtracks && alpha > 0.0; ++k, alpha *= 0.5) {
      trial = *q + alpha * dq;
      trial_energy = total_value(terms, parameter_terms, map, trial);
      if (trial_energy <= energy) {
        accepted = true;
        break;
      }
    }
    if (!accepted) {
      result.stop_reason = "line search failed";
      return result;
    }
    *q = trial;
    stalled = energy - trial_energy < options.stall_tolerance * std::abs(energy) ? stalled + 1 : 0;
    energy = trial_energy;
    result.energy = energy;
    result.iterations = iteration + 1;
    if (observer) {
      const Positions after = map.at(*q);
      NewtonStep step;
      step.iteration = iteration;
      step.energy = energy;
      step.step_length = alpha;
      step.ccd_bound = ccd_bound;
      step.direction_inf_norm = result.direction_inf_norm;
      step.before = &x;
      step.after = &after;
      step.collisions = collisions;
      observer(step);
    }
    if (options.stall_iterations > 0 && stalled >= options.stall_iterations) {
      result.stop_reason = "stalled";
      return result;
    }
  }
  result.stop_reason = "iteration limit";
  return result;
}

}  // namespace amt::refit
