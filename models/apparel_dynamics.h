#pragma once
// The apparel module f_d in local, normalised, second-order form: the default apparel module.
// Paper eq. 11-13 keep their shape (K = 3 past states, conditioning on the body's motion, EdgeConv
// blocks over the apparel graph grouped by component, an MLP decoder); what changes is the
// coordinates, the way learned cloth simulators that generalise to unseen garments and bodies do it
// (MeshGraphNets, HOOD, Deep Emulator, NeRD):
//   - every apparel vertex i has an anchor S_i, the rest apparel skinned with the weights of its
//     nearest body vertex (apparel_anchor_weights), and a frame R_i, the rotation of that anchor's
//     dominant joint;
//   - its state is the detail vector d_i = R_i^T (A_i - S_i): how far the apparel has swung away
//     from where rigid skinning carries it, in the frame that carries it;
//   - every input is a vector in that frame, or a rest-pose quantity: no absolute position, no world
//     orientation except gravity's direction, so a rigid motion of the whole animation about the
//     gravity axis changes nothing;
//   - inputs and target are normalised by statistics gathered from training data before the first
//     optimizer step and then frozen (stored in the checkpoint with the parameters);
//   - the network predicts the change of d around a rule: with zero output d_t = d_{t-1} +
//     inertia (d_{t-1} - d_{t-2}); inertia = 0 is hold_offset, "carry the current offset along with
//     the anchor's joint", so a fresh network (zero-initialised last layer) starts as that rule.
// ApparelDisplacementNet (models/apparel_displacement.h) keeps the earlier global form for the
// ablation tables; checkpoints say which form they hold (ApparelDynamicsOptions::form).
#include <torch/nn/module.h>
#include <torch/nn/pimpl.h>

#include <cstdint>
#include <string>
#include <vector>

#include "models/edge_conv.h"
#include "models/mlp.h"

