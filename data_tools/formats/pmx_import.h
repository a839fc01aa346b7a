#pragma once
// PMX 2.0 / 2.1 reader (MikuMikuDance models): mesh, skinning, bones with IK, rigid bodies and spring joints,
// the rig that docs/dataset.md ("Your own PMX models") simulates. Hand-written: no Debian package reads PMX.
//
// Two frames. A PmxModel holds either the file's values untouched (PmxFrame::kMmd: PMX units, 1 unit ~ 8 cm,
// MMD's left-handed frame, Y up, characters facing -Z, their left on +X) or the same model in amt's conventions
// (PmxFrame::kAmt, made by pmx_to_amt_frame: metres, Y up, right-handed, characters facing +Z, their left on +X).
//
// The mapping between them is the reflection S = diag(1, 1, -1) followed by a uniform scale s:
//   positions     p_amt = s S p              = s (x, y, -z)
//   directions    d_amt = S d                = (x, y, -z)            (normals, bone axes)
//   rotations     R_amt = S R S                                      (conjugation by the reflection)
//   Euler angles  e_amt = (-e_x, -e_y, e_z)  since S Rx(a) S = Rx(-a), S Ry(a) S = Ry(-a), S Rz(a) S = Rz(a)
//   angle ranges  x, y: [min, max] -> [-max, -min]; z unchanged     (joint and IK limits)
//   length ranges z: [min, max] -> [-s max, -s min]; x, y scaled     (joint translation limits)
//   triangles     (a, b, c) -> (a, c, b): a reflection reverses winding; after it, (b - a) x (c - a) points
//                 outwards as data_tools/geometry/mesh.h's vertex_normals expects.
// S maps MMD's -Z facing direction to +Z and keeps +X (the character's left), so no further turn is needed.
// PMX Euler angles compose as R = Ry(e_y) Rx(e_x) Rz(e_z) acting on column vectors (Direct3D's yaw-pitch-roll:
// roll about Z first, then pitch about X, then yaw about Y), in both frames: see pmx_euler_rotation.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Conventions

/// Metres per PMX unit used by default when converting to amt's frame (MMD's 1 unit ~ 8 cm).
constexpr float kPmxMetresPerUnit = 0.08f;

/// Frame and units of a PmxModel's geometric fields (see the top of this header).
enum class PmxFrame : uint8_t {
  kMmd,  ///< as stored in the file: PMX units, left-handed, facing -Z
  kAmt,  ///< amt's: PmxModel::scale metres per PMX unit, right-handed, facing +Z
};

/// Text encoding of the file's strings. Strings in a PmxModel are always UTF-8.
enum class PmxTextEncoding : uint8_t { kUtf16Le = 0, kUtf8 = 1 };

/// Vertex deform (skinning) type.
enum class PmxDeform : uint8_t {
  kBdef1 = 0,  ///< one bone, weight 1
  kBdef2 = 1,  ///< two bones, weights (w, 1 - w)
  kBdef4 = 2,  ///< four bones, four weights (not necessarily summing to 1 in the file)
  kSdef = 3,   ///< spherical deform: two bones as kBdef2 plus the centre C and the points R0, R1
  kQdef = 4,   ///< dual-quaternion deform with four bones (PMX 2.1)
};

/// Rigid body collision shape.
enum class PmxShape : uint8_t { kSphere = 0, kBox = 1, kCapsule = 2 };

/// How a rigid body and its bone drive each other.
enum class PmxPhysicsMode : uint8_t {
  kFollowBone = 0,               ///< kinematic: the body follows its bone
  kDynamic = 1,                  ///< simulated: the body drives its bone
  kDynamicWithBonePosition = 2,  ///< simulated rotation; the bone keeps its animated position
};

/// Joint (constraint) type. PMX 2.0 has only kSpring6Dof.
enum class PmxJointType : uint8_t {
  kSpring6Dof = 0,
  k6Dof = 1,
  kPointToPoint = 2,
  kConeTwist = 3,
  kSlider = 4,
  kHinge = 5,
};

/// Bone flag bits as stored in PmxBone::flags.
enum PmxBoneFlag : uint16_t {
  kPmxBoneTailIsBone = 0x0001,
  kPmxBoneRotatable = 0x0002,
  kPmxBoneTranslatable = 0x0004,
  kPmxBoneVisible = 0x0008,
  kPmxBoneEnabled = 0x0010,
  kPmxBoneIk = 0x0020,
  kPmxBoneInheritLocal = 0x0080,
  kPmxBoneInheritRotation = 0x0100,
  kPmxBoneInheritTranslation = 0x0200,
  kPmxBoneFixedAxis = 0x0400,
  kPmxBoneLocalAxes = 0x0800,
  kPmxBonePhysicsAfterDeform = 0x1000,
  kPmxBoneExternalParent = 0x2000,
};

