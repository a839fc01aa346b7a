#pragma once
// The CPU runtime (issue 6): bind once, then stream. `animate` reads a character and a motion, binds
// the character to the model (through the bind cache), blends the motion in from the rest pose, runs
// the one forward path of models/pipeline.h frame by frame (LBS, apparel step, refiner, under
// c10::InferenceMode), resolves penetration and streams each frame to the output writer.
// RuntimeSession is the per-frame part alone, for `amt bench --suite runtime` and the tests.
#include <memory>
#include <string>
#include <vector>

#include "data_tools/garment/penetration_resolution.h"
#include "data_tools/geometry/metrics.h"
#include "infer/bind_cache_torch.h"
#include "infer/character_input.h"
#include "infer/frame_writer.h"
#include "infer/motion_input.h"
#include "models/pipeline.h"

namespace amt {

// === Per-frame session

/// Wall time of the stages of one frame, seconds.
///   model        the pipeline step (LBS + apparel step + refiner) and the copy of V̂ out, inference mode
///   stages       the split of the pipeline step (models/pipeline.h StepTimes: LBS, apparel, refiner)
///   penetration  the resolution (0 when switched off); output: the writer's append
struct FrameTimes {
  double model = 0, penetration = 0, output = 0;
  StepTimes stages;
  double total() const { return model + penetration + output; }
};

/// One bound character running frame by frame: the pipeline stepper (history from the skinned rest
/// pose), the penetration resolver and a frame buffer. The bundle must outlive the session.
class RuntimeSession {
 public:
  /// Starts from rest_apparel_history. `resolve` switches penetration resolution on. Prepares the
  /// resolver on the rest pose (PenetrationResolver::prepare). `refine` runs the joint refiner after the
  /// apparel module (PipelineStages::kFull); without it V̂ is tile(Â, B̂) (kBodyApparel).
  /// `strain_limit` bounds the learned apparel's edge stretch (PipelineStepper::set_strain_limit; 0: off).
  RuntimeSession(const ModelBundle& bundle, BoundCharacter bound, const MatrixX3i& F, bool resolve,
                 PenetrationOptions penetration = {}, bool refine = true, float strain_limit = kDefaultStrainLimit);

  /// Runs frame T^(t) (J transforms on the bundle's skeleton): V̂ into `V` (#V by 3), then the
  /// penetration resolution when on. Returns the stage times (output excluded). Throws amt::Error
  /// naming the frame (counted from 0, lead-in excluded) and the first stage whose output is
  /// non-finite or exploded (a vertex farther from the root joint than 10 times the rest mesh's
  /// bounding-box diagonal): nothing absurd reaches the writer.
  FrameTimes step(const Transforms& joint_transforms, MatrixX3f& V, PenetrationReport* report = nullptr);

  /// Runs frame T^(t) without resolution or copy-out (lead-in frames).
  void advance(const at::Tensor& joint_transforms);

  const BoundCharacter& bound() const { return bound_; }
  /// The apparel mask in use, #V entries 0/1.
  const std::vector<uint8_t>& apparel_mask() const { return mask_; }
  bool resolving() const { return resolve_; }
  bool refining() const { return refine_; }

