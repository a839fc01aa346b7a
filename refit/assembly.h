#pragma once
// Assembly of per-element derivatives (a pair of primitives, a pair of triangles) into the global
// gradient and sparse Hessian over the stacked coordinates x (3 #V), with the PSD projection of projected
// Newton (Teran et al. 2005; IPC, Li et al. 2020, section 5).
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

namespace amt::refit {

/// Projects a symmetric matrix onto the positive semi-definite cone: eigenvalues below 0 set to 0.
void project_to_psd(Eigen::Ref<Eigen::MatrixXd> matrix);

/// Adds an element's gradient (3 n) to *gradient and its Hessian (3 n by 3 n), projected to PSD when
/// project_psd is set, to *hessian as triplets; the element's vertices are v[0 .. n). Either output may
/// be null.
void add_element(const int* v, int n, const Eigen::Ref<const Eigen::VectorXd>& element_gradient,
                 const Eigen::Ref<const Eigen::MatrixXd>& element_hessian, bool project_psd,
                 Eigen::VectorXd* gradient, std::vector<Eigen::Triplet<double>>* hessian);

}  // namespace amt::refit
