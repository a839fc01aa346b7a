#pragma once
// Rigid-body physics of the dataset builder (docs/dataset.md, "What the builder makes"): MMD-style rigs of bones, rigid
// bodies and spring 6-DOF joints, simulated with Bullet. Bullet stays inside physics.cpp: this header needs only Eigen.
//
// Conventions. A rig lives in one frame and one length unit: metres for procedural characters, PMX units for
// imported models (see mmd_physics_settings and data_tools/builder/pmx_physics.h). Bones have rest positions only; a
// bone pose is the project's joint transform T = [R | t] (data_tools/geometry/motion.h): R the bone's global rotation
// relative to the rest pose, t its global position, so a rest point p rigidly attached to the bone moves to R (p -
// p_rest) + t. Rigid bodies and joints have full world transforms (position and orientation) at rest, as PMX stores
// them.
//
// Per output frame: set_bone_pose (the animated pose) -> step (fixed substeps; kinematic bodies follow the pose,
// interpolated across the substeps) -> bone_transforms (the pose with the simulated bones written back).
// Deterministic: the same rig, settings and calls give bit-identical results (one thread, fixed steps, and reset
// rebuilds the Bullet world so that no cached contact or solver state carries over between clips).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

// === Rig description

/// A rigid placement x' = rotation * x + position (position in the rig's length unit, rotation a unit quaternion).
struct RigidPose {
  Eigen::Vector3f position = Eigen::Vector3f::Zero();
  Eigen::Quaternionf rotation = Eigen::Quaternionf::Identity();
};

/// Collision shape of a rigid body, centred on the body's origin, in the body's frame.
enum class PhysicsShape : uint8_t {
  kSphere = 0,   ///< size (radius, -, -)
  kBox = 1,      ///< size (half extent x, half extent y, half extent z)
  kCapsule = 2,  ///< size (radius, height of the cylinder between the cap centres along the body's Y, -)
};

/// How a rigid body and its bone drive each other (the PMX rigid body modes).
enum class PhysicsMode : uint8_t {
  kFollowBone = 0,       ///< kinematic: the body follows its animated bone and pushes dynamic bodies
  kDynamic = 1,          ///< simulated: the body sets its bone's rotation and position
  kDynamicRotation = 2,  ///< simulated: the body sets its bone's rotation; the position follows the parent chain
};

/// A bone of the rig. Bones may be listed in any order (PMX does not sort them); parents must not form cycles.
struct PhysicsBone {
  std::string name;
  int32_t parent = -1;                                      ///< parent bone index, or -1 for a root
  Eigen::Vector3f rest_position = Eigen::Vector3f::Zero();  ///< global rest position (length unit)
};

/// A rigid body attached to a bone (or to none: bone -1 keeps a kinematic body at its rest transform).
struct PhysicsBody {
  std::string name;
  int32_t bone = -1;  ///< bone index or -1. Of several simulated bodies on one bone, the first drives it.
  PhysicsShape shape = PhysicsShape::kSphere;
  Eigen::Vector3f size = Eigen::Vector3f::Zero();  ///< lengths, see PhysicsShape; the used components are > 0
  /// Rest transform: the body's world transform at rest (as PMX stores it), or, when rest_is_bone_local is true,
  /// its offset from the bone's rest frame (the bone's rest position, world axes): world = bone rest * rest.
  RigidPose rest;
  bool rest_is_bone_local = false;
  /// > 0 for simulated bodies (rig mass unit); ignored for kFollowBone. Inertia comes from the shape: keep a
  /// simulated body's size comparable to its distance from its joints (a point-like body far from its joint makes
  /// the joint ill-conditioned for the solver's iterations and slows the swing).
  float mass = 1.0f;
  float linear_damping = 0.0f;   ///< Bullet linear damping in [0, 1]: velocity scaled by (1 - d) per second
  float angular_damping = 0.0f;  ///< Bullet angular damping in [0, 1]
  float friction = 0.5f;         ///< Coulomb friction coefficient, >= 0
  float restitution = 0.0f;      ///< bounciness, >= 0
  uint8_t group = 0;             ///< collision group 0..15; the Bullet filter group is 1 << group
  /// Groups this body does not collide with (bit g set = no contact with group g); the Bullet filter mask is
  /// ~non_collision_mask & 0xFFFF. Two bodies touch only when each one's mask admits the other's group.
  uint16_t non_collision_mask = 0;
  PhysicsMode mode = PhysicsMode::kFollowBone;
};

