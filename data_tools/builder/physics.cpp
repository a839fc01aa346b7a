#include "data_tools/builder/physics.h"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

btVector3 to_bt(const Eigen::Vector3f& v) {
  return btVector3(v.x(), v.y(), v.z());
}

btQuaternion to_bt(const Eigen::Quaternionf& q) {
  return btQuaternion(q.x(), q.y(), q.z(), q.w());
}

btTransform to_bt(const RigidPose& p) {
  return btTransform(to_bt(p.rotation), to_bt(p.position));
}

Eigen::Vector3f from_bt(const btVector3& v) {
  return Eigen::Vector3f(v.x(), v.y(), v.z());
}

RigidPose from_bt(const btTransform& t) {
  const btQuaternion q = t.getRotation();
  RigidPose p;
  p.position = from_bt(t.getOrigin());
  p.rotation = Eigen::Quaternionf(q.w(), q.x(), q.y(), q.z()).normalized();
  return p;
}

bool is_simulated(PhysicsMode mode) {
  return mode != PhysicsMode::kFollowBone;
}

const char* shape_name(PhysicsShape s) {
  switch (s) {
    case PhysicsShape::kSphere:
      return "sphere";
    case PhysicsShape::kBox:
      return "box";
    case PhysicsShape::kCapsule:
      return "capsule";
  }
  return "unknown";
}

// Bone indices ordered parents first. The rig has been validated (no cycles).
std::vector<int> parents_first_order(const PhysicsRig& rig) {
  const int n = rig.num_bones();
  std::vector<int> order;
  order.reserve(static_cast<size_t>(n));
  std::vector<char> placed(static_cast<size_t>(n), 0);
  std::vector<int> chain;
  for (int j = 0; j < n; ++j) {
    // Walk up to the first placed ancestor, then place the chain top-down.
    chain.clear();
    for (int b = j; b >= 0 && !placed[b]; b = rig.bones[b].parent) chain.push_back(b);
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      placed[*it] = 1;
      order.push_back(*it);
    }
  }
  return order;
}

Eigen::Matrix3f rotation_of(const Transform34& T) {
  return T.leftCols<3>();
}

Eigen::Vector3f position_of(const Transform34& T) {
  return T.col(3);
}

// Interpolates between two placements: positions linearly, rotations by slerp; alpha = 1 gives `to` exactly.
RigidPose interpolate(const RigidPose& from, const RigidPose& to, float alpha) {
  if (alpha >= 1.0f) return to;
  RigidPose p;
  p.position = from.position + alpha * (to.position - from.position);
  p.rotation = from.rotation.slerp(alpha, to.rotation).normalized();
  return p;
}

}  // namespace

// === Rig description

