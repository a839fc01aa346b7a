#pragma once
// BVH (Biovision Hierarchy) motion import: a parser for the raw file, its conversion to amt's data
// model (docs/architecture.md, "The data model": metres, rotations relative to the rest pose), unit detection, frame-rate
// resampling, and the import onto the canonical 22-joint skeleton through data_tools/formats/joint_map.h.
//
// Conventions read from the file, as most BVH tools read them:
//   - The rest pose is the skeleton of OFFSETs with every rotation zero; Y is up.
//   - Rotation channels are Euler angles in degrees about the parent-frame axes, composed in the
//     order the CHANNELS line lists them: "Zrotation Xrotation Yrotation" gives R = Rz * Rx * Ry.
//   - Position channels give the joint's position in its parent's frame, replacing the OFFSET on
//     the axes they name (the root's position in the world).
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "data_tools/formats/joint_map.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === The raw file

/// One channel of a BVH joint, as named on its CHANNELS line.
enum class BvhChannel : uint8_t { kXposition, kYposition, kZposition, kXrotation, kYrotation, kZrotation };

/// The channel's name as BVH writes it ("Xposition", ..., "Zrotation").
const char* bvh_channel_name(BvhChannel channel);

/// A JOINT (or the ROOT) of the HIERARCHY section.
///   offset        position relative to the parent at rest, in file units
///   channels      in file order, 0 to 6, no channel twice
///   first_column  index of channels[0] in a frame's values
struct BvhJoint {
  std::string name;
  int parent = -1;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  std::vector<BvhChannel> channels;
  int first_column = 0;
};

/// An End Site: the tip of a leaf joint, a point without channels (offset in file units).
struct BvhEndSite {
  int parent = -1;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
};

/// A parsed BVH file, unchanged from the text: file units, degrees, the file's channel orders.
///   joints      in file order (depth first), joints[0] is the root, parents[j] < j
///   end_sites   in file order
///   frame_time  seconds between frames (the "Frame Time:" field)
///   values      #frames by #channels, frame-major: values[t * num_channels + c] is column c of frame t
struct BvhFile {
  std::string source;
  std::vector<BvhJoint> joints;
  std::vector<BvhEndSite> end_sites;
  int num_channels = 0;
  int num_frames = 0;
  double frame_time = 0.0;
  std::vector<double> values;

  /// Column c of frame t.
  double value(int t, int c) const { return values[static_cast<size_t>(t) * num_channels + c]; }
  /// 1 / frame_time, snapped to the nearest integer when within 0.01 % of it (".0083333" is 120 fps).
  double fps() const;
};

/// Parses BVH text. `source` names it in error messages ("walk.bvh"). The parser is hand-written:
/// no Debian package parses BVH. Any channel count (0 to 6) and order on any joint, End Sites, frame
/// times from 1e-6 to 10 s, any units. Bad input throws amt::Error with one line "source:LINE: field:
/// expected X, found Y": unknown keywords or channels, missing braces, duplicate joint names,
/// non-numeric, NaN or infinite values or numbers beyond +-1e9, a frame count that disagrees with
/// the data lines or that the rest of the text cannot hold (checked before anything is allocated),
/// more than 100 000 joints, a truncated file.
BvhFile parse_bvh(std::string_view text, const std::string& source);

/// Reads and parses the BVH file at `path` (errors name the path).
BvhFile read_bvh(const std::string& path);

// === Units

/// The units of a file: the scale that turns its lengths into metres.
///   metres_per_unit  the scale
///   name             "metres", "decimetres", "CMU units (1/0.45 inch)", "inches", "centimetres",
///                    "millimetres", or "given" when the user set the scale
///   rest_extent      largest side of the rest pose's bounding box (joints and End Sites), file units
struct BvhUnits {
  double metres_per_unit = 1.0;
  std::string name;
  double rest_extent = 0.0;
};

