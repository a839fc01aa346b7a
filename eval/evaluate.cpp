#include "eval/evaluate.h"

#include <ATen/ATen.h>
#include <c10/core/InferenceMode.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <set>
#include <tuple>

#include "data_tools/builder/garment_pairs.h"
#include "data_tools/builder/segmenter_augmentation.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/garment/body_penetration.h"
#include "data_tools/garment/cloth_retarget.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs_torch.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/metrics_torch.h"
#include "models/apparel_dynamics.h"
#include "models/edge_conv.h"

namespace amt {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr const char* kPaper = "paper";
constexpr const char* kRollout = "rollout";
constexpr int kHistory = 3;  // K of eq. 11

// How a method binds the character and which stages it runs.
struct MethodSpec {
  std::string key;
  // Bind configuration: "gt_weights", "predicted", "gt_mask", "gt_mask_no_geodesic", "gt_mask_sorted".
  std::string bind;
  PipelineStages stages;
  ApparelSource source = ApparelSource::kNetwork;
};

const std::vector<MethodSpec>& method_specs() {
  static const std::vector<MethodSpec> specs = {
      {"skinning_baseline", "gt_weights", PipelineStages::kBodyOnly},
      {"hold_offset", "gt_weights", PipelineStages::kBodyApparel, ApparelSource::kHoldOffset},
      {"inertial", "gt_weights", PipelineStages::kBodyApparel, ApparelSource::kInertial},
      {"apparel_gt", "gt_weights", PipelineStages::kBodyApparel, ApparelSource::kNetwork},
      {"lbs_predicted", "predicted", PipelineStages::kBodyOnly},
      {"body_apparel", "predicted", PipelineStages::kBodyApparel},
      // The inertial rule on the same inputs as the full model (predicted mask and weights): the like-for-like
      // zero-network baseline of the whole pipeline, as `inertial` is of the apparel module.
      {"inertial_predicted", "predicted", PipelineStages::kBodyApparel, ApparelSource::kInertial},
      {"full", "predicted", PipelineStages::kFull},
      {"full_gt_mask", "gt_mask", PipelineStages::kFull},
      {"no_geodesic", "gt_mask_no_geodesic", PipelineStages::kFull},
      {"sort_by_geodesic", "gt_mask_sorted", PipelineStages::kFull},
  };
  return specs;
}

at::Tensor float_tensor(const float* data, std::vector<int64_t> shape) {
  return at::from_blob(const_cast<float*>(data), shape, at::kFloat).clone();
}

at::Tensor transforms_tensor(const Transforms& transforms, int64_t count, int64_t J) {
  at::Tensor out = at::empty({count, J, 3, 4}, at::kFloat);
  float* dst = out.data_ptr<float>();
  for (size_t i = 0; i < transforms.size(); ++i) std::memcpy(dst + 12 * i, transforms[i].data(), 12 * sizeof(float));
  return out;
}

MatrixX3f to_matrix(const at::Tensor& t) {
  const at::Tensor c = t.to(at::kFloat).contiguous();
  return Eigen::Map<const MatrixX3f>(c.data_ptr<float>(), c.size(0), 3);
}

std::string duration_text(double seconds) {
  const long s = std::lround(std::max(0.0, seconds));
  char buffer[32];
  if (s >= 3600)
    std::snprintf(buffer, sizeof buffer, "%ldh%02ldm", s / 3600, (s / 60) % 60);
  else if (s >= 60)
    std::snprintf(buffer, sizeof buffer, "%ldm%02lds", s / 60, s % 60);
  else
    std::snprintf(buffer, sizeof buffer, "%lds", s);
  return buffer;
}

// Clips done / total, rate and ETA on one stderr line.
class Progress {
 public:
  Progress(bool enabled, int total, std::string what) : enabled_(enabled), total_(total), what_(std::move(what)) {}
  void update(int done) {
    if (!enabled_) return;
    const double elapsed = std::chrono::duration<double>(Clock::now() - start_).count();
    const double rate = done > 0 ? done / std::max(elapsed, 1e-9) : 0.0;
    std::fprintf(stderr, "\reval: %s %d/%d, %.2f clips/s, elapsed %s, ETA %s   ", what_.c_str(), done, total_, rate,
                 duration_text(elapsed).c_str(), done > 0 ? duration_text((total_ - done) / rate).c_str() : "?");
    if (done == total_) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  }

