#pragma once
// Central finite differences for the refit tests' gradient and Hessian checks.
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <algorithm>
#include <functional>
#include <vector>

#include "refit/contact.h"

namespace amt::refit::test {

/// ∇f at x by central differences with step h.
inline Eigen::VectorXd fd_gradient(const std::function<double(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& x,
                                   double h) {
  Eigen::VectorXd g(x.size());
  for (int i = 0; i < x.size(); ++i) {
    Eigen::VectorXd a = x, b = x;
    a[i] += h;
    b[i] -= h;
    g[i] = (f(a) - f(b)) / (2.0 * h);
  }
  return g;
}

/// The Jacobian of a gradient function at x by central differences (column i: d grad / d x_i).
inline Eigen::MatrixXd fd_jacobian(const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& grad,
                                   const Eigen::VectorXd& x, double h) {
  Eigen::MatrixXd J(x.size(), x.size());
  for (int i = 0; i < x.size(); ++i) {
    Eigen::VectorXd a = x, b = x;
    a[i] += h;
    b[i] -= h;
    J.col(i) = (grad(a) - grad(b)) / (2.0 * h);
  }
  return J;
}

/// The same for functions of positions (#V by 3), differentiated in the stacked coordinates (3 #V).
inline Eigen::VectorXd fd_position_gradient(const std::function<double(const Positions&)>& f, const Positions& x,
                                            double h) {
  const int rows = static_cast<int>(x.rows());
  auto stacked = [&](const Eigen::VectorXd& y) { return f(Eigen::Map<const Positions>(y.data(), rows, 3)); };
  return fd_gradient(stacked, Eigen::Map<const Eigen::VectorXd>(x.data(), x.size()), h);
}

/// The Jacobian of a gradient of positions (stacked, 3 #V) by central differences.
inline Eigen::MatrixXd fd_position_jacobian(const std::function<Eigen::VectorXd(const Positions&)>& grad,
                                            const Positions& x, double h) {
  const int rows = static_cast<int>(x.rows());
  auto stacked = [&](const Eigen::VectorXd& y) { return grad(Eigen::Map<const Positions>(y.data(), rows, 3)); };
  return fd_jacobian(stacked, Eigen::Map<const Eigen::VectorXd>(x.data(), x.size()), h);
}

/// A dense n by n matrix from triplets (repeated entries summed).
inline Eigen::MatrixXd dense(const std::vector<Eigen::Triplet<double>>& triplets, int n) {
  Eigen::SparseMatrix<double> H(n, n);
  H.setFromTriplets(triplets.begin(), triplets.end());
  return Eigen::MatrixXd(H);
}

/// max |a - b| / max |b|: the error of a against the reference b, relative to b's largest entry (the
/// barrier's derivatives are tiny numbers in metres, so no absolute floor).
inline double relative_error(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(1e-300, b.cwiseAbs().maxCoeff());
}

}  // namespace amt::refit::test
