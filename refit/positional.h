#pragma once
// The positional term of the garment refit (the garment-refit paper, section 3.4.3, eq. 3): every
// boundary vertex of the garment (cuffs, hems, collars) keeps its coordinate along its nearest bone, so
// that a sleeve follows a longer arm and a hem a longer leg.
#include <vector>

#include "data_tools/geometry/types.h"
#include "refit/newton.h"

namespace amt::refit {

/// L_pos = w Σ_(v ∈ ∂G) w_v (uˢ_v - u_v)², u_v = (v - a)·(b - a) / |b - a|² the coordinate of v along its
/// bone (a, b) of the current skeleton (the line's, not clamped to the segment, so that it is smooth),
/// uˢ_v the same on the source garment and skeleton, the bone the source skeleton's nearest to vˢ, w_v
/// the mean length of the source edges at v. The garment's vertices are the first #Vˢ of the positions.
class PositionalTerm : public Objective {
 public:
  /// source: #Vˢ by 3 source garment positions; F its faces; source_joints #J by 3 and bones #B by 2
  /// (skeleton_bones) the source skeleton; weight: w (the paper uses 10).
  PositionalTerm(const Positions& source, const MatrixX3i& F, const Positions& source_joints, const MatrixX2i& bones,
                 double weight = 10.0);

  /// The current skeleton (#J by 3): the target's at the garment fit, the interpolated V^b(t) during the
  /// inflation. Starts as the source skeleton. Throws amt::Error on a size mismatch or a zero-length bone.
  void set_skeleton(const Positions& joints);

  double value(const Positions& x) const override;
  double derivatives(const Positions& x, Eigen::VectorXd* gradient,
                     std::vector<Eigen::Triplet<double>>* hessian) const override;

  /// The boundary vertices the term holds, ascending.
  const std::vector<int>& boundary_vertices() const { return vertices_; }

  /// The term during the inflation (section 3.5), where the skeleton is V^b(t) = t V^tb + (1 - t) V^sb and
  /// t is an unknown: the term at garment positions x and skeleton `joints_at_t`, with its derivatives with
  /// respect to each held vertex and t (dt_joints = V^tb - V^sb, #J by 3). *gradient_t and *hessian_t
  /// (when not null) receive ∂/∂t and, per held vertex in boundary_vertices() order, the PSD-projected
  /// 4 by 4 Hessian over (v, t) appended to *blocks.
  double inflation_derivatives(const Positions& x, const Positions& joints_at_t, const Positions& dt_joints,
                               Eigen::VectorXd* gradient_x, double* gradient_t,
                               std::vector<Eigen::Matrix4d>* blocks) const;

 private:
  std::vector<int> vertices_;       // boundary vertices
  std::vector<int> bone_;           // their bones
  std::vector<double> source_u_;    // uˢ
  std::vector<double> weight_;      // w w_v
  MatrixX2i bones_;
  Positions joints_;
};

}  // namespace amt::refit
