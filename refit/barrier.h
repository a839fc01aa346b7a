#pragma once
// The IPC log barrier and the edge-edge mollifier (Li et al. 2020, "Incremental Potential Contact",
// eq. 6 and section 4.3), as functions of squared distances.
#include <Eigen/Core>

namespace amt::refit {

// === Barrier

/// b(s) and its first two derivatives with respect to s.
struct ScalarDerivatives {
  double value = 0.0;
  double first = 0.0;
  double second = 0.0;
};

/// The C² log barrier of IPC eq. 6, b(s) = -(s - ŝ)² ln(s / ŝ) for 0 < s < ŝ and 0 for s ≥ ŝ, applied
/// to the squared distance s = d² with threshold ŝ = d̂² (as IPC's implementation does; the paper
/// writes it on d). Derivatives: b' = -2 (s - ŝ) ln(s/ŝ) - (s - ŝ)²/s,
/// b'' = -2 ln(s/ŝ) - 4 (s - ŝ)/s + (s - ŝ)²/s². s ≤ 0 gives +infinity (an intersection).
ScalarDerivatives barrier(double s, double s_hat);

// === Edge-edge mollifier

/// The mollifier threshold ε× = 10⁻³ |ea0 - ea1|² |eb0 - eb1|² of two edges, from their squared rest
/// lengths (IPC section 4.3).
double edge_edge_mollifier_threshold(double ea_rest_length_sq, double eb_rest_length_sq);

/// m(c) = -c²/ε² + 2c/ε for c < ε, 1 otherwise, of c = |(ea1 - ea0) × (eb1 - eb0)|² (IPC section
/// 4.3): it takes the edge-edge barrier smoothly to zero as the edges become parallel, where the
/// closest-feature pieces switch. Derivatives with respect to x = [ea0, ea1, eb0, eb1] (12).
struct Mollifier {
  double value = 1.0;
  Eigen::Matrix<double, 12, 1> gradient = Eigen::Matrix<double, 12, 1>::Zero();
  Eigen::Matrix<double, 12, 12> hessian = Eigen::Matrix<double, 12, 12>::Zero();
  bool active = false;  // c < ε: value < 1 and the derivatives are non-zero
};
Mollifier edge_edge_mollifier(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
                              const Eigen::Vector3d& eb1, double eps_x);

}  // namespace amt::refit
