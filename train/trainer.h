#pragma once
// Trainers of the four modules (DESIGN.md section 1, paper section 5.2): AdamW at 1e-4, one seeded
// sample sequence per run (train/samples.h), a single versioned checkpoint file per module written
// every K steps and at the end (train/checkpoint.h), a CSV log and a progress line on stderr.
// A run resumed from a checkpoint continues bit for bit as the uninterrupted run would have.
#include <cstdint>
#include <string>
#include <vector>

#include "models/apparel_displacement.h"
#include "models/apparel_segmenter.h"
#include "models/joint_refiner.h"
#include "models/losses.h"
#include "models/skinning_predictor.h"
#include "train/checkpoint.h"

namespace amt {

// === Options

/// The networks' options for a fresh run; `num_joints` fields are set from the dataset. A resumed run
/// takes its network's options from the checkpoint instead.
struct NetworkOptions {
  ApparelSegmenterOptions segmenter;
  SkinningPredictorOptions skinning;
  ApparelDisplacementOptions apparel;
  JointRefinerOptions refiner;
};

/// Settings of a training run. Those marked "(run)" are stored in the checkpoint's config and, on
/// --resume, taken from it (so the resumed run continues the same sequence); the others may change.
struct TrainOptions {
  /// Step at which the run stops (also when resuming: the total, not the number of further steps).
  int64_t steps = 10000;
  /// (run) Seed of the network initialisation and of the sample order.
  uint64_t seed = 1;
  /// (run) AdamW learning rate (paper section 5.2) and decoupled weight decay (LibTorch's default).
  double learning_rate = 1e-4;
  double weight_decay = 1e-2;
  /// (run) Samples per optimizer step; the loss is their mean (characters differ in size, so each
  /// sample runs through the network on its own).
  int batch = 1;
  /// (run) T, frames per apparel / refiner window: 3 ground-truth history states, then T - 3 targets.
  int window = 10;
  /// (run) Frames per skinning sample (the LBS result is compared on each).
  int skinning_frames = 4;
  /// (run) Loss weights (section 5.2).
  LossWeights weights;
  /// (run) Segmenter: factor on the BCE terms of apparel vertices (apparel is the minority).
  double segmenter_pos_weight = 1.0;
  /// Write the checkpoint every this many steps (0: only at the end).
  int64_t checkpoint_every = 1000;
  /// Folder of the outputs: <out_dir>/<kind>.ckpt and <out_dir>/<kind>.csv. Created if missing.
  std::string out_dir = ".";
  /// Checkpoint to resume from (empty: a fresh run).
  std::string resume;
  /// Refiner only: the trained apparel module (required), whose rollout gives Â.
  std::string apparel_checkpoint;
  /// Refiner only: the trained skinning predictor for B̂; empty uses the ground-truth body weights.
  std::string skinning_checkpoint;
  /// Loader threads reading samples ahead (0: read on the training thread) and how far ahead.
  int loader_threads = 2;
  int prefetch = 8;
  /// Print a progress line (step/total, loss, samples/s, ETA) on stderr.
  bool progress = true;
  /// Networks of a fresh run.
  NetworkOptions networks;
};

// === Training

/// What a run did.
struct TrainResult {
  /// Step the run started at (0, or the resumed checkpoint's step) and ended at.
  int64_t first_step = 0, last_step = 0;
  /// Total loss of every step run, in order (steps first_step .. last_step - 1).
  std::vector<double> losses;
  /// The checkpoint and CSV log written.
  std::string checkpoint, log;
  /// Mean wall time of an optimizer step (seconds) and samples per second over the run.
  double seconds_per_step = 0.0, samples_per_second = 0.0;
};

/// Trains the module `kind` on the shards (resolve_shards) from step 0, or from options.resume, up
/// to options.steps. The CSV log <out_dir>/<kind>.csv has the columns step, loss, the module's
/// unweighted terms (segmenter: bce; skinning: vertex, edge, smoothness; apparel: vertex, edge;
/// refiner: vertex, edge, regularizer), samples_per_s, seconds; a resumed run drops the rows past
/// the checkpoint's step and appends. Throws amt::Error on bad input: a checkpoint of another module
/// or version, a dataset whose skeleton or fingerprint differs from the checkpoint's, a missing shard.
TrainResult train_module(ModuleKind kind, const std::vector<std::string>& shards, const TrainOptions& options);

}  // namespace amt
