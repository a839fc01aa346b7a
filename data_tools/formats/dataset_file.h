#pragma once
// The dataset file (docs/dataset.md, "The dataset file"): HDF5, format "amt-dataset", version 1. Characters (rest
// mesh, skeleton, apparel mask, body skinning weights, optional simulation rig) and clips (joint
// transforms per frame plus ground-truth vertices, stored directly or as rig skinning matrices).
//
// Layout:
//   /                      attributes format = "amt-dataset", version = 1, units = "metres",
//                          up_axis = "y", fps (float), skeleton (joint names); in a file of
//                          predictions (amt animate --out x.h5) also predictions = what made them
//   /characters/<name>/    rest_vertices (N,3) f32, faces (F,3) i32, rest_joints (J,3) f32,
//                          joint_parents (J) i32, apparel_mask (N) u8, body_weights (N,J) f32;
//                          attribute split ("train" | "test")
//   /characters/<name>/rig/  optional: attribute bone_names (B strings), bone_parents (B) i32,
//                          rest_transforms (B,3,4) f32, skin_indices (N,K) i32, skin_weights (N,K) f32,
//                          optional response (B,3) f32 (the rig's physics response, Rig::response)
//   /clips/<name>/         attributes character, motion, fps, split; joint_transforms (T,J,3,4) f32;
//                          ground truth vertices (T,N,3) f32 or rig_transforms (T,B,3,4) f32
// Per-frame arrays are chunked one frame per chunk, compressed (shuffle + deflate), and extendible in
// T, so the writer streams frames in and the reader reads frame ranges without loading a clip.
//
// This header does not include HDF5: the library's HDF5 dependency is private.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "data_tools/geometry/apparel_topology.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Format constants

/// Value of the root attribute `format`.
inline constexpr const char* kDatasetFormat = "amt-dataset";
/// Value of the root attribute `version` this code writes. Version 2 has the layout of version 1
/// with checksums: every dataset chunked with a Fletcher-32 checksum per chunk, and the HDF5 1.8
/// file format's checksummed metadata. Readers take versions kDatasetOldestVersion to
/// kDatasetVersion (a version 1 file is only verified as far as its compressed streams go).
inline constexpr int kDatasetVersion = 2;
inline constexpr int kDatasetOldestVersion = 1;
/// Root attribute present only in files of predictions (what made them, e.g. "amt animate: ..."):
/// `amt eval --predictions` refuses a file without it, so ground truth never scores as a prediction.
inline constexpr const char* kPredictionsAttribute = "predictions";

/// Dense row-major int32 matrix, e.g. rig skin indices (N, K).
using MatrixXiR = Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// === Data

/// The simulation rig a character's apparel was simulated with (MMD-style bones, docs/dataset.md,
/// "What the builder makes"). Bones need not be in topological order; rest transforms are global.
struct Rig {
  /// B bone names.
  std::vector<std::string> bone_names;
  /// B parent indices in [0, B), or -1 for a root bone.
  std::vector<int32_t> bone_parents;
  /// B global rest transforms [R | t] of the bones.
  Transforms rest_transforms;
  /// (N, K) bone indices in [0, B), K >= 1 influences per vertex (unused slots: any index, weight 0).
  MatrixXiR skin_indices;
  /// (N, K) non-negative skin weights, rows sum to 1.
  MatrixXfR skin_weights;
  /// Optional (B, kRigResponseChannels): each bone's response to the body's motion under this rig's physics
  /// (rig_response, data_tools/builder/rig_response.h); empty when the file has none (datasets written before it).
  MatrixXfR response;

  int num_bones() const { return static_cast<int>(bone_names.size()); }
};

/// One character of the dataset.
struct CharacterData {
  /// Group name under /characters: non-empty, without '/'.
  std::string name;
  /// Rest mesh: V (N, 3) metres, F (F, 3) indices into V.
  TriMesh mesh;
  /// The character's rest skeleton; names are the file's root `skeleton` attribute (J joints).
  Skeleton skeleton;
  /// N values, 1 for apparel vertices (driven by physics in the ground truth), 0 for body.
  std::vector<uint8_t> apparel_mask;
  /// (N, J) ground-truth body skinning weights, non-negative, rows sum to 1.
  MatrixXfR body_weights;
  /// The simulation rig, when the clips of this character store rig_transforms.
  std::optional<Rig> rig;
  /// "train" or "test".
  std::string split;
};

