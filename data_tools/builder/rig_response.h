#pragma once
// The physics response (data_tools/geometry/rig_probe.h) of a Bullet rig: the builder's spring 6-DOF chains or a PMX
// model's rigid bodies and joints. Stored per rig bone in datasets (Rig::response) and measured on a PMX model when
// amt animate loads it.
#include "data_tools/builder/physics.h"
#include "data_tools/geometry/rig_probe.h"

namespace amt {

/// The response of every bone of `rig` (B rows, kRigResponseChannels columns; probe_response): a bone is simulated
/// when a body that is not kFollowBone drives it. `settings` are the world's (its length unit), and metres_per_unit
/// converts the probe's amplitude to it. Deterministic (the world is rebuilt). Throws amt::Error for an invalid rig
/// or settings (validate_physics_rig) or a probe option out of range.
MatrixXfR rig_response(const PhysicsRig& rig, const PhysicsSettings& settings, float metres_per_unit,
                       const RigProbeOptions& probe = {});

}  // namespace amt