/// A spring 6-DOF joint (btGeneric6DofSpringConstraint) between two bodies, acting in the joint's frame.
/// Limits are passed to Bullet as they are, as MMD does: on each axis min == max locks it, min < max limits it,
/// min > max leaves it free. Angular limits bound Bullet's 6-DOF angles (x, y, z) of the relative rotation
/// R_rel = F_A^T F_B of the joint frame carried by body B (F_B) seen from the one carried by body A (F_A), defined
/// by R_rel^T = Rx(x) Ry(y) Rz(z): B turned by +a about the joint's X axis reads x = -a. Keep the Y range within
/// [-pi/2, pi/2]. Springs (Bullet's btGeneric6DofSpringConstraint: a motor whose force is stiffness times the
/// offset, force per length unit or torque per radian) pull towards the rest configuration on every axis with
/// non-zero stiffness.
struct PhysicsJoint {
  std::string name;
  int32_t body_a = -1;  ///< index into PhysicsRig::bodies
  int32_t body_b = -1;  ///< index into PhysicsRig::bodies, != body_a
  /// World transform of the joint frame at rest. From Euler angles, set rotation = Quaternionf(R(euler)) with the
  /// source's composition order (e.g. pmx_euler_rotation for PMX).
  RigidPose rest;
  Eigen::Vector3f linear_min = Eigen::Vector3f::Zero();         ///< translation limits along the joint axes (length)
  Eigen::Vector3f linear_max = Eigen::Vector3f::Zero();         ///< translation upper limits (length)
  Eigen::Vector3f angular_min = Eigen::Vector3f::Zero();        ///< rotation lower limits about the joint axes (rad)
  Eigen::Vector3f angular_max = Eigen::Vector3f::Zero();        ///< rotation upper limits (rad)
  Eigen::Vector3f linear_stiffness = Eigen::Vector3f::Zero();   ///< spring stiffness per translation axis, >= 0
  Eigen::Vector3f angular_stiffness = Eigen::Vector3f::Zero();  ///< spring stiffness per rotation axis, >= 0
};

/// Bones, rigid bodies and joints of one character, in one frame and length unit.
struct PhysicsRig {
  std::vector<PhysicsBone> bones;
  std::vector<PhysicsBody> bodies;
  std::vector<PhysicsJoint> joints;

  int num_bones() const { return static_cast<int>(bones.size()); }
  int num_bodies() const { return static_cast<int>(bodies.size()); }
  int num_joints() const { return static_cast<int>(joints.size()); }
};

/// Throws amt::Error naming `source`, the element and the field unless: bone parents are in range and acyclic,
/// every value is finite, rotations are non-zero quaternions (they are normalised when used), body bones and
/// joint bodies are in range, shapes have positive sizes, simulated bodies positive mass, damping is in [0, 1],
/// friction, restitution and stiffness are >= 0, groups are 0..15 and a joint joins two different bodies.
void validate_physics_rig(const PhysicsRig& rig, const std::string& source);

/// World transform of body `body` at rest (resolves PhysicsBody::rest_is_bone_local; rotation normalised).
RigidPose body_rest_pose(const PhysicsRig& rig, int body);

/// The rest pose of the rig's bones: identity rotations at the rest positions (#bones transforms).
Transforms physics_rest_pose(const PhysicsRig& rig);

