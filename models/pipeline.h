#pragma once
// The full model's forward pass (paper section 4, docs/architecture.md, "The pipeline"), the one code path that the
// evaluation (eval/evaluate.h) and the CPU runtime (infer/) share:
//   load_model_bundle  the four trained modules from one folder of checkpoints;
//   bind_character     per-character work that depends only on the rest mesh (segmentation,
//                      skinning weights from geodesics, apparel graph), computed once;
//   PipelineStepper    per frame: B̂ = LBS of the body with the predicted weights (eq. 4), Â = the
//                      apparel step from the last 3 states (eq. 11), V̂ = refiner(tile(Â, B̂)) (eq. 16).
// All tensors are float32 on the CPU. Stages can be switched off for the ablations of Tables 2-4.
#include <ATen/core/Tensor.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/strain_limit.h"
#include "data_tools/geometry/types.h"
#include "models/apparel_displacement.h"
#include "models/apparel_dynamics.h"
#include "models/apparel_handles.h"
#include "models/apparel_segmenter.h"
#include "models/checkpoint.h"
#include "models/joint_refiner.h"
#include "models/skinning_predictor.h"

namespace amt {

// === Model bundle

/// The trained modules of one model folder, in eval mode, all trained on the same skeleton.
struct ModelBundle {
  /// The folder the checkpoints were read from ("" for a bundle assembled in code).
  std::string dir;
  /// J joint names shared by every checkpoint.
  std::vector<std::string> joint_names;
  /// f_c, f_s (the paper's geodesic-attention variant), f_d, f_j. f_d is in one of its two forms:
  /// apparel_dynamics (the local form, models/apparel_dynamics.h) or apparel (the earlier global
  /// form, models/apparel_displacement.h); exactly one is set.
  ApparelSegmenter segmenter{nullptr};
  SkinningPredictor skinning{nullptr};
  ApparelDisplacementNet apparel{nullptr};
  ApparelDynamicsNet apparel_dynamics{nullptr};
  /// The local apparel module for characters bound with given weights (BindOptions::weights: a file's own skin,
  /// the ground truth), trained on anchors from such weights (kApparelOwnWeightsCheckpoint); null: apparel_dynamics
  /// for every character. Its options match apparel_dynamics' (the same handles).
  ApparelDynamicsNet apparel_dynamics_own_weights{nullptr};
  JointRefiner refiner{nullptr};
  /// The Table 4 ablation variants of f_s, null when their checkpoints are absent.
  SkinningPredictor skinning_no_geodesic{nullptr};
  SkinningPredictor skinning_sorted{nullptr};
  /// The checkpoint infos, in the order segmenter, skinning, apparel, refiner (steps, fingerprints).
  std::vector<CheckpointInfo> infos;

