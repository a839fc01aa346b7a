#pragma once
// The runtime measured on a generated character (`amt bench --suite runtime`, `amt eval --runtime`):
// a dressed procedural character of about the requested size, optionally remade as real models are
// built (a body of many open, overlapping parts: data_tools/builder/open_parts.h), bound through the
// bind cache with the dressed character's mask or the segmenter's, then RuntimeSession frame by frame
// on a walk after a lead-in, timed per stage. Timing is never asserted: the figures are reported.
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "models/pipeline.h"

namespace amt {

/// The per-frame cost of the whole runtime step (`amt animate`'s RuntimeSession: pipeline, penetration
/// resolution, GLB output) at one thread count; milliseconds are medians over the timed frames.
struct RuntimeThreadFigures {
  int threads = 1;
  double median_ms = std::nan(""), p95_ms = std::nan("");
  /// Stages of the median split: the model (LBS, apparel network and refiner, and the copy out),
  /// penetration, output.
  double model_ms = std::nan(""), lbs_ms = std::nan(""), apparel_ms = std::nan(""), refiner_ms = std::nan("");
  double penetration_ms = std::nan(""), output_ms = std::nan("");
  /// Share of apparel vertices inside the body before and after resolution, and the share of inside
  /// tests carried over from the previous frame.
  double inside_before = std::nan(""), inside_after = std::nan(""), carried_share = std::nan("");
  /// Resident memory after the timed frames (MB).
  double resident_mb = std::nan("");
  /// The global apparel form's network (the form the local one replaced) timed beside the model's, frame by
  /// frame on the same character (RuntimeBenchmarkOptions::reference_apparel); NaN when not measured.
  double reference_apparel_ms = std::nan("");
};

/// A runtime measurement on one generated character (`amt bench --suite runtime`, `amt eval --runtime`,
/// whose report tables it, eval/report.h), with the targets it is held to (0: none).
struct RuntimeFigures {
  /// What was measured, for the reader: the character, the mask.
  std::string label, character, mask;
  int vertices = 0, faces = 0, repeats = 0;
  /// Apparel vertices of the mask the model ran with, and of the character as built.
  int apparel_vertices = 0, true_apparel_vertices = 0;
  /// The apparel module's handles and the widest row of its graph over them (0 for the per-vertex form).
  int handles = 0, handle_neighbors = 0;
  double bind_seconds = std::nan(""), peak_resident_mb = std::nan("");
  std::vector<RuntimeThreadFigures> per_thread;
  /// Per-frame median at `target_threads` threads at most target_ms; bind at most target_bind_seconds.
  double target_ms = 0, target_bind_seconds = 0;
  int target_threads = 2;
  /// The apparel network's median on one thread in units of the global form's timed beside it at most this
  /// (0: none).
  double target_apparel_reference_ratio = 0;
};

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
  /// Timed frames per thread count (after a lead-in of kDefaultLeadInFrames).
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