void validate_physics_rig(const PhysicsRig& rig, const std::string& source) {
  const int nb = rig.num_bones();
  const int nr = rig.num_bodies();
  for (int j = 0; j < nb; ++j) {
    const PhysicsBone& b = rig.bones[j];
    AMT_CHECK(b.parent >= -1 && b.parent < nb && b.parent != j, source, ": bones[", j, "] '", b.name,
              "': parent: expected -1 or another bone index in [0, ", nb, "), found ", b.parent);
    AMT_CHECK(b.rest_position.allFinite(), source, ": bones[", j, "] '", b.name,
              "': rest_position: expected finite values, found NaN or infinity");
  }
  // Cycle check: from every bone, the parent chain must end within nb steps.
  for (int j = 0; j < nb; ++j) {
    int steps = 0;
    for (int b = rig.bones[j].parent; b >= 0; b = rig.bones[b].parent) {
      AMT_CHECK(++steps <= nb, source, ": bones[", j, "] '", rig.bones[j].name,
                "': parent: expected an acyclic hierarchy, found a cycle through this bone's ancestors");
    }
  }
  auto check_rotation = [&](const Eigen::Quaternionf& q, const char* what, int i, const std::string& name) {
    const float norm = q.norm();
    AMT_CHECK(q.coeffs().allFinite() && norm > 1e-6f, source, ": ", what, "[", i, "] '", name,
              "': rest.rotation: expected a finite non-zero quaternion, found norm ", norm);
  };
  for (int i = 0; i < nr; ++i) {
    const PhysicsBody& r = rig.bodies[i];
    const std::string where = detail::concat(source, ": bodies[", i, "] '", r.name, "': ");
    AMT_CHECK(r.bone >= -1 && r.bone < nb, where, "bone: expected -1 or a bone index in [0, ", nb, "), found ", r.bone);
    AMT_CHECK(r.shape == PhysicsShape::kSphere || r.shape == PhysicsShape::kBox || r.shape == PhysicsShape::kCapsule,
              where, "shape: expected sphere (0), box (1) or capsule (2), found ", static_cast<int>(r.shape));
    const int used = r.shape == PhysicsShape::kSphere ? 1 : r.shape == PhysicsShape::kBox ? 3 : 2;
    for (int k = 0; k < used; ++k) {
      AMT_CHECK(std::isfinite(r.size[k]) && r.size[k] > 0, where, "size[", k, "]: expected a positive length for a ",
                shape_name(r.shape), ", found ", r.size[k]);
    }
    AMT_CHECK(r.rest.position.allFinite(), where, "rest.position: expected finite values, found NaN or infinity");
    check_rotation(r.rest.rotation, "bodies", i, r.name);
    AMT_CHECK(r.mode == PhysicsMode::kFollowBone || r.mode == PhysicsMode::kDynamic ||
                  r.mode == PhysicsMode::kDynamicRotation,
              where, "mode: expected 0, 1 or 2, found ", static_cast<int>(r.mode));
    if (is_simulated(r.mode)) {
      AMT_CHECK(std::isfinite(r.mass) && r.mass > 0, where,
                "mass: expected a positive mass for a simulated body, found ", r.mass);
    }
    AMT_CHECK(std::isfinite(r.linear_damping) && r.linear_damping >= 0 && r.linear_damping <= 1, where,
              "linear_damping: expected a value in [0, 1], found ", r.linear_damping);
    AMT_CHECK(std::isfinite(r.angular_damping) && r.angular_damping >= 0 && r.angular_damping <= 1, where,
              "angular_damping: expected a value in [0, 1], found ", r.angular_damping);
    AMT_CHECK(std::isfinite(r.friction) && r.friction >= 0, where, "friction: expected a value >= 0, found ",
              r.friction);
    AMT_CHECK(std::isfinite(r.restitution) && r.restitution >= 0, where, "restitution: expected a value >= 0, found ",
              r.restitution);
    AMT_CHECK(r.group <= 15, where, "group: expected a collision group in [0, 15], found ", static_cast<int>(r.group));
  }
  for (int i = 0; i < rig.num_joints(); ++i) {
    const PhysicsJoint& c = rig.joints[i];
    const std::string where = detail::concat(source, ": joints[", i, "] '", c.name, "': ");
    AMT_CHECK(c.body_a >= 0 && c.body_a < nr, where, "body_a: expected a body index in [0, ", nr, "), found ",
              c.body_a);
    AMT_CHECK(c.body_b >= 0 && c.body_b < nr, where, "body_b: expected a body index in [0, ", nr, "), found ",
              c.body_b);
    AMT_CHECK(c.body_a != c.body_b, where, "body_b: expected a body other than body_a, found ", c.body_b, " for both");
    AMT_CHECK(c.rest.position.allFinite(), where, "rest.position: expected finite values, found NaN or infinity");
    check_rotation(c.rest.rotation, "joints", i, c.name);
    AMT_CHECK(
        c.linear_min.allFinite() && c.linear_max.allFinite() && c.angular_min.allFinite() && c.angular_max.allFinite(),
        where, "limits: expected finite values, found NaN or infinity");
    AMT_CHECK(c.linear_stiffness.allFinite() && (c.linear_stiffness.array() >= 0).all(), where,
              "linear_stiffness: expected finite values >= 0, found (", c.linear_stiffness.transpose(), ")");
    AMT_CHECK(c.angular_stiffness.allFinite() && (c.angular_stiffness.array() >= 0).all(), where,
              "angular_stiffness: expected finite values >= 0, found (", c.angular_stiffness.transpose(), ")");
  }
}