// === World settings

/// Settings of a PhysicsWorld. The defaults suit rigs in metres (procedural characters).
struct PhysicsSettings {
  Eigen::Vector3f gravity = Eigen::Vector3f(0.0f, -9.8f, 0.0f);  ///< acceleration (length unit / s^2)
  float fixed_step = 1.0f / 120.0f;  ///< target substep (s); a frame is split into ceil(dt / fixed_step) equal steps
  int max_substeps = 16;             ///< cap on substeps per step() call; beyond it the substeps get longer
  int solver_iterations = 10;        ///< sequential-impulse iterations per substep (Bullet's default)
  /// Collision margin of box shapes (length unit; spheres and capsules need none), capped at a fifth of the
  /// smallest half extent. Bullet's default 0.04 suits PMX units; the default here is 1 cm.
  float box_margin = 0.01f;
  /// Whether two bodies joined by a joint can collide (MMD: yes, subject to their groups and masks).
  bool joined_bodies_collide = true;
};

/// MMD's world in PMX units (1 unit ~ 8 cm): gravity 98 units/s^2 along -Y, box margin 0.04, other fields default.
PhysicsSettings mmd_physics_settings();

// === Simulation

/// A Bullet world built from a rig. Not copyable (it owns the Bullet world); movable.
class PhysicsWorld {
 public:
  /// Validates the rig (validate_physics_rig with source "physics rig") and builds the world with every body at
  /// rest, at rest velocity zero. Throws amt::Error on an invalid rig or invalid settings.
  PhysicsWorld(PhysicsRig rig, PhysicsSettings settings = {});
  ~PhysicsWorld();
  PhysicsWorld(PhysicsWorld&&) noexcept;
  PhysicsWorld& operator=(PhysicsWorld&&) noexcept;
  PhysicsWorld(const PhysicsWorld&) = delete;
  PhysicsWorld& operator=(const PhysicsWorld&) = delete;

  /// The rig and the settings the world was built from.
  const PhysicsRig& rig() const;
  const PhysicsSettings& settings() const;

  /// Rebuilds the Bullet world and places every body at `pose` (#bones joint transforms, see the top of this
  /// header) with zero velocity: kinematic bodies on their bones, simulated bodies where their bones' animated
  /// transforms put them. The next step starts from there, exactly as a freshly built world would.
  void reset(const Transforms& pose);

  /// Sets the animated pose (#bones joint transforms) that kinematic bodies reach at the end of the next step().
  /// Transforms of bones driven by simulated bodies are used only to place descendants that are not simulated.
  void set_bone_pose(const Transforms& pose);

  /// Advances by dt seconds (> 0) in n = min(ceil(dt / fixed_step), max_substeps) equal substeps. Over the
  /// substeps, kinematic bodies move from the previous pose to the one given to set_bone_pose (positions linearly,
  /// rotations by slerp) so that fast motions sweep through apparel instead of jumping over it.
  void step(float dt);

  /// Holds `pose` (sets it and keeps kinematic bodies still) and simulates `seconds` in fixed steps so the
  /// simulated bodies relax, e.g. after reset(pose) and before recording a clip.
  void settle(const Transforms& pose, float seconds);

  /// Joint transforms of all bones (#bones) after the last reset / step / settle: bones of kDynamic bodies take
  /// the body's rotation and position, bones of kDynamicRotation bodies its rotation and the position their parent
  /// chain gives them, and the other bones keep their animated transform relative to their (possibly simulated)
  /// parent. Bones untouched by the simulation return their animated transform exactly.
  const Transforms& bone_transforms() const;

  /// Current world transform of body `body` (position and absolute orientation, not relative to rest).
  RigidPose body_pose(int body) const;

  /// Current linear velocity of body `body` (length unit / s).
  Eigen::Vector3f body_linear_velocity(int body) const;

  /// Seconds simulated since construction or the last reset.
  double time() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace amt
