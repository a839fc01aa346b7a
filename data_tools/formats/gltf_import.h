#pragma once
// glTF 2.0 import (.gltf with embedded or external buffers, .glb) through tinygltf: a skinned character
// (mesh, skin, skeleton), its animation clips as amt motions, and any mesh animation (skinning and
// morph targets) evaluated into vertex positions per frame.
//
// Units: glTF lengths are metres and Y is up (glTF 2.0 section 3.4), as in amt; nothing is rescaled.
// Some assets are authored in other units (the Khronos Fox is about 80 units tall): scale them after
// import if needed.
//
// The rest pose is the scene as it is displayed without animation: every node at its own TRS (or
// matrix). Rest joint positions are the global rest translations of the joint nodes. Rest vertices
// are the skinned mesh evaluated in that pose the way glTF skins (section 3.7.3):
//   v_rest = sum_k w_k  G_k(rest) * IBM_k * v_mesh
// with G_k(rest) the global rest transform of joint k, IBM_k its inverse bind matrix and w_k the 4
// largest weights renormalised (as amt skins). The mesh node's own transform is not applied (a skinned
// mesh ignores it). When the file binds the mesh in its rest pose (IBM_k = G_k(rest)^-1, as exporters
// write it), v_rest = v_mesh.
//
// Motions (amt's convention, data_tools/geometry/motion.h): rest orientations are identity and rotations are
// relative to the rest pose. With W_n(t) the global 4x4 transform of node n at time t (glTF's node
// graph: parents, TRS, animated channels) and L() its 3x3 linear part, joint j on node n has
//   R_j(t) = polar( L(W_n(t)) L(W_n(rest))^-1 )     its global rotation relative to rest (exact),
//   local_j(t) = R_parent(t)^-1 R_j(t)               the Motion's local rotation.
// For a joint node whose parent node is the parent joint and without scale this is the glTF local
// rotation change, turned into the rest frame:  local_j = Q_j (q_rest^-1 q_anim) Q_j^-1  where Q_j =
// Q_parent q_rest is the joint's global rest rotation.
// amt motions are rigid: bones keep their rest length and only the root translates. Forward
// kinematics of the rotations alone leaves each joint j at a residual r_j(t) from its glTF position
// translation(W_n(t)); the root translation is the skin-weighted mean  sum_j m_j r_j(t) / sum_j m_j,
// with m_j the total skin weight of joint j over all vertices. So the motion is exact when the clip
// translates only the root joint, and also when it translates a single joint (usually the hips)
// whose ancestors carry no skin weight (helper joints such as the Fox's _rootJoint and b_Root_00,
// which then drift with the hips). Animated scale and any other translation are not representable;
// they are ignored (rotations are still exact) and GltfMotion reports the resulting joint position
// error. Uniform static scale anywhere in the hierarchy is fine.
//
// Input is checked before it is used: the GLB container against the byte count, the JSON (syntax,
// nesting at most 256 deep, asset.version 2.x), every buffer's size against its data, every index
// between objects, and every accessor's bytes against its buffer view and buffer before reading.
// Limits: TRIANGLES primitives only; joint indices and weights from every JOINTS_n / WEIGHTS_n set,
// reduced to the 4 largest per vertex; at most 2^27 values per accessor, and per import step at most
// 2^24 values plus 8 per buffer byte read from accessors (a valid file reads each value a few times;
// the bound keeps a small file from claiming gigabytes through accessors without data); at most
// 1 000 000 frames per sampled clip. Cameras, materials, textures and images are not read (images are
// not decoded). Every failure is an amt::Error with one line "source: field: expected X, found Y".
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "data_tools/formats/joint_map.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/spring_bones.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Loading

/// One animation clip of an asset.
///   name          the clip's name, or "animation_<i>" when the file leaves it empty
///   start, end    earliest and latest keyframe time over the clip's channels, seconds
///   num_channels  channels of the clip (every target path, including ones amt does not use)
struct GltfAnimationInfo {
  std::string name;
  float start = 0.0f;
  float end = 0.0f;
  int num_channels = 0;

  /// end - start, seconds.
  float duration() const { return end - start; }
};

/// A parsed glTF asset whose structure has been checked: GLB chunks, JSON, buffers (their data is
/// loaded), and every index between objects (nodes, meshes, skins, scenes, animations) is in range;
/// the node hierarchy is a forest; node transforms are finite. Accessor data is checked when read.
/// Cheap to copy (shares the immutable model).
class GltfAsset {
 public:
  /// The name used in error messages: the path, or the name given to parse_gltf.
  const std::string& source() const;
  /// The animation clips, in file order.
  const std::vector<GltfAnimationInfo>& animations() const;