/// Counts describing a character, read without loading its arrays (only the apparel mask is read).
struct CharacterSummary {
  std::string name;
  int num_vertices = 0;
  int num_faces = 0;
  /// Vertices whose apparel_mask is 1.
  int num_apparel_vertices = 0;
  /// Bones of the rig, 0 when the character has none.
  int num_bones = 0;
  std::string split;
};

/// How a clip stores its ground truth.
enum class GroundTruth {
  /// `vertices` (T, N, 3): positions per frame.
  kVertices,
  /// `rig_transforms` (T, B, 3, 4): skinning matrices of the character's rig bones per frame.
  kRig
};

/// "vertices" or "rig".
const char* ground_truth_name(GroundTruth ground_truth);

/// A clip's attributes and length.
struct ClipInfo {
  /// Group name under /clips: non-empty, without '/'.
  std::string name;
  /// Name of the character (a group under /characters) the clip animates.
  std::string character;
  /// Name of the source motion.
  std::string motion;
  /// "train" or "test".
  std::string split;
  /// Frame rate of the clip (frames per second).
  float fps = 30.0f;
  /// Number of frames T. Ignored by DatasetWriter::begin_clip, which counts appended frames.
  int num_frames = 0;
  GroundTruth ground_truth = GroundTruth::kVertices;
};

/// The apparel bones of a character's simulation rig (its bones that are not joints of its skeleton, by name:
/// the builder's hair, skirt and cape chains, a PMX dataset's physics-driven bones), as the apparel module's
/// handles (bone_handles). std::nullopt when the character has no rig or its rig has no such bone.
std::optional<ApparelBones> rig_apparel_bones(const CharacterData& character);

// === Writer

/// Writes a dataset file. Everything goes to a temporary file beside the target ("<path>.amt-tmp");
/// commit() closes it and renames it onto `path`, so a failed or interrupted run never leaves a
/// partial file in place of a good one. Destroying the writer without commit() removes the
/// temporary file and leaves `path` untouched. Every input is validated (throws amt::Error).
///
/// Clips stream: begin_clip(), then append_frame() once per frame (each frame is written to disk
/// as it comes), then end_clip(). One clip is open at a time. Not thread-safe.
class DatasetWriter {
 public:
  /// Starts a new, empty dataset at `path` with frame rate `fps` and the skeleton's joint names
  /// (usually canonical_joint_names()).
  DatasetWriter(const std::string& path, float fps, const std::vector<std::string>& joint_names);

  /// Resumes an existing dataset at `path` to add characters and clips: the file is copied to the
  /// temporary name and checked (format, version, root attributes); commit() replaces `path`.
  static DatasetWriter append(const std::string& path);

  /// Removes the temporary file unless commit() succeeded.
  ~DatasetWriter();
  DatasetWriter(DatasetWriter&& other) noexcept;
  DatasetWriter& operator=(DatasetWriter&& other) noexcept;
  DatasetWriter(const DatasetWriter&) = delete;
  DatasetWriter& operator=(const DatasetWriter&) = delete;

  /// The target path.
  const std::string& path() const;
  /// Marks the file as predictions, not ground truth: root attribute `predictions` = `made_by`
  /// (replacing an earlier mark).
  void mark_predictions(const std::string& made_by);
  /// The temporary file written until commit().
  const std::string& temporary_path() const;
  /// The file's frame rate.
  float fps() const;
  /// The file's J joint names.
  const std::vector<std::string>& joint_names() const;
  /// True when the file has a character (written now or before an append) called `name`.
  bool has_character(const std::string& name) const;
  /// True when the file has a clip called `name` (including the open one).
  bool has_clip(const std::string& name) const;

  /// Validates and writes a character: the mesh (validate_mesh), the skeleton (the file's joint
  /// names, validate_skeleton), shapes (N, J, B, K agree), finite values, mask values 0/1, weight
  /// rows summing to 1, rig consistency; a new unique name and a split of "train" or "test".
  void add_character(const CharacterData& character);

