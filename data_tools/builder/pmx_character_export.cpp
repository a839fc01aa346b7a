// A dressed procedural character as a PMX model (see pmx_character_export.h for what is written and why the
// dynamics convert as they do).
#include "data_tools/builder/pmx_character_export.h"

#include <cmath>

#include "data_tools/builder/pmx_physics.h"
#include "data_tools/formats/joint_map.h"
#include "data_tools/formats/pmx_export.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"

namespace amt {

// === Names

const std::array<std::string, kCanonicalJointCount>& mmd_canonical_bone_names() {
  static const std::array<std::string, kCanonicalJointCount> names = [] {
    std::array<std::string, kCanonicalJointCount> out;
    for (const JointNameConvention& convention : joint_name_conventions()) {
      if (convention.name != "MMD") continue;
      for (int j = 0; j < kCanonicalJointCount; ++j) {
        if (!convention.names[static_cast<size_t>(j)].empty()) out[static_cast<size_t>(j)] = convention.names[j][0];
      }
    }
    out[kSpine1] = "上半身";
    out[kSpine2] = "上半身2";
    out[kSpine3] = "上半身3";
    for (int j = 0; j < kCanonicalJointCount; ++j) {
      AMT_CHECK(!out[static_cast<size_t>(j)].empty(),
                "mmd_canonical_bone_names: the MMD joint-name convention has no name for ",
                canonical_joint_names()[static_cast<size_t>(j)]);
    }
    return out;
  }();
  return names;
}

namespace {

// === amt's frame to MMD's: the inverse of pmx_to_amt_frame (pmx_import.h)

// The reflection S = diag(1, 1, -1) is its own inverse, so the reader's maps with scale 1 / s invert its maps with
// scale s: positions (x, y, z) -> (x, y, -z) / s, length ranges likewise, angle ranges by the same involution.
struct ToMmd {
  float s;  // metres per unit

  Eigen::Vector3f position(const Eigen::Vector3f& p) const { return pmx_to_amt_position(p, 1.0f / s); }

