#pragma once
// Skeletons: joint names, parents and rest positions; the canonical 22-joint body skeleton
// (docs/architecture.md, "The data model") that every motion and character is mapped onto.
#include <string>
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

// === Skeleton

/// A joint hierarchy at rest. Joints are in topological order: parents[j] < j, the root has -1.
/// rest_joints #J by 3 global rest positions (metres). Rest orientations are identity by
/// convention: every rotation in the project is relative to the rest pose.
struct Skeleton {
  std::vector<std::string> names;
  std::vector<int32_t> parents;
  MatrixX3f rest_joints;

  int num_joints() const { return static_cast<int>(names.size()); }
  /// Index of the joint called `name`, or -1.
  int index_of(const std::string& name) const;
  /// Children of every joint, in joint order.
  std::vector<std::vector<int>> children() const;
};

/// Throws amt::Error unless names, parents and rest_joints agree in size, parents are topological
/// (-1 for joint 0 only, parents[j] < j otherwise), names are unique and positions finite.
void validate_skeleton(const Skeleton& skeleton, const std::string& source);

// === The canonical skeleton

/// Number of canonical body joints (the 22 SMPL body joints).
constexpr int kCanonicalJointCount = 22;

/// Canonical joint indices, in the order of docs/characters.md, "Conventions".
enum CanonicalJoint : int {
  kPelvis, kLeftHip, kRightHip, kSpine1, kLeftKnee, kRightKnee, kSpine2, kLeftAnkle, kRightAnkle, kSpine3,
  kLeftFoot, kRightFoot, kNeck, kLeftCollar, kRightCollar, kHead, kLeftShoulder, kRightShoulder, kLeftElbow,
  kRightElbow, kLeftWrist, kRightWrist
};

/// The 22 canonical joint names ("pelvis", "left_hip", ...).
const std::vector<std::string>& canonical_joint_names();

/// Parents of the canonical joints (SMPL's kinematic tree).
const std::vector<int32_t>& canonical_joint_parents();

/// The canonical skeleton in a T-pose: a 1.7 m adult, feet on y = 0, facing +Z, its left on +X.
Skeleton canonical_skeleton();

/// True when the skeleton has exactly the canonical names and parents, in canonical order.
bool is_canonical(const Skeleton& skeleton);

}  // namespace amt
