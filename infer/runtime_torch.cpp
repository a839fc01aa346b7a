#include "infer/runtime_torch.h"

#include "data_tools/formats/atomic_file.h"

#include <ATen/ATen.h>
#include <c10/core/InferenceMode.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>

#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/render.h"
#include "data_tools/formats/viewer_folder.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/motion.h"
#include "infer/pmx_physics_player.h"

namespace amt {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::vector<uint8_t> mask_vector(const at::Tensor& mask) {
  const at::Tensor m = mask.to(at::kByte).contiguous();
  return std::vector<uint8_t>(m.data_ptr<uint8_t>(), m.data_ptr<uint8_t>() + m.numel());
}

// The spacing of the handles a skinned output picks when the apparel path has none of its own (metres): the
// shipped module's.
constexpr double kOutputHandleSpacing = 0.04;

// The rig of a skinned .glb output (infer/frame_writer.h) for mesh V (N by 3) with apparel `mask` and body weights
// `weights` (N by J, rows summing to 1): handles picked along the apparel as the apparel module picks them
// (apparel_rig on the linked topology) kOutputHandleSpacing apart, whatever moved the apparel; each hangs from the
// joint its vertex weighs most. Measured (docs/runtime.md, "Skinned output"): on Godette these handles carry the
// spring bones' frames to 0.08 cm at p95 where the rig's own 16 spring bones, merged into 8 handles, left 0.58 cm,
// and the learned module's 2 cm handles would make a file 3 times larger for 0.14 against 0.32 cm.
std::shared_ptr<const OutputSkin> output_skin(const TriMesh& mesh, const std::vector<uint8_t>& mask,
                                              const MatrixXfR& weights) {
  c10::InferenceMode inference;
  const int64_t N = mesh.num_vertices();
  AMT_CHECK(int64_t(mask.size()) == N && weights.rows() == N, "skinned output: expected a mask and weights of ", N,
            " vertices, found ", mask.size(), " and ", weights.rows());
  auto skin = std::make_shared<OutputSkin>();
  skin->body = sparsify_weights(weights);
  std::vector<int64_t> apparel, body;
  for (int64_t v = 0; v < N; ++v) (mask[size_t(v)] ? apparel : body).push_back(v);
  if (apparel.empty()) return skin;
  const at::Tensor V = at::from_blob(const_cast<float*>(mesh.V.data()), {N, 3}, at::kFloat).clone();
  const at::Tensor apparel_ids = at::tensor(apparel, at::kLong), body_ids = at::tensor(body, at::kLong);
  const LinkedTopology topology = linked_topology(mesh.V, mesh.F, mask);
  const at::Tensor edges =
      at::from_blob(const_cast<int32_t*>(topology.edges.data()), {topology.edges.rows(), 2}, at::kInt).to(at::kLong);
  const ApparelRig handles = apparel_rig(V, edges, apparel_ids, body_ids, handle_options(kOutputHandleSpacing));
  const at::Tensor rows = handles.rows.to(at::kLong).contiguous();
  const at::Tensor vh = handles.vertex_handles.to(at::kInt).contiguous();
  const at::Tensor vw = handles.vertex_weights.to(at::kFloat).contiguous();
  const int64_t Na = int64_t(apparel.size()), H = rows.size(0), K = vh.size(1);
  AMT_CHECK(vh.size(0) == Na && vw.size(0) == Na, "skinned output: expected handles of ", Na,
            " apparel vertices, found ", vh.size(0));
  HandleSkin& a = skin->apparel;
  a.vertices.assign(apparel.begin(), apparel.end());
  a.handles = Eigen::Map<const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      vh.data_ptr<int32_t>(), Na, K);
  a.weights = Eigen::Map<const MatrixXfR>(vw.data_ptr<float>(), Na, K);
  a.rest.resize(H, 3);
  skin->handle_parents.resize(size_t(H));
  for (int64_t h = 0; h < H; ++h) {
    const int64_t v = apparel[size_t(rows.data_ptr<int64_t>()[h])];
    a.rest.row(h) = mesh.V.row(v);
    Eigen::Index j = 0;
    if (weights.row(v).maxCoeff(&j) <= 0) j = 0;
    skin->handle_parents[size_t(h)] = int32_t(j);
  }
  return skin;
}

}  // namespace

// === Per-frame session

at::Tensor transforms_tensor(const Transforms& transforms) {
  at::Tensor t = at::empty({int64_t(transforms.size()), 3, 4}, at::kFloat);
  float* p = t.data_ptr<float>();
  for (size_t j = 0; j < transforms.size(); ++j) std::memcpy(p + 12 * j, transforms[j].data(), 12 * sizeof(float));
  return t;
}

RuntimeSession::RuntimeSession(const ModelBundle& bundle, BoundCharacter bound, const MatrixX3i& F, bool resolve,
                               PenetrationOptions penetration, bool refine, float strain_limit)
    : bundle_(bundle),
      bound_(std::move(bound)),
      mask_(mask_vector(bound_.apparel_mask)),
      resolver_(F, mask_, penetration),
      resolve_(resolve),
      refine_(refine) {
  stepper_ = std::make_unique<PipelineStepper>(bundle_, bound_, rest_apparel_history(bound_),
                                               refine ? PipelineStages::kFull : PipelineStages::kBodyApparel);
  stepper_->set_strain_limit(strain_limit);
  c10::InferenceMode inference;
  const at::Tensor extent = std::get<0>(bound_.V.max(0)) - std::get<0>(bound_.V.min(0));
  output_bound_ = 10.0f * std::max(extent.norm().item<float>(), 0.1f);
  const at::Tensor root = bound_.joints[0].contiguous();
  root_rest_ = Eigen::Vector3f(root[0].item<float>(), root[1].item<float>(), root[2].item<float>());
  // The apparel on handles is pushed out of the body through them, as a piece (PenetrationResolver::set_rig).
  if (bound_.handle_rows.defined() && bound_.handle_vertex_handles.defined()) {
    const at::Tensor h = bound_.handle_vertex_handles.to(at::kInt).contiguous();
    const at::Tensor w = bound_.handle_vertex_weights.to(at::kFloat).contiguous();
    using Handles = Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    resolver_.set_rig(Eigen::Map<const Handles>(h.data_ptr<int32_t>(), h.size(0), h.size(1)),
                      Eigen::Map<const MatrixXfR>(w.data_ptr<float>(), w.size(0), w.size(1)),
                      int(bound_.handle_rows.size(0)));
  }
  // The resolver's body tree and its exposed faces on the rest pose, before the first frame.
  const at::Tensor rest = bound_.V.to(at::kFloat).contiguous();
  resolver_.prepare(Eigen::Map<const MatrixX3f>(rest.data_ptr<float>(), rest.size(0), 3));
}

void RuntimeSession::advance(const at::Tensor& joint_transforms) {
  stepper_->step(joint_transforms);
}

namespace {

// What the apparel module reads as the character's own physics (AnimateSummary::physics_source): the rig's bones'
// response averaged over the apparel, or unknown.
std::string physics_source(const ApparelBones* bones, const BoundCharacter& bound) {
  if (!bound.apparel_response.defined() || !bones || bones->response.rows() == 0)
    return "unknown (no rig whose physics amt can simulate: a PMX model's rigid bodies, a VRM avatar's spring bones, "
           "a dataset's rig); the module's physics inputs are zeros";
  int simulated = 0;
  for (Eigen::Index b = 0; b < bones->response.rows(); ++b) simulated += bones->response(b, 0) > 0;
  const at::Tensor mean = bound.apparel_response.mean(0);
  char text[200];
  std::snprintf(text, sizeof(text),
                "the rig's response to a probe sway (%d of its %d apparel bones simulated; over the apparel: %.0f %% "
                "of the weight on them, swing %.2f during the sway and %.2f after it)",
                simulated, bones->num_bones(), 100.0 * mean[0].item<double>(), mean[1].item<double>(),
                mean[2].item<double>());
  return text;
}

// How far the learned apparel swings (AnimateSummary::swing_source).
std::string swing_source(const BoundCharacter& bound, const std::string& calibration, double reference) {
  if (calibration == "off") return "as trained (--swing-calibration off)";
  if (reference <= 0)
    return "as trained (--swing-calibration auto: the apparel module does not know the least lively apparel it "
           "trained on; amt train swing_reference stores it)";
  if (bound.num_apparel() == 0) return "as trained (no apparel)";
  if (!bound.apparel_swing_gain.defined())
    return "as trained (--swing-calibration auto: the character's physics is unknown; calibrated on a PMX model's "
           "rigid bodies, a VRM avatar's spring bones or a dataset's rig)";
  const at::Tensor g = bound.apparel_swing_gain.to(at::kFloat);
  const at::Tensor calmed = g.lt(0.999f);
  char text[240];
  std::snprintf(text, sizeof(text),
                "calibrated on the rig's own physics (--swing-calibration auto): %.0f %% of the apparel calmed, gain "
                "median %.2f, lowest %.2f",
                100.0 * calmed.to(at::kFloat).mean().item<double>(), g.median().item<double>(), g.min().item<double>());
  return text;
}

// The first row of `P` (n, 3) that is non-finite or farther than `bound` from `root`, or -1.
int64_t first_exploded(const float* P, int64_t n, const Eigen::Vector3f& root, float bound) {
  for (int64_t i = 0; i < n; ++i) {
    const Eigen::Vector3f p(P[3 * i], P[3 * i + 1], P[3 * i + 2]);
    if (!p.allFinite() || (p - root).norm() > bound) return i;
  }
  return -1;
}

}  // namespace

