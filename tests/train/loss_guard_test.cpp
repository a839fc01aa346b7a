#include "train/loss_guard.h"

#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace amt {
namespace {

TEST(LossJumpGuard, AJumpOfFourOrdersOfMagnitudeStopsTheRunNamingTheStep) {
  LossJumpGuard guard;
  for (int step = 1; step <= 3; ++step) guard.check(0.5 / step, step, "apparel");
  EXPECT_NEAR(guard.reference(), 0.25, 1e-12);  // median of 0.5, 0.25, 0.1667
  guard.check(2.0, 4, "apparel");               // a bad batch, 8x: kept
  EXPECT_NO_THROW(guard.check(0.25 * 9.9e3, 5, "apparel"));
  const std::string e = test::error_of([&] { guard.check(6e33, 6, "apparel"); });
  EXPECT_EQ(e.rfind("apparel: step 6: the loss jumped to 6e+33, more than 10000 times its recent median", 0), 0u) << e;
}

TEST(LossJumpGuard, TheFirstStepsAndAFallingLossPass) {
  LossJumpGuard guard;
  EXPECT_NO_THROW(guard.check(1e9, 1, "segmenter"));  // no history yet: nothing to compare with
  EXPECT_NO_THROW(guard.check(1e3, 2, "segmenter"));
  EXPECT_NO_THROW(guard.check(1.0, 3, "segmenter"));
  for (int step = 4; step < 100; ++step) EXPECT_NO_THROW(guard.check(1.0 / step, step, "segmenter"));
}

}  // namespace
}  // namespace amt
