#pragma once
// The penetration measure (docs/evaluation.md, "Metrics") of one mesh in many poses: the mesh's vertices split
// into body and apparel by a mask, the body surface is the faces with three body vertices, and every
// pose asks how many apparel vertices lie inside that surface and how deep. The body surface gets one
// winding-number tree, built on the rest pose and refitted to each pose (WindingNumberTree::refit, O(#F))
// instead of built anew (O(#F log #F)); the evaluation (eval/evaluate.h) measures every predicted
// frame of every method this way.
#include <memory>
#include <optional>
#include <vector>

#include "data_tools/geometry/metrics.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Body penetration

/// Penetration of a mesh's apparel vertices into its body surface, pose after pose. Holds the body
/// surface's winding-number tree and scratch rows of the pose: measure() is not safe to call from
/// several threads at once (use one meter per thread). Its answers depend only on the pose, not on
/// the poses measured before (a refit recomputes every box and expansion from the pose alone).
class BodyPenetration {
 public:
  /// V #V by 3 rest positions (metres), F #F by 3 faces (indices into V), apparel_mask #V entries
  /// (1 = apparel, 0 = body). Builds the body tree on the body rows of V. Throws amt::Error for a mask
  /// of another length, face indices outside [0, #V), or non-finite rest positions of the body.
  BodyPenetration(const MatrixX3f& V, const MatrixX3i& F, const std::vector<uint8_t>& apparel_mask);
  ~BodyPenetration();
  BodyPenetration(BodyPenetration&&) noexcept;
  BodyPenetration& operator=(BodyPenetration&&) noexcept;

  /// False when there is nothing to measure: no apparel vertex or no body face.
  bool active() const { return tree_ != nullptr; }

  /// Apparel vertices (ascending indices into V) and the body surface: vertices (ascending) and
  /// faces (#F_b by 3, numbered by position in body_vertices()).
  const std::vector<int32_t>& apparel_vertices() const { return apparel_; }
  const std::vector<int32_t>& body_vertices() const { return body_; }
  const MatrixX3i& body_faces() const { return body_faces_; }

  /// Penetration of pose P (#V by 3, metres; the order of V): its apparel vertices tested against its
  /// body surface, with the same verdicts and depths as penetration() (data_tools/geometry/metrics.h) against
  /// a tree built on the posed body. The refitted tree's far field sums other subtrees than a fresh
  /// tree's, so its winding numbers differ by up to a few 1e-3 (7e-3 the largest seen over 9 M apparel
  /// vertices of an evaluation); the few within 0.05 of the 0.5 threshold are settled by a tree built
  /// on the pose (in about one frame in ten), every other verdict cannot differ. Depths are exact
  /// distances, the same from either tree, summed in point order (the same for any thread count).
  /// nullopt when the meter is not active or a body position of P is not finite (no surface to test
  /// against). Throws amt::Error for a pose with another row count than V.
  std::optional<Penetration> measure(const MatrixX3f& P);

 private:
  std::vector<int32_t> apparel_, body_;
  MatrixX3i body_faces_;
  std::unique_ptr<WindingNumberTree> tree_;  // over the body surface, refitted by measure()
  MatrixX3f body_pose_, apparel_pose_;      // rows of the pose, reused from call to call
};

}  // namespace amt
