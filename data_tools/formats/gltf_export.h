#pragma once
// Animated glTF 2.0 export (written with tinygltf): a mesh sequence (the runtime's output, T frames of
// N vertices over fixed faces) and a rigged character (mesh, skin, skeleton animation of a Motion).
// Both play in three.js and Blender and pass the Khronos glTF validator without errors
// (tools/gltf-validator/validate.mjs).
//
// Mesh sequence construction ("morph target per frame"):
//   - one node, one mesh, one TRIANGLES primitive; POSITION holds frame 0, indices the faces
//     (UNSIGNED_SHORT when N <= 65535, else UNSIGNED_INT);
//   - morph target k (k = 1 .. T-1) holds the POSITION deltas V_k - V_0 (float, with min/max); the
//     mesh's default weights are 0 and extras.targetNames names the targets "frame_0001", ...;
//   - one animation "weights" channel, LINEAR, keyframe k at time k / fps with target k at weight 1
//     and every other target at 0 (frame 0: all 0). The T x (T-1) weights output is a sparse accessor
//     over implicit zeros holding only the T-1 ones, so it grows linearly, not quadratically, with T.
//   Between keyframes a player blends two neighbouring frames linearly. Size per frame: 12 N bytes of
//   deltas + 12 bytes (keyframe time, sparse index, weight) + about 0.4 KB of JSON (the target's
//   accessor with min/max, its buffer view); once: 12 N bytes of frame 0 and 6 F or 12 F bytes of
//   indices. No normals are written (three.js then shades flat, Blender computes them).
//   - the apparel mask, when given, travels as the vertex colour COLOR_0 (UNSIGNED_BYTE, normalized,
//     VEC4, 4 N bytes): kApparelColor on apparel vertices, kBodyColor on the others, so any glTF
//     viewer tints the apparel and a reader recovers the mask exactly (blue channel above red);
//     asset.extras then also records "apparel_color" (its RGB) and "apparel_vertices" (the count).
//
// Rigged character construction:
//   - node 0 is the mesh (skin 0) at the scene root without a transform; nodes 1 .. J are the joints in
//     skeleton order, joint j with translation J_j - J_parent (the root: J_0) and identity rotation,
//     since amt's rest orientations are identity;
//   - skin 0: those joints, inverse bind matrices translate(-J_j); JOINTS_0 (UNSIGNED_BYTE when J <= 256,
//     else UNSIGNED_SHORT) and WEIGHTS_0 (float) from the SparseWeights;
//   - one animation: a LINEAR rotation channel per joint (the Motion's local rotations, unchanged, as
//     glTF local rotations relative to an identity rest orientation) and a LINEAR translation channel
//     on the root (J_0 + root_translation), keyframe t at time t / fps. glTF's node graph then gives
//     exactly amt's forward kinematics, and skinning gives linear_blend_skinning.
//
// Skinned animation construction (export_gltf_skinned_animation, what `amt animate` writes to a .glb): the
// rigged character's layout over any skeleton whose rest orientations are identity (amt's canonical joints plus
// the apparel's handles, each a joint under the body joint it hangs from), animated by node-local rotations of
// every joint and translations of the joints that move against their parent (the root, the handles). A joint
// of a skin with more than 256 joints takes UNSIGNED_SHORT indices. Compact storage: weights as normalized
// UNSIGNED_SHORT (each row summing to exactly 65535), rotations as normalized SHORT components (8 bytes a key
// instead of 16; about 3e-5 rad off), and all rotation keys in one buffer view, all translation keys in another. The apparel tint COLOR_0 as for a mesh
// sequence. asset.extras.amt_format is "skinned-animation".
//
// Files: GLB by default; .gltf JSON with the buffer embedded as a base64 data URI on request. Every
// file is written to "<path>.amt-tmp" and renamed onto `path`, so a failed export never leaves a partial
// file. asset.generator is "amt <version>"; asset.extras records {"amt_format": "mesh-sequence" or
// "rigged-character", "amt_format_version": 1, "fps": fps}. Units are metres, Y up.
#include <optional>
#include <string>
#include <vector>

#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Options

/// The container written.
enum class GltfContainer {
  kGlb,           ///< binary glTF: JSON chunk + BIN chunk
  kEmbeddedGltf,  ///< .gltf JSON with the buffer as a base64 data URI (about 4/3 the size of GLB)
};

