#pragma once
// A small VMD dance on MikuMikuDance's standard bone names, for tests and for data/mocap/vmd/sway.vmd (which is
// vmd_bytes(vmd_dance()): tests/data_tools/formats/vmd_import_test.cpp checks it and rewrites it when
// AMT_WRITE_VMD_DANCE names the file). Four seconds at 30 fps, a key every 15 frames: the centre bobbing and
// swaying, the lower body turning, the upper body leaning, the head nodding, the arms waving with bent elbows, and
// the feet stepping on their leg IK bones (MMD's 左足ＩＫ / 右足ＩＫ). Rotations ease in and out (Bézier curves).
// Values in MMD's frame and units (PMX units, left-handed, facing -Z).
#include <cmath>
#include <string>

#include "data_tools/formats/vmd_import.h"

namespace amt::test {

/// A bone key with its curves left at VmdCurve's default.
inline VmdBoneKey vmd_key(const std::string& bone, uint32_t frame, const Eigen::Vector3f& translation,
                          const Eigen::Quaternionf& rotation = Eigen::Quaternionf::Identity()) {
  VmdBoneKey k;
  k.bone = bone;
  k.frame = frame;
  k.translation = translation;
  k.rotation = rotation;
  return k;
}

inline VmdMotion vmd_dance() {
  VmdMotion m;
  m.model_name = "標準ボーン";
  const VmdCurve ease{40, 0, 87, 127};
  auto add = [&](const std::string& bone, uint32_t frame, const Eigen::Vector3f& t, const Eigen::Vector3f& euler) {
    VmdBoneKey k = vmd_key(bone, frame, t,
                           Eigen::Quaternionf(Eigen::AngleAxisf(euler.y(), Eigen::Vector3f::UnitY()) *
                                              Eigen::AngleAxisf(euler.x(), Eigen::Vector3f::UnitX()) *
                                              Eigen::AngleAxisf(euler.z(), Eigen::Vector3f::UnitZ())));
    k.curves[kVmdCurveRotation] = ease;
    m.bone_keys.push_back(k);
  };
  const Eigen::Vector3f none = Eigen::Vector3f::Zero();
  for (int beat = 0; beat <= 8; ++beat) {
    const uint32_t f = uint32_t(15 * beat);
    const float side = beat % 2 == 0 ? 1.0f : -1.0f;  // alternates every beat
    const bool first = beat == 0;
    add("センター", f, first ? none : Eigen::Vector3f(0.8f * side, -0.6f, 0), none);
    add("下半身", f, none, Eigen::Vector3f(0, first ? 0 : 0.2f * side, 0));
    add("上半身", f, none, Eigen::Vector3f(first ? 0 : 0.1f, 0, first ? 0 : 0.15f * side));
    add("頭", f, none, Eigen::Vector3f(first ? 0 : 0.15f * (beat % 4 < 2 ? 1 : -1), 0, 0));
    // Arms: from the rest pose down to about 40 degrees below horizontal, waving 23 degrees up and down.
    const float wave = first ? 0 : 0.4f * side;
    add("左腕", f, none, Eigen::Vector3f(0, 0, first ? 0 : -0.7f + wave));
    add("右腕", f, none, Eigen::Vector3f(0, 0, first ? 0 : 0.7f + wave));
    add("左ひじ", f, none, Eigen::Vector3f(0, first ? 0 : 0.5f + 0.3f * side, 0));
    add("右ひじ", f, none, Eigen::Vector3f(0, first ? 0 : -0.5f + 0.3f * side, 0));
    // Steps: the foot on the side the centre sways away from lifts and comes forwards (-Z), the other stays down.
    const bool left_up = !first && side < 0, right_up = !first && side > 0;
    add("左足ＩＫ", f, Eigen::Vector3f(0, left_up ? 1.2f : 0, left_up ? -0.8f : 0), none);
    add("右足ＩＫ", f, Eigen::Vector3f(0, right_up ? 1.2f : 0, right_up ? -0.8f : 0), none);
  }
  return m;
}

}  // namespace amt::test
