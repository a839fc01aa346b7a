#pragma once
// Surface-oriented deformation (the "wrap deformer"; Singh et al. 2000, as cloth_motion_retargeting
// section 2.1 uses it): a deformable point set follows a deformer mesh by keeping its initial spatial
// relationship with a few of the deformer's faces.
//   registration  each point P is bound to the `faces` deformer faces nearest to it (exact
//                 point-triangle distance among the faces with the nearest centroids); face k gets a
//                 weight inversely proportional to the distance from P to k's plane, the weights of P
//                 normalised to sum to 1; P's local coordinates in k's frame are stored;
//   deformation   each bound face's frame is rebuilt on the moved deformer, P is placed at the same
//                 local coordinates in it, and the new P is the weighted average over its faces.
// A face's frame: origin at its centroid, axes e1 = the unit edge v0 -> v1, n = the unit normal,
// e2 = n x e1 (orthonormal, so each face carries P rigidly; stretching of the face moves its centroid,
// not the distance of P from it). Hand-written: no Debian library offers this deformer; nanoflann
// (the KD-tree the geodesics use) finds the candidate faces.
#include <cstdint>
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

/// Registration settings.
struct WrapOptions {
  /// Faces each point is bound to (>= 1).
  int faces = 4;
  /// Faces with the nearest centroids whose exact distance is computed to choose the `faces` nearest
  /// (>= faces; more is slower and closer to the exact nearest faces).
  int candidates = 24;
  /// Floor on the plane distance in the weight 1 / distance (metres): a point on a face's plane
  /// gets a large but finite weight.
  float min_plane_distance = 1e-4f;
  /// Weight a face by 1 / the distance to the face itself (the exact point-triangle distance) instead of
  /// 1 / the distance to its plane. The paper's plane distance lets a face whose plane happens to pass
  /// near the point dominate however far its triangle is (a skirt vertex carried by a face of the other
  /// leg); cloth retargeting uses the triangle distance (data_tools/garment/cloth_retarget.h).
  bool triangle_distance_weights = false;
};

/// The registration of N points to a deformer mesh: for point i and slot s (s < k),
/// face(i, s) the deformer face, weight(i, s) its weight (each row sums to 1), local(i, s) the point
/// in that face's frame (e1, e2, n components).
struct WrapBinding {
  int k = 0;
  Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> face;
  MatrixXfR weight;
  /// (N * k) by 3: row i * k + s.
  MatrixX3f local;
  /// (N * k) by 3: the point minus the face's centroid in the rest shape, world axes (used when the
  /// face collapses).
  MatrixX3f rest_offset;

  int64_t num_points() const { return face.rows(); }
};

/// Binds `points` (N by 3) to the deformer mesh (V, F) in its rest shape. Faces of zero area are
/// never chosen. Throws amt::Error on bad input (no faces, out-of-range indices, non-finite values,
/// bad options), naming `source`.
WrapBinding wrap_register(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& points, const WrapOptions& options = {},
                          const char* source = "wrap deformer");

/// The points of `binding` carried by the deformer moved to `V_moved` (same faces F as registered).
/// A face that collapsed to zero area keeps its rest axes and follows its centroid.
/// (WrapDeformer below, prepared for one call.)
MatrixX3f wrap_deform(const WrapBinding& binding, const MatrixX3f& V_moved, const MatrixX3i& F);

/// A binding prepared for deforming frame after frame: the faces it uses listed once, with their
/// corners in the numbering of the frames given to deform(). Per frame, each used face's frame is
/// built once and every point is placed from those frames; nothing is looked up or checked per point.
class WrapDeformer {
 public:
  /// Per-frame working space of deform(): the used faces' frames (one per caller or thread).
  struct Frames {
    std::vector<float> data;         // per used face: centroid, e1, e2, n, unit normal (15 floats)
    std::vector<uint8_t> collapsed;  // per used face: no frame (zero area)
  };

  WrapDeformer() = default;
  /// `binding` as registered against faces F; `corners` #F by 3, the same faces with their corners
  /// numbered as the rows of the frames that deform() will get (F itself when the frames are the
  /// deformer mesh; a larger numbering when the deformer is part of a bigger mesh). Throws amt::Error
  /// when the binding names a face outside F or `corners` has another row count.
  WrapDeformer(WrapBinding binding, const MatrixX3i& corners);

  /// The points carried by the deformer posed as in V (rows numbered as `corners`) into `out` (#points
  /// by 3, resized), exactly as wrap_deform. `normals`, when given, receives per point the normalised
  /// weighted sum of its faces' unit normals (zero where that sum is shorter than 1e-6): the direction
  /// away from the deformer under the point. V must hold every vertex `corners` names.
  void deform(const MatrixX3f& V, MatrixX3f& out, MatrixX3f* normals, Frames& frames) const;

  const WrapBinding& binding() const { return binding_; }
  int num_used_faces() const { return int(corners_.size() / 3); }

 private:
  WrapBinding binding_;
  std::vector<int32_t> corners_;  // 3 per used face
  std::vector<int32_t> slot_;     // per point and slot (row-major like binding.face): its used face
  std::vector<float> weighted_;   // per point and slot: weight, then weight times local (3), then weight
                                  // times rest_offset (3)
};

/// The frame of face f of (V, F): rows e1, e2, n (a rotation: R * (p - c) gives local coordinates);
/// returns false (and the identity) for a face of zero area. `centroid` receives its centroid.
bool face_frame(const MatrixX3f& V, const MatrixX3i& F, int64_t f, Eigen::Matrix3f& R, Eigen::Vector3f& centroid);

/// Squared distance from p to the triangle (a, b, c) (Ericson, Real-Time Collision Detection, 5.1.5).
float point_triangle_distance2(const Eigen::Vector3f& p, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                               const Eigen::Vector3f& c);

}  // namespace amt