 private:
  bool enabled_;
  int total_;
  std::string what_;
  Clock::time_point start_ = Clock::now();
};

// A held-out clip to evaluate.
struct EvalClip {
  int shard = 0;
  ClipInfo info;
  std::string subset;
};

// The held-out clips of the shards per subset. With max_clips > 0 a subset keeps at most that many,
// taken round robin over its characters (every character's first clip, then every second clip, ...,
// each character's clips in file order), so that a capped evaluation still covers every character.
std::vector<EvalClip> held_out_clips(std::vector<std::unique_ptr<DatasetReader>>& readers, int max_clips,
                                     bool artist_style = false) {
  // subset -> characters -> (position in file order, clip)
  std::map<std::string, std::vector<std::vector<std::pair<size_t, EvalClip>>>> by_character;
  size_t position = 0;
  for (size_t s = 0; s < readers.size(); ++s) {
    std::map<std::string, std::string> character_split;
    std::map<std::pair<std::string, std::string>, size_t> slot;  // (subset, character) -> index
    for (const std::string& name : readers[s]->character_names())
      character_split[name] = readers[s]->character_summary(name).split;
    for (const std::string& name : readers[s]->clip_names()) {
      ClipInfo info = readers[s]->clip_info(name);
      std::string subset;
      if (character_split.at(info.character) == "test")
        subset = artist_style ? kHeldOutArtistStyle : kHeldOutCharacters;
      else if (info.split == "test")
        subset = kHeldOutClips;
      else
        continue;
      auto& characters = by_character[subset];
      const auto [it, added] = slot.try_emplace({subset, info.character}, characters.size());
      if (added) characters.emplace_back();
      characters[it->second].emplace_back(position++, EvalClip{static_cast<int>(s), std::move(info), subset});
    }
  }
  std::vector<std::pair<size_t, EvalClip>> chosen;
  for (auto& [subset, characters] : by_character) {
    int taken = 0;
    for (size_t round = 0;; ++round) {
      bool any = false;
      for (auto& list : characters) {
        if (round >= list.size() || (max_clips > 0 && taken >= max_clips)) continue;
        chosen.push_back(std::move(list[round]));
        ++taken;
        any = true;
      }
      if (!any) break;
    }
  }
  // Back in file order, the order of an uncapped evaluation.
  std::sort(chosen.begin(), chosen.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<EvalClip> clips;
  for (auto& [order, clip] : chosen) clips.push_back(std::move(clip));
  return clips;
}

// What the evaluation needs of one character: its arrays, ground-truth split, body surface, binds.
struct CharacterCache {
  std::string name, subset;
  at::Tensor V, F, joints, gt_mask, gt_weights;
  std::vector<uint8_t> mask;  // ground-truth apparel mask, 1 = apparel
  MatrixX2i E;                // unique edges, for ELS
  int num_apparel = 0;        // ground-truth apparel vertices
  // Penetration of a predicted frame's apparel into its body (both split by the ground-truth mask):
  // one winding-number tree of the body surface, built on the rest pose and refitted to every frame
  // of every method. Empty without the penetration measure or without apparel or body faces.
  std::optional<BodyPenetration> body;
  std::map<std::string, BoundCharacter> binds;
  std::optional<SegmentationScores> segmentation;
  // Share of the bare body (largest connected part, segmented alone) called apparel.
  double bare_apparel_share = std::nan("");
  // The character remade of open parts (open_parts_example): the segmenter's IoU on it and the share of its bare
  // version called apparel. NaN when the character cannot be remade (not a procedural character's layout).
  double open_parts_iou = std::nan(""), bare_open_parts_share = std::nan("");
  TriMesh mesh;  // the rest mesh and joints, for the bare body
  MatrixX3f rest_joints;
  Skeleton skeleton;  // and the skeleton and body weights, for the open-parts version
  MatrixXfR body_weights;
  // The artist-style remake the arrays above are of (EvaluateOptions::artist_style), whose map remakes the ground
  // truth read from the dataset; empty for a character evaluated as built.
  std::optional<ArtistStyleCharacter> remake;
  // The rig's apparel bones as the handles of the binds on the ground-truth mask (EvaluateOptions::rig_handles);
  // null otherwise.
  std::shared_ptr<const ApparelBones> bones;
  // The rig's apparel bones whose physics response (ApparelBones::response) the apparel module reads, whichever
  // handles it moves; null when the dataset has none.
  std::shared_ptr<const ApparelBones> physics;
  MatrixX2i pairs;      // coincident_pairs of the rest mesh: the seam gap's pairs
  MatrixX2i apparel_E;  // apparel_edges of E: tearing and apparel ELS
  MeshConstruction construction;
  // The character's clips in its shard, in file order (listed on first use), and its binds with the swing fitted on
  // some of them (EvaluateOptions::fit_swing): (bind, calibration clips, window: 0 rollout, else the paper protocol's)
  // -> bind.
  std::optional<std::vector<std::string>> own_clips;
  std::map<std::tuple<std::string, std::string, int64_t>, BoundCharacter> fitted;

  // The ground truth of `count` frames of `clip` from `first`, (count * N, 3): as stored, or remade.
  MatrixX3f ground_truth(const DatasetReader& reader, const std::string& clip, int first, int count) const {
    const MatrixX3f stored = reader.read_vertices(clip, first, count);
    return remake ? remake_frames(*remake, stored, reader.read_joint_transforms(clip, first, count)) : stored;
  }
};

// Share of a character's largest connected part called apparel when the segmenter sees that part
// alone. A procedural character's pieces are separate parts, so that part is its naked body (the
// builder's DressedCharacter lists the body's vertices first, as one component): what the
// segmenter makes of a character that wears nothing.
double bare_body_apparel_share(const ModelBundle& bundle, const CharacterCache& c) {
  const Eigen::Index N = c.mesh.V.rows();
  int count = 0;
  const std::vector<int32_t> label = connected_components(static_cast<int>(N), c.E, &count);
  std::vector<int32_t> size(static_cast<size_t>(count), 0);
  for (const int32_t l : label) ++size[static_cast<size_t>(l)];
  const int32_t largest = static_cast<int32_t>(std::max_element(size.begin(), size.end()) - size.begin());
  std::vector<int32_t> ids;
  for (Eigen::Index i = 0; i < N; ++i)
    if (label[i] == largest) ids.push_back(static_cast<int32_t>(i));
  const TriMesh bare = submesh(c.mesh.V, c.mesh.F, ids);
  return apparel_probabilities(bundle, bare.V, bare.F, c.rest_joints).gt(0.5).to(at::kDouble).mean().item<double>();
}

// The segmenter on character c remade as real models are built (open_parts_example: open, overlapping body parts,
// duplicated seams, a hair cap), dressed and bare: what `amt bench --suite segmenter` measures, in the report.
void score_open_parts(const ModelBundle& bundle, CharacterCache& c) {
  if (c.remake) return;  // already remade as real models are built: no open-parts version, NaN in the report
  const SegmenterExample example{c.mesh, c.skeleton, c.body_weights, c.mask};
  std::optional<SegmenterExample> open, bare;
  try {
    open = open_parts_example(example);
    bare = open_parts_example(example, true);
  } catch (const Error&) {
    return;  // not a procedural character's layout (a PMX model): no open-parts version, NaN in the report
  }
  const auto called = [&](const SegmenterExample& e) {
    return apparel_probabilities(bundle, e.mesh.V, e.mesh.F, e.skeleton.rest_joints).gt(0.5);
  };
  const at::Tensor p = called(*open);
  const at::Tensor gt = at::tensor(at::ArrayRef<uint8_t>(open->apparel_mask)).to(at::kBool);
  const double uni = p.logical_or(gt).sum().item<double>();
  c.open_parts_iou = uni > 0 ? p.logical_and(gt).sum().item<double>() / uni : 1.0;
  c.bare_open_parts_share = called(*bare).to(at::kDouble).mean().item<double>();
}

// Character `name` of `reader` for `subset`; remade artist-style with `artist_style` when the subset is
// kHeldOutArtistStyle.
std::unique_ptr<CharacterCache> load_character(const DatasetReader& reader, const std::string& name,
                                               const std::string& subset, bool penetration,
                                               const ArtistStyleOptions& artist_style = {}, bool rig_handles = false) {
  auto c = std::make_unique<CharacterCache>();
  if (subset == kHeldOutArtistStyle) c->remake = artist_style_character(reader.read_character(name), artist_style);
  const CharacterData data = c->remake ? c->remake->character : reader.read_character(name);
  if (std::optional<ApparelBones> bones = rig_apparel_bones(data)) {
    auto shared = std::make_shared<const ApparelBones>(std::move(*bones));
    if (rig_handles) c->bones = shared;
    if (shared->response.rows() > 0) c->physics = shared;
  }
  c->name = name;
  c->subset = subset;
  const int64_t N = data.mesh.num_vertices(), J = data.skeleton.num_joints();
  c->V = float_tensor(data.mesh.V.data(), {N, 3});
  c->F = at::from_blob(const_cast<int32_t*>(data.mesh.F.data()), {data.mesh.F.rows(), 3}, at::kInt).to(at::kLong);
  c->joints = float_tensor(data.skeleton.rest_joints.data(), {J, 3});
  c->mask = data.apparel_mask;
  c->gt_mask = at::from_blob(c->mask.data(), {N}, at::kByte).to(at::kBool);
  c->gt_weights = float_tensor(data.body_weights.data(), {N, J});
  c->E = unique_edges(data.mesh.F);
  c->mesh = data.mesh;
  c->rest_joints = data.skeleton.rest_joints;
  c->skeleton = data.skeleton;
  c->body_weights = data.body_weights;
  c->num_apparel = static_cast<int>(std::count_if(c->mask.begin(), c->mask.end(), [](uint8_t a) { return a != 0; }));
  c->pairs = coincident_pairs(data.mesh.V, data.mesh.F);
  c->apparel_E = apparel_edges(c->E, c->mask);
  c->construction = mesh_construction(data.mesh.V, data.mesh.F);
  if (penetration) {
    BodyPenetration body(data.mesh.V, data.mesh.F, c->mask);
    if (body.active()) c->body.emplace(std::move(body));
  }
  return c;
}

// The characters of the clips evaluated so far, each loaded once per (shard, name).
struct CharacterCaches {
  std::vector<std::unique_ptr<CharacterCache>> loaded;  // in the order first met
  std::map<std::pair<int, std::string>, CharacterCache*> index;
  ArtistStyleOptions artist_style;  // how the characters of kHeldOutArtistStyle are remade
  bool rig_handles = false;         // EvaluateOptions::rig_handles

  // The character of `clip`, read from `reader` (the clip's shard) on first use.
  CharacterCache& of(const DatasetReader& reader, const EvalClip& clip, bool penetration) {
    CharacterCache*& c = index[{clip.shard, clip.info.character}];
    if (!c) {
      loaded.push_back(
          load_character(reader, clip.info.character, clip.subset, penetration, artist_style, rig_handles));
      c = loaded.back().get();
    }
    return *c;
  }
};

// One predicted frame, ready to score.
struct PredictedFrame {
  MatrixX3f V;                             // (N, 3) in mesh order, metres
  std::optional<Penetration> penetration;  // when measured and the predicted body is finite
};

// The frame V (N, 3) of character c with the penetration of its apparel into its body, when measured.
PredictedFrame predicted_frame(CharacterCache& c, MatrixX3f V) {
  PredictedFrame frame{std::move(V), std::nullopt};
  if (c.body) frame.penetration = c.body->measure(frame.V);
  return frame;
}

using Key = std::tuple<std::string, std::string, std::string>;  // (method or character, protocol, subset)

// A rollout curve: per predicted frame, the sum of the clips' PMD_a and how many clips reached it.
using Curve = std::pair<std::vector<double>, std::vector<int>>;

// Adds frame t's PMD_a to a curve (a NaN PMD_a, no apparel, does not count).
void add_to_curve(Curve& curve, int64_t t, double pmd_a) {
  if (curve.first.size() <= static_cast<size_t>(t)) curve.first.push_back(0.0), curve.second.push_back(0);
  if (pmd_a == pmd_a) curve.first[t] += pmd_a, curve.second[t] += 1;
}

// Accumulators for every table row and per-character entry, and the rollout curves.
struct Accumulators {
  std::map<Key, ScoreAccumulator> rows;
  std::map<Key, ScoreAccumulator> characters;                     // (character, method, protocol)
  std::map<std::pair<std::string, std::string>, Curve> curves;    // (subset, method): rollout frames
  std::map<std::pair<std::string, std::string>, Curve> horizons;  // (subset, method): paper-window frames
  // (method, protocol, subset) -> sums over frames of mean |V - S| and mean |V_gt - S| over apparel.
  std::map<Key, std::pair<double, double>> amplitude;
  // (method, protocol, subset, character) -> the measures of falling apart.
  std::map<std::tuple<std::string, std::string, std::string, std::string>, SeparationAccumulator> separation;
  // The clip being scored (name, shard) and every scored clip's PMD_a (EvaluationResult::clip_scores).
  std::string clip;
  int shard = 0;
  std::vector<ClipScore> clip_scores;
};

// Mean over the apparel vertices (mask 1) of |a_i - b_i| (metres); 0 without apparel.
double mean_apparel_distance(const MatrixX3f& a, const MatrixX3f& b, const std::vector<uint8_t>& mask) {
  double sum = 0;
  int count = 0;
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    if (!mask[i]) continue;
    sum += (a.row(i) - b.row(i)).norm();
    ++count;
  }
  return count ? sum / count : 0.0;
}

// Scores the frames of one clip for one method and protocol.
class ClipScorer {
 public:
  ClipScorer(Accumulators& acc, const CharacterCache& c, const std::string& method, const std::string& protocol,
             bool per_character)
      : acc_(acc), c_(c), method_(method), protocol_(protocol) {
    row_ = &acc.rows[{method, protocol, c.subset}];
    row_->begin_clip();
    separation_ =
        &acc.separation.try_emplace({method, protocol, c.subset, c.name}, c.pairs, c.apparel_E, c.mesh.V).first->second;
    separation_->begin_clip();
    amplitude_ = &acc.amplitude[{method, protocol, c.subset}];
    if (per_character) {
      character_ = &acc.characters[{c.name, method, protocol}];
      character_->begin_clip();
    }
  }
  ~ClipScorer() {
    row_->end_clip();
    separation_->end_clip();
    if (character_) character_->end_clip();
    acc_.clip_scores.push_back({c_.subset, acc_.clip, c_.name, method_, protocol_, acc_.shard,
                                frames_ > 0 ? pmd_a_sum_ / frames_ : std::nan("")});
  }
  ClipScorer(const ClipScorer&) = delete;
  ClipScorer& operator=(const ClipScorer&) = delete;
  // Adds a frame (with `skinned`, the frame skinned by the ground-truth body weights, for the dynamics
  // amplitude) and returns its PMD_a (cm; NaN without apparel).
  double add(const PredictedFrame& frame, const MatrixX3f& gt, const MatrixX3f& skinned) {
    if (c_.num_apparel > 0) {
      amplitude_->first += mean_apparel_distance(frame.V, skinned, c_.mask);
      amplitude_->second += mean_apparel_distance(gt, skinned, c_.mask);
    }
    const Penetration* pen = frame.penetration ? &*frame.penetration : nullptr;
    row_->add_frame(frame.V, gt, c_.mask, c_.E, pen);
    separation_->add_frame(frame.V, gt);
    if (character_) character_->add_frame(frame.V, gt, c_.mask, c_.E, pen);
    const double pmd_a = point_mesh_distance_cm(frame.V, gt, &c_.mask, 1);
    if (std::isfinite(pmd_a)) pmd_a_sum_ += pmd_a, ++frames_;
    return pmd_a;
  }

