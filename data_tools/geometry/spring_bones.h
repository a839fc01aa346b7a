#pragma once
// Spring bones: the secondary motion VRM avatars carry for hair, skirts and ties (`amt animate --apparel
// spring-bones`). Each simulated segment is a joint whose tail follows a verlet point: inertia damped by the drag
// force, a pull back to the rest direction (stiffness), gravity, sphere and capsule colliders on the body, and the
// segment's length kept. The update is the one the VRM specification defines ("VRMC_springBone-1.0", section
// "Spring bone algorithm"; VRM 0.x "secondaryAnimation", as UniVRM implements it), written here on amt's skeletons
// (world rest poses without rotations, skinning transforms per joint) because no C++ library implements it.
//
// The specification's update depends on the step size (the drag is applied per step), so the simulator advances at
// a fixed internal step whatever the output frame rate, with the driving pose interpolated between output frames:
// the same clip at 30, 60 or 120 fps moves the springs the same way.
#include <string>
#include <vector>

#include "data_tools/geometry/rig_probe.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/types.h"

namespace amt {

/// One simulated segment: joint `joint` rotates about its head so that its tail follows the spring.
///   joint          skeleton joint index (its head is the joint's position)
///   tail           the tail's rest position (metres, world): the next joint of the chain, or a virtual tail 7 cm
///                  along the joint's own bone for the last one (as UniVRM and three-vrm make it)
///   stiffness      pull towards the rest direction, per second (VRM "stiffness", VRM 0.x "stiffiness")
///   gravity_power  gravity, metres per second along gravity_dir (unit vector, world)
///   drag           share of the velocity lost per internal step, in [0, 1]
///   hit_radius     the tail's radius against colliders (metres)
///   spring         index of its spring in SpringRig::spring_colliders
struct SpringJoint {
  int joint = -1;
  Eigen::Vector3f tail = Eigen::Vector3f::Zero();
  float stiffness = 1.0f;
  float gravity_power = 0.0f;
  Eigen::Vector3f gravity_dir = Eigen::Vector3f(0.0f, -1.0f, 0.0f);
  float drag = 0.4f;
  float hit_radius = 0.0f;
  int spring = 0;
};

/// A collider on joint `joint`: a sphere at `center` (rest, world) or a capsule from `center` to `tail`, with
/// `radius`; it moves rigidly with its joint.
struct SpringCollider {
  int joint = -1;
  Eigen::Vector3f center = Eigen::Vector3f::Zero();
  Eigen::Vector3f tail = Eigen::Vector3f::Zero();
  float radius = 0.0f;
  bool capsule = false;
};

/// The spring bones of a character.
///   joints            segments, a joint's parent segment before it
///   colliders         every collider
///   spring_colliders  per spring, the colliders its segments collide with
///   notes             what was read with a stated fallback (a branching chain, a centre node that is ignored)
struct SpringRig {
  std::vector<SpringJoint> joints;
  std::vector<SpringCollider> colliders;
  std::vector<std::vector<int>> spring_colliders;
  std::vector<std::string> notes;

  int num_joints() const { return static_cast<int>(joints.size()); }
};

/// Turns a rig half a turn about Y (x and z negated), as load_character turns a character that faces -Z.
void turn_spring_rig(SpringRig& rig);

/// Checks a rig against `skeleton`: joint and collider indices in range, a segment's joint listed once and after
/// its ancestors' segments, finite parameters, drag in [0, 1], a tail away from its head. Throws amt::Error naming
/// `source` and the segment.
void validate_spring_rig(const SpringRig& rig, const Skeleton& skeleton, const std::string& source);

/// The default internal step: 120 steps per second (a multiple of 24, 30 and 60 fps).
inline constexpr double kSpringStepSeconds = 1.0 / 120.0;

/// Simulates a rig's springs on a skeleton driven by skinning transforms (one [R | t] per joint, rest -> posed).
class SpringBoneSimulator {
 public:
  /// `rig` must pass validate_spring_rig on `skeleton`. step_seconds > 0.
  SpringBoneSimulator(Skeleton skeleton, SpringRig rig, double step_seconds = kSpringStepSeconds);

  /// Starts at `pose` (a skinning transform per skeleton joint) with every spring at rest relative to its parent
  /// and at rest (no velocity). Returns the pose with the spring joints (and the joints below them) placed.
  Transforms reset(const Transforms& pose);

  /// Advances by `seconds` (> 0) to `pose`: internal steps of step_seconds each, the driving pose interpolated
  /// between the previous pose and this one (joint positions linearly, rotations by slerp). Returns `pose` with every
  /// spring joint's transform simulated and every joint below a spring joint carried by it. The springs' rotations
  /// relative to their parents are those of the last internal step at or before the frame's time, so a frame
  /// that falls between two steps lags by less than one step.
  Transforms advance(const Transforms& pose, double seconds);

  /// One internal step of `dt` seconds under `pose` (the specification's update, exposed for tests).
  void step(const Transforms& pose, float dt);

  /// Current tail positions (world), per segment.
  const std::vector<Eigen::Vector3f>& tails() const { return current_; }
  const SpringRig& rig() const { return rig_; }

 private:
  // Places the spring joints of `pose` from the stored rotations relative to their parents.
  Transforms place(const Transforms& pose) const;
  Eigen::Vector3f collide(int segment, Eigen::Vector3f tail, const Transforms& pose) const;

  Skeleton skeleton_;
  SpringRig rig_;
  double step_seconds_;
  std::vector<int> segment_of_joint_;  // per skeleton joint, its segment or -1
  std::vector<Eigen::Vector3f> current_, previous_;
  std::vector<Eigen::Matrix3f> local_;  // per segment, its rotation relative to its parent joint's
  Transforms last_pose_;
  long long steps_ = 0;
  double frame_time_ = 0.0;
};

/// The physics response of a character's spring bones (probe_response, rig_probe.h), per skeleton joint (J rows;
/// `skeleton` in metres): a joint is simulated when it is a segment's joint. The probe's scale is the one of
/// rig_response (data_tools/builder/rig_response.h), so a VRM avatar's springs and a PMX model's rigid bodies read
/// alike. Deterministic. Throws amt::Error for a rig that fails validate_spring_rig or a probe option out of range.
MatrixXfR spring_response(const Skeleton& skeleton, const SpringRig& rig, const RigProbeOptions& probe = {});

}  // namespace amt