  /// tinygltf's model and what the functions below derive from it (defined in gltf_import.cpp).
  struct Impl;
  /// Wraps a checked model (made by parse_gltf).
  explicit GltfAsset(std::shared_ptr<const Impl> impl);
  /// The model, for the functions of this file.
  const Impl& impl() const { return *impl_; }

 private:
  std::shared_ptr<const Impl> impl_;
};

/// Reads a .gltf or .glb file. External buffer files are looked up beside it.
GltfAsset read_gltf(const std::string& path);

/// Parses a glTF asset from memory: GLB bytes (magic "glTF") or glTF JSON text. `source` names it in
/// error messages. External buffer files (buffers[i].uri that is not a data URI) are read from
/// `base_dir`; with an empty `base_dir` they are rejected, so parsing touches no file.
GltfAsset parse_gltf(const uint8_t* data, size_t size, const std::string& source, const std::string& base_dir = "");

// === Skinned character

/// A skinned character: the meshes of every node of the default scene that uses the chosen skin (the
/// skin of the first skinned mesh node in scene order), merged, and that skin's joints as a skeleton.
///   mesh                 rest mesh (see the top of this file): #V by 3 positions, #F by 3 triangles;
///                        primitives in node then primitive order, morph targets at their default weights
///   skeleton             the skin's joints in topological order (parents first; the file's order is kept
///                        where it already is topological). When the skin has several root joints, the
///                        nearest common ancestor node of those roots is added as the root joint (named
///                        after the node), or a joint "gltf_scene_root" at the origin if they share none.
///                        Names are node names ("node_<i>" when empty, "_<i>" appended when taken)
///   weights              #V by 4 skeleton joint indices and weights, the 4 largest of all weight sets,
///                        normalised to sum 1; a vertex whose weights are all 0 binds to the skin's first
///                        root joint
///   joint_nodes          per skeleton joint, its node index (-1 for "gltf_scene_root")
///   skin_joint_to_joint  per entry of the skin's joints list, the skeleton joint index
///   skin                 index of the skin in the file
struct GltfCharacter {
  TriMesh mesh;
  Skeleton skeleton;
  SparseWeights weights;
  std::vector<int> joint_nodes;
  std::vector<int> skin_joint_to_joint;
  int skin = -1;
};

/// Imports the skinned character of an asset. Throws amt::Error when the default scene has no
/// skinned mesh node, a primitive is not TRIANGLES, or any data read is invalid.
GltfCharacter gltf_character(const GltfAsset& asset);

// === VRM avatars

/// The VRM version of an asset: "0" for the "VRM" extension (VRM 0.x, UniVRM's), "1" for "VRMC_vrm" (VRM 1.0),
/// "" for a plain glTF. VRM 0.x avatars face -Z with their left on -X; VRM 1.0 ones face +Z (the VRM 1.0
/// specification, "Coordinate system").
std::string gltf_vrm_version(const GltfAsset& asset);

/// A VRM avatar's humanoid bone map as a joint map onto `character`'s skeleton names, so that no --joint-map is
/// needed: hips, upper / lower leg, foot, toes, neck, head, shoulder, upper / lower arm and hand of each side
/// (VRM 0.x extensions.VRM.humanoid.humanBones [{bone, node}], VRM 1.0 extensions.VRMC_vrm.humanoid.humanBones
/// {bone: {node}}). The spine, chest and upper chest are left to map_to_canonical's structure rule, which spreads
/// spine1..spine3 over the joints between the hips and the neck as for any rig. A bone on a node that is not one
/// of the skin's joints is left out. Empty for a plain glTF. Throws amt::Error naming the field for a malformed
/// map (a node index out of range, a bone that is not a string).
std::optional<JointMapFile> gltf_vrm_joint_map(const GltfAsset& asset, const GltfCharacter& character);

/// Per joint of `character.skeleton`, 1 when a VRM spring bone moves it: VRM 0.x
/// extensions.VRM.secondaryAnimation.boneGroups[].bones (each a chain's root) and every joint below them, VRM 1.0
/// extensions.VRMC_springBone.springs[].joints[].node and every joint below them. Empty when the asset has no
/// spring bones. Throws amt::Error naming the field for a node index out of range.
std::vector<uint8_t> gltf_vrm_spring_joints(const GltfAsset& asset, const GltfCharacter& character);

