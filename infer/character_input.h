#pragma once
// The character the runtime animates, from any supported source (glTF/GLB, OBJ + joints JSON, PMX or a
// dataset character), with its skeleton moved onto the canonical 22 joints. Real skeletons are not
// canonical (issue 6, item 3): a canonical joint that the file lacks (no collars, two spine joints
// instead of three, no foot) is placed on the line between its mapped neighbours; the file's extra
// joints (twist, finger, apparel bones) are carried along by their nearest mapped ancestor.
#include <optional>
#include <string>
#include <vector>

#include "data_tools/formats/joint_map.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/skeleton.h"

namespace amt {

// === Canonical rest skeleton of a file skeleton

/// The canonical skeleton of a file skeleton and how it was made.
///   skeleton        canonical names and parents; rest joints from the mapped file joints (metres)
///   mapping         the file joint of each canonical joint (data_tools/formats/joint_map.h)
///   placed          canonical joints the file lacks (their file joint is their canonical parent's),
///                   placed evenly on the line between the nearest mapped ancestor and descendant
///                   (a leaf, the foot, continues its parent bone in the canonical proportions)
///   carrier         per file joint, the canonical joint that carries it: its own when it is mapped,
///                   else that of its nearest mapped ancestor (the pelvis for joints above the root)
///   extra           names of the file joints that no canonical joint maps (carried by `carrier`)
struct CanonicalRest {
  Skeleton skeleton;
  JointMapping mapping;
  std::vector<int> placed;
  std::vector<int> carrier;
  std::vector<std::string> extra;

  /// Several lines: the canonical joint <- file joint table with how each was found, the placed
  /// joints and the extra joints.
  std::string describe(const std::vector<std::string>& file_names) const;
};

/// Places the canonical joints that share their file joint with their canonical parent (the file lacks
/// them): a chain of such joints is spread evenly on the line from its mapped ancestor to its first
/// mapped descendant (along first children in canonical order); a chain without one (a foot on its
/// ankle) continues the canonical skeleton's bones, scaled like the parent bone.
///   rest_joints  #22 by 3 canonical rest joints, each at its mapped file joint; updated in place
/// Returns the placed canonical joints, ascending.
std::vector<int> place_missing_joints(MatrixX3f& rest_joints, const JointMapping& mapping);

/// Maps a file skeleton onto the canonical joints (map_to_canonical) and places the missing ones.
/// `file` need not be topological (parents -1 for roots, no cycles); `source` names it in errors.
/// Throws amt::Error when the joints cannot be mapped (the message lists the file's joints and
/// suggests --character-joint-map).
CanonicalRest canonical_rest(const Skeleton& file, const std::optional<JointMapFile>& user_map,
                             const std::string& source);

// === The runtime character

/// Where a character comes from and how to read it.
///   spec        "hero.glb", "hero.gltf", "hero.obj", "hero.pmx", "data.h5:character_name", or
///               "generated:SEED[:VERTICES]" for the dataset builder's dressed stylized character
///               (generate_body + dress_character, about VERTICES vertices, 8000 by default, ~30 % apparel)
///   joints      a joints JSON (data_tools/formats/obj_io.h) giving the skeleton of an unrigged mesh; for OBJ
///               the sidecar "<stem>.joints.json" is used when this is empty
///   joint_map   the user's joint map (`--character-joint-map`), or empty
struct CharacterSpec {
  std::string spec;
  std::string joints;
  std::string joint_map;
};

/// A character ready to bind.
///   name            the file stem, or the dataset character's name
///   mesh            rest mesh, metres, Y up (PMX converted at 0.08 m per unit)
///   skeleton        canonical skeleton on the character's rest joints
///   file_skeleton   the file's own skeleton (canonical for a dataset character)
///   rest            how the canonical skeleton was made (mapping, placed and extra joints)
///   apparel_mask    the dataset's ground-truth mask (N entries 0/1) for a dataset character, else empty
///   rig_apparel_mask  the apparel the character's own rig names (`--apparel-mask rig`; N entries 0/1), empty
///                   when it names none: a PMX model's physics-driven vertices (pmx_physics_apparel_mask), a
///                   skinned glTF's vertices on chains of bones outside the canonical map (not fingers, toes,
///                   eyes, jaw, tongue, twist or roll bones by name), a dataset character's ground truth, a
///                   generated character's apparel; `rig_apparel` says where it came from
///   dataset, dataset_character  the dataset file and character name ("" otherwise)
struct RuntimeCharacter {
  std::string name;
  TriMesh mesh;
  Skeleton skeleton;
  Skeleton file_skeleton;
  CanonicalRest rest;
  std::vector<uint8_t> apparel_mask;
  std::vector<uint8_t> rig_apparel_mask;
  std::string rig_apparel;
  std::string dataset, dataset_character;
};

/// Splits "file.h5:name" into ("file.h5", "name") when the part before the last ':' ends in .h5 or
/// .hdf5; otherwise returns std::nullopt (a plain path).
std::optional<std::pair<std::string, std::string>> split_dataset_spec(const std::string& spec);

/// Reads a character. Throws amt::Error naming the file for an unreadable or unsupported file, a
/// character without a skeleton and no joints file ("x.obj: joints: the character has no skeleton:
/// expected x.joints.json beside it or --character-joints FILE"), or an unmappable skeleton.
RuntimeCharacter load_character(const CharacterSpec& spec);

/// Reads a per-vertex apparel mask (`--apparel-mask FILE`) for a mesh of `num_vertices` vertices:
/// a JSON array of N numbers 0/1 (or booleans), or a text file of N whitespace-separated 0/1 values.
/// Throws amt::Error for a wrong count or a value other than 0 and 1.
std::vector<uint8_t> read_apparel_mask(const std::string& path, int num_vertices);

}  // namespace amt
