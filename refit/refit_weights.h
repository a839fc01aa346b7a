#pragma once
// The weights of the garment refit's objectives (the garment-refit paper, eqs. 6 and 7), shared by the
// inflation (section 3.5) and the garment fit (section 3.6). Distances in metres.

namespace amt::refit {

/// Weights and the barrier's activation distance.
struct RefitWeights {
  double d_hat = 2e-3;              // barrier activation distance d̂ (the paper's 0.002, read as metres)
  double contact_weight = 1e4;      // κ (w_contact)
  double surface_weight = 1.0;      // on L_surf
  double positional_weight = 10.0;  // w_pos
  double curve_weight = 1.0;        // on L_curve
  double fit_weight = 2.0;          // w_fit on L_fit (garment fit only, section 3.6)
};

}  // namespace amt::refit