namespace amt {

// === Per-character inputs

/// What the module needs of one character's rest mesh, computed once (bind time, trainer cache).
struct ApparelGraph {
  /// (N_a, K_max) int64 neighbour table of the apparel graph (neighbor_table).
  at::Tensor neighbors;
  /// (N_a) int64: each vertex's frame joint, the joint with the largest anchor weight.
  at::Tensor frame_joints;
  /// (N_a, kApparelRestChannels) float rest-pose channels: the vertex's rest position minus its frame
  /// joint's rest position (3), the offset from the vertex to its nearest body vertex (3), and its
  /// attachment distance (1, attachment_distances).
  at::Tensor rest_features;
  /// Contact inputs (ApparelDynamicsOptions::contact): (N_a, 3) float rest position of each apparel
  /// vertex's nearest body vertex, and (N_a, J) float that body vertex's skinning weights, which carry it
  /// through the motion (the body part the vertex can touch: a hem's thigh, a strand's shoulder, which
  /// the attachment anchor does not see). Undefined when apparel_graph had no body weights.
  at::Tensor contact_rest, contact_weights;
  /// (N_a, kApparelReachLevels) int64: each vertex's ancestors 1, 2, 4, ... hops up its chain towards
  /// where its piece attaches (chain_ancestors), extra neighbours that let a few blocks see the chain
  /// above a vertex (ApparelDynamicsOptions::reach_levels).
  at::Tensor ancestors;
  /// (N_a, kApparelResponseChannels) float: how the character's own physics moves each vertex
  /// (vertex_response over its rig's bones: the share of its weight on simulated bones, its swing away
  /// from rigid skinning while the body sways and after it stops). Undefined: unknown (no rig with
  /// physics), read as zeros. Input of the module only with ApparelDynamicsOptions::response.
  at::Tensor response;
};

/// Channels of ApparelGraph::response (kRigResponseChannels of data_tools/geometry/apparel_topology.h).
inline constexpr int64_t kApparelResponseChannels = 3;

/// Columns of ApparelGraph::ancestors: ancestors up to 2^5 = 32 hops.
inline constexpr int64_t kApparelReachLevels = 6;

/// Jump pointers up each apparel vertex's shortest path to where its piece attaches (the paths of
/// attachment_distances): column l holds the apparel vertex 2^l hops up (a position in apparel_ids),
/// or the path's first apparel vertex where the path is shorter; the first vertex points at itself.
///   V (N, 3); edges (E, 2) int64; apparel_ids (N_a), body_ids (N_b) int64 ascending -> (N_a, levels).
at::Tensor chain_ancestors(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                           const at::Tensor& body_ids, int64_t levels);

/// Channels of ApparelGraph::rest_features.
inline constexpr int64_t kApparelRestChannels = 7;

/// Distance (metres, at rest) from each apparel vertex to where its piece hangs from the body,
/// measured along the apparel mesh: a piece whose mesh touches body vertices hangs from the apparel
/// vertices adjacent to them (distance = that edge's length), a separate piece (hair, ribbons) from
/// its vertex nearest to the body (distance = that gap); from there Dijkstra over apparel edges.
///   V (N, 3) rest positions; edges (E, 2) int64 mesh edges of the whole mesh; apparel_ids (N_a),
///   body_ids (N_b) int64 ascending -> (N_a) float. Without body vertices every distance is 0.
at::Tensor attachment_distances(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                                const at::Tensor& body_ids);

/// Anchor weights by attachment: each apparel vertex takes the body weights (rows of body_weights, in
/// body_ids order) of the body vertex where its piece attaches, the start of its attachment_distances
/// path: a skirt's hem moves with the waist it hangs from, not with the thigh it is nearest to.
at::Tensor attachment_anchor_weights(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                                     const at::Tensor& body_ids, const at::Tensor& body_weights);

/// The anchor weights of `anchor`: "nearest" (apparel_anchor_weights, the nearest body vertex's) or
/// "attachment" (attachment_anchor_weights). Throws amt::Error naming `anchor` otherwise.
at::Tensor apparel_anchor_weights_for(const std::string& anchor, const at::Tensor& V, const at::Tensor& edges,
                                      const at::Tensor& apparel_ids, const at::Tensor& body_ids,
                                      const at::Tensor& body_weights);

/// The ApparelGraph of a character:
///   V (N, 3) rest positions; edges (E, 2) int64 mesh edges; apparel_ids (N_a), body_ids (N_b) int64;
///   anchor_weights (N_a, J) the anchor skinning weights (apparel_anchor_weights); rest_joints (J, 3);
///   apparel_neighbors (N_a, K_max) the neighbour table of the apparel graph; body_weights (N_b, J) the
///   body vertices' skinning weights in body_ids order, for the contact inputs (undefined: none; without
///   body vertices the contact point is the apparel vertex itself, carried by its anchor weights).
ApparelGraph apparel_graph(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                           const at::Tensor& body_ids, const at::Tensor& anchor_weights, const at::Tensor& rest_joints,
                           const at::Tensor& apparel_neighbors, const at::Tensor& body_weights = {});

// === Detail vectors and the zero-network rules

/// d = R^T (A - S) per vertex, with R the rotation of each vertex's frame joint:
///   A, S (..., N_a, 3); transforms (..., J, 3, 4) with the same leading dimensions; frame_joints (N_a)
///   -> (..., N_a, 3).
at::Tensor detail_vectors(const at::Tensor& A, const at::Tensor& S, const at::Tensor& transforms,
                          const at::Tensor& frame_joints);

/// The apparel of frame t from the rule d_t = d_{t-1} + inertia (d_{t-1} - d_{t-2}) with no network:
/// inertia 0 is hold_offset (the detail vector carried along with its joint), > 0 the inertial rule.
///   history (B, 3, N_a, 3) A^(t-3..t-1); transforms (B, 4, J, 3, 4) and anchors (B, 4, N_a, 3) of
///   frames t-3..t; frame_joints (N_a) -> A^(t) (B, N_a, 3).
at::Tensor detail_rule_step(const at::Tensor& history, const at::Tensor& transforms, const at::Tensor& anchors,
                            const at::Tensor& frame_joints, double inertia);

/// The least-squares inertia of the rule above on ground-truth detail vectors d (T, N_a, 3) of
/// clips: the lambda minimising sum |d_{t+1} - d_t - lambda (d_t - d_{t-1})|^2, from the sums
/// accumulated by add (numerator: <dd_{t+1}, dd_t>, denominator |dd_t|^2, with dd_t = d_t - d_{t-1}).
struct InertiaFit {
  double numerator = 0, denominator = 0;
  void add(const at::Tensor& d);
  /// The fitted lambda, clamped to [0, 1] (0 without data).
  double inertia() const;
};

// === Normaliser

/// Per-channel statistics of a stream of feature rows, accumulated and then frozen (MeshGraphNets'
/// online normaliser): before freeze() normalize() is the identity; after it, (x - mean) / std, or
/// x / rms for an uncentred normaliser (which keeps 0 at 0: the target scale, so that a zero network
/// output stays "follow the rule"). The sums and the statistics are buffers, so a checkpoint keeps
/// them and a resumed run continues with the same ones.
class RunningNormalizerImpl : public torch::nn::Module {
 public:
  RunningNormalizerImpl(int64_t channels, bool centred);