// === Model

/// File header: format version, encodings and index sizes, names.
struct PmxHeader {
  float version = 2.0f;                                  ///< 2.0 or 2.1
  PmxTextEncoding encoding = PmxTextEncoding::kUtf16Le;  ///< encoding of the file's text
  int additional_uv_count = 0;                           ///< extra vec4 per vertex, 0..4
  int vertex_index_size = 4;                             ///< bytes per vertex index: 1, 2 (unsigned) or 4 (signed)
  int texture_index_size = 1;                            ///< bytes per texture index: 1, 2 or 4 (signed, -1 none)
  int material_index_size = 1;                           ///< bytes per material index (signed)
  int bone_index_size = 2;                               ///< bytes per bone index (signed)
  int morph_index_size = 1;                              ///< bytes per morph index (signed)
  int rigid_body_index_size = 2;                         ///< bytes per rigid body index (signed)
  std::string name;                                      ///< model name, UTF-8 (usually Japanese)
  std::string name_english;                              ///< universal (English) model name, UTF-8
  std::string comment;                                   ///< comment (licence and credits), UTF-8
  std::string comment_english;                           ///< universal comment, UTF-8
};

/// Per-vertex arrays; #V rows each.
struct PmxVertices {
  /// #V by 3 rest positions (PMX units, or metres in kAmt).
  MatrixX3f positions;
  /// #V by 3 normals (unit length as authored; directions, not scaled).
  MatrixX3f normals;
  /// #V by 2 texture coordinates (Direct3D convention: v grows downwards; unchanged by conversion).
  Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor> uvs;
  /// header.additional_uv_count matrices of #V by 4 extra vertex data (unchanged by conversion).
  std::vector<Eigen::Matrix<float, Eigen::Dynamic, 4, Eigen::RowMajor>> additional_uvs;
  /// #V deform types.
  std::vector<PmxDeform> deform;
  /// #V by 4 bone indices into PmxModel::bones; -1 in slots the deform does not use (and where the file says -1).
  Eigen::Matrix<int32_t, Eigen::Dynamic, 4, Eigen::RowMajor> bone_indices;
  /// #V by 4 weights of bone_indices: kBdef1 (1, 0, 0, 0); kBdef2 and kSdef (w, 1 - w, 0, 0) with w the stored
  /// weight; kBdef4 and kQdef the four stored weights, as stored (pmx_skin_weights normalises them).
  Eigen::Matrix<float, Eigen::Dynamic, 4, Eigen::RowMajor> bone_weights;
  /// #V by 3 SDEF centre C (a position: PMX units, or metres in kAmt); zero for other deform types.
  MatrixX3f sdef_c;
  /// #V by 3 SDEF point R0 (a position); zero for other deform types.
  MatrixX3f sdef_r0;
  /// #V by 3 SDEF point R1 (a position); zero for other deform types.
  MatrixX3f sdef_r1;
  /// #V outline (edge) scale factors, dimensionless.
  Eigen::VectorXf edge_scale;

  /// Number of vertices #V.
  int size() const { return static_cast<int>(positions.rows()); }
  /// Sizes every array for `n` vertices with `additional_uv_count` extra uvs: BDEF1 deforms, bone indices -1, edge
  /// scales 1 and everything else 0 (no bones until they are set).
  void resize(int n, int additional_uv_count);
};

/// One link of an IK chain.
struct PmxIkLink {
  int32_t bone = -1;                                    ///< index into PmxModel::bones
  bool has_limits = false;                              ///< whether limit_min / limit_max apply
  Eigen::Vector3f limit_min = Eigen::Vector3f::Zero();  ///< lower Euler angle limits (radians), same axes as joints
  Eigen::Vector3f limit_max = Eigen::Vector3f::Zero();  ///< upper Euler angle limits (radians)
};

/// Inverse kinematics of an IK bone: it moves `target` towards itself by rotating the links.
struct PmxIk {
  int32_t target = -1;           ///< effector bone index
  int32_t loop_count = 0;        ///< solver iterations
  float limit_angle = 0;         ///< maximum rotation per iteration (radians)
  std::vector<PmxIkLink> links;  ///< chain from the effector's parent upwards
};

