#include "train/trainer.h"

#include <ATen/ATen.h>
#include <torch/optim/adamw.h>
#include <torch/utils.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <type_traits>

#include "data_tools/atomic_file.h"
#include "data_tools/error.h"
#include "data_tools/lbs_torch.h"
#include "train/module_options.h"
#include "train/samples.h"

namespace amt {
namespace {

using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// === Run configuration stored in the checkpoint

std::string config_to_json(const TrainOptions& o) {
  Json j;
  j["seed"] = o.seed;
  j["learning_rate"] = o.learning_rate;
  j["weight_decay"] = o.weight_decay;
  j["batch"] = o.batch;
  j["window"] = o.window;
  j["skinning_frames"] = o.skinning_frames;
  j["segmenter_pos_weight"] = o.segmenter_pos_weight;
  j["weights"] = {{"vertex", o.weights.vertex},
                  {"edge", o.weights.edge},
                  {"smoothness", o.weights.smoothness},
                  {"regularizer", o.weights.regularizer}};
  return j.dump();
}

// Takes the (run) settings of TrainOptions from a checkpoint's config.
void config_from_json(const std::string& text, const std::string& path, TrainOptions& o) {
  const Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  AMT_CHECK(j.is_object(), path, ": config: expected a JSON object, found '", text.substr(0, 80), "'");
  const auto get = [&](const Json& from, const char* key, auto& out, const std::string& where) {
    const auto it = from.find(key);
    AMT_CHECK(it != from.end() && it->is_number(), path, ": config.", where, key, ": expected a number, found ",
              it == from.end() ? std::string("nothing") : it->dump());
    out = it->get<std::decay_t<decltype(out)>>();
  };
  get(j, "seed", o.seed, "");
  get(j, "learning_rate", o.learning_rate, "");
  get(j, "weight_decay", o.weight_decay, "");
  get(j, "batch", o.batch, "");
  get(j, "window", o.window, "");
  get(j, "skinning_frames", o.skinning_frames, "");
  get(j, "segmenter_pos_weight", o.segmenter_pos_weight, "");
  const auto weights = j.find("weights");
  AMT_CHECK(weights != j.end() && weights->is_object(), path, ": config.weights: expected an object");
  get(*weights, "vertex", o.weights.vertex, "weights.");
  get(*weights, "edge", o.weights.edge, "weights.");
  get(*weights, "smoothness", o.weights.smoothness, "weights.");
  get(*weights, "regularizer", o.weights.regularizer, "weights.");
}

// === Modules and their losses

// A module being trained: its network, its options as JSON, and the loss of one sample as
// {total, unweighted terms...} in the order of `terms`.
struct Task {
  std::shared_ptr<torch::nn::Module> module;
  std::string options_json;
  std::vector<std::string> terms;
  std::function<std::vector<at::Tensor>(const TrainingSample&)> loss;
};

// A trained module loaded for inference (the refiner's inputs): kind checked, skeleton checked.
template <typename Net, typename Options>
Net load_frozen(const std::string& path, ModuleKind kind, const std::vector<std::string>& joint_names) {
  const CheckpointInfo info = read_checkpoint_info(path, kind);
  check_checkpoint_skeleton(path, info, joint_names);
  Options options;
  options_from_json(info.options_json, path, options);
  Net net(options);
  load_checkpoint(path, kind, *net, nullptr);
  net->eval();
  for (auto& p : net->parameters()) p.set_requires_grad(false);
  return net;
}

// Options from the checkpoint being resumed (when `resumed` is not null) or the fresh ones.
template <typename Options>
Options network_options(const CheckpointInfo* resumed, const std::string& path, Options fresh) {
  if (resumed) options_from_json(resumed->options_json, path, fresh);
  return fresh;
}

// The same for a network over the skeleton's joints: a fresh one gets the dataset's J, a resumed
// one must have been trained on J joints.
template <typename Options>
Options joint_network_options(const CheckpointInfo* resumed, const std::string& path, Options fresh, int64_t J) {
  fresh.num_joints = J;
  const Options options = network_options(resumed, path, fresh);
  AMT_CHECK(options.num_joints == J, path, ": options.num_joints: expected ", J, " (the dataset's), found ",
            options.num_joints);
  return options;
}

Task make_task(ModuleKind kind, const CheckpointInfo* resumed, const TrainOptions& o, int64_t J,
               const std::vector<std::string>& joint_names) {
  Task task;
  const LossWeights w = o.weights;
  switch (kind) {
    case ModuleKind::kSegmenter: {
      ApparelSegmenter net(network_options(resumed, o.resume, o.networks.segmenter));
      task.module = net.ptr();
      task.options_json = options_to_json(net->options);
      task.terms = {"bce"};
      const double pos_weight = o.segmenter_pos_weight;
      task.loss = [net, pos_weight](const TrainingSample& s) mutable {
        const at::Tensor bce = apparel_bce_loss(net->forward(s.character->V), s.character->apparel_mask, pos_weight);
        return std::vector<at::Tensor>{bce, bce};  // eq. (3)
      };
      break;
    }
    case ModuleKind::kSkinning: {
      SkinningPredictor net(joint_network_options(resumed, o.resume, o.networks.skinning, J));
      task.module = net.ptr();
      task.options_json = options_to_json(net->options);
      task.terms = {"vertex", "edge", "smoothness"};
      task.loss = [net, w](const TrainingSample& s) mutable {
        const CharacterTensors& c = *s.character;
        const at::Tensor V_b = c.V.index_select(0, c.body_ids);
        const at::Tensor W = net->forward(V_b, c.joints, c.G_body);
        const at::Tensor B_hat = linear_blend_skinning(V_b, W, s.joint_transforms, c.joints);  // eq. (4)
        const LossTerms l = body_loss(B_hat, s.vertices.index_select(1, c.body_ids), V_b, c.body_edges, W, w);
        return std::vector<at::Tensor>{l.total, l.vertex, l.edge, l.smoothness};
      };
      break;
    }
    case ModuleKind::kApparel: {
      ApparelDisplacementNet net(joint_network_options(resumed, o.resume, o.networks.apparel, J));
      task.module = net.ptr();
      task.options_json = options_to_json(net->options);
      task.terms = {"vertex", "edge"};
      task.loss = [net, w](const TrainingSample& s) mutable {
        const CharacterTensors& c = *s.character;
        const int64_t T = s.vertices.size(0);
        const at::Tensor A = s.vertices.index_select(1, c.apparel_ids);  // (T, N_a, 3)
        // Paper protocol: the first 3 states from ground truth, then T - 3 autoregressive steps (eq. 11).
        const at::Tensor A_hat =
            net->rollout(A.narrow(0, 0, 3), s.joint_transforms.narrow(0, 3, T - 3), c.apparel_neighbors);
        const LossTerms l =
            apparel_loss(A_hat, A.narrow(0, 3, T - 3), c.V.index_select(0, c.apparel_ids), c.apparel_edges, w);
        return std::vector<at::Tensor>{l.total, l.vertex, l.edge};
      };
      break;
    }
    case ModuleKind::kRefiner: {
      AMT_CHECK(!o.apparel_checkpoint.empty(), "--apparel: the refiner trains on the apparel module's output: give ",
                "its checkpoint (amt train apparel writes <out>/apparel.ckpt)");
      ApparelDisplacementNet apparel = load_frozen<ApparelDisplacementNet, ApparelDisplacementOptions>(
          o.apparel_checkpoint, ModuleKind::kApparel, joint_names);
      SkinningPredictor skinning{nullptr};
      if (!o.skinning_checkpoint.empty()) {
        skinning = load_frozen<SkinningPredictor, SkinningPredictorOptions>(o.skinning_checkpoint,
                                                                            ModuleKind::kSkinning, joint_names);
      }
      JointRefiner net(network_options(resumed, o.resume, o.networks.refiner));
      task.module = net.ptr();
      task.options_json = options_to_json(net->options);
      task.terms = {"vertex", "edge", "regularizer"};
      task.loss = [net, apparel, skinning, w](const TrainingSample& s) mutable {
        const CharacterTensors& c = *s.character;
        const int64_t T = s.vertices.size(0);
        const at::Tensor motion = s.joint_transforms.narrow(0, 3, T - 3);
        at::Tensor tiled;
        {
          torch::NoGradGuard frozen;
          at::Tensor A_hat = at::zeros({T - 3, 0, 3});
          if (c.apparel_ids.size(0) > 0) {
            const at::Tensor A = s.vertices.index_select(1, c.apparel_ids);
            A_hat = apparel->rollout(A.narrow(0, 0, 3), motion, c.apparel_neighbors);
          }
          const at::Tensor V_b = c.V.index_select(0, c.body_ids);
          const at::Tensor W = !skinning.is_empty() ? skinning->forward(V_b, c.joints, c.G_body)
                                                    : c.body_weights.index_select(0, c.body_ids);
          const at::Tensor B_hat = linear_blend_skinning(V_b, W, motion, c.joints);
          tiled = tile_apparel_body(A_hat, B_hat, c.apparel_mask);  // eq. (16)
        }
        const RefinerOutput out = net->forward(tiled, c.V, c.apparel_mask.to(at::kFloat));
        const LossTerms l = refiner_loss(out.V_hat, s.vertices.narrow(0, 3, T - 3), c.V, c.edges, out.delta, w);
        return std::vector<at::Tensor>{l.total, l.vertex, l.edge, l.regularizer};
      };
      break;
    }
  }
  return task;
}

// === Log and progress

// Keeps the header and the rows of steps <= `last_step` of an existing log (a resumed run replaces
// what came after its checkpoint); writes a fresh header when there is no usable log.
void prepare_log(const std::string& path, const std::string& header, int64_t last_step) {
  std::vector<std::string> kept = {header};
  std::ifstream in(path);
  std::string line;
  if (last_step > 0 && in && std::getline(in, line) && line == header) {
    while (std::getline(in, line)) {
      if (!line.empty() && std::stoll(line.substr(0, line.find(','))) <= last_step) kept.push_back(line);
    }
  }
  in.close();
  std::string text;
  for (const auto& row : kept) text += row + "\n";
  write_file_atomically(path, text);
}

std::string duration_text(double seconds) {
  const int64_t s = static_cast<int64_t>(std::llround(std::max(0.0, seconds)));
  std::ostringstream out;
  if (s >= 3600)
    out << s / 3600 << "h" << std::setw(2) << std::setfill('0') << (s / 60) % 60 << "m";
  else if (s >= 60)
    out << s / 60 << "m" << std::setw(2) << std::setfill('0') << s % 60 << "s";
  else
    out << s << "s";
  return out.str();
}

}  // namespace

TrainResult train_module(ModuleKind kind, const std::vector<std::string>& data, const TrainOptions& options_in) {
  TrainOptions o = options_in;
  const std::string name = module_kind_name(kind);
  CheckpointInfo resumed;
  if (!o.resume.empty()) {
    resumed = read_checkpoint_info(o.resume, kind);
    config_from_json(resumed.config_json, o.resume, o);
  }
  AMT_CHECK(o.batch >= 1, "--batch: expected >= 1, found ", o.batch);
  AMT_CHECK(o.window >= 4, "--window: expected >= 4 (3 history states and a target), found ", o.window);
  AMT_CHECK(o.skinning_frames >= 1, "--skinning-frames: expected >= 1, found ", o.skinning_frames);
  AMT_CHECK(o.learning_rate > 0, "--lr: expected > 0, found ", o.learning_rate);
  AMT_CHECK(o.steps >= 1, "--steps: expected >= 1, found ", o.steps);

  SampleSourceOptions sampling;
  sampling.kind = kind;
  sampling.frames = kind == ModuleKind::kSkinning ? o.skinning_frames : o.window;
  sampling.seed = o.seed;
  sampling.geodesics = kind == ModuleKind::kRefiner && !o.skinning_checkpoint.empty();
  SampleSource source(resolve_shards(data), sampling);
  const std::vector<std::string>& joint_names = source.joint_names();

  int64_t first_step = 0;
  if (!o.resume.empty()) {
    check_checkpoint_skeleton(o.resume, resumed, joint_names);
    AMT_CHECK(resumed.data_fingerprint == source.fingerprint(), o.resume, ": data_fingerprint: the checkpoint was ",
              "trained on ", resumed.data_fingerprint, ", the given shards are ", source.fingerprint(),
              " (resume with the same shard files)");
    first_step = resumed.step;
    AMT_CHECK(first_step < o.steps, o.resume, ": step: the checkpoint is at step ", first_step, ", --steps ", o.steps,
              " asks for no more (give a larger --steps)");
  }

  torch::manual_seed(o.seed);
  Task task =
      make_task(kind, o.resume.empty() ? nullptr : &resumed, o, static_cast<int64_t>(joint_names.size()), joint_names);
  torch::nn::Module& model = *task.module;
  torch::optim::AdamW optimizer(model.parameters(),
                                torch::optim::AdamWOptions(o.learning_rate).weight_decay(o.weight_decay));
  if (!o.resume.empty()) load_checkpoint(o.resume, kind, model, &optimizer);
  model.train();

  std::error_code error;
  std::filesystem::create_directories(o.out_dir, error);
  AMT_CHECK(!error, o.out_dir, ": cannot create the output folder (", error.message(), ")");
  TrainResult result;
  result.first_step = first_step;
  result.checkpoint = (std::filesystem::path(o.out_dir) / (name + ".ckpt")).string();
  result.log = (std::filesystem::path(o.out_dir) / (name + ".csv")).string();
  std::string header = "step,loss";
  for (const auto& term : task.terms) header += "," + term;
  header += ",samples_per_s,seconds";
  prepare_log(result.log, header, first_step);
  std::ofstream log(result.log, std::ios::app);
  AMT_CHECK(log.good(), result.log, ": cannot append to the training log");
  log << std::setprecision(9);

  CheckpointInfo info;
  info.kind = kind;
  info.options_json = task.options_json;
  info.config_json = config_to_json(o);
  info.joint_names = joint_names;
  info.data_fingerprint = source.fingerprint();

  const bool tty = isatty(fileno(stderr));
  SampleLoader loader(source, first_step * o.batch, (o.steps - first_step) * o.batch, o.loader_threads, o.prefetch);
  const auto run_start = Clock::now();
  auto last_print = run_start;
  for (int64_t step = first_step; step < o.steps; ++step) {
    const auto step_start = Clock::now();
    optimizer.zero_grad();
    std::vector<double> values(task.terms.size() + 1, 0.0);
    for (int b = 0; b < o.batch; ++b) {
      const TrainingSample sample = loader.next();
      const std::vector<at::Tensor> terms = task.loss(sample);
      (terms[0] / static_cast<double>(o.batch)).backward();
      for (size_t i = 0; i < terms.size(); ++i) values[i] += terms[i].item<double>() / o.batch;
    }
    AMT_CHECK(std::isfinite(values[0]), name, ": step ", step + 1, ": the loss is not finite (", values[0],
              "); lower --lr or check the data");
    optimizer.step();
    const auto now = Clock::now();
    const double seconds = std::chrono::duration<double>(now - step_start).count();
    const double elapsed = std::chrono::duration<double>(now - run_start).count();
    result.losses.push_back(values[0]);

    log << step + 1;
    for (double v : values) log << "," << v;
    log << "," << o.batch / seconds << "," << elapsed << "\n";
    log.flush();

    const int64_t done = step + 1 - first_step;
    const bool last = step + 1 == o.steps;
    if (o.progress && (last || std::chrono::duration<double>(now - last_print).count() >= 1.0)) {
      last_print = now;
      const double per_step = elapsed / done;
      std::fprintf(stderr, "%s[%s] step %lld/%lld  loss %.6g  %.1f samples/s  ETA %s%s", tty ? "\r" : "", name.c_str(),
                   static_cast<long long>(step + 1), static_cast<long long>(o.steps), values[0],
                   done * o.batch / elapsed, duration_text(per_step * (o.steps - step - 1)).c_str(),
                   tty && !last ? "   " : "\n");
      std::fflush(stderr);
    }
    if (last || (o.checkpoint_every > 0 && (step + 1) % o.checkpoint_every == 0)) {
      info.step = step + 1;
      save_checkpoint(result.checkpoint, info, model, &optimizer);
    }
  }
  const double total = std::chrono::duration<double>(Clock::now() - run_start).count();
  result.last_step = o.steps;
  result.seconds_per_step = total / static_cast<double>(o.steps - first_step);
  result.samples_per_second = static_cast<double>((o.steps - first_step) * o.batch) / total;
  return result;
}

}  // namespace amt
