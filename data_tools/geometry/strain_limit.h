#pragma once
// Strain limiting of a predicted surface: no edge longer than a bound times its rest length, nor shorter than
// another (X. Provot, "Deformation Constraints in a Mass-Spring Model to Describe Rigid Cloth Behavior", Graphics
// Interface 1995; the "inextensibility" projection of position-based cloth). The learned apparel moves a few hundred
// handles that the vertices follow; where two neighbouring handles part, the edges between them stretch to 1.5 times
// their rest length and more while the simulation keeps them near rest (measured on the artist-style remakes: about
// half of the edges `amt eval` counts as torn); where they close in, edges squash to a fraction of their length. A
// few projections pull them back, moving apparel vertices only (the body is where the apparel hangs from). Written
// by hand: it is a few loops over an edge list, and the libraries that have it (cloth simulators) bring a whole
// solver.
#include <cstdint>
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

/// An edge is projected once it is this share past its bound, and then onto the bound itself. Jacobi projections
/// that average a vertex's requests approach a bound without reaching it, so without the slack the edges near it
/// keep the iterations going to the last one (measured on the artist-style remakes: every edge left at 1.2000x,
/// all 64 iterations run); with it they stop after a few.
inline constexpr float kStrainSlack = 0.02f;

/// Stretch limits over the edges of a surface split into free vertices (moved: the apparel) and fixed ones (the
/// body), numbered in one list: free vertices 0 .. num_free - 1, fixed ones num_free .. num_free + num_fixed - 1.
/// Free vertices joined by an edge of rest length below `weld_length` (the copies of a welded seam) are one point:
/// the limiter moves one of them and the others take its position, so a seam that is closed stays closed. A free
/// vertex so joined to a fixed one (apparel sewn to the body at a seam) is pinned: it takes the fixed position.
class StrainLimiter {
 public:
  StrainLimiter() = default;
  /// edges (E, 2) in the joint numbering, at least one end free (others are dropped); rest (E) their rest
  /// lengths, metres (>= 0, finite); max_stretch > 1 the largest length over rest length; iterations >= 1;
  /// min_stretch in [0, 1) the smallest length over rest length (0: compression is not bounded).
  /// Throws amt::Error on indices out of range, a negative or non-finite rest length, or bounds out of range.
  StrainLimiter(const MatrixX2i& edges, const std::vector<float>& rest, int num_free, int num_fixed, float max_stretch,
                int iterations = 4, float weld_length = 0.0f, float min_stretch = 0.0f);

  /// Projects the free positions free_xyz (num_free x 3, row-major, metres) in place, against the fixed ones
  /// fixed_xyz (num_fixed x 3): per iteration, every edge longer than (1 + kStrainSlack) max_stretch x rest asks
  /// its ends to close the excess over max_stretch x rest, and every edge shorter than (1 - kStrainSlack)
  /// min_stretch x rest (and longer than 0: a collapsed edge has no direction) to open the shortfall (a free end of
  /// a fixed edge takes all of it, two free ends half each), and every free vertex moves
  /// by the mean of the requests it received (Jacobi: the result does not depend on the edges' order). Deterministic.
  void apply(float* free_xyz, const float* fixed_xyz) const;

  bool empty() const { return a_.empty() && copies_.empty(); }
  int num_edges() const { return int(a_.size()); }
  float max_stretch() const { return max_stretch_; }

 private:
  std::vector<int32_t> a_, b_;  // a_ free; b_ free or fixed (>= num_free_); free ends are representatives
  std::vector<int32_t> copies_;  // (copy, its representative: free, or fixed when pinned) pairs, flattened
  std::vector<int32_t> incident_offsets_, incident_;  // each free vertex's edges: incident_[offsets[v] .. offsets[v+1])
  std::vector<float> rest_, bound2_, floor2_;         // rest lengths, (max_stretch x rest)^2, (min_stretch x rest)^2
  int num_free_ = 0, num_fixed_ = 0, iterations_ = 0;
  float max_stretch_ = 0, min_stretch_ = 0;
};

}  // namespace amt
