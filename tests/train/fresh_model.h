#pragma once
// A model folder of small, freshly initialised (seeded) networks for the pipeline, evaluation and
// runtime tests. The apparel decoder and the refiner start non-zero, so that they change the result.
#include <torch/utils.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "data_tools/geometry/skeleton.h"
#include "models/apparel_displacement.h"
#include "models/apparel_segmenter.h"
#include "models/checkpoint.h"
#include "models/joint_refiner.h"
#include "models/module_options.h"
#include "models/skinning_predictor.h"

namespace amt::test {

/// Saves `net` with `options_json` as a model-only checkpoint of `kind` trained on `joints`.
template <typename Net>
void save_fresh_checkpoint(const std::string& path, ModuleKind kind, const Net& net, const std::string& options_json,
                           const std::vector<std::string>& joints) {
  CheckpointInfo info;
  info.kind = kind;
  info.options_json = options_json;
  info.config_json = "{}";
  info.joint_names = joints;
  save_checkpoint(path, info, *net, nullptr);
}

/// Writes segmenter.ckpt, skinning.ckpt, apparel.ckpt and refiner.ckpt of small networks on `joints`
/// into `dir` (created) and returns `dir`.
/// With `local_apparel` the apparel checkpoint is the local form (ApparelDynamicsNet, random last
/// layer, identity normalisers), else the global form (ApparelDisplacementNet); `handle_spacing` > 0 makes the
/// local form move handles (ApparelDynamicsOptions::handle_spacing).
inline std::string write_fresh_model(const std::filesystem::path& dir, uint64_t seed = 7,
                                     const std::vector<std::string>& joints = canonical_joint_names(),
                                     bool local_apparel = false, double handle_spacing = 0.0) {
  std::filesystem::create_directories(dir);
  torch::manual_seed(seed);
  const int64_t J = static_cast<int64_t>(joints.size());
  ApparelSegmenterOptions so;
  so.encoder_widths = {16, 32};
  so.decoder_widths = {16};
  // Positions alone: a fresh network on them splits a character into apparel and body, which the
  // pipeline tests need; the shipped segmenter's shape features are bound in PretrainedModel and
  // the command-line tests.
  so.inputs = "positions";
  save_fresh_checkpoint((dir / "segmenter.ckpt").string(), ModuleKind::kSegmenter, ApparelSegmenter(so),
                        options_to_json(so), joints);
  SkinningPredictorOptions ko;
  ko.num_joints = J;
  ko.feature_widths = {16, 16};
  ko.head_encoder_widths = {16, 32};
  ko.head_decoder_widths = {16};
  save_fresh_checkpoint((dir / "skinning.ckpt").string(), ModuleKind::kSkinning, SkinningPredictor(ko),
                        options_to_json(ko), joints);
  ApparelDisplacementOptions ao;
  ao.num_joints = J;
  ao.motion_widths = {16};
  ao.motion_code = 8;
  ao.edge_widths = {16, 16};
  ao.decoder_widths = {16};
  ao.zero_init = false;
  if (local_apparel) {
    ApparelDynamicsOptions lo;
    lo.num_joints = J;
    lo.edge_widths = {16, 16};
    lo.decoder_widths = {16};
    lo.handle_spacing = handle_spacing;
    ApparelDynamicsNet net(lo);
    net->freeze_normalizers();
    {
      torch::NoGradGuard no_grad;
      for (auto& p : net->parameters()) p.copy_(0.05 * at::randn(p.sizes()));
    }
    save_fresh_checkpoint((dir / "apparel.ckpt").string(), ModuleKind::kApparel, net, options_to_json(lo), joints);
  } else {
    save_fresh_checkpoint((dir / "apparel.ckpt").string(), ModuleKind::kApparel, ApparelDisplacementNet(ao),
                          options_to_json(ao), joints);
  }
  JointRefinerOptions ro;
  ro.hidden_widths = {16};
  ro.zero_init = false;
  save_fresh_checkpoint((dir / "refiner.ckpt").string(), ModuleKind::kRefiner, JointRefiner(ro), options_to_json(ro),
                        joints);
  return dir.string();
}

}  // namespace amt::test
