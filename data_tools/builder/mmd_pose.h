#pragma once
// MikuMikuDance's pose evaluation: a PMX model's bones posed by VMD keyframes as MMD poses them, with append
// (grant) rotations and translations and IK solved by MMD's cyclic coordinate descent (leg and toe IK, knee
// constraints). Everything in the PMX file's frame and units (PmxFrame::kMmd); pmx_transforms_to_amt
// (data_tools/builder/pmx_physics.h) brings the result to amt's frame.
//
// Per frame (saba, github.com/benikabocha/saba, src/Saba/Model/MMD/MMDModel.cpp UpdateNodeAnimation, PMXModel.cpp
// and MMDIkSolver.cpp; blender_mmd_tools and three.js's MMDAnimationHelper / CCDIKSolver do the same):
//   1. each bone's local motion from the keys of the bone of the same name (identity without keys);
//      local transform = translate(rest offset from the parent + key translation + append translation) *
//      rotate(IK rotation * key rotation * append rotation);
//   2. bones in MMD's order, deform layer then index (bones flagged "after physics" in a second pass: there is no
//      physics here, they are simply evaluated last): a bone with an append parent takes weight x its rotation
//      (slerp from identity) and translation; an IK bone solves its chain;
//   3. global transforms down the hierarchy.
// IK (MMDIkSolver::Solve): the links' IK rotations start at identity; up to loop_count iterations, each turning
// every link in order (effector's parent first) so that the effector points at the IK bone, by at most
// limit_angle per step; a link with angle limits is clamped in Euler angles R = Rx Ry Rz, and a link limited to a
// single axis (the knee: x only) turns in that plane only, its angle mirrored on the first iteration when it would
// fall outside its limits, so that a knee bends forwards. The iteration whose effector came closest is kept.
// The VMD's IK-enable track is not read: every IK bone is solved.
#include <cstdint>
#include <string>
#include <vector>

#include "data_tools/formats/pmx_import.h"
#include "data_tools/formats/vmd_import.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Pose of one frame

/// A PMX model's pose evaluator: model order, children and IK chains prepared once.
class MmdPoser {
 public:
  /// `model` in PmxFrame::kMmd (throws amt::Error otherwise); it must outlive the poser.
  explicit MmdPoser(const PmxModel& model);
  ~MmdPoser();
  MmdPoser(MmdPoser&&) noexcept;
  MmdPoser& operator=(MmdPoser&&) noexcept;

  /// Global joint transforms of the B bones for local motions `local` (B; translation from the rest position in
  /// PMX units, rotation relative to rest): [R | t] with R the bone's rotation relative to the rest pose and t its
  /// posed position (PMX units, MMD's frame), so that a rest point p carried by bone b moves to R (p - p_b) + t.
  Transforms pose(const std::vector<VmdBonePose>& local);

 private:
  struct Bone;
  void update_local(int b);
  void update_global(int b);
  void update_append(int b);
  void solve_ik(int b);

  const PmxModel* model_;
  std::vector<int> order_;                  // deform layer, then index; after-physics bones last
  std::vector<std::vector<int>> children_;  // per bone
  std::vector<int> roots_;
  std::vector<Bone> bones_;
};

// === A VMD motion on a model

/// Most frames a VMD motion may span (keyframe numbers below this): two hours at 30 fps.
constexpr int kMaxMmdFrames = 216000;

/// Most IK iterations per IK bone and frame: a model's loop_count above it is taken as this (MMD models use up to a
/// few hundred).
constexpr int kMaxMmdIkIterations = 1000;

/// Bones of a model for every frame of a VMD motion.
///   frames         T = last keyframe + 1 (at kVmdFps)
///   bones          the K model bones kept (all B by default)
///   globals        T * K global joint transforms, frame-major (MmdPoser::pose), of `bones` in that order
///   matched_bones  model bones with keys
///   unmatched_keys keys on bones the model does not have (ignored); unmatched_bones their names
struct MmdBoneMotion {
  int frames = 0;
  std::vector<int> bones;
  Transforms globals;
  int matched_bones = 0;
  uint64_t unmatched_keys = 0;
  std::vector<std::string> unmatched_bones;
};

/// Evaluates `motion` on `model` (PmxFrame::kMmd) frame by frame, keeping the transforms of the bones `keep`
/// (indices into model.bones; empty: every bone). Keys match a bone by its name, or by its name cut to the VMD's
/// 15-byte field (vmd_field_name); of bones sharing a name the first takes the keys. Keys on other bones are counted,
/// never an error. Throws amt::Error naming the motion's file for a keyframe number of kMaxMmdFrames or more, and
/// naming the model for a bone index of `keep` out of range.
MmdBoneMotion mmd_bone_motion(const PmxModel& model, const VmdMotion& motion, const std::vector<int>& keep = {});

}  // namespace amt
