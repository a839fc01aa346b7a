// Checkpoints (models/checkpoint.h): save -> load round trip of parameters and AdamW state, and the
// errors for a checkpoint of another module, of another version, of another skeleton, or no checkpoint.
#include "models/checkpoint.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/optim/adamw.h>
#include <torch/serialize/output-archive.h>
#include <torch/utils.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/skeleton.h"
#include "models/apparel_displacement.h"
#include "models/apparel_segmenter.h"
#include "models/edge_conv.h"
#include "models/module_options.h"
#include "tests/file_size_limit.h"
#include "tests/test_support.h"
#include "tests/train/micro_dataset.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

std::string temp_path(const std::string& name) {
  static const std::string dir = test::test_directory("amt_checkpoint_test");
  return dir + "/" + name;
}

ApparelDisplacementOptions tiny_apparel(int64_t J) {
  ApparelDisplacementOptions o;
  o.num_joints = J;
  o.motion_widths = {16};
  o.motion_code = 4;
  o.edge_widths = {8, 8};
  o.decoder_widths = {8};
  return o;
}

// Two AdamW steps on a random rollout so that the optimizer has state for every parameter.
void train_two_steps(ApparelDisplacementNet& net, torch::optim::AdamW& optimizer) {
  const at::Tensor edges = at::tensor({0, 1, 1, 2, 2, 3}, at::kLong).view({-1, 2});
  const at::Tensor nbr = neighbor_table(4, edges);
  for (int s = 0; s < 2; ++s) {
    optimizer.zero_grad();
    const at::Tensor T = at::cat({at::eye(3).expand({2, 5, 3, 3}), at::randn({2, 5, 3, 1})}, 3);
    net->rollout(at::randn({3, 4, 3}), T, nbr, at::randn({2, 4, 3})).abs().mean().backward();
    optimizer.step();
  }
}

CheckpointInfo apparel_info(const ApparelDisplacementNet& net) {
  CheckpointInfo info;
  info.kind = ModuleKind::kApparel;
  info.options_json = options_to_json(net->options);
  info.config_json = "{\"seed\": 3}";
  info.step = 2;
  info.joint_names = {"a", "b", "c", "d", "e"};
  info.data_fingerprint = "fnv1a64:0123456789abcdef";
  return info;
}

std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Checkpoint, AFullDiskIsAOneLineErrorAndKeepsTheGoodFile) {
  test::use_one_thread();
  torch::manual_seed(1);
  ApparelDisplacementNet net(tiny_apparel(5));
  torch::optim::AdamW optimizer(net->parameters(), torch::optim::AdamWOptions(1e-3));
  train_two_steps(net, optimizer);
  const std::string path = temp_path("full_disk.ckpt");
  save_checkpoint(path, apparel_info(net), *net, &optimizer);
  const std::string good = test::read_file_bytes(path);
  ASSERT_GT(good.size(), 2048u);
  std::string error;
  {
    const test::FileSizeLimit full_disk(2048);
    if (!full_disk.active())
      GTEST_SKIP() << "the file size limit (RLIMIT_FSIZE) cannot be set: no full disk to simulate";
    error = error_of([&] { save_checkpoint(path, apparel_info(net), *net, &optimizer); });
  }
  // No std::terminate from LibTorch's archive writer: one line, the temporary gone, the good file kept.
  EXPECT_EQ(error, path + ".amt-tmp: write: expected the whole checkpoint written, found an error (File too large)");
  EXPECT_FALSE(fs::exists(path + ".amt-tmp"));
  EXPECT_EQ(test::read_file_bytes(path), good);
}

TEST(Checkpoint, AFlippedByteInAStoredParameterIsAChecksumError) {
  test::use_one_thread();
  torch::manual_seed(1);
  ApparelDisplacementNet net(tiny_apparel(5));
  const std::string path = temp_path("flipped.ckpt");
  save_checkpoint(path, apparel_info(net), *net, nullptr);
  ApparelDisplacementNet loaded(tiny_apparel(5));
  EXPECT_EQ(load_checkpoint(path, ModuleKind::kApparel, *loaded, nullptr).step, 2);  // intact: loads
  // One flipped bit in the first parameter's stored floats (found by their bytes).
  std::string bytes = test::read_file_bytes(path);
  const at::Tensor p0 = net->parameters()[0].detach().contiguous();
  ASSERT_GE(p0.nbytes(), 16u);
  const size_t at = bytes.find(std::string(static_cast<const char*>(p0.data_ptr()), 16));
  ASSERT_NE(at, std::string::npos);
  bytes[at + 7] ^= 0x20;
  std::ofstream(path, std::ios::binary) << bytes;
  const std::string error = error_of([&] { load_checkpoint(path, ModuleKind::kApparel, *loaded, nullptr); });
  EXPECT_EQ(error.rfind(path + ": payload_crc32: expected ", 0), 0u) << error;
  EXPECT_NE(error.find("the file is damaged"), std::string::npos) << error;
}

