#pragma once
// A fixed, small training run of the skinning predictor f_s through differentiable LBS (eq. 8), shared by
// its unit test (tests/models/skinning_predictor_torch_test.cpp: the loss falls tenfold) and by
// `amt bench --suite skinning` (its wall time): a bar of 2 x 11 vertices along Y with joints at its bottom,
// middle and top, hat-function ground-truth weights, and 8 random frames of a two-link chain.
#include <cstdint>

namespace amt {

/// The L1 vertex loss before and after `steps` AdamW steps (learning rate 2e-3).
struct SkinningOverfit {
  double initial_loss = 0, final_loss = 0;
  int steps = 0;
};

/// Runs the overfit on the current LibTorch threads, seeding LibTorch's generator with `seed` (the
/// frames and the initial weights depend on it).
SkinningOverfit overfit_skinning_on_a_bar(int steps = 500, uint64_t seed = 5);

}  // namespace amt