  /// J.
  int64_t num_joints() const { return static_cast<int64_t>(joint_names.size()); }
  /// Whether f_d is the local form.
  bool local_apparel() const { return !apparel_dynamics.is_empty(); }
  /// The anchor of the apparel module (ApparelDynamicsOptions::anchor; "nearest" for the global form,
  /// whose skinned anchor is the nearest body vertex's), which binding gives every character.
  std::string apparel_anchor() const { return local_apparel() ? apparel_dynamics->options.anchor : "nearest"; }
  /// The local apparel module that steps a character bound with given weights (`given_weights`) or not.
  const ApparelDynamicsNet& apparel_dynamics_for(bool given_weights) const {
    return given_weights && !apparel_dynamics_own_weights.is_empty() ? apparel_dynamics_own_weights : apparel_dynamics;
  }
  /// f_d as a module, whichever form it is.
  const torch::nn::Module* apparel_module() const;
  /// The skinning predictor of `variant`: skinning, skinning_no_geodesic or skinning_sorted. Throws
  /// amt::Error naming the missing checkpoint when that variant was not loaded.
  SkinningPredictor skinning_for(SkinningVariant variant) const;
};

/// File names of the checkpoints in a model folder.
inline constexpr const char* kSegmenterCheckpoint = "segmenter.ckpt";
inline constexpr const char* kSkinningCheckpoint = "skinning.ckpt";
inline constexpr const char* kApparelCheckpoint = "apparel.ckpt";
inline constexpr const char* kRefinerCheckpoint = "refiner.ckpt";
/// Optional: the local apparel module for characters bound with their own skin weights
/// (ModelBundle::apparel_dynamics_own_weights).
inline constexpr const char* kApparelOwnWeightsCheckpoint = "apparel_own_weights.ckpt";
inline constexpr const char* kSkinningNoGeodesicCheckpoint = "skinning_no_geodesic.ckpt";
inline constexpr const char* kSkinningSortedCheckpoint = "skinning_sorted.ckpt";

/// Loads <dir>/segmenter.ckpt, skinning.ckpt, apparel.ckpt (either form, told apart by its options:
/// is_local_apparel_options), refiner.ckpt (required) and
/// skinning_no_geodesic.ckpt, skinning_sorted.ckpt (optional), builds each network from its stored
/// options and puts it in eval mode with gradients off. Throws amt::Error with a one-line reason for
/// a missing folder or file ("m/apparel.ckpt: no such checkpoint (train it with amt train apparel)"),
/// a file of another kind or version (models/checkpoint.h), a skinning variant file whose variant
/// differs from its name, or checkpoints trained on different skeletons.
ModelBundle load_model_bundle(const std::string& dir);

/// A bundle holding only the segmenter of `checkpoint` (and its joint names), enough for
/// apparel_probabilities: how a segmenter checkpoint alone is scored. Throws as load_model_bundle.
ModelBundle load_segmenter_bundle(const std::string& checkpoint);

/// Throws amt::Error unless `bundle` was trained on `joint_names` (same names, same order), naming
/// `source` (e.g. the dataset file) and both skeletons.
void check_bundle_skeleton(const ModelBundle& bundle, const std::vector<std::string>& joint_names,
                           const std::string& source);

// === Bind: per-character work

/// How bind_character decides the parts and weights.
struct BindOptions {
  /// (N) bool or 0/1 override of the apparel mask (ground truth, an artist's mask); undefined: the
  /// segmenter's p̂ > 0.5 (eq. 2).
  at::Tensor apparel_mask;
  /// Which skinning predictor gives the weights (Table 4); its checkpoint must be in the bundle.
  SkinningVariant skinning_variant = SkinningVariant::kGeodesicAttention;
  /// (N, J) weights that replace the predicted ones for every vertex (the skinning baseline with the
  /// ground-truth body weights); undefined: predicted.
  at::Tensor weights;
  /// Also predict weights for every vertex (BoundCharacter::vertex_weights), which the "body module
  /// only" ablation and the skinned start of a rollout need: geodesics over the whole mesh and the
  /// skinning predictor on all N vertices. Ignored when `weights` is given (it fills vertex_weights).
  bool all_vertex_weights = false;
  /// The character's own apparel bones (N vertex rows) as the apparel module's handles (bone_rig), when the
  /// module moves handles; null: handles picked automatically (apparel_rig at the module's spacing).
  std::shared_ptr<const ApparelBones> apparel_bones;
  /// The character's own apparel bones whose physics response (ApparelBones::response) feeds the apparel
  /// module's response inputs (BoundCharacter::apparel_response), whichever handles it moves; null: taken
  /// from apparel_bones; neither (or no response): unknown.
  std::shared_ptr<const ApparelBones> physics_bones;
  /// Calibrate the learned apparel's swing on the character's own physics (swing_calibration) when its response is
  /// known (BoundCharacter::apparel_response) and the local module that moves it has a swing_reference; false: the
  /// module as trained.
  bool calibrate_swing = true;
};

/// What the linked topology of a bound character found (BoundCharacter::topology_counts).
struct TopologyCounts {
  int64_t seam_links = 0, proximity_links = 0, refused_welds = 0;
  int64_t parts = 0, welded_parts = 0, linked_parts = 0;
};

/// What hang_apparel_pieces changed: pieces pinned, and body islands made apparel.
struct HungPieces {
  int pinned = 0, unnailed = 0;
};

/// Everything the per-frame step needs about one character, computed once from its rest mesh.
/// Vertex sets are ascending index lists; "body" is the complement of the apparel mask.
struct BoundCharacter {
  /// V (N, 3) rest positions, metres; faces (F, 3) int64; joints (J, 3) rest joint positions, metres.
  at::Tensor V, faces, joints;
  /// edges (E, 2) int64 unique mesh edges (i < j).
  at::Tensor edges;
  /// Whether the weights were given (BindOptions::weights) rather than predicted: such a character's apparel
  /// steps with ModelBundle::apparel_dynamics_for(true).
  bool given_weights = false;
  /// apparel_prob (N) float p̂ of the segmenter (computed even when the mask is overridden).
  at::Tensor apparel_prob;
  /// apparel_mask (N) bool, the mask in use: the override, or p̂ > 0.5 with each piece made to hang from one
  /// place (hang_apparel_pieces).
  at::Tensor apparel_mask;
  /// What hang_apparel_pieces changed in the segmenter's mask (zeros when the mask was given).
  HungPieces hung;
  /// refiner_prob (N) float, the apparel input of the refiner: the mask in use as 0/1, the form the
  /// refiner is trained with.
  at::Tensor refiner_prob;
  /// apparel_ids (N_a) and body_ids (N_b) int64.
  at::Tensor apparel_ids, body_ids;
  /// body_edges (E_b, 2), apparel_edges (E_a, 2) int64 mesh edges inside each part, numbered by
  /// position in body_ids / apparel_ids (induced_edges).
  at::Tensor body_edges, apparel_edges;
  /// apparel_neighbors (N_a, K_max) int64 neighbour table of the apparel graph (neighbor_table).
  at::Tensor apparel_neighbors;
  /// G_body (N_b, J) float geodesic distances (metres) over the body mesh (the faces with three body
  /// vertices), as the trainer computes them (train/samples.cpp); undefined when N_b = 0 or weights
  /// were overridden.
  at::Tensor G_body;
  /// body_weights (N_b, J) float skinning weights of the body vertices, rows sum to 1.
  at::Tensor body_weights;
  /// apparel_anchor_weights (N_a, J) float: each apparel vertex's nearest body vertex's row of
  /// body_weights (apparel_anchor_weights), which skin the apparel network's anchor S^(t).
  at::Tensor apparel_anchor_weights;
  /// The local apparel module's per-character inputs (ApparelGraph): each apparel vertex's frame
  /// joint (N_a) int64 and rest channels (N_a, kApparelRestChannels) float.
  at::Tensor apparel_frame_joints, apparel_rest_features;
  /// Its contact inputs (ApparelGraph::contact_rest (N_a, 3), contact_weights (N_a, J) float).
  at::Tensor apparel_contact_rest, apparel_contact_weights;
  /// Its chain ancestors (ApparelGraph::ancestors (N_a, kApparelReachLevels) int64).
  at::Tensor apparel_ancestors;
  /// Its physics inputs (ApparelGraph::response (N_a, 3) float) from the apparel bones' response
  /// (BindOptions::apparel_bones with ApparelBones::response); undefined when unknown.
  at::Tensor apparel_response;
  /// (N_a) float: the gain on the learned apparel's swing away from its anchor, per apparel vertex
  /// (swing_calibration; BindOptions::calibrate_swing); undefined: none (the module as trained).
  at::Tensor apparel_swing_gain;
  /// vertex_weights (N, J) float weights of every vertex (BindOptions::all_vertex_weights or
  /// BindOptions::weights); undefined otherwise.
  at::Tensor vertex_weights;
  /// graph_edges (E', 2) int64 the linked topology (linked_topology, data_tools/geometry/apparel_topology.h):
  /// the mesh edges, a seam link from every vertex to the vertex it coincides with, and proximity links
  /// between apparel pieces that lie within a few millimetres of each other. The parts, the apparel graph,
  /// the attachment paths and the handles are built on it, so that coincident copies are one point.
  at::Tensor graph_edges;
  /// topology_counts (6) int64: seam links, proximity links, welds refused (a given mask splits the
  /// pair), connected parts of the mesh, with seams welded, and with every link (TopologyCounts).
  at::Tensor topology_counts;
  /// The apparel module's handles (ApparelDynamicsOptions::handle_spacing > 0; ApparelRig,
  /// models/apparel_handles.h); undefined for the per-vertex form.
  at::Tensor handle_rows, handle_vertex_handles, handle_vertex_weights, handle_edges;