TEST(Checkpoint, AFlippedByteInTheOptimizersStateIsAChecksumErrorOnResume) {
  test::use_one_thread();
  torch::manual_seed(1);
  ApparelDisplacementNet net(tiny_apparel(5));
  torch::optim::AdamW optimizer(net->parameters(), torch::optim::AdamWOptions(1e-3));
  train_two_steps(net, optimizer);
  const std::string path = temp_path("flipped_optimizer.ckpt");
  save_checkpoint(path, apparel_info(net), *net, &optimizer);
  ApparelDisplacementNet loaded(tiny_apparel(5));
  torch::optim::AdamW loaded_optimizer(loaded->parameters(), torch::optim::AdamWOptions(1e-3));
  EXPECT_NO_THROW(load_checkpoint(path, ModuleKind::kApparel, *loaded, &loaded_optimizer));  // intact: loads
  // One flipped bit in the first parameter's second moment (found by its bytes inside the optimizer's state).
  const at::Tensor p0 = net->parameters()[0];
  const auto& state = static_cast<const torch::optim::AdamWParamState&>(
      *optimizer.state().at(c10::guts::to_string(p0.unsafeGetTensorImpl())));
  const at::Tensor moment = state.exp_avg_sq().contiguous();
  ASSERT_GE(moment.nbytes(), 16u);
  std::string bytes = test::read_file_bytes(path);
  const size_t at = bytes.find(std::string(static_cast<const char*>(moment.data_ptr()), 16));
  ASSERT_NE(at, std::string::npos);
  bytes[at + 6] ^= 0x40;
  std::ofstream(path, std::ios::binary) << bytes;
  // The model alone still loads (its own checksum holds); resuming does not.
  EXPECT_NO_THROW(load_checkpoint(path, ModuleKind::kApparel, *loaded, nullptr));
  const std::string error = error_of([&] { load_checkpoint(path, ModuleKind::kApparel, *loaded, &loaded_optimizer); });
  EXPECT_EQ(error.rfind(path + ": optimizer_crc32: expected ", 0), 0u) << error;
  EXPECT_NE(error.find("over the optimizer's state: the file is damaged"), std::string::npos) << error;
}

TEST(Checkpoint, RoundTripRestoresParametersAndOptimizerState) {
  test::use_one_thread();
  torch::manual_seed(1);
  ApparelDisplacementNet net(tiny_apparel(5));
  torch::optim::AdamW optimizer(net->parameters(), torch::optim::AdamWOptions(1e-3));
  train_two_steps(net, optimizer);
  const std::string path = temp_path("apparel.ckpt");
  save_checkpoint(path, apparel_info(net), *net, &optimizer);
  EXPECT_FALSE(fs::exists(path + ".amt-tmp"));

  const CheckpointInfo info = read_checkpoint_info(path, ModuleKind::kApparel);
  EXPECT_EQ(info.kind, ModuleKind::kApparel);
  EXPECT_EQ(info.step, 2);
  EXPECT_EQ(info.config_json, "{\"seed\": 3}");
  EXPECT_EQ(info.joint_names, apparel_info(net).joint_names);
  EXPECT_EQ(info.data_fingerprint, "fnv1a64:0123456789abcdef");

  ApparelDisplacementOptions options;
  options_from_json(info.options_json, path, options);
  torch::manual_seed(99);  // a different initialisation, overwritten by the load
  ApparelDisplacementNet loaded(options);
  torch::optim::AdamW loaded_optimizer(loaded->parameters(), torch::optim::AdamWOptions(1e-3));
  load_checkpoint(path, ModuleKind::kApparel, *loaded, &loaded_optimizer);

  const auto a = net->named_parameters(), b = loaded->named_parameters();
  ASSERT_EQ(a.size(), b.size());
  for (const auto& p : a) EXPECT_TRUE(at::equal(p.value(), b[p.key()])) << p.key();
  const auto pa = net->parameters(), pb = loaded->parameters();
  for (size_t i = 0; i < pa.size(); ++i) {
    const auto& sa = static_cast<const torch::optim::AdamWParamState&>(
        *optimizer.state().at(c10::guts::to_string(pa[i].unsafeGetTensorImpl())));
    const auto& sb = static_cast<const torch::optim::AdamWParamState&>(
        *loaded_optimizer.state().at(c10::guts::to_string(pb[i].unsafeGetTensorImpl())));
    EXPECT_EQ(sa.step(), sb.step());
    EXPECT_TRUE(at::equal(sa.exp_avg(), sb.exp_avg()));
    EXPECT_TRUE(at::equal(sa.exp_avg_sq(), sb.exp_avg_sq()));
  }
  // One more identical step on both gives identical parameters.
  torch::manual_seed(5);
  train_two_steps(net, optimizer);
  torch::manual_seed(5);
  train_two_steps(loaded, loaded_optimizer);
  for (const auto& p : net->named_parameters()) EXPECT_TRUE(at::equal(p.value(), loaded->named_parameters()[p.key()]));
}