/// A bone. PMX bones have no rest rotation: a rest pose is positions only.
struct PmxBone {
  std::string name;          ///< UTF-8 (e.g. "左腕")
  std::string name_english;  ///< UTF-8, often empty
  /// Global rest position (PMX units, or metres in kAmt).
  Eigen::Vector3f position = Eigen::Vector3f::Zero();
  int32_t parent = -1;  ///< parent bone index or -1. Parents may come after children in the file; no cycles.
  int32_t layer = 0;    ///< deform layer: bones transform in (layer, index) order
  uint16_t flags = 0;   ///< raw flag bits (PmxBoneFlag); decoded below

  bool tail_is_bone = false;          ///< tail given by tail_bone (else by tail_offset)
  bool rotatable = false;             ///< animator may rotate it
  bool translatable = false;          ///< animator may move it
  bool visible = false;               ///< shown in the editor
  bool enabled = false;               ///< operable in the editor
  bool is_ik = false;                 ///< carries `ik`
  bool inherit_local = false;         ///< inheritance uses the local transform
  bool inherit_rotation = false;      ///< adds inherit_weight x the inherit_parent's rotation
  bool inherit_translation = false;   ///< adds inherit_weight x the inherit_parent's translation
  bool has_fixed_axis = false;        ///< rotation restricted to fixed_axis
  bool has_local_axes = false;        ///< local_axis_x / local_axis_z are set
  bool physics_after_deform = false;  ///< transformed after the physics step
  bool has_external_parent = false;   ///< external_parent_key is set

  int32_t tail_bone = -1;                                  ///< tail bone index or -1 (when tail_is_bone)
  Eigen::Vector3f tail_offset = Eigen::Vector3f::Zero();   ///< tail relative to position (a length; when !tail_is_bone)
  int32_t inherit_parent = -1;                             ///< bone whose motion is inherited, or -1
  float inherit_weight = 0;                                ///< inherited fraction (may be negative)
  Eigen::Vector3f fixed_axis = Eigen::Vector3f::Zero();    ///< rotation axis (a direction)
  Eigen::Vector3f local_axis_x = Eigen::Vector3f::Zero();  ///< local X axis (a direction)
  Eigen::Vector3f local_axis_z = Eigen::Vector3f::Zero();  ///< local Z axis (a direction)
  int32_t external_parent_key = 0;                         ///< key of the external parent model
  PmxIk ik;                                                ///< set when is_ik
};

/// A rigid body of the physics rig (docs/dataset.md, "Your own PMX models").
struct PmxRigidBody {
  std::string name;          ///< UTF-8
  std::string name_english;  ///< UTF-8
  int32_t bone = -1;         ///< bone it follows or drives, or -1
  uint8_t group = 0;         ///< collision group, 0..15; the body's filter group is 1 << group
  /// Groups this body collides with: bit g set = collides with group g. (The PMX editor shows the cleared bits
  /// as "non-collision groups"; MMD feeds the stored value to Bullet as the collision filter mask.)
  uint16_t collision_mask = 0xFFFF;
  PmxShape shape = PmxShape::kSphere;
  /// Shape size (lengths): kSphere (radius, -, -); kBox half extents (x, y, z); kCapsule (radius, height of the
  /// cylinder between the cap centres along the body's Y, -). Unused components as stored.
  Eigen::Vector3f size = Eigen::Vector3f::Zero();
  /// Centre in model space (PMX units, or metres in kAmt).
  Eigen::Vector3f position = Eigen::Vector3f::Zero();
  /// Orientation in model space, Euler angles (radians), R = Ry(y) Rx(x) Rz(z): see pmx_euler_rotation.
  Eigen::Vector3f rotation = Eigen::Vector3f::Zero();
  float mass = 0;             ///< mass as authored (MMD units; unchanged by conversion); ignored in kFollowBone
  float linear_damping = 0;   ///< Bullet linear damping, 0..1 per second fraction as authored
  float angular_damping = 0;  ///< Bullet angular damping as authored
  float restitution = 0;      ///< bounciness as authored
  float friction = 0;         ///< friction coefficient as authored
  PmxPhysicsMode mode = PmxPhysicsMode::kFollowBone;
};

/// Material flag bits as stored in PmxMaterial::flags.
enum PmxMaterialFlag : uint8_t {
  kPmxMaterialDoubleSided = 0x01,   ///< no back-face culling
  kPmxMaterialGroundShadow = 0x02,  ///< casts MMD's ground shadow
  kPmxMaterialShadowMap = 0x04,     ///< draws to the self-shadow map
  kPmxMaterialSelfShadow = 0x08,    ///< receives the self-shadow
  kPmxMaterialEdge = 0x10,          ///< draws the outline (edge)
  kPmxMaterialVertexColour = 0x20,  ///< PMX 2.1: the first additional uv is a vertex colour
  kPmxMaterialPoints = 0x40,        ///< PMX 2.1: drawn as points
  kPmxMaterialLines = 0x80,         ///< PMX 2.1: drawn as lines
};