/// A VRM avatar's spring bones on `character.skeleton` (rest positions in the file's frame, metres):
///   VRM 1.0  extensions.VRMC_springBone: each spring's joints in order, a segment from each joint to the next
///            with the joint's hitRadius, stiffness, gravityPower, gravityDir and dragForce (defaults 0, 1, 0,
///            [0, -1, 0], 0.5); sphere and capsule colliders through the spring's colliderGroups
///   VRM 0.x  extensions.VRM.secondaryAnimation: every node under each boneGroups[].bones root, its tail its first
///            child or, for a leaf, 7 cm on along its bone; the group's stiffiness, gravityPower, gravityDir,
///            dragForce, hitRadius (defaults 1, 0, {0, -1, 0}, 0.4, 0.02); sphere colliders of colliderGroups with
///            their z mirrored as VRM 0.x writes them
/// A collider moves with its node's nearest joint. Stated fallbacks go to `notes` (a branching node, a centre node,
/// a spring node that is not a joint of the skin, a node listed twice). Empty for a plain glTF. Throws amt::Error
/// naming the field for an index out of range or a value that is not a finite number.
SpringRig gltf_vrm_spring_rig(const GltfAsset& asset, const GltfCharacter& character);

// === Animation

/// A clip sampled as an amt motion.
///   motion                on character.skeleton at the chosen frame rate; frame k is clip time
///                         start + k / fps for k = 0 .. floor(duration * fps + 1e-4)
///   clip                  the clip's name ("" when the asset has no animation: one rest frame)
///   start, duration       the clip's time range, seconds
///   joint_position_error  largest distance (metres) over frames and joints between amt's forward
///                         kinematics of `motion` and the glTF node graph's joint positions (see the
///                         top of this file for when it is 0 up to rounding)
///   skinned_joint_position_error  the same over the joints that carry skin weight: what moves vertices
struct GltfMotion {
  Motion motion;
  std::string clip;
  float start = 0.0f;
  float duration = 0.0f;
  float joint_position_error = 0.0f;
  float skinned_joint_position_error = 0.0f;
};

/// Samples clip `clip` (a name; "" picks the first clip, or a single rest frame when there is none)
/// at `fps` (in (0, 1000]) into a motion on the character's skeleton. Channels are interpolated as
/// the file says: STEP, LINEAR (slerp for rotations) or CUBICSPLINE (Hermite with the in and out
/// tangents, rotations renormalised); times outside a channel's keys hold its first or last value.
GltfMotion gltf_motion(const GltfAsset& asset, const GltfCharacter& character, const std::string& clip = "",
                       float fps = 30.0f);

/// Mesh animation evaluated the way a glTF viewer plays it: every mesh node of the default scene, in
/// scene order, merged into one mesh; per frame, morph targets (node or mesh weights, animated by
/// "weights" channels) and then skinning (all JOINTS_n / WEIGHTS_n sets, normalised) or, for an
/// unskinned node, its animated global transform.
///   faces          #F by 3 triangles (fixed)
///   frames         one #V by 3 position matrix per frame, frame k at clip time start + k / fps
///   clip, start, duration, fps   as for GltfMotion
struct GltfVertexAnimation {
  MatrixX3i faces;
  std::vector<MatrixX3f> frames;
  std::string clip;
  float start = 0.0f;
  float duration = 0.0f;
  float fps = 30.0f;
};

/// Evaluates clip `clip` ("" picks the first clip, or a single frame of the rest pose when there is
/// none) at `fps` (in (0, 1000]). Reads back what export_gltf_mesh_sequence writes. Throws amt::Error
/// when the scene has no mesh or frames x vertices exceeds 200 000 000.
GltfVertexAnimation gltf_vertex_animation(const GltfAsset& asset, const std::string& clip = "", float fps = 30.0f);

// === Writing an asset back with an animation

/// Writes `source` again as a GLB at `path` (a .vrm name keeps it a VRM: every extension, material, texture,
/// mesh, skin and node is copied as read) with its animations replaced by one clip `clip` of frames at `fps`:
/// frame t moves joint j of `character.skeleton` by its skinning transform frames[t][j] (rest -> posed, in the
/// file's frame), so that the file's own skinning plays what linear blend skinning of `character.mesh` with those
/// transforms gives. Each joint's node gets rotation and translation channels (its local transform under its
/// parent's posed one, the rest scale kept); other nodes keep their rest place under their parents. Written to
/// "<path>.amt-tmp" and renamed. Throws amt::Error for an asset with several buffers, a joint node given as a matrix,
/// frames of the wrong size or non-finite transforms, fps <= 0, or a failed write.
void export_gltf_animated_copy(const GltfAsset& source, const GltfCharacter& character,
                               const std::vector<Transforms>& frames, float fps, const std::string& clip,
                               const std::string& path);

}  // namespace amt
