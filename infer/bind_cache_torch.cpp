#include <ATen/ATen.h>
#include <torch/serialize/input-archive.h>
#include <torch/serialize/output-archive.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "data_tools/formats/checksum_torch.h"
#include "data_tools/formats/input_file.h"
#include "data_tools/geometry/error.h"
#include "infer/bind_cache_torch.h"
#include "models/checkpoint.h"

namespace amt {

namespace {

// The BoundCharacter fields stored, by archive key.
std::vector<std::pair<const char*, at::Tensor BoundCharacter::*>> fields() {
  return {{"V", &BoundCharacter::V},
          {"faces", &BoundCharacter::faces},
          {"joints", &BoundCharacter::joints},
          {"edges", &BoundCharacter::edges},
          {"apparel_prob", &BoundCharacter::apparel_prob},
          {"apparel_mask", &BoundCharacter::apparel_mask},
          {"refiner_prob", &BoundCharacter::refiner_prob},
          {"apparel_ids", &BoundCharacter::apparel_ids},
          {"body_ids", &BoundCharacter::body_ids},
          {"body_edges", &BoundCharacter::body_edges},
          {"apparel_edges", &BoundCharacter::apparel_edges},
          {"apparel_neighbors", &BoundCharacter::apparel_neighbors},
          {"G_body", &BoundCharacter::G_body},
          {"body_weights", &BoundCharacter::body_weights},
          {"apparel_anchor_weights", &BoundCharacter::apparel_anchor_weights},
          {"apparel_frame_joints", &BoundCharacter::apparel_frame_joints},
          {"apparel_rest_features", &BoundCharacter::apparel_rest_features},
          {"apparel_contact_rest", &BoundCharacter::apparel_contact_rest},
          {"apparel_contact_weights", &BoundCharacter::apparel_contact_weights},
          {"apparel_ancestors", &BoundCharacter::apparel_ancestors},
          {"apparel_response", &BoundCharacter::apparel_response},
          {"apparel_swing_gain", &BoundCharacter::apparel_swing_gain},
          {"vertex_weights", &BoundCharacter::vertex_weights},
          {"graph_edges", &BoundCharacter::graph_edges},
          {"topology_counts", &BoundCharacter::topology_counts},
          {"handle_rows", &BoundCharacter::handle_rows},
          {"handle_vertex_handles", &BoundCharacter::handle_vertex_handles},
          {"handle_vertex_weights", &BoundCharacter::handle_vertex_weights},
          {"handle_edges", &BoundCharacter::handle_edges}};
}

}  // namespace

uint64_t fnv1a64_file(const std::string& path, const std::string& what, uint64_t hash) {
  check_input_file(path, what);
  std::ifstream in(path, std::ios::binary);
  AMT_CHECK(in.good(), path, ": expected ", what, " to read, found none readable");
  std::vector<char> chunk(size_t(1) << 20);
  while (in) {
    in.read(chunk.data(), std::streamsize(chunk.size()));
    hash = fnv1a64(chunk.data(), size_t(in.gcount()), hash);
  }
  return hash;
}

uint64_t fnv1a64(const void* data, size_t size, uint64_t hash) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) hash = (hash ^ p[i]) * 1099511628211ull;
  return hash;
}