RigidPose body_rest_pose(const PhysicsRig& rig, int body) {
  const PhysicsBody& r = rig.bodies[static_cast<size_t>(body)];
  RigidPose p;
  p.rotation = r.rest.rotation.normalized();
  p.position = r.rest.position;
  if (r.rest_is_bone_local && r.bone >= 0) p.position += rig.bones[static_cast<size_t>(r.bone)].rest_position;
  return p;
}

Transforms physics_rest_pose(const PhysicsRig& rig) {
  Transforms pose(rig.bones.size());
  for (size_t j = 0; j < rig.bones.size(); ++j)
    pose[j] = make_transform(Eigen::Matrix3f::Identity(), rig.bones[j].rest_position);
  return pose;
}

PhysicsSettings mmd_physics_settings() {
  PhysicsSettings s;
  s.gravity = Eigen::Vector3f(0.0f, -98.0f, 0.0f);
  s.box_margin = 0.04f;
  return s;
}

// === Simulation

struct PhysicsWorld::Impl {
  PhysicsRig rig;
  PhysicsSettings settings;
  std::vector<int> bone_order;       // parents first
  std::vector<int> bone_driver;      // per bone: the simulated body that drives it, or -1
  std::vector<RigidPose> body_rest;  // world rest transforms
  std::vector<int> kinematic;        // indices of kFollowBone bodies

  // Shapes are immutable and survive world rebuilds; everything else is rebuilt by reset().
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::unique_ptr<btDefaultCollisionConfiguration> configuration;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver;
  std::unique_ptr<btDiscreteDynamicsWorld> world;
  std::vector<std::unique_ptr<btDefaultMotionState>> motion_states;  // per body; null for simulated bodies
  std::vector<std::unique_ptr<btRigidBody>> bodies;
  std::vector<std::unique_ptr<btGeneric6DofSpringConstraint>> constraints;

  Transforms previous_pose;               // animated pose at the start of the next step
  Transforms target_pose;                 // animated pose at its end
  std::vector<RigidPose> kinematic_from;  // per kinematic body (parallel to `kinematic`)
  std::vector<RigidPose> kinematic_to;
  Transforms output;
  double time = 0.0;

  Impl(PhysicsRig rig_in, PhysicsSettings settings_in) : rig(std::move(rig_in)), settings(settings_in) {
    validate_physics_rig(rig, "physics rig");
    AMT_CHECK(settings.gravity.allFinite(), "physics settings: gravity: expected finite values, found (",
              settings.gravity.transpose(), ")");
    AMT_CHECK(std::isfinite(settings.fixed_step) && settings.fixed_step > 0,
              "physics settings: fixed_step: expected a "
              "positive duration in seconds, found ",
              settings.fixed_step);
    AMT_CHECK(settings.max_substeps >= 1, "physics settings: max_substeps: expected >= 1, found ",
              settings.max_substeps);
    AMT_CHECK(settings.solver_iterations >= 1, "physics settings: solver_iterations: expected >= 1, found ",
              settings.solver_iterations);
    AMT_CHECK(std::isfinite(settings.box_margin) && settings.box_margin >= 0,
              "physics settings: box_margin: expected a "
              "length >= 0, found ",
              settings.box_margin);
    bone_order = parents_first_order(rig);
    bone_driver.assign(rig.bones.size(), -1);
    for (int i = 0; i < rig.num_bodies(); ++i) {
      const PhysicsBody& r = rig.bodies[i];
      body_rest.push_back(body_rest_pose(rig, i));
      if (!is_simulated(r.mode)) kinematic.push_back(i);
      if (is_simulated(r.mode) && r.bone >= 0 && bone_driver[r.bone] < 0) bone_driver[r.bone] = i;
      shapes.push_back(make_shape(r));
    }
    const Transforms rest = physics_rest_pose(rig);
    rebuild(rest);
  }