/// How a material's sphere texture combines with its colour.
enum class PmxSphereMode : uint8_t { kNone = 0, kMultiply = 1, kAdd = 2, kSubTexture = 3 };

/// A material: how MMD draws the next face_count faces (materials cover the faces in file order).
struct PmxMaterial {
  std::string name;                                       ///< UTF-8
  std::string name_english;                               ///< UTF-8
  Eigen::Vector4f diffuse = Eigen::Vector4f::Ones();      ///< RGBA as authored (usually in [0, 1]; alpha 1 opaque)
  Eigen::Vector3f specular = Eigen::Vector3f::Zero();     ///< RGB as authored
  float specular_strength = 0;                            ///< specular exponent as authored
  Eigen::Vector3f ambient = Eigen::Vector3f::Zero();      ///< RGB as authored
  uint8_t flags = 0;                                      ///< PmxMaterialFlag bits
  Eigen::Vector4f edge_colour = Eigen::Vector4f::Zero();  ///< outline RGBA as authored
  float edge_size = 0;                                    ///< outline width as authored
  int32_t texture = -1;                                   ///< index into PmxModel::textures, or -1 (none)
  int32_t sphere_texture = -1;                            ///< index into PmxModel::textures, or -1 (none)
  PmxSphereMode sphere_mode = PmxSphereMode::kNone;
  bool shared_toon = false;  ///< toon is MMD's shared toon01.bmp ... toon10.bmp (toon 0 ... 9), else a texture
  int32_t toon = -1;         ///< shared toon number, or index into PmxModel::textures, or -1 (none)
  std::string memo;          ///< free text, UTF-8
  /// Triangles drawn with this material (the file's face index count / 3): the faces after those of the materials
  /// before it.
  int32_t face_count = 0;

  bool double_sided() const { return (flags & kPmxMaterialDoubleSided) != 0; }
};

/// A joint between two rigid bodies (a spring 6-DOF constraint in PMX 2.0).
struct PmxJoint {
  std::string name;          ///< UTF-8
  std::string name_english;  ///< UTF-8
  PmxJointType type = PmxJointType::kSpring6Dof;
  int32_t rigid_body_a = -1;  ///< index into PmxModel::rigid_bodies, or -1 (a builder skips such joints)
  int32_t rigid_body_b = -1;  ///< index into PmxModel::rigid_bodies, or -1
  /// Joint frame origin in model space (PMX units, or metres in kAmt).
  Eigen::Vector3f position = Eigen::Vector3f::Zero();
  /// Joint frame orientation, Euler angles (radians), composed as rigid body rotations.
  Eigen::Vector3f rotation = Eigen::Vector3f::Zero();
  Eigen::Vector3f linear_min = Eigen::Vector3f::Zero();   ///< translation limits along the joint axes (lengths)
  Eigen::Vector3f linear_max = Eigen::Vector3f::Zero();   ///< min > max on an axis leaves that axis free
  Eigen::Vector3f angular_min = Eigen::Vector3f::Zero();  ///< rotation limits about the joint axes (radians)
  Eigen::Vector3f angular_max = Eigen::Vector3f::Zero();
  /// Spring stiffness on the translation axes, as authored (unchanged by conversion: the physics runs in PMX
  /// units, docs/dataset.md, "Your own PMX models").
  Eigen::Vector3f spring_linear = Eigen::Vector3f::Zero();
  /// Spring stiffness on the rotation axes, as authored (unchanged by conversion).
  Eigen::Vector3f spring_angular = Eigen::Vector3f::Zero();
};

/// A PMX model: what the project uses of it (mesh, skinning, textures and materials, bones, physics rig), plus
/// counts of the sections that are read, checked for size and skipped (morphs, display frames, soft bodies).
struct PmxModel {
  std::string source;               ///< file path or display name given to the parser (for messages)
  PmxHeader header;                 ///< version, encodings, index sizes, names
  PmxFrame frame = PmxFrame::kMmd;  ///< frame of every geometric field below
  float scale = 1.0f;               ///< length units per PMX unit: 1 in kMmd, metres per unit in kAmt
  PmxVertices vertices;             ///< #V vertices: positions, normals, uvs, skinning
  /// #F by 3 triangle vertex indices into vertices (file order in kMmd; reversed winding in kAmt).
  MatrixX3i faces;
  std::vector<PmxBone> bones;              ///< in file order (not necessarily parents first)
  std::vector<PmxRigidBody> rigid_bodies;  ///< physics bodies, in file order
  std::vector<PmxJoint> joints;            ///< constraints between rigid bodies, in file order
  /// Texture paths as the file holds them (UTF-8, usually relative to the model's folder, '\\' separated).
  std::vector<std::string> textures;
  std::vector<PmxMaterial> materials;      ///< in file order; their face_counts add up to at most #F
  int32_t texture_count = 0;               ///< texture paths in the file (textures.size())
  int32_t material_count = 0;              ///< materials in the file (materials.size())
  int32_t morph_count = 0;                 ///< morphs in the file (skipped)
  int32_t display_frame_count = 0;         ///< display frames in the file (skipped)
  int32_t soft_body_count = 0;             ///< PMX 2.1 soft bodies in the file (skipped)
};