namespace {

// Throws naming frame `frame`, `stage` and the first row of P (n, 3) that is non-finite or farther than `bound` from
// `root`.
void check_rows(const float* P, int64_t n, const Eigen::Vector3f& root, float bound, int64_t frame, const char* stage) {
  const int64_t i = first_exploded(P, n, root, bound);
  if (i < 0) return;
  fail("frame ", frame, ": ", stage, ": expected finite positions within ", bound,
       " m of the root joint (10 rest sizes), found ", P[3 * i], " ", P[3 * i + 1], " ", P[3 * i + 2], " at vertex ", i,
       " (a damaged model or an absurd motion; nothing was written)");
}

}  // namespace

void check_frame_output(const MatrixX3f& V, const Eigen::Vector3f& root, float bound, int64_t frame,
                        const char* stage) {
  check_rows(V.data(), V.rows(), root, bound, frame, stage);
}

void RuntimeSession::check_output(const float* P, int64_t n, const Transforms& joint_transforms,
                                  const char* stage) const {
  check_rows(P, n, apply(joint_transforms.at(0), root_rest_), output_bound_, frame_, stage);
}

FrameTimes RuntimeSession::step(const Transforms& joint_transforms, MatrixX3f& V, PenetrationReport* report) {
  FrameTimes times;
  auto start = Clock::now();
  {
    const StepOutput out = stepper_->step_detailed(transforms_tensor(joint_transforms), &times.stages);
    c10::InferenceMode inference;
    const at::Tensor c = out.V_hat.contiguous();
    V.resize(c.size(0), 3);
    std::memcpy(V.data(), c.data_ptr<float>(), size_t(c.numel()) * sizeof(float));
    if (first_exploded(V.data(), V.rows(), apply(joint_transforms.at(0), root_rest_), output_bound_) >= 0) {
      // Name the first stage whose output is already broken (B̂, then Â, then the refiner's V̂).
      for (const auto& [part, stage] :
           {std::pair{out.B_hat, "skinning (LBS)"}, std::pair{out.A_hat, "apparel module"}}) {
        if (!part.defined() || part.numel() == 0) continue;
        const at::Tensor p = part.contiguous();
        check_output(p.data_ptr<float>(), p.size(0), joint_transforms, stage);
      }
      check_output(V.data(), V.rows(), joint_transforms, refine_ ? "refiner" : "apparel module");
    }
  }
  times.model = seconds_since(start);
  start = Clock::now();
  if (resolve_) {
    const PenetrationReport r = resolver_.resolve(V);
    if (report) *report = r;
    check_output(V.data(), V.rows(), joint_transforms, "penetration resolution");
  } else if (report) {
    report->before = report->after = resolver_.measure(V, &report->carried);
    report->pushed = report->smoothed = 0;
  }
  times.penetration = seconds_since(start);
  ++frame_;
  return times;
}

MatrixXfR output_weights(const BoundCharacter& bound) {
  c10::InferenceMode inference;
  const int64_t N = bound.num_vertices(), J = bound.joints.size(0);
  MatrixXfR W = MatrixXfR::Zero(N, J);
  const at::Tensor body_ids = bound.body_ids.contiguous();
  const at::Tensor bw = bound.body_weights.to(at::kFloat).contiguous();
  for (int64_t k = 0; k < body_ids.numel(); ++k) {
    std::memcpy(W.row(body_ids.data_ptr<int64_t>()[k]).data(), bw.data_ptr<float>() + k * J, size_t(J) * sizeof(float));
  }
  const at::Tensor apparel_ids = bound.apparel_ids.contiguous();
  if (apparel_ids.numel() > 0) {
    const at::Tensor nearest = at::cdist(bound.V.index_select(0, apparel_ids), bound.joints).argmin(1).contiguous();
    for (int64_t k = 0; k < apparel_ids.numel(); ++k) {
      W(apparel_ids.data_ptr<int64_t>()[k], nearest.data_ptr<int64_t>()[k]) = 1.0f;
    }
  }
  return W;
}

MatrixXfR anchor_skinning_weights(const BoundCharacter& bound) {
  c10::InferenceMode inference;
  const int64_t N = bound.num_vertices(), J = bound.joints.size(0);
  MatrixXfR W = MatrixXfR::Zero(N, J);
  const auto copy_rows = [&](const at::Tensor& ids, const at::Tensor& weights) {
    const at::Tensor i = ids.contiguous(), w = weights.to(at::kFloat).contiguous();
    for (int64_t k = 0; k < i.numel(); ++k)
      std::memcpy(W.row(i.data_ptr<int64_t>()[k]).data(), w.data_ptr<float>() + k * J, size_t(J) * sizeof(float));
  };
  copy_rows(bound.body_ids, bound.body_weights);
  if (bound.num_apparel() > 0) copy_rows(bound.apparel_ids, bound.apparel_anchor_weights);
  return W;
}

// === The job

std::string default_bind_path(const std::string& out) {
  std::filesystem::path p(out);
  if (p.filename().empty()) p = p.parent_path();  // "folder/" -> "folder"
  return output_kind(out) == "obj" ? p.string() + ".bind" : p.replace_extension(".bind").string();
}

namespace {

// What both apparel paths do around their frames: the picture's four frames (small renderings kept as they come:
// memory stays flat), the progress line on stderr, and the per-frame times of the summary.
class FrameLoop {
 public:
  FrameLoop(const AnimateOptions& o, const TriMesh& mesh, int frames) : o_(o), F_(mesh.F), frames_(frames) {
    if (!o.picture.empty()) {
      for (const double share : {0.2, 0.4, 0.6, 0.8}) picture_frames_.push_back(int(share * (frames - 1)));
    }
    picture_.width = 320;
    picture_.height = 400;
    picture_.world_height = 1.25f * float(mesh.V.col(1).maxCoeff() - mesh.V.col(1).minCoeff());
    seconds_.reserve(size_t(frames));
  }

  // Frame t written: V (#V by 3) with `mask`, `seconds` of wall time.
  void done(int t, const MatrixX3f& V, const std::vector<uint8_t>& mask, double seconds) {
    for (const int k : picture_frames_) {
      if (k == t) pictures_.push_back(render_character(TriMesh{V, F_}, mask, picture_));
    }
    seconds_.push_back(float(seconds));
    if (o_.verbose && (seconds_since(last_print_) > 1.0 || t + 1 == frames_)) {
      last_print_ = Clock::now();
      const double elapsed = seconds_since(start_), rate = (t + 1) / std::max(elapsed, 1e-9);
      std::fprintf(stderr, "\ranimate: %d/%d frames, %.1f frames/s, ETA %.0f s   ", t + 1, frames_, rate,
                   (frames_ - t - 1) / rate);
      if (t + 1 == frames_) std::fprintf(stderr, "\n");
    }
  }

  // Writes the picture and puts the frame times' median and 95th percentile into `s`.
  void finish(AnimateSummary& s) {
    if (!pictures_.empty()) write_png(image_grid(pictures_, int(pictures_.size())), o_.picture);
    std::sort(seconds_.begin(), seconds_.end());
    s.frame_median = seconds_[seconds_.size() / 2];
    s.frame_p95 = seconds_[std::min(seconds_.size() - 1, size_t(std::ceil(0.95 * seconds_.size())) - 1)];
  }