 private:
  Accumulators& acc_;
  const CharacterCache& c_;
  std::string method_, protocol_;
  double pmd_a_sum_ = 0;
  int frames_ = 0;
  ScoreAccumulator* row_ = nullptr;
  ScoreAccumulator* character_ = nullptr;
  SeparationAccumulator* separation_ = nullptr;
  std::pair<double, double>* amplitude_ = nullptr;
};

// The clips of character c whose simulation fits the apparel swing while `clip` is scored (EvaluateOptions::fit_swing),
// at most kSwingCalibrationClips: the character's first clips in file order that the evaluation does not score
// (`scored`: (shard, clip)), else its first clips other than `clip`; empty when it has no other clip.
std::vector<std::string> calibration_clips(CharacterCache& c, const DatasetReader& reader, int shard,
                                           const std::string& clip,
                                           const std::set<std::pair<int, std::string>>& scored) {
  if (!c.own_clips) {
    c.own_clips.emplace();
    for (const std::string& name : reader.clip_names())
      if (reader.clip_info(name).character == c.name) c.own_clips->push_back(name);
  }
  std::vector<std::string> unscored, other;
  for (const std::string& name : *c.own_clips) {
    if (!scored.count({shard, name}) && int(unscored.size()) < kSwingCalibrationClips) unscored.push_back(name);
    if (name != clip && int(other.size()) < kSwingCalibrationClips) other.push_back(name);
  }
  return unscored.empty() ? other : unscored;
}

// Bind `b` (key `bind`) of character c with its swing fitted on the first kSwingCalibrationSeconds of the clips
// `calibration`, their ground truth pooled, under the protocol it is scored with (fit_swing_on_motions): window 0, the
// rollout after the lead-in from the rest pose; window > 0, the paper protocol's windows. Clips shorter than a window
// are left out; `b` itself when every clip is.
const BoundCharacter& fitted_bind(const ModelBundle& bundle, CharacterCache& c, const DatasetReader& reader,
                                  const std::string& bind, const BoundCharacter& b,
                                  const std::vector<std::string>& calibration, int64_t window, float strain_limit,
                                  int64_t J) {
  std::string names;
  for (const std::string& name : calibration) names += name + "\n";
  const auto key = std::make_tuple(bind, names, window);
  if (const auto it = c.fitted.find(key); it != c.fitted.end()) return it->second;
  std::vector<SwingCalibrationMotion> runs;
  for (const std::string& name : calibration) {
    const ClipInfo info = reader.clip_info(name);
    const int T = std::min(info.num_frames, std::max(1, int(std::lround(kSwingCalibrationSeconds * info.fps))));
    if (T < window) continue;
    const at::Tensor motion = transforms_tensor(reader.read_joint_transforms(name, 0, T), T, J);
    const MatrixX3f truth = c.ground_truth(reader, name, 0, T);
    const at::Tensor G =
        float_tensor(truth.data(), {T, static_cast<int64_t>(c.mask.size()), 3}).index_select(1, b.apparel_ids);
    runs.push_back({motion_lead_in(motion[0], c.joints, kDefaultLeadInFrames), motion, G});
  }
  if (runs.empty()) return b;
  BoundCharacter fitted = b;
  fitted.apparel_swing_gain = fit_swing_on_motions(bundle, b, runs, strain_limit, window).gain;
  return c.fitted.emplace(key, std::move(fitted)).first->second;
}

BindOptions bind_options_for(const std::string& bind, const CharacterCache& c, bool calibrate_swing) {
  BindOptions o;
  o.calibrate_swing = calibrate_swing;
  if (bind == "gt_weights") {
    o.apparel_mask = c.gt_mask;
    o.weights = c.gt_weights;
    o.apparel_bones = c.bones;
    o.physics_bones = c.physics;
  } else if (bind == "predicted") {
    o.all_vertex_weights = true;
    o.physics_bones = c.physics;
  } else {
    o.apparel_mask = c.gt_mask;
    o.apparel_bones = c.bones;
    o.physics_bones = c.physics;
    if (bind == "gt_mask_no_geodesic") o.skinning_variant = SkinningVariant::kNoGeodesic;
    if (bind == "gt_mask_sorted") o.skinning_variant = SkinningVariant::kSortByGeodesic;
  }
  return o;
}

MatrixX3f frame_of(const MatrixX3f& all, int64_t t, int64_t N) {
  return all.middleRows(t * N, N);
}

// A row's measures of falling apart from its characters' (entries of acc.separation under the row's key): each
// measure's mean over the characters that have it, and its worst character.
void add_separation(MethodScores& row, const Accumulators& acc) {
  struct Measure {
    double SeparationScores::*value;
    bool larger_is_worse;
    std::string MethodScores::*worst_name;
  };
  const Measure measures[] = {{&SeparationScores::tearing, true, &MethodScores::worst_tearing},
                              {&SeparationScores::seam_gap_p95_cm, true, &MethodScores::worst_seam_gap_p95},
                              {&SeparationScores::seam_gap_max_cm, true, &MethodScores::worst_seam_gap_max},
                              {&SeparationScores::apparel_els, false, &MethodScores::worst_apparel_els},
                              {&SeparationScores::rest_tearing, true, nullptr},
                              {&SeparationScores::ground_truth_rest_tearing, true, nullptr},
                              {&SeparationScores::tearing_ground_truth_deformed, true, nullptr}};
  std::vector<std::pair<std::string, SeparationScores>> characters;
  for (auto it = acc.separation.lower_bound({row.method, row.protocol, row.subset, ""});
       it != acc.separation.end() && std::get<0>(it->first) == row.method && std::get<1>(it->first) == row.protocol &&
       std::get<2>(it->first) == row.subset;
       ++it)
    characters.emplace_back(std::get<3>(it->first), it->second.result());
  for (const auto& [name, s] : characters) {
    row.separation.pairs += s.pairs, row.separation.edge_frames += s.edge_frames;
    row.separation.pair_frames += s.pair_frames;
  }
  for (const Measure& m : measures) {
    double sum = 0;
    int count = 0;
    row.separation.*m.value = row.worst.*m.value = std::nan("");
    for (const auto& [name, s] : characters) {
      const double v = s.*m.value;
      if (!std::isfinite(v)) continue;
      sum += v, ++count;
      if (!m.worst_name) continue;
      const double worst = row.worst.*m.value;
      if (!std::isfinite(worst) || (m.larger_is_worse ? v > worst : v < worst))
        row.worst.*m.value = v, row.*m.worst_name = name;
    }
    if (count > 0) row.separation.*m.value = sum / count;
  }
}

std::vector<MethodScores> collect_rows(const Accumulators& acc) {
  std::vector<MethodScores> rows;
  for (const auto& [key, a] : acc.rows) {
    MethodScores row{std::get<0>(key), std::get<1>(key), std::get<2>(key), a.result()};
    const auto amplitude = acc.amplitude.find(key);
    // Below a micrometre of ground-truth lag per frame there is no dynamics to measure against.
    if (amplitude != acc.amplitude.end() && amplitude->second.second > 1e-6 * std::max(1, row.scores.frames))
      row.amplitude = amplitude->second.first / amplitude->second.second;
    add_separation(row, acc);
    rows.push_back(std::move(row));
  }
  // Order rows by the method order of evaluation_methods(), then protocol, then subset.
  const std::vector<std::string> order = evaluation_methods();
  const auto rank = [&](const std::string& m) {
    const auto it = std::find(order.begin(), order.end(), m);
    return it == order.end() ? order.size() : static_cast<size_t>(it - order.begin());
  };
  std::stable_sort(rows.begin(), rows.end(), [&](const MethodScores& a, const MethodScores& b) {
    return std::make_tuple(rank(a.method), a.protocol, a.subset) <
           std::make_tuple(rank(b.method), b.protocol, b.subset);
  });
  return rows;
}

void finish(EvaluationResult& result, const Accumulators& acc, std::vector<std::unique_ptr<CharacterCache>>& cache) {
  result.rows = collect_rows(acc);
  result.clip_scores = acc.clip_scores;
  std::map<std::string, std::pair<SegmentationScores, int>> seg;
  std::map<std::string, std::pair<double, int>> bare;
  struct OpenSum {
    double iou = 0, bare_share = 0;
    int count = 0;
  };
  std::map<std::string, OpenSum> open;
  for (const auto& c : cache) {
    CharacterScores cs;
    cs.character = c->name;
    cs.subset = c->subset;
    cs.num_vertices = static_cast<int>(c->mask.size());
    cs.num_apparel = c->num_apparel;
    if (c->segmentation) {
      cs.segmentation = *c->segmentation;
      auto& s = seg[c->subset];
      s.first.iou += cs.segmentation.iou, s.first.f1 += cs.segmentation.f1;
      s.first.precision += cs.segmentation.precision, s.first.recall += cs.segmentation.recall;
      ++s.second;
      cs.bare_apparel_share = c->bare_apparel_share;
      if (std::isfinite(c->bare_apparel_share)) {  // NaN on an artist-style remake (no bare body to cut out)
        auto& b = bare[c->subset];
        b.first += c->bare_apparel_share;
        ++b.second;
      }
      cs.open_parts_iou = c->open_parts_iou;
      cs.bare_open_parts_share = c->bare_open_parts_share;
      if (std::isfinite(c->open_parts_iou)) {
        auto& o = open[c->subset];
        o.iou += c->open_parts_iou, o.bare_share += c->bare_open_parts_share, ++o.count;
      }
    }
    for (const auto& [key, a] : acc.characters) {
      if (std::get<0>(key) == c->name) cs.scores[std::get<1>(key)][std::get<2>(key)] = a.result();
    }
    for (const auto& [key, a] : acc.separation)
      if (std::get<3>(key) == c->name && std::get<2>(key) == c->subset)
        cs.separation[std::get<0>(key)][std::get<1>(key)] = a.result();
    cs.construction = c->construction;
    cs.artist_style = c->remake.has_value();
    result.characters.push_back(std::move(cs));
  }
  for (auto& [subset, s] : seg) {
    SegmentationScores mean = s.first;
    mean.iou /= s.second, mean.f1 /= s.second, mean.precision /= s.second, mean.recall /= s.second;
    result.segmentation[subset] = mean;
  }
  for (const auto& [subset, b] : bare) result.bare_apparel_share[subset] = b.first / b.second;
  for (const auto& [subset, o] : open) result.open_parts[subset] = {o.iou / o.count, o.bare_share / o.count};
  const auto to_curves = [](const std::map<std::pair<std::string, std::string>, Curve>& from,
                            std::vector<RolloutCurve>& to) {
    for (const auto& [key, curve] : from) {
      RolloutCurve rc;
      rc.subset = key.first;
      rc.method = key.second;
      rc.clips = curve.second;
      for (size_t k = 0; k < curve.first.size(); ++k)
        rc.pmd_a.push_back(curve.second[k] > 0 ? curve.first[k] / curve.second[k] : std::nan(""));
      to.push_back(std::move(rc));
    }
  };
  to_curves(acc.curves, result.curves);
  to_curves(acc.horizons, result.horizons);
}

std::vector<std::unique_ptr<DatasetReader>> open_shards(const std::vector<std::string>& shards) {
  std::vector<std::unique_ptr<DatasetReader>> readers;
  for (const std::string& shard : shards) {
    readers.push_back(std::make_unique<DatasetReader>(shard));
    AMT_CHECK(readers.back()->joint_names() == readers.front()->joint_names(), shard, ": skeleton: expected the ",
              readers.front()->joint_names().size(), " joints of ", shards.front(), ", found ",
              readers.back()->joint_names().size(), " different ones");
  }
  return readers;
}

// The inertia of the inertial rule, least-squares fitted (InertiaFit) on the ground-truth detail
// vectors of up to 16 training clips of training characters (the first of each character, round
// robin), with the anchors the rule uses (`anchor`, the model's: ApparelDynamicsOptions::anchor, from the
// ground-truth weights). Returns the inertia and the number of clips.
std::pair<double, int> fit_inertia(std::vector<std::unique_ptr<DatasetReader>>& readers, int64_t J,
                                   const std::string& anchor) {
  constexpr int kClips = 16;
  InertiaFit fit;
  int clips = 0;
  c10::InferenceMode inference;
  for (size_t round = 0; round < 4 && clips < kClips; ++round) {
    for (size_t s = 0; s < readers.size() && clips < kClips; ++s) {
      const DatasetReader& reader = *readers[s];
      std::map<std::string, std::vector<std::string>> train_clips;
      for (const std::string& name : reader.clip_names()) {
        const ClipInfo info = reader.clip_info(name);
        if (info.split == "train" && reader.character_summary(info.character).split == "train")
          train_clips[info.character].push_back(name);
      }
      for (const auto& [character, names] : train_clips) {
        if (round >= names.size() || clips >= kClips) continue;
        const CharacterData data = reader.read_character(character);
        const int64_t N = data.mesh.num_vertices();
        const at::Tensor V = float_tensor(data.mesh.V.data(), {N, 3});
        const at::Tensor joints = float_tensor(data.skeleton.rest_joints.data(), {J, 3});
        const at::Tensor W = float_tensor(data.body_weights.data(), {N, J});
        const at::Tensor mask =
            at::from_blob(const_cast<uint8_t*>(data.apparel_mask.data()), {N}, at::kByte).to(at::kBool);
        const at::Tensor apparel_ids = at::nonzero(mask).flatten(),
                         body_ids = at::nonzero(mask.logical_not()).flatten();
        if (apparel_ids.size(0) == 0 || body_ids.size(0) == 0) continue;
        const at::Tensor faces =
            at::from_blob(const_cast<int32_t*>(data.mesh.F.data()), {data.mesh.F.rows(), 3}, at::kInt);
        const at::Tensor anchor_weights = apparel_anchor_weights_for(anchor, V, mesh_edges(faces), apparel_ids,
                                                                     body_ids, W.index_select(0, body_ids));
        const ClipInfo info = reader.clip_info(names[round]);
        const int64_t T = info.num_frames;
        const at::Tensor motion = transforms_tensor(reader.read_joint_transforms(info.name, 0, T), T, J);
        const MatrixX3f all = reader.read_vertices(info.name, 0, static_cast<int>(T));
        const at::Tensor A = float_tensor(all.data(), {T, N, 3}).index_select(1, apparel_ids);
        const at::Tensor S = linear_blend_skinning(V.index_select(0, apparel_ids), anchor_weights, motion, joints);
        fit.add(detail_vectors(A, S, motion, anchor_weights.argmax(1)));
        ++clips;
      }
    }
  }
  return {fit.inertia(), clips};
}

// The frames of `motion` (T, J, 3, 4) skinned by the ground-truth body weights of c: the dynamics
// amplitude's reference (and the skinning baseline's frames).
std::vector<MatrixX3f> skinned_frames(const CharacterCache& c, const at::Tensor& motion) {
  c10::InferenceMode inference;
  const at::Tensor all = linear_blend_skinning(c.V, c.gt_weights, motion, c.joints).contiguous();
  std::vector<MatrixX3f> skinned(static_cast<size_t>(all.size(0)));
  for (int64_t t = 0; t < all.size(0); ++t) skinned[t] = to_matrix(all[t]);
  return skinned;
}

// The frames of a clip of T frames that the paper protocol predicts, each once (1): windows at a stride of
// window - 3, their first 3 frames history. All 0 when the protocol is off or the clip shorter than a window.
std::vector<uint8_t> paper_frames(int64_t T, const EvaluateOptions& options) {
  std::vector<uint8_t> paper_frame(static_cast<size_t>(T), 0);
  if (options.paper && T >= options.window)
    for (int64_t s = 0; s + options.window <= T; s += options.window - kHistory)
      for (int64_t t = s + kHistory; t < s + options.window; ++t) paper_frame[t] = 1;
  return paper_frame;
}

// Cloth retargeting (issue 13) on the garment pairs of the shards (data_tools/builder/garment_pairs.h): every held-out
// clip that is the target of a pair (its first source, in file order) is scored with the apparel of the source
// clip's simulation retargeted onto the target's ground-truth body (data_tools/garment/cloth_retarget.h), against the
// target's own simulation, as "cloth_retarget" (collisions resolved) and "cloth_retarget_unresolved" (detail
// vectors shortened, no push-out), in the clip's own subset, beside the methods run on the same clip. Both
// protocols: retargeting has no state, so the paper protocol scores the windows' predicted frames of the same
// per-frame result. Returns the number of clips scored.
int score_cloth_retargeting(std::vector<std::unique_ptr<DatasetReader>>& readers, const std::vector<EvalClip>& clips,
                            const EvaluateOptions& options, int64_t J, const std::vector<std::string>& methods,
                            Accumulators& acc, CharacterCaches& characters) {
  const bool resolved = std::find(methods.begin(), methods.end(), "cloth_retarget") != methods.end();
  const bool unresolved = std::find(methods.begin(), methods.end(), "cloth_retarget_unresolved") != methods.end();
  if (!resolved && !unresolved) return 0;
  std::map<std::pair<int, std::string>, GarmentPair> source_of;  // (shard, target clip) -> its pair
  for (size_t s = 0; s < readers.size(); ++s)
    for (const GarmentPair& pair : find_garment_pairs(*readers[s]))
      source_of.try_emplace({static_cast<int>(s), pair.target_clip}, pair);
  std::map<std::tuple<int, std::string, std::string, bool>, std::unique_ptr<ClothRetargeter>> retargeters;
  int scored = 0;
  for (const EvalClip& clip : clips) {
    const auto pair = source_of.find({clip.shard, clip.info.name});
    if (pair == source_of.end()) continue;
    const DatasetReader& reader = *readers[clip.shard];
    CharacterCache& c = characters.of(reader, clip, options.penetration);
    if (c.remake) continue;  // the pair's apparel connectivity is the characters' as built
    const auto retargeter = [&](bool resolve) -> ClothRetargeter& {
      auto& r = retargeters[{clip.shard, pair->second.source_character, pair->second.target_character, resolve}];
      if (!r) {
        const CharacterData source = reader.read_character(pair->second.source_character);
        const CharacterData target = reader.read_character(pair->second.target_character);
        ClothRetargetOptions o;
        o.resolve = resolve;
        r = std::make_unique<ClothRetargeter>(
            ClothCharacter{reader.path() + ":" + source.name, source.mesh, source.apparel_mask},
            ClothCharacter{reader.path() + ":" + target.name, target.mesh, target.apparel_mask}, o);
      }
      return *r;
    };
    const int64_t T = clip.info.num_frames, N = static_cast<int64_t>(c.mask.size());
    const MatrixX3f gt_all = reader.read_vertices(clip.info.name, 0, static_cast<int>(T));
    const MatrixX3f source_all = reader.read_vertices(pair->second.source_clip, 0, static_cast<int>(T));
    const int64_t N_source = source_all.rows() / std::max<int64_t>(1, T);
    const std::vector<MatrixX3f> skinned =
        skinned_frames(c, transforms_tensor(reader.read_joint_transforms(clip.info.name, 0, T), T, J));
    const bool paper = options.paper && T >= options.window;
    const std::vector<uint8_t> paper_frame = paper_frames(T, options);
    for (const bool resolve : {true, false}) {
      if (resolve ? !resolved : !unresolved) continue;
      const std::string key = resolve ? "cloth_retarget" : "cloth_retarget_unresolved";
      ClothRetargeter& r = retargeter(resolve);
      std::optional<ClipScorer> paper_scorer, rollout_scorer;
      if (paper) paper_scorer.emplace(acc, c, key, kPaper, false);
      if (options.rollout) rollout_scorer.emplace(acc, c, key, kRollout, false);
      for (int64_t t = 0; t < T; ++t) {
        if (!rollout_scorer && !paper_frame[t]) continue;
        const MatrixX3f gt = frame_of(gt_all, t, N);
        MatrixX3f V = gt;  // the target's body as simulated; its apparel rows are replaced
        r.retarget(frame_of(source_all, t, N_source), V);
        const PredictedFrame frame = predicted_frame(c, std::move(V));
        if (paper_frame[t]) paper_scorer->add(frame, gt, skinned[t]);
        if (rollout_scorer) add_to_curve(acc.curves[{c.subset, key}], t, rollout_scorer->add(frame, gt, skinned[t]));
      }
    }
    ++scored;
  }
  return scored;
}

}  // namespace

