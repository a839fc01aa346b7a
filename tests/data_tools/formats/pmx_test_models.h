#pragma once
// A PMX model exercising every field a PmxModel holds, and a field-by-field comparison of two models: shared by the
// PMX reader's and writer's tests (pmx_import_test.cpp, pmx_export_test.cpp).
#include <gtest/gtest.h>

#include <iterator>
#include <string>

#include "data_tools/formats/pmx_import.h"

namespace amt::test {

// === A sample model exercising every field

// Flag booleans from the raw bits, decoded here independently of the reader.
inline void set_flag_booleans(PmxBone& b) {
  const uint16_t f = b.flags;
  b.tail_is_bone = f & 0x0001;
  b.rotatable = f & 0x0002;
  b.translatable = f & 0x0004;
  b.visible = f & 0x0008;
  b.enabled = f & 0x0010;
  b.is_ik = f & 0x0020;
  b.inherit_local = f & 0x0080;
  b.inherit_rotation = f & 0x0100;
  b.inherit_translation = f & 0x0200;
  b.has_fixed_axis = f & 0x0400;
  b.has_local_axes = f & 0x0800;
  b.physics_after_deform = f & 0x1000;
  b.has_external_parent = f & 0x2000;
}

inline PmxBone bone(const std::string& name, const std::string& english, Eigen::Vector3f position, int32_t parent,
                    uint16_t flags) {
  PmxBone b;
  b.name = name;
  b.name_english = english;
  b.position = position;
  b.parent = parent;
  b.flags = flags;
  set_flag_booleans(b);
  return b;
}

// Six vertices (BDEF1, BDEF2, BDEF4, SDEF, unnormalised BDEF4, and QDEF in 2.1 or a BDEF2 with a repeated bone in
// 2.0), four faces, five bones (IK, inheritance, fixed and local axes, external parent, tails by index and offset),
// three rigid bodies (sphere, box, capsule) and two joints. `extra_vertices` BDEF1 vertices are appended.
inline PmxModel sample_model(bool v21, int extra_vertices = 0) {
  PmxModel m;
  m.source = "model.pmx";
  m.header.version = v21 ? 2.1f : 2.0f;
  m.header.name = "テストモデル";
  m.header.name_english = "test model";
  m.header.comment = "コメント 😀 (MIT)";  // U+1F600: a surrogate pair in UTF-16
  m.header.comment_english = "comment";
  m.header.additional_uv_count = 1;

  const int n = 6 + extra_vertices;
  PmxVertices& v = m.vertices;
  v.resize(n, 1);
  for (int i = 0; i < n; ++i) {
    // The extra vertices repeat every 1000 so that 40000 of them stay within the importers'
    // plausibility bound (data_tools/geometry/mesh.h).
    const float t = static_cast<float>(i % 1000);
    v.positions.row(i) << 0.1f * t - 0.3f, 10 + 0.5f * t, 0.2f * t - 0.7f;
    v.normals.row(i) = Eigen::RowVector3f(0.3f, 0.4f, t - 2.5f).normalized();
    v.uvs.row(i) << 0.1f * t, 1 - 0.05f * t;
    v.additional_uvs[0].row(i) << t, 2 * t, -t, 0.5f;
    v.bone_indices(i, 0) = 0;
    v.bone_weights(i, 0) = 1;
    v.edge_scale[i] = 1 + 0.125f * t;
  }
  v.deform[1] = PmxDeform::kBdef2;
  v.bone_indices.row(1) << 1, 2, -1, -1;
  v.bone_weights.row(1) << 0.25f, 0.75f, 0, 0;
  v.deform[2] = PmxDeform::kBdef4;
  v.bone_indices.row(2) << 0, 1, 2, -1;
  v.bone_weights.row(2) << 0.5f, 0.3f, 0.2f, 0;
  v.deform[3] = PmxDeform::kSdef;
  v.bone_indices.row(3) << 2, 3, -1, -1;
  v.bone_weights.row(3) << 0.6f, 1 - 0.6f, 0, 0;
  v.sdef_c.row(3) << 0.1f, 11.5f, -0.2f;
  v.sdef_r0.row(3) << 0.2f, 11.4f, -0.1f;
  v.sdef_r1.row(3) << 0.0f, 11.6f, -0.3f;
  v.deform[4] = PmxDeform::kBdef4;
  v.bone_indices.row(4) << 3, 4, 0, 0;
  v.bone_weights.row(4) << 2, 2, 0, 0;
  if (v21) {
    v.deform[5] = PmxDeform::kQdef;
    v.bone_indices.row(5) << 1, 2, 3, 4;
    v.bone_weights.row(5) << 0.1f, 0.2f, 0.3f, 0.4f;
  } else {
    v.deform[5] = PmxDeform::kBdef2;
    v.bone_indices.row(5) << 3, 3, -1, -1;
    v.bone_weights.row(5) << 0.4f, 1 - 0.4f, 0, 0;
  }
  m.faces.resize(4 + extra_vertices / 3, 3);
  m.faces.topRows<4>() << 0, 1, 2, 2, 3, 4, 3, 4, 5, 5, 0, 1;
  for (int f = 4; f < m.faces.rows(); ++f) m.faces.row(f) << n - 3 * (f - 3), n - 3 * (f - 3) + 1, n - 3 * (f - 3) + 2;

  m.bones.push_back(bone("センター", "center", {0, 8, 0}, -1, 0x001E));
  m.bones.back().tail_offset = {0, 1, 0};
  m.bones.push_back(bone("上半身", "upper body", {0, 10, 0.5f}, 0, 0x001B));
  m.bones.back().tail_bone = 2;
  m.bones.back().layer = 1;
  m.bones.push_back(bone("左腕", "left arm", {1, 12, 0.25f}, 1, 0x0D1A));
  m.bones.back().tail_offset = {1, -0.5f, 0};
  m.bones.back().inherit_parent = 1;
  m.bones.back().inherit_weight = -0.5f;
  m.bones.back().fixed_axis = {0.6f, 0, -0.8f};
  m.bones.back().local_axis_x = {1, 0, 0};
  m.bones.back().local_axis_z = {0, 0.6f, 0.8f};
  m.bones.push_back(bone("左ひじ", "left elbow", {2, 11, 0.25f}, 2, 0x329B));
  m.bones.back().tail_bone = 4;  // a tail may point past the bone itself
  m.bones.back().inherit_parent = -1;
  m.bones.back().inherit_weight = 1;
  m.bones.back().external_parent_key = 7;
  m.bones.push_back(bone("左腕ＩＫ", "left arm IK", {3, 10, 0.25f}, 0, 0x003E));
  m.bones.back().tail_offset = {0, 0, 1};
  m.bones.back().layer = 2;
  m.bones.back().ik.target = 3;
  m.bones.back().ik.loop_count = 40;
  m.bones.back().ik.limit_angle = 0.5f;
  PmxIkLink link;
  link.bone = 2;
  link.has_limits = true;
  link.limit_min = {-1, -0.5f, 0};
  link.limit_max = {0.2f, 0.5f, 1};
  m.bones.back().ik.links.push_back(link);
  link = PmxIkLink();
  link.bone = 1;
  m.bones.back().ik.links.push_back(link);

  PmxRigidBody r;
  r.name = "頭";
  r.name_english = "head";
  r.bone = 0;
  r.group = 0;
  r.collision_mask = 0xFFFE;
  r.shape = PmxShape::kSphere;
  r.size = {0.9f, 0, 0};
  r.position = {0, 14, 0.1f};
  r.rotation = {0, 0, 0};
  r.mass = 0;
  r.linear_damping = 0.9f;
  r.angular_damping = 0.95f;
  r.restitution = 0;
  r.friction = 0.5f;
  r.mode = PmxPhysicsMode::kFollowBone;
  m.rigid_bodies.push_back(r);
  r.name = "スカート前";
  r.name_english = "skirt front";
  r.bone = 2;
  r.group = 5;
  r.collision_mask = 0xFFDF;
  r.shape = PmxShape::kBox;
  r.size = {0.5f, 0.25f, 0.1f};
  r.position = {0.5f, 9, -1};
  r.rotation = {0.1f, 0.2f, -0.3f};
  r.mass = 0.25f;
  r.mode = PmxPhysicsMode::kDynamic;
  m.rigid_bodies.push_back(r);
  r.name = "髪";
  r.name_english = "";
  r.bone = -1;
  r.group = 15;
  r.collision_mask = 0x7FFF;
  r.shape = PmxShape::kCapsule;
  r.size = {0.2f, 1.5f, 0};
  r.position = {-0.5f, 13, 1};
  r.rotation = {-1.5707963f, 0, 0.25f};  // (-pi / 2, 0, 0.25)
  r.mass = 1.5f;
  r.restitution = 0.125f;
  r.mode = PmxPhysicsMode::kDynamicWithBonePosition;
  m.rigid_bodies.push_back(r);

  PmxJoint j;
  j.name = "スカート接続";
  j.name_english = "skirt joint";
  j.type = PmxJointType::kSpring6Dof;
  j.rigid_body_a = 0;
  j.rigid_body_b = 1;
  j.position = {0.5f, 9.5f, -0.8f};
  j.rotation = {0.05f, -0.1f, 0.15f};
  j.linear_min = {-0.1f, -0.2f, -0.3f};
  j.linear_max = {0.1f, 0.2f, 0.4f};
  j.angular_min = {-0.5f, -0.25f, -0.125f};
  j.angular_max = {0.75f, 0.5f, 0.25f};
  j.spring_linear = {10, 20, 30};
  j.spring_angular = {100, 200, 300};
  m.joints.push_back(j);
  j.name = "髪接続";
  j.name_english = "";
  j.type = v21 ? PmxJointType::kHinge : PmxJointType::kSpring6Dof;
  j.rigid_body_a = 1;
  j.rigid_body_b = 2;
  m.joints.push_back(j);
  return m;
}

inline void expect_same_model(const PmxModel& e, const PmxModel& a) {
  EXPECT_EQ(a.frame, PmxFrame::kMmd);
  EXPECT_EQ(a.header.version, e.header.version);
  EXPECT_EQ(a.header.additional_uv_count, e.header.additional_uv_count);
  EXPECT_EQ(a.header.name, e.header.name);
  EXPECT_EQ(a.header.name_english, e.header.name_english);
  EXPECT_EQ(a.header.comment, e.header.comment);
  EXPECT_EQ(a.header.comment_english, e.header.comment_english);

  const PmxVertices& ev = e.vertices;
  const PmxVertices& av = a.vertices;
  ASSERT_EQ(av.size(), ev.size());
  EXPECT_EQ(av.positions, ev.positions);
  EXPECT_EQ(av.normals, ev.normals);
  EXPECT_EQ(av.uvs, ev.uvs);
  ASSERT_EQ(av.additional_uvs.size(), ev.additional_uvs.size());
  for (size_t k = 0; k < ev.additional_uvs.size(); ++k) EXPECT_EQ(av.additional_uvs[k], ev.additional_uvs[k]);
  EXPECT_EQ(av.deform, ev.deform);
  EXPECT_EQ(av.bone_indices, ev.bone_indices);
  EXPECT_EQ(av.bone_weights, ev.bone_weights);
  EXPECT_EQ(av.sdef_c, ev.sdef_c);
  EXPECT_EQ(av.sdef_r0, ev.sdef_r0);
  EXPECT_EQ(av.sdef_r1, ev.sdef_r1);
  EXPECT_EQ(av.edge_scale, ev.edge_scale);
  EXPECT_EQ(a.faces, e.faces);

  // Textures and materials, when the expected model has its own (else the writer's one grey material comes back).
  if (!e.materials.empty()) {
    EXPECT_EQ(a.textures, e.textures);
    ASSERT_EQ(a.materials.size(), e.materials.size());
    for (size_t i = 0; i < e.materials.size(); ++i) {
      SCOPED_TRACE("material " + std::to_string(i));
      const PmxMaterial& em = e.materials[i];
      const PmxMaterial& am = a.materials[i];
      EXPECT_EQ(am.name, em.name);
      EXPECT_EQ(am.name_english, em.name_english);
      EXPECT_EQ(am.diffuse, em.diffuse);
      EXPECT_EQ(am.specular, em.specular);
      EXPECT_EQ(am.specular_strength, em.specular_strength);
      EXPECT_EQ(am.ambient, em.ambient);
      EXPECT_EQ(am.flags, em.flags);
      EXPECT_EQ(am.edge_colour, em.edge_colour);
      EXPECT_EQ(am.edge_size, em.edge_size);
      EXPECT_EQ(am.texture, em.texture);
      EXPECT_EQ(am.sphere_texture, em.sphere_texture);
      EXPECT_EQ(am.sphere_mode, em.sphere_mode);
      EXPECT_EQ(am.shared_toon, em.shared_toon);
      EXPECT_EQ(am.toon, em.toon);
      EXPECT_EQ(am.memo, em.memo);
      EXPECT_EQ(am.face_count, em.face_count);
    }
  }

  ASSERT_EQ(a.bones.size(), e.bones.size());
  for (size_t i = 0; i < e.bones.size(); ++i) {
    SCOPED_TRACE("bone " + std::to_string(i));
    const PmxBone& eb = e.bones[i];
    const PmxBone& ab = a.bones[i];
    EXPECT_EQ(ab.name, eb.name);
    EXPECT_EQ(ab.name_english, eb.name_english);
    EXPECT_EQ(ab.position, eb.position);
    EXPECT_EQ(ab.parent, eb.parent);
    EXPECT_EQ(ab.layer, eb.layer);
    EXPECT_EQ(ab.flags, eb.flags);
    const bool PmxBone::*flags[] = {&PmxBone::tail_is_bone,
                                    &PmxBone::rotatable,
                                    &PmxBone::translatable,
                                    &PmxBone::visible,
                                    &PmxBone::enabled,
                                    &PmxBone::is_ik,
                                    &PmxBone::inherit_local,
                                    &PmxBone::inherit_rotation,
                                    &PmxBone::inherit_translation,
                                    &PmxBone::has_fixed_axis,
                                    &PmxBone::has_local_axes,
                                    &PmxBone::physics_after_deform,
                                    &PmxBone::has_external_parent};
    for (size_t k = 0; k < std::size(flags); ++k) EXPECT_EQ(ab.*flags[k], eb.*flags[k]) << "flag " << k;
    EXPECT_EQ(ab.tail_bone, eb.tail_bone);
    EXPECT_EQ(ab.tail_offset, eb.tail_offset);
    EXPECT_EQ(ab.inherit_parent, eb.inherit_parent);
    EXPECT_EQ(ab.inherit_weight, eb.inherit_weight);
    EXPECT_EQ(ab.fixed_axis, eb.fixed_axis);
    EXPECT_EQ(ab.local_axis_x, eb.local_axis_x);
    EXPECT_EQ(ab.local_axis_z, eb.local_axis_z);
    EXPECT_EQ(ab.external_parent_key, eb.external_parent_key);
    EXPECT_EQ(ab.ik.target, eb.ik.target);
    EXPECT_EQ(ab.ik.loop_count, eb.ik.loop_count);
    EXPECT_EQ(ab.ik.limit_angle, eb.ik.limit_angle);
    ASSERT_EQ(ab.ik.links.size(), eb.ik.links.size());
    for (size_t k = 0; k < eb.ik.links.size(); ++k) {
      EXPECT_EQ(ab.ik.links[k].bone, eb.ik.links[k].bone);
      EXPECT_EQ(ab.ik.links[k].has_limits, eb.ik.links[k].has_limits);
      EXPECT_EQ(ab.ik.links[k].limit_min, eb.ik.links[k].limit_min);
      EXPECT_EQ(ab.ik.links[k].limit_max, eb.ik.links[k].limit_max);
    }
  }

  ASSERT_EQ(a.rigid_bodies.size(), e.rigid_bodies.size());
  for (size_t i = 0; i < e.rigid_bodies.size(); ++i) {
    SCOPED_TRACE("rigid body " + std::to_string(i));
    const PmxRigidBody& er = e.rigid_bodies[i];
    const PmxRigidBody& ar = a.rigid_bodies[i];
    EXPECT_EQ(ar.name, er.name);
    EXPECT_EQ(ar.name_english, er.name_english);
    EXPECT_EQ(ar.bone, er.bone);
    EXPECT_EQ(ar.group, er.group);
    EXPECT_EQ(ar.collision_mask, er.collision_mask);
    EXPECT_EQ(ar.shape, er.shape);
    EXPECT_EQ(ar.size, er.size);
    EXPECT_EQ(ar.position, er.position);
    EXPECT_EQ(ar.rotation, er.rotation);
    EXPECT_EQ(ar.mass, er.mass);
    EXPECT_EQ(ar.linear_damping, er.linear_damping);
    EXPECT_EQ(ar.angular_damping, er.angular_damping);
    EXPECT_EQ(ar.restitution, er.restitution);
    EXPECT_EQ(ar.friction, er.friction);
    EXPECT_EQ(ar.mode, er.mode);
  }

  ASSERT_EQ(a.joints.size(), e.joints.size());
  for (size_t i = 0; i < e.joints.size(); ++i) {
    SCOPED_TRACE("joint " + std::to_string(i));
    const PmxJoint& ej = e.joints[i];
    const PmxJoint& aj = a.joints[i];
    EXPECT_EQ(aj.name, ej.name);
    EXPECT_EQ(aj.name_english, ej.name_english);
    EXPECT_EQ(aj.type, ej.type);
    EXPECT_EQ(aj.rigid_body_a, ej.rigid_body_a);
    EXPECT_EQ(aj.rigid_body_b, ej.rigid_body_b);
    EXPECT_EQ(aj.position, ej.position);
    EXPECT_EQ(aj.rotation, ej.rotation);
    EXPECT_EQ(aj.linear_min, ej.linear_min);
    EXPECT_EQ(aj.linear_max, ej.linear_max);
    EXPECT_EQ(aj.angular_min, ej.angular_min);
    EXPECT_EQ(aj.angular_max, ej.angular_max);
    EXPECT_EQ(aj.spring_linear, ej.spring_linear);
    EXPECT_EQ(aj.spring_angular, ej.spring_angular);
  }
}

}  // namespace amt::test
