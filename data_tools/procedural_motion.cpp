#include "data_tools/procedural_motion.h"

#include <algorithm>
#include <cmath>

#include "data_tools/error.h"

namespace amt {

namespace {
Eigen::Quaternionf rot(float degrees, const Eigen::Vector3f& axis) {
  return Eigen::Quaternionf(Eigen::AngleAxisf(degrees * float(M_PI) / 180.0f, axis));
}
}  // namespace

Motion walk_motion(int frames, float fps, float speed, float stride_seconds) {
  AMT_CHECK(frames >= 1 && fps > 0 && stride_seconds > 0, "walk_motion: expected frames >= 1, fps > 0 and a positive "
            "stride, found ", frames, ", ", fps, ", ", stride_seconds);
  const Skeleton s = canonical_skeleton();
  Motion m = rest_motion(s, frames, fps);
  const Eigen::Vector3f X = Eigen::Vector3f::UnitX(), Y = Eigen::Vector3f::UnitY(), Z = Eigen::Vector3f::UnitZ();
  for (int t = 0; t < frames; ++t) {
    const float phase = 2.0f * float(M_PI) * (t / fps) / stride_seconds;
    const float swing = std::sin(phase);
    // Characters face +Z: a negative turn about +X swings a leg forward.
    m.rotation(t, kLeftHip) = rot(-25.0f * swing, X);
    m.rotation(t, kRightHip) = rot(25.0f * swing, X);
    m.rotation(t, kLeftKnee) = rot(35.0f * std::max(0.0f, std::sin(phase + 1.2f)), X);
    m.rotation(t, kRightKnee) = rot(35.0f * std::max(0.0f, -std::sin(phase + 1.2f)), X);
    m.rotation(t, kLeftAnkle) = rot(-10.0f * swing, X);
    m.rotation(t, kRightAnkle) = rot(10.0f * swing, X);
    // Arms down from the T-pose (about Z), then a swing about the vertical, opposite to the legs.
    m.rotation(t, kLeftShoulder) = rot(-20.0f * swing, Y) * rot(-70.0f, Z);
    m.rotation(t, kRightShoulder) = rot(-20.0f * swing, Y) * rot(70.0f, Z);
    m.rotation(t, kLeftElbow) = rot(-15.0f - 10.0f * swing, Y);
    m.rotation(t, kRightElbow) = rot(15.0f - 10.0f * swing, Y);
    m.rotation(t, kSpine2) = rot(4.0f * swing, Y);  // counter-rotation of the chest
    m.rotation(t, kPelvis) = rot(-4.0f * swing, Y);
    m.root_translation.row(t) << 0.0f, 0.02f * std::cos(2.0f * phase) - 0.02f, speed * t / fps;
  }
  return m;
}

}  // namespace amt