/// Detects the units from the size of the rest pose. The rule: among metres (1), decimetres (0.1),
/// CMU units (0.0254 / 0.45 = 0.0564444), inches (0.0254), centimetres (0.01) and millimetres (0.001),
/// take the scale that makes rest_extent (a humanoid's height, or its arm span in a T-pose) closest to
/// 1.7 m in ratio. So a rest extent E in file units reads as
///   E < 5.38 metres, < 22.6 decimetres, < 44.9 CMU units, < 107 inches, < 538 centimetres, else
///   millimetres.
/// The 20 CMU MotionBuilder-friendly clips measure 24.8 to 27.0 units (1.40 to 1.52 m, the T-pose arm
/// span; their skeleton has a short torso, while legs and hip height, 0.94 m, are an adult's).
/// Throws amt::Error for a rest pose of zero size. Pass the scale explicitly (`--bvh-scale`) for
/// anything that is not a human figure.
BvhUnits detect_bvh_units(const BvhFile& file);

// === Conversion to amt's data model

/// A BVH file as a skeleton and a motion on it, at the file's frame rate.
///   skeleton  every BVH joint in file order, then every End Site as a leaf joint named
///             "<parent> End" (made unique with a number if taken); rest positions are the
///             accumulated OFFSETs times the scale, lifted along Y so the lowest rest point is at
///             y = 0 (the rest figure stands on the floor, as retargeting expects)
///   motion    rotations from the Euler channels (identity for End Sites and channel-less joints);
///             root translation = root position - rest root position, metres, so forward
///             kinematics gives the file's positions times the scale
///   dropped_translation  amt motions keep bone lengths, so position channels on non-root joints
///             are not represented: the largest distance (metres) between such a channel position
///             and the joint's OFFSET over the clip; 0 when the file has none or they match
struct BvhMotion {
  Skeleton skeleton;
  Motion motion;
  double dropped_translation = 0.0;
};

/// Converts a parsed file with `metres_per_unit` (in (0, 1000]) as the scale. Throws amt::Error for
/// a scale out of range or more than 1e8 frames x joints.
BvhMotion bvh_to_motion(const BvhFile& file, double metres_per_unit);


// === Import onto the canonical skeleton

/// Choices of a BVH import.
struct BvhImportOptions {
  /// Metres per file unit (`--bvh-scale`, in (0, 1000]); detected by detect_bvh_units when empty.
  std::optional<double> scale;
  /// Frame rate of the output motion (30 by default); the file's own rate is std::nullopt.
  std::optional<float> fps = 30.0f;
  /// The user's joint map (`--joint-map`), which overrides the built-in name tables.
  std::optional<JointMapFile> joint_map;
  /// Drop a leading calibration frame (see is_calibration_frame): mocap exports such as the CMU BVH
  /// conversions start with one frame in a T-pose before the take, which would otherwise snap the
  /// character from a T-pose into the motion between frames 0 and 1.
  bool drop_calibration_frame = true;
};

/// A BVH file on the canonical skeleton, with what the import decided.
///   canonical     canonical skeleton with the file's proportions (metres, standing on y = 0) and
///                 the motion on it at the chosen frame rate; canonical.mapping names the file joints
///   units         the scale used (detected or given)
///   source_fps    the file's frame rate;  source_frames  its frame count
///   dropped_translation  see BvhMotion
struct BvhImport {
  CanonicalMotion canonical;
  BvhUnits units;
  double source_fps = 0.0;
  int source_frames = 0;
  double dropped_translation = 0.0;
  /// Whether a leading calibration frame was dropped.
  bool dropped_calibration_frame = false;
};

/// Whether frame 0 of `motion` is a calibration pose rather than part of the take: the mean rotation
/// angle of its joints (relative to rest) is under 10 degrees and under a third of the median of the
/// same mean over frames 1 to 30. Needs at least 3 frames.
bool is_calibration_frame(const Motion& motion);

/// Converts a parsed file: units, full-skeleton motion, joint mapping (map_to_canonical),
/// composition onto the canonical joints (to_canonical), dropping a calibration frame, then resampling. Throws amt::Error naming
/// the file when the joints cannot be mapped or an option is out of range.
BvhImport bvh_to_canonical(const BvhFile& file, const BvhImportOptions& options = {});

/// Reads the BVH file at `path` and converts it (read_bvh, then bvh_to_canonical).
BvhImport import_bvh(const std::string& path, const BvhImportOptions& options = {});

}  // namespace amt
