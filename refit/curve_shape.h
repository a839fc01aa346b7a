#pragma once
// The curve-shape term of the garment refit (the garment-refit paper, section 3.4.5, eq. 5 and the
// torsion term after it): the discrete curvature and torsion of every boundary loop of the garment
// (cuffs, hems, necklines) held at their source values, so that a round cuff stays round and a V-neck
// keeps its V, up to a rigid motion and a uniform scale.
#include <array>
#include <vector>

#include "data_tools/geometry/types.h"
#include "refit/newton.h"

namespace amt::refit {

/// The boundary loops of an oriented manifold mesh F: each a closed list of vertices (the first not
/// repeated at the end), following the boundary sides a -> b of the faces. Throws amt::Error when the
/// boundary is not a union of simple loops (a vertex where two boundary loops touch).
std::vector<std::vector<int>> boundary_loops(const MatrixX3i& F);

/// L_curve = w Σ_loops Σ_i w_i [(αˢ_i - α_i)² + (βˢ_i - β_i)² + (γˢ_i - γ_i)²] over the loop vertices,
/// α_i = -ê_(i-1)·ê_i, β_i = P(ê_(i+1), ê_i)·P(-ê_(i-1), ê_i), γ_i = (P(ê_(i+1), ê_i) × P(-ê_(i-1), ê_i))·ê_i,
/// P(v, u) = v - (u·v) u, ê_i the unit edge directions of the loop, w_i = (|eˢ_(i-1)| + |eˢ_i|)/2 (all
/// indices cyclic). Invariant under rotations, translations and uniform scaling; an anisotropic scaling
/// (a round cuff becoming an ellipse) costs. The garment's vertices are the first #Vˢ of the positions;
/// Hessians are projected to positive semi-definite per loop vertex.
class CurveShapeTerm : public Objective {
 public:
  /// source: #Vˢ by 3 source garment positions; F its faces; weight: w. Loops of fewer than 3 vertices
  /// are left out.
  CurveShapeTerm(const Positions& source, const MatrixX3i& F, double weight = 1.0);

  double value(const Positions& x) const override;
  double derivatives(const Positions& x, Eigen::VectorXd* gradient,
                     std::vector<Eigen::Triplet<double>>* hessian) const override;

  int num_loops() const { return loops_; }

 private:
  struct Stencil {
    std::array<int, 4> v;           // v_(i-1), v_i, v_(i+1), v_(i+2)
    std::array<double, 3> source;   // αˢ, βˢ, γˢ
    double weight;                  // w w_i
  };
  std::vector<Stencil> stencils_;
  int loops_ = 0;
};

}  // namespace amt::refit