  /// Adds the rows of x (..., C) to the sums (no gradient). Throws once frozen.
  void accumulate(const at::Tensor& x);
  /// Computes mean and std (or rms) from the sums, floored at kMinScale, and stops accumulating.
  void freeze();
  bool frozen() const;
  /// Rows accumulated so far.
  double count() const;

  /// (x - mean) / scale; x (..., C).
  at::Tensor normalize(const at::Tensor& x) const;
  /// x * scale + mean: the inverse of normalize.
  at::Tensor denormalize(const at::Tensor& x) const;

  /// Statistics (C) float: mean (0 for an uncentred normaliser) and scale.
  at::Tensor mean, scale;

  /// Smallest scale: a channel that never varies is passed through, not blown up.
  static constexpr double kMinScale = 1e-6;

 private:
  int64_t channels_;
  bool centred_;
  at::Tensor count_, sum_, sum_squares_, frozen_;  // double sums, frozen flag (0 / 1)
};
TORCH_MODULE(RunningNormalizer);

// === The module

/// Configuration of the ApparelDynamicsNet.
struct ApparelDynamicsOptions {
  /// Always "local": the options JSON of every checkpoint of this module carries it, so that a loader
  /// tells this form from ApparelDisplacementNet's (whose options have no `form`).
  std::string form = "local";
  /// Number of joints J of the motion.
  int64_t num_joints = 22;
  /// Where each apparel vertex's anchor S and frame R come from (apparel_anchor_weights_for):
  /// "attachment" (the body vertex its piece attaches at: a hem moves with the waist) or "nearest"
  /// (its nearest body vertex; checkpoints written before this field existed hold it).
  std::string anchor = "attachment";
  /// Output widths of the EdgeConv blocks over the normalised features, in order (eq. 13).
  std::vector<int64_t> edge_widths = {64, 64, 64};
  /// Hidden widths of the per-vertex decoder from the last block to the normalised change of d.
  std::vector<int64_t> decoder_widths = {64};
  /// LeakyReLU slope of the blocks and the decoder.
  double negative_slope = 0.2;
  /// The rule the network corrects: d_t = d_{t-1} + inertia (d_{t-1} - d_{t-2}) + output.
  double inertia = 0.0;
  /// Evaluate the EdgeConv blocks per edge instead of factorised (reference and benchmark only).
  bool naive_edge_conv = false;
  /// Contact inputs: where the vertex's nearest body vertex will be after the body's next move, relative
  /// to the vertex, and that move (HOOD's body edges; ApparelGraph::contact_rest). Checkpoints written
  /// before this field existed have none (false).
  bool contact = true;
  /// Columns of ApparelGraph::ancestors added to every block's neighbours (0: mesh neighbours only):
  /// 6 lets three blocks see up to 96 hops up a chain, where mesh neighbours alone see 3 (the median
  /// apparel vertex of data/default is 9-21 hops from its attachment). Off by default: in 3000 one-step
  /// steps it lowered the validation loss by 1 % only (models/pretrained/README.md). Checkpoints
  /// written before this field existed have 0.
  int64_t reach_levels = 0;
  /// 0: every apparel vertex is a node of the module (the per-vertex form). > 0: the module moves handles
  /// about this far apart (metres, along the apparel; apparel_handles in data_tools/geometry/
  /// apparel_topology.h) and every vertex follows its handles (follow_handles): a piece cannot tear, and the
  /// network runs on hundreds of handles instead of thousands of vertices. Checkpoints written before this
  /// field existed have 0.
  double handle_spacing = 0.0;
  /// Physics inputs: ApparelGraph::response, how lively the character's own apparel physics is, when it
  /// has a rig (a PMX model's rigid bodies, a dataset's rig); zeros when it has none. Checkpoints written
  /// before this field existed have none (false).
  bool response = false;
  /// The least lively apparel physics the module trained on: the rig probe's swing, share x (during + after),
  /// averaged over each apparel piece, of its training characters' least lively piece (swing_reference,
  /// models/pipeline.h; `amt train apparel` measures it, `amt train swing_reference` stores it in a trained model).
  /// A piece whose rig swings less is calmed in proportion (swing_calibration). 0: unknown, no calibration
  /// (checkpoints written before this field existed).
  double swing_reference = 0.0;
};

/// f_d in local coordinates: apparel history, the motion and the anchors of frames t-3..t -> A^(t).
class ApparelDynamicsNetImpl : public torch::nn::Module {
 public:
  explicit ApparelDynamicsNetImpl(ApparelDynamicsOptions options = {});

