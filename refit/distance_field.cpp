#include "refit/distance_field.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

#include <cmath>
#include <mutex>

#include "data_tools/geometry/error.h"

namespace amt::refit {

struct AvatarDistanceField::Grid {
  openvdb::FloatGrid::Ptr grid;
};

AvatarDistanceField::AvatarDistanceField(const Positions& V, const MatrixX3i& F, double voxel_size, double band)
    : grid_(std::make_unique<Grid>()), voxel_size_(voxel_size) {
  AMT_CHECK(voxel_size > 0.0 && std::isfinite(voxel_size), "distance field: voxel size ", voxel_size,
            ", expected a positive length");
  AMT_CHECK(band >= voxel_size && std::isfinite(band), "distance field: band ", band,
            ", expected at least the voxel size ", voxel_size);
  AMT_CHECK(V.allFinite(), "distance field: a vertex coordinate is not finite");
  AMT_CHECK(F.rows() > 0, "distance field: the avatar has no faces");
  static std::once_flag initialised;
  std::call_once(initialised, [] { openvdb::initialize(); });
  std::vector<openvdb::Vec3s> points(V.rows());
  for (int v = 0; v < V.rows(); ++v) points[v] = openvdb::Vec3s(float(V(v, 0)), float(V(v, 1)), float(V(v, 2)));
  std::vector<openvdb::Vec3I> triangles(F.rows());
  for (int f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k)
      AMT_CHECK(F(f, k) >= 0 && F(f, k) < V.rows(), "distance field: face ", f, " has vertex ", F(f, k),
                ", expected 0 to ", V.rows() - 1);
    triangles[f] = openvdb::Vec3I(F(f, 0), F(f, 1), F(f, 2));
  }
  // One voxel more than asked: the interpolation at distance `band` reads a voxel beyond it.
  const float band_voxels = float(std::ceil(band / voxel_size)) + 1.0f;
  grid_->grid = openvdb::tools::meshToSignedDistanceField<openvdb::FloatGrid>(
      *openvdb::math::Transform::createLinearTransform(voxel_size), points, triangles, {}, band_voxels, band_voxels);
}

AvatarDistanceField::~AvatarDistanceField() = default;
AvatarDistanceField::AvatarDistanceField(AvatarDistanceField&&) noexcept = default;

long long AvatarDistanceField::active_voxels() const {
  return static_cast<long long>(grid_->grid->activeVoxelCount());
}

// By hand: OpenVDB's samplers (tools::BoxSampler) give the interpolated value, and its gradient operators
// (math::ISGradient) central differences of the voxel values, which are not the derivative of that
// interpolant; Newton's line search needs a gradient consistent with the value it evaluates.
double AvatarDistanceField::distance(const Eigen::Vector3d& p, Eigen::Vector3d* gradient,
                                     Eigen::Matrix3d* hessian) const {
  const Eigen::Vector3d s = p / voxel_size_;  // index space: voxel (i, j, k) sits at (i, j, k) h
  const Eigen::Vector3d lower = s.array().floor();
  const Eigen::Vector3d f = s - lower;  // in [0, 1)³
  const openvdb::Coord c0{static_cast<int>(lower[0]), static_cast<int>(lower[1]), static_cast<int>(lower[2])};
  // The accessor caches the last leaf; one per call keeps the method thread-safe.
  const auto accessor = grid_->grid->getConstAccessor();
  double value[2][2][2];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) value[i][j][k] = accessor.getValue(c0.offsetBy(i, j, k));
  // Trilinear: D = Σ w_i(f_x) w_j(f_y) w_k(f_z) value, w_0(u) = 1 - u, w_1(u) = u, dw_i/du = ±1.
  double d = 0.0;
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) {
        const double wx = i ? f[0] : 1 - f[0], wy = j ? f[1] : 1 - f[1], wz = k ? f[2] : 1 - f[2];
        const double dx = i ? 1 : -1, dy = j ? 1 : -1, dz = k ? 1 : -1;
        const double v = value[i][j][k];
        d += wx * wy * wz * v;
        g += v * Eigen::Vector3d(dx * wy * wz, wx * dy * wz, wx * wy * dz);
        h(0, 1) += v * dx * dy * wz;
        h(0, 2) += v * dx * wy * dz;
        h(1, 2) += v * wx * dy * dz;
      }
  if (gradient) *gradient = g / voxel_size_;
  if (hessian) {
    h(1, 0) = h(0, 1), h(2, 0) = h(0, 2), h(2, 1) = h(1, 2);  // the diagonal is zero: linear in each axis
    *hessian = h / (voxel_size_ * voxel_size_);
  }
  return d;
}

}  // namespace amt::refit
