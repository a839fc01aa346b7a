#include "data_tools/builder/mmd_pose.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

constexpr float kPi = 3.14159265358979f;

// Euler angles (x, y, z) of R = Rx(x) Ry(y) Rz(z).
Eigen::Vector3f euler_xyz(const Eigen::Matrix3f& R) {
  const float y = std::asin(std::clamp(R(0, 2), -1.0f, 1.0f));
  return {std::atan2(-R(1, 2), R(2, 2)), y, std::atan2(-R(0, 1), R(0, 0))};
}

Eigen::Quaternionf from_euler_xyz(const Eigen::Vector3f& e) {
  return Eigen::Quaternionf(Eigen::AngleAxisf(e.x(), Eigen::Vector3f::UnitX()) *
                            Eigen::AngleAxisf(e.y(), Eigen::Vector3f::UnitY()) *
                            Eigen::AngleAxisf(e.z(), Eigen::Vector3f::UnitZ()));
}

// The single axis a limited link may turn about (0 x, 1 y, 2 z: the other two ranges are [0, 0]), or -1.
int single_axis(const PmxIkLink& link) {
  int axis = -1;
  for (int a = 0; a < 3; ++a) {
    if (link.limit_min[a] == 0 && link.limit_max[a] == 0) continue;
    if (axis >= 0) return -1;
    axis = a;
  }
  return axis;
}

}  // namespace

// Per-bone state of one frame (saba's MMDNode).
struct MmdPoser::Bone {
  Eigen::Vector3f offset = Eigen::Vector3f::Zero();  // rest position relative to the parent's
  Eigen::Vector3f anim_t = Eigen::Vector3f::Zero();
  Eigen::Quaternionf anim_r = Eigen::Quaternionf::Identity();
  Eigen::Quaternionf ik_r = Eigen::Quaternionf::Identity();
  Eigen::Quaternionf append_r = Eigen::Quaternionf::Identity();
  Eigen::Vector3f append_t = Eigen::Vector3f::Zero();
  bool in_ik_chain = false;
  // Local and global transforms: rotation and translation.
  Eigen::Quaternionf local_r = Eigen::Quaternionf::Identity();
  Eigen::Vector3f local_t = Eigen::Vector3f::Zero();
  Eigen::Matrix3f global_R = Eigen::Matrix3f::Identity();
  Eigen::Vector3f global_t = Eigen::Vector3f::Zero();
};

MmdPoser::MmdPoser(const PmxModel& model) : model_(&model) {
  AMT_CHECK(model.frame == PmxFrame::kMmd, model.source,
            ": MMD pose: expected a model in the file's frame (PMX units), found one converted to amt's");
  const int B = static_cast<int>(model.bones.size());
  bones_.resize(size_t(B));
  children_.resize(size_t(B));
  for (int b = 0; b < B; ++b) {
    const PmxBone& bone = model.bones[size_t(b)];
    const bool has_parent = bone.parent >= 0 && bone.parent < B && bone.parent != b;
    bones_[size_t(b)].offset =
        bone.position - (has_parent ? model.bones[size_t(bone.parent)].position : Eigen::Vector3f::Zero());
    if (has_parent)
      children_[size_t(bone.parent)].push_back(b);
    else
      roots_.push_back(b);
    if (bone.is_ik) {
      for (const PmxIkLink& link : bone.ik.links)
        if (link.bone >= 0 && link.bone < B) bones_[size_t(link.bone)].in_ik_chain = true;
    }
  }
  order_.resize(size_t(B));
  for (int b = 0; b < B; ++b) order_[size_t(b)] = b;
  std::stable_sort(order_.begin(), order_.end(), [&](int a, int b) {
    const PmxBone &x = model.bones[size_t(a)], &y = model.bones[size_t(b)];
    if (x.physics_after_deform != y.physics_after_deform) return !x.physics_after_deform;
    return x.layer < y.layer;
  });
}