std::string bind_key(const TriMesh& mesh, const MatrixX3f& joints, const std::vector<uint8_t>& mask_override,
                     const ModelBundle& bundle, const ApparelBones* bones, const MatrixXfR& weights,
                     const ApparelBones* physics) {
  uint64_t h = kFnvOffset;
  const int64_t sizes[4] = {mesh.V.rows(), mesh.F.rows(), joints.rows(), int64_t(mask_override.size())};
  h = fnv1a64(sizes, sizeof(sizes), h);
  h = fnv1a64(mesh.V.data(), size_t(mesh.V.size()) * sizeof(float), h);
  h = fnv1a64(mesh.F.data(), size_t(mesh.F.size()) * sizeof(int32_t), h);
  h = fnv1a64(joints.data(), size_t(joints.size()) * sizeof(float), h);
  h = fnv1a64(mask_override.data(), mask_override.size(), h);
  for (const std::string& name : bundle.joint_names) h = fnv1a64(name.data(), name.size() + 1, h);
  if (bones) {
    const int64_t counts[3] = {bones->num_bones(), bones->indices.rows(), bones->indices.cols()};
    h = fnv1a64(counts, sizeof(counts), h);
    h = fnv1a64(bones->heads.data(), size_t(bones->heads.size()) * sizeof(float), h);
    h = fnv1a64(bones->parents.data(), bones->parents.size() * sizeof(int32_t), h);
    h = fnv1a64(bones->indices.data(), size_t(bones->indices.size()) * sizeof(int32_t), h);
    h = fnv1a64(bones->weights.data(), size_t(bones->weights.size()) * sizeof(float), h);
    h = fnv1a64(bones->response.data(), size_t(bones->response.size()) * sizeof(float), h);
  }
  if (physics && physics->response.rows() > 0) {
    const int64_t counts[3] = {physics->response.rows(), physics->indices.rows(), physics->indices.cols()};
    h = fnv1a64(counts, sizeof(counts), h);
    h = fnv1a64(physics->indices.data(), size_t(physics->indices.size()) * sizeof(int32_t), h);
    h = fnv1a64(physics->weights.data(), size_t(physics->weights.size()) * sizeof(float), h);
    h = fnv1a64(physics->response.data(), size_t(physics->response.size()) * sizeof(float), h);
  }
  if (weights.rows() > 0) {
    const int64_t shape[2] = {weights.rows(), weights.cols()};
    h = fnv1a64(shape, sizeof(shape), h);
    h = fnv1a64(weights.data(), size_t(weights.size()) * sizeof(float), h);
  }
  if (!bundle.dir.empty()) {
    for (const char* file : {kSegmenterCheckpoint, kSkinningCheckpoint, kApparelCheckpoint, kRefinerCheckpoint}) {
      h = fnv1a64_file((std::filesystem::path(bundle.dir) / file).string(), "a checkpoint", h);
    }
    // The module for given weights sets the swing calibration of a character bound with them (its swing_reference).
    if (!bundle.apparel_dynamics_own_weights.is_empty())
      h = fnv1a64_file((std::filesystem::path(bundle.dir) / kApparelOwnWeightsCheckpoint).string(), "a checkpoint", h);
  } else {
    // A bundle assembled in code: hash its parameters.
    for (const torch::nn::Module* m :
         {static_cast<const torch::nn::Module*>(bundle.segmenter.get()),
          static_cast<const torch::nn::Module*>(bundle.skinning.get()), bundle.apparel_module(),
          static_cast<const torch::nn::Module*>(bundle.refiner.get())}) {
      if (!m) continue;
      for (const at::Tensor& p : m->parameters()) {
        const at::Tensor c = p.detach().to(at::kFloat).contiguous();
        h = fnv1a64(c.data_ptr<float>(), size_t(c.numel()) * sizeof(float), h);
      }
    }
  }
  char text[40];
  std::snprintf(text, sizeof(text), "fnv1a64:%016llx", static_cast<unsigned long long>(h));
  return text;
}

// The counts of BoundCharacter::hung as the archive stores them: (2) int64, pinned and unnailed.
constexpr const char* kHungKey = "hung_pieces";
at::Tensor hung_tensor(const HungPieces& hung) {
  return at::tensor({int64_t(hung.pinned), int64_t(hung.unnailed)}, at::kLong);
}

// The archive entries of a CachedSwingFit.
constexpr const char* kSwingFitKey = "swing_fit_key";
constexpr const char* kSwingFitText = "swing_fit_text";
constexpr const char* kSwingFitGain = "swing_fit_gain";