 private:
  const AnimateOptions& o_;
  const MatrixX3i& F_;
  int frames_;
  std::vector<int> picture_frames_;
  std::vector<Image> pictures_;
  RenderOptions picture_;
  std::vector<float> seconds_;
  Clock::time_point last_print_ = Clock::now(), start_ = Clock::now();
};

// The input lines of a verbose run: character, its joint mapping, motion and its mapping.
void print_inputs(const RuntimeCharacter& character, const SourceMotion& source) {
  std::cerr << "animate: character " << character.name << " (" << character.mesh.num_vertices() << " vertices, "
            << character.file_skeleton.num_joints() << " joints)\n";
  if (!character.dataset.empty()) {
    std::cerr << "animate: character skeleton is the dataset's canonical skeleton\n";
  } else {
    std::cerr << "animate: character " << character.rest.describe(character.file_skeleton.names) << "\n";
  }
  if (!character.file_kind.empty())
    std::cerr << "animate: character is a " << character.file_kind << " avatar: its humanoid map maps the skeleton"
              << " and its spring bones name its apparel\n";
  if (character.turned)
    std::cerr << "animate: character faced -Z (its left hip on -X); turned half a turn about Y to face +Z as the "
                 "motions do\n";
  std::cerr << "animate: motion " << source.name << " (" << source.motion.num_frames() << " frames at "
            << source.motion.fps << " fps)\n";
  if (!source.mapping.empty()) std::cerr << "animate: motion " << source.mapping << "\n";
}

// The output's description: the character's mesh and canonical skeleton, the clip, and the summary's counts.
OutputInfo output_info(const RuntimeCharacter& character, const SourceMotion& source, const AnimateSummary& s) {
  OutputInfo info;
  info.character = character.name;
  info.mesh = character.mesh;
  info.skeleton = character.skeleton;
  info.clip = source.dataset_clip.empty() ? source.name : source.dataset_clip;
  info.motion = source.name;
  info.frames = s.frames;
  info.fps = s.fps;
  return info;
}

// Refuses, before any work, a run whose outputs (--out, the bind cache, --picture) would replace one of its inputs
// (the character, the motion, their joint maps and joints file, the apparel mask file, the model's checkpoints) or
// one another.
void check_outputs_are_not_inputs(const AnimateOptions& o) {
  std::vector<RunInput> inputs = {{o.character.spec, "--character"},
                                  {o.character.joints, "--character-joints"},
                                  {o.character.joint_map, "--character-joint-map"},
                                  {o.motion.spec, "--motion"},
                                  {o.motion.joint_map, "--motion-joint-map"}};
  if (o.apparel_mask != "auto" && o.apparel_mask != "model" && o.apparel_mask != "rig")
    inputs.push_back({o.apparel_mask, "--apparel-mask"});
  if (o.apparel != "physics" && o.apparel != "spring-bones" && !o.model_dir.empty()) {
    for (const char* name : {"segmenter.ckpt", "skinning.ckpt", "apparel.ckpt", "refiner.ckpt"})
      inputs.push_back({(std::filesystem::path(o.model_dir) / name).string(), "--model"});
  }
  const std::string bind = o.bind_path == "none"  ? ""
                           : !o.bind_path.empty() ? o.bind_path
                           : o.out.empty()        ? ""
                                                  : default_bind_path(o.out);
  std::vector<std::pair<std::string, std::string>> outputs = {
      {o.out, "--out"}, {bind, "--bind"}, {o.picture, "--picture"}};
  for (size_t k = 0; k < outputs.size(); ++k) {
    check_output_not_input(outputs[k].first, outputs[k].second, inputs);
    for (size_t m = k + 1; m < outputs.size(); ++m) {
      if (outputs[k].first.empty() || outputs[m].first.empty()) continue;
      std::error_code error;
      const auto a = std::filesystem::weakly_canonical(outputs[k].first, error);
      const auto b = std::filesystem::weakly_canonical(outputs[m].first, error);
      AMT_CHECK(a != b, outputs[m].first, ": ", outputs[m].second, ": expected a file of its own, found the run's ",
                outputs[k].second, " output: choose another name");
    }
  }
}

// Streams the frames of a simulated apparel path (--apparel physics, spring-bones) to `writer`: `simulate(t, T, V)`
// writes frame t's vertices under its canonical transforms T; every frame is checked before it is written, as on the
// learned path, so that a simulation that threw a body away stops the run instead of reaching the output. Fills the
// summary's times and output.
template <typename Simulate>
void stream_simulated_frames(const AnimateOptions& o, const RuntimeCharacter& character, const MotionPlayer& player,
                             const Transforms& first, const OutputInfo& info, FrameWriter& writer, const char* stage,
                             Clock::time_point job_start, AnimateSummary& s, Simulate&& simulate) {
  FrameLoop loop(o, character.mesh, s.frames);
  MatrixX3f V;
  const Eigen::Vector3f extent = character.mesh.V.colwise().maxCoeff() - character.mesh.V.colwise().minCoeff();
  const float bound = 10.0f * std::max(extent.norm(), 0.1f);
  const Eigen::Vector3f root_rest = character.skeleton.rest_joints.row(0).transpose();
  for (int t = 0; t < s.frames; ++t) {
    const auto frame_start = Clock::now();
    const Transforms T = t == 0 ? first : player.frame(t);
    simulate(t, T, V);
    check_frame_output(V, apply(T.at(0), root_rest), bound, t, stage);
    s.mean.model += seconds_since(frame_start);
    const auto out_start = Clock::now();
    writer.append(V, T);
    s.mean.output += seconds_since(out_start);
    loop.done(t, V, info.apparel_mask, seconds_since(frame_start));
  }
  s.output = writer.finish();
  loop.finish(s);
  const double n = std::max(1, s.frames);
  s.mean.model /= n, s.mean.output /= n;
  s.total_seconds = seconds_since(job_start);
}

// A clock of model or physics steps at `step_fps` beside output frames at `out_fps`: the motion resampled to the step
// rate (enough steps for `out_frames` output frames and one more to interpolate towards), and where output frame t
// falls on it: between steps k0 and k1 at fraction a (a = 0 and k1 = k0 on a step; the clip's last fraction of a step
// takes its last step).
struct StepPosition {
  int k0 = 0, k1 = 0;
  double a = 0.0;
};

MotionPlayer step_clock(const SourceMotion& source, const RuntimeCharacter& character, PlaybackOptions playback,
                        int out_frames, double out_fps, double step_fps) {
  playback.fps = float(step_fps);
  playback.frames = int(std::floor(double(out_frames - 1) * step_fps / out_fps + 1e-6)) + 2;
  return MotionPlayer(source, character, playback);
}

StepPosition step_position(int t, double out_fps, double step_fps, int num_steps) {
  const double x = double(t) * step_fps / out_fps;
  StepPosition p;
  p.k0 = int(std::floor(x + 1e-6));
  p.a = x - p.k0 < 1e-6 ? 0.0 : x - p.k0;
  if (p.k0 >= num_steps - 1) p.k0 = num_steps - 1, p.a = 0.0;
  p.k1 = p.a > 0 ? p.k0 + 1 : p.k0;
  return p;
}

// True when --out is a .glb written as a skinned animation (not --vertex-cache).
bool wants_skin(const AnimateOptions& o) {
  return !o.out.empty() && !o.vertex_cache && output_kind(o.out) == "glb";
}

// The checks a simulated apparel path (--apparel physics, spring-bones) makes before any work: one output file, no
// viewer folder, no input overwritten. Returns the summary it starts.
AnimateSummary start_simulated_path(const AnimateOptions& o, const std::string& apparel) {
  AMT_CHECK(o.html_dir.empty(), "--html: expected no viewer folder with --apparel ", apparel,
            " (it shows the learned prediction beside skinning); use --out FILE.glb");
  AMT_CHECK(!o.out.empty(), "--out: expected an output, found none");
  output_kind(o.out);
  check_outputs_are_not_inputs(o);
  AnimateSummary s;
  s.physics = true;
  return s;
}

// The PMX model of `o.character` with its own physics (its joint map, kPhysicsStepFps steps): what `amt animate
// --apparel physics` plays and the swing calibration fits on.
std::unique_ptr<PmxPhysicsPlayer> open_pmx_physics(const AnimateOptions& o) {
  std::optional<JointMapFile> joint_map;
  if (!o.character.joint_map.empty()) joint_map = read_joint_map(o.character.joint_map);
  PmxSimulationOptions simulation;
  simulation.fps = kPhysicsStepFps;
  return std::make_unique<PmxPhysicsPlayer>(o.character.spec, joint_map, simulation);
}

// `amt animate --apparel physics`: the PMX model's own physics under the motion, skinned by its own rig, streamed
// to the output. No network and no bind: the model folder is not read.
AnimateSummary animate_with_physics(const AnimateOptions& o) {
  const auto job_start = Clock::now();
  AnimateSummary s = start_simulated_path(o, "physics");
  AMT_CHECK(output_kind(o.out) != "vrm", o.out, ": --out: expected .glb, .h5 or a folder with --apparel physics (a ",
            ".vrm is written from a VRM avatar with --apparel spring-bones; amt convert turns a PMX model into one)");
  const std::string& path = o.character.spec;
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
  AMT_CHECK(e == ".pmx", path, ": --apparel physics: expected a PMX model with rigid bodies (.pmx), found a ",
            e.empty() ? std::string("file without extension") : e + " character",
            " that has no physics rig of its own; use --apparel learned");
  const RuntimeCharacter character = load_character(o.character);
  const SourceMotion source = load_motion(o.motion);
  const MotionPlayer player(source, character, o.playback);
  const std::unique_ptr<PmxPhysicsPlayer> player_physics = open_pmx_physics(o);
  PmxPhysicsPlayer& physics = *player_physics;
  const PmxCharacter& pmx = physics.character();
  int apparel = 0;
  for (const uint8_t m : pmx.apparel_mask) apparel += m;
  s.apparel = "physics (the PMX model's own " + std::to_string(pmx.simulated_bodies) + " simulated rigid bodies and " +
              std::to_string(pmx.model.joints.size()) + " joints, MMD gravity, simulated in PMX units at " +
              std::to_string(int(kPhysicsStepFps)) + " steps per second)";
  s.apparel_source =
      "the PMX physics: " + std::to_string(apparel) + " vertices on bones that simulated rigid bodies drive";
  if (o.verbose) {
    print_inputs(character, source);
    for (const std::string& warning : pmx.warnings) std::cerr << "animate: warning: " << warning << "\n";
    std::cerr << "animate: apparel: " << s.apparel << "\n";
  }
  s.load_seconds = seconds_since(job_start);
  check_output_writable(o.out);
  s.vertices = character.mesh.num_vertices();
  s.apparel_vertices = apparel;
  s.frames = player.num_frames();
  s.fps = player.fps();
  s.exact_motion = player.exact();

  OutputInfo info = output_info(character, source, s);
  info.apparel_mask = pmx.apparel_mask;
  info.weights = pmx_body_weights(pmx);
  if (wants_skin(o)) info.skin = output_skin(character.mesh, info.apparel_mask, info.weights);
  std::unique_ptr<FrameWriter> writer = open_frame_writer(o.out, info);
  // The physics steps on a clock of its own, kPhysicsStepFps (the motion resampled to it), whatever the output rate:
  // an output frame at 24, 30, 60 or 120 fps falls on a step and is that step's skinning, so the same clip gives
  // the same bodies at common times at every rate; a frame between two steps (25 fps) blends their vertices. The
  // lead-in's frames count at 30 fps, as on the other paths.
  const MotionPlayer clock = step_clock(source, character, o.playback, s.frames, s.fps, kPhysicsStepFps);
  const Transforms first = player.frame(0);
  s.lead_in = std::max(0, o.playback.lead_in);
  physics.start(first, int(std::lround(s.lead_in * double(kPhysicsStepFps) / kApparelStepFps)));

  int taken = -1;  // the last step simulated
  struct Skinned {
    int step = -1;
    MatrixX3f V;
  } before_step, after_step;
  stream_simulated_frames(o, character, player, first, info, *writer, "PMX physics", job_start, s,
                          [&](int t, const Transforms&, MatrixX3f& V) {
                            const StepPosition p = step_position(t, s.fps, kPhysicsStepFps, clock.num_frames());
                            while (taken < p.k1) {
                              physics.advance(clock.frame(++taken));
                              if (taken < p.k0) continue;
                              std::swap(before_step, after_step);
                              after_step.step = taken;
                              physics.skin(after_step.V);
                            }
                            if (p.a > 0) {
                              AMT_CHECK(before_step.step == p.k0, "animate: physics steps out of order at frame ", t);
                              V = float(1 - p.a) * before_step.V + float(p.a) * after_step.V;
                            } else {
                              V = after_step.V;
                            }
                          });
  return s;
}

// Per joint of the character's file skeleton, its skinning transform (rest -> posed: p' = R p + t) under canonical
// joint transforms T (T^(t): R_j and the joint's position, forward_kinematics): the skinning transform of the
// canonical joint that carries it (the file's rest poses have no rotations, so a carried joint moves rigidly with
// its carrier).
Transforms file_pose(const RuntimeCharacter& character, const Transforms& T) {
  const Transforms M = skinning_matrices(character.skeleton, T);
  Transforms P(character.rest.carrier.size());
  for (size_t b = 0; b < P.size(); ++b) P[b] = M.at(static_cast<size_t>(character.rest.carrier[b]));
  return P;
}

// The file skeleton at rest: identity skinning transforms.
Transforms file_rest_pose(const RuntimeCharacter& character) {
  return Transforms(character.rest.carrier.size(),
                    make_transform(Eigen::Matrix3f::Identity(), Eigen::Vector3f::Zero()));
}

// A .vrm output of `--apparel spring-bones`: the avatar's own file written again (its VRM extensions, humanoid map,
// spring bones, materials and textures as they were) with one clip that moves its own joints by the frames'
// skinning transforms, the simulated spring joints among them (export_gltf_animated_copy). A VRM player that
// simulates the springs itself starts from where amt left them.
class AvatarWriter : public FrameWriter {
 public:
  AvatarWriter(const std::string& path, const std::string& source, const RuntimeCharacter& character,
               const OutputInfo& info)
      : path_(path),
        asset_(read_gltf(source)),
        file_(gltf_character(asset_)),
        turned_(character.turned),
        fps_(info.fps),
        clip_(info.clip) {
    AMT_CHECK(file_.skeleton.names == character.file_skeleton.names, path,
              ": --out .vrm: expected the avatar's skeleton as read, found another (", file_.skeleton.num_joints(),
              " joints against ", character.file_skeleton.num_joints(), ")");
  }
  /// The frame's skinning transforms of the file's joints (in amt's frame), before append().
  void set_pose(const Transforms& M) {
    pose_ = M;
    if (!turned_) return;
    // The avatar was turned half a turn about Y to face +Z: back to the file's frame, D M D with D = diag(-1, 1, -1).
    const Eigen::Matrix3f D = Eigen::Vector3f(-1, 1, -1).asDiagonal();
    for (Transform34& m : pose_) m = make_transform(D * m.leftCols<3>() * D, D * Eigen::Vector3f(m.col(3)));
  }
  void append(const MatrixX3f&, const Transforms&) override { frames_.push_back(pose_); }
  std::string finish() override {
    export_gltf_animated_copy(asset_, file_, frames_, fps_, clip_, path_);
    char text[200];
    std::snprintf(text, sizeof(text), ", %.1f MB, the avatar with its own %d joints animated (its VRM extensions kept)",
                  double(std::filesystem::file_size(path_)) / 1e6, file_.skeleton.num_joints());
    return path_ + text;
  }
  int num_frames() const override { return int(frames_.size()); }

