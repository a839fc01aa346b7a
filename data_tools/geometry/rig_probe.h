#pragma once
// How lively a character's own apparel physics is, measured rather than read off its parameters: the whole rig sways
// sideways and stops, and each bone's swing away from where the rig carries it is recorded. Rigs differ in every
// parameter that matters (the builder's spring 6-DOF chains, an artist's PMX joints with locked or free axes, zero or
// huge springs, damping from 0 to 0.999, masses in any unit, VRM springs' stiffness, drag and gravity), and their
// effects interact; the response to one probe motion puts them all on one scale, the one the apparel module needs:
// how far the apparel leaves rigid skinning while the body moves and after it stops. The probe is the same for every
// simulator (Bullet rigs: data_tools/builder/rig_response.h; VRM spring bones: spring_response in spring_bones.h);
// the results are stored per rig bone in datasets (Rig::response) and read per vertex by the apparel module
// (vertex_response, apparel_topology.h).
#include <cstdint>
#include <functional>
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

/// Channels of a rig bone's response to the body's motion under the character's own physics (probe_response): 1 for
/// a bone the simulation moves (else 0, with the others 0), its swing away from rigid skinning while the body sways,
/// and after the body stops, both per unit of sway.
inline constexpr int kRigResponseChannels = 3;

/// The probe: the rig at rest (settle_seconds), then moved rigidly along the horizontal diagonal (x + z) / sqrt(2)
/// by amplitude sin(2 pi f t) for 1.5 periods (it ends at rest with its largest speed), then held still for
/// hold_seconds. Sampled at 30 frames per second.
struct RigProbeOptions {
  float amplitude_metres = 0.1f;
  float frequency = 1.2f;
  float settle_seconds = 1.0f;
  float hold_seconds = 1.0f;
};

/// Where the probe measures each bone: the point its vertices swing with, the mean rest head of its children, or
/// for a bone without children its head plus half of the step from its parent's head (its own head for a root).
/// heads (B, 3) rest heads, parents (B) in [-1, B) -> (B, 3).
MatrixX3f bone_tails(const MatrixX3f& heads, const std::vector<int32_t>& parents);

/// Runs the probe on a simulator and returns the response (B rows, kRigResponseChannels columns): column 0 is 1
/// for a bone the simulation moves (`simulated`, B flags, and every descendant: `parents`), else 0 with the other
/// columns 0; column 1 the RMS distance of the bone's tail (bone_tails of `heads`) from where a rigid rig would carry
/// it (its settled position plus the sway) during the sway, column 2 the same over the hold after it, both divided
/// by the amplitude (0: the bone follows rigidly; about 1: it lags by as much as the body moves), capped at 4.
/// `amplitude` is the probe's amplitude in the rig's length unit. `advance(pose, seconds)` steps the simulator by
/// `seconds` to `pose` (B skinning transforms, rest -> posed: a translation of the whole rig) and returns the
/// bones' skinning transforms; the simulator starts at rest. Throws amt::Error for a probe option out of range or
/// inputs of the wrong size.
MatrixXfR probe_response(const MatrixX3f& heads, const std::vector<int32_t>& parents,
                         const std::vector<uint8_t>& simulated, float amplitude, const RigProbeOptions& probe,
                         const std::function<Transforms(const Transforms& pose, float seconds)>& advance);

}  // namespace amt