// CRC-32 of a bind cache's payload: the key, every stored field (name and tensor) in fields() order, then the
// hung pieces' counts, then the swing fitted on it when there is one.
uint32_t bind_crc32(const std::string& key, const BoundCharacter& bound, const CachedSwingFit& fit) {
  uint32_t crc = crc32_update(0, key);
  for (const auto& [name, member] : fields()) {
    const at::Tensor& t = bound.*member;
    if (t.defined()) crc = crc32_update(crc32_update(crc, std::string_view(name)), t);
  }
  crc = crc32_update(crc32_update(crc, std::string_view(kHungKey)), hung_tensor(bound.hung));
  if (fit.empty()) return crc;
  crc = crc32_update(crc32_update(crc, std::string_view(kSwingFitKey)), fit.key);
  crc = crc32_update(crc32_update(crc, std::string_view(kSwingFitText)), fit.text);
  return crc32_update(crc32_update(crc, std::string_view(kSwingFitGain)), fit.gain);
}

void save_bind(const std::string& path, const std::string& key, const BoundCharacter& bound,
               const CachedSwingFit& fit) {
  AMT_CHECK(fit.empty() || (fit.gain.defined() && fit.gain.dim() == 1 && fit.gain.size(0) == bound.num_apparel()), path,
            ": bind cache: the fitted swing gain: expected (", bound.num_apparel(), ") values");
  torch::serialize::OutputArchive archive;
  archive.write("format", c10::IValue(std::string(kBindFormat)));
  archive.write("version", c10::IValue(kBindVersion));
  archive.write("key", c10::IValue(key));
  for (const auto& [name, member] : fields()) {
    const at::Tensor& t = bound.*member;
    if (t.defined()) archive.write(name, t.clone());  // clone: inference tensors cannot be saved as views
  }
  archive.write(kHungKey, hung_tensor(bound.hung));
  if (!fit.empty()) {
    archive.write(kSwingFitKey, c10::IValue(fit.key));
    archive.write(kSwingFitText, c10::IValue(fit.text));
    archive.write(kSwingFitGain, fit.gain.to(at::kFloat).contiguous().clone());
  }
  archive.write("crc32", c10::IValue(int64_t(bind_crc32(key, bound, fit))));
  save_archive_atomically(archive, path, "bind cache");
}

bool load_bind(const std::string& path, const std::string& key, BoundCharacter& bound, std::string* reason,
               CachedSwingFit* fit) {
  auto miss = [reason](const std::string& why) {
    if (reason) *reason = why;
    return false;
  };
  std::error_code error;
  if (!std::filesystem::exists(path, error)) return miss("no cache file");
  try {
    check_input_file(path, "a bind cache");
  } catch (const Error& e) {
    return miss(e.what());
  }
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const std::exception&) {
    return miss("unreadable cache file");
  }
  c10::IValue value;
  if (!archive.try_read("format", value) || !value.isString() || value.toStringRef() != kBindFormat) {
    return miss("not an amt bind file");
  }
  if (!archive.try_read("version", value) || !value.isInt() || value.toInt() != kBindVersion) {
    return miss("another bind file version");
  }
  if (!archive.try_read("key", value) || !value.isString()) return miss("no key");
  if (value.toStringRef() != key) return miss("another mesh or model (key " + value.toStringRef() + ")");
  BoundCharacter loaded;
  for (const auto& [name, member] : fields()) {
    at::Tensor t;
    if (archive.try_read(name, t)) loaded.*member = t;
  }
  for (const char* required : {"V", "faces", "joints", "edges", "apparel_mask", "refiner_prob", "apparel_ids",
                               "body_ids", "apparel_neighbors", "body_weights", "apparel_anchor_weights",
                               "apparel_frame_joints", "apparel_rest_features", "graph_edges", "topology_counts"}) {
    at::Tensor t;
    if (!archive.try_read(required, t)) return miss(std::string("damaged cache file (no ") + required + ")");
  }
  at::Tensor hung;
  if (!archive.try_read(kHungKey, hung) || hung.scalar_type() != at::kLong || hung.numel() != 2) {
    return miss(std::string("damaged cache file (no ") + kHungKey + ")");
  }
  loaded.hung = HungPieces{int(hung[0].item<int64_t>()), int(hung[1].item<int64_t>())};
  CachedSwingFit swing;
  if (archive.try_read(kSwingFitKey, value)) {
    if (!value.isString()) return miss(std::string("damaged cache file (") + kSwingFitKey + ")");
    swing.key = value.toStringRef();
    if (!archive.try_read(kSwingFitText, value) || !value.isString() || !archive.try_read(kSwingFitGain, swing.gain) ||
        swing.gain.scalar_type() != at::kFloat || swing.gain.dim() != 1 ||
        swing.gain.size(0) != loaded.apparel_ids.size(0))
      return miss("damaged cache file (the fitted swing)");
    swing.text = value.toStringRef();
  }
  if (!archive.try_read("crc32", value) || !value.isInt()) return miss("no checksum (written by an older amt)");
  if (value.toInt() != int64_t(bind_crc32(key, loaded, swing))) return miss("damaged cache file (checksum mismatch)");
  bound = std::move(loaded);
  if (fit) *fit = std::move(swing);
  if (reason) reason->clear();
  return true;
}