// === Reading

/// Reads a PMX 2.0 or 2.1 file. Throws amt::Error with one line "path: offset N: field: expected ..., found ..."
/// on anything malformed: truncation, wrong magic / version / globals, counts that cannot fit in the file,
/// indices outside their tables, non-finite numbers, bone parent cycles, material face counts that are not whole
/// triangles or run past the faces. The model is in PmxFrame::kMmd.
PmxModel read_pmx(const std::string& path);

/// The same from `size` bytes in memory; `source` names them in messages. Never reads outside [data, data + size).
PmxModel parse_pmx(const uint8_t* data, size_t size, const std::string& source);

// === Conversion to amt's conventions

/// The model in amt's frame with `scale` metres per PMX unit (see the top of this header for the mapping).
/// Masses, damping, friction, restitution and spring stiffness are kept as authored. Throws amt::Error unless
/// `model` is in PmxFrame::kMmd and `scale` is finite and positive.
PmxModel pmx_to_amt_frame(const PmxModel& model, float scale = kPmxMetresPerUnit);

/// A position (or length vector) to amt's frame: scale (x, y, -z).
Eigen::Vector3f pmx_to_amt_position(const Eigen::Vector3f& p, float scale = kPmxMetresPerUnit);

/// A direction (normal, axis) to amt's frame: (x, y, -z).
Eigen::Vector3f pmx_to_amt_direction(const Eigen::Vector3f& d);

/// PMX Euler angles (radians) to amt's frame: (-x, -y, z), same composition order (pmx_euler_rotation).
Eigen::Vector3f pmx_to_amt_euler(const Eigen::Vector3f& euler);

/// An Euler angle range [lo, hi] (radians, per axis) to amt's frame: x and y become [-hi, -lo], z is kept.
void pmx_to_amt_angle_range(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, Eigen::Vector3f& out_lo,
                            Eigen::Vector3f& out_hi);

/// A translation range [lo, hi] (per axis) to amt's frame: scaled, and z becomes [-scale hi, -scale lo].
void pmx_to_amt_length_range(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, float scale, Eigen::Vector3f& out_lo,
                             Eigen::Vector3f& out_hi);

/// Rotation matrix of PMX Euler angles (radians): R = Ry(y) Rx(x) Rz(z), acting on column vectors, with the
/// usual right-hand-rule axis rotations. Valid in either frame for that frame's angles.
Eigen::Matrix3f pmx_euler_rotation(const Eigen::Vector3f& euler);

// === Mesh and skinning

/// The triangle mesh of the model, in the model's frame: V = vertices.positions (#V by 3), F = faces (#F by 3).
TriMesh pmx_mesh(const PmxModel& model);

/// Skinning weights over PmxModel::bones, at most 4 per vertex, rows summing to 1. kBdef1/2/4 and kQdef are taken
/// as linear blends of their bones and kSdef as its kBdef2 weights (the linear approximation of spherical
/// skinning); negative weights count as 0, -1 slots are dropped and repeated bones merged. A vertex with no
/// positive weight binds to its first bone (or bone 0) with weight 1. Throws amt::Error if the model has vertices
/// but no bones.
SparseWeights pmx_skin_weights(const PmxModel& model);

// === Text

/// UTF-16LE bytes to UTF-8. Surrogate pairs become one 4-byte sequence; an unpaired surrogate or a trailing odd
/// byte becomes U+FFFD.
std::string utf16le_to_utf8(const uint8_t* bytes, size_t size);

/// The text with every byte that does not start a well-formed UTF-8 sequence (RFC 3629: no overlong forms, no
/// surrogates, nothing above U+10FFFF) replaced by U+FFFD: the reader's UTF-8 names are always valid UTF-8.
std::string sanitize_utf8(const std::string& text);

}  // namespace amt