std::vector<int32_t> rest_vertex_match(const MatrixX3f& truth, const MatrixX3f& predicted, float tolerance) {
  if (truth.rows() != predicted.rows()) return {};
  const Eigen::Index N = truth.rows();
  std::vector<int32_t> match(static_cast<size_t>(N));
  if (N == 0 || (truth - predicted).cwiseAbs().maxCoeff() <= tolerance) {
    for (Eigen::Index i = 0; i < N; ++i) match[size_t(i)] = int32_t(i);
    return match;
  }
  // Both sorted by position (copies of one position in index order), then paired rank by rank.
  const auto sorted = [N](const MatrixX3f& V) {
    std::vector<int32_t> order(static_cast<size_t>(N));
    for (Eigen::Index i = 0; i < N; ++i) order[size_t(i)] = int32_t(i);
    std::stable_sort(order.begin(), order.end(), [&V](int32_t a, int32_t b) {
      return std::make_tuple(V(a, 0), V(a, 1), V(a, 2)) < std::make_tuple(V(b, 0), V(b, 1), V(b, 2));
    });
    return order;
  };
  const std::vector<int32_t> t = sorted(truth), p = sorted(predicted);
  for (size_t k = 0; k < size_t(N); ++k) {
    if ((truth.row(t[k]) - predicted.row(p[k])).cwiseAbs().maxCoeff() > tolerance) return {};
    match[size_t(t[k])] = p[k];
  }
  return match;
}