 private:
  std::string path_;
  GltfAsset asset_;
  GltfCharacter file_;
  bool turned_;
  float fps_;
  std::string clip_;
  Transforms pose_;
  std::vector<Transforms> frames_;
};

// Starts `springs` as the spring-bone path starts a clip at `fps`: settled for a second at the rest pose, then
// blended into `first` over the lead-in (its frames count at 30 fps, so that the springs start the clip in the same
// state at every rate); without a lead-in, settled at `first`. Returns the file skeleton's transforms of the first
// frame.
Transforms start_spring_bones(SpringBoneSimulator& springs, const RuntimeCharacter& character, const Transforms& first,
                              int lead_in, double fps) {
  if (lead_in <= 0) {
    springs.reset(file_pose(character, first));
    return springs.advance(file_pose(character, first), 1.0);
  }
  const double frame_seconds = 1.0 / fps;
  const Transforms rest = file_rest_pose(character);
  springs.reset(rest);
  springs.advance(rest, 1.0);
  const int n = std::max(1, int(std::lround(double(lead_in) * fps / kApparelStepFps)));
  for (int k = 1; k < n; ++k)  // blend weights k / n
    springs.advance(file_pose(character, lead_in_pose(character.skeleton, first, k - 1, n - 1)), frame_seconds);
  return springs.advance(file_pose(character, first), frame_seconds);
}

// `amt animate --apparel spring-bones`: a VRM avatar's own spring bones under the motion, as the VRM specification
// simulates them, at a fixed internal step (kSpringStepSeconds) whatever the output frame rate. No network, no bind.
AnimateSummary animate_with_spring_bones(const AnimateOptions& o) {
  const auto job_start = Clock::now();
  AnimateSummary s = start_simulated_path(o, "spring-bones");
  const RuntimeCharacter character = load_character(o.character);
  AMT_CHECK(
      character.springs && character.springs->num_joints() > 0, o.character.spec,
      ": --apparel spring-bones: expected a VRM avatar with spring bones (.vrm: VRMC_springBone or VRM 0.x "
      "secondaryAnimation), found ",
      character.file_kind.empty() ? std::string("a character without them") : character.file_kind + " without them",
      "; use --apparel learned");
  const SourceMotion source = load_motion(o.motion);
  const MotionPlayer player(source, character, o.playback);
  const SpringRig& rig = *character.springs;
  s.apparel = "spring bones (the avatar's own " + std::to_string(rig.num_joints()) + " spring segments and " +
              std::to_string(rig.colliders.size()) + " colliders, simulated at " +
              std::to_string(int(std::lround(1.0 / kSpringStepSeconds))) + " steps per second)";
  s.apparel_source = character.rig_apparel.empty() ? std::string("the spring bones") : character.rig_apparel;
  if (o.verbose) {
    print_inputs(character, source);
    for (const std::string& note : rig.notes) std::cerr << "animate: spring bones: " << note << "\n";
    std::cerr << "animate: apparel: " << s.apparel << "\n";
  }
  s.load_seconds = seconds_since(job_start);
  check_output_writable(o.out);
  s.vertices = character.mesh.num_vertices();
  s.apparel_vertices =
      static_cast<int>(std::count(character.rig_apparel_mask.begin(), character.rig_apparel_mask.end(), uint8_t(1)));
  s.frames = player.num_frames();
  s.fps = player.fps();
  s.exact_motion = player.exact();

  OutputInfo info = output_info(character, source, s);
  info.apparel_mask = character.rig_apparel_mask;
  if (info.apparel_mask.size() != size_t(s.vertices)) info.apparel_mask.assign(size_t(s.vertices), 0);
  info.weights = canonical_file_weights(character);  // the file's weights on the canonical joints that carry them
  if (wants_skin(o)) info.skin = output_skin(character.mesh, info.apparel_mask, info.weights);
  std::unique_ptr<FrameWriter> writer;
  AvatarWriter* avatar = nullptr;
  if (output_kind(o.out) == "vrm") {
    auto w = std::make_unique<AvatarWriter>(o.out, o.character.spec, character, info);
    avatar = w.get();
    writer = std::move(w);
  } else {
    writer = open_frame_writer(o.out, info);
  }

  // Settle under gravity for a second at the rest pose, then blend into the first frame over the lead-in, as the
  // PMX physics path does. The lead-in lasts lead_in / 30 seconds whatever the output frame rate (its frames
  // count at 30 fps), so that the springs start the clip in the same state at every rate.
  SpringBoneSimulator springs(character.file_skeleton, rig);
  const double frame_seconds = 1.0 / double(s.fps);
  const Transforms first = player.frame(0);
  s.lead_in = std::max(0, o.playback.lead_in);
  const Transforms first_output = start_spring_bones(springs, character, first, s.lead_in, s.fps);

  stream_simulated_frames(o, character, player, first, info, *writer, "spring bones", job_start, s,
                          [&](int t, const Transforms& T, MatrixX3f& V) {
                            const Transforms M =
                                t == 0 ? first_output : springs.advance(file_pose(character, T), frame_seconds);
                            if (avatar) avatar->set_pose(M);
                            linear_blend_skinning(character.mesh.V, character.file_weights, M, V);
                          });
  return s;
}

// The calibration motions of a model folder: kCalibrationMotion and every other regular calibration_motion*.bvh, in
// name order (kCalibrationMotion sorts first).
std::vector<std::filesystem::path> calibration_motions(const std::string& model_dir) {
  std::vector<std::filesystem::path> out;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(model_dir, error)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(kCalibrationMotionStem, 0) == 0 && entry.path().extension() == ".bvh" &&
        std::filesystem::is_regular_file(entry.path()))
      out.push_back(entry.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// The key of a swing fitted on the character's own physics (CachedSwingFit): over the bind's key `bind_key` and what
// fit_swing_on_own_physics reads besides the bind: the character's files (its physics), each calibration motion's name
// and bytes (the model's checkpoints are in the bind's key), the stretch limit with its squash floor and iterations,
// the lead-in, the calibration's length and rate and the largest gain it gives.
std::string swing_fit_key(const AnimateOptions& o, const std::string& bind_key) {
  uint64_t h = fnv1a64(bind_key.data(), bind_key.size());
  for (const std::string* file : {&o.character.spec, &o.character.joints, &o.character.joint_map}) {
    const uint8_t present = std::filesystem::is_regular_file(*file) ? 1 : 0;
    h = fnv1a64(&present, 1, h);
    if (present) h = fnv1a64_file(*file, "a character file", h);
  }
  for (const std::filesystem::path& path : calibration_motions(o.model_dir)) {
    const std::string name = path.filename().string();
    h = fnv1a64(name.data(), name.size() + 1, h);
    h = fnv1a64_file(path.string(), "a calibration motion", h);
  }
  const double settings[7] = {double(o.strain_limit),
                              double(std::max(1, o.playback.lead_in)),
                              kSwingCalibrationSeconds,
                              double(kApparelStepFps),
                              kMaxSwingGain,
                              double(kDefaultStrainFloor),
                              double(kStrainLimitIterations)};
  h = fnv1a64(settings, sizeof(settings), h);
  char text[40];
  std::snprintf(text, sizeof(text), "fnv1a64:%016llx", static_cast<unsigned long long>(h));
  return text;
}

// The character's own apparel physics (a PMX model's rigid bodies, a VRM avatar's spring bones) on `player`'s frames
// (at kApparelStepFps), started from the rest pose through `lead_in` frames as the simulated paths start a clip:
// every vertex per frame. Empty when the character has no physics amt simulates.
std::vector<MatrixX3f> own_physics_frames(const AnimateOptions& o, const RuntimeCharacter& character,
                                          const SourceMotion& source, const MotionPlayer& player, int lead_in) {
  std::vector<MatrixX3f> frames(size_t(player.num_frames()));
  const Transforms first = player.frame(0);
  std::string e = std::filesystem::path(o.character.spec).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
  if (e == ".pmx" && character.rig_bones_with_response) {
    const std::unique_ptr<PmxPhysicsPlayer> physics = open_pmx_physics(o);
    PlaybackOptions playback;
    playback.lead_in = lead_in;
    const MotionPlayer clock =
        step_clock(source, character, playback, player.num_frames(), kApparelStepFps, kPhysicsStepFps);
    physics->start(first, int(std::lround(lead_in * double(kPhysicsStepFps) / kApparelStepFps)));
    int taken = -1;
    for (int t = 0; t < player.num_frames(); ++t) {  // every frame at kApparelStepFps falls on a step
      const StepPosition p = step_position(t, kApparelStepFps, kPhysicsStepFps, clock.num_frames());
      while (taken < p.k0) physics->advance(clock.frame(++taken));
      physics->skin(frames[size_t(t)]);
    }
    return frames;
  }
  if (character.springs && character.springs->num_joints() > 0) {
    SpringBoneSimulator springs(character.file_skeleton, *character.springs);
    const Transforms first_pose = start_spring_bones(springs, character, first, lead_in, kApparelStepFps);
    for (int t = 0; t < player.num_frames(); ++t) {
      const Transforms M =
          t == 0 ? first_pose : springs.advance(file_pose(character, player.frame(t)), 1.0 / kApparelStepFps);
      linear_blend_skinning(character.mesh.V, character.file_weights, M, frames[size_t(t)]);
    }
    return frames;
  }
  return {};
}

// The learned apparel's swing fitted on the character's own physics (fit_swing_on_motions) over the calibration
// motions of the model folder (calibration_motions): the uncalibrated module and the character's simulation run
// through the first kSwingCalibrationSeconds of each from the rest pose, their frames pooled. Returns what the run
// reports, and sets bound.apparel_swing_gain; an empty string (the gains left as they are) when the character has no
// physics amt simulates or the folder has no calibration motion.
std::string fit_swing_on_own_physics(const AnimateOptions& o, const ModelBundle& bundle,
                                     const RuntimeCharacter& character, BoundCharacter& bound) {
  const std::vector<std::filesystem::path> paths = calibration_motions(o.model_dir);
  if (bound.num_apparel() == 0 || paths.empty()) return "";
  if (!(character.springs && character.springs->num_joints() > 0) && !character.rig_bones_with_response) return "";
  c10::InferenceMode inference;
  std::vector<SwingCalibrationMotion> runs;
  std::string names;
  int64_t frames = 0;
  for (const std::filesystem::path& path : paths) {
    MotionSpec spec;
    spec.spec = path.string();
    const SourceMotion source = load_motion(spec);
    PlaybackOptions playback;
    playback.fps = kApparelStepFps;
    playback.frames = int(std::lround(kSwingCalibrationSeconds * kApparelStepFps));
    playback.lead_in = std::max(1, o.playback.lead_in);
    const MotionPlayer player(source, character, playback);
    const std::vector<MatrixX3f> truth = own_physics_frames(o, character, source, player, playback.lead_in);
    if (truth.empty()) return "";
    const int64_t T = player.num_frames(), N_a = bound.num_apparel();
    at::Tensor motion = at::empty({T, bound.joints.size(0), 3, 4}, at::kFloat), G = at::empty({T, N_a, 3}, at::kFloat);
    for (int64_t t = 0; t < T; ++t) {
      motion[t] = transforms_tensor(player.frame(int(t)));
      const MatrixX3f& V = truth[size_t(t)];
      AMT_CHECK(V.rows() == bound.num_vertices(), "swing calibration: the simulation gave ", V.rows(),
                " vertices, expected ", bound.num_vertices());
      G[t] = at::from_blob(const_cast<float*>(V.data()), {V.rows(), 3}, at::TensorOptions().dtype(at::kFloat))
                 .index_select(0, bound.apparel_ids);
    }
    runs.push_back({motion_lead_in(motion[0], bound.joints, playback.lead_in), motion, G});
    names += (names.empty() ? "" : ", ") + path.filename().string();
    frames += T;
  }
  const SwingCalibration fit = fit_swing_on_motions(bundle, bound, runs, o.strain_limit);
  bound.apparel_swing_gain = fit.gain;
  const at::Tensor g = fit.gain;
  char text[512];
  std::snprintf(text, sizeof(text),
                "fitted on the rig's own physics over %.1f s of %s (%s; --swing-calibration auto): %.0f %% of the "
                "apparel calmed, %.0f %% livened, gain median %.2f, lowest %.2f, highest %.2f",
                double(frames) / double(kApparelStepFps),
                runs.size() == 1 ? "the calibration motion" : "the calibration motions", names.c_str(),
                100.0 * g.lt(0.999f).to(at::kFloat).mean().item<double>(),
                100.0 * g.gt(1.001f).to(at::kFloat).mean().item<double>(), g.median().item<double>(),
                g.min().item<double>(), g.max().item<double>());
  return text;
}

}  // namespace

AnimateSummary animate(const AnimateOptions& o) {
  AMT_CHECK(o.apparel.empty() || o.apparel == "learned" || o.apparel == "physics" || o.apparel == "spring-bones",
            "--apparel: expected learned, physics or spring-bones, found '", o.apparel, "'");
  if (o.apparel == "physics") return animate_with_physics(o);
  if (o.apparel == "spring-bones") return animate_with_spring_bones(o);
  const auto job_start = Clock::now();
  AnimateSummary s;
  s.output = o.out;
  s.apparel = "learned (the apparel module of " + o.model_dir + (o.refine ? ", then its refiner" : "") + ")";
  AMT_CHECK(!o.out.empty() || !o.html_dir.empty(), "--out: expected an output (or --html DIR), found none");
  if (!o.out.empty()) {
    // Rejects .gltf / .obj names before any work, and a .vrm (written by --apparel spring-bones only).
    AMT_CHECK(output_kind(o.out) != "vrm", o.out, ": --out: expected .glb, .h5 or a folder with --apparel learned (a ",
              ".vrm keeps the avatar's own skeleton, which the learned apparel's handles are not part of; --apparel ",
              "spring-bones writes one)");
  }
  check_outputs_are_not_inputs(o);
  // The viewer folder: refused before any work when it holds files amt did not write.
  const std::filesystem::path html(o.html_dir);
  if (!o.html_dir.empty()) {
    check_viewer_folder(o.html_dir);
    viewer_page_files(o.viewer_dir);
  }

  // Inputs and model.
  RuntimeCharacter character = load_character(o.character);
  const SourceMotion source = load_motion(o.motion);
  const ModelBundle bundle = load_model_bundle(o.model_dir);
  check_bundle_skeleton(bundle, character.skeleton.names, o.model_dir);
  // The rig's physics response, measured only for an apparel module that reads it or whose swing it calibrates.
  AMT_CHECK(o.swing_calibration == "auto" || o.swing_calibration == "off",
            "--swing-calibration: expected auto or off, found '", o.swing_calibration, "'");
  const bool calibrate = bundle.local_apparel() && o.swing_calibration == "auto";
  const bool reads_response =
      bundle.local_apparel() &&
      (bundle.apparel_dynamics->options.response ||
       (!bundle.apparel_dynamics_own_weights.is_empty() && bundle.apparel_dynamics_own_weights->options.response));
  if ((reads_response || calibrate) && character.rig_bones_with_response)
    character.rig_bones = character.rig_bones_with_response();
  std::vector<uint8_t> mask_override;
  s.apparel_source = "the segmenter";
  const bool use_rig = o.apparel_mask == "rig" ||
                       ((o.apparel_mask.empty() || o.apparel_mask == "auto") && !character.rig_apparel_mask.empty());
  if (o.apparel_mask.empty() || o.apparel_mask == "auto") {
    s.apparel_source = use_rig ? "" : "the segmenter (--apparel-mask auto: the character has no rig)";
  }
  if (use_rig) {
    AMT_CHECK(!character.rig_apparel_mask.empty(), o.character.spec, ": --apparel-mask rig: the character's rig ",
              "names no apparel (no simulated rigid bodies driving bones); expected a PMX model with physics, a ",
              "dataset character or generated:SEED; use --apparel-mask model (the segmenter) or a mask file");
    mask_override = character.rig_apparel_mask;
    s.apparel_source = "the rig: " + character.rig_apparel +
                       (o.apparel_mask == "rig" ? "" : " (--apparel-mask auto: the character has a rig)");
  } else if (!o.apparel_mask.empty() && o.apparel_mask != "model" && o.apparel_mask != "auto") {
    mask_override = read_apparel_mask(o.apparel_mask, character.mesh.num_vertices());
    s.apparel_source = "the file " + o.apparel_mask;
  }
  // The handles: picked automatically along the apparel (auto, model), as the module was trained; or at the rig's
  // own apparel bones (rig). On the held-out characters' ground-truth masks the module on the rig's bones
  // measured worse than on handles picked automatically (rollout PMD_a 3.96 against 3.57 cm, skinning 5.06 cm;
  // CHANGELOG.md, "Apparel on handles and artist-style remakes"), so auto does not take them.
  AMT_CHECK(o.apparel_handles == "auto" || o.apparel_handles == "rig" || o.apparel_handles == "model",
            "--apparel-handles: expected auto, rig or model, found '", o.apparel_handles, "'");
  std::shared_ptr<const ApparelBones> bones;
  if (o.apparel_handles == "rig") {
    AMT_CHECK(character.rig_bones != nullptr, o.character.spec, ": --apparel-handles rig: the character's rig has no ",
              "apparel bones (physics-driven PMX bones, glTF chains outside the canonical skeleton, a dataset rig's ",
              "apparel bones); use --apparel-handles model");
    bones = character.rig_bones;
  }
  if (bones) {
    s.handle_source = "the rig's " + std::to_string(bones->num_bones()) + " apparel bones (--apparel-handles rig)";
  } else if (character.rig_bones && use_rig) {
    s.handle_source = "picked automatically (the rig's " + std::to_string(character.rig_bones->num_bones()) +
                      " apparel bones: --apparel-handles rig)";
  } else {
    s.handle_source = "picked automatically";
  }
  // The skinning weights: the character's own skin when its file has one (the artist's weights are the body's ground
  // truth, and skinning with them moves a body exactly as the file's own rig does), else the skinning predictor.
  AMT_CHECK(o.skin_weights.empty() || o.skin_weights == "auto" || o.skin_weights == "model" || o.skin_weights == "rig",
            "--skin-weights: expected auto, model or rig, found '", o.skin_weights, "'");
  MatrixXfR own_weights;
  if (o.skin_weights != "model") own_weights = canonical_file_weights(character);
  AMT_CHECK(o.skin_weights != "rig" || own_weights.rows() > 0, o.character.spec,
            ": --skin-weights rig: the character has no skin of its own (expected a skinned glTF / VRM or a PMX "
            "model); use --skin-weights model");
  s.weights_source = own_weights.rows() > 0
                         ? "the character's own skin (" + std::to_string(character.file_skeleton.num_joints()) +
                               " bones, each weight on the canonical joint that carries it" +
                               (o.skin_weights == "rig" ? ")" : "; --skin-weights auto: the file has one)")
                         : std::string("the skinning predictor") +
                               (o.skin_weights == "model" ? ""
                                                          : " (--skin-weights auto: own weights come from skinned "
                                                            "glTF / VRM and PMX files only)");
  if (own_weights.rows() > 0 && !bundle.apparel_dynamics_own_weights.is_empty())
    s.weights_source +=
        "; the apparel module trained on anchors of such weights (" + std::string(kApparelOwnWeightsCheckpoint) + ")";
  const MotionPlayer player(source, character, o.playback);
  if (o.verbose) {
    print_inputs(character, source);
    std::cerr << "animate: apparel mask from " << s.apparel_source << "\n";
    std::cerr << "animate: skinning weights from " << s.weights_source << "\n";
    std::cerr << "animate: apparel: " << s.apparel << "\n";
  }
  s.load_seconds = seconds_since(job_start);

  // An unwritable output fails before the work.
  if (!o.out.empty()) check_output_writable(o.out);
  const std::string prediction_glb = (html / "prediction.glb").string(),
                    skinning_glb = (html / "skinning.glb").string();
  if (!o.html_dir.empty()) {
    check_output_writable(prediction_glb), check_output_writable(skinning_glb);
    // The viewer folder's manifest and page go first: the default bind cache (without --out) lives in the folder,
    // and a folder holding it but no manifest would not be amt's. A run that fails later leaves the page without
    // GLBs, which the next run replaces.
    ViewerManifest manifest;
    manifest.title = character.name + " · " + source.name;
    manifest.groups.push_back(
        {"amt animate: the prediction beside rigid skinning (apparel glued to its anchor)",
         {{"prediction.glb", "prediction", "prediction"}, {"skinning.glb", "skinning", "skinning"}}});
    write_viewer_folder(o.html_dir, o.viewer_dir, manifest);
  }
  s.bind_path = o.bind_path.empty()     ? default_bind_path(o.out.empty() ? prediction_glb : o.out)
                : o.bind_path == "none" ? ""
                                        : o.bind_path;
  BindResult bind = bind_cached(bundle, character.mesh, character.skeleton.rest_joints, mask_override, s.bind_path,
                                bones, own_weights, reads_response || calibrate ? character.rig_bones : nullptr);
  if (!calibrate) bind.bound.apparel_swing_gain = at::Tensor();
  if (bundle.local_apparel())
    s.swing_source = swing_source(bind.bound, o.swing_calibration,
                                  bundle.apparel_dynamics_for(bind.bound.given_weights)->options.swing_reference);
  if (calibrate) {
    const auto fit_start = Clock::now();
    // A calibration that cannot run (a damaged calibration motion, a rig whose physics does not simulate) leaves
    // the probe's calibration, and the run says why: the user asked for the learned apparel, not for its physics.
    std::string fitted;
    try {
      // The fit kept in the bind cache when everything it reads is unchanged; else fitted now and kept there.
      const std::string key = bind.key.empty() ? "" : swing_fit_key(o, bind.key);
      if (!key.empty() && bind.swing_fit.key == key) {
        bind.bound.apparel_swing_gain = bind.swing_fit.gain;
        fitted = bind.swing_fit.text + " (from the bind cache)";
      } else {
        const BoundCharacter probe = bind.bound;
        fitted = fit_swing_on_own_physics(o, bundle, character, bind.bound);
        if (!fitted.empty() && !key.empty())
          save_bind(s.bind_path, bind.key, probe, CachedSwingFit{key, fitted, bind.bound.apparel_swing_gain});
      }
    } catch (const Error& e) {
      s.swing_source += " (not fitted on the rig's own physics: " + std::string(e.what()) + ")";
    }
    if (!fitted.empty()) {
      s.swing_source = fitted;
      s.calibration_seconds = seconds_since(fit_start);
    }
  }
  s.bind_seconds = bind.seconds;
  s.bind_cache_hit = bind.cache_hit;
  s.hung = bind.bound.hung;
  s.topology = bind.bound.topology();
  s.handles = bind.bound.handle_rows.defined() ? bind.bound.handle_rows.size(0) : 0;
  if (bundle.local_apparel() && bundle.apparel_dynamics_for(bind.bound.given_weights)->options.response)
    s.physics_source = physics_source(character.rig_bones.get(), bind.bound);
  if (o.verbose) {
    std::cerr << "animate: bind " << (bind.cache_hit ? "loaded from " + s.bind_path : "computed (" + bind.reason + ")")
              << " in " << bind.seconds << " s\n";
  }
  RuntimeSession session(bundle, bind.bound, character.mesh.F, o.resolve_penetration, o.penetration, o.refine,
                         o.strain_limit);
  s.vertices = character.mesh.num_vertices();
  s.apparel_vertices = int(session.bound().num_apparel());
  s.frames = player.num_frames();
  s.fps = player.fps();
  s.exact_motion = player.exact();

  OutputInfo info = output_info(character, source, s);
  info.apparel_mask = session.apparel_mask();
  info.weights = output_weights(session.bound());
  std::unique_ptr<FrameWriter> writer, html_prediction, html_skinning;
  if (!o.out.empty()) {
    OutputInfo out_info = info;
    if (wants_skin(o)) {
      out_info.skin = output_skin(character.mesh, info.apparel_mask, info.weights);
    }
    writer = open_frame_writer(o.out, out_info);
  }
  MatrixXfR skinning_weights;
  if (!o.html_dir.empty()) {
    html_prediction = open_frame_writer(prediction_glb, info);
    html_skinning = open_frame_writer(skinning_glb, info);
    skinning_weights = anchor_skinning_weights(session.bound());
  }
  MatrixX3f skinned;

  // The module steps at kApparelStepFps, the rate it was trained at. At another output rate it steps on a clock
  // of its own (the motion resampled to that rate), and each output frame is its exact body skinning plus the
  // apparel's offset from that skinning interpolated between the two steps around the frame's time.
  const bool resample = std::abs(s.fps - kApparelStepFps) > 1e-3f;
  std::optional<MotionPlayer> step_player;
  if (resample) step_player.emplace(step_clock(source, character, o.playback, s.frames, s.fps, kApparelStepFps));
  const MotionPlayer& clock = resample ? *step_player : player;
  // The skinning the offsets are taken from: any skinning does (a frame on a step gets that step's vertices back
  // exactly), so the anchor weights' 4 largest per vertex, which cost a sparse pass per frame instead of a dense one.
  const SparseWeights anchor = resample ? sparsify_weights(anchor_skinning_weights(session.bound())) : SparseWeights();

  // Lead-in from the rest pose (in model steps, so it lasts as long at every output rate), then the motion.
  const Transforms first = player.frame(0);
  s.lead_in = std::max(0, o.playback.lead_in);
  {
    const at::Tensor rest_joints = session.bound().joints;
    const at::Tensor lead = motion_lead_in(transforms_tensor(first), rest_joints, s.lead_in);
    for (int64_t k = 0; k < lead.size(0); ++k) session.advance(lead[k]);
  }
  MatrixX3f V, stepped;
  // The last two model steps as (step index, vertices minus their anchor skinning), for interpolation.
  struct Offsets {
    int step = -1;
    MatrixX3f offset;
  } before_step, after_step;
  auto step_model = [&](int k, const Transforms& T, FrameTimes& times) {
    PenetrationReport report;
    const FrameTimes step_times = session.step(T, resample ? stepped : V, &report);
    times.model += step_times.model, times.penetration += step_times.penetration;
    s.before.inside += report.before.inside, s.before.total += report.before.total;
    s.before.depth_sum_cm += report.before.depth_sum_cm;
    s.after.inside += report.after.inside, s.after.total += report.after.total;
    s.after.depth_sum_cm += report.after.depth_sum_cm;
    s.carried += report.carried, s.tucked += report.tucked;
    ++s.apparel_steps;
    if (!resample) return;
    MatrixX3f skinned_step;
    linear_blend_skinning(character.mesh.V, anchor, skinning_matrices(character.skeleton, T), skinned_step);
    std::swap(before_step, after_step);
    after_step.step = k;
    after_step.offset = stepped - skinned_step;
  };
  FrameLoop loop(o, character.mesh, s.frames);
  for (int t = 0; t < s.frames; ++t) {
    const Transforms T = t == 0 ? first : player.frame(t);
    FrameTimes times;
    if (!resample) {
      step_model(t, T, times);
    } else {
      const StepPosition p = step_position(t, s.fps, kApparelStepFps, clock.num_frames());
      for (int k = after_step.step + 1; k <= p.k1; ++k) step_model(k, k == 0 ? first : clock.frame(k), times);
      const auto blend_start = Clock::now();
      linear_blend_skinning(character.mesh.V, anchor, skinning_matrices(character.skeleton, T), V);
      if (p.a > 0) {
        AMT_CHECK(before_step.step == p.k0, "animate: apparel steps out of order at frame ", t);
        V += float(1 - p.a) * before_step.offset + float(p.a) * after_step.offset;
      } else {
        V += after_step.offset;
      }
      times.model += seconds_since(blend_start);
    }
    const auto out_start = Clock::now();
    if (writer) writer->append(V, T);
    if (html_prediction) {
      html_prediction->append(V, T);
      linear_blend_skinning(character.mesh.V, skinning_weights, skinning_matrices(character.skeleton, T), skinned);
      html_skinning->append(skinned, T);
    }
    times.output = seconds_since(out_start);
    loop.done(t, V, info.apparel_mask, times.total());
    s.mean.model += times.model, s.mean.penetration += times.penetration, s.mean.output += times.output;
  }
  const std::string written = writer ? writer->finish() : "";
  if (html_prediction) {
    html_prediction->finish();
    html_skinning->finish();
    s.html_dir = o.html_dir;
  }
  loop.finish(s);
  s.output = written;
  const double n = std::max(1, s.frames);
  s.mean.model /= n, s.mean.penetration /= n, s.mean.output /= n;
  s.total_seconds = seconds_since(job_start);
  return s;
}

std::string describe(const AnimateSummary& s) {
  std::ostringstream out;
  char line[256];
  if (!s.output.empty()) out << "wrote " << s.output << "\n";
  if (!s.html_dir.empty())
    out << "wrote the viewer folder " << s.html_dir << " (prediction.glb beside skinning.glb): open it with amt view "
        << s.html_dir << "\n";
  std::snprintf(line, sizeof(line),
                "frames: %d at %.4g fps (%.2f s of motion, after %d lead-in frames from the rest pose)%s\n", s.frames,
                s.fps, s.frames / s.fps, s.lead_in, s.exact_motion ? ", dataset transforms as stored" : "");
  out << line;
  if (s.apparel_steps > 0 && s.apparel_steps != s.frames) {
    std::snprintf(line, sizeof(line),
                  "apparel module: %d steps at %.4g steps per second (the rate it was trained at), interpolated to "
                  "the %.4g fps output\n",
                  s.apparel_steps, double(kApparelStepFps), double(s.fps));
    out << line;
  }
  std::snprintf(line, sizeof(line), "character: %d vertices, %d apparel (%.0f %%, mask from ", s.vertices,
                s.apparel_vertices, 100.0 * s.apparel_vertices / std::max(1, s.vertices));
  out << line << s.apparel_source << ")\n";
  if (s.hung.pinned > 0 || s.hung.unnailed > 0) {
    std::snprintf(line, sizeof(line),
                  "apparel mask made to hang from the body: %d floating piece%s pinned by %s lowest-probability "
                  "vertices, %d extra body island%s made apparel\n",
                  s.hung.pinned, s.hung.pinned == 1 ? "" : "s", s.hung.pinned == 1 ? "its" : "their", s.hung.unnailed,
                  s.hung.unnailed == 1 ? "" : "s");
    out << line;
  }
  if (!s.physics) {
    const TopologyCounts& t = s.topology;
    std::snprintf(line, sizeof(line),
                  "topology: %lld connected parts, %lld with %lld seam copies welded, %lld with %lld proximity links "
                  "between apparel pieces%s\n",
                  (long long)t.parts, (long long)t.welded_parts, (long long)t.seam_links, (long long)t.linked_parts,
                  (long long)t.proximity_links, s.handles > 0 ? "" : "; the apparel module moves every apparel vertex");
    out << line;
    if (s.handles > 0) {
      std::snprintf(line, sizeof(line), "apparel on %lld handles (%.1f apparel vertices each), %s\n",
                    (long long)s.handles, double(s.apparel_vertices) / double(s.handles), s.handle_source.c_str());
      out << line;
    }
    if (t.refused_welds > 0) {
      std::snprintf(line, sizeof(line),
                    "warning: %lld coincident vertex pair%s straddle body and apparel in the given mask: left apart, "
                    "each side moves with its own part (a seam there can open)\n",
                    (long long)t.refused_welds, t.refused_welds == 1 ? "" : "s");
      out << line;
    }
  }
  if (!s.weights_source.empty()) out << "skinning weights: " << s.weights_source << "\n";
  if (!s.physics_source.empty()) out << "apparel physics: " << s.physics_source << "\n";
  if (!s.swing_source.empty()) {
    out << "apparel swing: " << s.swing_source;
    if (s.calibration_seconds > 0) out << " (" << std::fixed << std::setprecision(2) << s.calibration_seconds << " s)";
    out << std::defaultfloat << "\n";
  }
  out << "apparel: " << s.apparel << "\n";
  if (s.physics) {
    std::snprintf(line, sizeof(line),
                  "time per frame: median %.2f ms, p95 %.2f ms (physics and skinning %.2f, output %.2f ms mean)\n",
                  1e3 * s.frame_median, 1e3 * s.frame_p95, 1e3 * s.mean.model, 1e3 * s.mean.output);
    out << line;
    std::snprintf(line, sizeof(line), "total: %.1f s\n", s.total_seconds);
    out << line;
    return out.str();
  }
  std::snprintf(line, sizeof(line), "bind: %.2f s (%s%s)\n", s.bind_seconds,
                s.bind_cache_hit      ? "cache hit: "
                : s.bind_path.empty() ? "no cache"
                                      : "computed, cached in ",
                s.bind_path.c_str());
  out << line;
  std::snprintf(line, sizeof(line),
                "time per frame: median %.2f ms, p95 %.2f ms (model %.2f, penetration %.2f, output %.2f ms mean)\n",
                1e3 * s.frame_median, 1e3 * s.frame_p95, 1e3 * s.mean.model, 1e3 * s.mean.penetration,
                1e3 * s.mean.output);
  out << line;
  std::snprintf(line, sizeof(line),
                "penetration share: %.2f %% of apparel vertices before, %.2f %% after (mean depth %.2f cm before; "
                "%.2f %% inside at rest too, left where the model has them; %.0f %% of inside tests carried over "
                "from the previous frame)\n",
                100.0 * s.before.share(), 100.0 * s.after.share(), s.before.mean_depth_cm(),
                s.before.total > 0 ? 100.0 * double(s.tucked) / double(s.before.total) : 0.0,
                s.before.total > 0 ? 100.0 * double(s.carried) / double(s.before.total) : 0.0);
  out << line;
  std::snprintf(line, sizeof(line), "total: %.1f s\n", s.total_seconds);
  out << line;
  return out.str();
}

}  // namespace amt
