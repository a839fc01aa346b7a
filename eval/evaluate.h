#pragma once
// Evaluation of a trained model on a dataset's held-out data (docs/evaluation.md; paper 5.3 and
// Tables 2-4): every method runs through the one forward path of models/pipeline.h, and is scored with
// data_tools/geometry/metrics.h (PMD, PMD_a, PMD_b in cm, ELS, penetration share and depth; vertex -> frame ->
// clip averaging of ScoreAccumulator) in two protocols:
//   "paper"    windows of `window` (10) frames at a stride of window - 3, the first 3 apparel states
//              from ground truth, metrics over the window - 3 predicted frames (every frame from the
//              4th on is predicted exactly once);
//   "rollout"  the whole clip, apparel started from the rest pose with the motion blended in from the
//              rest pose (motion_lead_in, kDefaultLeadInFrames), as a user runs it.
// Two subsets: "held-out characters" (clips of characters whose split is test) and "held-out clips"
// (clips whose split is test, of characters whose split is train). With EvaluateOptions::artist_style the
// held-out characters are remade as artists build models (data_tools/builder/artist_style.h) and their ground
// truth with them; their subset is then "held-out characters, artist-style".
// Beside PMD and ELS, what shows a prediction falling apart (data_tools/builder/artist_style.h,
// SeparationScores): tearing of apparel edges, the gap opening between vertices that coincide at rest (a
// seam's copies), and ELS over apparel edges; per character, and per table row as the mean over the subset's
// characters with its worst character beside it.
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "data_tools/builder/artist_style.h"
#include "data_tools/geometry/metrics.h"
#include "infer/runtime_benchmark_torch.h"
#include "models/pipeline.h"

