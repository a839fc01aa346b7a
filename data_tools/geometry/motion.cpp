#include "data_tools/geometry/motion.h"

#include <algorithm>
#include <cmath>

#include "data_tools/geometry/error.h"

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

Motion resample_motion(const Motion& motion, float fps) {
  AMT_CHECK(std::isfinite(fps) && fps > 0 && fps <= 1000, "resample: fps: expected a frame rate in (0, 1000], found ",
            fps);
  AMT_CHECK(std::isfinite(motion.fps) && motion.fps > 0, "resample: source fps: expected a positive frame rate, found ",
            motion.fps);
  const int T = motion.num_frames(), J = motion.num_joints();
  if (T == 0) {
    Motion out = motion;
    out.fps = fps;
    return out;
  }
  const double ratio = static_cast<double>(fps) / motion.fps;  // output frames per source frame
  const double last = (T - 1) * ratio + 1e-4;
  AMT_CHECK(last + 1 <= kMaxResampledFrames, "resample: fps: expected at most ", kMaxResampledFrames,
            " output frames, found ", std::floor(last) + 1, " (", T, " frames at ", motion.fps, " fps resampled to ",
            fps, " fps)");
  const int out_frames = static_cast<int>(std::floor(last)) + 1;

  Motion out;
  out.fps = fps;
  out.joint_names = motion.joint_names;
  out.local_rotations.resize(static_cast<size_t>(out_frames) * J);
  out.root_translation.resize(out_frames, 3);
  for (int k = 0; k < out_frames; ++k) {
    const double u = k / ratio;  // position in source frames
    int i0 = static_cast<int>(std::floor(u));
    float a = static_cast<float>(u - i0);
    if (i0 >= T - 1) i0 = T - 1, a = 0.0f;
    const int i1 = std::min(i0 + 1, T - 1);
    for (int j = 0; j < J; ++j)
      out.rotation(k, j) = motion.rotation(i0, j).slerp(a, motion.rotation(i1, j)).normalized();
    out.root_translation.row(k) = (1.0f - a) * motion.root_translation.row(i0) + a * motion.root_translation.row(i1);
  }
  return out;
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
