#include "train/trainer.h"
#include "train/loss_guard.h"

#include <ATen/ATen.h>
#include <ATen/CPUGeneratorImpl.h>
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
#include <random>
#include <sstream>
#include <type_traits>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/apparel_topology.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs_torch.h"
#include "models/edge_conv.h"
#include "models/module_options.h"
#include "models/pipeline.h"
#include "train/samples.h"

namespace amt {
namespace {

using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// === Run configuration stored in the checkpoint

// The `mode` of a checkpoint's config: a module trained on its own, or the end-to-end pair.
constexpr const char* kSingleMode = "single";
constexpr const char* kEndToEndMode = "apparel_refiner";

std::string config_to_json(const TrainOptions& o, const char* mode) {
  Json j;
  j["mode"] = mode;
  j["seed"] = o.seed;
  j["learning_rate"] = o.learning_rate;
  j["weight_decay"] = o.weight_decay;
  j["lr_schedule"] = o.lr_schedule;
  j["lr_decay_steps"] = o.lr_decay_steps;
  j["batch"] = o.batch;
  j["window"] = o.window;
  j["skinning_frames"] = o.skinning_frames;
  j["segmenter_pos_weight"] = o.segmenter_pos_weight;
  if (o.segmenter_held_weight != 1.0) j["segmenter_held_weight"] = o.segmenter_held_weight;
  if (o.ema != 0.0) j["ema"] = o.ema;  // only when on: earlier configs stay as they were
  j["unroll"] = o.unroll;
  j["history_noise"] = o.history_noise;
  j["noise_gamma"] = o.noise_gamma;
  j["rest_start_fraction"] = o.rest_start_fraction;
  j["free_run"] = o.free_run;
  j["apparel_loss"] = o.apparel_loss;
  j["normalizer_samples"] = o.normalizer_samples;
  j["weights"] = {{"vertex", o.weights.vertex},
                  {"edge", o.weights.edge},
                  {"smoothness", o.weights.smoothness},
                  {"regularizer", o.weights.regularizer},
                  {"skinning_weights", o.weights.skinning_weights}};
  if (!o.skinning_checkpoint.empty()) j["skinning_checkpoint"] = o.skinning_checkpoint;
  return j.dump();
}

// Takes the (run) settings of TrainOptions from a checkpoint's config and checks its mode (a config
// without one predates the end-to-end mode and is a single-module run).
void config_from_json(const std::string& text, const std::string& path, const char* expected_mode, TrainOptions& o) {
  const Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  AMT_CHECK(j.is_object(), path, ": config: expected a JSON object, found '", text.substr(0, 80), "'");
  const auto mode = j.find("mode");
  const std::string found = mode == j.end() ? kSingleMode : mode->is_string() ? mode->get<std::string>() : mode->dump();
  AMT_CHECK(found == expected_mode, path, ": config.mode: expected '", expected_mode, "', found '", found, "' (",
            found == kEndToEndMode ? "an end-to-end run resumes with amt train apparel_refiner"
                                   : "a single-module run resumes with amt train <module>",
            ")");
  const auto get = [&](const Json& from, const char* key, auto& out, const std::string& where) {
    const auto it = from.find(key);
    AMT_CHECK(it != from.end() && it->is_number(), path, ": config.", where, key, ": expected a number, found ",
              it == from.end() ? std::string("nothing") : it->dump());
    out = it->get<std::decay_t<decltype(out)>>();
  };
  // B̂ of a refiner run comes from the same skinning predictor unless another one is given.
  if (const auto skinning = j.find("skinning_checkpoint");
      skinning != j.end() && skinning->is_string() && o.skinning_checkpoint.empty()) {
    o.skinning_checkpoint = skinning->get<std::string>();
  }
  // Configs written before these settings existed ran with their defaults.
  if (const auto schedule = j.find("lr_schedule"); schedule != j.end()) {
    AMT_CHECK(schedule->is_string(), path, ": config.lr_schedule: expected a string, found ", schedule->dump());
    o.lr_schedule = schedule->get<std::string>();
  }
  if (j.contains("lr_decay_steps")) get(j, "lr_decay_steps", o.lr_decay_steps, "");
  get(j, "seed", o.seed, "");
  get(j, "learning_rate", o.learning_rate, "");
  get(j, "weight_decay", o.weight_decay, "");
  get(j, "batch", o.batch, "");
  get(j, "window", o.window, "");
  get(j, "skinning_frames", o.skinning_frames, "");
  get(j, "segmenter_pos_weight", o.segmenter_pos_weight, "");
  // Written only when not 1, so that the configs of earlier checkpoints and of unweighted runs stay as they were.
  if (j.contains("segmenter_held_weight")) get(j, "segmenter_held_weight", o.segmenter_held_weight, "");
  o.ema = 0.0;  // a run without the key had no average
  if (j.contains("ema")) get(j, "ema", o.ema, "");
  if (const auto unroll = j.find("unroll"); unroll != j.end()) {
    AMT_CHECK(unroll->is_string(), path, ": config.unroll: expected a string, found ", unroll->dump());
    o.unroll = unroll->get<std::string>();
  }
  if (j.contains("history_noise")) get(j, "history_noise", o.history_noise, "");
  if (j.contains("noise_gamma")) get(j, "noise_gamma", o.noise_gamma, "");
  if (j.contains("rest_start_fraction")) get(j, "rest_start_fraction", o.rest_start_fraction, "");
  if (j.contains("free_run")) get(j, "free_run", o.free_run, "");
  if (const auto loss = j.find("apparel_loss"); loss != j.end()) {
    AMT_CHECK(loss->is_string(), path, ": config.apparel_loss: expected a string, found ", loss->dump());
    o.apparel_loss = loss->get<std::string>();
  }
  if (j.contains("normalizer_samples")) get(j, "normalizer_samples", o.normalizer_samples, "");
  const auto weights = j.find("weights");
  AMT_CHECK(weights != j.end() && weights->is_object(), path, ": config.weights: expected an object");
  get(*weights, "vertex", o.weights.vertex, "weights.");
  get(*weights, "edge", o.weights.edge, "weights.");
  get(*weights, "smoothness", o.weights.smoothness, "weights.");
  get(*weights, "regularizer", o.weights.regularizer, "weights.");
  if (weights->contains("skinning_weights")) get(*weights, "skinning_weights", o.weights.skinning_weights, "weights.");
}

// The learning rate of the 0-based `step` under o.lr_schedule.
double learning_rate_at(const TrainOptions& o, int64_t step) {
  if (o.lr_schedule != "cosine") return o.learning_rate;
  constexpr double kPi = 3.14159265358979323846;
  const double D = static_cast<double>(o.lr_decay_steps);
  return o.learning_rate * 0.5 * (1.0 + std::cos(kPi * std::min(static_cast<double>(step), D) / D));
}

// === Modules and their losses

// One network being trained: what it is, the stem of its files, its options as JSON, its optimizer,
// and the checkpoint it resumes from (empty: fresh).
struct Part {
  ModuleKind kind = ModuleKind::kSegmenter;
  std::string stem;
  std::shared_ptr<torch::nn::Module> module;
  std::string options_json;
  std::unique_ptr<torch::optim::AdamW> optimizer;
  std::string resume;
  std::string checkpoint;
  /// The moving average of the parameters (TrainOptions::ema; empty when off), in parameters() order.
  std::vector<at::Tensor> average;
  /// Loads an --init checkpoint into module when it differs from a plain load (a module widened by
  /// TrainOptions::apparel_response); empty: load_checkpoint.
  std::function<void(const std::string&)> load_init;
};

// The parameters of `part` and its moving average swapped (no gradient): before validating and saving,
// so that both see the average, and back afterwards.
void swap_average(Part& part) {
  if (part.average.empty()) return;
  torch::NoGradGuard no_grad;
  const std::vector<at::Tensor> parameters = part.module->parameters();
  for (size_t i = 0; i < parameters.size(); ++i) {
    const at::Tensor own = parameters[i].detach().clone();
    at::Tensor(parameters[i]).copy_(part.average[i]);
    part.average[i].copy_(own);
  }
}

// What a run trains: its networks, the stem of its log, the loss of one sample at a step as
// {total, unweighted terms...} in the order of `terms` (validating: the fixed validation form, no
// noise), and what a fresh run does before its first step (the local apparel module's normalisers).
struct Task {
  std::vector<Part> parts;
  std::string log_stem;
  std::vector<std::string> terms;
  std::function<std::vector<at::Tensor>(const TrainingSample&, int64_t step, bool validating)> loss;
  std::function<void(SampleSource&)> prepare;
};

// One augmented segmenter input of character `c` (TrainOptions::segmenter_augment): a variant drawn
// (the artist-style remake with probability `artist_share`, else as built 60 %, open parts 20 %, bare body 10 %,
// bare open parts 10 %), mirrored through x = 0 with
// probability 1/2, turned about the vertical (+Y) by an angle in [-2, 2] degrees and scaled by a
// factor in [0.85, 1.15]. The features follow the geometry: normals (columns 0-2) are mirrored and
// turned, the other columns are distances over the height and part shares, which none of these change.
// A function of (seed, step, the character's name).
struct SegmenterInput {
  at::Tensor V, features, apparel_mask, weights;
};
SegmenterInput augmented_segmenter_input(const CharacterTensors& c, uint64_t seed, int64_t step, double artist_share) {
  std::seed_seq seq{uint64_t(seed), uint64_t(step), uint64_t(std::hash<std::string>{}(c.name)), uint64_t(0x5e6)};
  std::mt19937_64 rng(seq);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  SegmenterInput in{c.V, c.segmenter_features, c.apparel_mask, c.segmenter_weights};
  // The artist-style share is drawn first and only when asked for, so that runs without it draw as before.
  const bool artist = artist_share > 0.0 && unit(rng) < artist_share;
  const double u = unit(rng);
  const char* what = artist    ? "artist_style"
                     : u < 0.6 ? ""
                     : u < 0.8 ? "open_parts"
                     : u < 0.9 ? "bare_body"
                               : "bare_open_parts";
  for (const auto& v : c.segmenter_variants)
    if (v.what == what) in = {v.V, v.features, v.apparel_mask, v.weights};
  const bool mirror = unit(rng) < 0.5;
  const double angle = (unit(rng) * 2.0 - 1.0) * 2.0 * M_PI / 180.0;
  const double scale = 0.85 + 0.3 * unit(rng);
  const float co = float(std::cos(angle)), si = float(std::sin(angle)), sx = mirror ? -1.0f : 1.0f;
  // Row vectors times M: x' = co * sx x + si z, z' = -si * sx x + co z (mirror first, then turn).
  const at::Tensor M = at::tensor({co * sx, 0.0f, -si * sx, 0.0f, 1.0f, 0.0f, si, 0.0f, co}).view({3, 3});
  in.V = at::matmul(in.V, M) * float(scale);
  if (in.features.size(1) >= 3)
    in.features =
        at::cat({at::matmul(in.features.narrow(1, 0, 3), M), in.features.narrow(1, 3, in.features.size(1) - 3)}, 1);
  return in;
}

// A trained module loaded for inference (the refiner's inputs): kind checked, skeleton checked.
template <typename Net, typename Options>
Net load_frozen(const std::string& path, ModuleKind kind, const std::vector<std::string>& joint_names) {
  CheckpointInfo info;
  Net net = load_frozen_network<Net, Options>(path, kind, info);
  check_checkpoint_skeleton(path, info, joint_names);
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

template <typename Net>
Part make_part(ModuleKind kind, std::string stem, const Net& net, std::string options_json) {
  Part part;
  part.kind = kind;
  part.stem = std::move(stem);
  part.module = net.ptr();
  part.options_json = std::move(options_json);
  return part;
}

// B̂ (T, N_b, 3): the body skinned by LBS (eq. 4) with predicted weights when `skinning` is set,
// else with the ground-truth ones; no gradient.
at::Tensor skinned_body(SkinningPredictor& skinning, const CharacterTensors& c, const at::Tensor& motion) {
  torch::NoGradGuard frozen;
  const at::Tensor V_b = c.V.index_select(0, c.body_ids);
  const at::Tensor W =
      !skinning.is_empty() ? skinning->forward(V_b, c.joints, c.G_body) : c.body_weights.index_select(0, c.body_ids);
  return linear_blend_skinning(V_b, W, motion, c.joints);
}

// S (T, N_a, 3): the rest apparel skinned to `motion` with the weights of the anchor body vertices
// (ApparelDisplacementOptions::skinned_anchor; CharacterTensors::apparel_anchor), from the same body
// weights as skinned_body; undefined for a network without the anchor. No gradient.
at::Tensor apparel_anchors(bool anchored, SkinningPredictor& skinning, const CharacterTensors& c,
                           const at::Tensor& motion) {
  if (!anchored) return {};
  torch::NoGradGuard frozen;
  const at::Tensor A_rest = c.V.index_select(0, c.apparel_ids);
  at::Tensor W = c.apparel_anchor_weights;
  if (!skinning.is_empty()) {
    const at::Tensor W_b = skinning->forward(c.V.index_select(0, c.body_ids), c.joints, c.G_body);
    W = apparel_anchor_weights_for(c.apparel_anchor, c.V, c.graph_edges, c.apparel_ids, c.body_ids, W_b);
  }
  return linear_blend_skinning(A_rest, W, motion, c.joints);
}

// The anchors of the apparel module's nodes (CharacterTensors::apparel_node_ids) from those of every apparel
// vertex S (..., N_a, 3): the handles' rows, or S itself.
at::Tensor node_anchors(const CharacterTensors& c, const at::Tensor& S) {
  return c.apparel_rig.defined() ? S.index_select(-2, c.apparel_rig.rows) : S;
}

// A seeded generator for the draws of one training window (noise, free-run length), a function of the
// run's seed, the step and the sample, so that a resumed run draws the same.
at::Generator window_generator(const TrainOptions& o, const TrainingSample& s, int64_t step, uint64_t stream) {
  uint64_t seed = o.seed * 0x9E3779B97F4A7C15ull ^ static_cast<uint64_t>(step) * 0xBF58476D1CE4E5B9ull ^
                  static_cast<uint64_t>(s.first_frame);
  for (char ch : s.clip) seed = (seed ^ static_cast<unsigned char>(ch)) * 1099511628211ull;
  return at::detail::createCPUGenerator(seed ^ stream * 0x94D049BB133111EBull);
}

}  // namespace

// The local apparel module's loss on one sample at `step`: the curriculum's unroll length u, a rollout
// of u frames from the window's 3 ground-truth states (the last one noised, the first target corrected:
// add_history_noise), or, with --free-run, from the states the module itself reached after a prefix of
// r frames rolled out without gradient (pushforward), or, for a window at its clip's first frame, from
// the rest pose through the motion's lead-in as a user's clip starts (the lead-in without gradient).
// Terms: the error of the predicted detail vectors in units of the target normaliser's scale (so that a
// one-step run starts near 1), squared or as a distance (TrainOptions::apparel_loss), and the
// edge-length loss (eq. 15). Validation uses the longest unroll, no noise and no prefix.
std::vector<at::Tensor> local_apparel_loss(ApparelDynamicsNet& net, const TrainingSample& s, int64_t step,
                                           bool validating, const TrainOptions& o) {
  const CharacterTensors& c = *s.character;
  const int64_t u = validating ? longest_unroll(o.unroll) : unroll_at(o.unroll, step, o.lr_decay_steps);
  // The module's nodes: every apparel vertex, or the handles (their vertices' ground truth).
  const at::Tensor A = s.vertices.index_select(1, c.apparel_node_ids);  // (F, N_n, 3)
  const at::Tensor A_rest = c.V.index_select(0, c.apparel_node_ids);
  SkinningPredictor ground_truth_weights{nullptr};
  at::Tensor initial, motion, targets;
  if (o.rest_start_fraction > 0 && s.first_frame == 0) {
    // The lead-in runs without gradient (the pushforward trick: the clip then starts from the module's
    // own settled state, at a third of the cost of differentiating through it).
    const at::Tensor lead_in = motion_lead_in(s.joint_transforms[0], c.joints, kDefaultLeadInFrames);
    const int64_t L = lead_in.size(0);
    const at::Tensor before = at::cat({rest_pose_transforms(c.joints, 3), lead_in}, 0);  // (3 + L, J, 3, 4)
    {
      torch::NoGradGuard no_grad;
      const at::Tensor settled =
          net->rollout(A_rest.unsqueeze(0).expand({3, -1, -1}), before,
                       node_anchors(c, apparel_anchors(true, ground_truth_weights, c, before)), c.apparel_graph);
      initial = settled.narrow(0, L - 3, 3);
    }
    motion = at::cat({before.narrow(0, L, 3), s.joint_transforms.narrow(0, 0, u)}, 0);
    targets = A.narrow(0, 0, u);
  } else {
    const int64_t available = A.size(0) - 3 - u;
    const int64_t r = validating || o.free_run <= 0 || available <= 0
                          ? 0
                          : at::randint(0, std::min<int64_t>(o.free_run, available) + 1, {1},
                                        window_generator(o, s, step, 1), at::kLong)
                                .item<int64_t>();
    if (r > 0) {
      // Frames 3 .. 3 + r - 1 on the module's own predictions; its history for frame 3 + r is then
      // frames r .. r + 2 (ground truth where r < 3).
      torch::NoGradGuard no_grad;
      const at::Tensor prefix_motion = s.joint_transforms.narrow(0, 0, 3 + r);
      const at::Tensor prefix =
          net->rollout(A.narrow(0, 0, 3), prefix_motion,
                       node_anchors(c, apparel_anchors(true, ground_truth_weights, c, prefix_motion)), c.apparel_graph);
      initial = at::cat({A.narrow(0, 0, 3), prefix}, 0).narrow(0, r, 3).contiguous();
    } else {
      initial = A.narrow(0, 0, 3);
    }
    motion = s.joint_transforms.narrow(0, r, 3 + u);
    targets = A.narrow(0, r + 3, u);
    if (!validating && r == 0 && o.history_noise > 0) {
      at::Generator generator = window_generator(o, s, step, 0);
      const at::Tensor noise = o.history_noise * at::randn({A.size(1), 3}, generator, at::kFloat);
      auto [noisy, first] = add_history_noise(initial, targets[0], noise, o.noise_gamma);
      initial = noisy;
      targets = at::cat({first.unsqueeze(0), targets.narrow(0, 1, u - 1)}, 0);
    }
  }
  const at::Tensor S = node_anchors(c, apparel_anchors(true, ground_truth_weights, c, motion));
  const at::Tensor predicted = net->rollout(initial, motion, S, c.apparel_graph);
  const at::Tensor scale2 = net->target_normalizer->scale.pow(2).sum();
  const at::Tensor squared = (predicted - targets).pow(2).sum(-1);
  // The distance's gradient at 0 is undefined: a floor far below any error that matters (1e-12 of
  // the scale squared).
  const at::Tensor detail =
      o.apparel_loss == "distance" ? (squared / scale2 + 1e-12).sqrt().mean() : squared.mean() / scale2;
  const at::Tensor edge = edge_length_loss(predicted, A_rest, c.apparel_node_edges);
  return {detail + o.weights.edge * edge, detail, edge};
}

namespace {

// The normalisers of a fresh local apparel module: every one-step window (3 ground-truth states and
// the next) of the first o.normalizer_samples training samples, then frozen.
void prepare_normalizers(ApparelDynamicsNet& net, SampleSource& source, const TrainOptions& o) {
  if (net->normalizers_frozen()) return;
  torch::NoGradGuard no_grad;
  SkinningPredictor ground_truth_weights{nullptr};
  int64_t windows = 0;
  for (int k = 0; k < o.normalizer_samples; ++k) {
    const TrainingSample s = source.get(k);
    const CharacterTensors& c = *s.character;
    const at::Tensor A = s.vertices.index_select(1, c.apparel_node_ids);
    const at::Tensor S = node_anchors(c, apparel_anchors(true, ground_truth_weights, c, s.joint_transforms));
    for (int64_t t = 3; t < A.size(0); ++t, ++windows) {
      net->observe(A.narrow(0, t - 3, 3), s.joint_transforms.narrow(0, t - 3, 4), S.narrow(0, t - 3, 4),
                   c.apparel_graph, A[t]);
    }
  }
  net->freeze_normalizers();
  if (o.progress) {
    std::fprintf(stderr, "[apparel] normalisers from %d samples (%lld one-step windows); target scale %s m\n",
                 o.normalizer_samples, static_cast<long long>(windows),
                 [&] {
                   std::ostringstream text;
                   const at::Tensor sc = net->target_normalizer->scale;
                   text << sc[0].item<float>() << " " << sc[1].item<float>() << " " << sc[2].item<float>();
                   return text.str();
                 }()
                     .c_str());
  }
}

// `resumed` holds the info of each part's resumed checkpoint in the order the parts are made
// (empty for a fresh run).
Task make_task(ModuleKind kind, bool end_to_end, const std::vector<CheckpointInfo>& resumed,
               const std::vector<std::string>& resume_paths, const TrainOptions& o, int64_t J,
               const std::vector<std::string>& joint_names) {
  Task task;
  const LossWeights w = o.weights;
  const auto info = [&](size_t i) { return resumed.empty() ? nullptr : &resumed[i]; };
  const auto path = [&](size_t i) { return resume_paths.empty() ? std::string() : resume_paths[i]; };
  SkinningPredictor skinning{nullptr};
  if ((end_to_end || kind == ModuleKind::kRefiner) && !o.skinning_checkpoint.empty()) {
    skinning = load_frozen<SkinningPredictor, SkinningPredictorOptions>(o.skinning_checkpoint, ModuleKind::kSkinning,
                                                                        joint_names);
  }
  if (end_to_end) {
    AMT_CHECK(info(0) ? !is_local_apparel_options(info(0)->options_json) : o.networks.apparel_form == "global",
              "apparel_refiner: the end-to-end run trains the global apparel form (--apparel-form global); the local "
              "apparel module trains on its own (amt train apparel), then the refiner on it (amt train refiner "
              "--apparel CKPT)");
    ApparelDisplacementNet apparel(joint_network_options(info(0), path(0), o.networks.apparel, J));
    JointRefiner refiner(network_options(info(1), path(1), o.networks.refiner));
    task.parts.push_back(make_part(ModuleKind::kApparel, "apparel", apparel, options_to_json(apparel->options)));
    task.parts.push_back(make_part(ModuleKind::kRefiner, "refiner", refiner, options_to_json(refiner->options)));
    task.log_stem = kEndToEndMode;
    task.terms = {"apparel_vertex", "apparel_edge", "refiner_vertex", "refiner_edge", "refiner_regularizer"};
    task.loss = [apparel, refiner, skinning, w](const TrainingSample& s, int64_t, bool) mutable {
      const CharacterTensors& c = *s.character;
      const int64_t T = s.vertices.size(0);
      const at::Tensor motion = s.joint_transforms.narrow(0, 3, T - 3);
      at::Tensor A_hat = at::zeros({T - 3, 0, 3});
      LossTerms la;
      la.total = la.vertex = la.edge = at::zeros({});
      if (c.apparel_ids.size(0) > 0) {
        // Paper protocol: the first 3 states from ground truth, then T - 3 autoregressive steps (eq. 11).
        const at::Tensor A = s.vertices.index_select(1, c.apparel_ids);  // (T, N_a, 3)
        A_hat = apparel->rollout(A.narrow(0, 0, 3), motion, c.apparel_neighbors,
                                 apparel_anchors(apparel->options.skinned_anchor, skinning, c, motion));
        la = apparel_loss(A_hat, A.narrow(0, 3, T - 3), c.V.index_select(0, c.apparel_ids), c.apparel_edges, w);
      }
      const at::Tensor tiled = tile_apparel_body(A_hat, skinned_body(skinning, c, motion), c.apparel_mask);  // eq. (16)
      const RefinerOutput out = refiner->forward(tiled, c.V, c.apparel_mask.to(at::kFloat));
      const LossTerms lj = refiner_loss(out.V_hat, s.vertices.narrow(0, 3, T - 3), c.V, c.edges, out.delta, w);
      return std::vector<at::Tensor>{la.total + lj.total, la.vertex, la.edge, lj.vertex, lj.edge, lj.regularizer};
    };
    return task;
  }
  switch (kind) {
    case ModuleKind::kSegmenter: {
      ApparelSegmenter net(network_options(info(0), path(0), o.networks.segmenter));
      task.parts.push_back(make_part(kind, "segmenter", net, options_to_json(net->options)));
      task.terms = {"bce"};
      const double pos_weight = o.segmenter_pos_weight;
      const bool augment = net->options.inputs == "welded" && o.segmenter_augment;
      const uint64_t seed = o.seed;
      const double artist_share = o.segmenter_artist_style;
      task.loss = [net, pos_weight, augment, seed, artist_share](const TrainingSample& s, int64_t step,
                                                                 bool validating) mutable {
        const CharacterTensors& c = *s.character;
        if (!augment || validating) {
          const at::Tensor bce = apparel_bce_loss(net->forward(c.V, c.segmenter_features), c.apparel_mask, pos_weight,
                                                  validating ? at::Tensor() : c.segmenter_weights);
          return std::vector<at::Tensor>{bce, bce};  // eq. (3)
        }
        const SegmenterInput in = augmented_segmenter_input(c, seed, step, artist_share);
        const at::Tensor bce =
            apparel_bce_loss(net->forward(in.V, in.features), in.apparel_mask, pos_weight, in.weights);
        return std::vector<at::Tensor>{bce, bce};  // eq. (3)
      };
      break;
    }
    case ModuleKind::kSkinning: {
      SkinningPredictor net(joint_network_options(info(0), path(0), o.networks.skinning, J));
      task.parts.push_back(
          make_part(kind, skinning_file_stem(net->options.variant), net, options_to_json(net->options)));
      task.terms = {"vertex", "edge", "smoothness", "weights"};
      task.loss = [net, w](const TrainingSample& s, int64_t, bool) mutable {
        const CharacterTensors& c = *s.character;
        const at::Tensor V_b = c.V.index_select(0, c.body_ids);
        const SkinningOutput out = net->forward_detailed(V_b, c.joints, c.G_body);
        const at::Tensor B_hat = linear_blend_skinning(V_b, out.W, s.joint_transforms, c.joints);  // eq. (4)
        const LossTerms l = body_loss(B_hat, s.vertices.index_select(1, c.body_ids), V_b, c.body_edges, out.W, w,
                                      out.logits, c.body_weights.index_select(0, c.body_ids));
        return std::vector<at::Tensor>{l.total, l.vertex, l.edge, l.smoothness, l.weights};
      };
      break;
    }
    case ModuleKind::kApparel: {
      const bool local = info(0) ? is_local_apparel_options(info(0)->options_json) : o.networks.apparel_form == "local";
      if (local) {
        ApparelDynamicsOptions options = joint_network_options(info(0), path(0), o.networks.apparel_dynamics, J);
        if (o.handle_spacing >= 0 && o.resume.empty()) options.handle_spacing = o.handle_spacing;
        const ApparelDynamicsOptions init_options = options;
        if (o.apparel_response && o.resume.empty()) options.response = true;
        if (o.swing_reference >= 0 && o.resume.empty()) options.swing_reference = o.swing_reference;
        ApparelDynamicsNet net(options);
        task.parts.push_back(make_part(kind, "apparel", net, options_to_json(net->options)));
        if (info(0) && options.response && !init_options.response) {
          task.parts.back().load_init = [net, init_options](const std::string& init) mutable {
            ApparelDynamicsNet source(init_options);
            load_checkpoint(init, ModuleKind::kApparel, *source, nullptr);
            net->widen_from(*source);
          };
        }
        task.terms = {"detail", "edge"};
        task.loss = [net, o](const TrainingSample& s, int64_t step, bool validating) mutable {
          return local_apparel_loss(net, s, step, validating, o);
        };
        task.prepare = [net, o](SampleSource& source) mutable { prepare_normalizers(net, source, o); };
        break;
      }
      ApparelDisplacementNet net(joint_network_options(info(0), path(0), o.networks.apparel, J));
      task.parts.push_back(make_part(kind, "apparel", net, options_to_json(net->options)));
      task.terms = {"vertex", "edge"};
      task.loss = [net, w](const TrainingSample& s, int64_t, bool) mutable {
        const CharacterTensors& c = *s.character;
        const int64_t T = s.vertices.size(0);
        const at::Tensor A = s.vertices.index_select(1, c.apparel_ids);  // (T, N_a, 3)
        const at::Tensor motion = s.joint_transforms.narrow(0, 3, T - 3);
        SkinningPredictor ground_truth_weights{nullptr};
        // Paper protocol: the first 3 states from ground truth, then T - 3 autoregressive steps (eq. 11).
        const at::Tensor A_hat =
            net->rollout(A.narrow(0, 0, 3), motion, c.apparel_neighbors,
                         apparel_anchors(net->options.skinned_anchor, ground_truth_weights, c, motion));
        const LossTerms l =
            apparel_loss(A_hat, A.narrow(0, 3, T - 3), c.V.index_select(0, c.apparel_ids), c.apparel_edges, w);
        return std::vector<at::Tensor>{l.total, l.vertex, l.edge};
      };
      break;
    }
    case ModuleKind::kRefiner: {
      AMT_CHECK(!o.apparel_checkpoint.empty(), "--apparel: the refiner trains on the apparel module's output: give ",
                "its checkpoint (amt train apparel writes <out>/apparel.ckpt)");
      ApparelDisplacementNet apparel{nullptr};
      ApparelDynamicsNet dynamics{nullptr};
      if (is_local_apparel_options(read_checkpoint_info(o.apparel_checkpoint, ModuleKind::kApparel).options_json)) {
        dynamics = load_frozen<ApparelDynamicsNet, ApparelDynamicsOptions>(o.apparel_checkpoint, ModuleKind::kApparel,
                                                                           joint_names);
      } else {
        apparel = load_frozen<ApparelDisplacementNet, ApparelDisplacementOptions>(o.apparel_checkpoint,
                                                                                  ModuleKind::kApparel, joint_names);
      }
      JointRefiner net(network_options(info(0), path(0), o.networks.refiner));
      task.parts.push_back(make_part(kind, "refiner", net, options_to_json(net->options)));
      task.terms = {"vertex", "edge", "regularizer"};
      task.loss = [net, apparel, dynamics, skinning, w](const TrainingSample& s, int64_t, bool) mutable {
        const CharacterTensors& c = *s.character;
        const int64_t T = s.vertices.size(0);
        const at::Tensor motion = s.joint_transforms.narrow(0, 3, T - 3);
        at::Tensor A_hat = at::zeros({T - 3, 0, 3});
        if (c.apparel_ids.size(0) > 0) {
          torch::NoGradGuard frozen;
          const at::Tensor A = s.vertices.index_select(1, c.apparel_ids);
          if (!dynamics.is_empty()) {
            // The local module measures detail vectors from the history's frames on: anchors of all T frames.
            const at::Tensor S = apparel_anchors(true, skinning, c, s.joint_transforms);
            const at::Tensor S_n = node_anchors(c, S);
            A_hat = dynamics->rollout(s.vertices.index_select(1, c.apparel_node_ids).narrow(0, 0, 3),
                                      s.joint_transforms, S_n, c.apparel_graph);
            if (c.apparel_rig.defined()) {
              A_hat = follow_handles(A_hat, S_n.narrow(0, 3, T - 3), S.narrow(0, 3, T - 3), c.apparel_rig);
            }
          } else {
            A_hat = apparel->rollout(A.narrow(0, 0, 3), motion, c.apparel_neighbors,
                                     apparel_anchors(apparel->options.skinned_anchor, skinning, c, motion));
          }
        }
        const at::Tensor tiled =
            tile_apparel_body(A_hat, skinned_body(skinning, c, motion), c.apparel_mask);  // eq. (16)
        const RefinerOutput out = net->forward(tiled, c.V, c.apparel_mask.to(at::kFloat));
        const LossTerms l = refiner_loss(out.V_hat, s.vertices.narrow(0, 3, T - 3), c.V, c.edges, out.delta, w);
        return std::vector<at::Tensor>{l.total, l.vertex, l.edge, l.regularizer};
      };
      break;
    }
  }
  task.log_stem = task.parts.front().stem;
  return task;
}

// === Outputs

// `--out` replaces only what amt wrote there (docs/reliability.md): the folder may hold anything else, but a
// checkpoint or log this run writes must be missing, or a checkpoint amt wrote for the same module (kind), or a
// log whose header is a training log's. A user's file, a folder or a link under one of those names, or an --out
// that is not a folder, is refused before any file is touched.
void check_replaceable_outputs(const std::string& out_dir, const Task& task, const std::string& log_stem) {
  namespace fs = std::filesystem;
  std::error_code error;
  const fs::file_status folder = fs::symlink_status(out_dir, error);
  if (!fs::exists(folder)) return;
  AMT_CHECK(fs::is_directory(folder), out_dir, ": --out: expected a folder (new or amt's), found ",
            fs::is_regular_file(folder) ? "a file" : "something else", ": name a new folder");
  const auto existing = [&](const std::string& stem, const char* extension) {
    const fs::path path = fs::path(out_dir) / (stem + extension);
    const fs::file_status status = fs::symlink_status(path, error);
    if (!fs::exists(status)) return std::string();
    AMT_CHECK(fs::is_regular_file(status), path.string(), ": --out: this run writes a ", extension,
              " file of that name, found ", fs::is_directory(status) ? "a folder" : "a link or special file",
              ": refusing to replace it (name another --out)");
    return path.string();
  };
  for (const Part& part : task.parts) {
    const std::string checkpoint = existing(part.stem, ".ckpt");
    if (checkpoint.empty()) continue;
    try {
      read_checkpoint_info(checkpoint, part.kind);
    } catch (const Error& e) {
      std::string why = e.what();
      if (why.rfind(checkpoint + ": ", 0) == 0) why.erase(0, checkpoint.size() + 2);
      throw Error(checkpoint + ": --out: this run writes its " + part.stem + " checkpoint there, and the file is not " +
                  "one amt wrote for that module (" + why + "): refusing to replace it (name another --out)");
    }
  }
  const std::string log = existing(log_stem, ".csv");
  if (log.empty()) return;
  std::ifstream in(log);
  std::string header;
  std::getline(in, header);
  AMT_CHECK(header.rfind("step,loss,", 0) == 0, log, ": --out: this run writes its training log there, and the file ",
            "is not a training log amt wrote (its first line is not 'step,loss,...'): refusing to replace it (name ",
            "another --out)");
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

// Mean total loss of `samples` under NoGradGuard, with the networks in eval mode (and back in
// training mode afterwards).
double validation_loss(Task& task, const std::vector<TrainingSample>& samples) {
  torch::NoGradGuard no_grad;
  for (Part& part : task.parts) part.module->eval(), swap_average(part);
  double sum = 0.0;
  for (const TrainingSample& sample : samples) sum += task.loss(sample, 0, /*validating=*/true)[0].item<double>();
  for (Part& part : task.parts) part.module->train(), swap_average(part);
  return sum / static_cast<double>(samples.size());
}

// The fixed validation set: samples 0 .. n - 1 of the validation split, read once. Empty (with a
// note on stderr) when the data has no such split or validation is off.
std::vector<TrainingSample> validation_set(const std::vector<std::string>& shards, SampleSourceOptions sampling,
                                           const TrainOptions& o, const std::string& name) {
  std::vector<TrainingSample> samples;
  if (o.validate_every <= 0 || o.validation_samples <= 0) return samples;
  sampling.split = o.validation_split;
  sampling.seed = o.validation_seed;
  std::unique_ptr<SampleSource> source;
  try {
    source = std::make_unique<SampleSource>(shards, sampling);
  } catch (const Error& e) {
    // Only "nothing to draw" reaches here: the shards themselves were opened by the training source.
    if (o.progress) std::fprintf(stderr, "[%s] no validation: %s\n", name.c_str(), e.what());
    return samples;
  }
  for (int k = 0; k < o.validation_samples; ++k) samples.push_back(source->get(k));
  return samples;
}

TrainResult run_training(ModuleKind kind, bool end_to_end, const std::vector<std::string>& data,
                         const TrainOptions& options_in) {
  TrainOptions o = options_in;
  const char* mode = end_to_end ? kEndToEndMode : kSingleMode;
  DataParallelGroup* group = o.group;
  const int rank = group ? group->rank() : 0, world_size = group ? group->world_size() : 1;
  if (rank != 0) o.progress = false;
  // The checkpoints resumed: the module's, or the apparel module's and the refiner's.
  std::vector<std::string> resume_paths;
  std::vector<ModuleKind> kinds = {kind};
  if (end_to_end) kinds = {ModuleKind::kApparel, ModuleKind::kRefiner};
  if (!o.resume.empty()) {
    if (end_to_end) {
      const std::string apparel = !o.apparel_checkpoint.empty()
                                      ? o.apparel_checkpoint
                                      : (std::filesystem::path(o.resume).parent_path() / "apparel.ckpt").string();
      resume_paths = {apparel, o.resume};
    } else {
      resume_paths = {o.resume};
    }
  }
  // Read from the last (the one given as --resume) so that its errors come first.
  std::vector<CheckpointInfo> resumed(resume_paths.size());
  for (size_t i = resume_paths.size(); i-- > 0;) {
    resumed[i] = read_checkpoint_info(resume_paths[i], kinds[i]);
    config_from_json(resumed[i].config_json, resume_paths[i], mode, o);
  }
  for (size_t i = 1; i < resumed.size(); ++i) {
    AMT_CHECK(resumed[i].step == resumed[0].step, resume_paths[i], ": step: expected ", resumed[0].step,
              " (the step of ", resume_paths[0], ", written by the same run), found ", resumed[i].step);
  }
  // --init: the network of another run's checkpoint, as a fresh run of this one (its options and
  // weights; this run's config, optimizer and step 0).
  std::vector<CheckpointInfo> initial;
  std::vector<std::string> init_paths;
  if (!o.init.empty()) {
    AMT_CHECK(o.resume.empty(), "--init ", o.init, " and --resume ", o.resume,
              ": expected one (--init starts a new run from a network, --resume continues a run)");
    AMT_CHECK(!end_to_end, "--init: the end-to-end run (", kEndToEndMode, ") starts from scratch or resumes");
    initial = {read_checkpoint_info(o.init, kind)};
    init_paths = {o.init};
  }
  const std::vector<CheckpointInfo>& network_infos = resumed.empty() ? initial : resumed;
  const std::vector<std::string>& network_paths = resume_paths.empty() ? init_paths : resume_paths;
  AMT_CHECK(o.batch >= 1, "--batch: expected >= 1, found ", o.batch);
  // Samples per step of each rank and of all ranks together (the config's batch). A resumed run splits
  // its checkpoint's batch between the ranks.
  int rank_batch = o.batch;
  if (!resumed.empty()) {
    AMT_CHECK(o.batch % world_size == 0, resume_paths[0], ": config.batch: the run takes ", o.batch,
              " samples per step, which do not split evenly between --world-size ", world_size, " ranks");
    rank_batch = o.batch / world_size;
  } else {
    o.batch = rank_batch * world_size;
  }
  AMT_CHECK(o.window >= 4, "--window: expected >= 4 (3 history states and a target), found ", o.window);
  AMT_CHECK(o.skinning_frames >= 1, "--skinning-frames: expected >= 1, found ", o.skinning_frames);
  AMT_CHECK(o.learning_rate > 0, "--lr: expected > 0, found ", o.learning_rate);
  AMT_CHECK(o.lr_schedule == "constant" || o.lr_schedule == "cosine",
            "--lr-schedule: expected constant or cosine, found '", o.lr_schedule, "'");
  AMT_CHECK(o.lr_decay_steps >= 0, "--lr-decay-steps: expected >= 0, found ", o.lr_decay_steps);
  if (o.lr_decay_steps == 0) o.lr_decay_steps = o.steps;  // a fresh run's default; stored in the config
  AMT_CHECK(o.weights.skinning_weights >= 0, "--weight-loss: expected >= 0, found ", o.weights.skinning_weights);
  AMT_CHECK(o.steps >= 1, "--steps: expected >= 1, found ", o.steps);

  // The local apparel module: a fresh run's form from the options, a resumed one's from its checkpoint.
  const bool local_apparel = !end_to_end && kind == ModuleKind::kApparel &&
                             (network_infos.empty() ? o.networks.apparel_form == "local"
                                                    : is_local_apparel_options(network_infos[0].options_json));
  if (local_apparel) {
    AMT_CHECK(o.free_run >= 0, "--free-run: expected >= 0 frames, found ", o.free_run);
    AMT_CHECK(o.window >= 3 + o.free_run + longest_unroll(o.unroll),
              "--window: expected >= ", 3 + o.free_run + longest_unroll(o.unroll), " (3 history states, --free-run ",
              o.free_run, " and the longest unroll of --unroll ", o.unroll, "), found ", o.window);
    AMT_CHECK(o.apparel_loss == "squared" || o.apparel_loss == "distance",
              "--apparel-loss: expected squared or distance, found '", o.apparel_loss, "'");
    AMT_CHECK(o.history_noise >= 0 && o.noise_gamma >= 0 && o.noise_gamma <= 1, "--noise: expected a std >= 0 and ",
              "gamma in [0, 1], found ", o.history_noise, " and ", o.noise_gamma);
    AMT_CHECK(o.rest_start_fraction >= 0 && o.rest_start_fraction <= 1, "--rest-start: expected a share in [0, 1], ",
              "found ", o.rest_start_fraction);
    AMT_CHECK(o.normalizer_samples >= 1, "--normalizer-samples: expected >= 1, found ", o.normalizer_samples);
  }
  AMT_CHECK(o.networks.apparel_form == "local" || o.networks.apparel_form == "global",
            "--apparel-form: expected local or global, found '", o.networks.apparel_form, "'");

  SampleSourceOptions sampling;
  // The anchor of the local apparel module being trained, or of the frozen one a refiner trains on.
  if (local_apparel) {
    ApparelDynamicsOptions a = o.networks.apparel_dynamics;
    if (!network_infos.empty()) options_from_json(network_infos[0].options_json, network_paths[0], a);
    sampling.apparel_anchor = a.anchor;
    sampling.handle_spacing = o.handle_spacing >= 0 && o.resume.empty() ? o.handle_spacing : a.handle_spacing;
  } else if (kind == ModuleKind::kRefiner && !end_to_end && !o.apparel_checkpoint.empty()) {
    const CheckpointInfo frozen = read_checkpoint_info(o.apparel_checkpoint, ModuleKind::kApparel);
    if (is_local_apparel_options(frozen.options_json)) {
      ApparelDynamicsOptions a;
      options_from_json(frozen.options_json, o.apparel_checkpoint, a);
      sampling.apparel_anchor = a.anchor;
      sampling.handle_spacing = a.handle_spacing;
    }
  }
  if (kind == ModuleKind::kSegmenter && !end_to_end) {
    ApparelSegmenterOptions segmenter = o.networks.segmenter;
    if (!network_infos.empty()) options_from_json(network_infos[0].options_json, network_paths[0], segmenter);
    sampling.segmenter_inputs = segmenter.inputs;
    sampling.segmenter_variants = segmenter.inputs == "welded" && o.segmenter_augment;
    if (sampling.segmenter_variants && o.segmenter_artist_style > 0.0) {
      AMT_CHECK(o.segmenter_artist_vertices == 0 || o.segmenter_artist_vertices >= 1000,
                "--segmenter-artist-vertices: expected 0 (no subdivision) or at least 1000, found ",
                o.segmenter_artist_vertices);
      sampling.segmenter_artist_vertices = o.segmenter_artist_vertices;
    }
    sampling.segmenter_held_weight = o.segmenter_held_weight;
  }
  sampling.kind = end_to_end ? ModuleKind::kRefiner : kind;
  sampling.clip_start_fraction = local_apparel ? o.rest_start_fraction : 0.0;
  sampling.frames = kind == ModuleKind::kSkinning && !end_to_end ? o.skinning_frames : o.window;
  sampling.seed = o.seed;
  sampling.geodesics = sampling.kind == ModuleKind::kRefiner && !o.skinning_checkpoint.empty();
  // The local apparel module with --skinning: anchors skinned with the predictor's body weights, as at run
  // time. The predictor is loaded once the shards' joint names are known, before any character is read.
  auto anchor_skinning = std::make_shared<SkinningPredictor>(nullptr);
  AMT_CHECK(o.anchor_truth_share >= 0.0 && o.anchor_truth_share <= 1.0,
            "--anchor-truth-share: expected a share in [0, 1], found ", o.anchor_truth_share);
  AMT_CHECK(o.anchor_truth_share == 0.0 || (local_apparel && !o.skinning_checkpoint.empty()),
            "--anchor-truth-share: expected the local apparel module with --skinning (the share of characters "
            "that keep ground-truth anchors instead of the predictor's)");
  sampling.anchor_truth_share = o.anchor_truth_share;
  if (local_apparel && !o.skinning_checkpoint.empty()) {
    sampling.geodesics = true;
    sampling.anchor_body_weights = [anchor_skinning](const CharacterTensors& c) {
      torch::NoGradGuard frozen;
      return (*anchor_skinning)->forward(c.V.index_select(0, c.body_ids), c.joints, c.G_body).contiguous();
    };
  }
  const std::vector<std::string> shards = resolve_shards(data);
  // Measured on the training data; data without responses keeps the options' own (an --init module's).
  if (local_apparel && o.resume.empty()) {
    const double reference = measure_swing_reference(shards);
    if (reference > 0) o.swing_reference = reference;
  }
  SampleSource source(shards, sampling);
  const std::vector<std::string>& joint_names = source.joint_names();
  if (sampling.anchor_body_weights) {
    *anchor_skinning = load_frozen<SkinningPredictor, SkinningPredictorOptions>(o.skinning_checkpoint,
                                                                                ModuleKind::kSkinning, joint_names);
  }

  int64_t first_step = 0;
  for (size_t i = 0; i < resumed.size(); ++i) {
    check_checkpoint_skeleton(resume_paths[i], resumed[i], joint_names);
    AMT_CHECK(resumed[i].data_fingerprint == source.fingerprint(), resume_paths[i], ": data_fingerprint: the ",
              "checkpoint was trained on ", resumed[i].data_fingerprint, ", the given shards are ",
              source.fingerprint(), " (resume with the same shard files)");
    first_step = resumed[i].step;
    AMT_CHECK(first_step < o.steps, resume_paths[i], ": step: the checkpoint is at step ", first_step, ", --steps ",
              o.steps, " asks for no more (give a larger --steps)");
  }

  torch::manual_seed(o.seed);
  for (size_t i = 0; i < initial.size(); ++i) check_checkpoint_skeleton(init_paths[i], initial[i], joint_names);
  Task task = make_task(kind, end_to_end, network_infos, network_paths, o, static_cast<int64_t>(joint_names.size()),
                        joint_names);
  CheckpointInfo info;
  info.config_json = config_to_json(o, mode);
  info.joint_names = joint_names;
  info.data_fingerprint = source.fingerprint();
  if (group) {
    group->expect_same("the run (config, data fingerprint, steps)",
                       info.config_json + " data " + info.data_fingerprint + " steps " + std::to_string(first_step) +
                           ".." + std::to_string(o.steps));
  }
  const bool writes = rank == 0;
  if (writes) {
    check_replaceable_outputs(o.out_dir, task, task.log_stem);
    std::error_code error;
    std::filesystem::create_directories(o.out_dir, error);
    AMT_CHECK(!error, o.out_dir, ": cannot create the output folder (", error.message(), ")");
  }
  TrainResult result;
  result.first_step = first_step;
  result.rank = rank;
  result.world_size = world_size;
  for (size_t i = 0; i < task.parts.size(); ++i) {
    Part& part = task.parts[i];
    part.optimizer = std::make_unique<torch::optim::AdamW>(
        part.module->parameters(), torch::optim::AdamWOptions(o.learning_rate).weight_decay(o.weight_decay));
    std::vector<at::Tensor> training_parameters;
    if (!resume_paths.empty())
      load_checkpoint(resume_paths[i], part.kind, *part.module, part.optimizer.get(), &training_parameters);
    if (!init_paths.empty()) {
      if (part.load_init) {
        part.load_init(init_paths[i]);
      } else {
        load_checkpoint(init_paths[i], part.kind, *part.module, nullptr);
      }
    }
    if (o.ema > 0) {
      // The average starts at the network; a resumed run's network is the average, its own parameters
      // the stored training parameters.
      torch::NoGradGuard no_grad;
      for (const at::Tensor& p : part.module->parameters()) part.average.push_back(p.detach().clone());
      if (!resume_paths.empty()) {
        AMT_CHECK(!training_parameters.empty(), resume_paths[i], ": training_parameters: expected the parameters ",
                  "of a run with --ema (config.ema ", o.ema, "), found none");
        const std::vector<at::Tensor> parameters = part.module->parameters();
        for (size_t k = 0; k < parameters.size(); ++k) at::Tensor(parameters[k]).copy_(training_parameters[k]);
      }
    }
    part.module->train();
    part.checkpoint = (std::filesystem::path(o.out_dir) / (part.stem + ".ckpt")).string();
    if (writes) result.checkpoints.push_back(part.checkpoint);
  }
  const std::string name = task.log_stem;
  result.checkpoint = task.parts.back().checkpoint;
  result.log = (std::filesystem::path(o.out_dir) / (name + ".csv")).string();
  std::string header = "step,loss";
  for (const auto& term : task.terms) header += "," + term;
  header += ",samples_per_s,seconds,val_loss";
  std::ofstream log;
  // A fresh run that fails before its first row removes the log it started (a header alone says nothing).
  struct FreshLog {
    std::string path;
    bool armed = false;
    ~FreshLog() {
      std::error_code ignored;
      if (armed) std::filesystem::remove(path, ignored);
    }
  } fresh_log;
  if (writes) {
    std::error_code error;
    fresh_log = {result.log, first_step == 0 && !std::filesystem::exists(result.log, error)};
    prepare_log(result.log, header, first_step);
    log.open(result.log, std::ios::app);
    AMT_CHECK(log.good(), result.log, ": cannot append to the training log");
    log << std::setprecision(9);
  }

  if (first_step == 0 && task.prepare) task.prepare(source);
  // Every rank starts from rank 0's parameters and buffers (the normalisers among them).
  std::vector<at::Tensor> parameters;
  for (const Part& part : task.parts) {
    for (const at::Tensor& p : part.module->parameters()) parameters.push_back(p);
  }
  if (group) {
    std::vector<at::Tensor> state = parameters;
    for (const Part& part : task.parts) {
      for (const at::Tensor& b : part.module->buffers()) state.push_back(b);
    }
    torch::NoGradGuard no_grad;
    group->broadcast_from_rank0(state);
  }
  const std::vector<TrainingSample> validation =
      writes ? validation_set(shards, sampling, o, name) : std::vector<TrainingSample>{};
  const bool tty = isatty(fileno(stderr));
  SampleLoader loader(source, first_step * rank_batch, (o.steps - first_step) * rank_batch, o.loader_threads,
                      o.prefetch, SampleShare{rank_batch, world_size, rank});
  const double communication_start = group ? group->communication_seconds() : 0.0;
  const double allreduce_start = group ? group->allreduce_seconds() : 0.0;
  const int64_t exchanges_start = group ? group->communication_count() : 0;
  const auto run_start = Clock::now();
  auto last_print = run_start;
  double step_seconds = 0.0;
  double last_validation = std::nan("");
  LossJumpGuard loss_guard;
  for (int64_t step = first_step; step < o.steps; ++step) {
    const auto step_start = Clock::now();
    const double lr = learning_rate_at(o, step);
    for (Part& part : task.parts) {
      for (auto& group : part.optimizer->param_groups())
        static_cast<torch::optim::AdamWOptions&>(group.options()).lr(lr);
      part.optimizer->zero_grad();
    }
    std::vector<double> values(task.terms.size() + 1, 0.0);
    for (int b = 0; b < rank_batch; ++b) {
      const TrainingSample sample = loader.next();
      const std::vector<at::Tensor> terms = task.loss(sample, step, /*validating=*/false);
      (terms[0] / static_cast<double>(rank_batch)).backward();
      for (size_t i = 0; i < terms.size(); ++i) values[i] += terms[i].item<double>() / rank_batch;
    }
    // The mean over the ranks' samples, as one process with all of them computes it.
    if (group) group->average_gradients(parameters, values, step);
    AMT_CHECK(std::isfinite(values[0]), name, ": step ", step + 1, ": the loss is not finite (", values[0],
              "); lower --lr or check the data");
    loss_guard.check(values[0], step + 1, name);  // before the optimizer steps on it
    for (Part& part : task.parts) part.optimizer->step();
    if (o.ema > 0) {
      const double decay = std::min(o.ema, (1.0 + double(step)) / (10.0 + double(step)));
      torch::NoGradGuard no_grad;
      for (Part& part : task.parts) {
        const std::vector<at::Tensor> parameters = part.module->parameters();
        for (size_t i = 0; i < parameters.size(); ++i) part.average[i].mul_(decay).add_(parameters[i], 1.0 - decay);
      }
    }
    const auto step_end = Clock::now();
    const double seconds = std::chrono::duration<double>(step_end - step_start).count();
    step_seconds += seconds;
    result.losses.push_back(values[0]);

    const bool last = step + 1 == o.steps;
    const bool validate = !validation.empty() && (last || (step + 1) % o.validate_every == 0);
    if (validate) {
      last_validation = validation_loss(task, validation);
      result.validation_steps.push_back(step + 1);
      result.validation_losses.push_back(last_validation);
    }
    const auto now = Clock::now();
    const double elapsed = std::chrono::duration<double>(now - run_start).count();
    if (writes) {
      log << step + 1;
      for (double v : values) log << "," << v;
      log << "," << o.batch / seconds << "," << elapsed << ",";
      if (validate) log << last_validation;
      log << "\n";
      fresh_log.armed = false;
      log.flush();
      AMT_CHECK(log.good(), result.log, ": write: expected to append step ", step + 1,
                ", found a write error (disk full?)");
    }

    const int64_t done = step + 1 - first_step;
    if (o.progress && (last || std::chrono::duration<double>(now - last_print).count() >= 1.0)) {
      last_print = now;
      const double per_step = elapsed / done;
      std::string val;
      if (!std::isnan(last_validation)) val = "  val " + std::to_string(last_validation);
      std::fprintf(stderr, "%s[%s] step %lld/%lld  loss %.6g%s  %.1f samples/s  ETA %s%s", tty ? "\r" : "",
                   name.c_str(), static_cast<long long>(step + 1), static_cast<long long>(o.steps), values[0],
                   val.c_str(), done * o.batch / elapsed, duration_text(per_step * (o.steps - step - 1)).c_str(),
                   tty && !last ? "   " : "\n");
      std::fflush(stderr);
    }
    if (writes && (last || (o.checkpoint_every > 0 && (step + 1) % o.checkpoint_every == 0))) {
      info.step = step + 1;
      for (Part& part : task.parts) {
        info.kind = part.kind;
        info.options_json = part.options_json;
        if (part.average.empty()) {
          save_checkpoint(part.checkpoint, info, *part.module, part.optimizer.get());
          continue;
        }
        // The average as the network, the optimizer's own parameters beside it.
        std::vector<at::Tensor> own;
        for (const at::Tensor& p : part.module->parameters()) own.push_back(p.detach().clone());
        swap_average(part);
        save_checkpoint(part.checkpoint, info, *part.module, part.optimizer.get(), &own);
        swap_average(part);
      }
    }
  }
  // The other ranks wait for rank 0's last checkpoint (a next run, as in amt train all, may read it).
  if (group) group->barrier("rank 0's last checkpoint");
  result.wall_seconds = std::chrono::duration<double>(Clock::now() - run_start).count();
  result.last_step = o.steps;
  result.seconds_per_step = step_seconds / static_cast<double>(o.steps - first_step);
  result.samples_per_second = o.batch / result.seconds_per_step;
  if (group && group->communication_count() > exchanges_start) {
    const double exchanges = static_cast<double>(group->communication_count() - exchanges_start);
    result.communication_seconds_per_step = (group->communication_seconds() - communication_start) / exchanges;
    result.allreduce_seconds_per_step = (group->allreduce_seconds() - allreduce_start) / exchanges;
    result.gradient_bytes = group->gradient_bytes();
  }
  if (!writes) result.checkpoint = result.log = "";
  fresh_log.armed = false;
  return result;
}

}  // namespace

// === Local apparel training pieces

namespace {

std::vector<std::pair<int, double>> parse_unroll(const std::string& schedule) {
  std::vector<std::pair<int, double>> phases;
  std::stringstream text(schedule);
  std::string item;
  while (std::getline(text, item, ',')) {
    const size_t colon = item.find(':');
    int length = 0;
    double until = 0;
    bool ok = colon != std::string::npos;
    if (ok) {
      try {
        size_t used = 0;
        length = std::stoi(item.substr(0, colon), &used);
        ok = used == colon;
        const std::string rest = item.substr(colon + 1);
        until = std::stod(rest, &used);
        ok = ok && used == rest.size();
      } catch (const std::exception&) {
        ok = false;
      }
    }
    AMT_CHECK(ok && length >= 1 && until > 0 && (phases.empty() || until > phases.back().second), "--unroll: expected ",
              "LENGTH:FRACTION pairs with lengths >= 1 and rising fractions, e.g. 1:0.3,5:0.6,20:1, found '", schedule,
              "'");
    phases.emplace_back(length, until);
  }
  AMT_CHECK(!phases.empty(), "--unroll: expected at least one LENGTH:FRACTION pair, found '", schedule, "'");
  return phases;
}

}  // namespace

int unroll_at(const std::string& schedule, int64_t step, int64_t horizon) {
  const auto phases = parse_unroll(schedule);
  for (const auto& [length, until] : phases)
    if (static_cast<double>(step) < until * static_cast<double>(horizon)) return length;
  return phases.back().first;
}

int longest_unroll(const std::string& schedule) {
  int longest = 0;
  for (const auto& phase : parse_unroll(schedule)) longest = std::max(longest, phase.first);
  return longest;
}

std::pair<at::Tensor, at::Tensor> add_history_noise(const at::Tensor& history, const at::Tensor& target,
                                                    const at::Tensor& noise, double gamma) {
  at::Tensor noisy = history.clone();
  noisy.select(0, 2).add_(noise);
  return {noisy, target + (1.0 - gamma) * noise};
}

double measure_swing_reference(const std::vector<std::string>& shards) {
  std::vector<SwingCalibration> characters;
  for (const std::string& shard : shards) {
    DatasetReader reader(shard);
    for (const std::string& name : reader.character_names()) {
      if (reader.character_summary(name).split != "train") continue;
      const CharacterData c = reader.read_character(name);
      if (!c.rig || c.rig->response.rows() == 0) continue;
      std::vector<int64_t> apparel;
      for (size_t v = 0; v < c.apparel_mask.size(); ++v)
        if (c.apparel_mask[v]) apparel.push_back(int64_t(v));
      if (apparel.empty()) continue;
      // Pieces as a bind finds them: over the linked topology (seams welded, nearby pieces linked).
      const at::Tensor ids = at::tensor(apparel, at::kLong);
      const MatrixX2i linked = linked_topology(c.mesh.V, c.mesh.F, c.apparel_mask).edges;
      const at::Tensor edges =
          at::from_blob(const_cast<int32_t*>(linked.data()), {linked.rows(), 2}, at::TensorOptions().dtype(at::kInt))
              .to(at::kLong);
      characters.push_back(
          apparel_piece_swing(apparel_response(c.rig->skin_indices, c.rig->skin_weights, c.rig->response, ids),
                              induced_edges(c.mesh.num_vertices(), edges, ids)));
    }
  }
  return swing_reference(characters);
}

double set_swing_reference(const std::string& checkpoint, double reference) {
  AMT_CHECK(std::isfinite(reference) && reference > 0, checkpoint, ": swing reference: expected > 0, found ",
            reference);
  CheckpointInfo info = read_checkpoint_info(checkpoint, ModuleKind::kApparel);
  AMT_CHECK(is_local_apparel_options(info.options_json), checkpoint,
            ": options: expected the local apparel module (form \"local\"), found the global form");
  ApparelDynamicsOptions options;
  options_from_json(info.options_json, checkpoint, options);
  ApparelDynamicsNet net(options);
  // Everything is carried over: the tensors, the training parameters and the optimizer's state (the trainer's AdamW
  // over the parameters, as --resume loads it), so the rewritten file resumes as the original did.
  std::vector<at::Tensor> training_parameters;
  std::unique_ptr<torch::optim::AdamW> optimizer;
  if (info.has_optimizer) optimizer = std::make_unique<torch::optim::AdamW>(net->parameters());
  load_checkpoint(checkpoint, ModuleKind::kApparel, *net, optimizer.get(), &training_parameters);
  const double before = options.swing_reference;
  net->options.swing_reference = reference;
  info.options_json = options_to_json(net->options);
  save_checkpoint(checkpoint, info, *net, optimizer.get(), training_parameters.empty() ? nullptr : &training_parameters);
  return before;
}

TrainResult train_module(ModuleKind kind, const std::vector<std::string>& data, const TrainOptions& options) {
  return run_training(kind, /*end_to_end=*/false, data, options);
}

TrainResult train_apparel_refiner(const std::vector<std::string>& data, const TrainOptions& options) {
  return run_training(ModuleKind::kRefiner, /*end_to_end=*/true, data, options);
}

}  // namespace amt