BindResult bind_cached(const ModelBundle& bundle, const TriMesh& mesh, const MatrixX3f& joints,
                       const std::vector<uint8_t>& mask_override, const std::string& cache_path,
                       std::shared_ptr<const ApparelBones> bones, const MatrixXfR& weights,
                       std::shared_ptr<const ApparelBones> physics) {
  const auto start = std::chrono::steady_clock::now();
  BindResult result;
  std::string key;
  if (!cache_path.empty()) {
    key = bind_key(mesh, joints, mask_override, bundle, bones.get(), weights, physics.get());
    result.key = key;
    result.cache_hit = load_bind(cache_path, key, result.bound, &result.reason, &result.swing_fit);
    if (result.reason.rfind("damaged", 0) == 0) {
      std::cerr << "amt: " << cache_path << ": bind cache: " << result.reason << ", recomputing it\n";
    }
  } else {
    result.reason = "cache disabled";
  }
  if (!result.cache_hit) {
    const at::Tensor V = at::from_blob(const_cast<float*>(mesh.V.data()), {mesh.V.rows(), 3}, at::kFloat).clone();
    const at::Tensor F = at::from_blob(const_cast<int32_t*>(mesh.F.data()), {mesh.F.rows(), 3}, at::kInt).to(at::kLong);
    const at::Tensor Jt = at::from_blob(const_cast<float*>(joints.data()), {joints.rows(), 3}, at::kFloat).clone();
    BindOptions options;
    options.apparel_bones = std::move(bones);
    options.physics_bones = std::move(physics);
    if (!mask_override.empty()) {
      AMT_CHECK(int64_t(mask_override.size()) == mesh.V.rows(), "--apparel-mask: expected ", mesh.V.rows(),
                " values, found ", mask_override.size());
      options.apparel_mask =
          at::from_blob(const_cast<uint8_t*>(mask_override.data()), {int64_t(mask_override.size())}, at::kByte)
              .to(at::kBool);
    }
    if (weights.rows() > 0) {
      AMT_CHECK(weights.rows() == mesh.V.rows() && weights.cols() == joints.rows(), "skin weights: expected ",
                mesh.V.rows(), " x ", joints.rows(), " weights, found ", weights.rows(), " x ", weights.cols());
      options.weights =
          at::from_blob(const_cast<float*>(weights.data()), {weights.rows(), weights.cols()}, at::kFloat).clone();
    }
    result.bound = bind_character(bundle, V, F, Jt, options);
    if (!cache_path.empty()) save_bind(cache_path, key, result.bound);
  }
  result.bound.given_weights = weights.rows() > 0;  // the cache key holds the weights
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace amt
