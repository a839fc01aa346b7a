#pragma once
// The motion the runtime plays, from a BVH file, a glTF animation or a dataset clip, moved onto the
// canonical skeleton (missing joints placed as for characters, infer/character_input.h) and retargeted
// onto the character: per frame the joint transforms T^(t) (J, [R_j | t_j]) the networks take.
#include <memory>
#include <optional>
#include <string>

#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/skeleton.h"
#include "infer/character_input.h"

namespace amt {

// === Reading a motion

/// Where a motion comes from.
///   spec       "walk.bvh", "anim.glb" (its first clip, or `clip`), or "data.h5:clip_name"
///   joint_map  the user's joint map (`--motion-joint-map`), or empty
///   clip       glTF clip name ("" = the first)
///   bvh_scale  metres per BVH unit; detected when empty
///   model      for a .vmd motion, the PMX model it was made for (`--motion-model`, else the character when it
///              is a .pmx): its bones are posed as MikuMikuDance poses them, then mapped to the canonical joints
struct MotionSpec {
  std::string spec;
  std::string joint_map;
  std::string clip;
  std::optional<double> bvh_scale;
  std::string model;
};

/// A motion on the canonical skeleton.
///   name        file stem or dataset clip name
///   skeleton    canonical skeleton with the source's rest proportions (metres, missing joints placed)
///   motion      on `skeleton`, at the source's frame rate
///   mapping     how the source's joints were mapped (empty for a dataset clip, already canonical)
///   dataset, dataset_clip, dataset_character  for a dataset clip: file, clip and its character
struct SourceMotion {
  std::string name;
  Skeleton skeleton;
  Motion motion;
  std::string mapping;
  std::string dataset, dataset_clip, dataset_character;
};

/// Reads a motion. Throws amt::Error naming the file for unreadable input, an unsupported extension
/// or a skeleton that cannot be mapped onto the canonical joints (suggesting --motion-joint-map).
SourceMotion load_motion(const MotionSpec& spec);

/// The canonical motion of dataset joint transforms: local rotations R_parent^T R_j and root
/// translation t_0 - J_0, frame by frame. transforms (T * J, frame-major) on `skeleton`.
Motion motion_from_joint_transforms(const Skeleton& skeleton, const Transforms& transforms, float fps);

// === Playing it on a character

/// Choices of playback.
///   fps        output frame rate (resampled); empty: 30 fps for BVH and glTF motions, a dataset clip's own rate
///   frames     at most this many output frames (0: all)
///   lead_in    frames that blend from the character's rest pose to the first frame before output
///              starts (motion_lead_in of models/pipeline.h, eased in and out: lead_in_weight); they are run, not
///              written, and count at 30 fps whatever the output rate, so the lead-in lasts lead_in / 30 seconds on
///              every path
struct PlaybackOptions {
  std::optional<float> fps;
  int frames = 0;
  int lead_in = kDefaultLeadInFrames;
};

/// The joint transforms of a motion on a character, frame by frame. A dataset clip on its own
/// character at its own frame rate is played exactly as stored (read per frame, never whole), so the
/// runtime sees what the evaluation sees; anything else is retargeted (data_tools/geometry/retarget.h).
class MotionPlayer {
 public:
  /// Prepares playback of `source` on `character`. Throws amt::Error for a frame rate out of range.
  MotionPlayer(const SourceMotion& source, const RuntimeCharacter& character, const PlaybackOptions& options);
  ~MotionPlayer();
  MotionPlayer(MotionPlayer&&) noexcept;
  MotionPlayer& operator=(MotionPlayer&&) noexcept;

  /// Output frames (after --fps and --frames) and their rate.
  int num_frames() const;
  float fps() const;
  /// True when the frames are the dataset's stored transforms (no retargeting).
  bool exact() const;

  /// T^(t) of output frame t: J transforms [R_j | t_j] on the character's canonical skeleton.
  Transforms frame(int t) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace amt
