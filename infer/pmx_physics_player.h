#pragma once
// `amt animate --apparel physics`: a PMX model's apparel moved by its own rigid bodies and joints under the motion
// (the look its artist tuned) instead of the apparel module. The whole mesh is skinned by the model's own weights
// over its whole rig, physics-driven bones from the simulation (data_tools/builder/pmx_dataset.h): stepped at the
// dataset's rate, what the dataset builder records as ground truth for the same model and motion, frame for frame
// (`amt animate` steps it at kPhysicsStepFps of infer/runtime_torch.h instead, whatever the output rate).
#include <optional>
#include <string>

#include "data_tools/builder/pmx_dataset.h"
#include "data_tools/formats/joint_map.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/types.h"

namespace amt {

/// Lead-in pose k (0-based) of n: the canonical pose blending from the rest pose of `skeleton` into `first` (22 joint
/// transforms on it): every local rotation slerped from the identity by w = lead_in_weight(k, n) and the root
/// translation scaled by w, then forward kinematics. Pose n - 1 is close to `first`, never past it.
Transforms lead_in_pose(const Skeleton& skeleton, const Transforms& first, int k, int n);

/// A PMX character played under canonical poses with its own physics.
class PmxPhysicsPlayer {
 public:
  /// Loads and repairs the model at `path` (load_pmx_character with `joint_map`). Throws amt::Error "path:
  /// --apparel physics: ..." when the model has no simulated rigid body driving a bone (nothing to simulate).
  PmxPhysicsPlayer(const std::string& path, const std::optional<JointMapFile>& joint_map,
                   const PmxSimulationOptions& options);

  /// Not copyable or movable: the simulator points at the character it holds.
  PmxPhysicsPlayer(const PmxPhysicsPlayer&) = delete;
  PmxPhysicsPlayer& operator=(const PmxPhysicsPlayer&) = delete;

  const PmxCharacter& character() const { return character_; }

  /// Starts at the rest pose (the bodies settle for options.settle_seconds), then runs `lead_in` frames that blend
  /// into `first` (22 canonical transforms): the motion starts from a settled rest, as MMD clips do.
  void start(const Transforms& first, int lead_in);

  /// One frame (1 / options.fps seconds) towards `canonical`: every vertex (#V by 3, metres, amt's frame, file order)
  /// skinned with the simulated rig into `V`.
  void step(const Transforms& canonical, MatrixX3f& V);

  /// step() without the skinning, and the skinning of the last step alone (frames that are simulated but not all
  /// written: a simulation clock faster than the output).
  void advance(const Transforms& canonical);
  void skin(MatrixX3f& V) const;

 private:
  PmxCharacter character_;
  PmxRigSimulator simulator_;
};

}  // namespace amt