  int64_t num_vertices() const { return V.size(0); }
  int64_t num_apparel() const { return apparel_ids.size(0); }
  int64_t num_body() const { return body_ids.size(0); }
  /// The ApparelGraph of the local apparel module (neighbour table, frame joints, rest channels).
  ApparelGraph apparel_graph() const {
    return {apparel_neighbors,       apparel_frame_joints, apparel_rest_features, apparel_contact_rest,
            apparel_contact_weights, apparel_ancestors,    apparel_response};
  }
  /// The handles as a rig (undefined rows for the per-vertex form).
  ApparelRig rig() const { return {handle_rows, handle_vertex_handles, handle_vertex_weights, handle_edges}; }
  /// topology_counts by name.
  TopologyCounts topology() const;
};

/// The share of a floating piece held by the body (hang_apparel_pieces).
inline constexpr double kFloatingPiecePinShare = 0.05;

/// The segmenter's mask made to hang from the body as the dataset's pieces do: each piece hangs from one place, a
/// single region of its first rows that a body bone holds rigidly and the ground truth calls body (4-27 % of a
/// piece). For every connected part of the mesh (by `edges`) that the mask calls at least half apparel:
/// - with no body vertex (on a mesh with body elsewhere) it would float free and drift off the character (the
///   apparel module learned pieces that are held): its ceil(share * size) vertices of lowest p̂ become body;
/// - with several body islands (body vertices joined by body-body edges) it would be nailed to the body mid-way
///   (strands torn where the mask misses a few vertices): the largest island stays, the others become apparel.
/// Parts mostly body are left alone. mask (N) bool, prob (N) float; returns the new mask.
at::Tensor hang_apparel_pieces(const at::Tensor& mask, const at::Tensor& prob, const MatrixX2i& edges,
                               double share = kFloatingPiecePinShare, HungPieces* hung = nullptr);

/// The segmenter's p̂ (N) (eq. 2) of a rest mesh (V, F) with rest joints on the bundle's skeleton (J, 3),
/// its shape features computed here (segmentation_features). Throws amt::Error on a mesh without
/// faces when the segmenter reads shape features. Runs without gradients.
at::Tensor apparel_probabilities(const ModelBundle& bundle, const MatrixX3f& V, const MatrixX3i& F,
                                 const MatrixX3f& joints);

/// Binds a character to the model:
///   V (N, 3) float rest positions (metres), F (F, 3) int32/int64 faces, joints (J, 3) float rest
///   joint positions on the bundle's skeleton.
/// Throws amt::Error for shapes that do not match (naming the argument and the expected shape), a
/// joint count other than the bundle's, an override mask of the wrong length, or a body part without
/// faces when weights are to be predicted. Runs without gradients; deterministic.
BoundCharacter bind_character(const ModelBundle& bundle, const at::Tensor& V, const at::Tensor& F,
                              const at::Tensor& joints, const BindOptions& options = {});

// === Starting a motion

// kDefaultLeadInFrames (data_tools/geometry/motion.h): the frames of motion_lead_in that evaluation's rollout
// protocol and the runtime put before a clip's first frame, so that both start a clip identically.

/// The rest pose as joint transforms (frames, J, 3, 4): R = I, t = the rest joint (J, 3) positions.
at::Tensor rest_pose_transforms(const at::Tensor& rest_joints, int64_t frames);

/// A history of 3 copies of the rest apparel positions: (3, N_a, 3). With the motion blended in from
/// the rest pose (motion_lead_in) this starts a user's clip with nothing but the rest mesh.
at::Tensor rest_apparel_history(const BoundCharacter& character);

/// Joint transforms (frames, J, 3, 4) that move the skeleton from its rest pose (R = I, t = J_rest)
/// to `first` (J, 3, 4), the first frame of a motion: per joint, rotations slerped and positions
/// interpolated linearly at s = lead_in_weight(k, frames) (eased in and out), k = 0 .. frames - 1 (the frame `first`
/// itself is not included). frames = 0 gives (0, J, 3, 4).
at::Tensor motion_lead_in(const at::Tensor& first, const at::Tensor& rest_joints, int64_t frames);

// === Per-frame stepping

/// Which stages run (paper Table 3) and what a step returns.
enum class PipelineStages {
  /// Every vertex skinned with BoundCharacter::vertex_weights (the body module only; with the
  /// ground-truth weights, the skinning baseline of Table 2). Needs vertex_weights.
  kBodyOnly,
  /// B̂ and Â tiled into mesh order, no refiner.
  kBodyApparel,
  /// The full model: V̂ = refiner(tile(Â, B̂)) (eq. 16).
  kFull,
};

/// "body_only", "body_apparel", "full".
const char* pipeline_stages_name(PipelineStages stages);

/// The learned apparel's default stretch limit (PipelineStepper::set_strain_limit): an apparel edge at most this
/// many times its rest length, by a few projections per frame. Chosen on the held-out characters (CHANGELOG.md,
/// "The stretch limit and the runtime on artist-style remakes"); `amt animate --strain-limit`, `amt eval
/// --strain-limit` change it (0: off).
inline constexpr float kDefaultStrainLimit = 1.2f;
/// Its bound on compression (an apparel edge at least this many times its rest length; 0: none). The learned
/// apparel moves handles that the vertices follow; where neighbouring handles close in, edges between them squash
/// to a fraction of their length. A floor of 0.7 takes the artist-style remakes' rollout tearing from 0.52 to
/// 0.48 % and their paper-protocol tearing from 0.53 to 0.36 %, with PMD_a unchanged (docs/runtime.md, "Stretch
/// limit").
inline constexpr float kDefaultStrainFloor = 0.7f;
/// The most projections per frame; they stop once every edge is within its bounds.
inline constexpr int kStrainLimitIterations = 32;

/// What moves the apparel in kBodyApparel and kFull: the apparel module, or one of the zero-network
/// rules on the same detail vectors (models/apparel_dynamics.h detail_rule_step): hold_offset
/// (d_t = d_{t-1}) or inertial (d_t = d_{t-1} + inertia (d_{t-1} - d_{t-2})).
enum class ApparelSource { kNetwork, kHoldOffset, kInertial };

/// One frame's result.
struct StepOutput {
  /// V̂ (N, 3) in mesh order, metres.
  at::Tensor V_hat;
  /// B̂ (N_b, 3) and Â (N_a, 3) before tiling (undefined for kBodyOnly, where V̂ is B̂ of every vertex).
  at::Tensor B_hat, A_hat;
  /// (H, 3) the handles the apparel module moved, before the swing gain (its own state); undefined when the module
  /// moves vertices.
  at::Tensor A_handles;
};

/// Wall time of the stages of one step, seconds (PipelineStepper::step with a StepTimes to fill).
///   lbs       B̂ = LBS of the skinned vertex set (eq. 4)
///   apparel   Â = the apparel step (eq. 11) and the history update (0 without apparel or kBodyOnly)
///   refiner   tile(Â, B̂) and the refiner (eq. 16) (the tile alone for kBodyApparel; 0 for kBodyOnly)
struct StepTimes {
  double lbs = 0, apparel = 0, refiner = 0;
  double total() const { return lbs + apparel + refiner; }
};

/// Runs the model frame by frame on one bound character. Holds references to the bundle and the
/// character (both must outlive the stepper) and the apparel history, the last 3 predicted states.
/// Every step runs under c10::InferenceMode; outputs are inference tensors (clone() to use them in
/// autograd). Per frame it does only LBS, the apparel step and the refiner: nothing of bind is redone,
/// and the refiner's constant inputs (rest positions, mask) pass its first layer once, at construction
/// (JointRefinerImpl::prepare), so the refiner's parameters must not change while the stepper is used.
class PipelineStepper {
 public:
  /// history (3, N_a, 3): A^(t-3), A^(t-2), A^(t-1), oldest first (rest_apparel_history, or ground
  /// truth for the paper protocol). Throws amt::Error for a history of another shape, or kBodyOnly
  /// without vertex_weights.
  /// `source` and `inertia` choose what moves the apparel (ApparelSource); the history's frames are at
  /// the rest pose (see reset).
  PipelineStepper(const ModelBundle& bundle, const BoundCharacter& character, const at::Tensor& history,
                  PipelineStages stages = PipelineStages::kFull, ApparelSource source = ApparelSource::kNetwork,
                  double inertia = 0.0);

