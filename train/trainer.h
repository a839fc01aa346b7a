#pragma once
// Trainers of the four modules (docs/training.md, paper section 5.2): AdamW at 1e-4, one seeded
// sample sequence per run (train/samples.h), a single versioned checkpoint file per module written
// every K steps and at the end (models/checkpoint.h), a CSV log, a validation loss on held-out
// windows every K steps, and a progress line on stderr. The apparel module and the refiner also
// train end to end (train_apparel_refiner), as the paper does. A run resumed from a checkpoint
// continues bit for bit as the uninterrupted run would have.
#include <cstdint>
#include <string>
#include <vector>

#include "models/apparel_displacement.h"
#include "models/apparel_dynamics.h"
#include "models/apparel_segmenter.h"
#include "models/checkpoint.h"
#include "models/joint_refiner.h"
#include "models/losses.h"
#include "models/skinning_predictor.h"
#include "train/distributed.h"

namespace amt {

// === Options

/// The networks' options for a fresh run; `num_joints` fields are set from the dataset. A resumed run
/// takes its network's options from the checkpoint instead.
struct NetworkOptions {
  ApparelSegmenterOptions segmenter;
  SkinningPredictorOptions skinning;
  /// The apparel module of a fresh run: "local" (ApparelDynamicsNet with apparel_dynamics, the
  /// default) or "global" (ApparelDisplacementNet with apparel, the earlier form).
  std::string apparel_form = "local";
  ApparelDisplacementOptions apparel;
  ApparelDynamicsOptions apparel_dynamics;
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
  /// (run) Learning-rate schedule: "constant" (the paper's), or "cosine": learning_rate times
  /// (1 + cos(pi * min(step, D) / D)) / 2, decaying to 0 at step D = lr_decay_steps. The rate is a
  /// function of the step alone, so a resumed run follows the same schedule.
  std::string lr_schedule = "constant";
  /// (run) D of the cosine schedule; 0 takes `steps` of the run that starts (a run meant to stop
  /// early and resume later gives the final step count here).
  int64_t lr_decay_steps = 0;
  /// (run) Samples per optimizer step of each rank; the loss is their mean (characters differ in size, so
  /// each sample runs through the network on its own). The checkpoint's config stores the samples per step
  /// of all ranks together (batch times the world size); a resumed run takes that and splits it evenly
  /// between its ranks, so it may resume with another number of ranks.
  int batch = 1;
  /// (run) T, frames per apparel / refiner window: 3 ground-truth history states, then T - 3 targets.
  int window = 10;
  /// (run) The local apparel module's curriculum of unrolled steps: "L1:F1,L2:F2,...", L_k steps
  /// rolled out on the module's own predictions (differentiably) until the step F_k * lr_decay_steps,
  /// the last length thereafter. The window must hold 3 + the longest L (the default fits the
  /// default 10-frame window; the shipped model's recipe rolls out 20 frames in 23-frame windows).
  std::string unroll = "1:0.3,4:0.6,7:1";
  /// (run) Local apparel module: standard deviation (metres) of the Gaussian noise added to the last
  /// ground-truth history state, and the share gamma of it the first target does not follow
  /// (add_history_noise; MeshGraphNets' training noise against exposure bias). 0: no noise.
  double history_noise = 0.001;
  double noise_gamma = 0.1;
  /// (run) Local apparel module: share of windows that start at their clip's first frame from the
  /// rest pose, as `amt animate` and the rollout protocol start (rest apparel history, the motion
  /// blended in over kDefaultLeadInFrames), the loss on the clip's frames.
  double rest_start_fraction = 0.2;
  /// (run) Local apparel module: the pushforward prefix, at most this many frames rolled out on the
  /// module's own predictions without gradient before the differentiable unroll (a seeded draw in
  /// [0, free_run] per window), so that the loss also sees states the module drifted into, as whole-clip
  /// rollouts reach them. The window must hold 3 + free_run + the longest unroll. 0: none.
  int free_run = 0;
  /// The local apparel module's handle spacing (ApparelDynamicsOptions::handle_spacing, metres) for a fresh
  /// run or one started with --init (a per-vertex network fine-tuned on handles); < 0: the options' own.
  double handle_spacing = -1.0;
  /// The local apparel module's physics inputs (ApparelDynamicsOptions::response) for a fresh run or one started
  /// with --init from a module without them (its first block widened with zero weights: it starts as it was).
  bool apparel_response = false;
  /// The local apparel module's swing_reference (ApparelDynamicsOptions) for a fresh run or one started with --init:
  /// measured on the training shards (measure_swing_reference) by run_training; < 0: the options' own.
  double swing_reference = -1.0;
  /// (run) Local apparel module: "squared" (the squared error of the detail vectors, in units of the
  /// target normaliser's scale) or "distance" (the mean Euclidean distance per vertex and frame in the
  /// same units, PMD's own measure: a window that went far off weighs linearly, not quadratically).
  std::string apparel_loss = "squared";
  /// (run) Local apparel module: training samples whose one-step windows set the normalisers before
  /// the first step (a fresh run only; a resumed run has them in its checkpoint).
  int normalizer_samples = 200;
  /// (run) Frames per skinning sample (the LBS result is compared on each).
  int skinning_frames = 4;
  /// (run) Loss weights (section 5.2).
  LossWeights weights;
  /// (run) Segmenter: factor on the BCE terms of apparel vertices (apparel is the minority).
  double segmenter_pos_weight = 1.0;
  /// Segmenter with inputs "welded": train on augmented characters (each step draws the character as
  /// built (60 %), remade of open parts (20 %), its bare body or its bare open parts (10 % each), then mirrors it with
  /// probability 1/2, turns it about the vertical by up to 2 degrees and scales it by 0.85 to 1.15;
  /// seeded by --seed, the step and the character). Validation sees the characters as built.
  bool segmenter_augment = true;
  /// Segmenter with augmentation: share of steps that draw the character remade as artists build models
  /// (data_tools/builder/artist_style.h: UV islands with coincident copies, hair strips, double-sided and layered
  /// panels, open body parts, subdivided to `segmenter_artist_vertices`), before the other variants share the rest;
  /// the remake is then mirrored, turned and scaled like them. 0: never (no remake is made).
  double segmenter_artist_style = 0.0;
  int segmenter_artist_vertices = 20000;
  /// (run) Segmenter: loss weight of the held rows (held_rows_weights: body vertices of parts that hold apparel,
  /// where a piece hangs from the body); 1 for none.
  double segmenter_held_weight = 1.0;
  /// (run) Exponential moving average of the parameters (Polyak averaging), the decay per step (0: off):
  /// after each optimizer step avg = d avg + (1 - d) p with d = min(ema, (1 + step) / (10 + step)), so the
  /// average forgets its start early on. The checkpoint's network (what inference, --init and the
  /// validation use) is the average; the optimizer's own parameters are stored beside it
  /// (save_checkpoint's training_parameters) for --resume.
  double ema = 0.0;
  /// Write the checkpoint every this many steps (0: only at the end).
  int64_t checkpoint_every = 1000;
  /// Validate every this many steps and at the last step (0: never): the mean loss, under
  /// torch::NoGradGuard, of a fixed set of windows (characters for the segmenter) of the
  /// `validation_split`, written to the CSV column val_loss. Data without that split runs without
  /// validation (a note on stderr).
  int64_t validate_every = 500;
  /// Size of the validation set and the seed that picks it (fixed, so every run and every variant is
  /// measured on the same windows), and the split it is drawn from.
  int validation_samples = 16;
  uint64_t validation_seed = 7;
  std::string validation_split = "test";
  /// Folder of the outputs: <out_dir>/<stem>.ckpt and <out_dir>/<stem>.csv, where the stem is the
  /// module's name, or for the skinning variants skinning_file_stem() ("skinning_sorted"), or
  /// "apparel_refiner" for the log of the end-to-end run. Created if missing.
  std::string out_dir = ".";
  /// Checkpoint to resume from (empty: a fresh run). End-to-end run: the refiner's checkpoint.
  std::string resume;
  /// Checkpoint whose network (options, weights, normalisers) a fresh run starts from, with a fresh
  /// optimizer, step 0 and this run's own schedule (fine-tuning; empty: a fresh network). Not with
  /// `resume` or the end-to-end run.
  std::string init;
  /// Refiner only: the trained apparel module (required), whose rollout gives Â. End-to-end run: the
  /// apparel checkpoint resumed along with `resume` (empty: apparel.ckpt next to it).
  std::string apparel_checkpoint;
  /// Refiner and end-to-end run: the trained skinning predictor for B̂; local apparel module: the
  /// predictor whose body weights skin its anchors and build its graph, as at run time. Empty uses the
  /// ground-truth body weights.
  std::string skinning_checkpoint;
  /// Local apparel module with skinning_checkpoint: the share of the training characters whose anchors keep the
  /// ground-truth body weights (picked by a hash of the seed and the character's name), so that the module
  /// meets both the predictor's anchors (generated characters, OBJ meshes) and a file's own weights (PMX, skinned
  /// glTF / VRM, `amt animate --skin-weights auto`). 0: every character on the predictor's.
  double anchor_truth_share = 0.0;
  /// Loader threads reading samples ahead (0: read on the training thread) and how far ahead.
  int loader_threads = 2;
  int prefetch = 8;
  /// Print a progress line (step/total, loss, samples/s, ETA) on stderr.
  bool progress = true;
  /// Networks of a fresh run.
  NetworkOptions networks;
  /// The data-parallel run this process is a rank of (train/distributed.h; not owned, must outlive the
  /// run), null for a process on its own. Every rank holds the model and takes a disjoint share of each
  /// step's samples (SampleShare); the gradients are averaged over the ranks before the optimizer step, and
  /// the parameters start from rank 0's. Rank 0 alone writes the checkpoints, the log, the validation and
  /// the progress line; every rank reads the shards and a resumed checkpoint (a file system they share).
  /// Every rank must run with the same settings and data (checked at the start).
  DataParallelGroup* group = nullptr;
};

// === Local apparel training pieces

/// The curriculum's unroll length at 0-based `step` (TrainOptions::unroll over `horizon` steps).
/// Throws amt::Error "--unroll: ..." for a malformed schedule.
int unroll_at(const std::string& schedule, int64_t step, int64_t horizon);

/// The longest unroll of a schedule.
int longest_unroll(const std::string& schedule);

/// Training noise against exposure bias: `noise` (N_a, 3) is added to the last state of `history`
/// (3, N_a, 3), and `target` (N_a, 3), the next state, moves by (1 - gamma) * noise, so that the
/// network learns to undo the velocity the noise fakes while keeping most of its position error
/// (gamma = 1: undo all of it). Returns {history, target} (new tensors).
std::pair<at::Tensor, at::Tensor> add_history_noise(const at::Tensor& history, const at::Tensor& target,
                                                    const at::Tensor& noise, double gamma);

struct TrainingSample;

/// The local apparel module's loss terms {total, detail, edge} on one sample at 0-based `step`
/// (train/trainer.cpp says how each window is rolled out); `validating` uses the longest unroll, no
/// noise and no prefix. What `amt train apparel` minimises, exposed so that its targets can be checked
/// against a hand-made clip.
std::vector<at::Tensor> local_apparel_loss(ApparelDynamicsNet& net, const TrainingSample& s, int64_t step,
                                           bool validating, const TrainOptions& o);

// === Training

/// What a run did.
struct TrainResult {
  /// Step the run started at (0, or the resumed checkpoint's step) and ended at.
  int64_t first_step = 0, last_step = 0;
  /// Total loss of every step run, in order (steps first_step .. last_step - 1).
  std::vector<double> losses;
  /// The checkpoint and CSV log written (end-to-end run: the refiner's checkpoint).
  std::string checkpoint, log;
  /// Every checkpoint written (end-to-end run: apparel, then refiner).
  std::vector<std::string> checkpoints;
  /// Steps at which the run validated and the validation losses there (empty without validation).
  std::vector<int64_t> validation_steps;
  std::vector<double> validation_losses;
  /// Mean time of an optimizer step including its wait for samples, without validation and
  /// checkpoints (seconds); samples per second at that rate; wall time of the whole run (seconds).
  double seconds_per_step = 0.0, samples_per_second = 0.0, wall_seconds = 0.0;
  /// The process's rank, the number of ranks, and the mean time per step of the gradient exchange (seconds,
  /// included in seconds_per_step, with the wait for the slowest rank; 0 for one process) and of its
  /// all-reduce of the gradients alone. samples_per_second counts every rank's samples.
  int rank = 0, world_size = 1;
  double communication_seconds_per_step = 0.0, allreduce_seconds_per_step = 0.0;
  /// Bytes of the gradients exchanged each step (0 for one process).
  int64_t gradient_bytes = 0;
};

/// Trains the module `kind` on the shards (resolve_shards) from step 0, or from options.resume, up
/// to options.steps. The CSV log <out_dir>/<stem>.csv has the columns step, loss, the module's
/// unweighted terms (segmenter: bce; skinning: vertex, edge, smoothness; apparel: vertex, edge;
/// refiner: vertex, edge, regularizer), samples_per_s, seconds, val_loss (empty on steps without
/// validation); a resumed run drops the rows past the checkpoint's step and appends. The skinning
/// predictor's variant (options.networks.skinning.variant, or the resumed checkpoint's) names its
/// files (skinning_file_stem). Throws amt::Error on bad input: a checkpoint of another module, run
/// or version, a dataset whose skeleton or fingerprint differs from the checkpoint's, a missing shard.
TrainResult train_module(ModuleKind kind, const std::vector<std::string>& shards, const TrainOptions& options);

/// Trains the apparel module and the refiner end to end (docs/training.md, paper section 5.2):
/// on windows of T = options.window frames of any clip, the apparel module rolls out T - 3 frames
/// from 3 ground-truth states (eq. 11), the result is tiled with B̂ (LBS with the weights of
/// options.skinning_checkpoint, or the ground-truth ones) and refined (eq. 16); the loss is
/// L_a + L_j and flows through Â into the apparel module. Characters without apparel contribute
/// L_j only. Writes <out_dir>/apparel.ckpt and <out_dir>/refiner.ckpt (each module with its own AdamW
/// state, at the same step; loadable like those of train_module) and the log
/// <out_dir>/apparel_refiner.csv with the terms apparel_vertex, apparel_edge, refiner_vertex,
/// refiner_edge, refiner_regularizer. Resumes from options.resume (the refiner's checkpoint) and
/// options.apparel_checkpoint (default: apparel.ckpt next to it); both must come from an end-to-end
/// run and be at the same step.
TrainResult train_apparel_refiner(const std::vector<std::string>& shards, const TrainOptions& options);

/// The least lively apparel physics of the training characters (split "train") of `shards` whose rig carries a
/// physics response: swing_reference (models/pipeline.h) over their ground-truth apparel vertices. 0 when none has a
/// response. Throws amt::Error on a shard that cannot be read.
double measure_swing_reference(const std::vector<std::string>& shards);

/// Stores `reference` (> 0) as the swing_reference of the local apparel module in `checkpoint`, which is rewritten
/// (through a temporary, then renamed) with its parameters, buffers, training parameters, optimizer state, step,
/// config and data fingerprint as they were. Returns the reference it held before. Throws amt::Error for a
/// checkpoint that is not a local apparel module's.
double set_swing_reference(const std::string& checkpoint, double reference);

}  // namespace amt
