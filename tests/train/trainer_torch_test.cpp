// Trainers (train/trainer.h) on the micro dataset: a resumed run repeats the uninterrupted loss curve
// bit for bit, short runs lower the loss of every module, bad input gives one clear error, and the
// `amt train` command works end to end.
#include "train/trainer.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numeric>
#include <string>

#include "data_tools/error.h"
#include "micro_dataset.h"
#include "train/module_options.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

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

TrainOptions tiny_options(const std::string& out) {
  TrainOptions o;
  o.out_dir = (test_dir() / out).string();
  o.progress = false;
  o.loader_threads = 1;
  o.checkpoint_every = 0;
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
  return o;
}

double mean(const std::vector<double>& v, size_t first, size_t count) {
  return std::accumulate(v.begin() + first, v.begin() + first + count, 0.0) / count;
}

std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

int count_lines(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) ++n;
  return n;
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
  if (kind == ModuleKind::kRefiner) {  // the refiner trains on a (briefly) trained apparel module
    TrainOptions apparel = tiny_options("refiner_input");
    apparel.steps = 3;
    straight.apparel_checkpoint = train_module(ModuleKind::kApparel, {micro_dataset()}, apparel).checkpoint;
  }
  const TrainResult a = train_module(kind, {micro_dataset()}, straight);
  ASSERT_EQ(a.losses.size(), 20u);

  TrainOptions first = straight;
  first.out_dir = (test_dir() / ("split_" + name)).string();
  first.steps = 10;
  first.loader_threads = 2;  // threads change when samples are read, never which
  const TrainResult b1 = train_module(kind, {micro_dataset()}, first);
  TrainOptions second = first;
  second.steps = 20;
  second.resume = b1.checkpoint;
  second.seed = 1234;  // ignored: the run settings come from the checkpoint
  second.learning_rate = 0.5;
  const TrainResult b2 = train_module(kind, {micro_dataset()}, second);
  EXPECT_EQ(b2.first_step, 10);
  std::vector<double> resumed = b1.losses;
  resumed.insert(resumed.end(), b2.losses.begin(), b2.losses.end());
  ASSERT_EQ(resumed.size(), a.losses.size());
  for (size_t i = 0; i < resumed.size(); ++i) EXPECT_EQ(resumed[i], a.losses[i]) << name << " step " << i + 1;
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
  for (ModuleKind kind : {ModuleKind::kSegmenter, ModuleKind::kSkinning, ModuleKind::kApparel}) {
    const TrainResult r = train_module(kind, {micro_dataset()}, o);
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

TEST(TrainCommand, TrainsAndResumesFromTheCommandLine) {
  const std::string out = (test_dir() / "cli").string();
  const std::string base = std::string(AMT_BINARY) + " train segmenter --data " + micro_dataset() + " --out " + out +
                           " --lr 1e-3 --threads 1 --quiet";
  ASSERT_EQ(std::system((base + " --steps 3 > /dev/null").c_str()), 0);
  EXPECT_TRUE(fs::exists(out + "/segmenter.ckpt"));
  ASSERT_EQ(std::system((base + " --steps 5 --resume " + out + "/segmenter.ckpt > /dev/null").c_str()), 0);
  EXPECT_EQ(read_checkpoint_info(out + "/segmenter.ckpt").step, 5);
  EXPECT_EQ(count_lines(out + "/segmenter.csv"), 6);

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