  /// Predicts the next frame from its joint transforms T^(t) (J, 3, 4) and appends Â^(t) to the
  /// history -> V̂ (N, 3). `times`, when given, receives the wall time of each stage.
  at::Tensor step(const at::Tensor& joint_transforms, StepTimes* times = nullptr);

  /// As step, keeping B̂ and Â.
  StepOutput step_detailed(const at::Tensor& joint_transforms, StepTimes* times = nullptr);

  /// Replaces the history (3, N_a, 3) and the frame counter (e.g. at the start of a new window).
  /// history_transforms (3, J, 3, 4) are the motion of the history's frames, which the local apparel
  /// module and the rules measure detail vectors against; undefined: the rest pose.
  void reset(const at::Tensor& history, const at::Tensor& history_transforms = {});

  /// The current history (3, N_a, 3), oldest first.
  const at::Tensor& history() const { return history_; }
  /// Steps taken since construction or the last reset.
  int64_t frames() const { return frames_; }

  /// Limits the stretch of the learned apparel's edges (StrainLimiter, data_tools/geometry/strain_limit.h) to
  /// `max_stretch` times their rest length and their squash to `min_stretch` times it, over the mesh edges with an
  /// apparel end and the welded seams (not the proximity links between pieces), moving apparel vertices only, after
  /// every step of the local apparel module (not the rules', not the global form's, which the paper's comparisons
  /// run as published); the limited Â is the output and the history. 0 turns it off. The stepper starts with
  /// kDefaultStrainLimit and kDefaultStrainFloor.
  void set_strain_limit(float max_stretch, int iterations = kStrainLimitIterations,
                        float min_stretch = kDefaultStrainFloor);
  float strain_limit() const { return strain_.empty() ? 0.0f : strain_.max_stretch(); }
  PipelineStages stages() const { return stages_; }