namespace amt {

// === Options

/// Methods, by key (paper Tables 2-4):
///   skinning_baseline  every vertex, apparel included, skinned with the ground-truth body weights;
///   hold_offset        zero-network rule: the body skinned with the ground-truth weights, each apparel
///                      vertex's detail vector (its offset from its skinned anchor, in its frame joint's
///                      frame) carried along unchanged (models/apparel_dynamics.h detail_rule_step);
///   inertial           zero-network rule: the detail vector continues with its last velocity, damped
///                      by the inertia least-squares fitted on training clips (InertiaFit);
///   apparel_gt         the apparel module on the same bind as the rules (ground-truth mask and
///                      weights, no refiner): the module itself, measured exactly as the rules are;
///   lbs_predicted      every vertex skinned with predicted weights ("body module only");
///   body_apparel       B̂ and Â tiled, no refiner;
///   full               the full model (predicted mask);
///   full_gt_mask       the full model with the ground-truth apparel mask (Table 4's "G + attention");
///   no_geodesic, sort_by_geodesic  the full model, ground-truth mask, with the ablation skinning
///                      predictors of Table 4 (only when their checkpoints are in the model folder).
///   cloth_retarget     on clips that are the target of a garment pair (data_tools/builder/garment_pairs.h): the
///                      apparel of the pair's other body, simulated under the same motion, retargeted onto
///                      this clip's ground-truth body (data_tools/garment/cloth_retarget.h); no network;
///   cloth_retarget_unresolved  the same without the push-out of apparel vertices inside the body.
std::vector<std::string> evaluation_methods();

/// Human-readable label of a method key ("Full model (GT mask)").
std::string method_label(const std::string& method);

/// What evaluate_model runs.
struct EvaluateOptions {
  /// Run the "paper" and / or the "rollout" protocol.
  bool paper = true, rollout = true;
  /// Evaluate at most this many clips per subset (0: all), the first in file order.
  int max_clips = 0;
  /// Methods to run (keys of evaluation_methods(); empty: all that the bundle supports).
  std::vector<std::string> methods;
  /// Paper protocol window T; the first 3 frames of each window are ground-truth history.
  int window = 10;
  /// Rollout frames (1-based: the k-th predicted frame of a clip) at which PMD_a is reported.
  std::vector<int> rollout_frames = {10, 100, 300};
  /// Measure penetration (a winding-number tree of the predicted body per frame and method).
  bool penetration = true;
  /// Print progress (clips done / total, rate, ETA) on stderr.
  bool progress = true;
  /// Evaluate the held-out characters remade artist-style (artist_style_character with these options; every
  /// method binds the remade mesh, the ground truth is remade by remake_frames) instead of as built.
  bool artist_style = false;
  ArtistStyleOptions artist_style_options;
  /// On characters whose rig has apparel bones (rig_apparel_bones), the binds on the ground-truth mask (the rig's
  /// mask, as `amt animate` uses it by default) move the apparel module's handles at the rig's bones (bone_rig)
  /// instead of handles picked automatically.
  bool rig_handles = false;
  /// The learned apparel's stretch limit in every method that runs the apparel module
  /// (PipelineStepper::set_strain_limit; 0: off, the module's raw output).
  float strain_limit = kDefaultStrainLimit;
  /// Calibrate the learned apparel's swing on each character's own physics when its rig carries a response
  /// (BindOptions::calibrate_swing, swing_calibration in models/pipeline.h).
  bool calibrate_swing = true;
  /// With calibrate_swing: fit the swing instead on other clips of the character (fit_swing_on_motions): its first
  /// kSwingCalibrationClips clips in file order that the evaluation does not score, else its first other clips, the
  /// first kSwingCalibrationSeconds of each, pooled; what `amt animate` does with its calibration motions. A character
  /// with a single clip keeps the probe's calibration.
  bool fit_swing = true;
  /// evaluate_predictions: also score a file without the mark of predictions (ground truth, e.g. a dataset
  /// rebuilt with other physics scored against the original); refused otherwise, as it would score perfect.
  bool ground_truth_as_predictions = false;
};

// === Results

/// One table row: a method's scores in one protocol on one subset.
struct MethodScores {
  std::string method, protocol, subset;
  MotionScores scores;
  /// Dynamics amplitude: mean over frames of mean |Â - S| over apparel vertices, divided by the same
  /// for the ground truth, with S the apparel skinned by the dataset's ground-truth body weights (the
  /// skinning baseline's apparel): 0 = glued to the body, 1 = as lively as the simulation. NaN
  /// without apparel.
  double amplitude = std::nan("");
  /// Falling apart: each measure's mean over the subset's characters that have it (pairs and counts summed),
  /// and its worst character (largest tearing and seam gaps, smallest apparel ELS) with the character's name.
  SeparationScores separation, worst;
  std::string worst_tearing, worst_seam_gap_p95, worst_seam_gap_max, worst_apparel_els;
};

/// Scores of one character (all its evaluated clips).
struct CharacterScores {
  std::string character, subset;
  int num_vertices = 0, num_apparel = 0;
  /// Predicted mask (p̂ > 0.5) against the ground truth.
  SegmentationScores segmentation;
  /// Share of the character's bare body (its largest connected part, segmented alone) called apparel.
  double bare_apparel_share = std::nan("");
  /// The segmenter on the character remade of open parts as real models are (open_parts_example): IoU, and the
  /// share of its bare version called apparel. NaN when it cannot be remade (a PMX model's layout).
  double open_parts_iou = std::nan(""), bare_open_parts_share = std::nan("");
  /// method -> protocol -> scores, for the skinning baseline and the full model.
  std::map<std::string, std::map<std::string, MotionScores>> scores;
  /// method -> protocol -> the measures of falling apart, for every method.
  std::map<std::string, std::map<std::string, SeparationScores>> separation;
  /// How the evaluated mesh is built (parts, coincident copies), and whether it is an artist-style remake.
  MeshConstruction construction;
  bool artist_style = false;
};

/// PMD_a (cm) of a method per rollout frame (or per predicted frame of a paper-protocol window),
/// averaged over the clips that are that long.
struct RolloutCurve {
  std::string subset, method;
  /// pmd_a[k] is the mean PMD_a of predicted frame k + 1; clips[k] how many clips reached it.
  std::vector<double> pmd_a;
  std::vector<int> clips;
};

/// One scored clip: its PMD_a (cm) under one method and protocol, the mean over its scored frames.
///   shard  index into EvaluationResult::shards
struct ClipScore {
  std::string subset, clip, character, method, protocol;
  int shard = 0;
  double pmd_a = std::nan("");
};

/// Everything an evaluation measured.
struct EvaluationResult {
  /// Dataset shards, model folder (or the predictions file) evaluated.
  std::vector<std::string> shards;
  std::string model_dir, predictions;
  /// Rows of every method, protocol and subset that had clips.
  std::vector<MethodScores> rows;
  /// subset -> segmentation scores averaged over its characters.
  std::map<std::string, SegmentationScores> segmentation;
  /// subset -> share of the bare bodies' vertices called apparel (CharacterScores::bare_apparel_share),
  /// averaged over its characters.
  std::map<std::string, double> bare_apparel_share;
  /// subset -> (open-parts IoU, bare open parts called apparel) averaged over the characters that have an
  /// open-parts version (CharacterScores::open_parts_iou).
  std::map<std::string, std::pair<double, double>> open_parts;
  std::vector<CharacterScores> characters;
  std::vector<RolloutCurve> curves;
  /// Paper protocol per horizon: pmd_a[k] is the mean PMD_a of the (k + 1)-th predicted frame of the
  /// windows (k = 0: teacher-forced one step, from 3 ground-truth states).
  std::vector<RolloutCurve> horizons;
  /// The inertia of the inertial rule and the number of training clips it was fitted on (0: not run).
  double inertia = std::nan("");
  int inertia_clips = 0;
  /// subset -> number of clips evaluated.
  std::map<std::string, int> clips;
  /// Every clip's PMD_a per method and protocol, in evaluation order (the viewer's picks).
  std::vector<ClipScore> clip_scores;
  /// Runtime measurements (`amt eval --runtime`, infer/runtime_benchmark_torch.h; empty: not measured).
  std::vector<RuntimeFigures> runtime;
  /// Things the report must say (missing ablation checkpoints, clips too short for a window, ...).
  std::vector<std::string> notes;
  /// The options used.
  EvaluateOptions options;
  /// Wall time (seconds).
  double seconds = 0;