  ~Impl() { destroy_world(); }

  std::unique_ptr<btCollisionShape> make_shape(const PhysicsBody& r) const {
    switch (r.shape) {
      case PhysicsShape::kSphere:
        return std::make_unique<btSphereShape>(r.size.x());
      case PhysicsShape::kCapsule:
        return std::make_unique<btCapsuleShape>(r.size.x(), r.size.y());
      case PhysicsShape::kBox: {
        auto box = std::make_unique<btBoxShape>(to_bt(r.size));
        // setMargin keeps the outer half extents and rounds the corners by the margin.
        box->setMargin(std::min(settings.box_margin, 0.2f * r.size.minCoeff()));
        return box;
      }
    }
    fail("physics rig: body '", r.name, "': unknown shape");
  }

  // World transform of body i when its bone has joint transform pose[bone] (see the top of physics.h).
  RigidPose posed_body(int i, const Transforms& pose) const {
    const int bone = rig.bodies[i].bone;
    if (bone < 0) return body_rest[i];
    const Eigen::Matrix3f R = rotation_of(pose[bone]);
    const Eigen::Quaternionf q(R);
    RigidPose p;
    p.rotation = (q * body_rest[i].rotation).normalized();
    p.position = R * (body_rest[i].position - rig.bones[bone].rest_position) + position_of(pose[bone]);
    return p;
  }

  void destroy_world() {
    if (world) {
      for (auto& c : constraints) world->removeConstraint(c.get());
      for (auto& b : bodies) world->removeRigidBody(b.get());
    }
    constraints.clear();
    bodies.clear();
    motion_states.clear();
    world.reset();
    solver.reset();
    broadphase.reset();
    dispatcher.reset();
    configuration.reset();
  }

