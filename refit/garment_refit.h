#pragma once
// The whole garment refit (the garment-refit paper, section 3, Fig. 2): a garment designed on a source
// avatar moved onto a target avatar of other proportions, intersection-free. Checks the input, shrinks the
// target avatar onto its skeleton (3.3), inflates it inside the garment (3.5), fits the garment onto it
// with the fit term (3.6), and reports the shape and fit figures of the result.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/types.h"
#include "refit/newton.h"
#include "refit/refit_weights.h"

namespace amt::refit {

/// A triangle mesh with a skeleton, in metres.
///   V       #V by 3 vertices
///   F       #F by 3 faces
///   joints  #J by 3 rest joints; the source and the target avatar share the joints and their parents
struct RiggedMesh {
  Positions V;
  MatrixX3i F;
  Positions joints;
};

/// Parameters of the refit; distances in metres.
struct GarmentRefitOptions {
  RefitWeights weights;
  /// G_fit: garment vertices this close to the source avatar are fitted to the target (0: no fit term).
  double fit_region_distance = 0.02;
  /// The avatars' signed distance fields: voxel size and band.
  double voxel_size = 0.004;
  double field_band = 0.04;
  /// Outer (augmented Lagrangian) iterations of the inflation before giving up on t = 1.
  int max_outer_iterations = 30;
  /// Newton's iteration limit and stopping rules in each solve: converged when no coordinate would move
  /// by 10 µm, stalled after 3 iterations that lower the energy by less than 10⁻⁹ of itself.
  NewtonOptions newton = refit_newton_options();

  static NewtonOptions refit_newton_options() {
    NewtonOptions o;
    o.tolerance = 1e-5;
    o.stall_iterations = 3;
    return o;
  }
};

/// One line of progress: an outer iteration of the inflation, or a Newton step of the garment fit.
struct GarmentRefitProgress {
  std::string stage;  // "inflation" or "fit"
  int iteration = 0;
  double t = 0.0;  // the inflation parameter (1 in the fit)
  double energy = 0.0;
  double min_distance = 0.0;  // metres, over the garment's pairs with itself and the avatar (+inf: none within 2 cm)
  int newton_iterations = 0;  // inflation: the inner solve's iterations
};

/// The refit garment and what it cost.
struct GarmentRefitResult {
  Positions garment;         // #Vˢ by 3 on the target avatar
  int shrunk_vertices = 0;   // vertices of the shrunk avatar (with the subdivision's)
  int outer_iterations = 0;  // of the inflation
  int fit_iterations = 0;    // Newton iterations of the garment fit
  std::string fit_stop_reason;
  int fit_vertices = 0;            // |G_fit|
  double source_fit_distance = 0;  // area-weighted mean |D| over G_fit on the source avatar, metres
  double fit_distance = 0;         // the same on the target avatar after the refit
  double distortion_rms = 0;       // |τ1 x - τ2 x| of L_surf over adjacent face pairs (0: the source shape): RMS
  double distortion_max = 0;       //   and largest
  double min_distance = 0;         // smallest garment-garment or garment-avatar distance at the end, metres
  int crossing_pairs = 0;          // triangle pairs of the result that cross (triangle_intersections.h): 0
  double shrink_seconds = 0, inflation_seconds = 0, fit_seconds = 0;
};

/// Refits `garment` (#Vˢ by 3 positions and faces, designed on `source`) onto `target`. parents (#J, -1
/// for roots) give both skeletons' bones. Throws amt::Error naming `garment_name`, `source_name` or
/// `target_name` with a one-line reason when the input is unusable: non-finite coordinates, skeletons of
/// different joint counts or a zero-length bone, a degenerate or non-manifold garment, a garment that
/// crosses itself or the source avatar, or an inflation that could not reach the target's shape.
GarmentRefitResult refit_garment(const Positions& garment, const MatrixX3i& garment_F, const RiggedMesh& source,
                                 const RiggedMesh& target, const std::vector<int32_t>& parents,
                                 const GarmentRefitOptions& options = {},
                                 const std::function<void(const GarmentRefitProgress&)>& progress = {},
                                 const std::string& garment_name = "garment", const std::string& source_name = "source",
                                 const std::string& target_name = "target");

/// Skinning weights of the garment (#Vˢ by 3) from the avatar's (V #V by 3, weights over its joints):
/// each garment vertex takes the weights of its nearest avatar vertex, as the dataset builder skins its
/// body-connected apparel.
SparseWeights transfer_weights(const Positions& garment, const Positions& avatar_V,
                               const SparseWeights& avatar_weights);

}  // namespace amt::refit
