#pragma once
// The signed distance field of an avatar for the fit term (the garment-refit paper, sections 3.4.4 and
// 3.6): OpenVDB's narrow-band signed distance field of the mesh (Museth 2013,
// tools::meshToSignedDistanceField), as the paper uses, sampled by trilinear interpolation of the voxel
// values with the interpolant's exact gradient and Hessian.
#include <Eigen/Core>
#include <memory>

#include "data_tools/geometry/types.h"
#include "refit/contact.h"

namespace amt::refit {

/// D(p): distance to the avatar's surface, positive outside, negative inside (metres).
class AvatarDistanceField {
 public:
  /// V #V by 3 (metres), F #F by 3: a closed surface (OpenVDB decides inside and outside by flood fill;
  /// for an open mesh the sign may be wrong away from the surface, while |D| stays right).
  /// voxel_size: the grid's spacing (metres, > 0); band: how far from the surface the field is exact
  /// (metres, ≥ voxel_size), beyond which D is ±(band + a voxel or two) with zero gradient. Throws
  /// amt::Error on a bad size, a non-finite coordinate or a face index out of range.
  AvatarDistanceField(const Positions& V, const MatrixX3i& F, double voxel_size, double band);
  ~AvatarDistanceField();
  AvatarDistanceField(AvatarDistanceField&&) noexcept;

  /// D at p, the trilinear interpolation of the 8 voxel values around p; when non-null, *gradient
  /// receives ∇D and *hessian ∇²D of that interpolant (exact inside a voxel cell; the interpolant is
  /// continuous across cells, its derivatives are not). Thread-safe.
  double distance(const Eigen::Vector3d& p, Eigen::Vector3d* gradient = nullptr,
                  Eigen::Matrix3d* hessian = nullptr) const;

  double voxel_size() const { return voxel_size_; }
  /// Active voxels of the narrow band.
  long long active_voxels() const;

 private:
  struct Grid;  // OpenVDB's types stay out of this header
  std::unique_ptr<Grid> grid_;
  double voxel_size_;
};

}  // namespace amt::refit
