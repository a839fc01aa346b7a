#pragma once
// The apparel deformation module f_d (paper section 4.3): from the K = 3 past apparel states and
// the current joint transforms, per-vertex features H (eq. 12), EdgeConv blocks over the apparel
// mesh graph (eq. 13) and an MLP decoder give the displacement ΔA, and A^(t) = A^(t-1) + ΔA (eq. 11).
#include <torch/nn/module.h>
#include <torch/nn/pimpl.h>

#include <cstdint>
#include <vector>

#include "models/edge_conv.h"
#include "models/mlp.h"

namespace amt {

/// Configuration of the ApparelDisplacementNet.
struct ApparelDisplacementOptions {
  /// Number of joints J of the motion (the canonical body skeleton has 22).
  int64_t num_joints = 22;
  /// Hidden widths of f_t, the motion encoder on the flattened transforms (J * 12 inputs).
  std::vector<int64_t> motion_widths = {128};
  /// K of eq. 12: width of the global motion code f_t(T^(t)), so H has 9 + K channels.
  int64_t motion_code = 32;
  /// Output widths of the EdgeConv blocks, in order (eq. 13).
  std::vector<int64_t> edge_widths = {64, 64, 128};
  /// Hidden widths of the per-vertex decoder from the last EdgeConv feature to ΔA.
  std::vector<int64_t> decoder_widths = {64};
  /// LeakyReLU slope of the EdgeConv blocks and MLPs.
  double negative_slope = 0.2;
  /// Express A^(t-1) and the joint positions relative to the root joint (joint 0) of frame t, so that
  /// the network is invariant to where the character walks. False uses world coordinates (eq. 12 as written).
  bool root_relative = true;
  /// Factor on the velocity and acceleration features: per-frame differences are centimetres, this
  /// brings them near unit range.
  double velocity_scale = 10.0;
  /// Factor on the decoder output: ΔA = output_scale * decoder(H'), metres per frame.
  double output_scale = 0.1;
  /// Evaluate the EdgeConv blocks per edge instead of factorised (reference and benchmark only).
  bool naive_edge_conv = false;
  /// Condition on the skinned anchor S^(t): the rest apparel skinned (LBS, eq. 4) to frame t with the
  /// weights of each apparel vertex's nearest body vertex (apparel_anchor_weights). H gains the
  /// channels velocity_scale * (S^(t) - A^(t-1)) and the decoder's output becomes a residual over
  /// following the body: ΔA = S^(t) - A^(t-1) + output_scale * decoder(H'). Eq. 11 still holds
  /// (A^(t) = A^(t-1) + ΔA); the skip makes "move with the body" the network's starting point, so it
  /// learns only the dynamics (swing, lag, inertia), and it pulls a rollout back towards the body
  /// instead of letting errors accumulate. False is eq. 12 as written (no anchor).
  bool skinned_anchor = true;
  /// With skinned_anchor: initialise the decoder's last layer to zero, so that a fresh network moves
  /// the apparel exactly with the body (the skinning baseline) and learns the dynamics from there.
  bool zero_init = true;
};

/// Skinning weights for the apparel vertices from the body's: each apparel vertex takes the row of
/// its Euclidean-nearest body vertex in the rest pose.
///   V (N, 3) rest positions; apparel_ids (N_a), body_ids (N_b) int64; body_weights (N_b, J) rows of
///   body_ids -> (N_a, J). With no body vertex every apparel vertex follows joint 0 (the root).
at::Tensor apparel_anchor_weights(const at::Tensor& V, const at::Tensor& apparel_ids, const at::Tensor& body_ids,
                                  const at::Tensor& body_weights);

/// f_d: apparel history + joint transforms -> next apparel state, over a fixed apparel graph.
/// The graph is per character and passed to every call as a neighbour table (N_a, K_max) int64 from
/// neighbor_table(): each row is the vertex itself, then its neighbours, padded with itself. Edges
/// exist only inside connected components, so the convolution is grouped by component (eq. 13).
class ApparelDisplacementNetImpl : public torch::nn::Module {
 public:
  explicit ApparelDisplacementNetImpl(ApparelDisplacementOptions options = {});

  /// ΔA = f_d(history, T^(t)) (eq. 11):
  ///   history          (3, N_a, 3) or (B, 3, N_a, 3): A^(t-3), A^(t-2), A^(t-1) in that order, metres
  ///   joint_transforms (J, 3, 4) or (B, J, 3, 4): T^(t), the dataset's [R_j | t_j] of the frame to predict
  ///   neighbors        (N_a, K_max) int64 apparel graph
  ///   anchor           (N_a, 3) or (B, N_a, 3): S^(t), required with options.skinned_anchor, else ignored
  /// -> ΔA (N_a, 3) or (B, N_a, 3), metres.
  at::Tensor forward(const at::Tensor& history, const at::Tensor& joint_transforms, const at::Tensor& neighbors,
                     const at::Tensor& anchor = {});

  /// A^(t) = A^(t-1) + ΔA (eq. 11). Shapes as forward; returns (N_a, 3) or (B, N_a, 3).
  at::Tensor step(const at::Tensor& history, const at::Tensor& joint_transforms, const at::Tensor& neighbors,
                  const at::Tensor& anchor = {});

  /// Autoregressive rollout: starting from the 3 given states, predicts T frames, each from the
  /// previous 3 (ground truth first, then the network's own predictions); differentiable through time.
  ///   initial          (3, N_a, 3) or (B, 3, N_a, 3): the states before frame 0, oldest first
  ///   joint_transforms (T, J, 3, 4) or (B, T, J, 3, 4): the motion of the predicted frames
  ///   anchors          (T, N_a, 3) or (B, T, N_a, 3): S of the predicted frames (with skinned_anchor)
  /// -> (T, N_a, 3) or (B, T, N_a, 3).
  at::Tensor rollout(const at::Tensor& initial, const at::Tensor& joint_transforms, const at::Tensor& neighbors,
                     const at::Tensor& anchors = {});

  /// The per-vertex features H (B, N_a, 9 + K), or (B, N_a, 12 + K) with the anchor channels, of
  /// eq. 12 from batched history (B, 3, N_a, 3), transforms (B, J, 3, 4) and anchor (B, N_a, 3).
  at::Tensor features(const at::Tensor& history, const at::Tensor& joint_transforms, const at::Tensor& anchor = {});

  ApparelDisplacementOptions options;

 private:
  Mlp motion_encoder_{nullptr};  // f_t
  std::vector<EdgeConv> blocks_;
  Mlp decoder_{nullptr};
};
TORCH_MODULE(ApparelDisplacementNet);

}  // namespace amt
