#pragma once
// Simulation of a dressed character's apparel under a body motion (docs/dataset.md, "What the builder makes"): per
// output frame, pose the body bones -> kinematic capsules follow (swept over the substeps) -> Bullet steps at 1/120 s
// -> simulated apparel bones written back -> skinning matrices of every rig bone (the dataset's rig_transforms of that
// frame).
#include "data_tools/builder/apparel.h"
#include "data_tools/builder/physics.h"
#include "data_tools/geometry/types.h"

namespace amt {

/// Simulates one DressedCharacter. Owns its Bullet world (PhysicsWorld); not copyable, movable. Deterministic: the
/// same character, settings and calls give bit-identical transforms (one thread; start() rebuilds the world, so
/// clips do not depend on what was simulated before).
class ApparelSimulator {
 public:
  /// Builds the world from character.rig (validated). The character is copied where needed; it may go away.
  explicit ApparelSimulator(const DressedCharacter& character, PhysicsSettings settings = {});

  /// Resets the world at `body_pose` (22 canonical joint transforms [R_j|t_j], forward_kinematics output), apparel
  /// bones rigidly following their parents, and lets the apparel settle for `settle_seconds` (>= 0) with the body
  /// held still. Call before each clip.
  void start(const Transforms& body_pose, float settle_seconds = 1.0f);

  /// One output frame of dt seconds (> 0) towards `body_pose`; returns the rig's skinning matrices (B transforms,
  /// posed global * inverse rest global, the dataset's rig_transforms of that frame). The reference stays valid
  /// until the next call.
  const Transforms& step(const Transforms& body_pose, float dt);

  /// Skinning matrices after the last start() or step() (B transforms).
  const Transforms& skinning() const { return skinning_; }

  /// Joint transforms [R | t] of every rig bone (B) after the last start() or step().
  const Transforms& bone_transforms() const;

  /// Full rig pose (B transforms) for a body pose: body bones from `body_pose`, apparel bones rigidly carried by
  /// their parents (what the simulation would give with perfectly stiff apparel).
  Transforms rigid_pose(const Transforms& body_pose) const;

  /// The world, e.g. to read body poses in tests.
  const PhysicsWorld& world() const { return world_; }

 private:
  void check_body_pose(const Transforms& body_pose, const char* what) const;
  void update_skinning();

  PhysicsWorld world_;
  std::vector<int32_t> parents_;       // rig bone parents (apparel bones after their parents)
  std::vector<Eigen::Vector3f> rest_;  // rig bone rest positions
  Transforms pose_;                    // scratch: full rig pose
  Transforms skinning_;                // output
};

/// Skinning matrices [R | t - R rest] of joint transforms `pose` over bones at `rest_positions` (B each).
Transforms rig_skinning_matrices(const PhysicsRig& rig, const Transforms& pose);

}  // namespace amt
