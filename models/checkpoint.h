#pragma once
// Training checkpoints: one self-describing file per trained module, format "amt-checkpoint",
// version 1, written through torch::serialize::OutputArchive (a TorchScript zip archive) to
// "<path>.amt-tmp" and renamed onto the target, so an interrupted save never replaces a good file.
//
// Keys of the archive:
//   format "amt-checkpoint", version 1, kind ("segmenter" | "skinning" | "apparel" | "refiner"),
//   options (the network's options, JSON text: models/module_options.h), config (the training
//   run's settings, JSON text), step (optimizer steps taken), joint_names (J strings: the skeleton
//   the module was trained on), data_fingerprint (data_fingerprint() of the training shards),
//   model/ (parameter_names and buffer_names, the qualified names of the module's tensors, and the
//   tensors themselves under p0, p1, ... and b0, b1, ...), optimizer/ (Optimizer::save; absent in a
//   model-only file), training_parameters/ and training_parameters_crc32 (a run with a moving average
//   of its parameters: the parameters the optimizer works on; model/ holds the average).
// No random-number state is stored: a training step draws no random numbers, and the samples of a
// step are a function of (seed, step) alone (train/samples.h), so step and seed resume a run exactly.
#include <torch/nn/module.h>
#include <torch/optim/optimizer.h>
#include <torch/serialize/output-archive.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace amt {

// === Format

/// Value of the key `format`.
inline constexpr const char* kCheckpointFormat = "amt-checkpoint";
/// Value of the key `version` this code writes and reads.
inline constexpr int64_t kCheckpointVersion = 1;

/// The module a checkpoint holds (docs/architecture.md, "The pipeline").
enum class ModuleKind { kSegmenter, kSkinning, kApparel, kRefiner };

/// "segmenter", "skinning", "apparel" or "refiner".
const char* module_kind_name(ModuleKind kind);

/// Inverse of module_kind_name; throws amt::Error "<source>: expected segmenter, skinning, apparel or
/// refiner, found 'x'".
ModuleKind parse_module_kind(const std::string& name, const std::string& source);

// === Contents

/// Everything in a checkpoint besides the tensors.
struct CheckpointInfo {
  /// The module the file holds.
  ModuleKind kind = ModuleKind::kSegmenter;
  /// The network's options as JSON text (options_to_json); rebuilds the network before loading.
  std::string options_json;
  /// The training run's settings as JSON text (TrainOptions, train/trainer.h), kept for the record.
  std::string config_json;
  /// Optimizer steps taken when the file was written.
  int64_t step = 0;
  /// J joint names of the skeleton the module was trained on.
  std::vector<std::string> joint_names;
  /// data_fingerprint() of the shards the module was trained on.
  std::string data_fingerprint;
  /// Whether the file carries payload_crc32 (the CRC-32 of the options and tensors, checked on every load). Files
  /// written before amt stored it load unverified; save_checkpoint always writes it.
  bool checksummed = false;
  /// Whether the file holds an optimizer state (a checkpoint that --resume can continue).
  bool has_optimizer = false;
};

// === Save and load

/// Writes `info`, the parameters and buffers of `model` and, when not null, the state of `optimizer`
/// to `path` (through "<path>.amt-tmp", then renamed). Throws amt::Error when the file cannot be written.
/// `training_parameters`, when not null, are the parameters the optimizer works on where they differ
/// from the model's (a run with a moving average of its parameters stores the average as the model and
/// these for --resume): key training_parameters/ (t0, t1, ... in model->parameters() order) with its own
/// CRC-32 training_parameters_crc32.
void save_checkpoint(const std::string& path, const CheckpointInfo& info, const torch::nn::Module& model,
                     const torch::optim::Optimizer* optimizer,
                     const std::vector<at::Tensor>* training_parameters = nullptr);

/// Saves `archive` to `path` through "<path>.amt-tmp", renamed when complete (the parent folder is created).
/// Throws amt::Error "<path>.amt-tmp: cannot write the <what> (reason)" and removes the temporary on failure.
void save_archive_atomically(torch::serialize::OutputArchive& archive, const std::string& path,
                             const std::string& what);

/// Reads the info of a checkpoint without touching any model, checking the format, the version and,
/// when `expected_kind` is given, the kind. Errors name the file and the key:
/// "x.ckpt: kind: expected 'skinning', found 'segmenter'", "x.ckpt: version: expected 1, found 2".
CheckpointInfo read_checkpoint_info(const std::string& path, std::optional<ModuleKind> expected_kind = std::nullopt);

/// Loads a checkpoint of kind `expected_kind` into `model`, which must have been built from the
/// checkpoint's options (read_checkpoint_info first): every parameter and buffer must exist with the
/// stored shape. When `optimizer` is not null, its state is restored too (the file must hold one; the
/// optimizer must be over model->parameters() in the same order). `training_parameters`, when not null,
/// receives the stored training parameters (save_checkpoint; empty when the file has none), checked
/// against the model's parameters' count and shapes and against their CRC-32. Returns the info.
CheckpointInfo load_checkpoint(const std::string& path, ModuleKind expected_kind, torch::nn::Module& model,
                               torch::optim::Optimizer* optimizer,
                               std::vector<at::Tensor>* training_parameters = nullptr);

/// A trained network rebuilt for inference from the checkpoint at `path`: reads the info (the kind must be
/// `kind`), builds a Net from the stored options (options_from_json, models/module_options.h), loads its
/// tensors (load_checkpoint) and freezes it: eval mode, no parameter requires grad. `info` receives the
/// checkpoint's info. Errors name the file and the key, as those of the functions it calls.
/// Defined for the four networks of models/: (ApparelSegmenter, ApparelSegmenterOptions),
/// (SkinningPredictor, SkinningPredictorOptions), (ApparelDisplacementNet, ApparelDisplacementOptions),
/// (ApparelDynamicsNet, ApparelDynamicsOptions) and (JointRefiner, JointRefinerOptions).
template <typename Net, typename Options>
Net load_frozen_network(const std::string& path, ModuleKind kind, CheckpointInfo& info);

/// Throws amt::Error unless the checkpoint was trained on `dataset_joint_names` (same names, same
/// order): "x.ckpt: skeleton: the checkpoint was trained on N joints (a, b, ...), the dataset has M (...)".
void check_checkpoint_skeleton(const std::string& path, const CheckpointInfo& info,
                               const std::vector<std::string>& dataset_joint_names);

}  // namespace amt
