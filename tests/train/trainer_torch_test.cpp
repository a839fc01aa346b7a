// Trainers (train/trainer.h) on the micro dataset: a resumed run repeats the uninterrupted loss and
// validation curves bit for bit, short runs lower the loss of every module and of the end-to-end
// apparel + refiner run, skinning variants write their own loadable checkpoints, bad input gives one
// clear error, and the `amt train` command works end to end.
#include "train/trainer.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numeric>
#include <sstream>
#include <string>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/threads.h"
#include "micro_dataset.h"
#include "tests/test_support.h"
#include "models/apparel_segmenter.h"
#include "models/checkpoint.h"
#include "models/module_options.h"
#include "train/samples.h"

namespace amt {
namespace {

namespace fs = std::filesystem;
using test::error_of;

fs::path test_dir() {
  static const fs::path dir = test::test_directory("amt_trainer_test");
  return dir;
}

const std::string& micro_dataset() {
  static const std::string path = [] {
    const std::string p = (test_dir() / "micro.h5").string();
    test::write_micro_dataset(p);
    return p;
  }();
  return path;
}

// The micro dataset with held-out data: its character again as "capsules_test" (split test) and
// the clip walk1 moved onto that copy as a test clip; walk0 stays the only training clip.
const std::string& split_dataset() {
  static const std::string path = [] {
    const std::string p = (test_dir() / "split.h5").string();
    DatasetReader reader(micro_dataset());
    DatasetWriter writer(p, reader.fps(), reader.joint_names());
    CharacterData character = reader.read_character("capsules");
    writer.add_character(character);
    character.name = "capsules_test";
    character.split = "test";
    writer.add_character(character);
    const int J = reader.num_joints(), N = character.mesh.num_vertices();
    for (const std::string& name : reader.clip_names()) {
      ClipInfo clip = reader.clip_info(name);
      if (name == "walk1") {
        clip.character = "capsules_test";
        clip.split = "test";
      }
      writer.begin_clip(clip);
      const Transforms joints = reader.read_joint_transforms(name, 0, clip.num_frames);
      const MatrixX3f vertices = reader.read_vertices(name, 0, clip.num_frames);
      for (int t = 0; t < clip.num_frames; ++t) {
        const Transforms frame(joints.begin() + t * J, joints.begin() + (t + 1) * J);
        writer.append_frame(frame, MatrixX3f(vertices.middleRows(t * N, N)));
      }
      writer.end_clip();
    }
    writer.commit();
    return p;
  }();
  return path;
}

TrainOptions tiny_options(const std::string& out) {
  TrainOptions o;
  o.out_dir = (test_dir() / out).string();
  o.progress = false;
  o.loader_threads = 1;
  o.checkpoint_every = 0;
  o.validate_every = 0;
  o.seed = 4;
  o.networks.segmenter.encoder_widths = {16, 32};
  o.networks.segmenter.decoder_widths = {16};
  o.networks.skinning.feature_widths = {16};
  o.networks.skinning.attention_widths = {8};
  o.networks.skinning.head_encoder_widths = {16, 32};
  o.networks.skinning.head_decoder_widths = {16};
  o.networks.apparel.motion_widths = {16};
  o.networks.apparel.motion_code = 8;
  o.networks.apparel.edge_widths = {16, 16};
  o.networks.apparel.decoder_widths = {16};
  o.networks.refiner.hidden_widths = {16};
  // The local apparel module's curriculum within the default 10-frame window, a short warm-up.
  o.networks.apparel_dynamics.edge_widths = {16, 16};
  o.networks.apparel_dynamics.decoder_widths = {16};
  o.unroll = "1:0.4,2:0.7,7:1";
  o.normalizer_samples = 4;
  return o;
}

double mean(const std::vector<double>& v, size_t first, size_t count) {
  return std::accumulate(v.begin() + first, v.begin() + first + count, 0.0) / count;
}

int count_lines(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) ++n;
  return n;
}

// The cells of column `column` of a CSV log, one per row after the header.
std::vector<std::string> csv_column(const std::string& path, const std::string& column) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  const auto split = [](const std::string& row) {
    std::vector<std::string> cells;
    std::stringstream stream(row);
    std::string cell;
    while (std::getline(stream, cell, ',')) cells.push_back(cell);
    if (!row.empty() && row.back() == ',') cells.push_back("");
    return cells;
  };
  const std::vector<std::string> header = split(line);
  const size_t index = std::find(header.begin(), header.end(), column) - header.begin();
  std::vector<std::string> cells;
  while (std::getline(in, line)) {
    const std::vector<std::string> row = split(line);
    cells.push_back(index < row.size() ? row[index] : "(missing)");
  }
  return cells;
}

}  // namespace

// Prints the module's name in test messages.
void PrintTo(ModuleKind kind, std::ostream* out) {
  *out << module_kind_name(kind);
}