/// Choices of an export.
///   container  GLB or embedded .gltf; when empty, ".gltf" paths (any letter case) get kEmbeddedGltf
///              and every other path kGlb
///   name       name of the mesh and node (mesh sequence) or of the mesh node (rigged character)
///   clip       name of the animation
///   apparel_mask  mesh sequence and skinned animation: #V entries 0/1 written as the COLOR_0 tint (above), or
///              empty for none
struct GltfExportOptions {
  std::optional<GltfContainer> container;
  std::string name = "amt_mesh";
  std::string clip = "amt_animation";
  std::vector<uint8_t> apparel_mask;
};

// === The apparel tint (COLOR_0 of a mesh sequence)

/// RGBA of apparel and body vertices in COLOR_0 (the apparel blue of data_tools/formats/render.h's pictures).
inline constexpr uint8_t kApparelColor[4] = {61, 120, 214, 255};
inline constexpr uint8_t kBodyColor[4] = {204, 199, 191, 255};

/// COLOR_0 bytes of a mask: 4 #V bytes, RGBA per vertex. Throws amt::Error naming `path` for entries
/// other than 0 and 1.
std::vector<uint8_t> apparel_vertex_colors(const std::vector<uint8_t>& apparel_mask, const std::string& path);

// === Export

/// Writes a mesh sequence as an animated glTF (construction above).
///   F       #F by 3 triangles, indices into each frame's vertices
///   frames  T >= 1 frames, each #V by 3 positions (metres), the same #V for all
///   fps     frame rate (> 0); frame k plays at time k / fps
/// Throws amt::Error for empty or mismatched input, NaN, bad face indices, or a failed write.
void export_gltf_mesh_sequence(const std::string& path, const MatrixX3i& F, const std::vector<MatrixX3f>& frames,
                               float fps, const GltfExportOptions& options = {});

/// Writes a rigged character whose animation is `motion` applied by skinning (construction above).
///   mesh      rest mesh (#V by 3, #F by 3)
///   skeleton  the rest skeleton (J joints, topological)
///   weights   #V by 4 indices into the skeleton's joints and weights (rows are renormalised to sum 1)
///   motion    on the skeleton (validate_motion), T >= 1 frames at motion.fps
/// Throws amt::Error for invalid or mismatched input or a failed write.
void export_gltf_rigged(const std::string& path, const TriMesh& mesh, const Skeleton& skeleton,
                        const SparseWeights& weights, const Motion& motion, const GltfExportOptions& options = {});

/// A skeleton's animation as glTF nodes hold it, T frames of J joints (frame-major, joint-minor):
///   rotations     T J unit quaternions, each joint's rotation relative to its parent (the root: to the scene)
///   translations  T J offsets from the parent joint's origin in its frame (the root: the position in the scene)
///   translated    J flags: 1 writes joint j's translation channel; 0 keeps its rest offset (its translations
///                 are not read)
///   fps           frame rate (> 0); frame k plays at time k / fps
struct NodeAnimation {
  Quaternions rotations;
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> translations;
  std::vector<uint8_t> translated;
  float fps = 30.0f;
  int num_frames(int joints) const { return joints > 0 ? int(rotations.size() / size_t(joints)) : 0; }
};

/// The node-local animation of joint transforms (forward_kinematics' T^(t): global rotation R_j, global position
/// t_j) on a skeleton with identity rest orientations: rotation R_parent^T R_j, translation R_parent^T (t_j -
/// t_parent) (the root: R_0, t_0). Appends one frame to `animation`.
void append_node_frame(const Skeleton& skeleton, const Transforms& joint_transforms, NodeAnimation& animation);

/// Writes a skinned character animated by its joints' node transforms (construction above).
///   mesh       rest mesh (#V by 3, #F by 3)
///   skeleton   J joints, topological, identity rest orientations (rest_joints are their rest positions)
///   weights    #V by 4 indices into the skeleton's joints and weights (rows are renormalised to sum 1)
///   animation  T >= 1 frames of the J joints
/// Throws amt::Error for invalid or mismatched input (non-finite values included) or a failed write.
void export_gltf_skinned_animation(const std::string& path, const TriMesh& mesh, const Skeleton& skeleton,
                                   const SparseWeights& weights, const NodeAnimation& animation,
                                   const GltfExportOptions& options = {});

}  // namespace amt
