#pragma once
// The motions of a built dataset: every BVH file of a folder imported onto the canonical skeleton and
// resampled, plus seeded procedural motions (data_tools/geometry/procedural_motion.h), cut into clips that start
// from the rest pose and blend into the motion, as MMDMC's clips do. Every clip is on
// canonical_skeleton() (BVH motions are retargeted onto it), so the builder retargets each clip onto a
// character with retarget_motion(clip, canonical_skeleton(), character skeleton).
#include <cstdint>
#include <string>
#include <vector>

#include "data_tools/geometry/motion.h"

namespace amt {

// === Options

/// Choices of build_motion_library.
struct MotionLibraryOptions {
  /// Folder of BVH files (every *.bvh, sorted by name; not recursive). Empty: no mocap.
  std::string bvh_folder;
  /// Number of procedural motions (one clip each), cycling through the ProceduralKind values.
  int procedural = 24;
  /// Seed of the procedural variations.
  uint64_t seed = 1;
  /// Frames per clip (>= 2); a motion is cut into windows of this length.
  int clip_frames = 120;
  /// Frame rate of every clip (BVH files are resampled to it).
  float fps = 30.0f;
  /// A trailing window shorter than clip_frames becomes a clip when it has at least this many frames
  /// (a motion shorter than one window always gives one clip, when it has at least 2 frames).
  int min_tail_frames = 30;
};

/// Throws amt::Error naming the field unless clip_frames is in [2, 100000], procedural in [0, 100000],
/// fps in (0, 1000] and min_tail_frames >= 2.
void validate_motion_library_options(const MotionLibraryOptions& options);

// === Clips

/// One clip of the library, before it is put on a character.
///   name    unique, usable as part of an HDF5 name: "bvh-<file stem>-<k>" (k counts from 0, 3 digits)
///           or "proc-<kind>-<index>" (index 3 digits)
///   source  the motion it was cut from: the BVH file name or "procedural"
///   first_frame  the clip's first frame in the source motion (after resampling)
///   motion  the window on canonical_skeleton() at options.fps (cut_window: facing +Z at frame 0, root
///           translation starting at x = z = 0); the blend from the rest pose comes per character
struct MotionClip {
  std::string name;
  std::string source;
  int first_frame = 0;
  Motion motion;
};

/// The *.bvh files of `folder`, full paths sorted by file name. Throws amt::Error when the folder does
/// not exist or holds no BVH file.
std::vector<std::string> list_bvh_files(const std::string& folder);

/// Windows of `motion_frames` frames cut into clips: (first frame, length) pairs. Full windows of
/// clip_frames frames from frame 0; the remainder becomes a shorter clip when it has at least
/// min_tail_frames frames, or when there is no full window and it has at least 2 frames.
std::vector<std::pair<int, int>> clip_windows(int motion_frames, int clip_frames, int min_tail_frames);

/// Frames [first_frame, first_frame + frames) of `motion` (joint 0 the root), turned about +Y so that
/// the root faces +Z at the window's first frame (its local +Z axis projected on the floor; its +X
/// axis when +Z points up or down), with the root translation taken relative to the first frame
/// horizontally: x and z start at 0, y is kept. Throws amt::Error for a window outside the motion.
Motion cut_window(const Motion& motion, int first_frame, int frames);

/// The motion blended in from the rest pose: over the first b = min(round(blend_seconds * fps),
/// T - 1) frames the weight w(t) = s^2 (3 - 2s), s = t / b, blends every local rotation as
/// exp(w log q), with each joint's quaternions first put on one continuous branch over time (so a joint
/// turning past 180 degrees from rest blends smoothly instead of flipping to the other arc; for rotations
/// under 180 degrees this is slerp(identity, q, w)), and the root translation as w * r (use cut_window first so that x and z
/// start at 0 and the character does not slide). Frame 0 is exactly the rest pose (identity
/// rotations, zero root translation); frames from b on are unchanged. blend_seconds in [0, 60].
Motion blend_from_rest(const Motion& motion, float blend_seconds);

/// The clip as a motion on a character: retarget_motion(clip.motion, canonical_skeleton(), character)
/// (bone directions aligned at rest, root translation scaled by leg length), then blend_from_rest, so
/// that frame 0 is the character's own rest pose (A-pose or T-pose).
Motion clip_on_character(const MotionClip& clip, const Skeleton& character, float blend_seconds);

/// A BVH file as a motion on canonical_skeleton() at `fps`: import_bvh (units detected), then
/// retarget_motion from the file's canonical skeleton onto canonical_skeleton(). Errors name the file.
Motion canonical_bvh_motion(const std::string& path, float fps);

/// The clips of the library: every BVH file of options.bvh_folder (when set) cut into clips, then
/// options.procedural procedural clips (kind i % 6, parameters from derive_seed(options.seed, i)).
/// Deterministic for the same options and files. Throws amt::Error for bad options, an empty or
/// missing folder, an unreadable BVH (naming it) or a library without a single clip.
std::vector<MotionClip> build_motion_library(const MotionLibraryOptions& options);

/// A 64-bit seed derived from a base seed and a stream index (SplitMix64 of both): well mixed, so that
/// neighbouring indices give unrelated streams.
uint64_t derive_seed(uint64_t seed, uint64_t stream);

}  // namespace amt