 private:
  const ModelBundle& bundle_;
  BoundCharacter bound_;
  std::vector<uint8_t> mask_;
  std::unique_ptr<PipelineStepper> stepper_;
  PenetrationResolver resolver_;
  bool resolve_, refine_;
  float output_bound_ = 0;     // metres from the root joint
  Eigen::Vector3f root_rest_;  // the root joint at rest
  int64_t frame_ = 0;          // frames of step() so far
  void check_output(const float* P, int64_t n, const Transforms& joint_transforms, const char* stage) const;
};

/// Throws amt::Error naming frame `frame` and `stage` when a row of V (#V, 3) is non-finite or farther than `bound`
/// metres from `root` (the frame's root joint): the check every path of `amt animate` runs on a frame before it is
/// written (RuntimeSession::step, and the PMX physics of --apparel physics).
void check_frame_output(const MatrixX3f& V, const Eigen::Vector3f& root, float bound, int64_t frame, const char* stage);

/// Rigid skinning of every vertex (#V by J, rows sum to 1), the "skinning" the viewer shows beside a
/// prediction: the bound body weights on body rows and, on apparel rows, the weights of the apparel
/// module's anchor (apparel_anchor_weights: the apparel glued to the body vertex it follows).
MatrixXfR anchor_skinning_weights(const BoundCharacter& bound);

/// (J, 3, 4) float tensor of J transforms.
at::Tensor transforms_tensor(const Transforms& transforms);

/// Skinning weights of every vertex (#V by J) for outputs that store them: the bound body weights on
/// body rows and, for apparel rows, weight 1 on the joint nearest to the rest vertex.
MatrixXfR output_weights(const BoundCharacter& bound);

// === The `amt animate` job

/// Everything `amt animate` takes.
///   model_dir   folder of the four checkpoints (models/pipeline.h load_model_bundle)
///   out         .glb, .h5 or an OBJ folder (infer/frame_writer.h); may be empty when html_dir is set
///   bind_path   bind cache file; empty: "<out without extension>.bind" beside the output (beside
///               html_dir/prediction.glb without out); "none" disables
///   html_dir    when not empty, also a viewer folder (data_tools/formats/viewer_folder.h): prediction.glb and
///               skinning.glb (anchor_skinning_weights) side by side, opened with `amt view html_dir`;
///               viewer_dir is the repository's viewer/ its page is copied from
///   apparel_mask  where the apparel mask comes from: "auto" or empty (the rig when the character has one, else
///               the segmenter), "model" (the segmenter), "rig" (the character's own rig:
///               RuntimeCharacter::rig_apparel_mask), or a mask file (read_apparel_mask)
///   apparel_handles  where the apparel module's handles are (a module on handles): "auto" or "model" (picked
///               automatically at the module's spacing, as the module was trained: it measures better than the
///               rig's bones), or "rig" (the rig's own apparel bones: RuntimeCharacter::rig_bones)
///   apparel     what moves the apparel: "learned" or empty (the apparel module of the model), or "physics" (a PMX
///               model's own rigid bodies and joints, infer/pmx_physics_player.h: no network, no bind; the whole
///               mesh skinned by the model's own rig; not with html_dir)
struct AnimateOptions {
  CharacterSpec character;
  MotionSpec motion;
  std::string model_dir;
  std::string out;
  std::string bind_path;
  std::string apparel_mask;
  std::string apparel = "learned";
  std::string apparel_handles = "auto";
  /// Where the skinning weights come from: "auto" or empty (the character's own skin when its file has one: a
  /// skinned glTF / VRM, a PMX model; else the skinning predictor), "model" (the skinning predictor, eq. 5-7), or
  /// "rig" (the character's own skin: canonical_file_weights; an error without one).
  std::string skin_weights = "auto";
  std::string html_dir, viewer_dir;
  /// A .glb output as a per-frame vertex cache (`--vertex-cache`: every vertex of every frame, exactly as
  /// computed) instead of a skinned animation (the canonical joints and the apparel's handles, fitted to each
  /// frame; infer/frame_writer.h).
  bool vertex_cache = false;
  PlaybackOptions playback;
  bool resolve_penetration = true;
  /// Run the joint refiner after the apparel module (`--refiner`). Off by default: measured on the held-out
  /// characters it changes PMD_a by at most 0.01 cm and costs about a third of a 28k-vertex frame.
  bool refine = false;
  /// The learned apparel's stretch limit (`--strain-limit`; PipelineStepper::set_strain_limit, 0: off).
  float strain_limit = kDefaultStrainLimit;
  /// `--swing-calibration`: "auto" (the learned apparel's swing scaled per piece to the character's own physics when
  /// its rig's response can be measured: swing_calibration, models/pipeline.h) or "off" (the module as trained).
  std::string swing_calibration = "auto";
  /// Apparel inside the body at rest stays there (PenetrationOptions::keep_rest_penetration; `--push-rest-penetration`
  /// turns it off).
  PenetrationOptions penetration = [] {
    PenetrationOptions p;
    p.keep_rest_penetration = true;
    return p;
  }();
  /// Print the mapping and a progress line (done/total, frames/s, ETA) on stderr.
  bool verbose = true;
  /// When not empty, a PNG of four output frames (at 20, 40, 60 and 80 % of the clip) side by side,
  /// rendered with data_tools/formats/render.h (apparel in blue), for a quick look without a glTF viewer.
  std::string picture;
};

/// What a run did: counts, timings (seconds) and penetration over the written frames.
struct AnimateSummary {
  /// What was written: the output's description, and the viewer folder (or "").
  std::string output, html_dir;
  int frames = 0, lead_in = 0;
  float fps = 30.0f;
  /// Steps of the learned apparel module: at kApparelStepFps whatever the output rate, the output frames
  /// interpolated between them (equal to `frames` at that rate; 0 on the simulated paths).
  int apparel_steps = 0;
  int vertices = 0, apparel_vertices = 0;
  /// Where the apparel mask came from ("the segmenter", "the rig: ...", "the file ...").
  std::string apparel_source;
  /// What the bind changed in the segmenter's mask so that each piece hangs from one place.
  HungPieces hung;
  /// The linked topology of the bound mesh (seams welded, nearby pieces linked), and the apparel module's
  /// handles (0: it moves every apparel vertex).
  TopologyCounts topology;
  int64_t handles = 0;
  /// Where the handles are: "picked automatically ..." or "the rig's N apparel bones ..."
  /// (AnimateOptions::apparel_handles).
  std::string handle_source;
  /// Where the skinning weights came from: "the skinning predictor" or "the character's own skin ..."
  /// (AnimateOptions::skin_weights).
  std::string weights_source;
  /// What the apparel module read as the character's own physics (its response inputs, ApparelGraph::response):
  /// "the rig's ..." or "unknown ..."; empty when the module has no such inputs.
  std::string physics_source;
  /// How far the learned apparel swings: "as trained ..." or "calibrated on the rig's physics ..."
  /// (AnimateOptions::swing_calibration); empty without the local apparel module.
  std::string swing_source;
  /// What moved the apparel: "learned (the apparel module)" or "physics (...: the PMX model's own rigid bodies)".
  std::string apparel;
  /// True for --apparel physics: no bind, no penetration resolution.
  bool physics = false;
  std::string bind_path;
  bool bind_cache_hit = false;
  double bind_seconds = 0, load_seconds = 0, total_seconds = 0;
  /// Seconds spent fitting the swing calibration on the character's own physics (0 when it did not run).
  double calibration_seconds = 0;
  /// Per-frame wall time (model + penetration + output): median and 95th percentile.
  double frame_median = 0, frame_p95 = 0;
  /// Mean stage times per frame.
  FrameTimes mean;
  /// Apparel vertices inside the body, summed over frames, before and after resolution.
  Penetration before, after;
  /// Inside verdicts carried over from the previous frame, summed over frames (PenetrationReport).
  int64_t carried = 0;
  /// Apparel vertex-frames inside the body now and at rest, left where the model has them (PenetrationReport::tucked).
  int64_t tucked = 0;
  bool exact_motion = false;
};

/// The default bind cache path of an output: "<out without extension>.bind" (for an OBJ folder,
/// "<folder>.bind" beside it).
std::string default_bind_path(const std::string& out);

/// The rate the learned apparel module steps at: the frame rate of the data it was trained on (`amt dataset build`,
/// 30 fps). An output at another rate is interpolated between its steps, so the apparel swings the same way at 24,
/// 60 or 120 fps instead of faster or slower with the output rate.
inline constexpr float kApparelStepFps = 30.0f;

/// The rate `amt animate --apparel physics` steps a PMX model's physics at (each step of 2 Bullet substeps of
/// 1/240 s): a multiple of 24, 30, 60 and 120 fps, so frames at those rates fall on steps.
inline constexpr float kPhysicsStepFps = 120.0f;

/// The motions `amt animate` fits the learned apparel's swing on (fit_swing_on_motions, models/pipeline.h) when the
/// character carries physics amt simulates: files of the model folder, kCalibrationMotion and every other
/// kCalibrationMotionStem*.bvh, pooled; the first kSwingCalibrationSeconds of each run.
inline constexpr const char* kCalibrationMotion = "calibration_motion.bvh";
inline constexpr const char* kCalibrationMotionStem = "calibration_motion";

/// Runs the whole job. Throws amt::Error on bad input (before any output is created where it can be
/// checked up front); the output is complete or absent.
AnimateSummary animate(const AnimateOptions& options);

/// The summary as a few lines of text (frames, time per frame, penetration share before and after).
std::string describe(const AnimateSummary& summary);

}  // namespace amt