namespace {

class ResumeEquality : public testing::TestWithParam<ModuleKind> {};

TEST_P(ResumeEquality, TenPlusTenStepsEqualTwentyStraight) {
  test::use_one_thread();
  const ModuleKind kind = GetParam();
  const std::string name = module_kind_name(kind);
  TrainOptions straight = tiny_options("straight_" + name);
  straight.steps = 20;
  straight.batch = 2;
  straight.learning_rate = 1e-3;
  straight.lr_schedule = "cosine";  // the rate depends on the step, so the resumed run must follow it
  straight.lr_decay_steps = 20;
  straight.weights.skinning_weights = 0.1;
  straight.validate_every = 5;
  straight.validation_samples = 2;
  if (kind == ModuleKind::kRefiner) {  // the refiner trains on a (briefly) trained apparel module
    TrainOptions apparel = tiny_options("refiner_input");
    apparel.steps = 3;
    straight.apparel_checkpoint = train_module(ModuleKind::kApparel, {split_dataset()}, apparel).checkpoint;
  }
  const TrainResult a = train_module(kind, {split_dataset()}, straight);
  ASSERT_EQ(a.losses.size(), 20u);
  EXPECT_EQ(a.validation_steps, (std::vector<int64_t>{5, 10, 15, 20}));
  // The val_loss column holds the validation losses on their steps and nothing elsewhere.
  const std::vector<std::string> val = csv_column(a.log, "val_loss");
  ASSERT_EQ(val.size(), 20u);
  for (size_t i = 0; i < val.size(); ++i) {
    if ((i + 1) % 5 != 0) {
      EXPECT_EQ(val[i], "") << "row " << i + 1;
    } else {
      EXPECT_NEAR(std::stod(val[i]), a.validation_losses[i / 5], 1e-7 * a.validation_losses[i / 5]);
    }
  }

  TrainOptions first = straight;
  first.out_dir = (test_dir() / ("split_" + name)).string();
  first.steps = 10;
  first.loader_threads = 2;  // threads change when samples are read, never which
  const TrainResult b1 = train_module(kind, {split_dataset()}, first);
  TrainOptions second = first;
  second.steps = 20;
  second.resume = b1.checkpoint;
  second.seed = 1234;  // ignored: the run settings come from the checkpoint
  second.learning_rate = 0.5;
  second.lr_schedule = "constant";
  second.lr_decay_steps = 7;
  second.weights.skinning_weights = 3.0;
  const TrainResult b2 = train_module(kind, {split_dataset()}, second);
  EXPECT_EQ(b2.first_step, 10);
  std::vector<double> resumed = b1.losses;
  resumed.insert(resumed.end(), b2.losses.begin(), b2.losses.end());
  ASSERT_EQ(resumed.size(), a.losses.size());
  for (size_t i = 0; i < resumed.size(); ++i) EXPECT_EQ(resumed[i], a.losses[i]) << name << " step " << i + 1;
  std::vector<double> validation = b1.validation_losses;
  validation.insert(validation.end(), b2.validation_losses.begin(), b2.validation_losses.end());
  EXPECT_EQ(validation, a.validation_losses);
  EXPECT_EQ(count_lines(b2.log), 21);  // header + 20 steps
}

INSTANTIATE_TEST_SUITE_P(Modules, ResumeEquality,
                         testing::Values(ModuleKind::kSegmenter, ModuleKind::kSkinning, ModuleKind::kApparel,
                                         ModuleKind::kRefiner),
                         [](const testing::TestParamInfo<ModuleKind>& info) {
                           return std::string(module_kind_name(info.param));
                         });

TEST(Trainer, ShortRunsLowerTheLossOfEveryModule) {
  test::use_one_thread();
  TrainOptions o = tiny_options("lowers");
  o.learning_rate = 3e-3;
  o.steps = 40;
  o.unroll = "1:1";  // one loss scale over the run (longer unrolls have larger errors)
  for (ModuleKind kind : {ModuleKind::kSegmenter, ModuleKind::kSkinning, ModuleKind::kApparel}) {
    const TrainResult r = train_module(kind, {micro_dataset()}, o);
    if (kind == ModuleKind::kApparel) continue;  // LocalApparel.ShortRunLowersTheValidationLoss
    EXPECT_LT(mean(r.losses, 30, 10), 0.7 * mean(r.losses, 0, 10)) << module_kind_name(kind);
    std::printf("%s: %.2f ms/step, %.1f samples/s, loss %.4g -> %.4g\n", module_kind_name(kind),
                1e3 * r.seconds_per_step, r.samples_per_second, mean(r.losses, 0, 10), mean(r.losses, 30, 10));
  }
  TrainOptions refiner = o;
  refiner.apparel_checkpoint = (test_dir() / "lowers" / "apparel.ckpt").string();
  refiner.skinning_checkpoint = (test_dir() / "lowers" / "skinning.ckpt").string();
  const TrainResult r = train_module(ModuleKind::kRefiner, {micro_dataset()}, refiner);
  EXPECT_LT(mean(r.losses, 30, 10), mean(r.losses, 0, 10));
  std::printf("refiner: %.2f ms/step, %.1f samples/s, loss %.4g -> %.4g\n", 1e3 * r.seconds_per_step,
              r.samples_per_second, mean(r.losses, 0, 10), mean(r.losses, 30, 10));
}

TEST(Trainer, AFreshRunThatFailsBeforeItsFirstRowLeavesNoLogAndAResumedOneKeepsItsRows) {
  test::use_one_thread();
  TrainOptions o = tiny_options("no_header_only_log");
  fs::remove_all(o.out_dir);
  o.steps = 2;
  const TrainResult good = train_module(ModuleKind::kSegmenter, {micro_dataset()}, o);
  // The trained network with every parameter NaN: a run started from it fails at its first step.
  CheckpointInfo info;
  ApparelSegmenter net = load_frozen_network<ApparelSegmenter, ApparelSegmenterOptions>(
      good.checkpoint, ModuleKind::kSegmenter, info);
  {
    torch::NoGradGuard no_grad;
    for (at::Tensor p : net->parameters()) p.fill_(std::nan(""));
  }
  const std::string poisoned = (test_dir() / "no_header_only_log_nan.ckpt").string();
  save_checkpoint(poisoned, info, *net, nullptr);
  TrainOptions fresh = tiny_options("no_header_only_log_fresh");
  fs::remove_all(fresh.out_dir);
  fresh.steps = 2;
  fresh.init = poisoned;
  EXPECT_NE(error_of([&] { train_module(ModuleKind::kSegmenter, {micro_dataset()}, fresh); })
                .find("step 1: the loss is not finite"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(fs::path(fresh.out_dir) / "segmenter.csv"));
  // The good run's log keeps its header and two rows.
  std::ifstream in(good.log);
  std::string line;
  int rows = 0;
  while (std::getline(in, line)) ++rows;
  EXPECT_EQ(rows, 3);
}

TEST(LocalApparel, UnrollScheduleAndNoiseTargetCorrection) {
  EXPECT_EQ(unroll_at("1:0.3,5:0.6,20:1", 0, 100), 1);
  EXPECT_EQ(unroll_at("1:0.3,5:0.6,20:1", 29, 100), 1);
  EXPECT_EQ(unroll_at("1:0.3,5:0.6,20:1", 30, 100), 5);
  EXPECT_EQ(unroll_at("1:0.3,5:0.6,20:1", 99, 100), 20);
  EXPECT_EQ(unroll_at("1:0.3,5:0.6,20:1", 500, 100), 20);  // past the horizon: the last length
  EXPECT_EQ(longest_unroll("1:0.3,25:0.6,20:1"), 25);
  for (const char* bad : {"", "5", "0:1", "1:0.5,2:0.4", "a:1", "1:x"})
    EXPECT_NE(error_of([&] { unroll_at(bad, 0, 10); }).find("--unroll: expected"), std::string::npos) << bad;
  // Noise n on the last of three states; the target follows (1 - gamma) n: by hand with gamma 0.1.
  const at::Tensor history = at::arange(18, at::kFloat).view({3, 2, 3});
  const at::Tensor target = at::full({2, 3}, 100.0f), noise = at::tensor({1.f, -2.f, 0.f, 0.5f, 0.f, 4.f}).view({2, 3});
  const auto [noisy, moved] = add_history_noise(history, target, noise, 0.1);
  EXPECT_TRUE(noisy.narrow(0, 0, 2).equal(history.narrow(0, 0, 2)));
  EXPECT_TRUE(noisy[2].equal(history[2] + noise));
  EXPECT_NEAR(moved[0][0].item<float>(), 100.9f, 1e-5);
  EXPECT_NEAR(moved[0][1].item<float>(), 98.2f, 1e-5);
  EXPECT_NEAR(moved[1][2].item<float>(), 103.6f, 1e-5);
  EXPECT_EQ(history[2][0][0].item<float>(), 12.0f);  // the input is not changed
}

TEST(LocalApparel, ShortRunLowersTheValidationLoss) {
  // The micro dataset's apparel trails its skinned position by two frames: a rule the module can
  // learn. The fixed validation windows (one-step, from ground truth) after the first step and after
  // 60 show it; per-sample training losses vary too much with the window's speed to show it in 60.
  test::use_one_thread();
  TrainOptions o = tiny_options("local_lowers");
  // The trailing is relative to the position the ground-truth weights skin it to, which the micro
  // dataset gives from the nearest body vertex: the nearest anchor makes the rule exact.
  o.networks.apparel_dynamics.anchor = "nearest";
  o.steps = 60;
  o.learning_rate = 1e-3;
  o.unroll = "1:1";
  o.history_noise = 0;
  o.rest_start_fraction = 0;
  o.validate_every = 1;
  o.validation_samples = 8;
  const TrainResult r = train_module(ModuleKind::kApparel, {split_dataset()}, o);
  ASSERT_EQ(r.validation_losses.size(), 60u);
  EXPECT_LT(r.validation_losses.back(), 0.8 * r.validation_losses.front());
  std::printf("local apparel: %.2f ms/step, validation %.4g -> %.4g\n", 1e3 * r.seconds_per_step,
              r.validation_losses.front(), r.validation_losses.back());
}

TEST(LocalApparel, FreeRunAndDistanceLossAreSeededResumeExactlyAndAreStored) {
  // Windows of 10 frames: 3 states, a pushforward prefix of up to 5 frames, then up to 2 unrolled.
  test::use_one_thread();
  TrainOptions straight = tiny_options("free_run_straight");
  straight.steps = 8;
  straight.learning_rate = 1e-3;
  straight.unroll = "1:0.5,2:1";
  straight.lr_decay_steps = 8;  // the curriculum's horizon, the same for the split run
  straight.free_run = 5;
  straight.apparel_loss = "distance";
  straight.rest_start_fraction = 0;
  const TrainResult a = train_module(ModuleKind::kApparel, {split_dataset()}, straight);
  ASSERT_EQ(a.losses.size(), 8u);
  const std::string config = read_checkpoint_info(a.checkpoint, ModuleKind::kApparel).config_json;
  EXPECT_NE(config.find("\"free_run\":5"), std::string::npos) << config;
  EXPECT_NE(config.find("\"apparel_loss\":\"distance\""), std::string::npos) << config;
  // The prefix and the loss change the run: the same seed without them gives other losses.
  TrainOptions plain = straight;
  plain.out_dir = (test_dir() / "free_run_plain").string();
  plain.free_run = 0;
  plain.apparel_loss = "squared";
  const TrainResult p = train_module(ModuleKind::kApparel, {split_dataset()}, plain);
  EXPECT_NE(p.losses, a.losses);
  // 4 + 4 steps with a resume equal 8 straight (the prefix lengths are drawn from the run's seed).
  TrainOptions first = straight;
  first.out_dir = (test_dir() / "free_run_split").string();
  first.steps = 4;
  const TrainResult b1 = train_module(ModuleKind::kApparel, {split_dataset()}, first);
  TrainOptions second = first;
  second.steps = 8;
  second.resume = b1.checkpoint;
  second.free_run = 0;  // ignored: the run settings come from the checkpoint
  second.apparel_loss = "squared";
  const TrainResult b2 = train_module(ModuleKind::kApparel, {split_dataset()}, second);
  std::vector<double> resumed = b1.losses;
  resumed.insert(resumed.end(), b2.losses.begin(), b2.losses.end());
  EXPECT_EQ(resumed, a.losses);
  // A window too short for prefix and unroll is refused before any work, naming both.
  TrainOptions tight = straight;
  tight.out_dir = (test_dir() / "free_run_tight").string();
  tight.free_run = 6;
  const std::string error = error_of([&] { train_module(ModuleKind::kApparel, {split_dataset()}, tight); });
  EXPECT_NE(error.find("--free-run 6"), std::string::npos) << error;
}

TEST(LocalApparel, InitStartsANewRunFromAnotherRunsNetwork) {
  // One-step training, then a run with its own schedule from that network: step 0, a fresh optimizer,
  // the first run's options, weights and normalisers; its first loss is the first run's network's.
  test::use_one_thread();
  TrainOptions one_step = tiny_options("init_source");
  one_step.steps = 3;
  one_step.networks.apparel_dynamics.edge_widths = {6, 5};
  const TrainResult source = train_module(ModuleKind::kApparel, {split_dataset()}, one_step);
  TrainOptions tuned = tiny_options("init_tuned");
  tuned.steps = 2;
  tuned.unroll = "2:1";
  tuned.init = source.checkpoint;
  const TrainResult r = train_module(ModuleKind::kApparel, {split_dataset()}, tuned);
  EXPECT_EQ(r.first_step, 0);
  ASSERT_EQ(r.losses.size(), 2u);
  CheckpointInfo a, b;
  ApparelDynamicsNet from = load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(source.checkpoint,
                                                                                         ModuleKind::kApparel, a);
  ApparelDynamicsNet to = load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(r.checkpoint,
                                                                                       ModuleKind::kApparel, b);
  EXPECT_EQ(b.options_json, a.options_json);  // the widths 6, 5 came from the source, not the defaults
  EXPECT_EQ(b.step, 2);
  EXPECT_TRUE(at::equal(to->input_normalizer->scale, from->input_normalizer->scale));
  // The same run from a fresh network of those options starts elsewhere: the weights were loaded.
  TrainOptions fresh = tuned;
  fresh.out_dir = (test_dir() / "init_fresh").string();
  fresh.init.clear();
  fresh.networks.apparel_dynamics.edge_widths = {6, 5};
  EXPECT_NE(train_module(ModuleKind::kApparel, {split_dataset()}, fresh).losses[0], r.losses[0]);
  // --apparel-response widens the source (its physics inputs start with zero weights): the same first loss, and a
  // checkpoint that has the inputs.
  TrainOptions widened = tuned;
  widened.out_dir = (test_dir() / "init_widened").string();
  widened.apparel_response = true;
  const TrainResult w = train_module(ModuleKind::kApparel, {split_dataset()}, widened);
  EXPECT_NEAR(w.losses[0], r.losses[0], 1e-5 * std::abs(r.losses[0]));
  CheckpointInfo c;
  ApparelDynamicsNet with_response =
      load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(w.checkpoint, ModuleKind::kApparel, c);
  EXPECT_TRUE(with_response->options.response);
  EXPECT_EQ(with_response->channels(), from->channels() + kApparelResponseChannels);
  // The source's swing reference is kept when the data carries no physics response to measure one from.
  set_swing_reference(source.checkpoint, 0.25);
  TrainOptions calibrated = tuned;
  calibrated.out_dir = (test_dir() / "init_calibrated").string();
  const TrainResult kept = train_module(ModuleKind::kApparel, {split_dataset()}, calibrated);
  CheckpointInfo d;
  ApparelDynamicsNet keeps =
      load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(kept.checkpoint, ModuleKind::kApparel, d);
  EXPECT_EQ(keeps->options.swing_reference, 0.25);
  // --init with --resume is refused, naming both.
  TrainOptions both = tuned;
  both.resume = r.checkpoint;
  const std::string error = error_of([&] { train_module(ModuleKind::kApparel, {split_dataset()}, both); });
  EXPECT_NE(error.find("--init"), std::string::npos) << error;
  EXPECT_NE(error.find("--resume"), std::string::npos) << error;
}

// --ema: the checkpoint's network is the moving average of the parameters the plain run takes step by
// step (each p_k from a plain run of k steps: the sample order and a constant rate do not depend on the
// run's length), computed here by hand; the optimizer's own parameters are stored beside it, equal to the
// plain run's; a resumed run continues the average bit-exactly.
TEST(Trainer, MovingAverageIsTheCheckpointsNetworkAndResumesBitExactly) {
  test::use_one_thread();
  TrainOptions source = tiny_options("ema_source");
  source.steps = 2;
  const std::string start = train_module(ModuleKind::kApparel, {split_dataset()}, source).checkpoint;
  const auto network = [](const std::string& path) {
    CheckpointInfo info;
    return load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(path, ModuleKind::kApparel, info)
        ->parameters();
  };
  const auto run = [&](const std::string& out, int64_t steps, double ema, const std::string& resume = "") {
    TrainOptions o = tiny_options(out);
    o.steps = steps;
    o.learning_rate = 1e-3;
    o.lr_schedule = "constant";
    o.lr_decay_steps = 3;  // the curriculum's phases at the same steps in every run
    o.ema = ema;
    if (resume.empty())
      o.init = start;
    else
      o.resume = resume;
    return train_module(ModuleKind::kApparel, {split_dataset()}, o);
  };
  std::vector<std::vector<at::Tensor>> plain = {network(start)};
  for (int64_t k = 1; k <= 3; ++k) plain.push_back(network(run("ema_plain" + std::to_string(k), k, 0.0).checkpoint));
  const double ema = 0.5;
  std::vector<at::Tensor> average;
  for (const at::Tensor& p : plain[0]) average.push_back(p.clone());
  for (int64_t step = 0; step < 3; ++step) {
    const double d = std::min(ema, (1.0 + double(step)) / (10.0 + double(step)));  // 0.1, 0.18, 0.25
    for (size_t i = 0; i < average.size(); ++i) average[i].mul_(d).add_(plain[size_t(step) + 1][i], 1.0 - d);
  }
  const TrainResult averaged = run("ema_straight", 3, ema);
  const std::vector<at::Tensor> stored = network(averaged.checkpoint);
  ASSERT_EQ(stored.size(), average.size());
  for (size_t i = 0; i < stored.size(); ++i) {
    EXPECT_TRUE(at::allclose(stored[i], average[i], 1e-6, 1e-7)) << "parameter " << i;
    EXPECT_FALSE(at::equal(stored[i], plain[3][i])) << "parameter " << i;  // the average, not the last step
  }
  // The optimizer's own parameters beside it: the plain run's, exactly (the average does not steer training).
  ApparelDynamicsNet holder(ApparelDynamicsOptions{});
  {
    CheckpointInfo info = read_checkpoint_info(averaged.checkpoint, ModuleKind::kApparel);
    ApparelDynamicsOptions options;
    options_from_json(info.options_json, averaged.checkpoint, options);
    holder = ApparelDynamicsNet(options);
  }
  std::vector<at::Tensor> own;
  load_checkpoint(averaged.checkpoint, ModuleKind::kApparel, *holder, nullptr, &own);
  ASSERT_EQ(own.size(), plain[3].size());
  for (size_t i = 0; i < own.size(); ++i) EXPECT_TRUE(at::equal(own[i], plain[3][i])) << "parameter " << i;
  // A plain checkpoint has none.
  load_checkpoint(run("ema_plain_again", 1, 0.0).checkpoint, ModuleKind::kApparel, *holder, nullptr, &own);
  EXPECT_TRUE(own.empty());
  // 2 + 1 steps equal 3 straight, the average and the losses alike.
  const TrainResult first = run("ema_split", 2, ema);
  const TrainResult second = run("ema_split", 3, 0.0, first.checkpoint);  // ema comes from the checkpoint
  EXPECT_EQ(second.first_step, 2);
  ASSERT_EQ(second.losses.size(), 1u);
  EXPECT_EQ(second.losses[0], averaged.losses[2]);
  const std::vector<at::Tensor> resumed = network(second.checkpoint);
  for (size_t i = 0; i < resumed.size(); ++i) EXPECT_TRUE(at::equal(resumed[i], stored[i])) << "parameter " << i;
}

TEST(LocalApparel, TrainerTargetsAreTheNextFramesOfAHandMadeClip) {
  // A hand-made clip: the body stands in its rest pose, the apparel drifts by an offset of its own in
  // every frame (so that each frame's target is told apart from its neighbours'). On a body that does
  // not move the anchors and their frames stay put, so a fresh network (zero output) with inertia 0.6
  // predicts A_t = A_{t-1} + 0.6 (A_{t-1} - A_{t-2}) from its own states, starting from the window's 3
  // ground-truth ones. The loss's detail term must be the mean distance (over the target scale) of those
  // predictions from the window's frames 3 and 4, not from frames shifted by one.
  test::use_one_thread();
  const std::string path = (test_dir() / "hand_made_clip.h5").string();
  const Skeleton skeleton = canonical_skeleton();
  CharacterData character = capsule_example_character(skeleton, 300);
  const int N = character.mesh.num_vertices(), T = 8;
  for (int i = 0; i < N; ++i) character.apparel_mask[i] = character.body_weights(i, kPelvis) == 1.0f ? 1 : 0;
  const auto offset = [](int t, int i) {
    return Eigen::RowVector3f(0.001f * t * t, 0.002f * t + 0.0001f * (i % 7), -0.0005f * t * t * t);
  };
  {
    DatasetWriter writer(path, 30.0f, skeleton.names);
    writer.add_character(character);
    ClipInfo clip;
    clip.name = "drift";
    clip.character = character.name;
    clip.motion = "rest";
    clip.split = "train";
    writer.begin_clip(clip);
    const Motion still = rest_motion(skeleton, T);
    for (int t = 0; t < T; ++t) {
      MatrixX3f frame = character.mesh.V;
      for (int i = 0; i < N; ++i)
        if (character.apparel_mask[i]) frame.row(i) += offset(t, i);
      writer.append_frame(forward_kinematics(skeleton, still, t), frame);
    }
    writer.end_clip();
    writer.commit();
  }
  TrainOptions o = tiny_options("hand_made_targets");
  o.unroll = "2:1";
  o.apparel_loss = "distance";
  o.rest_start_fraction = 0;  // every window from its own 3 ground-truth states
  ApparelDynamicsOptions options;
  options.edge_widths = {6, 5};
  options.decoder_widths = {4};
  options.inertia = 0.6;
  ApparelDynamicsNet net(options);
  SampleSourceOptions so;
  so.kind = ModuleKind::kApparel;
  so.frames = 5;  // 3 states and the 2 unrolled frames
  so.apparel_anchor = options.anchor;
  SampleSource source({path}, so);
  for (int64_t k = 0; k < 3; ++k) {
    const TrainingSample sample = source.get(k);
    const int f = sample.first_frame;  // the window's frames are f .. f + 4 of the clip
    const at::Tensor scale2 = net->target_normalizer->scale.pow(2).sum();
    double expected = 0;
    int count = 0;
    for (int i = 0; i < N; ++i) {
      if (!character.apparel_mask[i]) continue;
      const Eigen::RowVector3f rest = character.mesh.V.row(i);
      const Eigen::RowVector3f a1 = rest + offset(f + 1, i), a2 = rest + offset(f + 2, i);
      const Eigen::RowVector3f p3 = a2 + 0.6f * (a2 - a1), p4 = p3 + 0.6f * (p3 - a2);
      for (const auto& [p, t] : {std::pair{p3, f + 3}, std::pair{p4, f + 4}}) {
        expected += std::sqrt((p - (rest + offset(t, i))).squaredNorm() / scale2.item<double>() + 1e-12);
        ++count;
      }
    }
    expected /= count;
    const std::vector<at::Tensor> terms = local_apparel_loss(net, sample, 0, /*validating=*/true, o);
    EXPECT_NEAR(terms[1].item<double>(), expected, 1e-4 * expected) << "window at frame " << f;
  }
}

TEST(LocalApparel, NormalisersAreSetBeforeTheFirstStepAndKeptByTheCheckpoint) {
  test::use_one_thread();
  TrainOptions o = tiny_options("local_normalisers");
  o.steps = 2;
  const TrainResult r = train_module(ModuleKind::kApparel, {micro_dataset()}, o);
  CheckpointInfo info;
  ApparelDynamicsNet net = load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(r.checkpoint,
                                                                                        ModuleKind::kApparel, info);
  EXPECT_TRUE(is_local_apparel_options(info.options_json));
  EXPECT_TRUE(net->normalizers_frozen());
  EXPECT_GT(net->input_normalizer->count(), 0.0);
  // Real statistics: the gravity channel's y (the frame's -R_1y) is near -1 for a mostly upright joint.
  EXPECT_LT(net->input_normalizer->mean[28].item<float>(), -0.5f);
  EXPECT_GT(net->target_normalizer->scale.min().item<float>(), 0.0f);
  // A checkpoint of the global form is told apart and refused by the local loader, naming the field.
  TrainOptions global = tiny_options("global_form");
  global.steps = 1;
  global.networks.apparel_form = "global";
  const TrainResult g = train_module(ModuleKind::kApparel, {micro_dataset()}, global);
  EXPECT_FALSE(is_local_apparel_options(read_checkpoint_info(g.checkpoint, ModuleKind::kApparel).options_json));
  const std::string error = error_of([&] {
    load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(g.checkpoint, ModuleKind::kApparel, info);
  });
  EXPECT_NE(error.find("unknown field"), std::string::npos) << error;
}

TEST(Trainer, CosineScheduleAndWeightLossChangeTheRun) {
  test::use_one_thread();
  // The same 6 skinning steps under the constant and the cosine schedule: the first step (rate
  // lr * (1 + cos 0) / 2 = lr) is identical, later ones differ.
  TrainOptions constant = tiny_options("schedule_constant");
  constant.steps = 6;
  constant.learning_rate = 3e-3;
  TrainOptions cosine = constant;
  cosine.out_dir = (test_dir() / "schedule_cosine").string();
  cosine.lr_schedule = "cosine";
  const TrainResult a = train_module(ModuleKind::kSkinning, {micro_dataset()}, constant);
  const TrainResult b = train_module(ModuleKind::kSkinning, {micro_dataset()}, cosine);
  ASSERT_EQ(a.losses.size(), 6u);
  ASSERT_EQ(b.losses.size(), 6u);
  EXPECT_EQ(a.losses[0], b.losses[0]);
  EXPECT_EQ(a.losses[1], b.losses[1]);  // step 2 sees the parameters after step 1, which used lr in both
  EXPECT_NE(a.losses[2], b.losses[2]);
  // The weights column is the KL to the ground-truth weights; with λ_w = 0 it is logged but not in
  // the loss, so the total is the paper's L_b.
  const std::vector<std::string> kl = csv_column(a.log, "weights");
  ASSERT_EQ(kl.size(), 6u);
  EXPECT_GT(std::stod(kl[0]), 0.0);
  TrainOptions weighted = constant;
  weighted.out_dir = (test_dir() / "schedule_weighted").string();
  weighted.weights.skinning_weights = 2.0;
  const TrainResult c = train_module(ModuleKind::kSkinning, {micro_dataset()}, weighted);
  EXPECT_NEAR(c.losses[0], a.losses[0] + 2.0 * std::stod(kl[0]), 1e-5 * c.losses[0]);
  TrainOptions bad = constant;
  bad.lr_schedule = "linear";
  EXPECT_NE(error_of([&] { train_module(ModuleKind::kSkinning, {micro_dataset()}, bad); }).find("--lr-schedule"),
            std::string::npos);
}

TEST(EndToEnd, LowersTheLossResumesBitExactlyAndWritesBothModules) {
  test::use_one_thread();
  TrainOptions straight = tiny_options("e2e_straight");
  straight.networks.apparel_form = "global";  // the end-to-end run trains the global form
  straight.steps = 30;
  straight.learning_rate = 3e-3;
  straight.validate_every = 10;
  straight.validation_samples = 2;
  const TrainResult a = train_apparel_refiner({split_dataset()}, straight);
  ASSERT_EQ(a.losses.size(), 30u);
  // The apparel module starts as its skinned anchor, close to the micro dataset's apparel; the
  // fixed validation windows show the gain better than the noisy per-sample training loss.
  EXPECT_LT(mean(a.losses, 20, 10), mean(a.losses, 0, 10));
  ASSERT_EQ(a.validation_losses.size(), 3u);
  EXPECT_LT(a.validation_losses[2], 0.9 * a.validation_losses[0]);
  std::printf("apparel_refiner: %.2f ms/step, loss %.4g -> %.4g, val %.4g -> %.4g\n", 1e3 * a.seconds_per_step,
              mean(a.losses, 0, 10), mean(a.losses, 20, 10), a.validation_losses[0], a.validation_losses[2]);

  // Both checkpoints load as their modules, at the same step, with the options of the run.
  const fs::path out = straight.out_dir;
  EXPECT_EQ(a.checkpoints,
            (std::vector<std::string>{(out / "apparel.ckpt").string(), (out / "refiner.ckpt").string()}));
  EXPECT_EQ(a.log, (out / "apparel_refiner.csv").string());
  const CheckpointInfo apparel_info = read_checkpoint_info(a.checkpoints[0], ModuleKind::kApparel);
  EXPECT_EQ(apparel_info.step, 30);
  ApparelDisplacementOptions apparel_options;
  options_from_json(apparel_info.options_json, a.checkpoints[0], apparel_options);
  EXPECT_EQ(apparel_options.edge_widths, straight.networks.apparel.edge_widths);
  ApparelDisplacementNet apparel(apparel_options);
  load_checkpoint(a.checkpoints[0], ModuleKind::kApparel, *apparel, nullptr);
  JointRefinerOptions refiner_options;
  options_from_json(read_checkpoint_info(a.checkpoints[1], ModuleKind::kRefiner).options_json, a.checkpoints[1],
                    refiner_options);
  JointRefiner refiner(refiner_options);
  EXPECT_EQ(load_checkpoint(a.checkpoints[1], ModuleKind::kRefiner, *refiner, nullptr).step, 30);
  EXPECT_EQ(csv_column(a.log, "apparel_vertex").size(), 30u);
  EXPECT_EQ(csv_column(a.log, "refiner_regularizer").size(), 30u);

  // 12 + 18 steps equal 30 straight, losses and validation losses alike.
  TrainOptions first = straight;
  first.out_dir = (test_dir() / "e2e_split").string();
  first.steps = 12;
  first.loader_threads = 2;
  const TrainResult b1 = train_apparel_refiner({split_dataset()}, first);
  TrainOptions second = first;
  second.steps = 30;
  second.resume = b1.checkpoint;
  second.learning_rate = 0.5;  // ignored: from the checkpoint
  const TrainResult b2 = train_apparel_refiner({split_dataset()}, second);
  std::vector<double> resumed = b1.losses;
  resumed.insert(resumed.end(), b2.losses.begin(), b2.losses.end());
  ASSERT_EQ(resumed.size(), a.losses.size());
  for (size_t i = 0; i < resumed.size(); ++i) EXPECT_EQ(resumed[i], a.losses[i]) << "step " << i + 1;
  EXPECT_EQ(b1.validation_steps, (std::vector<int64_t>{10, 12}));
  EXPECT_EQ(b2.validation_steps, (std::vector<int64_t>{20, 30}));
  EXPECT_EQ(b1.validation_losses[0], a.validation_losses[0]);
  EXPECT_EQ(b2.validation_losses, (std::vector<double>{a.validation_losses[1], a.validation_losses[2]}));

  // A single-module run does not resume an end-to-end checkpoint, nor the reverse.
  TrainOptions single = second;
  single.steps = 40;
  single.apparel_checkpoint = a.checkpoints[0];
  EXPECT_EQ(error_of([&] { train_module(ModuleKind::kRefiner, {split_dataset()}, single); }),
            b1.checkpoint + ": config.mode: expected 'single', found 'apparel_refiner' (an end-to-end run resumes " +
                "with amt train apparel_refiner)");
  TrainOptions refiner_only = tiny_options("e2e_refiner_only");
  refiner_only.steps = 2;
  refiner_only.apparel_checkpoint = a.checkpoints[0];
  TrainOptions reverse = tiny_options("e2e_reverse");
  reverse.steps = 4;
  reverse.resume = train_module(ModuleKind::kRefiner, {split_dataset()}, refiner_only).checkpoint;
  EXPECT_EQ(error_of([&] { train_apparel_refiner({split_dataset()}, reverse); }),
            reverse.resume + ": config.mode: expected 'apparel_refiner', found 'single' (a single-module run " +
                "resumes with amt train <module>)");
}

TEST(Trainer, SkinningVariantsWriteCheckpointsThatLoadWithTheirOptions) {
  test::use_one_thread();
  for (SkinningVariant variant : {SkinningVariant::kNoGeodesic, SkinningVariant::kSortByGeodesic}) {
    TrainOptions o = tiny_options("variants");
    o.steps = 3;
    o.networks.skinning.variant = variant;
    const TrainResult r = train_module(ModuleKind::kSkinning, {micro_dataset()}, o);
    const std::string stem = skinning_file_stem(variant);
    EXPECT_EQ(r.checkpoint, (fs::path(o.out_dir) / (stem + ".ckpt")).string());
    EXPECT_EQ(r.log, (fs::path(o.out_dir) / (stem + ".csv")).string());
    const CheckpointInfo info = read_checkpoint_info(r.checkpoint, ModuleKind::kSkinning);
    SkinningPredictorOptions options;
    options_from_json(info.options_json, r.checkpoint, options);
    EXPECT_EQ(options.variant, variant);
    SkinningPredictor net(options);
    EXPECT_EQ(load_checkpoint(r.checkpoint, ModuleKind::kSkinning, *net, nullptr).step, 3);

    // Resuming keeps the variant and its file names whatever the fresh options say.
    TrainOptions resume = o;
    resume.steps = 4;
    resume.resume = r.checkpoint;
    resume.networks.skinning.variant = SkinningVariant::kGeodesicAttention;
    EXPECT_EQ(train_module(ModuleKind::kSkinning, {micro_dataset()}, resume).checkpoint, r.checkpoint);
  }
  EXPECT_EQ(skinning_file_stem(SkinningVariant::kGeodesicAttention), "skinning");
}

TEST(Trainer, BadInputGivesOneClearError) {
  test::use_one_thread();
  TrainOptions o = tiny_options("bad");
  o.steps = 2;
  const TrainResult segmenter = train_module(ModuleKind::kSegmenter, {micro_dataset()}, o);

  TrainOptions wrong_kind = o;
  wrong_kind.resume = segmenter.checkpoint;
  wrong_kind.steps = 4;
  EXPECT_EQ(error_of([&] { train_module(ModuleKind::kApparel, {micro_dataset()}, wrong_kind); }),
            segmenter.checkpoint + ": kind: expected 'apparel', found 'segmenter'");

  test::MicroDatasetOptions renamed;
  for (int j = 0; j < 22; ++j) renamed.joint_names.push_back("bone" + std::to_string(j));
  const std::string other = (test_dir() / "renamed.h5").string();
  test::write_micro_dataset(other, renamed);
  TrainOptions resume = o;
  resume.resume = segmenter.checkpoint;
  resume.steps = 4;
  EXPECT_EQ(
      error_of([&] { train_module(ModuleKind::kSegmenter, {other}, resume); }),
      segmenter.checkpoint +
          ": skeleton: the checkpoint was trained on 22 joints (pelvis, left_hip, right_hip, "
          "spine1, left_knee, right_knee, ...), the dataset has 22 (bone0, bone1, bone2, bone3, bone4, bone5, ...)");

  const std::string copy = (test_dir() / "copy.h5").string();
  fs::copy_file(micro_dataset(), copy, fs::copy_options::overwrite_existing);
  EXPECT_EQ(error_of([&] {
              train_module(ModuleKind::kSegmenter, {micro_dataset(), copy}, resume);
            }).rfind(segmenter.checkpoint + ": data_fingerprint: the checkpoint was trained on fnv1a64:", 0),
            0u);

  const std::string missing = (test_dir() / "missing.h5").string();
  EXPECT_EQ(error_of([&] {
              train_module(ModuleKind::kSegmenter, {micro_dataset(), missing}, o);
            }),
            missing + ": no such file or folder (expected a dataset shard or a folder of *.h5)");

  resume.steps = 2;
  EXPECT_EQ(error_of([&] { train_module(ModuleKind::kSegmenter, {micro_dataset()}, resume); }),
            segmenter.checkpoint +
                ": step: the checkpoint is at step 2, --steps 2 asks for no more (give a larger "
                "--steps)");
  TrainOptions refiner = o;
  EXPECT_NE(error_of([&] { train_module(ModuleKind::kRefiner, {micro_dataset()}, refiner); }).find("--apparel: "),
            std::string::npos);
}

TEST(Trainer, OutReplacesOnlyCheckpointsAndLogsAmtWrote) {
  test::use_one_thread();
  const auto text_of = [](const fs::path& path) {
    std::ifstream in(path);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const auto write_text = [](const fs::path& path, const std::string& text) { std::ofstream(path) << text; };
  TrainOptions o = tiny_options("out_rule");
  o.steps = 1;
  const fs::path out = o.out_dir;
  fs::remove_all(out);
  fs::create_directories(out);
  write_text(out / "notes.txt", "a user's notes");  // other files in the folder are left alone
  const TrainResult first = train_module(ModuleKind::kSegmenter, {micro_dataset()}, o);
  EXPECT_EQ(text_of(out / "notes.txt"), "a user's notes");
  EXPECT_EQ(train_module(ModuleKind::kSegmenter, {micro_dataset()}, o).checkpoint, first.checkpoint);  // amt's: replaced

  // A user's file under the checkpoint's or the log's name, another module's checkpoint, a folder: refused, untouched.
  const fs::path checkpoint = out / "segmenter.ckpt", log = out / "segmenter.csv";
  fs::copy_file(out / "segmenter.ckpt", out / "other.ckpt");
  TrainOptions apparel = o;
  apparel.out_dir = (test_dir() / "out_rule_apparel").string();
  fs::remove_all(apparel.out_dir);
  fs::create_directories(apparel.out_dir);
  fs::copy_file(checkpoint, fs::path(apparel.out_dir) / "apparel.ckpt");
  EXPECT_EQ(error_of([&] { train_module(ModuleKind::kApparel, {micro_dataset()}, apparel); }),
            apparel.out_dir + "/apparel.ckpt: --out: this run writes its apparel checkpoint there, and the file is not "
                              "one amt wrote for that module (kind: expected 'apparel', found 'segmenter'): refusing "
                              "to replace it (name another --out)");
  write_text(checkpoint, "my thesis");
  EXPECT_EQ(error_of([&] { train_module(ModuleKind::kSegmenter, {micro_dataset()}, o); })
                .rfind(checkpoint.string() + ": --out: this run writes its segmenter checkpoint there, and the file is "
                                             "not one amt wrote for that module (not an amt checkpoint (",
                       0),
            0u);
  EXPECT_EQ(text_of(checkpoint), "my thesis");
  fs::copy_file(out / "other.ckpt", checkpoint, fs::copy_options::overwrite_existing);
  write_text(log, "date,temperature\n");
  EXPECT_EQ(error_of([&] { train_module(ModuleKind::kSegmenter, {micro_dataset()}, o); }),
            log.string() + ": --out: this run writes its training log there, and the file is not a training log amt "
                           "wrote (its first line is not 'step,loss,...'): refusing to replace it (name another --out)");
  EXPECT_EQ(text_of(log), "date,temperature\n");
  fs::remove(log);
  fs::create_directory(log);
  EXPECT_EQ(error_of([&] { train_module(ModuleKind::kSegmenter, {micro_dataset()}, o); }),
            log.string() + ": --out: this run writes a .csv file of that name, found a folder: refusing to replace "
                           "it (name another --out)");
  TrainOptions file_out = o;
  file_out.out_dir = (out / "notes.txt").string();
  EXPECT_EQ(error_of([&] { train_module(ModuleKind::kSegmenter, {micro_dataset()}, file_out); }),
            file_out.out_dir + ": --out: expected a folder (new or amt's), found a file: name a new folder");
  EXPECT_EQ(text_of(out / "notes.txt"), "a user's notes");
}

TEST(TrainCommand, TrainsAndResumesFromTheCommandLine) {
  const std::string out = (test_dir() / "cli").string();
  const std::string base = std::string(AMT_BINARY) + " train segmenter --data " + micro_dataset() + " --out " + out +
                           " --lr 1e-3 --threads 1 --quiet";
  ASSERT_EQ(std::system((base + " --steps 3 > /dev/null").c_str()), 0);
  EXPECT_TRUE(fs::exists(out + "/segmenter.ckpt"));
  ASSERT_EQ(std::system((base + " --steps 5 --resume " + out + "/segmenter.ckpt > /dev/null").c_str()), 0);
  EXPECT_EQ(read_checkpoint_info(out + "/segmenter.ckpt").step, 5);
  EXPECT_EQ(count_lines(out + "/segmenter.csv"), 6);

  ASSERT_EQ(std::system((std::string(AMT_BINARY) + " train skinning --variant sorted --steps 2 --data " +
                         micro_dataset() + " --out " + out + " --threads 1 --quiet > /dev/null")
                            .c_str()),
            0);
  EXPECT_EQ(read_checkpoint_info(out + "/skinning_sorted.ckpt", ModuleKind::kSkinning).step, 2);

  const std::string err = out + "/stderr.txt";
  EXPECT_NE(
      std::system(
          (std::string(AMT_BINARY) + " train apparel --data " + out + "/none.h5 --out " + out + " 2> " + err).c_str()),
      0);
  std::ifstream in(err);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line,
            "amt: error: " + out + "/none.h5: no such file or folder (expected a dataset shard or a folder of *.h5)");
}

}  // namespace
}  // namespace amt

