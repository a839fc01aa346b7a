#include "refit/fit_term.h"

#include <cmath>

#include "data_tools/geometry/error.h"
#include "refit/assembly.h"

namespace amt::refit {

std::vector<uint8_t> fit_region(const Positions& source, const AvatarDistanceField& source_avatar,
                                double max_distance) {
  std::vector<uint8_t> fit(source.rows(), 0);
  for (int v = 0; v < source.rows(); ++v)
    fit[v] = std::abs(source_avatar.distance(source.row(v).transpose())) <= max_distance;
  return fit;
}

FitTerm::FitTerm(const AvatarDistanceField& field, const Positions& source, const MatrixX3i& F,
                 const std::vector<uint8_t>& fit, double weight)
    : field_(field) {
  AMT_CHECK(fit.size() == size_t(source.rows()), "fit term: a mask of ", fit.size(), " entries for ", source.rows(),
            " garment vertices");
  std::vector<double> area(source.rows(), 0.0);
  for (int f = 0; f < F.rows(); ++f) {
    const Eigen::RowVector3d a = source.row(F(f, 0)), b = source.row(F(f, 1)), c = source.row(F(f, 2));
    const double third = (b - a).cross(c - a).norm() / 6.0;
    for (int k = 0; k < 3; ++k) area[F(f, k)] += third;
  }
  for (int v = 0; v < source.rows(); ++v)
    if (fit[v] && area[v] > 0.0) {
      vertices_.push_back(v);
      weight_.push_back(weight * area[v]);
    }
}

double FitTerm::evaluate(const Positions& x, Eigen::VectorXd* gradient, std::vector<Eigen::Triplet<double>>* hessian,
                         bool project) const {
  double energy = 0.0;
  for (size_t i = 0; i < vertices_.size(); ++i) {
    const int v = vertices_[i];
    Eigen::Vector3d g;
    Eigen::Matrix3d h;
    const double d = field_.distance(x.row(v).transpose(), &g, &h);
    energy += weight_[i] * d * d;
    if (gradient) gradient->segment<3>(3 * v) += 2.0 * weight_[i] * d * g;
    if (hessian) {
      Eigen::MatrixXd H = 2.0 * weight_[i] * (g * g.transpose() + d * h);
      if (project) project_to_psd(H);
      for (int p = 0; p < 3; ++p)
        for (int q = 0; q < 3; ++q) hessian->emplace_back(3 * v + p, 3 * v + q, H(p, q));
    }
  }
  return energy;
}

double FitTerm::value(const Positions& x) const {
  return evaluate(x, nullptr, nullptr, true);
}

double FitTerm::derivatives(const Positions& x, Eigen::VectorXd* gradient,
                            std::vector<Eigen::Triplet<double>>* hessian) const {
  return evaluate(x, gradient, hessian, true);
}

void FitTerm::exact_hessian(const Positions& x, std::vector<Eigen::Triplet<double>>* hessian) const {
  evaluate(x, nullptr, hessian, false);
}

double FitTerm::mean_fit_distance(const Positions& x) const {
  double sum = 0.0, total = 0.0;
  for (size_t i = 0; i < vertices_.size(); ++i) {
    sum += weight_[i] * std::abs(field_.distance(x.row(vertices_[i]).transpose()));
    total += weight_[i];
  }
  return total > 0.0 ? sum / total : 0.0;
}

}  // namespace amt::refit