  /// Opens a clip of an already written character. `info.num_frames` is ignored. With
  /// GroundTruth::kRig, the character must have a rig.
  void begin_clip(const ClipInfo& info);

  /// Appends one frame with vertex ground truth: joint_transforms J transforms [R_j | t_j],
  /// vertices (N, 3) positions of the character's N vertices.
  void append_frame(const Transforms& joint_transforms, const MatrixX3f& vertices);

  /// Appends one frame with rig ground truth: joint_transforms J transforms, rig_transforms B
  /// skinning matrices (posed global times inverse rest global) of the character's rig bones.
  void append_frame(const Transforms& joint_transforms, const Transforms& rig_transforms);

  /// Frames appended to the open clip so far.
  int num_frames_in_clip() const;

  /// Closes the open clip; it must have at least one frame.
  void end_clip();

  /// Closes the file and renames it onto path() (replacing any file there). No clip may be open.
  /// The writer cannot be used afterwards.
  void commit();

 private:
  struct Impl;
  explicit DatasetWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// === Reader

/// Reads a dataset file, validating as it goes: opening checks the file and root attributes
/// (format, version, units, up axis, fps, skeleton); read_character checks every field of a
/// character; clip_info checks a clip's attributes and shapes against its character; frame reads
/// check the values they return. Every failure is an amt::Error "file: field: expected X, found Y".
///
/// Clip data is read in frame ranges (HDF5 hyperslabs): nothing reads a whole clip unless asked.
/// Clip infos, and the skinning data of characters whose rig-form clips are read, are cached.
/// Not thread-safe: use one reader per thread.
class DatasetReader {
 public:
  /// Opens `path` and checks its root attributes.
  explicit DatasetReader(const std::string& path);
  ~DatasetReader();
  DatasetReader(DatasetReader&& other) noexcept;
  DatasetReader& operator=(DatasetReader&& other) noexcept;
  DatasetReader(const DatasetReader&) = delete;
  DatasetReader& operator=(const DatasetReader&) = delete;

  /// The file's path.
  const std::string& path() const;
  /// Root attribute `fps`.
  float fps() const;
  /// Root attribute `version` (kDatasetOldestVersion to kDatasetVersion).
  int version() const;
  /// Root attribute `predictions`: what made the file's frames when it holds predictions, empty when
  /// it holds ground truth.
  const std::string& predictions() const;
  /// Reads every dataset in full so that HDF5 checks its checksums (h5::verify_datasets): throws
  /// amt::Error naming the file and the first damaged dataset. Returns the number of datasets.
  int64_t verify() const;
  /// Root attribute `skeleton`: the J joint names every character and clip uses.
  const std::vector<std::string>& joint_names() const;
  /// J.
  int num_joints() const;
  /// Names of the characters, sorted.
  const std::vector<std::string>& character_names() const;
  /// Names of the clips, sorted.
  const std::vector<std::string>& clip_names() const;
  /// True when the file has a character called `name`.
  bool has_character(const std::string& name) const;
  /// True when the file has a clip called `name`.
  bool has_clip(const std::string& name) const;

  /// Reads and validates a whole character.
  CharacterData read_character(const std::string& name) const;

  /// Counts of a character, checking its array shapes but reading only the apparel mask.
  CharacterSummary character_summary(const std::string& name) const;

  /// Attributes and length of a clip, checked against its character (shapes, T agreement).
  ClipInfo clip_info(const std::string& clip) const;

  /// Joint transforms of frames [first_frame, first_frame + count): count * J transforms,
  /// frame-major (entry t * J + j is joint j at frame first_frame + t).
  Transforms read_joint_transforms(const std::string& clip, int first_frame, int count) const;

  /// Ground-truth vertices of frames [first_frame, first_frame + count): (count * N, 3), frame-major
  /// (rows t * N .. t * N + N - 1 are frame first_frame + t). For a rig clip they are skinned from
  /// rig_transforms: v = sum_k w_k M_{b_k} [v_rest; 1] with the rig's skin weights.
  MatrixX3f read_vertices(const std::string& clip, int first_frame, int count) const;

  /// Rig skinning matrices of frames [first_frame, first_frame + count) of a rig clip: count * B
  /// transforms, frame-major.
  Transforms read_rig_transforms(const std::string& clip, int first_frame, int count) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace amt