  /// The row of (method, protocol, subset), or null.
  const MethodScores* find(const std::string& method, const std::string& protocol, const std::string& subset) const;
};

/// Subset names.
inline constexpr const char* kHeldOutCharacters = "held-out characters";
inline constexpr const char* kHeldOutClips = "held-out clips";
/// The held-out characters remade artist-style (EvaluateOptions::artist_style).
inline constexpr const char* kHeldOutArtistStyle = "held-out characters, artist-style";

// === Evaluation

/// Evaluates `bundle` on the held-out clips of the shards (resolve_shards). Throws amt::Error for a
/// dataset whose skeleton differs from the model's, unknown method keys, or no held-out clips at all.
/// Deterministic for a given thread count.
EvaluationResult evaluate_model(const ModelBundle& bundle, const std::vector<std::string>& shards,
                                const EvaluateOptions& options);

/// Scores a dataset file of predicted vertices (e.g. written by `amt animate --out x.h5`) against the
/// ground truth of the shards: every held-out clip of the shards that the predictions file has (same
/// clip name, same character vertex count and frame count) is scored over all its frames as method
/// "predictions", protocol "file". The predicted character's rest mesh must be the ground truth's, its vertices
/// in any order (rest_vertex_match: a dataset built from a PMX model puts the body first, `amt animate` keeps
/// the file's order). Throws amt::Error for a missing file, a file without the mark of predictions (unless
/// options.ground_truth_as_predictions), mismatched shapes or rest meshes, no clip in common, or
/// options.artist_style (a predictions file is of the characters as built).
EvaluationResult evaluate_predictions(const std::vector<std::string>& shards, const std::string& predictions,
                                      const EvaluateOptions& options);

/// For each vertex of the rest mesh `truth` (N, 3), the row of `predicted` (N, 3) at the same place: the identity
/// when the two agree row by row within `tolerance` (metres), else the match of equal positions after sorting both
/// (copies of one position paired in index order). Empty when the meshes do not hold the same positions.
std::vector<int32_t> rest_vertex_match(const MatrixX3f& truth, const MatrixX3f& predicted, float tolerance = 1e-5f);

/// The result as JSON text (NaN as null): rows, segmentation, characters, curves, notes.
std::string evaluation_json(const EvaluationResult& result);

// === Clips to look at (`amt eval --viewer`)

/// A clip picked from an evaluation: the "worst", "median" or "best" of its subset by the full model's
/// PMD_a in `protocol` (rollout when it ran, else paper).
struct ViewerPick {
  ClipScore score;
  std::string pick;
};

/// The worst, median and best clip of each subset by the full model's PMD_a (fewer when a subset has
/// fewer clips; each clip once). Empty when the full model was not evaluated.
std::vector<ViewerPick> viewer_picks(const EvaluationResult& result);

/// The three sequences of a picked clip, each T frames of #V by 3 positions (metres) over faces F:
/// the full model rolled out from the rest pose over the whole clip (as the "rollout" protocol and
/// `amt animate` run it, without penetration resolution), the ground truth, and the skinning baseline
/// (every vertex skinned by the ground-truth body weights). `mask` is the ground-truth apparel mask.
struct ViewedClip {
  MatrixX3i F;
  std::vector<uint8_t> mask;
  float fps = 30.0f;
  std::vector<MatrixX3f> prediction, ground_truth, skinning;
};

/// Runs `bundle` on the picked clip of `result.shards` (its first `max_frames` frames; 0: all).
ViewedClip view_clip(const ModelBundle& bundle, const EvaluationResult& result, const ViewerPick& pick, int max_frames);

}  // namespace amt
