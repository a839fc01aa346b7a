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
MatrixX3f wrap_deform(const WrapBinding& binding, const MatrixX3f& V_moved, const MatrixX3i& F);

/// The frame of face f of (V, F): rows e1, e2, n (a rotation: R * (p - c) gives local coordinates);
/// returns false (and the identity) for a face of zero area. `centroid` receives its centroid.
bool face_frame(const MatrixX3f& V, const MatrixX3i& F, int64_t f, Eigen::Matrix3f& R, Eigen::Vector3f& centroid);

/// Squared distance from p to the triangle (a, b, c) (Ericson, Real-Time Collision Detection, 5.1.5).
float point_triangle_distance2(const Eigen::Vector3f& p, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                               const Eigen::Vector3f& c);

}  // namespace amt
