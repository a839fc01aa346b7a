#pragma once
// A tiny MMD-style humanoid for the PMX dataset and animate tests, in the file's frame and units (PmxFrame::kMmd),
// as an MMD artist rigs one: Japanese bone names (センター above 下半身 and 上半身, twist bone 左腕捩, a D bone
// 左ひざD that inherits 左ひざ's rotation and carries the shin), a box per body segment skinned BDEF1 to its bone,
// kinematic bodies on the head and upper body, and a three-bone hair chain behind the head on simulated bodies
// (modes 1, 1, 2) hung by spring 6-DOF joints. Proportions of canonical_skeleton() (1.7 m) at 0.08 m per unit.
#include <string>
#include <vector>

#include "data_tools/formats/pmx_import.h"
#include "data_tools/geometry/skeleton.h"

namespace amt::test {

namespace humanoid_detail {

inline PmxBone make_bone(const std::string& name, const Eigen::Vector3f& position, int parent) {
  PmxBone b;
  b.name = name;
  b.position = position;
  b.parent = parent;
  b.flags = kPmxBoneRotatable | kPmxBoneVisible | kPmxBoneEnabled;
  b.rotatable = b.visible = b.enabled = true;
  return b;
}

// Appends a box from a to b (half width h, PMX units) skinned to `bone`.
inline void add_box(PmxModel& m, std::vector<Eigen::Vector3f>& V, std::vector<int>& bone_of,
                    std::vector<Eigen::Vector3i>& F, const Eigen::Vector3f& a, const Eigen::Vector3f& b, float h,
                    int bone) {
  const Eigen::Vector3f lo = a.cwiseMin(b) - Eigen::Vector3f::Constant(h),
                        hi = a.cwiseMax(b) + Eigen::Vector3f::Constant(h);
  const int first = static_cast<int>(V.size());
  for (int k = 0; k < 8; ++k) {
    V.emplace_back(k & 1 ? hi.x() : lo.x(), k & 2 ? hi.y() : lo.y(), k & 4 ? hi.z() : lo.z());
    bone_of.push_back(bone);
  }
  // Outward-facing in MMD's left-handed frame is (a, c, b) in a right-handed one; either way a closed box.
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    F.emplace_back(first + q[0], first + q[1], first + q[2]);
    F.emplace_back(first + q[0], first + q[2], first + q[3]);
  }
  (void)m;
}

}  // namespace humanoid_detail

