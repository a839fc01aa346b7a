#pragma once
// Step 2 of the garment refit (the garment-refit paper, section 3.5): the shrunk target avatar, embedded
// in the source garment, inflated back to its own shape while the garment keeps its shape and stays
// intersection-free. The avatar's vertices are V^a(t) = t V^ta + (1 - t) V^shrink and the skeleton
// V^b(t) = t V^tb + (1 - t) V^sb; t is an unknown beside the garment's positions, driven to 1 by an
// augmented Lagrangian, and snapped to 1 once continuous collision detection shows that the rest of the
// inflation passes through nothing.
#include <functional>
#include <string>
#include <vector>

#include "data_tools/geometry/types.h"
#include "refit/newton.h"
#include "refit/refit_weights.h"
#include "refit/skeleton_shrink.h"

namespace amt::refit {

/// Parameters of the inflation (eq. 6).
struct InflationOptions {
  RefitWeights weights;
  double lambda1 = 1.0;  // the augmented Lagrangian's starting penalty λ1
  int max_outer_iterations = 30;
  NewtonOptions newton;
};

/// One outer iteration, for progress displays.
struct InflationProgress {
  int outer_iteration = 0;
  double t = 0.0;
  double energy = 0.0;
  double min_distance = 0.0;  // metres, over the garment's pairs with itself and the avatar
  int newton_iterations = 0;
};

/// The inflated scene.
struct InflationResult {
  Positions garment;         // #Vˢ by 3
  double t = 0.0;            // 1 when snapped
  bool snapped = false;      // the final t = 1 was certified collision-free by CCD
  int outer_iterations = 0;
  std::string stop_reason;
};

/// Inflates the shrunk avatar inside the source garment (source #Vˢ by 3, F_garment). The joints
/// (#J by 3) are the source and target skeletons over the bones the avatar was shrunk with. The scene must
/// start intersection-free (the shrunk avatar strictly inside the garment); throws amt::Error otherwise.
/// `progress`, when set, sees every outer iteration, and `step_observer` every accepted Newton step (over
/// the scene of the garment's vertices followed by the avatar's).
InflationResult inflate_avatar(const Positions& source_garment, const MatrixX3i& F_garment, const ShrunkAvatar& avatar,
                               const Positions& source_joints, const Positions& target_joints, const MatrixX2i& bones,
                               const InflationOptions& options = {},
                               const std::function<void(const InflationProgress&)>& progress = {},
                               const std::function<void(const NewtonStep&)>& step_observer = {});

}  // namespace amt::refit
