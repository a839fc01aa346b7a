#pragma once
// Projected Newton with a CCD-filtered backtracking line search (Li et al. 2020, "Incremental Potential
// Contact", Algorithm 1; the PSD projection of per-term Hessians follows Teran et al. 2005): the
// minimiser the garment refit runs in each of its optimisation stages.
//
// Every step it accepts is collision-free along the whole segment from the old to the new positions:
// the step length starts at the largest fraction that continuous collision detection certifies
// (contact.h, max_collision_free_step) and only shrinks from there.
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "refit/contact.h"

namespace amt::refit {

// === Objective

/// A term of the energy, a function of the positions x (#V by 3).
class Objective {
 public:
  virtual ~Objective() = default;
  /// E(x); +infinity outside the term's domain (for the barrier: touching or crossing primitives).
  virtual double value(const Positions& x) const = 0;
  /// E(x), with its gradient added to *gradient (3 #V, stacked coordinates) and its Hessian, projected
  /// to positive semi-definite term by term, appended to *hessian as triplets.
  virtual double derivatives(const Positions& x, Eigen::VectorXd* gradient,
                             std::vector<Eigen::Triplet<double>>* hessian) const = 0;
};

/// A term of the energy that is a function of the unknowns q themselves (see LinearPositions), such as
/// the augmented Lagrangian on the inflation parameter t (section 3.5).
class ParameterObjective {
 public:
  virtual ~ParameterObjective() = default;
  virtual double value(const Eigen::VectorXd& q) const = 0;
  /// The term, its gradient added to *gradient (#q) and its PSD Hessian appended to *hessian.
  virtual double derivatives(const Eigen::VectorXd& q, Eigen::VectorXd* gradient,
                             std::vector<Eigen::Triplet<double>>* hessian) const = 0;
};

/// The positions as an affine function of the unknowns: x(q) = base + J q, stacked (3 #V). Free vertices
/// are a selection; the refit's inflation adds the column of t, which moves every avatar vertex from its
/// shrunk to its target position (section 3.5). Straight lines in q are straight lines of every vertex,
/// so the line search's CCD is exact for them.
struct LinearPositions {
  Positions base;                 // #V by 3
  Eigen::SparseMatrix<double> J;  // 3 #V by #q

  /// x(q), #V by 3.
  Positions at(const Eigen::VectorXd& q) const;
  /// The free coordinates of x (vertices with fixed[v] = 1 held, fixed #V or empty): q = those coordinates.
  static LinearPositions free_vertices(const Positions& x, const std::vector<uint8_t>& fixed, Eigen::VectorXd* q);
};

/// The barrier potential (contact.h) as an objective term, with PSD-projected pair Hessians.
class BarrierObjective : public Objective {
 public:
  explicit BarrierObjective(const BarrierPotential& barrier) : barrier_(barrier) {}
  double value(const Positions& x) const override { return barrier_.value(x); }
  double derivatives(const Positions& x, Eigen::VectorXd* gradient,
                     std::vector<Eigen::Triplet<double>>* hessian) const override {
    return barrier_.derivatives(x, gradient, hessian, true);
  }

 private:
  const BarrierPotential& barrier_;
};

// === Solver

/// Parameters of projected_newton.
struct NewtonOptions {
  int max_iterations = 200;
  /// Converged when the Newton direction moves no coordinate by more than this (metres), IPC's
  /// stopping criterion ‖p‖∞ < ε.
  double tolerance = 1e-6;
  /// Stop ("stalled") after this many consecutive iterations that each lowered the energy by less than
  /// stall_tolerance times itself (0: never). Near a contact that the CCD bound keeps from closing, the
  /// direction can stay above `tolerance` while the steps no longer change anything.
  int stall_iterations = 0;
  double stall_tolerance = 1e-9;
  /// Backtracking halvings of the step before giving up on an iteration.
  int max_backtracks = 50;
  /// Filter the line search by CCD (off only to show, in tests, what the filter prevents).
  bool ccd_filter = true;
  CcdOptions ccd;
};

/// One accepted step, reported to the observer.
struct NewtonStep {
  int iteration = 0;
  double energy = 0.0;          // after the step
  double step_length = 0.0;     // α: the fraction of the Newton direction taken
  double ccd_bound = 1.0;       // the largest fraction CCD allowed
  double direction_inf_norm = 0.0;
  const Positions* before = nullptr;  // positions before and after the step
  const Positions* after = nullptr;
  const CollisionMesh* collisions = nullptr;  // the scene the step was checked against (may be null)
};

/// Why the solver stopped, and where.
struct NewtonResult {
  bool converged = false;
  int iterations = 0;
  double energy = 0.0;
  double direction_inf_norm = 0.0;
  std::string stop_reason;  // "converged", "stalled", "iteration limit", "line search failed"
};

/// Minimises the sum of `terms` over the positions *x (#V by 3), keeping the vertices with fixed[v] = 1
/// (fixed: #V, or empty for none) where they are. `collisions` (may be null) is the scene whose
/// primitives no step may pass through. *x must start with a finite energy (for the barrier:
/// intersection-free). `observer`, when set, sees every accepted step.
NewtonResult projected_newton(const std::vector<const Objective*>& terms, const CollisionMesh* collisions,
                              const std::vector<uint8_t>& fixed, Positions* x, const NewtonOptions& options = {},
                              const std::function<void(const NewtonStep&)>& observer = {});

/// The same over unknowns q with positions map.at(q): the sum of `terms` (functions of the positions,
/// their derivatives carried to q through J) and `parameter_terms` (functions of q).
NewtonResult projected_newton(const std::vector<const Objective*>& terms,
                              const std::vector<const ParameterObjective*>& parameter_terms,
                              const CollisionMesh* collisions, const LinearPositions& map, Eigen::VectorXd* q,
                              const NewtonOptions& options = {},
                              const std::function<void(const NewtonStep&)>& observer = {});

}  // namespace amt::refit
