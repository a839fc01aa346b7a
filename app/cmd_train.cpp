// `amt train segmenter|skinning|apparel|refiner|apparel_refiner|all`: trains the modules on dataset
// shards (train/trainer.h), writing <out>/<module>.ckpt and <out>/<module>.csv, and prints the step
// time and throughput of each run. With --world-size N (or torchrun's WORLD_SIZE), the process is one
// rank of a data-parallel run (train/distributed.h).
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "app/commands.h"
#include "data_tools/geometry/error.h"
#include "models/module_options.h"
#include "models/pipeline.h"
#include "train/samples.h"
#include "train/trainer.h"

namespace amt::app {
namespace {

struct TrainCommand {
  std::string module;
  std::vector<std::string> data;
  std::string variant;
  // Network options of a fresh run as JSON objects (models/module_options.h); empty: the defaults.
  std::string segmenter_json, skinning_json, apparel_json, refiner_json;
  TrainOptions options;
  bool quiet = false;
  // Data-parallel run as given on the command line (world_size 0, rank -1: not given; the environment
  // may give them).
  DistributedOptions distributed{0, -1, "", 300.0, ""};
};

// Bytes in KiB with one decimal.
std::string kibibytes(int64_t bytes) {
  std::ostringstream text;
  text << std::fixed << std::setprecision(1) << static_cast<double>(bytes) / 1024.0;
  return text.str();
}

// One line per run: the figures of the training speed benchmark (docs/training.md, "Speed") and the files.
void report(const TrainResult& result) {
  if (result.rank != 0) {
    std::cout << "rank " << result.rank << " of " << result.world_size << ": steps " << result.first_step << " -> "
              << result.last_step << ", " << 1e3 * result.seconds_per_step << " ms/step (gradient exchange "
              << 1e3 * result.communication_seconds_per_step << " ms/step); rank 0 writes the files" << std::endl;
    return;
  }
  std::cout << std::filesystem::path(result.log).stem().string() << ": steps " << result.first_step << " -> "
            << result.last_step << ", " << 1e3 * result.seconds_per_step << " ms/step, " << result.samples_per_second
            << " samples/s, wall " << result.wall_seconds << " s";
  if (result.world_size > 1) {
    std::cout << ", " << result.world_size << " ranks, gradient exchange "
              << 1e3 * result.communication_seconds_per_step << " ms/step (all-reduce of "
              << kibibytes(result.gradient_bytes) << " KiB " << 1e3 * result.allreduce_seconds_per_step << ")";
  }
  if (!result.validation_losses.empty()) std::cout << ", val_loss " << result.validation_losses.back();
  std::cout << "; wrote";
  for (const std::string& checkpoint : result.checkpoints) std::cout << " " << checkpoint;
  std::cout << " and " << result.log << std::endl;
}

void run(const TrainCommand& command) {
  TrainOptions options = command.options;
  options.progress = !command.quiet;
  const DistributedOptions distributed =
      resolve_distributed_options(command.distributed, [](const char* name) { return std::getenv(name); });
  // Joined before the runs and kept across them (amt train all trains four modules on one group).
  std::unique_ptr<DataParallelGroup> group;
  if (distributed.world_size > 1) group = std::make_unique<DataParallelGroup>(distributed);
  options.group = group.get();
  NetworkOptions& networks = options.networks;
  if (!command.segmenter_json.empty())
    options_from_json(command.segmenter_json, "--segmenter-options", networks.segmenter);
  if (!command.skinning_json.empty()) options_from_json(command.skinning_json, "--skinning-options", networks.skinning);
  if (!command.apparel_json.empty()) {
    if (networks.apparel_form == "local")
      options_from_json(command.apparel_json, "--apparel-options", networks.apparel_dynamics);
    else
      options_from_json(command.apparel_json, "--apparel-options", networks.apparel);
  }
  if (!command.refiner_json.empty()) options_from_json(command.refiner_json, "--refiner-options", networks.refiner);
  if (!command.variant.empty()) {
    AMT_CHECK(command.module == "skinning", "--variant: only the skinning predictor has variants, not '",
              command.module, "'");
    options.networks.skinning.variant = parse_skinning_variant(command.variant, "--variant");
  }
  if (command.module == "swing_reference") {
    // Measures the training data's least lively apparel physics and stores it in the model's local apparel modules.
    const double reference = measure_swing_reference(resolve_shards(command.data));
    AMT_CHECK(reference > 0,
              "--data: no training character's rig carries a physics response (rebuild the data with "
              "this amt: amt dataset build writes /characters/<name>/rig/response)");
    const auto out = std::filesystem::path(options.out_dir);
    AMT_CHECK(std::filesystem::is_regular_file(out / kApparelCheckpoint), (out / kApparelCheckpoint).string(),
              ": no such checkpoint (--out is the model folder whose apparel module is calibrated)");
    for (const char* name : {kApparelCheckpoint, kApparelOwnWeightsCheckpoint}) {
      const std::string path = (out / name).string();
      if (!std::filesystem::is_regular_file(path)) continue;
      const double before = set_swing_reference(path, reference);
      std::printf("%s: swing_reference %.4f (was %.4f)\n", path.c_str(), reference, before);
    }
    return;
  }
  if (command.module == "apparel_refiner") {
    report(train_apparel_refiner(command.data, options));
    return;
  }
  if (command.module != "all") {
    report(train_module(parse_module_kind(command.module, "amt train: MODULE"), command.data, options));
    return;
  }
  AMT_CHECK(options.resume.empty(), "--resume: resumes one module (amt train <module> --resume CKPT), not 'all'");
  const auto out = std::filesystem::path(options.out_dir);
  for (ModuleKind kind : {ModuleKind::kSegmenter, ModuleKind::kSkinning}) {
    report(train_module(kind, command.data, options));
  }
  TrainOptions end_to_end = options;
  if (end_to_end.skinning_checkpoint.empty()) end_to_end.skinning_checkpoint = (out / "skinning.ckpt").string();
  if (networks.apparel_form == "global") {
    report(train_apparel_refiner(command.data, end_to_end));
    return;
  }
  // The local apparel module trains on its own, then the refiner on its rollouts.
  report(train_module(ModuleKind::kApparel, command.data, options));
  end_to_end.apparel_checkpoint = (out / "apparel.ckpt").string();
  report(train_module(ModuleKind::kRefiner, command.data, end_to_end));
}

}  // namespace

void add_train_command(CLI::App& app) {
  auto* train = app.add_subcommand("train", "Train the networks on dataset shards: checkpoints, CSV log, --resume");
  auto command = std::make_shared<TrainCommand>();
  TrainOptions& o = command->options;
  train
      ->add_option("MODULE", command->module,
                   "segmenter, skinning, apparel, refiner, apparel_refiner (the global apparel form and the refiner "
                   "end to end), all (segmenter, skinning, then apparel and refiner, or apparel_refiner for the "
                   "global form), or swing_reference (no training: measures the least lively apparel physics of "
                   "the --data and stores it in the apparel modules of the model folder --out)")
      ->required()
      ->check(
          CLI::IsMember({"segmenter", "skinning", "apparel", "refiner", "apparel_refiner", "all", "swing_reference"}));
  train->add_option("--data", command->data, "Dataset shards: *.h5 files or folders of them")->required();
  train->add_option("--out", o.out_dir, "Output folder for <module>.ckpt and <module>.csv")->required();
  train->add_option("--steps", o.steps, "Step to stop at (a resumed run continues up to it)")->capture_default_str();
  train->add_option("--seed", o.seed, "Seed of the initialisation and the sample order")->capture_default_str();
  train->add_option("--lr", o.learning_rate, "AdamW learning rate")->capture_default_str();
  train->add_option("--weight-decay", o.weight_decay, "AdamW weight decay")->capture_default_str();
  train
      ->add_option("--lr-schedule", o.lr_schedule, "constant (the paper's) or cosine (decays to 0 at --lr-decay-steps)")
      ->check(CLI::IsMember({"constant", "cosine"}))
      ->capture_default_str();
  train
      ->add_option("--lr-decay-steps", o.lr_decay_steps,
                   "Step at which the cosine schedule reaches 0 (0: --steps of the run that starts)")
      ->capture_default_str();
  train
      ->add_option("--weight-loss", o.weights.skinning_weights,
                   "skinning: weight of a direct KL loss against the ground-truth weights (0: the paper's "
                   "indirect supervision through LBS only)")
      ->capture_default_str();
  train
      ->add_option("--edge-weight", o.weights.edge,
                   "lambda_e: weight of the edge-length losses against the rest mesh (skinning, apparel, refiner; "
                   "the paper's 100)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  train
      ->add_option("--regularizer-weight", o.weights.regularizer,
                   "lambda_r: weight of the refiner's L2 loss on its displacements (the paper's 0.01)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  train->add_option("--batch", o.batch, "Samples per step")->capture_default_str();
  train->add_option("--window", o.window, "Frames per apparel / refiner window (3 history + targets)")
      ->capture_default_str();
  train
      ->add_option("--variant", command->variant,
                   "skinning: geodesic (default), no_geodesic or sorted (Table 4); writes skinning.ckpt, "
                   "skinning_no_geodesic.ckpt or skinning_sorted.ckpt")
      ->check(CLI::IsMember({"geodesic", "no_geodesic", "sorted"}));
  train->add_option("--segmenter-options", command->segmenter_json,
                    "Segmenter network options of a fresh run, a JSON object, e.g. '{\"encoder_widths\":[32,64,128]}'");
  train->add_option("--skinning-options", command->skinning_json, "Skinning predictor options (JSON object)");
  train->add_option("--apparel-options", command->apparel_json, "Apparel network options (JSON object)");
  train->add_option("--refiner-options", command->refiner_json, "Refiner network options (JSON object)");
  train
      ->add_option("--apparel-form", o.networks.apparel_form,
                   "Apparel module of a fresh run: local (detail vectors in the anchor joint's frame, normalised, "
                   "around the hold-offset rule; the default) or global (the earlier form, for the ablations)")
      ->check(CLI::IsMember({"local", "global"}))
      ->capture_default_str();
  train
      ->add_option("--unroll", o.unroll,
                   "Local apparel: curriculum of rollout lengths, LENGTH:FRACTION of --lr-decay-steps, ...")
      ->capture_default_str();
  train->add_option("--noise", o.history_noise, "Local apparel: std (m) of the noise on the last history state")
      ->capture_default_str();
  train->add_option("--noise-gamma", o.noise_gamma, "Local apparel: share of the noise the target does not follow")
      ->capture_default_str();
  train
      ->add_option("--rest-start", o.rest_start_fraction,
                   "Local apparel: share of windows rolled out from the rest pose at their clip's start")
      ->capture_default_str();
  train
      ->add_option("--handle-spacing", o.handle_spacing,
                   "Local apparel: move handles about this far apart (metres) that the vertices follow, instead of "
                   "every vertex (0: every vertex); for a fresh run or one started with --init")
      ->check(CLI::Range(0.0, 1.0));
  train->add_flag("--apparel-response", o.apparel_response,
                  "Local apparel: read how lively each character's own physics is (its rig's response, when its "
                  "dataset stores one); for a fresh run or one started with --init (widened with zero weights)");
  train
      ->add_option("--free-run", o.free_run,
                   "Local apparel: at most this many frames rolled out without gradient before the unroll "
                   "(pushforward; --window must hold 3 + this + the longest unroll)")
      ->capture_default_str();
  train
      ->add_option("--apparel-loss", o.apparel_loss,
                   "Local apparel: squared (squared error of the detail vectors) or distance (their mean "
                   "Euclidean distance, PMD's measure)")
      ->check(CLI::IsMember({"squared", "distance"}))
      ->capture_default_str();
  train
      ->add_option("--normalizer-samples", o.normalizer_samples,
                   "Local apparel: samples whose one-step windows set the normalisers of a fresh run")
      ->capture_default_str();
  train->add_option("--skinning-frames", o.skinning_frames, "Frames per skinning sample")->capture_default_str();
  train
      ->add_option("--validate-every", o.validate_every,
                   "Validation loss on held-out windows every K steps and at the end (0: never)")
      ->capture_default_str();
  train->add_option("--validation-samples", o.validation_samples, "Windows in the fixed validation set")
      ->capture_default_str();
  train->add_option("--validation-split", o.validation_split, "Split the validation windows come from")
      ->capture_default_str();
  train->add_option("--checkpoint-every", o.checkpoint_every, "Write the checkpoint every K steps (0: at the end)")
      ->capture_default_str();
  train->add_option("--resume", o.resume,
                    "Continue from this checkpoint (seed, lr, batch and window come from it; --steps is the total; "
                    "apparel_refiner: the refiner.ckpt)");
  train->add_option("--init", o.init,
                    "Start from this checkpoint's network (options, weights, normalisers) with a fresh optimizer, "
                    "step 0 and this run's schedule (fine-tuning, e.g. a rollout curriculum after one-step training)");
  train->add_option("--apparel", o.apparel_checkpoint,
                    "refiner: the trained apparel module; apparel_refiner --resume: the apparel checkpoint "
                    "(default: apparel.ckpt next to the resumed refiner.ckpt)");
  train->add_option("--skinning", o.skinning_checkpoint,
                    "refiner, apparel_refiner: the trained skinning predictor for the body; apparel (local form): the "
                    "one whose body weights skin the anchors, as at run time (default: ground-truth body weights; "
                    "all: <out>/skinning.ckpt for the refiner)");
  train
      ->add_option("--anchor-truth-share", o.anchor_truth_share,
                   "apparel (local form) with --skinning: the share of characters whose anchors keep the "
                   "ground-truth body weights (the weights of a file's own skin), the others the predictor's")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  train->add_option("--loader-threads", o.loader_threads, "Threads reading samples ahead of training")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  train->add_flag(
      "--no-segmenter-augment", [command](int64_t) { command->options.segmenter_augment = false; },
      "Segmenter with inputs welded: train on the characters as built only (no open-parts, bare-body, "
      "mirrored, turned or scaled variants)");
  train
      ->add_option("--segmenter-artist-style", command->options.segmenter_artist_style,
                   "Segmenter with augmentation: share of steps that draw the character remade as artists build "
                   "models (UV islands with coincident copies, hair strips, double-sided and layered panels; as amt "
                   "eval --artist-style remakes them)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  train
      ->add_option("--segmenter-artist-vertices", command->options.segmenter_artist_vertices,
                   "Vertices the segmenter's artist-style remakes are subdivided to (0: no subdivision)")
      ->check(CLI::Range(0, 200000))
      ->capture_default_str();
  train
      ->add_option("--segmenter-held-weight", command->options.segmenter_held_weight,
                   "Segmenter: loss weight of the held rows, the body vertices of parts that also hold apparel "
                   "(where a piece hangs from the body)")
      ->check(CLI::Range(0.01, 1000.0))
      ->capture_default_str();
  train
      ->add_option("--ema", command->options.ema,
                   "Keep an exponential moving average of the parameters with this decay per step (e.g. 0.999; 0: "
                   "off): the checkpoint's network and the validation are the average")
      ->check(CLI::Range(0.0, 0.99999))
      ->capture_default_str();
  train->add_flag("--quiet", command->quiet, "No progress line on stderr");
  DistributedOptions& d = command->distributed;
  train
      ->add_option("--world-size", d.world_size,
                   "Data-parallel run: number of ranks (processes), each with --batch samples per step (default: "
                   "WORLD_SIZE, else 1)")
      ->check(CLI::PositiveNumber);
  train->add_option("--rank", d.rank, "Data-parallel run: this process's rank in [0, world size) (default: RANK)")
      ->check(CLI::NonNegativeNumber);
  train->add_option("--rendezvous", d.rendezvous,
                    "Data-parallel run: where the ranks meet, tcp://HOST:PORT (rank 0 listens on HOST's address "
                    "only: 127.0.0.1 keeps the run on this machine) or file://PATH (a path every rank sees, free or "
                    "left by an earlier amt run; rank 0 starts a new run there, the others wait for it) (default: "
                    "tcp://MASTER_ADDR:MASTER_PORT); see docs/distributed_security.md");
  train->add_option("--dist-token", d.token,
                    "Data-parallel run: the shared secret every rank presents to a tcp:// rendezvous, 16 to 256 "
                    "printable characters, the same on every rank (default: AMT_DIST_TOKEN, which unlike the command "
                    "line other users cannot see in the process list). Needed for an address other than loopback; "
                    "on a loopback address without one, rank 0 generates one and writes it to "
                    "~/.cache/amt/rendezvous-HOST-PORT.token (mode 0600), where the other ranks of the same user "
                    "read it");
  train
      ->add_option("--dist-timeout", d.timeout_seconds,
                   "Data-parallel run: seconds to wait for every rank to join and for the others at each step before "
                   "stopping with an error (rank 0's validation and checkpoints must fit in it)")
      ->capture_default_str();
  add_threads_option(*train);
  train->callback([command] { run(*command); });
}

}  // namespace amt::app
