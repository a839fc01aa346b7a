#pragma once
// A PMX model (MikuMikuDance) as glTF 2.0 (GLB) or as a VRM 1.0 avatar (`amt convert MODEL.pmx --out X.glb|X.vrm`),
// its physics as VRMC_springBone spring bones. Written with Debian's libtinygltf as gltf_export.h writes its files,
// and read back by gltf_import.h (gltf_character, gltf_vrm_joint_map, gltf_vrm_spring_rig).
//
// Frame. The model is taken into amt's frame first (pmx_to_amt_frame: metres at metres_per_unit, Y up,
// right-handed, facing +Z), which is also glTF's frame and VRM 1.0's facing, so nothing is turned.
//
// Mesh. One mesh with one TRIANGLES primitive per PMX material that draws faces (its face range, in file order;
// faces no material draws go to one more primitive with a grey material). Each primitive has its own vertices:
// the PMX vertices its faces use, in PMX order (a vertex two materials share is written twice, one no face uses
// is not written; PmxGltfSummary::vertex_source gives the PMX vertex of each written one). Attributes: POSITION;
// NORMAL, the authored normal made unit length (the area-weighted face normal where it is zero, then +Y);
// TEXCOORD_0, PMX's uv unchanged (both PMX, a Direct3D format, and glTF put uv (0, 0) at the image's top-left
// corner, v growing downwards, so no flip is needed); JOINTS_0 / WEIGHTS_0. Additional uvs and edge scales are
// not written.
//
// Skeleton. Node 0 is the skinned mesh at the scene root; node 1 + b is PMX bone b (every bone, IK and helper
// bones too: glTF has no IK or append rotations, they become plain bones) at translation position_b -
// position_parent (a root bone: position_b) with identity rotation, since PMX bones have no rest rotation. A model
// with several root bones gets a node "pmx_root" at the origin above them (not a joint), so that the skin's joints
// share one root. One skin over the bones in PMX order, inverse bind matrices translate(-position_b). Weights are
// pmx_skin_weights': BDEF1 / BDEF2 / BDEF4 as authored; QDEF (dual-quaternion blending) taken as BDEF4 and SDEF
// (spherical blending around C, R0, R1) as its BDEF2: linear blend skinning approximates both, exact at rest and
// off by the candy-wrapper loss of volume under strong twists; normalised, at most 4 per vertex, largest first.
//
// Materials. Per PMX material: baseColorFactor its diffuse RGBA (clamped to [0, 1]), metallicFactor 0,
// roughnessFactor 1 (MMD's shading is diffuse with a toon ramp; specular, ambient and outlines are not carried),
// doubleSided its no-cull flag, alphaMode BLEND when its alpha < 1 (else OPAQUE). Its main texture becomes
// baseColorTexture (TEXCOORD_0) with the image embedded as it is when the file is a PNG or a JPEG (recognised by
// its bytes, not its name). Anything else is left out with a one-line note naming the texture and the material
// keeps its colour: BMP, TGA and DDS cannot go into core glTF, nor can a file that is missing, outside the model's
// folder (an absolute path or one climbing out with ".."), larger than 64 MiB or of an unknown kind. A texture path
// is the PMX's with '\' as '/', relative to the model's folder; a name that differs only in letter case is found
// (the models come from Windows). Sphere and toon textures are not carried (a note each).
//
// Spring bones (VRMC_springBone 1.0, in both .glb and .vrm). A bone is physics-driven when a rigid body in mode 1
// (dynamic) or 2 (dynamic with bone position) is on it. Each physics-driven bone whose parent is not one starts a
// chain, which runs down its physics-driven children to the leaf; the chain is one spring whose joints are its
// bones in order. At a branch the first child (lowest index) continues the chain and every other child starts a
// spring of its own, as the specification's "Branching SpringChain" says (the branch point is not repeated). The
// last joint of a spring is only its tail (the specification rotates a joint towards the next one): a leaf is
// followed by a bone without a rigid body below it when there is one, else by a tip node "<bone>_tip" at the
// leaf's tail (its tail bone or offset; failing that, the far end of its rigid body, twice its centre's offset
// from the bone), else the leaf does not turn. A chain of one bone with no tail is left out (a note).
// Per joint (its bone's first physics-driven body, and the PMX joint whose body B is that body, else whose body A
// is): hitRadius the body's size (sphere and capsule radius, a box's smallest half extent: the sphere that stays
// inside it), and stiffness, dragForce and gravityPower from pmx_spring_parameters.
// Colliders: each rigid body in mode 0 (follows its bone) on a bone is a collider on that bone's node, its
// offsets in the node's frame (identity rotation, so model axes): a sphere as it is, a capsule from end cap centre
// to end cap centre (its Y axis, as MMD shapes it), a box as the smaller of the capsule and the sphere that cover
// it. Colliders are grouped by their PMX collision group (colliderGroups "group N"); a spring uses the groups its
// bodies collide with under MMD's masks (a body of group a with mask ma and a collider of group c with mask mc
// collide when bit c of ma and bit a of mc are set, as MMD passes them to Bullet), which is every group when the
// masks exclude nothing. PMX joints' translation limits and springs are not carried: a VRM spring only turns.
//
// VRM (.vrm). extensions.VRMC_vrm: specVersion "1.0"; meta: name the model's name (English name, then the file
// name when empty), authors from the comment's author line ("作者", "author", "model by", "made by", ...: the text
// after it) or "unknown", licenseUrl "https://vrm.dev/licenses/1.0/" and every permission at the specification's
// most restrictive value (onlyAuthor, personalNonProfit, no redistribution, modification prohibited, credit
// required, no violent, sexual, political or antisocial use): the PMX's own terms are in its comment, which goes
// whole into meta.extras.pmx_comment for the user to carry over by hand. humanoid: pmx_vrm_humanoid. The rest pose
// is the PMX's (usually an A-pose), not the T-pose VRM 1.0 asks for: amt aligns rest poses itself when it
// retargets, other VRM tools may not (a note). extensionsUsed lists VRMC_vrm and VRMC_springBone.
//
// File. GLB, written to "<path>.amt-tmp" and renamed onto the path (atomic_file.h). asset.generator "amt
// <version>"; asset.extras {"amt_format": "converted-pmx", "amt_format_version": 1, "metres_per_unit": s}.
// Morphs, display frames and soft bodies are dropped (a note each).
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "data_tools/formats/joint_map.h"
#include "data_tools/formats/pmx_import.h"

