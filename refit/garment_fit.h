#pragma once
// Step 3 of the garment refit (the garment-refit paper, section 3.6): the avatar fixed at its own shape
// (t = 1), the garment optimised for fit, shape, position and contact (eq. 7). With no fit region the fit
// term is left out (w_fit = 0): the garment relaxes to the target skeleton keeping its shape, without
// being drawn towards the body.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "data_tools/geometry/types.h"
#include "refit/newton.h"
#include "refit/refit_weights.h"

namespace amt::refit {

/// Parameters of the garment fit (eq. 7).
struct GarmentFitOptions {
  RefitWeights weights;
  NewtonOptions newton;
  /// G_fit of the fit term (#Vˢ mask, fit_term.h's fit_region), or empty for no fit term.
  std::vector<uint8_t> fit_vertices;
  /// The avatar's distance field for the fit term (distance_field.h): voxel size and band, metres.
  double voxel_size = 0.004;
  double field_band = 0.04;
};

/// What the garment fit reports beside the positions.
struct GarmentFitReport {
  NewtonResult newton;
  double fit_distance = 0.0;  // area-weighted mean |D| over G_fit at the result, metres (0 without a fit region)
  double field_seconds = 0.0; // building the avatar's distance field
};

/// The garment fitted onto the avatar (V #V by 3, F): `start` (#Vˢ by 3, intersection-free with the avatar,
/// e.g. the inflation's result) moved to minimise eq. 7 with the shape terms measured against the source
/// garment (source, F_garment) and the positional term against the target skeleton. Returns the Newton
/// solver's account; *garment receives the fitted positions; *report (when not null) the fit distance.
/// `observer` sees every accepted step (over the garment's vertices followed by the avatar's).
NewtonResult fit_garment(const Positions& source, const MatrixX3i& F_garment, const Positions& start,
                         const Positions& avatar_V, const MatrixX3i& avatar_F, const Positions& source_joints,
                         const Positions& target_joints, const MatrixX2i& bones, Positions* garment,
                         const GarmentFitOptions& options = {},
                         const std::function<void(const NewtonStep&)>& observer = {},
                         GarmentFitReport* report = nullptr);

}  // namespace amt::refit