// === Methods

std::vector<std::string> evaluation_methods() {
  std::vector<std::string> keys;
  for (const MethodSpec& m : method_specs()) keys.push_back(m.key);
  keys.push_back("cloth_retarget_unresolved");
  keys.push_back("cloth_retarget");
  return keys;
}

std::string method_label(const std::string& method) {
  static const std::map<std::string, std::string> labels = {
      {"skinning_baseline", "Skinning baseline (LBS, GT body weights)"},
      {"hold_offset", "hold_offset rule (no network)"},
      {"inertial", "inertial rule (no network)"},
      {"apparel_gt", "Apparel module, GT mask + weights"},
      {"lbs_predicted", "LBS, predicted weights (body module only)"},
      {"body_apparel", "Body + apparel modules"},
      {"inertial_predicted", "inertial rule, predicted mask + weights"},
      {"full", "Full model"},
      {"full_gt_mask", "Full model + GT mask (G + attention)"},
      {"no_geodesic", "w/o G (GT mask)"},
      {"sort_by_geodesic", "Sort by G (GT mask)"},
      {"predictions", "Predictions file"},
      {"cloth_retarget_unresolved", "Cloth retargeting from the pair's other body, no push-out"},
      {"cloth_retarget", "Cloth retargeting from the pair's other body"},
  };
  const auto it = labels.find(method);
  return it == labels.end() ? method : it->second;
}

const MethodScores* EvaluationResult::find(const std::string& method, const std::string& protocol,
                                           const std::string& subset) const {
  for (const MethodScores& r : rows)
    if (r.method == method && r.protocol == protocol && r.subset == subset) return &r;
  return nullptr;
}

// === Evaluation

