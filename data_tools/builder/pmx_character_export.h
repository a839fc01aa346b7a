#pragma once
// A dressed procedural character (data_tools/builder/apparel.h) as a PMX model: test data for the PMX paths of amt
// (`amt dataset build --pmx`, `amt animate` on PMX) without a real MMD character, which cannot be redistributed.
// `amt dataset export-pmx` writes one with data_tools/formats/pmx_export.h's write_pmx.
//
// What the model holds (PmxFrame::kMmd: PMX units, MMD's left-handed frame; pmx_to_amt_frame with the same
// metres_per_unit maps every position back to the character's, to float rounding):
//   vertices  DressedCharacter::mesh in order (body vertices first), normals from the mesh, uv 0, edge scale 1,
//             skinning DressedCharacter::rig_weights: BDEF1 for one influence, else BDEF4 with the weights as they
//             are (unused slots bone -1, weight 0), so the non-zero weights are exactly the rig's;
//   faces     the mesh's triangles, winding reversed with the reflection (as pmx_to_amt_frame reverses it back);
//   bones     the rig's bones in order: 0..21 the canonical joints under MMD's standard Japanese names (the MMD
//             name table of data_tools/formats/joint_map.h, e.g. 下半身, 左腕, 右ひざ; the spine, which that table
//             leaves to the structure, 上半身, 上半身2, 上半身3), so map_to_canonical maps them back joint for
//             joint; then the apparel bones under their rig names ("pleated_skirt0_c3_b2"), parents before children;
//             English names are the rig's names;
//   bodies    the rig's bodies in order: body capsules kFollowBone (kinematic), apparel bodies kDynamic (the
//             procedural rig's PhysicsMode, mode for mode), sizes and rest transforms converted, masses as below,
//             damping, friction and restitution as they are, collision group as is and collision mask = the
//             complement of the rig's non-collision mask (as pmx_physics_rig reads it);
//   joints    the rig's spring 6-DOF joints in order, limits converted to MMD's frame and units, stiffness as below.
// Hence pmx_physics_apparel_mask of the model is the character's apparel_mask exactly, and pmx_physics_rig accepts
// it. The sections a PmxModel does not hold are written as pmx_export.h says (one material, no morphs).
//
// Units of the dynamics. The procedural rig is simulated in metres under g_m = 9.8 m/s^2 (PhysicsSettings' default);
// a PMX rig in its own units under MMD's g_u = 98 units/s^2 (pmx_physics_settings). With s metres per unit, lengths
// become L_u = L_m / s and time is kept (clips play at the same frame rate). Let gamma = g_u s / g_m, MMD's gravity
// in metres over the procedural one: 0.8 at 0.08 m per unit, 1 at 0.1 m per unit.
//   masses             m_u = s^2 m_m. Only mass ratios matter to the motion (gravity, springs, joints and contacts
//                      all act per unit mass), but Bullet's spring (btGeneric6DofSpringConstraint) is not a plain
//                      spring: it is a motor with the force limit k * offset and the target velocity fps / iterations
//                      * k * offset. On a rotation axis the target velocity is an angular velocity, the same in both
//                      unit systems, so k_ang must not change; the torque limit k_ang * angle must then hold for
//                      inertias m L^2 that are s^-2 times larger in units, hence masses s^2 times smaller.
//   angular stiffness  k_u = gamma k_m  (with gamma = 1, unchanged: the same torque per radian for the same
//                      angular motion, as just said).
//   linear stiffness   k_u = gamma s^2 k_m (a force m a, s times larger in units, per length, 1/s times larger in
//                      units); its target velocity is then off by s^2, so linear springs do not convert exactly
//                      (the procedural rigs have none: ring joints limit their translation without a spring).
//   damping            unchanged (Bullet's damping is a fraction of the velocity lost per second).
//   friction, restitution  unchanged (dimensionless).
// At gamma = 1 (metres_per_unit = 0.1, where 98 units/s^2 is 9.8 m/s^2) this is an exact change of units: the PMX
// rig moves as the procedural one, exactly until bodies touch, then drifting slowly because Bullet's few absolute
// contact tolerances are in metres in one world and units in the other (a few centimetres after a second of
// swinging, tests/data_tools/builder/pmx_character_export_test.cpp). At MMD's usual 0.08 m per unit MMD's gravity is
// 20 % weaker than the procedural one; multiplying the springs by gamma keeps every equilibrium against gravity
// (rest sags) the same, while free swings are 1 / sqrt(gamma) (12 %) slower, which is how MMD itself moves a
// character of that size.
#include <array>
#include <string>

#include "data_tools/builder/apparel.h"
#include "data_tools/builder/dataset_builder.h"
#include "data_tools/formats/pmx_import.h"

namespace amt {

// === Names

/// MMD's standard Japanese bone name of each canonical joint (CanonicalJoint order): the first name of the MMD
/// convention of joint_name_conventions() (data_tools/formats/joint_map.h), and 上半身, 上半身2, 上半身3 for the
/// spine joints, which that convention leaves to the skeleton's structure.
const std::array<std::string, kCanonicalJointCount>& mmd_canonical_bone_names();

// === Export

/// Choices of pmx_from_character.
struct PmxCharacterExportOptions {
  /// Metres per PMX unit (> 0, finite): the inverse of pmx_to_amt_frame's scale. MMD's 0.08 by default; 0.1 makes
  /// the PMX physics under MMD's gravity a change of units of the procedural one (see the top of this header).
  float metres_per_unit = kPmxMetresPerUnit;
  /// Model name (header.name and name_english) and comment (header.comment and comment_english).
  std::string name = "amt character";
  std::string comment = "A procedural character made by amt (apparel-aware motion transfer).";
};

/// The PMX model of a dressed character (see the top of this header), in PmxFrame::kMmd, PMX 2.0, UTF-16LE, with
/// the smallest index sizes (pmx_fit_index_sizes). Throws amt::Error for a metres_per_unit that is not finite and
/// positive, or a character whose rig has not the canonical joints first.
PmxModel pmx_from_character(const DressedCharacter& dressed, const PmxCharacterExportOptions& options = {});

/// The dressed character `index` of the dataset that `options` describes, as `amt dataset build` makes it: the
/// seeds of plan_dataset (which depend only on options.seed and the index), generate_body with options.vertices,
/// dress_character with options.apparel. Throws amt::Error unless 0 <= index < options.characters, or on options
/// validate_build_options rejects (except `out`, which is not needed here).
DressedCharacter dataset_character(const DatasetBuildOptions& options, int index);

}  // namespace amt