TEST(Checkpoint, ModelOnlyFileLoadsWithoutOptimizerAndRefusesToResume) {
  torch::manual_seed(1);
  ApparelDisplacementNet net(tiny_apparel(5));
  const std::string path = temp_path("model_only.ckpt");
  save_checkpoint(path, apparel_info(net), *net, nullptr);
  ApparelDisplacementNet loaded(tiny_apparel(5));
  load_checkpoint(path, ModuleKind::kApparel, *loaded, nullptr);
  for (const auto& p : net->named_parameters()) EXPECT_TRUE(at::equal(p.value(), loaded->named_parameters()[p.key()]));
  torch::optim::AdamW optimizer(loaded->parameters());
  EXPECT_NE(error_of([&] {
              load_checkpoint(path, ModuleKind::kApparel, *loaded, &optimizer);
            }).find(path + ": optimizer: missing"),
            std::string::npos);
}

TEST(Checkpoint, WrongKindNamesBoth) {
  ApparelSegmenter net;
  CheckpointInfo info;
  info.kind = ModuleKind::kSegmenter;
  info.options_json = options_to_json(net->options);
  const std::string path = temp_path("x.ckpt");
  save_checkpoint(path, info, *net, nullptr);
  EXPECT_EQ(error_of([&] { read_checkpoint_info(path, ModuleKind::kSkinning); }),
            path + ": kind: expected 'skinning', found 'segmenter'");
  SkinningPredictor skinning;
  EXPECT_EQ(error_of([&] { load_checkpoint(path, ModuleKind::kSkinning, *skinning, nullptr); }),
            path + ": kind: expected 'skinning', found 'segmenter'");
}

TEST(Checkpoint, OtherVersionIsRejected) {
  torch::serialize::OutputArchive archive;
  archive.write("format", c10::IValue(std::string(kCheckpointFormat)));
  archive.write("version", c10::IValue(int64_t{2}));
  const std::string path = temp_path("v2.ckpt");
  archive.save_to(path);
  EXPECT_EQ(error_of([&] { read_checkpoint_info(path); }),
            path + ": version: expected 1, found 2 (written by a newer amt)");
}

TEST(Checkpoint, SkeletonMismatchNamesBothSkeletons) {
  CheckpointInfo info;
  info.joint_names = canonical_joint_names();
  const std::string message = error_of([&] { check_checkpoint_skeleton("x.ckpt", info, {"root", "spine", "head"}); });
  EXPECT_EQ(message,
            "x.ckpt: skeleton: the checkpoint was trained on 22 joints (pelvis, left_hip, right_hip, spine1, "
            "left_knee, right_knee, ...), the dataset has 3 (root, spine, head)");
  EXPECT_NO_THROW(check_checkpoint_skeleton("x.ckpt", info, canonical_joint_names()));
}

TEST(Checkpoint, MissingFileAndForeignFile) {
  const std::string missing = temp_path("missing.ckpt");
  fs::remove(missing);
  EXPECT_EQ(error_of([&] { read_checkpoint_info(missing); }),
            missing + ": cannot open: no such file (expected an amt checkpoint)");
  const std::string text = temp_path("text.ckpt");
  std::ofstream(text) << "not a checkpoint\n";
  EXPECT_EQ(error_of([&] { read_checkpoint_info(text); }).rfind(text + ": not an amt checkpoint (", 0), 0u);
}

TEST(Checkpoint, ShapeMismatchIsReported) {
  torch::manual_seed(1);
  ApparelDisplacementNet net(tiny_apparel(5));
  const std::string path = temp_path("shape.ckpt");
  save_checkpoint(path, apparel_info(net), *net, nullptr);
  ApparelDisplacementOptions wider = tiny_apparel(5);
  wider.edge_widths = {8, 16};
  ApparelDisplacementNet other(wider);
  EXPECT_NE(error_of([&] { load_checkpoint(path, ModuleKind::kApparel, *other, nullptr); }).find(path + ": model: "),
            std::string::npos);
}

}  // namespace
}  // namespace amt
