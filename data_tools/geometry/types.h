#pragma once
// Matrix types shared by the geometry code. Row-major so that an (N,3) block is laid out exactly as
// in the dataset file and in a torch tensor of the same shape.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace amt {

/// #V by 3 positions (metres) or directions.
using MatrixX3f = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// #F by 3 triangle vertex indices.
using MatrixX3i = Eigen::Matrix<int32_t, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// #E by 2 edge vertex indices.
using MatrixX2i = Eigen::Matrix<int32_t, Eigen::Dynamic, 2, Eigen::RowMajor>;
/// Dense row-major float matrix, e.g. skinning weights (N, J) or geodesic distances (N, J).
using MatrixXfR = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// A rigid (or affine) transform [R | t] as a 3x4 row-major block; x' = R x + t.
using Transform34 = Eigen::Matrix<float, 3, 4, Eigen::RowMajor>;
/// One transform per joint (or bone), in joint order.
using Transforms = std::vector<Transform34, Eigen::aligned_allocator<Transform34>>;
/// Rotations as unit quaternions, in joint order (or frame-major, joint-minor for a clip).
using Quaternions = std::vector<Eigen::Quaternionf, Eigen::aligned_allocator<Eigen::Quaternionf>>;

/// Builds [R | t].
inline Transform34 make_transform(const Eigen::Matrix3f& R, const Eigen::Vector3f& t) {
  Transform34 T;
  T.leftCols<3>() = R;
  T.col(3) = t;
  return T;
}

/// Applies [R | t] to a point.
inline Eigen::Vector3f apply(const Transform34& T, const Eigen::Vector3f& p) {
  return T.leftCols<3>() * p + T.col(3);
}

}  // namespace amt