namespace amt {

// === Spring bones

/// The VRMC_springBone parameters of one spring joint.
///   stiffness      pull back to the rest direction (VRM "stiffness", >= 0)
///   drag_force     share of the velocity lost per update (VRM "dragForce", [0, 1])
///   gravity_power  pull along -Y (VRM "gravityPower", >= 0)
///   hit_radius     the joint's collision sphere, metres (VRM "hitRadius")
struct PmxSpringParameters {
  float stiffness = 1.0f;
  float drag_force = 0.5f;
  float gravity_power = 0.0f;
  float hit_radius = 0.0f;
};

/// Spring parameters from MMD physics (hit_radius is left 0: it comes from the body's size).
///   damping         the body's damping as authored, the mean of its linear and angular damping (Bullet's share of
///                   velocity lost per second), clamped to [0, 1]
///   angular_spring  the PMX joint's rotation spring stiffness, the median of its three |spring_angular| (0: none)
///   angular_range   the PMX joint's rotation freedom in radians, the median over its three axes of max - min
///                   (2 pi on an axis whose min > max, i.e. free; 2 pi when the body has no joint)
/// The mapping:
///   dragForce    = 0.1 + 0.7 damping
///   stiffness    = min(4, 0.5 (1 + log2(1 + angular_spring)) / sqrt(max(angular_range, 0.1)))
///   gravityPower = 0.25 / (1 + angular_spring / 10)
/// dragForce grows with damping; stiffness grows with the spring and shrinks as the joint's limits widen;
/// gravityPower shrinks as the spring stiffens. It is an approximation, not a conversion: MMD simulates rigid bodies
/// with mass, Bullet's per-second damping, spring-motor joints with hard angle limits and contacts between the
/// bodies, while a VRM spring is a massless verlet point per joint with a per-update drag, a pull back to rest and
/// no limits. A literal per-second match of the damping at 60 updates a second would give drags near 0.01 and
/// springs that never settle (nothing else takes their energy), so the mapping keeps every parameter in the range
/// VRM authoring tools use (UniVRM's defaults: stiffness 1, drag 0.4, gravity 0) and monotone in the PMX values, so
/// stiffer, more damped MMD physics gives stiffer, more damped springs.
PmxSpringParameters pmx_spring_parameters(float damping, float angular_spring, float angular_range);

/// One spring (a VRM SpringChain) of a model.
///   bones     PMX bone indices, head first; each is a spring joint with `parameters` (same index), the last one
///             only a tail when `tip` is false
///   tip       true when the chain ends in a tip node at `tip_position` (model frame) below the last bone
struct PmxSpringChain {
  std::vector<int> bones;
  std::vector<PmxSpringParameters> parameters;
  bool tip = false;
  Eigen::Vector3f tip_position = Eigen::Vector3f::Zero();
};

/// The springs of a model in amt's frame (see the top of this file), in the order of their first bone. Chains
/// that cannot turn anything are left out with a one-line note in `notes` (when given).
std::vector<PmxSpringChain> pmx_spring_chains(const PmxModel& model, std::vector<std::string>* notes = nullptr);

/// A spring-bone collider: on bone `bone`'s node, a sphere at `offset` or a capsule from `offset` to `tail`
/// (metres, in the node's frame, which has the model's axes), of `radius`. `body` is the PMX rigid body it comes
/// from.
struct PmxSpringCollider {
  int body = -1;
  int bone = -1;
  bool capsule = false;
  Eigen::Vector3f offset = Eigen::Vector3f::Zero();
  Eigen::Vector3f tail = Eigen::Vector3f::Zero();
  float radius = 0.0f;
};

/// The colliders of a model in amt's frame: every rigid body in mode 0 with a bone, in body order.
std::vector<PmxSpringCollider> pmx_spring_colliders(const PmxModel& model);

// === VRM humanoid

/// The VRM humanoid bones of a model (any frame): (VRM bone name, PMX bone index) in the order hips, spine, chest,
/// upperChest, neck, head, then legs and arms, left before right. The bones come from map_to_canonical on the
/// bones' names and parents (the MMD name table of joint_map.h: 下半身, 上半身, 首, 頭, 左足, 左ひざ, 左足首,
/// 左つま先, 左肩, 左腕, 左ひじ, 左手首, ...; or `joint_map`): hips the pelvis's bone, spine / chest / upperChest
/// the distinct bones of spine1..spine3 in order, leftShoulder the collar's, leftUpperArm the shoulder's,
/// leftLowerArm the elbow's, leftHand the wrist's, leftUpperLeg the hip's, leftLowerLeg the knee's, leftFoot the
/// ankle's, leftToes the foot's. A bone already taken is not given to an optional humanoid bone. When the hips'
/// bone is not above the spine's (an MMD model hangs 下半身 and 上半身 side by side from センター), the hips are
/// their nearest common ancestor (a note). An optional bone whose nearest humanoid ancestor is not the one VRM
/// requires is dropped (a note). Throws amt::Error with one line naming the required humanoid bones that are
/// missing or misplaced.
std::vector<std::pair<std::string, int>> pmx_vrm_humanoid(const PmxModel& model,
                                                          const std::optional<JointMapFile>& joint_map = std::nullopt,
                                                          std::vector<std::string>* notes = nullptr);

// === Conversion

/// The file written.
enum class PmxGltfKind { kGlb, kVrm };

/// Choices of write_pmx_gltf.
///   kind             GLB, or VRM 1.0 (a GLB with VRMC_vrm)
///   metres_per_unit  pmx_to_amt_frame's scale for a model in PmxFrame::kMmd (a model in kAmt keeps its own)
///   texture_folder   where texture paths are resolved; empty: the folder of model.source
///   joint_map        for the humanoid of a .vrm (pmx_vrm_humanoid)
struct PmxGltfOptions {
  PmxGltfKind kind = PmxGltfKind::kGlb;
  float metres_per_unit = kPmxMetresPerUnit;
  std::string texture_folder;
  std::optional<JointMapFile> joint_map;
};

/// What write_pmx_gltf wrote.
///   pmx_vertices, vertices  the model's vertices and those written (see the top of this file)
///   faces, primitives, bones, nodes, materials  as written
///   textures_embedded       images in the file; textures_left_out, main textures that are not (a note each)
///   springs, spring_joints, spring_segments  springs, their joints (tails included) and the joints that turn
///   colliders, collider_groups  as written
///   humanoid                (VRM bone, PMX bone name), for a .vrm
///   vertex_source           per written vertex, its PMX vertex
///   notes                   one line each: what was left out, dropped or approximated
///   bytes                   the file's size
struct PmxGltfSummary {
  int pmx_vertices = 0, vertices = 0, faces = 0, primitives = 0, bones = 0, nodes = 0, materials = 0;
  int textures_embedded = 0, textures_left_out = 0;
  int springs = 0, spring_joints = 0, spring_segments = 0, colliders = 0, collider_groups = 0;
  std::vector<std::pair<std::string, std::string>> humanoid;
  std::vector<int> vertex_source;
  std::vector<std::string> notes;
  uint64_t bytes = 0;
};

/// Writes `model` (either frame) to `path` as the top of this file says. Throws amt::Error with one line naming the
/// path or the model and the field: a model without faces, a .vrm whose humanoid bones are missing, a
/// metres_per_unit that is not finite and positive, a file of 4 GiB or more, a failed write (nothing is left at
/// `path` then).
PmxGltfSummary write_pmx_gltf(const PmxModel& model, const std::string& path, const PmxGltfOptions& options = {});

}  // namespace amt
