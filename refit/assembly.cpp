#include "refit/assembly.h"

#include <Eigen/Eigenvalues>

namespace amt::refit {

void project_to_psd(Eigen::Ref<Eigen::MatrixXd> matrix) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(matrix);
  const Eigen::VectorXd lambda = eig.eigenvalues();
  if (lambda.minCoeff() >= 0.0) return;
  matrix = eig.eigenvectors() * lambda.cwiseMax(0.0).asDiagonal() * eig.eigenvectors().transpose();
}

void add_element(const int* v, int n, const Eigen::Ref<const Eigen::VectorXd>& element_gradient,
                 const Eigen::Ref<const Eigen::MatrixXd>& element_hessian, bool project_psd,
                 Eigen::VectorXd* gradient, std::vector<Eigen::Triplet<double>>* hessian) {
  if (gradient)
    for (int i = 0; i < n; ++i) gradient->segment<3>(3 * v[i]) += element_gradient.segment<3>(3 * i);
  if (!hessian) return;
  Eigen::MatrixXd block = element_hessian.topLeftCorner(3 * n, 3 * n);
  if (project_psd) project_to_psd(block);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) hessian->emplace_back(3 * v[i] + a, 3 * v[j] + b, block(3 * i + a, 3 * j + b));
}

}  // namespace amt::refit