  // Euler angles (PMX order, R = Ry(y) Rx(x) Rz(z)) of the rotation S R S, for a rotation R in amt's frame.
  static Eigen::Vector3f euler(const Eigen::Quaternionf& rotation) {
    Eigen::Matrix3f R = rotation.normalized().toRotationMatrix();
    R.row(2) *= -1.0f;  // S R S
    R.col(2) *= -1.0f;
    return pmx_euler_angles(R);
  }
};

// === Sections

void add_vertices(const DressedCharacter& dressed, const ToMmd& to_mmd, PmxModel& model) {
  const TriMesh& mesh = dressed.mesh;
  const SparseWeights& w = dressed.rig_weights;
  const int n = static_cast<int>(mesh.V.rows());
  AMT_CHECK(w.num_vertices() == n, "pmx_from_character: rig_weights: expected ", n, " rows (one per vertex), found ",
            w.num_vertices());
  PmxVertices& v = model.vertices;
  v.resize(n, 0);  // uv 0, edge scale 1
  v.normals = vertex_normals(mesh.V, mesh.F);
  for (int i = 0; i < n; ++i) {
    v.positions.row(i) = to_mmd.position(mesh.V.row(i).transpose()).transpose();
    v.normals(i, 2) = -v.normals(i, 2);
    int used = 0;
    for (int k = 0; k < kMaxInfluences; ++k) {
      if (!(w.weights(i, k) > 0)) continue;
      v.bone_indices(i, used) = w.indices(i, k);
      v.bone_weights(i, used) = w.weights(i, k);
      ++used;
    }
    v.deform[static_cast<size_t>(i)] = used == 1 ? PmxDeform::kBdef1 : PmxDeform::kBdef4;
    if (used == 1) v.bone_weights(i, 0) = 1;
  }
  // The reflection reverses the winding: (a, b, c) -> (a, c, b).
  model.faces = mesh.F;
  if (model.faces.rows() > 0) model.faces.col(1).swap(model.faces.col(2));
}

void add_bones(const PhysicsRig& rig, const ToMmd& to_mmd, PmxModel& model) {
  const std::array<std::string, kCanonicalJointCount>& mmd_names = mmd_canonical_bone_names();
  const std::vector<std::string>& canonical = canonical_joint_names();
  AMT_CHECK(rig.num_bones() >= kCanonicalJointCount, "pmx_from_character: rig: expected the ", kCanonicalJointCount,
            " canonical joints as its first bones, found ", rig.num_bones(), " bones");
  std::vector<int32_t> first_child(rig.bones.size(), -1);
  for (int b = rig.num_bones() - 1; b >= 0; --b) {
    const int32_t parent = rig.bones[static_cast<size_t>(b)].parent;
    if (parent >= 0 && parent < rig.num_bones()) first_child[static_cast<size_t>(parent)] = b;
  }
  for (int b = 0; b < rig.num_bones(); ++b) {
    const PhysicsBone& source = rig.bones[static_cast<size_t>(b)];
    PmxBone bone;
    if (b < kCanonicalJointCount) {
      AMT_CHECK(source.name == canonical[static_cast<size_t>(b)], "pmx_from_character: rig.bones[", b,
                "].name: expected the canonical joint ", canonical[static_cast<size_t>(b)], ", found ", source.name);
      bone.name = mmd_names[static_cast<size_t>(b)];
    } else {
      bone.name = source.name;
    }
    bone.name_english = source.name;
    bone.position = to_mmd.position(source.rest_position);
    bone.parent = source.parent;
    // Rotatable, visible, enabled; the root also translatable; the tail on the first child (MMD draws the bone
    // towards it), or a zero offset for a leaf.
    bone.flags = kPmxBoneRotatable | kPmxBoneVisible | kPmxBoneEnabled;
    if (source.parent < 0) bone.flags |= kPmxBoneTranslatable;
    bone.tail_bone = first_child[static_cast<size_t>(b)];
    if (bone.tail_bone >= 0) bone.flags |= kPmxBoneTailIsBone;
    bone.tail_is_bone = bone.tail_bone >= 0;
    bone.rotatable = bone.visible = bone.enabled = true;
    bone.translatable = source.parent < 0;
    model.bones.push_back(bone);
  }
}

void add_bodies(const PhysicsRig& rig, const ToMmd& to_mmd, PmxModel& model) {
  for (int b = 0; b < rig.num_bodies(); ++b) {
    const PhysicsBody& source = rig.bodies[static_cast<size_t>(b)];
    const RigidPose rest = body_rest_pose(rig, b);  // world transform, also for bone-local rests
    PmxRigidBody body;
    body.name = source.name;
    body.name_english = source.name;
    body.bone = source.bone;
    body.group = source.group;
    body.collision_mask = static_cast<uint16_t>(~source.non_collision_mask & 0xFFFF);
    body.shape = static_cast<PmxShape>(source.shape);  // the same values: physics.h mirrors PMX's shapes and modes
    body.size = source.size / to_mmd.s;
    body.position = to_mmd.position(rest.position);
    body.rotation = ToMmd::euler(rest.rotation);
    body.mass = to_mmd.s * to_mmd.s * source.mass;  // see the top of pmx_character_export.h
    body.linear_damping = source.linear_damping;
    body.angular_damping = source.angular_damping;
    body.restitution = source.restitution;
    body.friction = source.friction;
    body.mode = static_cast<PmxPhysicsMode>(source.mode);
    model.rigid_bodies.push_back(body);
  }
}

void add_joints(const PhysicsRig& rig, const ToMmd& to_mmd, float gamma, PmxModel& model) {
  const float s = to_mmd.s;
  for (const PhysicsJoint& source : rig.joints) {
    PmxJoint joint;
    joint.name = source.name;
    joint.name_english = source.name;
    joint.type = PmxJointType::kSpring6Dof;
    joint.rigid_body_a = source.body_a;
    joint.rigid_body_b = source.body_b;
    joint.position = to_mmd.position(source.rest.position);
    joint.rotation = ToMmd::euler(source.rest.rotation);
    pmx_to_amt_length_range(source.linear_min, source.linear_max, 1.0f / s, joint.linear_min, joint.linear_max);
    pmx_to_amt_angle_range(source.angular_min, source.angular_max, joint.angular_min, joint.angular_max);
    // See the top of pmx_character_export.h: k_ang,u = gamma k_ang,m; k_lin,u = gamma s^2 k_lin,m.
    joint.spring_linear = (gamma * s * s) * source.linear_stiffness;
    joint.spring_angular = gamma * source.angular_stiffness;
    model.joints.push_back(joint);
  }
}

}  // namespace

// === Export

PmxModel pmx_from_character(const DressedCharacter& dressed, const PmxCharacterExportOptions& options) {
  const float s = options.metres_per_unit;
  AMT_CHECK(std::isfinite(s) && s > 0, "pmx_from_character: metres_per_unit: expected a finite value > 0, found ", s);
  // MMD's gravity in metres over the procedural world's (see the top of pmx_character_export.h).
  const float gamma = pmx_physics_settings().gravity.norm() * s / PhysicsSettings().gravity.norm();
  const ToMmd to_mmd{s};

  PmxModel model;
  model.source = options.name;
  model.frame = PmxFrame::kMmd;
  model.scale = 1.0f;
  model.header.version = 2.0f;
  model.header.encoding = PmxTextEncoding::kUtf16Le;
  model.header.name = model.header.name_english = options.name;
  model.header.comment = model.header.comment_english = options.comment;
  add_vertices(dressed, to_mmd, model);
  add_bones(dressed.rig, to_mmd, model);
  add_bodies(dressed.rig, to_mmd, model);
  add_joints(dressed.rig, to_mmd, gamma, model);
  pmx_fit_index_sizes(model);
  return model;
}

DressedCharacter dataset_character(const DatasetBuildOptions& options, int index) {
  AMT_CHECK(index >= 0 && index < options.characters, "dataset character: expected an index from 0 to ",
            options.characters - 1, ", found ", index);
  const DatasetPlan plan = plan_dataset(options, {});
  const PlannedCharacter& planned = plan.characters[static_cast<size_t>(index)];
  const GeneratedBody body = generate_body(sample_body_params(planned.body_seed), options.vertices);
  return dress_character(body, planned.apparel_seed, options.apparel);
}

}  // namespace amt
