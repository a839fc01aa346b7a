#pragma once
// The fit term of the garment refit (the garment-refit paper, section 3.4.4, eq. 4): the part of the
// garment that fits the source avatar closely is drawn onto the target avatar's surface, through the
// target's signed distance field (distance_field.h). Used in the garment fit only (section 3.6), where
// the avatar has its own, closed shape.
#include <cstdint>
#include <vector>

#include "data_tools/geometry/types.h"
#include "refit/distance_field.h"
#include "refit/newton.h"

namespace amt::refit {

/// G_fit of eq. 4: the garment vertices (source #Vˢ by 3) within max_distance (metres) of the source
/// avatar's surface, by its distance field, as a #Vˢ mask. The paper leaves the rule open ("decided
/// based on the distance between the source avatar and garment"); this is the simplest such rule.
std::vector<uint8_t> fit_region(const Positions& source, const AvatarDistanceField& source_avatar, double max_distance);

/// L_fit = w Σ_(v ∈ G_fit) A_v D(x_v)², the integral of eq. 4 with one quadrature point per vertex: A_v a
/// third of the source area of the faces at v, D the target avatar's distance field. The Hessian per
/// vertex is 2 w A_v (∇D ∇Dᵀ + D ∇²D) of the field's trilinear interpolant, projected to positive
/// semi-definite. The garment's vertices are the first #Vˢ of the positions.
class FitTerm : public Objective {
 public:
  /// field: the target avatar's (must outlive the term); source, F: the source garment (#Vˢ by 3, #F by
  /// 3); fit: #Vˢ mask of G_fit (fit_region); weight: w (the paper's w_fit = 2).
  FitTerm(const AvatarDistanceField& field, const Positions& source, const MatrixX3i& F,
          const std::vector<uint8_t>& fit, double weight = 2.0);

  double value(const Positions& x) const override;
  double derivatives(const Positions& x, Eigen::VectorXd* gradient,
                     std::vector<Eigen::Triplet<double>>* hessian) const override;

  /// The exact (not projected) per-vertex Hessian blocks of the term, for tests: appended as triplets.
  void exact_hessian(const Positions& x, std::vector<Eigen::Triplet<double>>* hessian) const;

  /// Area-weighted mean |D| over G_fit at x (metres): the fit distance reported per result.
  double mean_fit_distance(const Positions& x) const;

  const std::vector<int>& vertices() const { return vertices_; }

 private:
  double evaluate(const Positions& x, Eigen::VectorXd* gradient, std::vector<Eigen::Triplet<double>>* hessian,
                  bool project) const;
  const AvatarDistanceField& field_;
  std::vector<int> vertices_;   // G_fit
  std::vector<double> weight_;  // w A_v
};

}  // namespace amt::refit
