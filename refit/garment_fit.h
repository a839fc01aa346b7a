#pragma once
// Step 3 of the garment refit (the garment-refit paper, section 3.6): the avatar fixed at its own shape
// (t = 1), the garment optimised for shape, position and contact (eq. 7).
//
// Not yet included: the fit term L_fit (eq. 4), which needs the avatar's signed distance field (OpenVDB);
// until then this is eq. 7 with w_fit = 0, i.e. the garment relaxes to the target skeleton while keeping
// its shape, without being drawn towards the body.
#include <functional>
#include <string>

#include "data_tools/geometry/types.h"
#include "refit/newton.h"
#include "refit/refit_weights.h"

namespace amt::refit {

/// Parameters of the garment fit (eq. 7 without L_fit).
struct GarmentFitOptions {
  RefitWeights weights;
  NewtonOptions newton;
};

/// The garment fitted onto the avatar (V #V by 3, F): `start` (#Vˢ by 3, intersection-free with the avatar,
/// e.g. the inflation's result) moved to minimise eq. 7 with the shape terms measured against the source
/// garment (source, F_garment) and the positional term against the target skeleton. Returns the Newton
/// solver's account; *garment receives the fitted positions. `observer` sees every accepted step (over
/// the garment's vertices followed by the avatar's).
NewtonResult fit_garment(const Positions& source, const MatrixX3i& F_garment, const Positions& start,
                         const Positions& avatar_V, const MatrixX3i& avatar_F, const Positions& source_joints,
                         const Positions& target_joints, const MatrixX2i& bones, Positions* garment,
                         const GarmentFitOptions& options = {},
                         const std::function<void(const NewtonStep&)>& observer = {});

}  // namespace amt::refit