MmdPoser::~MmdPoser() = default;
MmdPoser::MmdPoser(MmdPoser&&) noexcept = default;
MmdPoser& MmdPoser::operator=(MmdPoser&&) noexcept = default;

void MmdPoser::update_local(int b) {
  Bone& s = bones_[size_t(b)];
  const PmxBone& bone = model_->bones[size_t(b)];
  s.local_t = s.offset + s.anim_t;
  if (bone.inherit_translation) s.local_t += s.append_t;
  s.local_r = s.ik_r * s.anim_r;
  if (bone.inherit_rotation) s.local_r = s.local_r * s.append_r;
  s.local_r.normalize();
}

// The bone's global transform from its parent's, then its subtree's.
void MmdPoser::update_global(int b) {
  std::vector<int> stack = {b};
  while (!stack.empty()) {
    const int k = stack.back();
    stack.pop_back();
    Bone& s = bones_[size_t(k)];
    const int p = model_->bones[size_t(k)].parent;
    const Eigen::Matrix3f R = s.local_r.toRotationMatrix();
    if (p >= 0 && p < int(bones_.size()) && p != k) {
      const Bone& parent = bones_[size_t(p)];
      s.global_R = parent.global_R * R;
      s.global_t = parent.global_R * s.local_t + parent.global_t;
    } else {
      s.global_R = R;
      s.global_t = s.local_t;
    }
    for (const int c : children_[size_t(k)]) stack.push_back(c);
  }
}

// Append (grant) motion, as saba's MMDNode::UpdateAppendTransform: the append parent's key rotation (or, when
// that bone has an append parent itself and the inheritance is not local, its append rotation), times its IK
// rotation, slerped from identity by the weight; its key translation (or its append translation) times the weight.
void MmdPoser::update_append(int b) {
  const PmxBone& bone = model_->bones[size_t(b)];
  const int a = bone.inherit_parent;
  if (a < 0 || a >= int(bones_.size()) || a == b) return;
  Bone& s = bones_[size_t(b)];
  const Bone& from = bones_[size_t(a)];
  const PmxBone& from_bone = model_->bones[size_t(a)];
  const bool chained = !bone.inherit_local && from_bone.inherit_parent >= 0 &&
                       from_bone.inherit_parent < int(bones_.size()) &&
                       (from_bone.inherit_rotation || from_bone.inherit_translation);
  if (bone.inherit_rotation) {
    Eigen::Quaternionf r = chained && from_bone.inherit_rotation ? from.append_r : from.anim_r;
    if (from.in_ik_chain) r = from.ik_r * r;
    s.append_r = Eigen::Quaternionf::Identity().slerp(bone.inherit_weight, r.normalized());
    // slerp takes the short way; a negative weight turns the other way.
    if (bone.inherit_weight < 0)
      s.append_r = Eigen::Quaternionf::Identity().slerp(-bone.inherit_weight, r.normalized()).conjugate();
  }
  if (bone.inherit_translation) {
    const Eigen::Vector3f t = chained && from_bone.inherit_translation ? from.append_t : from.anim_t;
    s.append_t = bone.inherit_weight * t;
  }
  update_local(b);
}

