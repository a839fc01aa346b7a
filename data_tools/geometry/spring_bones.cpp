#include "data_tools/geometry/spring_bones.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/Geometry>

#include "data_tools/geometry/error.h"

namespace amt {

namespace {

bool finite(const Eigen::Vector3f& v) {
  return v.allFinite();
}

// The skinning transform of a joint at world position q with world rotation R (rest rotations are the identity).
Transform34 placed(const Eigen::Matrix3f& R, const Eigen::Vector3f& q, const Eigen::Vector3f& rest) {
  return make_transform(R, q - R * rest);
}

// The skinning transforms of `pose` with every spring joint placed by `rotate(segment, parent transform, rest
// head)`, which returns the joint's world rotation, parents first; a joint below a spring is carried rigidly by it
// (with rest rotations the identity, it shares its parent's skinning transform).
template <typename Rotate>
Transforms walk(const Skeleton& skeleton, const std::vector<int>& segment_of_joint, const Transforms& pose,
                Rotate&& rotate) {
  const int J = skeleton.num_joints();
  AMT_CHECK(static_cast<int>(pose.size()) == J, "spring bones: pose: expected ", J, " transforms, found ", pose.size());
  Transforms M = pose;
  std::vector<uint8_t> moved(static_cast<size_t>(J), 0);
  for (int j = 0; j < J; ++j) {
    const int p = skeleton.parents[static_cast<size_t>(j)];
    const int s = segment_of_joint[static_cast<size_t>(j)];
    const bool moved_parent = p >= 0 && moved[static_cast<size_t>(p)];
    if (s < 0) {
      if (moved_parent) M[j] = M[p];
      moved[static_cast<size_t>(j)] = moved_parent;
      continue;
    }
    const Transform34 parent = p >= 0 ? M[p] : make_transform(Eigen::Matrix3f::Identity(), Eigen::Vector3f::Zero());
    const Eigen::Vector3f rest = skeleton.rest_joints.row(j).transpose();
    M[j] = placed(rotate(s, parent, rest), apply(parent, rest), rest);
    moved[static_cast<size_t>(j)] = 1;
  }
  return M;
}

}  // namespace

void turn_spring_rig(SpringRig& rig) {
  const Eigen::Vector3f flip(-1.0f, 1.0f, -1.0f);
  for (SpringJoint& j : rig.joints) {
    j.tail = j.tail.cwiseProduct(flip);
    j.gravity_dir = j.gravity_dir.cwiseProduct(flip);
  }
  for (SpringCollider& c : rig.colliders) {
    c.center = c.center.cwiseProduct(flip);
    c.tail = c.tail.cwiseProduct(flip);
  }
}

void validate_spring_rig(const SpringRig& rig, const Skeleton& skeleton, const std::string& source) {
  const int J = skeleton.num_joints();
  std::vector<uint8_t> seen(static_cast<size_t>(std::max(J, 0)), 0);
  for (int s = 0; s < rig.num_joints(); ++s) {
    const SpringJoint& j = rig.joints[static_cast<size_t>(s)];
    const std::string where = source + ": spring bone " + std::to_string(s);
    AMT_CHECK(j.joint >= 0 && j.joint < J, where, ": joint: expected an index in [0, ", J, "), found ", j.joint);
    const std::string name = where + " (" + skeleton.names[static_cast<size_t>(j.joint)] + ")";
    AMT_CHECK(!seen[static_cast<size_t>(j.joint)], name, ": expected each joint in one segment, found it twice");
    seen[static_cast<size_t>(j.joint)] = 1;
    AMT_CHECK(finite(j.tail) && finite(j.gravity_dir), name, ": expected a finite tail and gravity direction");
    const Eigen::Vector3f head = skeleton.rest_joints.row(j.joint).transpose();
    AMT_CHECK((j.tail - head).norm() > 1e-6f, name, ": expected a tail away from its head, found them at one point");
    AMT_CHECK(std::isfinite(j.stiffness) && j.stiffness >= 0.0f && j.stiffness < 1e4f, name,
              ": stiffness: expected a value in [0, 1e4), found ", j.stiffness);
    AMT_CHECK(std::isfinite(j.gravity_power) && j.gravity_power >= 0.0f && j.gravity_power < 1e4f, name,
              ": gravityPower: expected a value in [0, 1e4), found ", j.gravity_power);
    AMT_CHECK(std::isfinite(j.drag) && j.drag >= 0.0f && j.drag <= 1.0f, name,
              ": dragForce: expected a value in [0, 1], found ", j.drag);
    AMT_CHECK(std::isfinite(j.hit_radius) && j.hit_radius >= 0.0f && j.hit_radius < 100.0f, name,
              ": hitRadius: expected a value in [0, 100) metres, found ", j.hit_radius);
    AMT_CHECK(j.spring >= 0 && static_cast<size_t>(j.spring) < rig.spring_colliders.size(), name,
              ": spring: expected an index in [0, ", rig.spring_colliders.size(), "), found ", j.spring);
  }
  for (size_t c = 0; c < rig.colliders.size(); ++c) {
    const SpringCollider& k = rig.colliders[c];
    const std::string where = source + ": spring collider " + std::to_string(c);
    AMT_CHECK(k.joint >= 0 && k.joint < J, where, ": joint: expected an index in [0, ", J, "), found ", k.joint);
    AMT_CHECK(finite(k.center) && finite(k.tail) && std::isfinite(k.radius) && k.radius >= 0.0f && k.radius < 100.0f,
              where, ": expected a finite offset and a radius in [0, 100) metres, found radius ", k.radius);
  }
  for (size_t s = 0; s < rig.spring_colliders.size(); ++s) {
    for (const int c : rig.spring_colliders[s]) {
      AMT_CHECK(c >= 0 && static_cast<size_t>(c) < rig.colliders.size(), source, ": spring ", s,
                ": collider: expected an index in [0, ", rig.colliders.size(), "), found ", c);
    }
  }
}

SpringBoneSimulator::SpringBoneSimulator(Skeleton skeleton, SpringRig rig, double step_seconds)
    : skeleton_(std::move(skeleton)), rig_(std::move(rig)), step_seconds_(step_seconds) {
  AMT_CHECK(std::isfinite(step_seconds) && step_seconds > 0.0, "spring bones: step: expected seconds > 0, found ",
            step_seconds);
  validate_spring_rig(rig_, skeleton_, "spring bones");
  const int J = skeleton_.num_joints();
  for (int j = 0; j < J; ++j) {
    AMT_CHECK(skeleton_.parents[static_cast<size_t>(j)] < j, "spring bones: skeleton: expected parents before ",
              "children, found joint ", j, " under ", skeleton_.parents[static_cast<size_t>(j)]);
  }
  segment_of_joint_.assign(static_cast<size_t>(J), -1);
  for (int s = 0; s < rig_.num_joints(); ++s) segment_of_joint_[static_cast<size_t>(rig_.joints[s].joint)] = s;
  const size_t S = rig_.joints.size();
  current_.assign(S, Eigen::Vector3f::Zero());
  previous_.assign(S, Eigen::Vector3f::Zero());
  local_.assign(S, Eigen::Matrix3f::Identity());
}

Transforms SpringBoneSimulator::place(const Transforms& pose) const {
  return walk(skeleton_, segment_of_joint_, pose, [&](int s, const Transform34& parent, const Eigen::Vector3f&) {
    return Eigen::Matrix3f(parent.leftCols<3>() * local_[static_cast<size_t>(s)]);
  });
}

Transforms SpringBoneSimulator::reset(const Transforms& pose) {
  std::fill(local_.begin(), local_.end(), Eigen::Matrix3f::Identity());
  const Transforms M = place(pose);
  for (int s = 0; s < rig_.num_joints(); ++s) {
    const SpringJoint& sj = rig_.joints[static_cast<size_t>(s)];
    current_[s] = previous_[s] = apply(M[sj.joint], sj.tail);
  }
  last_pose_ = pose;
  steps_ = 0;
  frame_time_ = 0.0;
  return M;
}

Eigen::Vector3f SpringBoneSimulator::collide(int segment, Eigen::Vector3f tail, const Transforms& pose) const {
  const SpringJoint& sj = rig_.joints[static_cast<size_t>(segment)];
  for (const int c : rig_.spring_colliders[static_cast<size_t>(sj.spring)]) {
    const SpringCollider& k = rig_.colliders[static_cast<size_t>(c)];
    const Transform34& M = pose[k.joint];
    Eigen::Vector3f nearest = apply(M, k.center);
    if (k.capsule) {  // the nearest point of the capsule's axis
      const Eigen::Vector3f end = apply(M, k.tail), axis = end - nearest;
      const float length2 = axis.squaredNorm();
      if (length2 > 0.0f) nearest += std::clamp((tail - nearest).dot(axis) / length2, 0.0f, 1.0f) * axis;
    }
    const Eigen::Vector3f d = tail - nearest;
    const float distance = d.norm(), reach = k.radius + sj.hit_radius;
    if (distance < reach && distance > 1e-9f) tail = nearest + d * (reach / distance);
  }
  return tail;
}

void SpringBoneSimulator::step(const Transforms& pose, float dt) {
  walk(skeleton_, segment_of_joint_, pose, [&](int s, const Transform34& parent, const Eigen::Vector3f& rest) {
    const SpringJoint& sj = rig_.joints[static_cast<size_t>(s)];
    const Eigen::Matrix3f Rp = parent.leftCols<3>();
    const Eigen::Vector3f head = apply(parent, rest);
    const Eigen::Vector3f bone = sj.tail - rest;
    const float length = bone.norm();
    const Eigen::Vector3f axis = Rp * (bone / length);  // the rest direction under the parent
    Eigen::Vector3f& current = current_[static_cast<size_t>(s)];
    Eigen::Vector3f& previous = previous_[static_cast<size_t>(s)];
    // The specification's verlet step: inertia less drag, stiffness towards the rest direction, gravity.
    Eigen::Vector3f next = current + (current - previous) * (1.0f - sj.drag) + axis * (sj.stiffness * dt) +
                           sj.gravity_dir * (sj.gravity_power * dt);
    const auto keep_length = [&](const Eigen::Vector3f& tail) {
      const Eigen::Vector3f d = tail - head;
      const float n = d.norm();
      return n > 1e-9f ? Eigen::Vector3f(head + d * (length / n)) : Eigen::Vector3f(head + axis * length);
    };
    next = keep_length(collide(s, keep_length(next), pose));
    previous = current;
    current = next;
    const Eigen::Matrix3f R =
        Eigen::Quaternionf::FromTwoVectors(axis, (next - head).normalized()).toRotationMatrix() * Rp;
    local_[static_cast<size_t>(s)] = Rp.transpose() * R;
    return R;
  });
}

Transforms SpringBoneSimulator::advance(const Transforms& pose, double seconds) {
  AMT_CHECK(std::isfinite(seconds) && seconds > 0.0, "spring bones: advance: expected seconds > 0, found ", seconds);
  const int J = skeleton_.num_joints();
  AMT_CHECK(static_cast<int>(pose.size()) == J && last_pose_.size() == pose.size(), "spring bones: pose: expected ", J,
            " transforms after reset, found ", pose.size());
  const double target = frame_time_ + seconds;
  Transforms between(pose.size());
  while (static_cast<double>(steps_ + 1) * step_seconds_ <= target + 1e-9) {
    const float w = static_cast<float>((static_cast<double>(steps_ + 1) * step_seconds_ - frame_time_) / seconds);
    for (int j = 0; j < J; ++j) {
      const Eigen::Vector3f rest = skeleton_.rest_joints.row(j).transpose();
      const Transform34 &a = last_pose_[j], &b = pose[j];
      const Eigen::Quaternionf qa(Eigen::Matrix3f(a.leftCols<3>())), qb(Eigen::Matrix3f(b.leftCols<3>()));
      const Eigen::Vector3f at = (1.0f - w) * apply(a, rest) + w * apply(b, rest);
      between[j] = placed(qa.slerp(w, qb).toRotationMatrix(), at, rest);
    }
    step(between, static_cast<float>(step_seconds_));
    ++steps_;
  }
  frame_time_ = target;
  last_pose_ = pose;
  return place(pose);
}

MatrixXfR spring_response(const Skeleton& skeleton, const SpringRig& rig, const RigProbeOptions& probe) {
  SpringBoneSimulator simulator(skeleton, rig);  // validates the rig
  const int J = skeleton.num_joints();
  std::vector<uint8_t> simulated(static_cast<size_t>(J), 0);
  for (const SpringJoint& s : rig.joints) simulated[static_cast<size_t>(s.joint)] = 1;
  simulator.reset(Transforms(static_cast<size_t>(J), Transform34::Identity()));
  return probe_response(skeleton.rest_joints, skeleton.parents, simulated, probe.amplitude_metres, probe,
                        [&](const Transforms& pose, float seconds) { return simulator.advance(pose, seconds); });
}

}  // namespace amt
