#pragma once
// A training run stops when its loss jumps by many orders of magnitude: a damaged optimizer state, a corrupted
// sample or a learning rate far too high shows as a loss 1e4 times (or more) its recent level, and the next
// checkpoint would otherwise carry a valid checksum over the damage.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "data_tools/geometry/error.h"

namespace amt {

/// Watches a run's losses. check() throws amt::Error when a loss exceeds `factor` times the median of the last
/// `window` losses (once at least `min_history` are known); the losses that pass join the window.
class LossJumpGuard {
 public:
  explicit LossJumpGuard(double factor = 1e4, size_t window = 20, size_t min_history = 3)
      : factor_(factor), window_(window), min_history_(min_history) {}

  /// The median of the recent losses (NaN before any).
  double reference() const {
    if (recent_.empty()) return std::nan("");
    std::vector<double> v(recent_.begin(), recent_.end());
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
    return v[v.size() / 2];
  }

  /// Checks the loss of step `step` (1-based) of run `name`.
  void check(double loss, int64_t step, const std::string& name) {
    if (recent_.size() >= min_history_) {
      const double median = reference();
      AMT_CHECK(!(median > 0 && loss > factor_ * median), name, ": step ", step, ": the loss jumped to ", loss,
                ", more than ", factor_, " times its recent median ", median,
                "; the optimizer state or the data may be damaged: resume from an earlier checkpoint or lower --lr");
    }
    recent_.push_back(loss);
    if (recent_.size() > window_) recent_.pop_front();
  }

 private:
  double factor_;
  size_t window_, min_history_;
  std::deque<double> recent_;
};

}  // namespace amt
