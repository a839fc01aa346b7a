#pragma once
// The apparel module on handles (ApparelDynamicsOptions::handle_spacing > 0): the module's nodes are a
// few hundred handles picked on the apparel (apparel_handles, data_tools/geometry/apparel_topology.h), and
// every apparel vertex follows them: A_v = S_v + sum_k w_vk (A_h - S_h), the weighted offsets of its
// handles from where rigid skinning carries them (their anchors S), added to its own anchor. Vertices
// that coincide at rest get the same handles and weights (the rig is built on the linked topology), so
// a seam cannot open; neighbouring strips share handles, so a bundle moves as one.
#include <ATen/Tensor.h>

#include "data_tools/geometry/apparel_topology.h"
#include "models/apparel_dynamics.h"

namespace amt {

/// One character's handles, as tensors.
struct ApparelRig {
  /// (H) int64 positions in the character's apparel list (apparel_ids) of the handles.
  at::Tensor rows;
  /// (N_a, K) int64 handle indices and (N_a, K) float weights (rows sum to 1) of every apparel vertex.
  at::Tensor vertex_handles, vertex_weights;
  /// (E, 2) int64 pairs of handle indices whose regions overlap (the module's graph over handles).
  at::Tensor edges;
  bool defined() const { return rows.defined(); }
  int64_t num_handles() const { return rows.defined() ? rows.size(0) : 0; }
};

/// The options of apparel_handles for a module spacing (metres, > 0): radius 2.25 spacings, 4 handles.
HandleOptions handle_options(double spacing);

/// The rig of the apparel vertices apparel_ids (N_a) of V (N, 3), over `edges` (E, 2) int64 (the linked
/// topology), picked in order of each vertex's attachment distance (attachment_distances over the same
/// edges, body_ids the rest of the mesh).
ApparelRig apparel_rig(const at::Tensor& V, const at::Tensor& edges, const at::Tensor& apparel_ids,
                       const at::Tensor& body_ids, const HandleOptions& options);

/// The rig of the apparel vertices apparel_ids (N_a) of V (N, 3) from the character's own apparel bones
/// (bone_handles: a handle per bone, at the vertex it weighs most; the vertices' own skin weights).
ApparelRig bone_rig(const at::Tensor& V, const at::Tensor& apparel_ids, const ApparelBones& bones, int max_handles = 4);

/// ApparelGraph::response of the apparel vertices apparel_ids ((N_a) int64 mesh indices): vertex_response of
/// their skin (indices, weights (N, K)) on bones whose response is bone_response (B, kRigResponseChannels), as an
/// (N_a, kApparelResponseChannels) float tensor.
at::Tensor apparel_response(const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& indices,
                            const MatrixXfR& weights, const MatrixXfR& bone_response, const at::Tensor& apparel_ids);

/// The module's graph over the handles: the rows of the per-vertex graph g at the handles, the
/// neighbour table of the rig's edges, and ancestors mapped to each ancestor vertex's nearest handle.
ApparelGraph handle_graph(const ApparelGraph& g, const ApparelRig& rig);

/// The apparel vertices' positions from the handles': A_h (..., H, 3) and their anchors S_h (..., H, 3),
/// the vertices' anchors S (..., N_a, 3) -> S + sum_k w_k (A_h - S_h)[handle_k] (..., N_a, 3).
/// Differentiable in A_h.
at::Tensor follow_handles(const at::Tensor& A_h, const at::Tensor& S_h, const at::Tensor& S, const ApparelRig& rig);

/// Each handle's turn away from its anchor: the rotation R_k that best carries the offsets of its neighbours over the
/// rig's edges at their anchors, S_h[j] - S_h[k], onto theirs in A_h, in least squares (Kabsch), pulled slightly
/// towards no turn (a thousandth of the offsets' squared length: a piece turned as a whole turns a few thousandths
/// less), so that a handle whose neighbours lie on one line turns the least way that lines them up, and one with no
/// neighbours, or whose neighbours sit exactly where their anchors put them, does not turn (the identity exactly).
///   A_h, S_h (..., H, 3) -> (..., H, 3, 3) float, not differentiable.
at::Tensor handle_turns(const at::Tensor& A_h, const at::Tensor& S_h, const ApparelRig& rig);

/// follow_handles with the handles turning (handle_turns), as an artist's bones turn the skin they carry:
/// A_v = sum_k w_k (A_h[k] + R_k (S_v - S_h[k])). Offsets alone carry a piece that swings through a wide angle
/// without turning it, which squashes and stretches it across its handles; with the turns a piece swinging as a whole
/// keeps its edge lengths (to the turns' pull). Equal to follow_handles where no handle turns (A_h = S_h: the anchor
/// skinning exactly).
/// Differentiable in A_h with the turns held.
at::Tensor follow_turning_handles(const at::Tensor& A_h, const at::Tensor& S_h, const at::Tensor& S,
                                  const ApparelRig& rig);

}  // namespace amt
