#include "data_tools/geometry/skeleton.h"

#include <unordered_set>

#include "data_tools/geometry/error.h"

namespace amt {

int Skeleton::index_of(const std::string& name) const {
  for (int j = 0; j < num_joints(); ++j) {
    if (names[j] == name) return j;
  }
  return -1;
}

std::vector<std::vector<int>> Skeleton::children() const {
  std::vector<std::vector<int>> out(names.size());
  for (int j = 0; j < num_joints(); ++j) {
    if (parents[j] >= 0) out[parents[j]].push_back(j);
  }
  return out;
}

void validate_skeleton(const Skeleton& s, const std::string& source) {
  const size_t J = s.names.size();
  AMT_CHECK(J > 0, source, ": skeleton: expected at least 1 joint, found none");
  AMT_CHECK(s.parents.size() == J, source, ": joint_parents: expected ", J, " entries (one per joint name), found ",
            s.parents.size());
  AMT_CHECK(static_cast<size_t>(s.rest_joints.rows()) == J, source, ": rest_joints: expected (", J,
            ", 3) (one row per joint name), found (", s.rest_joints.rows(), ", 3)");
  std::unordered_set<std::string> seen;
  for (size_t j = 0; j < J; ++j) {
    AMT_CHECK(seen.insert(s.names[j]).second, source, ": skeleton: joint name '", s.names[j], "' appears twice");
    const int p = s.parents[j];
    if (j == 0) {
      AMT_CHECK(p == -1, source, ": joint_parents: expected -1 for the root joint 0, found ", p);
    } else {
      AMT_CHECK(p >= 0 && p < static_cast<int>(j), source, ": joint_parents: expected a parent in [0, ", j,
                ") for joint ", j, " ('", s.names[j], "'), found ", p);
    }
    AMT_CHECK(s.rest_joints.row(static_cast<Eigen::Index>(j)).allFinite(), source,
              ": rest_joints: expected finite values, found a NaN or infinity at joint ", j);
  }
}

const std::vector<std::string>& canonical_joint_names() {
  static const std::vector<std::string> names = {
      "pelvis",       "left_hip",      "right_hip",      "spine1",     "left_knee",   "right_knee",
      "spine2",       "left_ankle",    "right_ankle",    "spine3",     "left_foot",   "right_foot",
      "neck",         "left_collar",   "right_collar",   "head",       "left_shoulder", "right_shoulder",
      "left_elbow",   "right_elbow",   "left_wrist",     "right_wrist"};
  return names;
}

const std::vector<int32_t>& canonical_joint_parents() {
  static const std::vector<int32_t> parents = {-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19};
  return parents;
}

Skeleton canonical_skeleton() {
  Skeleton s;
  s.names = canonical_joint_names();
  s.parents = canonical_joint_parents();
  s.rest_joints.resize(kCanonicalJointCount, 3);
  // Proportions of an average 1.7 m adult in a T-pose (SMPL-like), left side on +X.
  const float rows[kCanonicalJointCount][3] = {
      {0.00f, 0.95f, 0.00f},   // pelvis
      {0.09f, 0.88f, 0.00f},   // left_hip
      {-0.09f, 0.88f, 0.00f},  // right_hip
      {0.00f, 1.06f, -0.01f},  // spine1
      {0.10f, 0.50f, 0.01f},   // left_knee
      {-0.10f, 0.50f, 0.01f},  // right_knee
      {0.00f, 1.19f, -0.01f},  // spine2
      {0.10f, 0.08f, -0.03f},  // left_ankle
      {-0.10f, 0.08f, -0.03f}, // right_ankle
      {0.00f, 1.25f, 0.00f},   // spine3
      {0.11f, 0.02f, 0.10f},   // left_foot
      {-0.11f, 0.02f, 0.10f},  // right_foot
      {0.00f, 1.47f, -0.01f},  // neck
      {0.07f, 1.39f, -0.01f},  // left_collar
      {-0.07f, 1.39f, -0.01f}, // right_collar
      {0.00f, 1.57f, 0.03f},   // head
      {0.18f, 1.42f, -0.02f},  // left_shoulder
      {-0.18f, 1.42f, -0.02f}, // right_shoulder
      {0.44f, 1.42f, -0.02f},  // left_elbow
      {-0.44f, 1.42f, -0.02f}, // right_elbow
      {0.69f, 1.42f, -0.01f},  // left_wrist
      {-0.69f, 1.42f, -0.01f}, // right_wrist
  };
  for (int j = 0; j < kCanonicalJointCount; ++j) s.rest_joints.row(j) << rows[j][0], rows[j][1], rows[j][2];
  return s;
}

bool is_canonical(const Skeleton& s) {
  return s.names == canonical_joint_names() && s.parents == canonical_joint_parents();
}

}  // namespace amt
