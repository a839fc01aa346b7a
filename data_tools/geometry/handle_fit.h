#pragma once
// Apparel as skinned joints: a rigid transform per handle fitted to where the apparel's vertices are, so that
// linear blend skinning by the handles reproduces a frame that any apparel path computed (the learned module, a
// PMX model's physics, spring bones) in a skinned glTF instead of a per-frame vertex cache.
//
// Each handle h is a joint at rest position c_h with identity rest orientation; a vertex v of rest position p_v
// with handles k and weights w_vk (rows summing to 1) is skinned to
//     x_v = sum_k w_vk (R_k (p_v - c_k) + t_k).
// Per frame, given the target positions y_v:
//   1. R_h: the weighted Kabsch rotation (Kabsch 1976; the SVD form with the reflection fixed) between the rest
//      and the target positions of the vertices h weighs, with those weights, about their weighted centroids.
//      When those vertices lie on a line or a point (the second singular value below 1e-6 of the first), R_h is
//      the caller's fallback rotation (the body joint the handle hangs from).
//   2. t: the handle positions minimising sum_v |x_v - y_v|^2 with the rotations fixed, a linear least-squares
//      problem whose normal matrix W^T W (W the N_a by H weight matrix) does not change from frame to frame, so
//      it is factored once (sparse Cholesky, Eigen's SimplicialLDLT) and each frame costs a back-substitution.
//   3. The same positions with every handle at its fallback rotation; of the two, the frame keeps the one whose
//      squared residual is smaller. Swinging strands and panels (physics, spring bones) rotate with their own
//      vertices; apparel that moves as the learned module's handles move it (each vertex its anchor's rigid
//      motion plus the weighted offsets of its handles) is reproduced exactly under its anchor's rotation, where a
//      Kabsch rotation of a stretched region would not be.
// The caller measures what is left (FitError).
//
// Written by hand: a weighted Kabsch per handle and one sparse least-squares solve are a few lines on Eigen; no
// library fits skinning transforms to a given skin.
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

/// The handles of a skinned apparel (rows of the vertices the handles move).
///   vertices   N_a mesh vertex indices moved by handles
///   handles    N_a by K handle indices (0..H-1) per vertex, with weights N_a by K (rows sum to 1; 0 pads)
///   rest       H by 3 rest positions of the handles (metres)
struct HandleSkin {
  std::vector<int32_t> vertices;
  Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> handles;
  MatrixXfR weights;
  MatrixX3f rest;
  int num_handles() const { return static_cast<int>(rest.rows()); }
};

/// Fits the handles' transforms to frames of a mesh (construction above).
class HandleFit {
 public:
  /// Prepares the fit for the mesh of rest positions V (#V by 3). Throws amt::Error naming the field for a skin of
  /// the wrong shape, indices out of range, weights that are not finite and non-negative or a row without weight.
  HandleFit(const MatrixX3f& V, HandleSkin skin);
  ~HandleFit();
  HandleFit(HandleFit&&) noexcept;
  HandleFit& operator=(HandleFit&&) noexcept;

  const HandleSkin& skin() const { return skin_; }

  /// The handles' rotations (H) and positions (H by 3) that skin the rest mesh onto the vertices of Y (#V by 3;
  /// only the skin's vertices are read). `fallback` (H rotations) is used for a handle whose vertices cannot fix
  /// a rotation.
  void fit(const MatrixX3f& Y, const Quaternions& fallback, Quaternions& rotations, MatrixX3f& positions) const;

  /// Step 1 alone: the handles' Kabsch rotations (H) towards Y, `fallback` where the vertices cannot fix one.
  void kabsch(const MatrixX3f& Y, const Quaternions& fallback, Quaternions& rotations) const;

  /// Step 2 alone: the least-squares positions (H by 3) under `rotations`; returns the squared residual (m^2).
  double positions_for(const MatrixX3f& Y, const Quaternions& rotations, MatrixX3f& positions) const;

  /// The skin's vertices under handle transforms (rotations, positions), written into rows of X (#V by 3; other
  /// rows untouched).
  void skin_vertices(const Quaternions& rotations, const MatrixX3f& positions, MatrixX3f& X) const;

 private:
  struct Solver;
  MatrixX3f rest_;  // the skin's vertices at rest, N_a by 3
  HandleSkin skin_;
  std::unique_ptr<Solver> solver_;
};

/// Distances between computed and skinned positions over frames, as a histogram of 0.01 mm bins up to 1 m (the
/// last bin takes the rest): quantiles without keeping every distance.
class FitError {
 public:
  FitError();
  /// Adds the distances |A_v - B_v| of the rows `rows` (every row when empty).
  void add(const MatrixX3f& A, const MatrixX3f& B, const std::vector<int32_t>& rows = {});
  /// The q-quantile (0..1) of the distances added, metres (0 when none); the max is exact.
  double quantile(double q) const;
  double max() const { return max_; }
  int64_t count() const { return count_; }

 private:
  std::vector<int64_t> bins_;
  int64_t count_ = 0;
  double max_ = 0.0;
};

}  // namespace amt