void MmdPoser::solve_ik(int b) {
  const PmxBone& bone = model_->bones[size_t(b)];
  const PmxIk& ik = bone.ik;
  const int B = static_cast<int>(bones_.size());
  if (ik.target < 0 || ik.target >= B || ik.links.empty()) return;
  struct Link {
    int bone;
    const PmxIkLink* spec;
    int axis;  // single rotation axis, or -1
    Eigen::Vector3f previous = Eigen::Vector3f::Zero();
    float plane_angle = 0;
    Eigen::Quaternionf saved = Eigen::Quaternionf::Identity();
  };
  std::vector<Link> links;
  for (const PmxIkLink& l : ik.links) {
    if (l.bone < 0 || l.bone >= B) continue;
    links.push_back({l.bone, &l, l.has_limits ? single_axis(l) : -1});
    bones_[size_t(l.bone)].ik_r = Eigen::Quaternionf::Identity();
    update_local(l.bone);
    update_global(l.bone);
  }
  const float limit = ik.limit_angle > 0 ? ik.limit_angle : kPi;
  const Bone& goal = bones_[size_t(b)];
  const Bone& effector = bones_[size_t(ik.target)];
  float best = std::numeric_limits<float>::max();
  const int iterations = std::clamp(ik.loop_count, 1, kMaxMmdIkIterations);
  for (int iteration = 0; iteration < iterations; ++iteration) {
    for (Link& link : links) {
      if (link.bone == ik.target) continue;
      Bone& s = bones_[size_t(link.bone)];
      // Goal and effector in the link's frame.
      const Eigen::Vector3f goal_local = s.global_R.transpose() * (goal.global_t - s.global_t);
      const Eigen::Vector3f effector_local = s.global_R.transpose() * (effector.global_t - s.global_t);
      if (goal_local.norm() < 1e-9f || effector_local.norm() < 1e-9f) continue;
      const Eigen::Vector3f to_goal = goal_local.normalized(), to_effector = effector_local.normalized();
      // atan2 rather than saba's acos of the dot product: acos loses the last millimetres in float (a dot product
      // of 1 - 1e-8 rounds to 1), which would stop the chain short of its goal.
      const float angle = std::min(std::atan2(to_effector.cross(to_goal).norm(), to_effector.dot(to_goal)), limit);
      if (link.axis >= 0) {
        // One axis (MMDIkSolver::SolvePlane): turn by +-angle about it, whichever brings the effector nearer.
        const Eigen::Vector3f axis = Eigen::Vector3f::Unit(link.axis);
        const float dot_plus = (Eigen::AngleAxisf(angle, axis) * to_effector).dot(to_goal);
        const float dot_minus = (Eigen::AngleAxisf(-angle, axis) * to_effector).dot(to_goal);
        float a = link.plane_angle + (dot_plus > dot_minus ? angle : -angle);
        const float lo = link.spec->limit_min[link.axis], hi = link.spec->limit_max[link.axis];
        if (iteration == 0 && (a < lo || a > hi)) {
          // Mirror a first step that leaves the range: a knee bends forwards, never backwards.
          if (-a > lo && -a < hi) {
            a = -a;
          } else {
            const float middle = 0.5f * (lo + hi);
            if (std::abs(middle - a) > std::abs(middle + a)) a = -a;
          }
        }
        a = std::clamp(a, lo, hi);
        link.plane_angle = a;
        s.ik_r = Eigen::Quaternionf(Eigen::AngleAxisf(a, axis)) * s.anim_r.conjugate();
      } else {
        if (angle * 180.0f / kPi < 1e-3f) continue;
        const Eigen::Vector3f cross = to_effector.cross(to_goal);
        if (cross.norm() < 1e-9f) continue;
        Eigen::Quaternionf turned =
            s.ik_r * s.anim_r * Eigen::Quaternionf(Eigen::AngleAxisf(angle, cross.normalized()));
        if (link.spec->has_limits) {
          Eigen::Vector3f e = euler_xyz(turned.normalized().toRotationMatrix());
          e = e.cwiseMax(link.spec->limit_min).cwiseMin(link.spec->limit_max);
          e = link.previous + (e - link.previous).cwiseMax(-limit).cwiseMin(limit);
          link.previous = e;
          turned = from_euler_xyz(e);
        }
        s.ik_r = (turned * s.anim_r.conjugate()).normalized();
      }
      update_local(link.bone);
      update_global(link.bone);
    }
    const float distance = (goal.global_t - effector.global_t).norm();
    if (distance < best) {
      best = distance;
      for (Link& link : links) link.saved = bones_[size_t(link.bone)].ik_r;
    } else {
      // Worse than the best iteration: restore it and stop (saba).
      for (Link& link : links) {
        bones_[size_t(link.bone)].ik_r = link.saved;
        update_local(link.bone);
      }
      for (Link& link : links) update_global(link.bone);
      break;
    }
  }
}

