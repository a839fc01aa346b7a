#pragma once
// The character the runtime animates, from any supported source (glTF/GLB, OBJ + joints JSON, PMX or a
// dataset character), with its skeleton moved onto the canonical 22 joints. Real skeletons are not
// canonical (issue 6, item 3): a canonical joint that the file lacks (no collars, two spine joints
// instead of three, no foot) is placed on the line between its mapped neighbours; the file's extra
// joints (twist, finger, apparel bones) are carried along by their nearest mapped ancestor.
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "data_tools/formats/canonical_rest.h"
#include "data_tools/formats/joint_map.h"
#include "data_tools/geometry/apparel_topology.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/spring_bones.h"

namespace amt {

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
///   rig_bones       the rig's own apparel bones (below)
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
  /// The rig's own apparel bones with their vertices' weights (`--apparel-handles rig`): a PMX model's
  /// physics-driven bones, a skinned glTF's chain bones, a dataset character's rig bones that are not joints of its
  /// skeleton (rig_apparel_bones); null when the character's rig names none (a generated character: none kept).
  std::shared_ptr<const ApparelBones> rig_bones;
  /// rig_bones with ApparelBones::response measured (rig_probe.h: a PMX model's rigid bodies, a VRM avatar's
  /// springs), for an apparel module that reads it; the probe simulates a few seconds of the rig, so it runs only
  /// when called. Null when the file has no rig amt can simulate (rig_bones then carry what they have: a dataset
  /// character's stored response, or none).
  std::function<std::shared_ptr<const ApparelBones>()> rig_bones_with_response;
  std::string dataset, dataset_character;
  /// What the file is beyond its extension ("VRM 0.x", "VRM 1.0"; "" otherwise): a VRM avatar's humanoid map
  /// maps its skeleton and its spring bones are its rig's apparel.
  std::string file_kind;
  /// True when the file's character faced -Z (its left hip on -X, as VRM 0.x avatars stand) and was turned half
  /// a turn about Y to face +Z as amt's motions do; mesh and skeletons are the turned ones.
  bool turned = false;
  /// A VRM avatar's spring bones on file_skeleton (`--apparel spring-bones`); null for other characters.
  std::shared_ptr<const SpringRig> springs;
  /// The file's own skin weights over file_skeleton (a skinned glTF / VRM, a PMX model), which `amt animate`
  /// skins the body with by default (canonical_file_weights) and spring bones move vertices with; empty for
  /// characters without a skin of their own (OBJ, dataset and generated characters, --character-joints).
  SparseWeights file_weights;
};

/// Splits "file.h5:name" into ("file.h5", "name") when the part before the last ':' ends in .h5 or
/// .hdf5; otherwise returns std::nullopt (a plain path).
std::optional<std::pair<std::string, std::string>> split_dataset_spec(const std::string& spec);

/// Reads a character. Throws amt::Error naming the file for an unreadable or unsupported file, a
/// character without a skeleton and no joints file ("x.obj: joints: the character has no skeleton:
/// expected x.joints.json beside it or --character-joints FILE"), or an unmappable skeleton.
RuntimeCharacter load_character(const CharacterSpec& spec);

/// The file's own skin weights moved onto the canonical joints: each file joint's weight added to the canonical joint
/// that carries it (CanonicalRest::carrier), rows renormalised to sum to 1. #V by kCanonicalJointCount; empty (0
/// rows) when the character has no skin of its own (RuntimeCharacter::file_weights).
MatrixXfR canonical_file_weights(const RuntimeCharacter& character);

/// Reads a per-vertex apparel mask (`--apparel-mask FILE`) for a mesh of `num_vertices` vertices:
/// a JSON array of N numbers 0/1 (or booleans), or a text file of N whitespace-separated 0/1 values.
/// Throws amt::Error for a wrong count or a value other than 0 and 1.
std::vector<uint8_t> read_apparel_mask(const std::string& path, int num_vertices);

}  // namespace amt