  /// Whether the apparel vertices follow the module's handles turning (follow_turning_handles, the default) or by
  /// their offsets alone (follow_handles, as the module trains).
  void set_turning_handles(bool on) { turning_handles_ = on; }
  bool turning_handles() const { return turning_handles_; }

 private:
  const ModelBundle& bundle_;
  const BoundCharacter& character_;
  PipelineStages stages_;
  ApparelSource source_;
  double inertia_;
  at::Tensor history_;
  // Local module and rules: the transforms (3, J, 3, 4) and anchors (3, N_a, 3) of the history's frames.
  at::Tensor history_transforms_, history_anchors_;
  int64_t frames_ = 0;
  // Per-character constants of LBS: weights and rest positions of the skinned vertex set.
  at::Tensor lbs_rest_, lbs_weights_;
  // Per-character constants of the refiner (kFull): its first layer on the rest mesh and the mask.
  RefinerCharacter refiner_character_;
  // The module on handles (ApparelDynamicsOptions::handle_spacing > 0): the rig, the module's graph over
  // the handles, and the handles' own history (3, H, 3) and its anchors.
  ApparelRig rig_;
  ApparelGraph handle_graph_;
  at::Tensor handle_history_, handle_history_anchors_;
  bool turning_handles_ = true;
  // The learned apparel's stretch limit over the apparel (free) and body (fixed) vertices; empty: off.
  StrainLimiter strain_;
  // (N_a, 1) the swing gain of the character (BoundCharacter::apparel_swing_gain) for the local module; undefined:
  // none.
  at::Tensor swing_gain_;
  // (H, 1) the swing gain at the handles when the module moves handles: applied before the vertices follow them.
  at::Tensor handle_gain_;
};

// === Calibrating the swing on the character's own physics

/// The learned apparel on a rig stiffer than any it trained on: a module that learned the builder's chains swings a
/// VRM avatar's stiff spring bones, or a PMX model's nearly locked accessories, as if they were loose (on the
/// Godette avatar 3.2 cm from its own physics, where rigid skinning is 0.56 cm off). When the character's own physics
/// response is known (BoundCharacter::apparel_response, the rig probe of data_tools/geometry/rig_probe.h) and the
/// module knows the least lively apparel it trained on (ApparelDynamicsOptions::swing_reference), each apparel piece
/// whose rig swings less than that is calmed in proportion: per connected part of the apparel over the linked
/// topology, gain = clamp(mean over its vertices of share x (swing during + after) / swing_reference, 0, 1). The
/// stepper then outputs S + gain (Â - S) and keeps the module's own Â as its history: the module runs as trained and
/// only what it shows is scaled; a gain that is the same over a piece cannot tear it. On rigs as lively as the
/// training data's every gain is 1. A fitted gain may exceed 1 (fit_swing_calibration, up to kMaxSwingGain): on
/// handles it scales the handles' offsets before the vertices follow them turning (StepOutput::A_handles keeps the
/// module's own), and a module that moves vertices is not livened.
struct SwingCalibration {
  /// (N_a) float gain per apparel vertex (BoundCharacter::apparel_swing_gain); undefined from apparel_piece_swing.
  at::Tensor gain;
  /// (N_a) int64 each apparel vertex's piece; (P) float per piece: its gain (undefined from apparel_piece_swing) and
  /// its rig's mean swing over its vertices (share x (during + after), per unit of sway); (P) int64 its vertices.
  at::Tensor piece_of, piece_gain, piece_swing, piece_vertices;
};

/// The apparel's pieces and their rigs' swing: response (N_a, kApparelResponseChannels) (ApparelGraph::response),
/// apparel_edges (E_a, 2) int64 positions in the apparel list (BoundCharacter::apparel_edges: the linked topology).
/// Throws amt::Error on shapes that do not match.
SwingCalibration apparel_piece_swing(const at::Tensor& response, const at::Tensor& apparel_edges);

/// The swing calibration of a bound character with the reference `swing_reference` (> 0). Throws amt::Error when the
/// character's physics response (apparel_response) is undefined or the reference is not positive.
SwingCalibration swing_calibration(const BoundCharacter& character, double swing_reference);

/// The reference of the calibration from training data: the least swing of the pieces (apparel_piece_swing) of
/// the training characters, so that the calibration acts only outside what the module was trained on (the 1 %
/// quantile of the pieces, weighted by vertices, 0.3247 on data/default, also calmed pieces of held-out character 29
/// whose rig swings 0.25, where the module was right, and cost 0.04 cm there: models/pretrained/README.md). 0
/// without pieces.
double swing_reference(const std::vector<SwingCalibration>& characters);

/// The swing calibration fitted on the character's own physics over a calibration motion: the module (uncalibrated)
/// and the character's own simulation run through the same motion, and each apparel piece gets the scale that brings
/// the module's offsets from the anchor skinning closest to the simulation's, in least squares:
/// scale = clamp(sum <Â - S, G - S> / sum |Â - S|^2, 0, kMaxSwingGain) over the piece's vertices and the frames (1 for
/// a piece the module does not move). The gain is the scale where the module loses to rigid skinning on the motion
/// (scale < 1/2, the same as |Â - G|^2 > |S - G|^2), 1 where it clearly wins (3/4 <= scale <= 1), 2 scale - 1/2
/// between, and the scale above 1: a piece whose learned swing is unrelated to the rig's is calmed towards rigid
/// skinning, one whose swing follows it keeps it, and one that swings in step with the rig but less far is livened.
///   A_hat, S, G (T, N_a, 3): the module's apparel, its anchor skinning and the simulation's, on the same frames;
///   apparel_edges (E_a, 2) int64 positions in the apparel list (the pieces). Throws amt::Error on shapes that do
///   not match or non-finite input.
SwingCalibration fit_swing_calibration(const at::Tensor& A_hat, const at::Tensor& S, const at::Tensor& G,
                                       const at::Tensor& apparel_edges);

/// The largest gain of a fitted swing calibration (fit_swing_calibration): a piece the module moves in step with the
/// rig's physics but less far than it (least-squares scale above 1) swings up to this much further. On the PMX export
/// of held-out character 13, whose scale is 1.5 and more, 1.25 measured best (docs/runtime.md, "Livened swing"): at 1.5
/// it was farther from its physics again and tore more where the twin tails are pushed out of the back.
inline constexpr double kMaxSwingGain = 1.25;

/// How much of each motion the fitted swing calibration runs (fit_swing_on_motions): `amt animate`'s calibration
/// motions, `amt eval`'s other clips of the character.
inline constexpr double kSwingCalibrationSeconds = 4.0;
/// How many of a character's other clips `amt eval` fits the swing on (its first clips the evaluation does not score),
/// as many as `amt animate` has calibration motions in the shipped model folder: pooled over two dances, a piece's gain
/// hangs less on one motion's phase (models/pretrained/README.md).
inline constexpr int kSwingCalibrationClips = 2;

/// fit_swing_calibration on one motion: the module (the character's own gain set aside) with
/// PipelineStages::kBodyApparel and the stretch limit `strain_limit` (PipelineStepper::set_strain_limit) through
/// `motion` (T, J, 3, 4), beside the anchor skinning of each frame, fitted to `truth` (T, N_a, 3), the simulation's
/// apparel on the same frames. With window = 0 the module rolls out from the rest apparel over `lead_in`
/// (L, J, 3, 4) and then the whole motion (`amt animate`, and `amt eval`'s rollout protocol); with window > 3 it
/// predicts windows of `window` frames at a stride of window - 3, each started from the truth's 3 frames before it
/// (the paper protocol; lead_in unused), and the fit sees the predicted frames. What `amt animate` does with each
/// calibration motion and `amt eval` with each other clip of the character (fit_swing_on_motions). Throws amt::Error on
/// shapes that do not match or a motion too short for one window.
SwingCalibration fit_swing_on_motion(const ModelBundle& bundle, const BoundCharacter& character,
                                     const at::Tensor& lead_in, const at::Tensor& motion, const at::Tensor& truth,
                                     float strain_limit = kDefaultStrainLimit, int64_t window = 0);

/// One motion of a fitted swing calibration (fit_swing_on_motions): lead_in (L, J, 3, 4), motion (T, J, 3, 4) and the
/// simulation's apparel on the motion's frames, truth (T, N_a, 3).
struct SwingCalibrationMotion {
  at::Tensor lead_in, motion, truth;
};

/// fit_swing_on_motion over several motions at once: each runs as fit_swing_on_motion runs its one, and the fit pools
/// their frames (every piece gets one scale over all of them), so that a piece's gain does not hang on one motion's
/// phase. Throws amt::Error as fit_swing_on_motion does, naming the shape that does not match, or without motions.
SwingCalibration fit_swing_on_motions(const ModelBundle& bundle, const BoundCharacter& character,
                                      const std::vector<SwingCalibrationMotion>& motions,
                                      float strain_limit = kDefaultStrainLimit, int64_t window = 0);

/// Whole-sequence convenience over PipelineStepper: joint_transforms (T, J, 3, 4) -> V̂ (T, N, 3).
at::Tensor run_pipeline(const ModelBundle& bundle, const BoundCharacter& character, const at::Tensor& history,
                        const at::Tensor& joint_transforms, PipelineStages stages = PipelineStages::kFull);

}  // namespace amt
