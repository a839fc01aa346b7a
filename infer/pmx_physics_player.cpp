#include "infer/pmx_physics_player.h"

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/motion.h"
#include "infer/motion_input.h"

namespace amt {

Transforms lead_in_pose(const Skeleton& skeleton, const Transforms& first, int k, int n) {
  AMT_CHECK(n >= 1 && k >= 0 && k < n, "lead-in: expected pose k in [0, n) with n >= 1, found k = ", k, ", n = ", n);
  Motion m = motion_from_joint_transforms(skeleton, first, 30.0f);
  const float w = lead_in_weight(k, n);
  for (Eigen::Quaternionf& q : m.local_rotations) q = Eigen::Quaternionf::Identity().slerp(w, q).normalized();
  m.root_translation *= w;
  return forward_kinematics(skeleton, m, 0);
}

namespace {

PmxCharacter load_simulated(const std::string& path, const std::optional<JointMapFile>& joint_map) {
  PmxCharacter c = load_pmx_character(path, joint_map);
  AMT_CHECK(c.simulated_bodies > 0, path, ": --apparel physics: expected a PMX model with simulated rigid bodies ",
            "(modes 1 and 2) on its bones, found ", c.model.rigid_bodies.size(),
            " rigid bodies and none simulated; use --apparel learned");
  return c;
}

}  // namespace

PmxPhysicsPlayer::PmxPhysicsPlayer(const std::string& path, const std::optional<JointMapFile>& joint_map,
                                   const PmxSimulationOptions& options)
    : character_(load_simulated(path, joint_map)), simulator_(character_, options) {}

void PmxPhysicsPlayer::start(const Transforms& first, int lead_in) {
  const Skeleton& skeleton = character_.skeleton();
  simulator_.start(forward_kinematics(skeleton, rest_motion(skeleton, 1), 0));
  for (int k = 0; k < lead_in; ++k) simulator_.step(lead_in_pose(skeleton, first, k, lead_in));
}

void PmxPhysicsPlayer::step(const Transforms& canonical, MatrixX3f& V) {
  advance(canonical);
  skin(V);
}

void PmxPhysicsPlayer::advance(const Transforms& canonical) {
  simulator_.step(canonical);
}

void PmxPhysicsPlayer::skin(MatrixX3f& V) const {
  linear_blend_skinning(character_.mesh.V, character_.skin, simulator_.skinning(), V);
}

}  // namespace amt