/// The humanoid (see the top of this file). Bones: 0 センター, 1 下半身, 2 上半身, 3 上半身2, 4 首, 5 頭,
/// 6-10 左肩 左腕 左腕捩 左ひじ 左手首, 11-15 the right side, 16-19 左足 左ひざ 左足首 左つま先, 20-23 the right side,
/// 24 左ひざD, 25-27 髪1 髪2 髪3 (hair, simulated). Bodies: 0 head (sphere, kinematic), 1 upper body (capsule,
/// kinematic), 2-4 hair (boxes on 髪1, 髪2 mode 1, 髪3 mode 2). Joints: head-hair1, hair1-hair2, hair2-hair3.
inline PmxModel pmx_humanoid(const std::string& source = "humanoid.pmx") {
  using humanoid_detail::add_box;
  using humanoid_detail::make_bone;
  const float s = 1.0f / kPmxMetresPerUnit;
  const Skeleton canonical = canonical_skeleton();
  auto at = [&](int j) {  // canonical joint j in MMD's frame and units
    const Eigen::Vector3f p = canonical.rest_joints.row(j).transpose();
    return Eigen::Vector3f(s * p.x(), s * p.y(), -s * p.z());
  };
  PmxModel m;
  m.source = source;
  m.header.name = "テスト人形";
  m.header.name_english = "test humanoid";
  std::vector<PmxBone>& B = m.bones;
  B.push_back(make_bone("センター", at(kPelvis) + Eigen::Vector3f(0, -0.5f, 0), -1));  // 0
  B.push_back(make_bone("下半身", at(kPelvis), 0));                                    // 1
  B.push_back(make_bone("上半身", at(kSpine1), 0));                                    // 2
  B.push_back(make_bone("上半身2", at(kSpine3), 2));                                   // 3
  B.push_back(make_bone("首", at(kNeck), 3));                                          // 4
  B.push_back(make_bone("頭", at(kHead), 4));                                          // 5
  for (const int side : {0, 1}) {                                                      // 6-10, 11-15
    const std::string p = side == 0 ? "左" : "右";
    const int collar = side == 0 ? kLeftCollar : kRightCollar, shoulder = side == 0 ? kLeftShoulder : kRightShoulder;
    const int elbow = side == 0 ? kLeftElbow : kRightElbow, wrist = side == 0 ? kLeftWrist : kRightWrist;
    const int base = static_cast<int>(B.size());
    B.push_back(make_bone(p + "肩", at(collar), 3));
    B.push_back(make_bone(p + "腕", at(shoulder), base));
    B.push_back(make_bone(p + "腕捩", 0.5f * (at(shoulder) + at(elbow)), base + 1));
    B.push_back(make_bone(p + "ひじ", at(elbow), base + 1));
    B.push_back(make_bone(p + "手首", at(wrist), base + 3));
  }
  for (const int side : {0, 1}) {  // 16-19, 20-23
    const std::string p = side == 0 ? "左" : "右";
    const int hip = side == 0 ? kLeftHip : kRightHip, knee = side == 0 ? kLeftKnee : kRightKnee;
    const int ankle = side == 0 ? kLeftAnkle : kRightAnkle, foot = side == 0 ? kLeftFoot : kRightFoot;
    const int base = static_cast<int>(B.size());
    B.push_back(make_bone(p + "足", at(hip), 1));
    B.push_back(make_bone(p + "ひざ", at(knee), base));
    B.push_back(make_bone(p + "足首", at(ankle), base + 1));
    B.push_back(make_bone(p + "つま先", at(foot), base + 2));
  }
  PmxBone knee_d = make_bone("左ひざD", at(kLeftKnee), 16);  // 24: takes 左ひざ's rotation, carries the shin
  knee_d.inherit_rotation = true;
  knee_d.flags |= kPmxBoneInheritRotation;
  knee_d.inherit_parent = 17;
  knee_d.inherit_weight = 1.0f;
  B.push_back(knee_d);
  const Eigen::Vector3f head = at(kHead);
  const Eigen::Vector3f hair[4] = {head + Eigen::Vector3f(0, 0.5f, 2.2f), head + Eigen::Vector3f(0, -2.0f, 2.2f),
                                   head + Eigen::Vector3f(0, -4.5f, 2.2f), head + Eigen::Vector3f(0, -7.0f, 2.2f)};
  B.push_back(make_bone("髪1", hair[0], 5));   // 25
  B.push_back(make_bone("髪2", hair[1], 25));  // 26
  B.push_back(make_bone("髪3", hair[2], 26));  // 27

  // Mesh: a box per segment.
  std::vector<Eigen::Vector3f> V;
  std::vector<int> bone_of;
  std::vector<Eigen::Vector3i> F;
  add_box(m, V, bone_of, F, at(kPelvis), 0.5f * (at(kPelvis) + at(kSpine1)), 1.3f, 1);
  add_box(m, V, bone_of, F, at(kSpine1), at(kNeck), 1.2f, 2);
  add_box(m, V, bone_of, F, at(kNeck), at(kHead), 0.5f, 4);
  add_box(m, V, bone_of, F, at(kHead), at(kHead) + Eigen::Vector3f(0, 2.0f, 0), 1.1f, 5);
  for (const int base : {6, 11}) {
    add_box(m, V, bone_of, F, B[base].position, B[base + 1].position, 0.4f, base);
    add_box(m, V, bone_of, F, B[base + 1].position, B[base + 2].position, 0.4f, base + 1);
    add_box(m, V, bone_of, F, B[base + 2].position, B[base + 3].position, 0.4f, base + 2);
    add_box(m, V, bone_of, F, B[base + 3].position, B[base + 4].position, 0.35f, base + 3);
  }
  for (const int base : {16, 20}) {
    add_box(m, V, bone_of, F, B[base].position, B[base + 1].position, 0.6f, base);
    add_box(m, V, bone_of, F, B[base + 1].position, B[base + 2].position, 0.5f, base == 16 ? 24 : base + 1);
    add_box(m, V, bone_of, F, B[base + 2].position, B[base + 3].position, 0.4f, base + 2);
  }
  add_box(m, V, bone_of, F, hair[0], hair[1], 0.3f, 25);
  add_box(m, V, bone_of, F, hair[1], hair[2], 0.3f, 26);
  add_box(m, V, bone_of, F, hair[2], hair[3], 0.3f, 27);

  const int n = static_cast<int>(V.size());
  PmxVertices& v = m.vertices;
  v.positions.resize(n, 3);
  v.normals.setZero(n, 3);
  v.normals.col(1).setOnes();
  v.uvs.setZero(n, 2);
  v.deform.assign(static_cast<size_t>(n), PmxDeform::kBdef1);
  v.bone_indices.setConstant(n, 4, -1);
  v.bone_weights.setZero(n, 4);
  v.sdef_c.setZero(n, 3);
  v.sdef_r0.setZero(n, 3);
  v.sdef_r1.setZero(n, 3);
  v.edge_scale.setOnes(n);
  for (int i = 0; i < n; ++i) {
    v.positions.row(i) = V[static_cast<size_t>(i)].transpose();
    v.bone_indices(i, 0) = bone_of[static_cast<size_t>(i)];
    v.bone_weights(i, 0) = 1.0f;
  }
  m.faces.resize(static_cast<Eigen::Index>(F.size()), 3);
  for (size_t f = 0; f < F.size(); ++f) m.faces.row(static_cast<Eigen::Index>(f)) = F[f].transpose();

  // Physics: kinematic head and upper body (group 0), hair on simulated boxes (group 1, not colliding with itself).
  auto body = [](const std::string& name, int bone, PmxShape shape, const Eigen::Vector3f& size,
                 const Eigen::Vector3f& position, PmxPhysicsMode mode, uint8_t group, uint16_t mask) {
    PmxRigidBody r;
    r.name = name;
    r.bone = bone;
    r.shape = shape;
    r.size = size;
    r.position = position;
    r.mass = 1.0f;
    r.linear_damping = 0.5f;
    r.angular_damping = 0.5f;
    r.friction = 0.5f;
    r.group = group;
    r.collision_mask = mask;
    r.mode = mode;
    return r;
  };
  const uint16_t not_hair = static_cast<uint16_t>(0xFFFF & ~(1 << 1));
  m.rigid_bodies.push_back(body("頭", 5, PmxShape::kSphere, Eigen::Vector3f(1.2f, 0, 0),
                                head + Eigen::Vector3f(0, 1.0f, 0), PmxPhysicsMode::kFollowBone, 0, 0xFFFF));
  m.rigid_bodies.push_back(body("上半身", 2, PmxShape::kCapsule, Eigen::Vector3f(1.6f, 2.5f, 0),
                                0.5f * (at(kSpine1) + at(kNeck)), PmxPhysicsMode::kFollowBone, 0, 0xFFFF));
  const PmxPhysicsMode modes[3] = {PmxPhysicsMode::kDynamic, PmxPhysicsMode::kDynamic,
                                   PmxPhysicsMode::kDynamicWithBonePosition};
  for (int k = 0; k < 3; ++k) {
    m.rigid_bodies.push_back(body("髪" + std::to_string(k + 1), 25 + k, PmxShape::kBox,
                                  Eigen::Vector3f(0.35f, 0.9f, 0.35f), 0.5f * (hair[k] + hair[k + 1]), modes[k], 1,
                                  not_hair));
  }
  for (int k = 0; k < 3; ++k) {
    PmxJoint j;
    j.name = "髪" + std::to_string(k + 1);
    j.rigid_body_a = k == 0 ? 0 : 1 + k;
    j.rigid_body_b = 2 + k;
    j.position = hair[k];
    j.angular_min = Eigen::Vector3f::Constant(-1.0f);
    j.angular_max = Eigen::Vector3f::Constant(1.0f);
    j.spring_angular = Eigen::Vector3f::Constant(20.0f);
    m.joints.push_back(j);
  }
  return m;
}

}  // namespace amt::test