  // Builds a fresh Bullet world with every body placed at `pose`, at rest velocity zero.
  void rebuild(const Transforms& pose) {
    destroy_world();
    configuration = std::make_unique<btDefaultCollisionConfiguration>();
    dispatcher = std::make_unique<btCollisionDispatcher>(configuration.get());
    broadphase = std::make_unique<btDbvtBroadphase>();
    solver = std::make_unique<btSequentialImpulseConstraintSolver>();
    world = std::make_unique<btDiscreteDynamicsWorld>(dispatcher.get(), broadphase.get(), solver.get(),
                                                      configuration.get());
    world->setGravity(to_bt(settings.gravity));
    world->getSolverInfo().m_numIterations = settings.solver_iterations;

    for (int i = 0; i < rig.num_bodies(); ++i) {
      const PhysicsBody& r = rig.bodies[i];
      const bool simulated = is_simulated(r.mode);
      const btTransform start = to_bt(posed_body(i, pose));
      btVector3 inertia(0, 0, 0);
      const btScalar mass = simulated ? r.mass : 0.0f;
      if (simulated) shapes[i]->calculateLocalInertia(mass, inertia);
      // Kinematic bodies read their transform from a motion state each substep; Bullet derives their velocity
      // from the change, so contacts push apparel with the animated speed.
      motion_states.push_back(simulated ? nullptr : std::make_unique<btDefaultMotionState>(start));
      btRigidBody::btRigidBodyConstructionInfo info(mass, motion_states.back().get(), shapes[i].get(), inertia);
      info.m_startWorldTransform = start;
      info.m_linearDamping = r.linear_damping;
      info.m_angularDamping = r.angular_damping;
      info.m_friction = r.friction;
      info.m_restitution = r.restitution;
      auto body = std::make_unique<btRigidBody>(info);
      if (!simulated) body->setCollisionFlags(body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
      body->setActivationState(DISABLE_DEACTIVATION);
      const int group = 1 << r.group;
      const int mask = ~static_cast<int>(r.non_collision_mask) & 0xFFFF;
      world->addRigidBody(body.get(), group, mask);
      bodies.push_back(std::move(body));
    }

    for (const PhysicsJoint& c : rig.joints) {
      const btTransform joint = to_bt(RigidPose{c.rest.position, c.rest.rotation.normalized()});
      const btTransform in_a = to_bt(body_rest[c.body_a]).inverse() * joint;
      const btTransform in_b = to_bt(body_rest[c.body_b]).inverse() * joint;
      auto constraint = std::make_unique<btGeneric6DofSpringConstraint>(*bodies[c.body_a], *bodies[c.body_b], in_a,
                                                                        in_b, /*useLinearReferenceFrameA=*/true);
      constraint->setLinearLowerLimit(to_bt(c.linear_min));
      constraint->setLinearUpperLimit(to_bt(c.linear_max));
      constraint->setAngularLowerLimit(to_bt(c.angular_min));
      constraint->setAngularUpperLimit(to_bt(c.angular_max));
      for (int k = 0; k < 3; ++k) {
        if (c.linear_stiffness[k] != 0) {
          constraint->enableSpring(k, true);
          constraint->setStiffness(k, c.linear_stiffness[k]);
        }
        if (c.angular_stiffness[k] != 0) {
          constraint->enableSpring(k + 3, true);
          constraint->setStiffness(k + 3, c.angular_stiffness[k]);
        }
      }
      // The rest configuration (frames aligned) is the springs' equilibrium.
      for (int k = 0; k < 6; ++k) constraint->setEquilibriumPoint(k, 0.0f);
      world->addConstraint(constraint.get(), /*disableCollisionsBetweenLinkedBodies=*/!settings.joined_bodies_collide);
      constraints.push_back(std::move(constraint));
    }

    previous_pose = pose;
    target_pose = pose;
    kinematic_from.resize(kinematic.size());
    for (size_t k = 0; k < kinematic.size(); ++k) kinematic_from[k] = posed_body(kinematic[k], pose);
    kinematic_to = kinematic_from;
    time = 0.0;
    write_back();
  }

  void check_pose(const Transforms& pose, const char* what) const {
    AMT_CHECK(pose.size() == rig.bones.size(), "physics: ", what, ": expected ", rig.bones.size(),
              " bone transforms, found ", pose.size());
    for (size_t j = 0; j < pose.size(); ++j) {
      AMT_CHECK(pose[j].allFinite(), "physics: ", what, ": bone ", j, " '", rig.bones[j].name,
                "': expected a finite transform, found NaN or infinity");
    }
  }

  void set_target(const Transforms& pose) {
    target_pose = pose;
    for (size_t k = 0; k < kinematic.size(); ++k) kinematic_to[k] = posed_body(kinematic[k], pose);
  }

  // One Bullet step of h seconds, kinematic bodies at `alpha` of the way from the previous to the target pose.
  void substep(float h, float alpha) {
    for (size_t k = 0; k < kinematic.size(); ++k) {
      const int i = kinematic[k];
      motion_states[i]->setWorldTransform(to_bt(interpolate(kinematic_from[k], kinematic_to[k], alpha)));
    }
    // maxSubSteps = 0: exactly one internal step of h, no interpolation of motion states.
    world->stepSimulation(h, 0, h);
    time += h;
  }

  void finish_step() {
    previous_pose = target_pose;
    kinematic_from = kinematic_to;
    write_back();
  }

  // Bone transforms from the target pose and the simulated bodies (see PhysicsWorld::bone_transforms).
  void write_back() {
    const size_t n = rig.bones.size();
    output.resize(n);
    std::vector<char> moved(n, 0);  // whether the bone's output differs from its animated transform
    for (int j : bone_order) {
      const int parent = rig.bones[j].parent;
      const int driver = bone_driver[j];
      const bool parent_moved = parent >= 0 && moved[parent];
      // A rigid map of the parent's animated frame onto its output frame, applied to follow the parent.
      auto follow_parent_position = [&]() -> Eigen::Vector3f {
        if (!parent_moved) return position_of(target_pose[j]);
        return rotation_of(output[parent]) * rotation_of(target_pose[parent]).transpose() *
                   (position_of(target_pose[j]) - position_of(target_pose[parent])) +
               position_of(output[parent]);
      };
      if (driver >= 0) {
        const RigidPose body = from_bt(bodies[driver]->getWorldTransform());
        const Eigen::Matrix3f R =
            (body.rotation * body_rest[driver].rotation.conjugate()).normalized().toRotationMatrix();
        Eigen::Vector3f t;
        if (rig.bodies[driver].mode == PhysicsMode::kDynamic) {
          t = body.position - R * (body_rest[driver].position - rig.bones[j].rest_position);
        } else {
          t = follow_parent_position();
        }
        output[j] = make_transform(R, t);
        moved[j] = 1;
      } else if (parent_moved) {
        const Eigen::Matrix3f R =
            rotation_of(output[parent]) * rotation_of(target_pose[parent]).transpose() * rotation_of(target_pose[j]);
        output[j] = make_transform(R, follow_parent_position());
        moved[j] = 1;
      } else {
        output[j] = target_pose[j];
      }
    }
  }
};

PhysicsWorld::PhysicsWorld(PhysicsRig rig, PhysicsSettings settings)
    : impl_(std::make_unique<Impl>(std::move(rig), settings)) {}

PhysicsWorld::~PhysicsWorld() = default;
PhysicsWorld::PhysicsWorld(PhysicsWorld&&) noexcept = default;
PhysicsWorld& PhysicsWorld::operator=(PhysicsWorld&&) noexcept = default;

const PhysicsRig& PhysicsWorld::rig() const {
  return impl_->rig;
}

const PhysicsSettings& PhysicsWorld::settings() const {
  return impl_->settings;
}

void PhysicsWorld::reset(const Transforms& pose) {
  impl_->check_pose(pose, "reset");
  impl_->rebuild(pose);
}

void PhysicsWorld::set_bone_pose(const Transforms& pose) {
  impl_->check_pose(pose, "set_bone_pose");
  impl_->set_target(pose);
}

void PhysicsWorld::step(float dt) {
  AMT_CHECK(std::isfinite(dt) && dt > 0, "physics: step: expected a positive duration in seconds, found ", dt);
  const PhysicsSettings& s = impl_->settings;
  // The small slack keeps dt = k * fixed_step (up to rounding) at k substeps.
  const double ratio = static_cast<double>(dt) / s.fixed_step;
  const int n = std::clamp(static_cast<int>(std::ceil(ratio - 1e-4)), 1, s.max_substeps);
  const float h = dt / static_cast<float>(n);
  for (int k = 1; k <= n; ++k) impl_->substep(h, k == n ? 1.0f : static_cast<float>(k) / static_cast<float>(n));
  impl_->finish_step();
}

void PhysicsWorld::settle(const Transforms& pose, float seconds) {
  impl_->check_pose(pose, "settle");
  AMT_CHECK(std::isfinite(seconds) && seconds >= 0, "physics: settle: expected a duration >= 0 seconds, found ",
            seconds);
  impl_->set_target(pose);
  impl_->previous_pose = pose;
  impl_->kinematic_from = impl_->kinematic_to;
  const int n = static_cast<int>(std::lround(seconds / impl_->settings.fixed_step));
  for (int k = 0; k < n; ++k) impl_->substep(impl_->settings.fixed_step, 1.0f);
  impl_->finish_step();
}

const Transforms& PhysicsWorld::bone_transforms() const {
  return impl_->output;
}

RigidPose PhysicsWorld::body_pose(int body) const {
  AMT_CHECK(body >= 0 && body < impl_->rig.num_bodies(), "physics: body_pose: expected a body index in [0, ",
            impl_->rig.num_bodies(), "), found ", body);
  return from_bt(impl_->bodies[body]->getWorldTransform());
}

Eigen::Vector3f PhysicsWorld::body_linear_velocity(int body) const {
  AMT_CHECK(body >= 0 && body < impl_->rig.num_bodies(), "physics: body_linear_velocity: expected a body index in [0, ",
            impl_->rig.num_bodies(), "), found ", body);
  return from_bt(impl_->bodies[body]->getLinearVelocity());
}

double PhysicsWorld::time() const {
  return impl_->time;
}

}  // namespace amt
