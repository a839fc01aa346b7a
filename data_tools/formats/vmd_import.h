#pragma once
// VMD motions (MikuMikuDance's "Vocaloid Motion Data"): the bone keyframes of a motion made for a PMX model, with
// MMD's per-keyframe Bézier interpolation. Morph, camera, light, self-shadow and IK-enable tracks are counted and
// skipped (VmdMotion::ignored_note). The layout is described at the top of vmd_import.cpp with its sources.
//
// Frames and units are MMD's, untouched: positions in PMX units, MMD's left-handed frame (Y up, characters facing
// -Z), quaternions acting on those coordinates. A key's translation and rotation are the bone's local motion
// relative to its rest pose (PMX bones have no rest rotation): data_tools/builder/mmd_pose.h evaluates them on a
// model. Keyframe numbers count frames at kVmdFps.
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

// === Conventions

/// Frame rate of VMD keyframe numbers.
constexpr float kVmdFps = 30.0f;

/// Bytes of a bone name field in a bone keyframe (Shift-JIS, NUL-terminated within the field when shorter).
constexpr size_t kVmdBoneNameBytes = 15;

/// One interpolation curve: the cubic Bézier from (0, 0) to (1, 1) with control points (x1, y1) and (x2, y2) in
/// 1/127 units ([0, 127] each). The default (20, 20, 107, 107) is MMD's linear curve.
struct VmdCurve {
  uint8_t x1 = 20, y1 = 20, x2 = 107, y2 = 107;
};

/// Curves of a bone keyframe, in the order the 64-byte block stores them.
enum VmdCurveAxis : int { kVmdCurveX = 0, kVmdCurveY = 1, kVmdCurveZ = 2, kVmdCurveRotation = 3 };

// === Motion

/// A bone keyframe.
///   bone         bone name, UTF-8 (as decoded from the 15-byte Shift-JIS field: long names arrive cut)
///   frame        keyframe number (at kVmdFps)
///   translation  local translation from the rest position (PMX units, MMD's frame)
///   rotation     local rotation (unit quaternion; stored x, y, z, w)
///   curves       interpolation from the previous key to this one: X, Y, Z translation and rotation
struct VmdBoneKey {
  std::string bone;
  uint32_t frame = 0;
  Eigen::Vector3f translation = Eigen::Vector3f::Zero();
  Eigen::Quaternionf rotation = Eigen::Quaternionf::Identity();
  std::array<VmdCurve, 4> curves{};
};

/// A VMD file: its bone keys in file order and the counts of the tracks amt does not use.
struct VmdMotion {
  std::string source;      ///< file path or display name (for messages)
  int version = 2;         ///< 2 ("Vocaloid Motion Data 0002", 20-byte model name) or 1 (10-byte model name)
  std::string model_name;  ///< the model the motion was made for, UTF-8
  std::vector<VmdBoneKey> bone_keys;
  uint32_t morph_keys = 0, camera_keys = 0, light_keys = 0, self_shadow_keys = 0, ik_keys = 0;

  /// Largest keyframe number of the bone keys (0 without keys).
  uint32_t last_frame() const;
  /// One line about the skipped tracks, e.g. "morph, camera and light tracks ignored (12 keyframes)"; empty when
  /// the file has none.
  std::string ignored_note() const;
};

// === Reading and writing

/// Reads a VMD file (version 1 or 2). Throws amt::Error with one line "path: field: expected ..., found ..." for a
/// non-regular file, a wrong header, a truncated file, a count larger than the bytes left allow, or a non-finite
/// number. A file may end after any complete section (older writers stop after the bone or morph keys).
VmdMotion read_vmd(const std::string& path);

/// The same from `size` bytes in memory; `source` names them in messages. Never reads outside [data, data + size).
VmdMotion parse_vmd(const uint8_t* data, size_t size, const std::string& source);

/// The bytes of a version-2 VMD file with `motion`'s model name and bone keys (names encoded as Shift-JIS, CP932,
/// and cut to their field) and empty morph, camera, light, self-shadow and IK sections. For tests and examples.
std::vector<uint8_t> vmd_bytes(const VmdMotion& motion);

/// Writes vmd_bytes(motion) to `path`. Throws amt::Error when the file cannot be written.
void write_vmd(const VmdMotion& motion, const std::string& path);

// === Text

/// Shift-JIS (CP932) bytes up to the first NUL within `size` to UTF-8 (iconv). A character cut by the end of
/// the field is dropped; an invalid byte becomes U+FFFD.
std::string shift_jis_to_utf8(const uint8_t* bytes, size_t size);

/// UTF-8 to Shift-JIS (CP932, iconv); a character CP932 cannot hold becomes '?'.
std::string utf8_to_shift_jis(const std::string& text);

/// A name as a VMD field of `field_bytes` bytes holds it: encoded, cut to the field without splitting a
/// character, decoded. A PMX bone whose name is longer than the field matches the keys of this name.
std::string vmd_field_name(const std::string& name, size_t field_bytes = kVmdBoneNameBytes);

// === Interpolation

/// MMD's interpolation weight at t in [0, 1] of the curve (x1, y1, x2, y2) (each in [0, 127]): the Bézier
/// parameter s with x(s) = t is found by bisection to 1e-6, and y(s) returned. Linear curves return t.
float vmd_bezier_weight(uint8_t x1, uint8_t y1, uint8_t x2, uint8_t y2, float t);

/// A bone's local motion at one (possibly fractional) frame.
struct VmdBonePose {
  Eigen::Vector3f translation = Eigen::Vector3f::Zero();
  Eigen::Quaternionf rotation = Eigen::Quaternionf::Identity();
};

/// Bone keys grouped by bone name, each group sorted by frame; of keys on the same frame the last in the file wins.
std::map<std::string, std::vector<VmdBoneKey>> vmd_bone_tracks(const VmdMotion& motion);

/// The pose of a track (sorted by frame, non-empty) at `frame`: before its first key the first key's, after its
/// last the last's; between keys k and k + 1 each translation axis moves by the weight of key k + 1's curve of
/// that axis and the rotation slerps by the weight of its rotation curve (MMD's rule).
VmdBonePose vmd_sample(const std::vector<VmdBoneKey>& track, float frame);

}  // namespace amt