Transforms MmdPoser::pose(const std::vector<VmdBonePose>& local) {
  const int B = static_cast<int>(bones_.size());
  AMT_CHECK(int(local.size()) == B, model_->source, ": MMD pose: expected ", B, " bone poses, found ", local.size());
  for (int b = 0; b < B; ++b) {
    Bone& s = bones_[size_t(b)];
    s.anim_t = local[size_t(b)].translation;
    s.anim_r = local[size_t(b)].rotation.normalized();
    s.ik_r = s.append_r = Eigen::Quaternionf::Identity();
    s.append_t.setZero();
    update_local(b);
  }
  for (const int r : roots_) update_global(r);
  for (const int b : order_) {
    const PmxBone& bone = model_->bones[size_t(b)];
    if (bone.inherit_rotation || bone.inherit_translation) {
      update_append(b);
      update_global(b);
    }
    if (bone.is_ik) {
      solve_ik(b);
      update_global(b);
    }
  }
  for (const int r : roots_) update_global(r);
  Transforms out(size_t(B), Transform34::Zero());
  for (int b = 0; b < B; ++b) {
    out[size_t(b)].leftCols<3>() = bones_[size_t(b)].global_R;
    out[size_t(b)].col(3) = bones_[size_t(b)].global_t;
  }
  return out;
}

MmdBoneMotion mmd_bone_motion(const PmxModel& model, const VmdMotion& motion, const std::vector<int>& keep) {
  MmdPoser poser(model);
  const int B = static_cast<int>(model.bones.size());
  const std::map<std::string, std::vector<VmdBoneKey>> tracks = vmd_bone_tracks(motion);
  // Track of each bone: by its name, else by its name as the 15-byte field holds it.
  std::vector<const std::vector<VmdBoneKey>*> track_of(size_t(B), nullptr);
  std::map<std::string, bool> used;
  for (int b = 0; b < B; ++b) {
    const std::string& name = model.bones[size_t(b)].name;
    for (const std::string& key : {name, vmd_field_name(name)}) {
      const auto it = tracks.find(key);
      if (it == tracks.end() || used.count(key)) continue;
      track_of[size_t(b)] = &it->second;
      used[key] = true;
      break;
    }
  }
  MmdBoneMotion out;
  for (const auto* t : track_of) out.matched_bones += t != nullptr;
  for (const auto& [name, keys] : tracks) {
    if (!used.count(name)) out.unmatched_bones.push_back(name);
  }
  for (const VmdBoneKey& k : motion.bone_keys) out.unmatched_keys += used.count(k.bone) ? 0 : 1;
  AMT_CHECK(motion.last_frame() < uint32_t(kMaxMmdFrames), motion.source,
            ": bone keyframe frame: expected frame numbers below ", kMaxMmdFrames, " (",
            kMaxMmdFrames / int(kVmdFps) / 3600, " hours at 30 fps), found ", motion.last_frame());
  out.frames = static_cast<int>(motion.last_frame()) + 1;
  out.bones = keep;
  if (keep.empty()) {
    for (int b = 0; b < B; ++b) out.bones.push_back(b);
  }
  for (const int b : out.bones)
    AMT_CHECK(b >= 0 && b < B, model.source, ": bones: expected a bone index in [0, ", B, "), found ", b);
  out.globals.reserve(size_t(out.frames) * out.bones.size());
  std::vector<VmdBonePose> local(static_cast<size_t>(B));
  for (int t = 0; t < out.frames; ++t) {
    for (int b = 0; b < B; ++b)
      local[size_t(b)] = track_of[size_t(b)] ? vmd_sample(*track_of[size_t(b)], float(t)) : VmdBonePose{};
    const Transforms g = poser.pose(local);
    for (const int b : out.bones) out.globals.push_back(g[size_t(b)]);
  }
  return out;
}

}  // namespace amt