EvaluationResult evaluate_model(const ModelBundle& bundle, const std::vector<std::string>& shards,
                                const EvaluateOptions& options) {
  const auto start = Clock::now();
  AMT_CHECK(options.paper || options.rollout, "eval: protocol: expected paper, rollout or both, found none");
  AMT_CHECK(options.window > kHistory, "eval: window: expected more than ", kHistory, " frames, found ",
            options.window);
  EvaluationResult result;
  result.shards = shards;
  result.model_dir = bundle.dir;
  result.options = options;

  // Methods to run.
  std::vector<MethodSpec> methods;
  const std::vector<std::string> all = evaluation_methods();
  for (const std::string& m : options.methods)
    AMT_CHECK(
        std::find(all.begin(), all.end(), m) != all.end(), "eval: method: expected one of ",
        [&] {
          std::string list;
          for (const std::string& key : all) list += (list.empty() ? "" : ", ") + key;
          return list;
        }(),
        ", found '", m, "'");
  for (const MethodSpec& spec : method_specs()) {
    if (!options.methods.empty() &&
        std::find(options.methods.begin(), options.methods.end(), spec.key) == options.methods.end())
      continue;
    if (spec.key == "no_geodesic" && bundle.skinning_no_geodesic.is_empty()) {
      result.notes.push_back(std::string("Table 4: ") + kSkinningNoGeodesicCheckpoint +
                             " is not in the model folder; the w/o G variant was not evaluated.");
      continue;
    }
    if (spec.key == "sort_by_geodesic" && bundle.skinning_sorted.is_empty()) {
      result.notes.push_back(std::string("Table 4: ") + kSkinningSortedCheckpoint +
                             " is not in the model folder; the sort-by-G variant was not evaluated.");
      continue;
    }
    methods.push_back(spec);
  }

  auto readers = open_shards(shards);
  check_bundle_skeleton(bundle, readers.front()->joint_names(), shards.front());
  const std::vector<EvalClip> clips = held_out_clips(readers, options.max_clips, options.artist_style);
  AMT_CHECK(!clips.empty(), shards.front(), (shards.size() > 1 ? " (and the other shards)" : ""),
            ": no held-out clips (expected clips of test characters, or test clips of train characters)");
  const int64_t J = bundle.num_joints();
  double inertia = 0.0;
  if (std::any_of(methods.begin(), methods.end(),
                  [](const MethodSpec& m) { return m.source == ApparelSource::kInertial; })) {
    std::tie(inertia, result.inertia_clips) = fit_inertia(readers, J, bundle.apparel_anchor());
    result.inertia = inertia;
    result.notes.push_back("inertial rule: inertia " + std::to_string(inertia) + ", least-squares fitted on " +
                           std::to_string(result.inertia_clips) + " training clips (InertiaFit).");
  }
  result.notes.push_back("apparel anchor: " + bundle.apparel_anchor() +
                         (bundle.apparel_anchor() == "attachment"
                              ? " (each apparel vertex skinned with the weights of the body vertex its piece "
                                "attaches at)"
                              : " (each apparel vertex skinned with the weights of its nearest body vertex)") +
                         "; the zero-network rules use the same anchors.");
  // "body_apparel" is the full model without its refiner: the same bind, B̂ and Â (the apparel history
  // holds Â, not the refined V̂). When both run, the full model's steps also give body_apparel's
  // frames, tile(Â, B̂), which is what a body_apparel stepper returns, at the cost of one model run.
  const auto spec_of = [&](const std::string& key) -> const MethodSpec* {
    for (const MethodSpec& m : methods)
      if (m.key == key) return &m;
    return nullptr;
  };
  const MethodSpec* full_spec = spec_of("full");
  const MethodSpec* tiled_spec = spec_of("body_apparel");
  const bool tiled_from_full = full_spec && tiled_spec && full_spec->bind == tiled_spec->bind &&
                               full_spec->stages == PipelineStages::kFull &&
                               tiled_spec->stages == PipelineStages::kBodyApparel;
  // Per character: skinning, the full model, and the apparel module on the ground-truth mask and weights (the
  // path of a character with a rig, `amt animate --apparel-mask auto`), so the worst character can be judged on both.
  const auto per_character = [](const std::string& key) {
    return key == "skinning_baseline" || key == "full" || key == "apparel_gt";
  };

  Accumulators acc;
  CharacterCaches characters;
  characters.artist_style = options.artist_style_options;
  characters.rig_handles = options.rig_handles;
  int short_clips = 0;
  std::set<std::pair<int, std::string>> scored, fitted_characters;
  for (const EvalClip& clip : clips) scored.insert({clip.shard, clip.info.name});
  Progress progress(options.progress, static_cast<int>(clips.size()), "clips");
  progress.update(0);
  for (size_t k = 0; k < clips.size(); ++k) {
    const EvalClip& clip = clips[k];
    const DatasetReader& reader = *readers[clip.shard];
    CharacterCache& c = characters.of(reader, clip, options.penetration);
    acc.clip = clip.info.name;
    acc.shard = clip.shard;
    ++result.clips[clip.subset];
    const int64_t T = clip.info.num_frames, N = static_cast<int64_t>(c.mask.size());
    const at::Tensor motion = transforms_tensor(reader.read_joint_transforms(clip.info.name, 0, T), T, J);
    const MatrixX3f gt_all = c.ground_truth(reader, clip.info.name, 0, static_cast<int>(T));
    const at::Tensor gt_tensor = float_tensor(gt_all.data(), {T, N, 3});
    std::vector<MatrixX3f> gt(static_cast<size_t>(T));  // gt[t] (N, 3)
    for (int64_t t = 0; t < T; ++t) gt[t] = frame_of(gt_all, t, N);
    const std::vector<MatrixX3f> skinned = skinned_frames(c, motion);
    if (options.paper && T < options.window) ++short_clips;
    // The frames that the paper protocol predicts (each once): windows at a stride of window - 3.
    const bool paper = options.paper && T >= options.window;
    const std::vector<uint8_t> paper_frame = paper_frames(T, options);

    for (const MethodSpec& m : methods) {
      if (tiled_from_full && m.key == tiled_spec->key) continue;  // scored from the full model's steps
      auto bound = c.binds.find(m.bind);
      if (bound == c.binds.end())
        bound = c.binds
                    .emplace(m.bind, bind_character(bundle, c.V, c.F, c.joints,
                                                    bind_options_for(m.bind, c, options.calibrate_swing)))
                    .first;
      const bool fit = options.calibrate_swing && options.fit_swing && m.stages != PipelineStages::kBodyOnly &&
                       m.source == ApparelSource::kNetwork && bundle.local_apparel() && bound->second.num_apparel() > 0;
      const std::vector<std::string> calibration =
          fit ? calibration_clips(c, reader, clip.shard, clip.info.name, scored) : std::vector<std::string>{};
      if (!calibration.empty()) fitted_characters.insert({clip.shard, c.name});
      const BoundCharacter& b = bound->second;
      // The bind each protocol scores: with the swing fitted under that protocol, or as bound.
      const auto scored_bind = [&](int64_t window) -> const BoundCharacter& {
        return calibration.empty()
                   ? b
                   : fitted_bind(bundle, c, reader, m.bind, b, calibration, window, options.strain_limit, J);
      };
      if (m.bind == "predicted" && !c.segmentation) {
        c.segmentation = segmentation_scores(b.apparel_prob, c.gt_mask);
        if (!c.remake) c.bare_apparel_share = bare_body_apparel_share(bundle, c);
        score_open_parts(bundle, c);
      }

      if (m.stages == PipelineStages::kBodyOnly) {
        // Body only: frame t is LBS of motion[t] whatever the apparel history, so the paper protocol's
        // frames are the rollout's (and need no lead-in): each is predicted and measured once for both.
        std::optional<ClipScorer> paper_scorer, rollout_scorer;
        if (paper) paper_scorer.emplace(acc, c, m.key, kPaper, per_character(m.key));
        if (options.rollout) rollout_scorer.emplace(acc, c, m.key, kRollout, per_character(m.key));
        PipelineStepper stepper(bundle, b, rest_apparel_history(b), m.stages);
        for (int64_t t = 0; t < T; ++t) {
          if (!rollout_scorer && !paper_frame[t]) continue;
          const PredictedFrame frame = predicted_frame(c, to_matrix(stepper.step(motion[t])));
          if (paper_frame[t]) {
            const double pmd_a = paper_scorer->add(frame, gt[t], skinned[t]);
            const int64_t window_start = (t - kHistory) / (options.window - kHistory) * (options.window - kHistory);
            add_to_curve(acc.horizons[{c.subset, m.key}], t - window_start - kHistory, pmd_a);
          }
          if (rollout_scorer)
            add_to_curve(acc.curves[{c.subset, m.key}], t, rollout_scorer->add(frame, gt[t], skinned[t]));
        }
        continue;
      }

      // Scores one step of `stepper`: the method's frame and, from the full model's steps, body_apparel's.
      const bool with_tiled = tiled_from_full && m.key == full_spec->key;
      const auto score_step = [&](PipelineStepper& stepper, int64_t t, ClipScorer& scorer, ClipScorer* tiled) {
        const StepOutput out = stepper.step_detailed(motion[t]);
        const double pmd_a = scorer.add(predicted_frame(c, to_matrix(out.V_hat)), gt[t], skinned[t]);
        if (tiled) {
          // tile(Â, B̂): the bound index lists partition the mesh.
          c10::InferenceMode inference;
          at::Tensor tiled_V = at::empty({N, 3}, at::kFloat);
          tiled_V.index_copy_(0, b.apparel_ids, out.A_hat).index_copy_(0, b.body_ids, out.B_hat);
          return std::make_pair(pmd_a, tiled->add(predicted_frame(c, to_matrix(tiled_V)), gt[t], skinned[t]));
        }
        return std::make_pair(pmd_a, 0.0);
      };
      if (paper) {
        const at::Tensor gt_apparel = gt_tensor.index_select(1, b.apparel_ids);  // (T, N_a, 3)
        ClipScorer scorer(acc, c, m.key, kPaper, per_character(m.key));
        std::optional<ClipScorer> tiled;
        if (with_tiled) tiled.emplace(acc, c, tiled_spec->key, kPaper, per_character(tiled_spec->key));
        PipelineStepper stepper(bundle, scored_bind(options.window), gt_apparel.narrow(0, 0, kHistory), m.stages,
                                m.source, inertia);
        stepper.set_strain_limit(options.strain_limit);
        for (int64_t s = 0; s + options.window <= T; s += options.window - kHistory) {
          stepper.reset(gt_apparel.narrow(0, s, kHistory), motion.narrow(0, s, kHistory));
          for (int64_t t = s + kHistory; t < s + options.window; ++t) {
            const auto [pmd_a, tiled_pmd_a] = score_step(stepper, t, scorer, tiled ? &*tiled : nullptr);
            add_to_curve(acc.horizons[{c.subset, m.key}], t - s - kHistory, pmd_a);
            if (tiled) add_to_curve(acc.horizons[{c.subset, tiled_spec->key}], t - s - kHistory, tiled_pmd_a);
          }
        }
      }
      if (options.rollout) {
        ClipScorer scorer(acc, c, m.key, kRollout, per_character(m.key));
        std::optional<ClipScorer> tiled;
        if (with_tiled) tiled.emplace(acc, c, tiled_spec->key, kRollout, per_character(tiled_spec->key));
        PipelineStepper stepper(bundle, scored_bind(0), rest_apparel_history(b), m.stages, m.source, inertia);
        stepper.set_strain_limit(options.strain_limit);
        const at::Tensor lead_in = motion_lead_in(motion[0], c.joints, kDefaultLeadInFrames);
        for (int64_t t = 0; t < lead_in.size(0); ++t) stepper.step(lead_in[t]);
        Curve& curve = acc.curves[{c.subset, m.key}];
        Curve* tiled_curve = with_tiled ? &acc.curves[{c.subset, tiled_spec->key}] : nullptr;
        for (int64_t t = 0; t < T; ++t) {
          const auto [pmd_a, tiled_pmd_a] = score_step(stepper, t, scorer, tiled ? &*tiled : nullptr);
          add_to_curve(curve, t, pmd_a);
          if (tiled_curve) add_to_curve(*tiled_curve, t, tiled_pmd_a);
        }
      }
    }
    progress.update(static_cast<int>(k + 1));
  }
  if (!fitted_characters.empty())
    result.notes.push_back(
        "apparel swing: fitted on other clips of each character (the first " + std::to_string(kSwingCalibrationClips) +
        " in file order that are not scored, else the first others; their first " +
        std::to_string(static_cast<int>(kSwingCalibrationSeconds)) +
        " s, pooled, under the protocol scored: from rest for rollouts, in windows from its ground truth for the "
        "paper protocol), as `amt animate` fits it on its calibration motions, for " +
        std::to_string(fitted_characters.size()) +
        " character(s) (--swing-calibration on; probe: from the rig's "
        "response only).");
  if (short_clips > 0)
    result.notes.push_back(std::to_string(short_clips) + " clip(s) shorter than the " + std::to_string(options.window) +
                           "-frame window were left out of the paper protocol.");
  const int retargeted = score_cloth_retargeting(readers, clips, options, J,
                                                 options.methods.empty() ? all : options.methods, acc, characters);
  if (retargeted > 0)
    result.notes.push_back("cloth_retarget: " + std::to_string(retargeted) +
                           " held-out clip(s) are the target of a garment pair (same apparel connectivity, same "
                           "motion); their apparel was retargeted from the pair's other body and scored against "
                           "their own simulation.");
  finish(result, acc, characters.loaded);
  // Only the curves of the rollout methods that matter for the plot: keep all, the report picks.
  result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return result;
}

