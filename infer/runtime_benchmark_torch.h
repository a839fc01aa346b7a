#pragma once
// The runtime measured on a generated character (`amt bench --suite runtime`, `amt eval --runtime`):
// a dressed procedural character of about the requested size, optionally remade as real models are
// built (a body of many open, overlapping parts: data_tools/builder/open_parts.h), bound through the
// bind cache with the dressed character's mask or the segmenter's, then RuntimeSession frame by frame
// on a walk after a lead-in, timed per stage. Timing is never asserted: the figures are reported.
#include <string>
#include <utility>
#include <vector>

#include "eval/evaluate.h"
#include "models/pipeline.h"

namespace amt {

/// What to measure.
struct RuntimeBenchmarkOptions {
  /// Requested vertex count (the generated character comes close to it).
  int vertices = 20000;
  /// Remake the body of open, overlapping parts (real models' build), ~20 % apparel; else a closed
  /// dressed body with ~30 % apparel.
  bool open_parts = false;
  /// Remake the dressed character as artists build models (data_tools/builder/artist_style.h: open body parts,
  /// UV seams with coincident copies, hair strips, double-sided and layered panels) at about `vertices`.
  bool artist_style = false;
  /// Bind with the segmenter's mask (as `amt animate` does by default) instead of the dressed character's.
  bool segmenter_mask = false;
  /// Thread counts measured, in order (the bind runs on the last).
  std::vector<int> threads = {1, 2};
  /// Timed frames per thread count (after a 10-frame lead-in).
  int repeats = 30;
  /// Also time the apparel network of the global form, which the local form replaced (the widths it was
  /// shipped with, fresh weights: a step's time does not depend on their values), on the same character
  /// frame by frame beside the model's, so that the two are compared under the same load
  /// (RuntimeThreadFigures::reference_apparel_ms). Ignored when the model's apparel module is the global form.
  bool reference_apparel = false;
  /// Run the joint refiner after the apparel module, as `amt animate --refiner` (off by default, as in
  /// `amt animate`).
  bool refine = false;
  /// The learned apparel's stretch limit, as `amt animate --strain-limit` (0: off).
  float strain_limit = kDefaultStrainLimit;
  /// Folder for the scratch GLB (removed afterwards).
  std::string scratch_dir;
};

/// Measures `bundle` as `options` say (the caller's thread count is restored afterwards). `label` names the
/// measurement in the report; no targets are set.
RuntimeFigures measure_runtime(const ModelBundle& bundle, const RuntimeBenchmarkOptions& options,
                               const std::string& label = "");

/// Median and 95th percentile of a sample (sorted in place; empty: NaN).
std::pair<double, double> median_p95(std::vector<double>& v);

/// Peak and current resident memory of the process (MB).
double peak_resident_mb();
double resident_mb();

}  // namespace amt