namespace amt {
namespace {

// === Profile (disabled: a measurement, not a test; run with --gtest_also_run_disabled_tests)

// A character of about `vertices` vertices whose lower body (the capsules of the pelvis, hips,
// knees, ... in skeleton order until `apparel_share` of the vertices) is apparel trailing the body
// by two frames, with `clips` walks of `frames` frames (the last one held out as "test"): the size
// of a default dataset character.
void write_profile_dataset(const std::string& path, int vertices, double apparel_share, int clips, int frames) {
  const Skeleton skeleton = canonical_skeleton();
  CharacterData character = capsule_example_character(skeleton, vertices);
  const int N = character.mesh.num_vertices();
  int apparel = 0;
  for (int j : {kPelvis, kLeftHip, kRightHip, kLeftKnee, kRightKnee, kSpine1, kLeftAnkle, kRightAnkle}) {
    if (apparel >= apparel_share * N) break;
    for (int i = 0; i < N; ++i) {
      if (character.body_weights(i, j) == 1.0f) {
        character.apparel_mask[i] = 1;
        ++apparel;
      }
    }
  }
  DatasetWriter writer(path, 30.0f, skeleton.names);
  writer.add_character(character);
  const SparseWeights weights = sparsify_weights(character.body_weights);
  for (int c = 0; c < clips; ++c) {
    Motion walk = walk_motion(frames, 30.0f, 1.0f + 0.3f * c);
    walk.joint_names = skeleton.names;
    ClipInfo clip;
    clip.name = "walk" + std::to_string(c);
    clip.character = character.name;
    clip.motion = "procedural_walk";
    clip.split = c + 1 == clips && clips > 1 ? "test" : "train";  // the last clip is held out
    writer.begin_clip(clip);
    std::vector<MatrixX3f> posed(frames);
    for (int t = 0; t < frames; ++t) {
      const Transforms joints = forward_kinematics(skeleton, walk, t);
      linear_blend_skinning(character.mesh.V, weights, skinning_matrices(skeleton, joints), posed[t]);
      MatrixX3f gt = posed[t];
      for (int i = 0; i < N; ++i) {
        if (character.apparel_mask[i]) gt.row(i) = posed[std::max(t - 2, 0)].row(i);
      }
      writer.append_frame(joints, gt);
    }
    writer.end_clip();
  }
  writer.commit();
  std::printf("profile character: %d vertices, %d apparel (%.0f %%)\n", N, apparel, 100.0 * apparel / N);
}

TEST(TrainerProfile, DISABLED_StepTimesOnAFiveThousandVertexCharacter) {
  set_thread_count(2);
  // AMT_PROFILE_DATA=file keeps the dataset (e.g. for trying scripts/train_pretrained.sh on it).
  const char* keep = std::getenv("AMT_PROFILE_DATA");
  const std::string data = keep ? keep : (test_dir() / "profile.h5").string();
  write_profile_dataset(data, 5000, 0.3, 4, 90);
  {
    SampleSourceOptions sampling;
    sampling.kind = ModuleKind::kApparel;
    SampleSource source({data}, sampling);
    source.get(0);  // character tensors
    const auto start = std::chrono::steady_clock::now();
    for (int k = 1; k <= 20; ++k) source.get(k);
    std::printf("sample loading: %.2f ms per 10-frame window\n",
                1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 20);
  }
  TrainOptions o;
  o.out_dir = (test_dir() / "profile").string();
  o.progress = false;
  o.checkpoint_every = 0;
  o.validate_every = 0;
  o.loader_threads = 1;
  o.steps = 6;
  for (ModuleKind kind : {ModuleKind::kSegmenter, ModuleKind::kSkinning, ModuleKind::kApparel}) {
    const TrainResult r = train_module(kind, {data}, o);
    std::printf("%s (default options): %.1f ms/step, %.2f samples/s\n", module_kind_name(kind),
                1e3 * r.seconds_per_step, r.samples_per_second);
  }
  o.skinning_checkpoint = (fs::path(o.out_dir) / "skinning.ckpt").string();
  const TrainResult r = train_apparel_refiner({data}, o);
  std::printf("apparel_refiner (default options): %.1f ms/step, %.2f samples/s\n", 1e3 * r.seconds_per_step,
              r.samples_per_second);
}

}  // namespace
}  // namespace amt