EvaluationResult evaluate_predictions(const std::vector<std::string>& shards, const std::string& predictions,
                                      const EvaluateOptions& options) {
  const auto start = Clock::now();
  AMT_CHECK(!options.artist_style, predictions,
            ": artist style: expected a model to run on the remade characters, "
            "found a predictions file (its vertices are the characters' as built)");
  std::error_code error;
  AMT_CHECK(fs::is_regular_file(predictions, error), predictions,
            ": no such predictions file (expected an amt-dataset file, e.g. from amt animate --out x.h5)");
  EvaluationResult result;
  result.shards = shards;
  result.predictions = predictions;
  result.options = options;
  auto readers = open_shards(shards);
  const DatasetReader predicted(predictions);
  AMT_CHECK(options.ground_truth_as_predictions || !predicted.predictions().empty(), predictions, ": attribute '",
            kPredictionsAttribute,
            "': missing: the file holds ground truth, which would score as perfect (expected predictions, e.g. "
            "from amt animate --out x.h5; --ground-truth-as-predictions scores it anyway)");
  AMT_CHECK(predicted.joint_names() == readers.front()->joint_names(), predictions, ": skeleton: expected the ",
            readers.front()->joint_names().size(), " joints of ", shards.front(), ", found ",
            predicted.joint_names().size(), " different ones");
  std::vector<EvalClip> clips;
  for (EvalClip& clip : held_out_clips(readers, 0))
    if (predicted.has_clip(clip.info.name)) clips.push_back(std::move(clip));
  if (options.max_clips > 0 && static_cast<int>(clips.size()) > options.max_clips) clips.resize(options.max_clips);
  AMT_CHECK(!clips.empty(), predictions, ": no clip in common with the held-out clips of ", shards.front(),
            " (expected clips of the same names)");

  Accumulators acc;
  CharacterCaches characters;
  // Per predicted character: rest_vertex_match, empty when its vertices are in the ground truth's order.
  std::map<std::string, std::vector<int32_t>> matches;
  Progress progress(options.progress, static_cast<int>(clips.size()), "clips");
  for (size_t k = 0; k < clips.size(); ++k) {
    const EvalClip& clip = clips[k];
    const DatasetReader& reader = *readers[clip.shard];
    CharacterCache& c = characters.of(reader, clip, options.penetration);
    const ClipInfo p = predicted.clip_info(clip.info.name);
    const int64_t T = clip.info.num_frames, N = static_cast<int64_t>(c.mask.size());
    AMT_CHECK(p.num_frames == T, predictions, ": /clips/", p.name, ": frames: expected ", T,
              " (the ground truth's), found ", p.num_frames);
    const CharacterSummary summary = predicted.character_summary(p.character);
    AMT_CHECK(summary.num_vertices == N, predictions, ": /characters/", p.character, ": vertices: expected ", N,
              " (the ground truth's ", clip.info.character, "), found ", summary.num_vertices);
    ++result.clips[clip.subset];
    acc.clip = clip.info.name;
    acc.shard = clip.shard;
    auto match = matches.find(p.character);
    if (match == matches.end()) {
      std::vector<int32_t> rows = rest_vertex_match(c.mesh.V, predicted.read_character(p.character).mesh.V);
      AMT_CHECK(!rows.empty(), predictions, ": /characters/", p.character,
                ": rest_vertices: expected the rest mesh of the ground truth's ", clip.info.character,
                " (its vertices, in any order), found other positions");
      bool identity = true;
      for (size_t i = 0; i < rows.size(); ++i) identity = identity && rows[i] == int32_t(i);
      if (identity) {
        rows.clear();
      } else {
        std::fprintf(stderr,
                     "eval: %s: /characters/%s: vertices in another order than %s's, matched by rest position\n",
                     predictions.c_str(), p.character.c_str(), clip.info.character.c_str());
      }
      match = matches.emplace(p.character, std::move(rows)).first;
    }
    const MatrixX3f gt_all = reader.read_vertices(clip.info.name, 0, static_cast<int>(T));
    MatrixX3f pred_all = predicted.read_vertices(p.name, 0, static_cast<int>(T));
    if (!match->second.empty()) {
      const MatrixX3f stored = pred_all;
      for (int64_t t = 0; t < T; ++t)
        for (int64_t i = 0; i < N; ++i) pred_all.row(t * N + i) = stored.row(t * N + match->second[size_t(i)]);
    }
    const int64_t J = static_cast<int64_t>(reader.joint_names().size());
    at::Tensor skinned_all;
    {
      c10::InferenceMode inference;
      const at::Tensor motion = transforms_tensor(reader.read_joint_transforms(clip.info.name, 0, T), T, J);
      skinned_all = linear_blend_skinning(c.V, c.gt_weights, motion, c.joints).contiguous();
    }
    ClipScorer scorer(acc, c, "predictions", "file", true);
    Curve& curve = acc.curves[{c.subset, "predictions"}];
    for (int64_t t = 0; t < T; ++t)
      add_to_curve(
          curve, t,
          scorer.add(predicted_frame(c, frame_of(pred_all, t, N)), frame_of(gt_all, t, N), to_matrix(skinned_all[t])));
    progress.update(static_cast<int>(k + 1));
  }
  finish(result, acc, characters.loaded);
  result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return result;
}

// === JSON

