#include "data_tools/builder/apparel_simulation.h"

#include <cmath>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/skeleton.h"

namespace amt {

Transforms rig_skinning_matrices(const PhysicsRig& rig, const Transforms& pose) {
  AMT_CHECK(pose.size() == rig.bones.size(), "rig_skinning_matrices: expected ", rig.bones.size(),
            " bone transforms, found ", pose.size());
  Transforms M(pose.size());
  for (size_t b = 0; b < pose.size(); ++b) {
    const Eigen::Matrix3f R = pose[b].leftCols<3>();
    M[b] = make_transform(R, pose[b].col(3) - R * rig.bones[b].rest_position);
  }
  return M;
}

ApparelSimulator::ApparelSimulator(const DressedCharacter& character, PhysicsSettings settings)
    : world_(character.rig, settings) {
  const PhysicsRig& rig = world_.rig();
  AMT_CHECK(rig.num_bones() >= kCanonicalJointCount, "ApparelSimulator: expected a rig with the ",
            kCanonicalJointCount, " canonical bones first, found ", rig.num_bones(), " bones");
  for (int b = 0; b < rig.num_bones(); ++b) {
    const int parent = rig.bones[b].parent;
    // Apparel bones must come after their parents so that rigid_pose can place them in one pass.
    AMT_CHECK(parent < b, "ApparelSimulator: bone ", b, " '", rig.bones[b].name,
              "': expected its parent before it, found parent ", parent);
    parents_.push_back(parent);
    rest_.push_back(rig.bones[b].rest_position);
  }
  pose_ = physics_rest_pose(rig);
  skinning_ = rig_skinning_matrices(rig, pose_);
}

void ApparelSimulator::check_body_pose(const Transforms& body_pose, const char* what) const {
  AMT_CHECK(body_pose.size() == static_cast<size_t>(kCanonicalJointCount), "ApparelSimulator: ", what, ": expected ",
            kCanonicalJointCount, " joint transforms, found ", body_pose.size());
  for (size_t j = 0; j < body_pose.size(); ++j)
    AMT_CHECK(body_pose[j].allFinite(), "ApparelSimulator: ", what, ": joint ", j,
              ": expected a finite transform, found NaN or infinity");
}

Transforms ApparelSimulator::rigid_pose(const Transforms& body_pose) const {
  check_body_pose(body_pose, "rigid_pose");
  Transforms pose(rest_.size());
  for (size_t b = 0; b < rest_.size(); ++b) {
    if (b < static_cast<size_t>(kCanonicalJointCount)) {
      pose[b] = body_pose[b];
      continue;
    }
    const Transform34& P = pose[static_cast<size_t>(parents_[b])];
    const Eigen::Matrix3f R = P.leftCols<3>();
    pose[b] = make_transform(R, R * (rest_[b] - rest_[static_cast<size_t>(parents_[b])]) + P.col(3));
  }
  return pose;
}

void ApparelSimulator::start(const Transforms& body_pose, float settle_seconds) {
  AMT_CHECK(std::isfinite(settle_seconds) && settle_seconds >= 0,
            "ApparelSimulator: start: settle_seconds: expected a duration >= 0, found ", settle_seconds);
  pose_ = rigid_pose(body_pose);
  world_.reset(pose_);
  if (settle_seconds > 0) world_.settle(pose_, settle_seconds);
  update_skinning();
}

const Transforms& ApparelSimulator::step(const Transforms& body_pose, float dt) {
  pose_ = rigid_pose(body_pose);
  world_.set_bone_pose(pose_);
  world_.step(dt);
  update_skinning();
  return skinning_;
}

const Transforms& ApparelSimulator::bone_transforms() const {
  return world_.bone_transforms();
}

void ApparelSimulator::update_skinning() {
  const Transforms& T = world_.bone_transforms();
  skinning_.resize(T.size());
  for (size_t b = 0; b < T.size(); ++b) {
    const Eigen::Matrix3f R = T[b].leftCols<3>();
    skinning_[b] = make_transform(R, T[b].col(3) - R * rest_[b]);
  }
}

}  // namespace amt
