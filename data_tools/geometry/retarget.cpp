#include "data_tools/geometry/retarget.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

#include "data_tools/geometry/error.h"

namespace amt {

namespace {

// Least-squares rotation Q with Q a_k ≈ b_k for unit vectors (Kabsch / Wahba's problem).
Eigen::Quaternionf best_rotation(const std::vector<Eigen::Vector3f>& a, const std::vector<Eigen::Vector3f>& b) {
  if (a.size() == 1) return Eigen::Quaternionf::FromTwoVectors(a[0], b[0]);
  Eigen::Matrix3f H = Eigen::Matrix3f::Zero();
  for (size_t k = 0; k < a.size(); ++k) H += b[k] * a[k].transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3f> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  // Collinear directions leave the rotation about their line free: take the minimal one instead.
  if (svd.singularValues()(1) < 1e-6f * std::max(1.0f, svd.singularValues()(0))) {
    Eigen::Vector3f sa = Eigen::Vector3f::Zero(), sb = Eigen::Vector3f::Zero();
    for (size_t k = 0; k < a.size(); ++k) sa += a[k], sb += b[k];
    return Eigen::Quaternionf::FromTwoVectors(sa, sb);
  }
  Eigen::Matrix3f D = Eigen::Matrix3f::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0f : 1.0f;
  return Eigen::Quaternionf(Eigen::Matrix3f(svd.matrixU() * D * svd.matrixV().transpose())).normalized();
}

}  // namespace

Quaternions rest_alignment(const Skeleton& source, const Skeleton& target) {
  AMT_CHECK(source.names == target.names && source.parents == target.parents,
            "retarget: skeletons: expected the same joints in the same order, found ", source.num_joints(), " and ",
            target.num_joints(), " joints that differ");
  const int J = target.num_joints();
  const auto children = target.children();
  Quaternions Q(J, Eigen::Quaternionf::Identity());
  for (int j = 0; j < J; ++j) {
    std::vector<Eigen::Vector3f> dt, ds;
    for (int c : children[j]) {
      const Eigen::Vector3f t = (target.rest_joints.row(c) - target.rest_joints.row(j)).transpose();
      const Eigen::Vector3f s = (source.rest_joints.row(c) - source.rest_joints.row(j)).transpose();
      if (t.norm() < 1e-8f || s.norm() < 1e-8f) continue;  // zero-length bone: no direction to align
      dt.push_back(t.normalized());
      ds.push_back(s.normalized());
    }
    if (!dt.empty()) {
      Q[j] = best_rotation(dt, ds);
    } else if (target.parents[j] >= 0) {
      Q[j] = Q[target.parents[j]];  // a leaf turns with its bone
    }
  }
  return Q;
}

float leg_length(const Skeleton& s) {
  if (is_canonical(s)) {
    auto len = [&](int a, int b) { return (s.rest_joints.row(a) - s.rest_joints.row(b)).norm(); };
    return 0.5f * (len(kLeftHip, kLeftKnee) + len(kLeftKnee, kLeftAnkle) + len(kRightHip, kRightKnee) +
                   len(kRightKnee, kRightAnkle));
  }
  return s.rest_joints(0, 1) - s.rest_joints.col(1).minCoeff();
}

Motion retarget_motion(const Motion& motion, const Skeleton& source, const Skeleton& target) {
  validate_motion(motion, source, "retarget: source motion");
  const Quaternions Q = rest_alignment(source, target);
  const float source_legs = leg_length(source), target_legs = leg_length(target);
  AMT_CHECK(source_legs > 0 && target_legs > 0, "retarget: leg length: expected positive lengths, found ", source_legs,
            " (source) and ", target_legs, " (target)");

  const int J = target.num_joints(), T = motion.num_frames();
  Motion out = motion;
  out.joint_names = target.names;
  out.root_translation = motion.root_translation * (target_legs / source_legs);
  Quaternions source_global(J), target_global(J);
  for (int t = 0; t < T; ++t) {
    for (int j = 0; j < J; ++j) {
      const int p = source.parents[j];
      source_global[j] = p < 0 ? motion.rotation(t, j) : source_global[p] * motion.rotation(t, j);
      target_global[j] = (source_global[j] * Q[j]).normalized();
      out.rotation(t, j) = p < 0 ? target_global[j] : (target_global[p].conjugate() * target_global[j]).normalized();
    }
  }
  return out;
}

}  // namespace amt
