#include "data_tools/formats/canonical_rest.h"

#include <algorithm>
#include <sstream>

#include "data_tools/geometry/error.h"

namespace amt {

namespace {

const char* kind_name(JointMatchKind kind) {
  switch (kind) {
    case JointMatchKind::kUserMap:
      return "joint map";
    case JointMatchKind::kNameTable:
      return "name";
    case JointMatchKind::kStructure:
      return "structure";
  }
  return "?";
}

// The first canonical child of j, in canonical order, or -1 for a leaf.
int first_child(int j) {
  const auto& parents = canonical_joint_parents();
  for (int c = j + 1; c < kCanonicalJointCount; ++c) {
    if (parents[size_t(c)] == j) return c;
  }
  return -1;
}

}  // namespace

// === Canonical rest skeleton

std::vector<int> place_missing_joints(MatrixX3f& rest_joints, const JointMapping& mapping) {
  const auto& cparents = canonical_joint_parents();
  const MatrixX3f reference = canonical_skeleton().rest_joints;  // canonical proportions, for leaves
  std::vector<bool> placed(kCanonicalJointCount, false);
  for (int j = 1; j < kCanonicalJointCount; ++j) {
    placed[size_t(j)] = mapping.source_joint[size_t(j)] == mapping.source_joint[size_t(cparents[size_t(j)])];
  }
  // Placed joints come in chains (spine1..spine3 on the pelvis's joint); place each chain evenly between
  // its mapped ancestor and its first mapped descendant along first children.
  for (int j = 1; j < kCanonicalJointCount; ++j) {
    if (!placed[size_t(j)] || placed[size_t(cparents[size_t(j)])]) continue;  // chain starts only
    const int anchor = cparents[size_t(j)];
    std::vector<int> chain = {j};
    int next = first_child(j);
    while (next >= 0 && placed[size_t(next)]) chain.push_back(next), next = first_child(next);
    const Eigen::Vector3f a = rest_joints.row(anchor).transpose();
    if (next >= 0) {
      const Eigen::Vector3f d = rest_joints.row(next).transpose();
      for (size_t k = 0; k < chain.size(); ++k) {
        const float s = float(k + 1) / float(chain.size() + 1);
        rest_joints.row(chain[k]) = (a + s * (d - a)).transpose();
      }
    } else {
      // A leaf chain (the foot on its ankle): continue the canonical bones, scaled like the parent bone.
      const int grand = cparents[size_t(anchor)];
      float scale = 1.0f;
      if (grand >= 0) {
        const float here = (rest_joints.row(anchor) - rest_joints.row(grand)).norm();
        const float there = (reference.row(anchor) - reference.row(grand)).norm();
        if (there > 1e-6f && here > 1e-6f) scale = here / there;
      }
      Eigen::Vector3f p = a;
      int previous = anchor;
      for (int c : chain) {
        p += scale * (reference.row(c) - reference.row(previous)).transpose();
        rest_joints.row(c) = p.transpose();
        previous = c;
      }
    }
  }
  std::vector<int> out;
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    if (placed[size_t(j)]) out.push_back(j);
  }
  return out;
}

CanonicalRest canonical_rest(const Skeleton& file, const std::optional<JointMapFile>& user_map,
                             const std::string& source) {
  CanonicalRest out;
  std::vector<int> parents(file.parents.begin(), file.parents.end());
  try {
    out.mapping = map_to_canonical(file.names, parents, user_map, source);
  } catch (const Error& e) {
    std::string message = e.what();
    if (message.find("--joint-map") != std::string::npos &&
        message.find("--character-joint-map") == std::string::npos) {
      message += " (for a character: --character-joint-map FILE)";
    }
    throw Error(message);
  }
  out.skeleton = canonical_skeleton();
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    out.skeleton.rest_joints.row(j) = file.rest_joints.row(out.mapping.source_joint[size_t(j)]);
  }
  out.placed = place_missing_joints(out.skeleton.rest_joints, out.mapping);
  std::vector<bool> placed(kCanonicalJointCount, false);
  for (int j : out.placed) placed[size_t(j)] = true;
  // Carriers of the file joints: the deepest canonical joint mapped to it, else the nearest mapped ancestor's.
  const int M = file.num_joints();
  std::vector<int> own(size_t(M), -1);
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    if (!placed[size_t(j)]) own[size_t(out.mapping.source_joint[size_t(j)])] = j;
  }
  out.carrier.assign(size_t(M), 0);
  for (int i = 0; i < M; ++i) {
    int k = i, steps = 0;
    while (k >= 0 && own[size_t(k)] < 0 && steps++ <= M) k = file.parents[size_t(k)];
    out.carrier[size_t(i)] = k >= 0 && own[size_t(k)] >= 0 ? own[size_t(k)] : 0;
    if (own[size_t(i)] < 0) out.extra.push_back(file.names[size_t(i)]);
  }
  return out;
}

std::string CanonicalRest::describe(const std::vector<std::string>& file_names) const {
  std::ostringstream s;
  const auto& names = canonical_joint_names();
  s << "joint mapping (" << (mapping.convention.empty() ? "user map" : mapping.convention) << "):";
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    const bool is_placed = std::find(placed.begin(), placed.end(), j) != placed.end();
    s << (j % 4 == 0 ? "\n  " : ", ") << names[size_t(j)] << " <- ";
    if (is_placed) {
      s << "(placed)";
    } else {
      s << file_names[size_t(mapping.source_joint[size_t(j)])] << " [" << kind_name(mapping.kind[size_t(j)]) << "]";
    }
  }
  if (!placed.empty()) {
    s << "\n  placed between mapped neighbours:";
    for (int j : placed) s << " " << names[size_t(j)];
  }
  if (!extra.empty()) {
    s << "\n  " << extra.size() << " extra joints carried by their mapped parents:";
    for (size_t k = 0; k < extra.size() && k < 12; ++k) s << " " << extra[k];
    if (extra.size() > 12) s << " ...";
  }
  return s.str();
}

}  // namespace amt
