// `amt train segmenter|skinning|apparel|refiner|all`: trains the modules on dataset shards
// (train/trainer.h), writing <out>/<module>.ckpt and <out>/<module>.csv.
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "app/commands.h"
#include "data_tools/error.h"
#include "train/trainer.h"

namespace amt::app {
namespace {

struct TrainCommand {
  std::string module;
  std::vector<std::string> data;
  TrainOptions options;
  bool quiet = false;
};

void report(ModuleKind kind, const TrainResult& result) {
  std::cout << module_kind_name(kind) << ": steps " << result.first_step << " -> " << result.last_step << ", "
            << result.seconds_per_step << " s/step, " << result.samples_per_second << " samples/s; wrote "
            << result.checkpoint << " and " << result.log << "\n";
}

void run(const TrainCommand& command) {
  TrainOptions options = command.options;
  options.progress = !command.quiet;
  if (command.module != "all") {
    const ModuleKind kind = parse_module_kind(command.module, "amt train: MODULE");
    report(kind, train_module(kind, command.data, options));
    return;
  }
  AMT_CHECK(options.resume.empty(), "--resume: resumes one module (amt train <module> --resume CKPT), not 'all'");
  const auto out = std::filesystem::path(options.out_dir);
  for (ModuleKind kind : {ModuleKind::kSegmenter, ModuleKind::kSkinning, ModuleKind::kApparel, ModuleKind::kRefiner}) {
    TrainOptions module_options = options;
    if (kind == ModuleKind::kRefiner) {
      if (module_options.apparel_checkpoint.empty())
        module_options.apparel_checkpoint = (out / "apparel.ckpt").string();
      if (module_options.skinning_checkpoint.empty()) {
        module_options.skinning_checkpoint = (out / "skinning.ckpt").string();
      }
    }
    report(kind, train_module(kind, command.data, module_options));
  }
}

}  // namespace

void add_train_command(CLI::App& app) {
  auto* train = app.add_subcommand("train", "Train the networks on dataset shards: checkpoints, CSV log, --resume");
  auto command = std::make_shared<TrainCommand>();
  TrainOptions& o = command->options;
  train->add_option("MODULE", command->module, "segmenter, skinning, apparel, refiner, or all (in that order)")
      ->required()
      ->check(CLI::IsMember({"segmenter", "skinning", "apparel", "refiner", "all"}));
  train->add_option("--data", command->data, "Dataset shards: *.h5 files or folders of them")->required();
  train->add_option("--out", o.out_dir, "Output folder for <module>.ckpt and <module>.csv")->required();
  train->add_option("--steps", o.steps, "Step to stop at (a resumed run continues up to it)")->capture_default_str();
  train->add_option("--seed", o.seed, "Seed of the initialisation and the sample order")->capture_default_str();
  train->add_option("--lr", o.learning_rate, "AdamW learning rate")->capture_default_str();
  train->add_option("--weight-decay", o.weight_decay, "AdamW weight decay")->capture_default_str();
  train->add_option("--batch", o.batch, "Samples per step")->capture_default_str();
  train->add_option("--window", o.window, "Frames per apparel / refiner window (3 history + targets)")
      ->capture_default_str();
  train->add_option("--checkpoint-every", o.checkpoint_every, "Write the checkpoint every K steps (0: at the end)")
      ->capture_default_str();
  train->add_option("--resume", o.resume,
                    "Continue from this checkpoint (seed, lr, batch and window come from it; --steps is the total)");
  train->add_option("--apparel", o.apparel_checkpoint, "refiner: the trained apparel module (all: <out>/apparel.ckpt)");
  train->add_option("--skinning", o.skinning_checkpoint,
                    "refiner: the trained skinning predictor (default: ground-truth body weights; all: "
                    "<out>/skinning.ckpt)");
  train->add_option("--loader-threads", o.loader_threads, "Threads reading samples ahead of training")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  train->add_flag("--quiet", command->quiet, "No progress line on stderr");
  add_threads_option(*train);
  train->callback([command] { run(*command); });
}

}  // namespace amt::app
