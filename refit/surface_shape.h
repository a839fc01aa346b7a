#pragma once
// The surface-shape term of the garment refit (the garment-refit paper, section 3.4.2, eq. 2): the
// difference between the deformations of every pair of adjacent garment triangles, measured on the
// source vector between their opposite corners, weighted by the pair's source area.
#include <array>
#include <vector>

#include "data_tools/geometry/types.h"
#include "refit/newton.h"

namespace amt::refit {

/// L_surf = w Σ_(t1,t2) (A(t1) + A(t2)) |τ1 x - τ2 x|² over pairs of triangles sharing an edge, with
/// t1 = (v1, v2, v3), t2 = (v2, v1, v4), x = (v4ˢ - v3ˢ) / |v4ˢ - v3ˢ| and τ the map of a triangle's source
/// frame {e1ˢ, e2ˢ, nˢ} onto its current frame {e1, e2, n}, e1 = v2 - v1, e2 = v3 - v1.
///
/// One deviation from the paper, which writes n = e1 × e2: here n = (e1 × e2) / |e1 × e2|^½, which
/// scales like a length. With the paper's n a uniform scaling by λ scales the in-plane part of τx by λ
/// and its normal part by λ², so a garment merely scaled up would pay (λ² - λ)² times a non-zero amount
/// wherever adjacent triangles are not coplanar, against the paper's stated aim that the garment may
/// "scale freely"; with this n the term is zero under rotations, translations and uniform scaling
/// (tested), as the paper intends.
///
/// The garment's vertices are the first #Vˢ of the positions the term is evaluated on (the scene puts the
/// avatar after them). Hessians are projected to positive semi-definite per pair.
class SurfaceShapeTerm : public Objective {
 public:
  /// source: #Vˢ by 3 source garment positions; F: #F by 3 garment faces (a manifold mesh: an edge shared
  /// by more than two faces, or by two faces of opposite orientation, throws amt::Error); weight: w.
  SurfaceShapeTerm(const Positions& source, const MatrixX3i& F, double weight = 1.0);

  double value(const Positions& x) const override;
  double derivatives(const Positions& x, Eigen::VectorXd* gradient,
                     std::vector<Eigen::Triplet<double>>* hessian) const override;

  /// Each pair's own |τ1 x - τ2 x|² (unweighted), for distortion reports and pictures.
  std::vector<double> pair_distortion(const Positions& x) const;
  int num_pairs() const { return static_cast<int>(pairs_.size()); }

 private:
  struct Pair {
    std::array<int, 4> v;                // v1, v2, v3, v4
    Eigen::Vector3d c1, c2;              // x in the source frames of t1 and t2
    double weight;                       // w (A(t1ˢ) + A(t2ˢ))
  };
  std::vector<Pair> pairs_;
};

}  // namespace amt::refit
