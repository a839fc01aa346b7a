#include "data_tools/geometry/rig_probe.h"

#include <algorithm>
#include <cmath>

#include "data_tools/geometry/error.h"

namespace amt {

MatrixX3f bone_tails(const MatrixX3f& heads, const std::vector<int32_t>& parents) {
  const Eigen::Index B = heads.rows();
  AMT_CHECK(static_cast<Eigen::Index>(parents.size()) == B, "bone tails: expected ", B, " parents, found ",
            parents.size());
  MatrixX3f sum = MatrixX3f::Zero(B, 3);
  std::vector<int> children(static_cast<size_t>(B), 0);
  for (Eigen::Index b = 0; b < B; ++b) {
    const int32_t p = parents[static_cast<size_t>(b)];
    AMT_CHECK(p >= -1 && p < B && p != b, "bone tails: bone ", b, ": parent: expected -1 or another bone in [0, ", B,
              "), found ", p);
    if (p < 0) continue;
    sum.row(p) += heads.row(b);
    ++children[static_cast<size_t>(p)];
  }
  MatrixX3f tails(B, 3);
  for (Eigen::Index b = 0; b < B; ++b) {
    const int32_t p = parents[static_cast<size_t>(b)];
    if (children[static_cast<size_t>(b)] > 0) {
      tails.row(b) = sum.row(b) / static_cast<float>(children[static_cast<size_t>(b)]);
    } else {
      tails.row(b) = heads.row(b);
      if (p >= 0) tails.row(b) += 0.5f * (heads.row(b) - heads.row(p));
    }
  }
  return tails;
}

MatrixXfR probe_response(const MatrixX3f& heads, const std::vector<int32_t>& parents,
                         const std::vector<uint8_t>& simulated, float amplitude, const RigProbeOptions& probe,
                         const std::function<Transforms(const Transforms& pose, float seconds)>& advance) {
  AMT_CHECK(std::isfinite(amplitude) && amplitude > 0, "rig response: amplitude: expected > 0, found ", amplitude);
  AMT_CHECK(std::isfinite(probe.amplitude_metres) && probe.amplitude_metres > 0 && std::isfinite(probe.frequency) &&
                probe.frequency > 0 && probe.frequency < 100 && std::isfinite(probe.settle_seconds) &&
                probe.settle_seconds >= 0 && probe.settle_seconds <= 60 && std::isfinite(probe.hold_seconds) &&
                probe.hold_seconds > 0 && probe.hold_seconds <= 60,
            "rig response: probe: expected a positive amplitude, a frequency in (0, 100) Hz, a settle in [0, 60] s "
            "and a hold in (0, 60] s");
  const int B = static_cast<int>(heads.rows());
  AMT_CHECK(static_cast<int>(simulated.size()) == B, "rig response: expected ", B, " simulated flags, found ",
            simulated.size());
  const MatrixX3f tails = bone_tails(heads, parents);
  MatrixXfR out = MatrixXfR::Zero(B, kRigResponseChannels);
  // Bones the simulation moves: a simulated bone and everything below it.
  std::vector<uint8_t> moved = simulated;
  for (bool changed = true; changed;) {  // parents may come after their children (PMX order)
    changed = false;
    for (int b = 0; b < B; ++b) {
      const int p = parents[static_cast<size_t>(b)];
      if (!moved[static_cast<size_t>(b)] && p >= 0 && moved[static_cast<size_t>(p)]) {
        moved[static_cast<size_t>(b)] = 1;
        changed = true;
      }
    }
  }
  if (std::find(moved.begin(), moved.end(), uint8_t(1)) == moved.end()) return out;

  constexpr float kFps = 30.0f;
  const float dt = 1.0f / kFps;
  const Eigen::Vector3f direction = Eigen::Vector3f(1.0f, 0.0f, 1.0f).normalized();
  const auto pose_at = [&](float offset) {
    return Transforms(static_cast<size_t>(B), make_transform(Eigen::Matrix3f::Identity(), offset * direction));
  };
  const auto tail_positions = [&](const Transforms& bones) {
    AMT_CHECK(static_cast<int>(bones.size()) == B, "rig response: the simulator returned ", bones.size(),
              " transforms, expected ", B);
    MatrixX3f p(B, 3);
    for (int b = 0; b < B; ++b) p.row(b) = apply(bones[static_cast<size_t>(b)], tails.row(b).transpose()).transpose();
    return p;
  };
  const Transforms rest = pose_at(0.0f);
  Transforms bones = rest;
  const int settle_frames = static_cast<int>(std::lround(probe.settle_seconds * kFps));
  for (int f = 0; f < settle_frames; ++f) bones = advance(rest, dt);
  const MatrixX3f settled = tail_positions(bones);

  const int sway_frames = std::max(1, static_cast<int>(std::lround(1.5f / probe.frequency * kFps)));
  const int hold_frames = std::max(1, static_cast<int>(std::lround(probe.hold_seconds * kFps)));
  Eigen::VectorXd sway = Eigen::VectorXd::Zero(B), hold = Eigen::VectorXd::Zero(B);
  for (int f = 1; f <= sway_frames + hold_frames; ++f) {
    const float t = static_cast<float>(std::min(f, sway_frames)) * dt;
    const float offset = f >= sway_frames ? 0.0f : amplitude * std::sin(2.0f * 3.14159265f * probe.frequency * t);
    const MatrixX3f p = tail_positions(advance(pose_at(offset), dt));
    for (int b = 0; b < B; ++b) {
      if (!moved[static_cast<size_t>(b)]) continue;
      const double d2 = (p.row(b) - settled.row(b) - offset * direction.transpose()).squaredNorm();
      (f <= sway_frames ? sway : hold)(b) += d2;
    }
  }
  for (int b = 0; b < B; ++b) {
    if (!moved[static_cast<size_t>(b)]) continue;
    out(b, 0) = 1.0f;
    const float during = static_cast<float>(std::sqrt(sway(b) / sway_frames) / amplitude);
    const float after = static_cast<float>(std::sqrt(hold(b) / hold_frames) / amplitude);
    // A rig that explodes under the probe would feed absurd values to the module: cap at 4 (four times the sway).
    out(b, 1) = std::isfinite(during) ? std::min(during, 4.0f) : 4.0f;
    out(b, 2) = std::isfinite(after) ? std::min(after, 4.0f) : 4.0f;
  }
  return out;
}

}  // namespace amt
