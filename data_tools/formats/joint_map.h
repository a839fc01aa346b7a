#pragma once
// Mapping a file's skeleton onto the canonical 22-joint body skeleton (docs/characters.md, "Joint maps"): built-in
// joint-name tables of the common conventions, the skeleton's structure for the joints those leave
// open, and a user map (`--joint-map FILE`). Format-independent: BVH, glTF and PMX skeletons all come
// here as joint names and parents, and their motions as a Skeleton plus a Motion.
#include <array>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/skeleton.h"

namespace amt {

// === Joint names

/// The form in which joint names are compared: without a namespace or DAG path (everything up to the
/// last ':' or '|': "mixamorig:Hips" -> "hips"), ASCII letters in lower case, full-width digits as
/// ASCII ("上半身２" -> "上半身2"), without a 3ds Max Biped prefix ("Bip01 L Thigh" -> "lthigh") and
/// without separators (space, '_', '-', '.'). Other UTF-8 text (MMD's Japanese names) is kept.
std::string normalize_joint_name(const std::string& name);

/// A built-in naming convention: for every canonical joint, the accepted joint names in priority
/// order, in normalize_joint_name form. The spine joints are left empty: they come from the
/// skeleton's structure (see map_to_canonical).
struct JointNameConvention {
  std::string name;
  std::array<std::vector<std::string>, kCanonicalJointCount> names;
};

/// The built-in conventions, in the order ties are broken: CMU / MotionBuilder / Mixamo,
/// 3ds Max / Biovision, 3ds Max Biped, SecondLife / Poser, SMPL, MMD (Japanese bone names).
const std::vector<JointNameConvention>& joint_name_conventions();

// === The user's joint map

/// A user joint map (`--joint-map FILE`), a JSON object {canonical joint name: the file's joint name},
/// e.g. {"left_hip": "LThigh", "spine3": "Chest"}. Any subset of the 22 canonical joints; the rest
/// are matched as usual.
///   source   the map's file name, for messages
///   entries  (canonical joint index, file joint name), in the order of the JSON text
struct JointMapFile {
  std::string source;
  std::vector<std::pair<int, std::string>> entries;
};

/// Parses a joint map from JSON text. Throws amt::Error "source:LINE: joint map: expected ..., found
/// ..." for malformed JSON, a value that is not an object, an unknown canonical joint name (the
/// message lists the 22) or a value that is not a non-empty string.
JointMapFile parse_joint_map(const std::string& json_text, const std::string& source);

/// Reads and parses the joint map at `path`.
JointMapFile read_joint_map(const std::string& path);

// === Mapping

/// How a canonical joint found its file joint.
enum class JointMatchKind : uint8_t { kUserMap, kNameTable, kStructure };

/// Which joint of the file drives each canonical joint.
///   source_joint  per canonical joint (CanonicalJoint order), an index into the file's joints; two
///                 canonical joints may share one (a file with fewer spine joints than three)
///   kind          per canonical joint, how it was found
///   convention    the built-in convention that matched most names
struct JointMapping {
  std::array<int, kCanonicalJointCount> source_joint{};
  std::array<JointMatchKind, kCanonicalJointCount> kind{};
  std::string convention;

  /// "pelvis=Hips, left_hip=LeftUpLeg, ..." with the file's joint names.
  std::string describe(const std::vector<std::string>& names) const;
};

/// Maps the file's joints (names, and parents: -1 for a root, any order without cycles) onto the
/// canonical joints. `source` names the file in messages.
///   1. The user map's entries, by exact name, else by normalize_joint_name (unique match).
///   2. The built-in convention that matches most of the remaining canonical joints, by
///      normalize_joint_name after removing a prefix that all joint names share up to a separator
///      ("Character1_", "m_avg_"); then the other conventions for what it left open, never
///      reusing a file joint.
///   3. From the structure: spine3 is the lowest common ancestor of the neck and the two collars
///      (the shoulders when collars are unmatched), or the neck's parent when that is the neck
///      itself (3ds Max Biped hangs the clavicles on the neck); the joints from the pelvis (not
///      included) up to spine3 give spine1 = the first, spine2 = the ((n - 1) / 2)-th, spine3 = the
///      last (all three the pelvis's joint when there are none); an unmatched collar is its
///      shoulder's parent; an unmatched foot is its ankle's only child (an End Site joint, say),
///      else the ankle.
/// Throws amt::Error for a user-map name that is not in the file, or when canonical joints remain
/// unmatched: "source: skeleton: could not match canonical joints neck, head to any of the file's
/// joints (Hips, ...); pass --joint-map ...".
JointMapping map_to_canonical(const std::vector<std::string>& names, const std::vector<int>& parents,
                              const std::optional<JointMapFile>& user_map, const std::string& source);

// === Motion on the canonical skeleton

/// A motion moved onto the canonical skeleton.
///   skeleton  canonical names and parents; rest positions are the mapped file joints' (metres)
///   motion    on `skeleton`: each canonical joint turns with the full global rotation of its file
///             joint, and the pelvis moves as its file joint does
///   mapping   the file joints used
struct CanonicalMotion {
  Skeleton skeleton;
  Motion motion;
  JointMapping mapping;
};

/// Composes a motion on the file's full skeleton onto the canonical joints: global rotations G by
/// forward kinematics on the full skeleton, then canonical local rotation = G(mapped joint of the
/// canonical parent)^-1 * G(mapped joint), and root translation = position of the pelvis's file
/// joint - its rest position. Joints between two mapped ones (CMU's LHipJoint) thus pass their
/// rotation on; a bone of the canonical skeleton that spans them turns with its parent's file joint.
/// `skeleton` must be valid (validate_skeleton) and `motion` on it.
CanonicalMotion to_canonical(const Skeleton& skeleton, const Motion& motion, const JointMapping& mapping,
                             const std::string& source);

}  // namespace amt