  /// Per-vertex input channels without and with the contact inputs (channels(): the normaliser's width).
  static constexpr int64_t kChannels = 30 + kApparelRestChannels;
  static constexpr int64_t kContactChannels = 6;
  int64_t channels() const {
    return kChannels + (options.contact ? kContactChannels : 0) + (options.response ? kApparelResponseChannels : 0);
  }

  /// The raw (unnormalised) input channels H (B, N_a, kChannels) for the frame t:
  ///   history (B, 3, N_a, 3) A^(t-3), A^(t-2), A^(t-1), metres;
  ///   transforms (B, 4, J, 3, 4) T of frames t-3..t (the dataset's [R_j | t_j]);
  ///   anchors (B, 4, N_a, 3) S of frames t-3..t.
  /// Channels, every vector in the frame R of the vertex's frame joint at t-1 unless said:
  ///   0-2 d_{t-1}; 3-5 d_{t-1} - d_{t-2}; 6-8 d_{t-2} - d_{t-3} (each d in its own frame's R);
  ///   9-11, 12-14, 15-17 the anchor's moves S_t - S_{t-1}, S_{t-1} - S_{t-2}, S_{t-2} - S_{t-3};
  ///   18-20 the apparel's own move A_{t-1} - A_{t-2};
  ///   21-23, 24-26 the frame joint's rotation over the step into t and the step before, as the
  ///   axial vector of R_a^T R_b (sin(angle) times the axis);
  ///   27-29 gravity's direction (0, -1, 0) in the frame at t;
  ///   30-36 ApparelGraph::rest_features;
  ///   with options.contact, 37-39 P_t - A_{t-1} and 40-42 P_t - P_{t-1}, P the vertex's contact point
  ///   (its nearest body vertex, skinned: ApparelGraph::contact_rest, contact_weights);
  ///   with options.response, the last 3: ApparelGraph::response (zeros when undefined).
  at::Tensor features(const at::Tensor& history, const at::Tensor& transforms, const at::Tensor& anchors,
                      const ApparelGraph& graph) const;

  /// A^(t) (B, N_a, 3) or (N_a, 3) from unbatched or batched inputs shaped as for features (unbatched:
  /// without B). `detail`, when given, receives d_t (same shape).
  at::Tensor step(const at::Tensor& history, const at::Tensor& transforms, const at::Tensor& anchors,
                  const ApparelGraph& graph, at::Tensor* detail = nullptr);

  /// Autoregressive rollout of T frames from 3 given states, each step on the previous 3 (given
  /// first, then predicted); differentiable through time:
  ///   initial (B, 3, N_a, 3) or (3, N_a, 3): states of the frames before the first predicted one;
  ///   transforms (B, 3 + T, J, 3, 4) and anchors (B, 3 + T, N_a, 3): the 3 frames of `initial`, then
  ///   the T predicted frames (or unbatched).
  /// -> (B, T, N_a, 3) or (T, N_a, 3).
  at::Tensor rollout(const at::Tensor& initial, const at::Tensor& transforms, const at::Tensor& anchors,
                     const ApparelGraph& graph);

  /// Adds one sample to the normalisers: the features of the frame and the change of d that the
  /// network would have to predict to reach `target` (B, N_a, 3), A^(t). Shapes as for features.
  void observe(const at::Tensor& history, const at::Tensor& transforms, const at::Tensor& anchors,
               const ApparelGraph& graph, const at::Tensor& target);
  /// Freezes both normalisers (the end of the warm-up).
  void freeze_normalizers();
  bool normalizers_frozen() const;

  /// The rule's d_t (no network): d_{t-1} + inertia (d_{t-1} - d_{t-2}).
  at::Tensor rule_detail(const at::Tensor& d_last, const at::Tensor& d_before) const;

  /// Copies a trained module without the physics inputs into this one, which has them (options.response)
  /// and is otherwise alike: the first block's weights on the new channels start at zero and their
  /// normaliser at mean 0, scale 1, so that this module computes exactly what `source` does until
  /// training moves them. Throws amt::Error when the options differ otherwise.
  void widen_from(ApparelDynamicsNetImpl& source);

  ApparelDynamicsOptions options;
  RunningNormalizer input_normalizer{nullptr}, target_normalizer{nullptr};

 private:
  // features() from the per-vertex rotations R (B, 4, N_a, 3, 3) of the frame joints.
  at::Tensor features_from(const at::Tensor& history, const at::Tensor& transforms, const at::Tensor& anchors,
                           const ApparelGraph& graph, const at::Tensor& R) const;

  std::vector<EdgeConv> blocks_;
  Mlp decoder_{nullptr};
};
TORCH_MODULE(ApparelDynamicsNet);

}  // namespace amt