std::string evaluation_json(const EvaluationResult& result) {
  using Json = nlohmann::json;
  const auto number = [](double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); };
  const auto scores = [&](const MotionScores& s) {
    return Json{{"pmd_cm", number(s.pmd)},
                {"pmd_a_cm", number(s.pmd_a)},
                {"pmd_b_cm", number(s.pmd_b)},
                {"els", number(s.els)},
                {"penetration_share", number(s.penetration_share)},
                {"penetration_depth_cm", number(s.penetration_depth_cm)},
                {"clips", s.clips},
                {"frames", s.frames}};
  };
  const auto seg = [&](const SegmentationScores& s) {
    return Json{
        {"iou", number(s.iou)}, {"f1", number(s.f1)}, {"precision", number(s.precision)}, {"recall", number(s.recall)}};
  };
  const auto separation = [&](const SeparationScores& s) {
    return Json{{"tearing", number(s.tearing)},
                {"rest_tearing", number(s.rest_tearing)},
                {"ground_truth_rest_tearing", number(s.ground_truth_rest_tearing)},
                {"tearing_ground_truth_deformed", number(s.tearing_ground_truth_deformed)},
                {"seam_gap_p95_cm", number(s.seam_gap_p95_cm)},
                {"seam_gap_max_cm", number(s.seam_gap_max_cm)},
                {"apparel_els", number(s.apparel_els)},
                {"coincident_pairs", s.pairs},
                {"apparel_edge_frames", s.edge_frames},
                {"pair_frames", s.pair_frames}};
  };
  const auto bare_share = [&](const std::string& subset) {
    const auto it = result.bare_apparel_share.find(subset);
    return it == result.bare_apparel_share.end() ? Json(nullptr) : number(it->second);
  };
  Json j;
  j["format"] = "amt-eval";
  j["version"] = 1;
  j["shards"] = result.shards;
  j["model"] = result.model_dir;
  if (!result.predictions.empty()) j["predictions"] = result.predictions;
  j["options"] = {{"paper", result.options.paper},
                  {"rollout", result.options.rollout},
                  {"window", result.options.window},
                  {"max_clips", result.options.max_clips},
                  {"penetration", result.options.penetration},
                  {"lead_in_frames", kDefaultLeadInFrames},
                  {"artist_style", result.options.artist_style},
                  {"rig_handles", result.options.rig_handles},
                  {"swing_calibration", !result.options.calibrate_swing ? "off"
                                        : result.options.fit_swing      ? "on"
                                                                        : "probe"}};
  if (result.options.artist_style) {
    const ArtistStyleOptions& a = result.options.artist_style_options;
    j["artist_style"] = {{"subset", kHeldOutArtistStyle},
                         {"seed", a.seed},
                         {"target_vertices", a.target_vertices},
                         {"island_faces", a.island_faces},
                         {"strip_width_m", a.strip_width},
                         {"panel_width_m", a.panel_width},
                         {"reverse_offset_m", {a.back_offset_min, a.back_offset_max}},
                         {"layer_share", a.layer_share},
                         {"layer_offset_m", {a.layer_offset_min, a.layer_offset_max}}};
  }
  j["seconds"] = result.seconds;
  j["clips"] = result.clips;
  Json rows = Json::array();
  for (const MethodScores& r : result.rows) {
    Json row = scores(r.scores);
    row["method"] = r.method;
    row["protocol"] = r.protocol;
    row["subset"] = r.subset;
    row["dynamics_amplitude"] = number(r.amplitude);
    Json falling = separation(r.separation);
    const auto worst = [&](double v, const std::string& c) { return Json{{"value", number(v)}, {"character", c}}; };
    falling["worst"] = {{"tearing", worst(r.worst.tearing, r.worst_tearing)},
                        {"seam_gap_p95_cm", worst(r.worst.seam_gap_p95_cm, r.worst_seam_gap_p95)},
                        {"seam_gap_max_cm", worst(r.worst.seam_gap_max_cm, r.worst_seam_gap_max)},
                        {"apparel_els", worst(r.worst.apparel_els, r.worst_apparel_els)}};
    row["falling_apart"] = falling;
    rows.push_back(row);
  }
  j["rows"] = rows;
  Json segmentation = Json::object();
  for (const auto& [subset, s] : result.segmentation) {
    segmentation[subset] = seg(s);
    segmentation[subset]["bare_body_apparel_share"] = bare_share(subset);
    const auto open = result.open_parts.find(subset);
    if (open != result.open_parts.end()) {
      segmentation[subset]["open_parts_iou"] = number(open->second.first);
      segmentation[subset]["bare_open_parts_apparel_share"] = number(open->second.second);
    }
  }
  j["segmentation"] = segmentation;
  Json characters = Json::array();
  for (const CharacterScores& c : result.characters) {
    Json cj{{"character", c.character},
            {"subset", c.subset},
            {"vertices", c.num_vertices},
            {"apparel_vertices", c.num_apparel},
            {"segmentation", seg(c.segmentation)},
            {"bare_body_apparel_share", number(c.bare_apparel_share)},
            {"open_parts_iou", number(c.open_parts_iou)},
            {"bare_open_parts_apparel_share", number(c.bare_open_parts_share)}};
    Json methods = Json::object();
    for (const auto& [method, protocols] : c.scores)
      for (const auto& [protocol, s] : protocols) methods[method][protocol] = scores(s);
    cj["scores"] = methods;
    Json falling = Json::object();
    for (const auto& [method, protocols] : c.separation)
      for (const auto& [protocol, s] : protocols) falling[method][protocol] = separation(s);
    cj["falling_apart"] = falling;
    cj["artist_style"] = c.artist_style;
    cj["construction"] = {{"vertices", c.construction.vertices},
                          {"faces", c.construction.faces},
                          {"parts", c.construction.parts},
                          {"welded_parts", c.construction.welded_parts},
                          {"coincident_share", number(c.construction.coincident_share)}};
    characters.push_back(cj);
  }
  j["characters"] = characters;
  Json curves = Json::array();
  for (const RolloutCurve& c : result.curves) {
    Json values = Json::array();
    for (double v : c.pmd_a) values.push_back(number(v));
    Json at_frames = Json::object();
    for (int f : result.options.rollout_frames)
      if (f >= 1 && f <= static_cast<int>(c.pmd_a.size())) at_frames[std::to_string(f)] = number(c.pmd_a[f - 1]);
    curves.push_back({{"subset", c.subset},
                      {"method", c.method},
                      {"pmd_a_cm", values},
                      {"clips", c.clips},
                      {"pmd_a_cm_at_frame", at_frames}});
  }
  j["rollout_curves"] = curves;
  Json horizons = Json::array();
  for (const RolloutCurve& c : result.horizons) {
    Json values = Json::array();
    for (double v : c.pmd_a) values.push_back(number(v));
    horizons.push_back({{"subset", c.subset}, {"method", c.method}, {"pmd_a_cm", values}, {"clips", c.clips}});
  }
  j["paper_horizons"] = horizons;
  if (result.inertia_clips > 0) j["inertia"] = {{"value", result.inertia}, {"clips", result.inertia_clips}};
  if (!result.runtime.empty()) {
    Json runtime = Json::array();
    for (const RuntimeFigures& r : result.runtime) {
      Json threads = Json::array();
      for (const RuntimeThreadFigures& t : r.per_thread)
        threads.push_back({{"threads", t.threads},
                           {"median_ms", number(t.median_ms)},
                           {"p95_ms", number(t.p95_ms)},
                           {"model_ms", number(t.model_ms)},
                           {"lbs_ms", number(t.lbs_ms)},
                           {"apparel_ms", number(t.apparel_ms)},
                           {"refiner_ms", number(t.refiner_ms)},
                           {"penetration_ms", number(t.penetration_ms)},
                           {"output_ms", number(t.output_ms)},
                           {"inside_before", number(t.inside_before)},
                           {"inside_after", number(t.inside_after)},
                           {"carried_share", number(t.carried_share)},
                           {"resident_mb", number(t.resident_mb)},
                           {"reference_apparel_ms", number(t.reference_apparel_ms)}});
      runtime.push_back({{"label", r.label},
                         {"character", r.character},
                         {"mask", r.mask},
                         {"vertices", r.vertices},
                         {"faces", r.faces},
                         {"repeats", r.repeats},
                         {"apparel_vertices", r.apparel_vertices},
                         {"true_apparel_vertices", r.true_apparel_vertices},
                         {"bind_seconds", number(r.bind_seconds)},
                         {"peak_resident_mb", number(r.peak_resident_mb)},
                         {"per_thread", threads},
                         {"target_ms", r.target_ms},
                         {"target_threads", r.target_threads},
                         {"target_bind_seconds", r.target_bind_seconds},
                         {"target_apparel_reference_ratio", r.target_apparel_reference_ratio}});
    }
    j["runtime"] = runtime;
  }
  j["notes"] = result.notes;
  return j.dump(2) + "\n";
}

// === Clips to look at

std::vector<ViewerPick> viewer_picks(const EvaluationResult& result) {
  const bool rollout = std::any_of(result.clip_scores.begin(), result.clip_scores.end(),
                                   [](const ClipScore& s) { return s.method == "full" && s.protocol == kRollout; });
  const std::string protocol = rollout ? kRollout : kPaper;
  std::map<std::string, std::vector<ClipScore>> by_subset;
  for (const ClipScore& s : result.clip_scores)
    if (s.method == "full" && s.protocol == protocol && std::isfinite(s.pmd_a)) by_subset[s.subset].push_back(s);
  std::vector<ViewerPick> picks;
  for (auto& [subset, scores] : by_subset) {
    std::stable_sort(scores.begin(), scores.end(),
                     [](const ClipScore& a, const ClipScore& b) { return a.pmd_a > b.pmd_a; });
    const size_t n = scores.size();
    const std::pair<size_t, const char*> chosen[] = {{0, "worst"}, {n / 2, "median"}, {n - 1, "best"}};
    std::vector<size_t> taken;
    for (const auto& [k, name] : chosen) {
      if (std::find(taken.begin(), taken.end(), k) != taken.end()) continue;
      taken.push_back(k);
      picks.push_back({scores[k], name});
    }
  }
  return picks;
}

ViewedClip view_clip(const ModelBundle& bundle, const EvaluationResult& result, const ViewerPick& pick,
                     int max_frames) {
  const ClipScore& s = pick.score;
  AMT_CHECK(s.shard >= 0 && size_t(s.shard) < result.shards.size(), "eval: viewer: shard ", s.shard,
            ": expected one of the ", result.shards.size(), " evaluated shards");
  const DatasetReader reader(result.shards[size_t(s.shard)]);
  const ClipInfo info = reader.clip_info(s.clip);
  const std::unique_ptr<CharacterCache> c =
      load_character(reader, info.character, s.subset, false, result.options.artist_style_options);
  const int64_t T = max_frames > 0 ? std::min<int64_t>(max_frames, info.num_frames) : info.num_frames;
  const int64_t N = static_cast<int64_t>(c->mask.size()), J = bundle.num_joints();
  ViewedClip v;
  v.F = c->mesh.F;
  v.mask = c->mask;
  v.fps = info.fps;
  const at::Tensor motion = transforms_tensor(reader.read_joint_transforms(s.clip, 0, int(T)), T, J);
  const MatrixX3f gt_all = c->ground_truth(reader, s.clip, 0, static_cast<int>(T));
  for (int64_t t = 0; t < T; ++t) v.ground_truth.push_back(frame_of(gt_all, t, N));
  c10::InferenceMode inference;
  const at::Tensor skinned = linear_blend_skinning(c->V, c->gt_weights, motion, c->joints).contiguous();
  for (int64_t t = 0; t < T; ++t) v.skinning.push_back(to_matrix(skinned[t]));
  // The full model's rollout, as evaluate_model runs it.
  const BoundCharacter b =
      bind_character(bundle, c->V, c->F, c->joints, bind_options_for("predicted", *c, result.options.calibrate_swing));
  PipelineStepper stepper(bundle, b, rest_apparel_history(b), PipelineStages::kFull, ApparelSource::kNetwork, 0.0);
  stepper.set_strain_limit(result.options.strain_limit);
  const at::Tensor lead_in = motion_lead_in(motion[0], c->joints, kDefaultLeadInFrames);
  for (int64_t t = 0; t < lead_in.size(0); ++t) stepper.step(lead_in[t]);
  for (int64_t t = 0; t < T; ++t) v.prediction.push_back(to_matrix(stepper.step(motion[t])));
  return v;
}

}  // namespace amt
