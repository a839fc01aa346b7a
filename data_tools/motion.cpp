#include "data_tools/motion.h"

#include <cmath>

#include "data_tools/error.h"

namespace amt {

Motion rest_motion(const Skeleton& skeleton, int frames, float fps) {
  Motion m;
  m.fps = fps;
  m.joint_names = skeleton.names;
  m.local_rotations.assign(static_cast<size_t>(frames) * skeleton.num_joints(), Eigen::Quaternionf::Identity());
  m.root_translation = MatrixX3f::Zero(frames, 3);
  return m;
}

void validate_motion(const Motion& m, const Skeleton& s, const std::string& source) {
  AMT_CHECK(std::isfinite(m.fps) && m.fps > 0, source, ": fps: expected a positive frame rate, found ", m.fps);
  AMT_CHECK(m.joint_names == s.names, source, ": joints: expected the ", s.num_joints(),
            " joints of the skeleton in its order, found ", m.num_joints(), " joints");
  AMT_CHECK(m.local_rotations.size() == static_cast<size_t>(m.num_frames()) * m.num_joints(), source,
            ": rotations: expected ", m.num_frames(), " x ", m.num_joints(), " quaternions, found ",
            m.local_rotations.size());
  for (size_t i = 0; i < m.local_rotations.size(); ++i) {
    const float n = m.local_rotations[i].norm();
    AMT_CHECK(std::isfinite(n) && std::abs(n - 1.0f) < 1e-3f, source, ": rotations: expected unit quaternions, found norm ",
              n, " at frame ", i / m.num_joints(), " joint ", m.joint_names[i % m.num_joints()]);
  }
  AMT_CHECK(m.root_translation.allFinite(), source, ": root_translation: expected finite values, found NaN or infinity");
}

Transforms forward_kinematics(const Skeleton& s, const Motion& m, int t) {
  const int J = s.num_joints();
  Transforms out(J);
  std::vector<Eigen::Quaternionf, Eigen::aligned_allocator<Eigen::Quaternionf>> global(J);
  for (int j = 0; j < J; ++j) {
    const int p = s.parents[j];
    const Eigen::Quaternionf& local = m.rotation(t, j);
    Eigen::Vector3f position;
    if (p < 0) {
      global[j] = local;
      position = s.rest_joints.row(j).transpose() + m.root_translation.row(t).transpose();
    } else {
      global[j] = global[p] * local;
      // The bone from the parent keeps its rest offset, turned by the parent's global rotation.
      position = out[p].col(3) + global[p] * (s.rest_joints.row(j) - s.rest_joints.row(p)).transpose();
    }
    global[j].normalize();
    out[j] = make_transform(global[j].toRotationMatrix(), position);
  }
  return out;
}

Transforms forward_kinematics(const Skeleton& s, const Motion& m) {
  Transforms all;
  all.reserve(static_cast<size_t>(m.num_frames()) * s.num_joints());
  for (int t = 0; t < m.num_frames(); ++t) {
    const Transforms frame = forward_kinematics(s, m, t);
    all.insert(all.end(), frame.begin(), frame.end());
  }
  return all;
}

Transforms skinning_matrices(const Skeleton& s, const Transforms& T) {
  Transforms M(T.size());
  for (size_t j = 0; j < T.size(); ++j) {
    const Eigen::Matrix3f R = T[j].leftCols<3>();
    M[j] = make_transform(R, T[j].col(3) - R * s.rest_joints.row(static_cast<Eigen::Index>(j)).transpose());
  }
  return M;
}

}  // namespace amt
