#include "data_tools/builder/rig_response.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "data_tools/geometry/error.h"

namespace amt {

MatrixXfR rig_response(const PhysicsRig& rig, const PhysicsSettings& settings, float metres_per_unit,
                       const RigProbeOptions& probe) {
  AMT_CHECK(std::isfinite(metres_per_unit) && metres_per_unit > 0,
            "rig response: metres per unit: expected > 0, found ", metres_per_unit);
  const int B = rig.num_bones();
  MatrixX3f heads(B, 3);
  std::vector<int32_t> parents(static_cast<size_t>(B));
  std::vector<uint8_t> simulated(static_cast<size_t>(B), 0);
  for (int b = 0; b < B; ++b) {
    heads.row(b) = rig.bones[static_cast<size_t>(b)].rest_position.transpose();
    parents[static_cast<size_t>(b)] = rig.bones[static_cast<size_t>(b)].parent;
  }
  for (const PhysicsBody& body : rig.bodies)
    if (body.mode != PhysicsMode::kFollowBone && body.bone >= 0 && body.bone < B) simulated[body.bone] = 1;
  if (std::find(simulated.begin(), simulated.end(), uint8_t(1)) == simulated.end()) {
    validate_physics_rig(rig, "physics rig");
    return MatrixXfR::Zero(B, kRigResponseChannels);
  }
  // The world poses bones by their frames (rotation, head position; physics_rest_pose at rest), the probe by
  // skinning transforms (rest -> posed): S = [R | p - R h] for the frame [R | p] of a bone with rest head h.
  PhysicsWorld world(rig, settings);
  const auto frames = [&](const Transforms& skinning) {
    Transforms out(skinning.size());
    for (int b = 0; b < B; ++b)
      out[b] = make_transform(skinning[b].leftCols<3>(), apply(skinning[b], heads.row(b).transpose()));
    return out;
  };
  world.reset(physics_rest_pose(rig));
  return probe_response(heads, parents, simulated, probe.amplitude_metres / metres_per_unit, probe,
                        [&](const Transforms& pose, float seconds) {
                          world.set_bone_pose(frames(pose));
                          world.step(seconds);
                          Transforms skinning = world.bone_transforms();
                          for (int b = 0; b < B; ++b) {
                            const Eigen::Matrix3f R = skinning[b].leftCols<3>();
                            skinning[b] = make_transform(R, skinning[b].col(3) - R * heads.row(b).transpose());
                          }
                          return skinning;
                        });
}

}  // namespace amt
