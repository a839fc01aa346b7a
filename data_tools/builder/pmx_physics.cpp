#include "data_tools/builder/pmx_physics.h"

#include <cmath>

#include "data_tools/geometry/error.h"

namespace amt {

std::vector<uint8_t> pmx_physics_driven_bones(const PmxModel& model, int* drivers) {
  const int B = static_cast<int>(model.bones.size());
  // 1: a simulated body drives the bone; -1: a body that follows its bone holds it; 0: no body names it.
  std::vector<int> held(static_cast<size_t>(B), 0);
  int simulated = 0;
  for (const PmxRigidBody& body : model.rigid_bodies) {
    if (body.bone < 0 || body.bone >= B) continue;
    if (body.mode == PmxPhysicsMode::kFollowBone) {
      if (held[body.bone] == 0) held[body.bone] = -1;
    } else {
      held[body.bone] = 1;
      ++simulated;
    }
  }
  if (drivers) *drivers = simulated;
  // A bone without a body of its own moves with its nearest ancestor that has one. Memoised walk up the parents
  // (parents may follow their children in the file; a cycle, which the reader rejects, would stop at B steps).
  std::vector<int> driven(static_cast<size_t>(B), -2);  // -2: not yet known
  for (int b = 0; b < B; ++b) {
    std::vector<int> path;
    int k = b, result = 0;
    for (int steps = 0; k >= 0 && k < B && steps <= B; ++steps) {
      if (driven[k] != -2) {
        result = driven[k];
        break;
      }
      path.push_back(k);
      if (held[k] != 0) {
        result = held[k] > 0 ? 1 : 0;
        break;
      }
      k = model.bones[k].parent;
    }
    for (const int p : path) driven[p] = held[p] != 0 ? (held[p] > 0 ? 1 : 0) : result;
  }
  return std::vector<uint8_t>(driven.begin(), driven.end());
}

std::vector<uint8_t> pmx_physics_apparel_mask(const PmxModel& model, int* drivers) {
  const int B = static_cast<int>(model.bones.size());
  const std::vector<uint8_t> driven = pmx_physics_driven_bones(model, drivers);
  const int N = model.vertices.size();
  std::vector<uint8_t> mask(static_cast<size_t>(N), 0);
  for (int i = 0; i < N; ++i) {
    for (int s = 0; s < 4; ++s) {
      const int bone = model.vertices.bone_indices(i, s);
      if (bone >= 0 && bone < B && model.vertices.bone_weights(i, s) > 0.0f && driven[bone] == 1) mask[i] = 1;
    }
  }
  return mask;
}

PhysicsRig pmx_physics_rig(const PmxModel& model) {
  AMT_CHECK(model.frame == PmxFrame::kMmd, model.source,
            ": pmx_physics_rig: expected a model in the file's frame (PMX units), found one converted to amt's");
  PhysicsRig rig;
  rig.bones.reserve(model.bones.size());
  for (const PmxBone& b : model.bones) rig.bones.push_back({b.name, b.parent, b.position});

  rig.bodies.reserve(model.rigid_bodies.size());
  for (const PmxRigidBody& r : model.rigid_bodies) {
    PhysicsBody body;
    body.name = r.name;
    body.bone = r.bone;
    body.shape = static_cast<PhysicsShape>(r.shape);  // same numbering: sphere 0, box 1, capsule 2
    body.size = r.size;
    body.rest.position = r.position;
    body.rest.rotation = Eigen::Quaternionf(pmx_euler_rotation(r.rotation)).normalized();
    body.rest_is_bone_local = false;
    body.mass = r.mass;
    body.linear_damping = r.linear_damping;
    body.angular_damping = r.angular_damping;
    body.friction = r.friction;
    body.restitution = r.restitution;
    body.group = r.group;
    body.non_collision_mask = static_cast<uint16_t>(~r.collision_mask & 0xFFFF);
    body.mode = static_cast<PhysicsMode>(r.mode);  // same numbering: follow bone 0, dynamic 1, rotation only 2
    rig.bodies.push_back(body);
  }

  for (size_t i = 0; i < model.joints.size(); ++i) {
    const PmxJoint& j = model.joints[i];
    if (j.rigid_body_a < 0 || j.rigid_body_b < 0) continue;
    AMT_CHECK(j.type == PmxJointType::kSpring6Dof, model.source, ": joints[", i, "] '", j.name,
              "': type: expected a spring 6-DOF joint (0), found type ", static_cast<int>(j.type),
              " (PMX 2.1 joint types are not simulated)");
    PhysicsJoint joint;
    joint.name = j.name;
    joint.body_a = j.rigid_body_a;
    joint.body_b = j.rigid_body_b;
    joint.rest.position = j.position;
    joint.rest.rotation = Eigen::Quaternionf(pmx_euler_rotation(j.rotation)).normalized();
    joint.linear_min = j.linear_min;
    joint.linear_max = j.linear_max;
    joint.angular_min = j.angular_min;
    joint.angular_max = j.angular_max;
    joint.linear_stiffness = j.spring_linear;
    joint.angular_stiffness = j.spring_angular;
    rig.joints.push_back(joint);
  }
  validate_physics_rig(rig, model.source);
  return rig;
}

PhysicsSettings pmx_physics_settings() {
  return mmd_physics_settings();
}

Transforms pmx_transforms_to_amt(const Transforms& transforms, float scale) {
  AMT_CHECK(std::isfinite(scale) && scale > 0, "pmx_transforms_to_amt: expected a finite scale > 0, found ", scale);
  const Eigen::Matrix3f S = Eigen::Vector3f(1, 1, -1).asDiagonal();
  Transforms out(transforms.size());
  for (size_t j = 0; j < transforms.size(); ++j) {
    const Eigen::Matrix3f R = transforms[j].leftCols<3>();
    out[j] = make_transform(S * R * S, scale * (S * transforms[j].col(3)));
  }
  return out;
}

}  // namespace amt
