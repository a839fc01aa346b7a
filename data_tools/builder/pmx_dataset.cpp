#include "data_tools/builder/pmx_dataset.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "data_tools/builder/pmx_physics.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/skeleton.h"

namespace amt {
namespace {

bool is_simulated(PmxPhysicsMode mode) {
  return mode != PmxPhysicsMode::kFollowBone;
}

// Components of PmxRigidBody::size a shape uses: sphere (radius), box (three half extents), capsule (radius, height).
int used_size_components(PmxShape shape) {
  return shape == PmxShape::kSphere ? 1 : shape == PmxShape::kBox ? 3 : 2;
}

std::string body_where(const PmxModel& m, size_t i) {
  return detail::concat(m.source, ": rigid_bodies[", i, "] '", m.rigid_bodies[i].name, "': ");
}

std::string joint_where(const PmxModel& m, size_t i) {
  return detail::concat(m.source, ": joints[", i, "] '", m.joints[i].name, "': ");
}

// Clamps `value` into [lo, hi], with a warning naming `field` when it moves.
void clamp_field(float& value, float lo, float hi, const std::string& where, const char* field, const char* expected,
                 std::vector<std::string>& warnings) {
  const float clamped = std::clamp(value, lo, hi);
  if (clamped == value) return;
  warnings.push_back(detail::concat(where, field, ": expected ", expected, ", found ", value, "; set to ", clamped));
  value = clamped;
}

}  // namespace

// === Repairs

PmxModel repair_pmx_physics(const PmxModel& model, std::vector<std::string>& warnings) {
  AMT_CHECK(model.frame == PmxFrame::kMmd, model.source,
            ": physics: expected a model in the file's frame (PMX units), found one converted to amt's");
  AMT_CHECK(!model.bones.empty(), model.source, ": bones: expected at least one bone for the physics rig, found none");
  PmxModel m = model;
  const int B = static_cast<int>(m.bones.size());
  for (size_t i = 0; i < m.rigid_bodies.size(); ++i) {
    PmxRigidBody& r = m.rigid_bodies[i];
    const std::string where = body_where(m, i);
    for (int k = 0; k < used_size_components(r.shape); ++k) {
      if (r.size[k] > 0) continue;
      warnings.push_back(detail::concat(where, "size[", k, "]: expected a positive length, found ", r.size[k],
                                        "; set to ", kPmxMinimumBodySize, " units"));
      r.size[k] = kPmxMinimumBodySize;
    }
    if (is_simulated(r.mode) && !(r.mass > 0)) {
      // saba (MMDRigidBody::Create) passes mass 0 to Bullet, which makes the body static: it would stay at its rest
      // place while the character moves away. Following its bone is the nearest sane reading.
      warnings.push_back(detail::concat(where, "mass: expected a positive mass on a simulated body (mode ",
                                        static_cast<int>(r.mode), "), found ", r.mass,
                                        "; it follows its bone (mode 0)"));
      r.mode = PmxPhysicsMode::kFollowBone;
    }
    if (r.bone < 0 || r.bone >= B) {
      if (r.mode == PmxPhysicsMode::kFollowBone) {
        // saba MMDRigidBody::Create: a body without a bone follows node 0 and drives none.
        warnings.push_back(detail::concat(where, "bone: expected a bone, found ", r.bone, "; it follows bone 0 '",
                                          m.bones[0].name, "' as MMD players do"));
        r.bone = 0;
      } else {
        warnings.push_back(detail::concat(where, "bone: expected a bone, found ", r.bone,
                                          "; the body is simulated and drives no bone"));
        r.bone = -1;
      }
    }
    clamp_field(r.linear_damping, 0.0f, 1.0f, where, "linear_damping", "[0, 1]", warnings);
    clamp_field(r.angular_damping, 0.0f, 1.0f, where, "angular_damping", "[0, 1]", warnings);
    clamp_field(r.friction, 0.0f, 1e30f, where, "friction", "a value >= 0", warnings);
    clamp_field(r.restitution, 0.0f, 1e30f, where, "restitution", "a value >= 0", warnings);
    if (r.group > 15) {
      warnings.push_back(
          detail::concat(where, "group: expected 0 to 15, found ", static_cast<int>(r.group), "; set to 15"));
      r.group = 15;
    }
  }
  const int R = static_cast<int>(m.rigid_bodies.size());
  std::vector<PmxJoint> kept;
  for (size_t i = 0; i < m.joints.size(); ++i) {
    PmxJoint j = m.joints[i];
    const std::string where = joint_where(m, i);
    AMT_CHECK(j.type == PmxJointType::kSpring6Dof, where, "type: expected a spring 6-DOF joint (0), found type ",
              static_cast<int>(j.type), " (PMX 2.1 joint types are not simulated)");
    const bool a_ok = j.rigid_body_a >= 0 && j.rigid_body_a < R, b_ok = j.rigid_body_b >= 0 && j.rigid_body_b < R;
    if (!a_ok || !b_ok) {
      warnings.push_back(detail::concat(where, "rigid_body_", a_ok ? "b" : "a", ": expected a rigid body, found ",
                                        a_ok ? j.rigid_body_b : j.rigid_body_a, "; joint dropped"));
      continue;
    }
    if (j.rigid_body_a == j.rigid_body_b) {
      warnings.push_back(detail::concat(where, "rigid_body_b: expected a body other than rigid_body_a, found ",
                                        j.rigid_body_b, " for both; joint dropped"));
      continue;
    }
    if (!is_simulated(m.rigid_bodies[j.rigid_body_a].mode) && !is_simulated(m.rigid_bodies[j.rigid_body_b].mode)) {
      warnings.push_back(detail::concat(where, "rigid bodies: expected at least one simulated body, found '",
                                        m.rigid_bodies[j.rigid_body_a].name, "' and '",
                                        m.rigid_bodies[j.rigid_body_b].name,
                                        "' both following their bones (it can move nothing); joint dropped"));
      continue;
    }
    for (Eigen::Vector3f* spring : {&j.spring_linear, &j.spring_angular}) {
      if ((spring->array() >= 0).all()) continue;
      warnings.push_back(detail::concat(where, spring == &j.spring_linear ? "spring_linear" : "spring_angular",
                                        ": expected stiffness >= 0, found (", spring->transpose(),
                                        "); negative entries set to 0"));
      *spring = spring->cwiseMax(0.0f);
    }
    kept.push_back(j);
  }
  m.joints = std::move(kept);
  return m;
}

// === The character

Skeleton pmx_skeleton(const PmxModel& model) {
  Skeleton s;
  s.rest_joints.resize(static_cast<Eigen::Index>(model.bones.size()), 3);
  for (size_t b = 0; b < model.bones.size(); ++b) {
    s.names.push_back(model.bones[b].name.empty() ? model.bones[b].name_english : model.bones[b].name);
    s.parents.push_back(model.bones[b].parent);
    s.rest_joints.row(static_cast<Eigen::Index>(b)) = model.bones[b].position.transpose();
  }
  // Names must be unique for mapping and for the dataset's rig; PMX allows repeats.
  for (size_t b = 0; b < s.names.size(); ++b) {
    for (size_t k = 0; k < b; ++k) {
      if (s.names[k] == s.names[b]) {
        s.names[b] += "_" + std::to_string(b);
        break;
      }
    }
  }
  return s;
}

PmxCharacter pmx_physics_character(PmxModel model, float scale) {
  PmxCharacter c;
  c.source = model.source;
  c.model = repair_pmx_physics(model, c.warnings);
  c.scale = scale;
  c.physics = pmx_physics_rig(c.model);
  const PmxModel converted = pmx_to_amt_frame(c.model, scale);
  c.mesh = pmx_mesh(converted);
  c.skin = pmx_skin_weights(c.model);
  c.file_skeleton = pmx_skeleton(converted);
  c.apparel_mask = pmx_physics_apparel_mask(c.model, &c.simulated_bodies);
  return c;
}

PmxCharacter pmx_character(PmxModel model, const std::optional<JointMapFile>& joint_map, float scale) {
  PmxCharacter c = pmx_physics_character(std::move(model), scale);
  c.rest = canonical_rest(c.file_skeleton, joint_map, c.source);

  // Carriers: a mapped bone its own joint; a bone that takes its whole rotation from another (MMD's D bones, whose
  // inherit_parent is the animated bone) that bone's carrier; any other its parent's (memoised, cycle-safe).
  const int B = c.num_bones();
  std::vector<int> own(static_cast<size_t>(B), -1);
  std::vector<bool> placed(kCanonicalJointCount, false);
  for (const int j : c.rest.placed) placed[static_cast<size_t>(j)] = true;
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    if (!placed[static_cast<size_t>(j)])
      own[static_cast<size_t>(c.rest.mapping.source_joint[static_cast<size_t>(j)])] = j;
  }
  c.carrier.assign(static_cast<size_t>(B), -1);
  for (int b = 0; b < B; ++b) {
    std::vector<int> path;
    int k = b, result = -1;
    for (int steps = 0; k >= 0 && steps <= B; ++steps) {
      if (c.carrier[static_cast<size_t>(k)] >= 0) {
        result = c.carrier[static_cast<size_t>(k)];
        break;
      }
      if (own[static_cast<size_t>(k)] >= 0) {
        result = own[static_cast<size_t>(k)];
        break;
      }
      path.push_back(k);
      const PmxBone& bone = c.model.bones[static_cast<size_t>(k)];
      const bool inherits = bone.inherit_rotation && !bone.inherit_local && bone.inherit_parent >= 0 &&
                            bone.inherit_parent < B && bone.inherit_parent != k &&
                            std::abs(bone.inherit_weight - 1.0f) < 1e-3f;
      k = inherits ? bone.inherit_parent : bone.parent;
    }
    if (result < 0) result = c.rest.carrier[static_cast<size_t>(b)];  // above the root, or an inheritance cycle
    for (const int p : path) c.carrier[static_cast<size_t>(p)] = result;
    if (c.carrier[static_cast<size_t>(b)] < 0) c.carrier[static_cast<size_t>(b)] = result;
  }
  return c;
}

PmxCharacter load_pmx_character(const std::string& path, const std::optional<JointMapFile>& joint_map, float scale) {
  return pmx_character(read_pmx(path), joint_map, scale);
}

Transforms pmx_bone_pose(const PmxCharacter& c, const Transforms& canonical) {
  AMT_CHECK(c.carrier.size() == c.model.bones.size(), c.source,
            ": pose: expected a character with a canonical skeleton (pmx_character), found none");
  AMT_CHECK(canonical.size() == static_cast<size_t>(kCanonicalJointCount), c.source, ": pose: expected ",
            kCanonicalJointCount, " canonical joint transforms, found ", canonical.size());
  const Eigen::Matrix3f S = Eigen::Vector3f(1, 1, -1).asDiagonal();
  const float inverse = 1.0f / c.scale;
  Eigen::Matrix3f R[kCanonicalJointCount];
  Eigen::Vector3f t[kCanonicalJointCount], rest[kCanonicalJointCount];
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    AMT_CHECK(canonical[static_cast<size_t>(j)].allFinite(), c.source, ": pose: joint ", j,
              ": expected a finite transform, found NaN or infinity");
    const Eigen::Matrix3f Rj = canonical[static_cast<size_t>(j)].leftCols<3>();
    R[j] = S * Rj * S;
    t[j] = inverse * (S * canonical[static_cast<size_t>(j)].col(3));
    rest[j] = inverse * (S * c.rest.skeleton.rest_joints.row(j).transpose());
  }
  Transforms pose(c.model.bones.size());
  for (size_t b = 0; b < pose.size(); ++b) {
    const int j = c.carrier[b];
    pose[b] = make_transform(R[j], R[j] * (c.model.bones[b].position - rest[j]) + t[j]);
  }
  return pose;
}

// === Simulation

PhysicsSettings pmx_simulation_settings(const PmxSimulationOptions& o, const std::string& source) {
  AMT_CHECK(std::isfinite(o.fps) && o.fps > 0, source, ": simulation: fps: expected > 0, found ", o.fps);
  AMT_CHECK(std::isfinite(o.physics_step) && o.physics_step > 0, source,
            ": simulation: physics step: expected > 0 s, found ", o.physics_step);
  AMT_CHECK(o.solver_iterations >= 1, source, ": simulation: solver iterations: expected >= 1, found ",
            o.solver_iterations);
  AMT_CHECK(std::isfinite(o.settle_seconds) && o.settle_seconds >= 0, source,
            ": simulation: settle seconds: expected >= 0, found ", o.settle_seconds);
  PhysicsSettings s = pmx_physics_settings();  // MMD's gravity and box margin, in PMX units
  s.fixed_step = o.physics_step;
  s.solver_iterations = o.solver_iterations;
  s.max_substeps = std::max(s.max_substeps, static_cast<int>(std::ceil(1.0 / o.fps / o.physics_step)));
  return s;
}

PmxRigSimulator::PmxRigSimulator(const PmxCharacter& c, const PmxSimulationOptions& options)
    : character_(&c), options_(options), world_(c.physics, pmx_simulation_settings(options, c.source)) {
  update();
}

void PmxRigSimulator::start(const Transforms& canonical) {
  start_bones(pmx_bone_pose(*character_, canonical));
}

const Transforms& PmxRigSimulator::step(const Transforms& canonical) {
  return step_bones(pmx_bone_pose(*character_, canonical));
}

void PmxRigSimulator::start_bones(const Transforms& bones) {
  world_.reset(bones);
  if (options_.settle_seconds > 0) world_.settle(bones, options_.settle_seconds);
  update();
}

const Transforms& PmxRigSimulator::step_bones(const Transforms& bones) {
  world_.set_bone_pose(bones);
  world_.step(1.0f / options_.fps);
  update();
  return amt_;
}

void PmxRigSimulator::update() {
  amt_ = pmx_transforms_to_amt(world_.bone_transforms(), character_->scale);
}

Transforms PmxRigSimulator::skinning() const {
  Transforms M(amt_.size());
  for (size_t b = 0; b < amt_.size(); ++b) {
    const Eigen::Matrix3f R = amt_[b].leftCols<3>();
    const Eigen::Vector3f rest = character_->file_skeleton.rest_joints.row(static_cast<Eigen::Index>(b)).transpose();
    M[b] = make_transform(R, amt_[b].col(3) - R * rest);
  }
  return M;
}

Transforms simulate_pmx_clip(const PmxCharacter& c, const Transforms& joints, int frames,
                             const PmxSimulationOptions& options, std::unique_ptr<PmxRigSimulator>& simulator) {
  const size_t J = kCanonicalJointCount;
  AMT_CHECK(frames >= 1 && joints.size() == J * static_cast<size_t>(frames), c.source, ": clip: expected ", frames,
            " x ", J, " joint transforms, found ", joints.size());
  if (!simulator) simulator = std::make_unique<PmxRigSimulator>(c, options);
  auto pose = [&](int t) {
    return Transforms(joints.begin() + static_cast<ptrdiff_t>(t * J),
                      joints.begin() + static_cast<ptrdiff_t>((t + 1) * J));
  };
  simulator->start(pose(0));
  Transforms rig = simulator->skinning();
  for (int t = 1; t < frames; ++t) {
    simulator->step(pose(t));
    const Transforms M = simulator->skinning();
    rig.insert(rig.end(), M.begin(), M.end());
  }
  return rig;
}

// === As a dataset character

MatrixXfR pmx_body_weights(const PmxCharacter& c) {
  const int N = c.mesh.num_vertices(), B = c.num_bones();
  MatrixXfR W = MatrixXfR::Zero(N, kCanonicalJointCount);
  for (int i = 0; i < N; ++i) {
    for (int k = 0; k < kMaxInfluences; ++k) {
      const int b = c.skin.indices(i, k);
      const float w = c.skin.weights(i, k);
      if (b >= 0 && b < B && w > 0) W(i, c.carrier[static_cast<size_t>(b)]) += w;
    }
  }
  return W;
}

PmxDatasetCharacter pmx_dataset_character(const PmxCharacter& c, const std::string& name, const std::string& split) {
  const int N = c.mesh.num_vertices(), B = c.num_bones(), J = kCanonicalJointCount;
  const std::vector<uint8_t> driven = pmx_physics_driven_bones(c.model);
  // Each apparel vertex's piece: the top of the driven chain of its heaviest driven bone.
  std::vector<int> root_of(static_cast<size_t>(N), -1);
  std::vector<int> roots;  // in order of first appearance
  for (int i = 0; i < N; ++i) {
    if (!c.apparel_mask[static_cast<size_t>(i)]) continue;
    int best = -1;
    float weight = 0;
    for (int k = 0; k < kMaxInfluences; ++k) {
      const int b = c.skin.indices(i, k);
      if (b >= 0 && b < B && driven[static_cast<size_t>(b)] && c.skin.weights(i, k) > weight)
        best = b, weight = c.skin.weights(i, k);
    }
    if (best < 0) {  // a weight on a driven bone that pmx_skin_weights dropped (repeats merged): any driven one
      for (int k = 0; k < 4; ++k) {
        const int b = c.model.vertices.bone_indices(i, k);
        if (b >= 0 && b < B && driven[static_cast<size_t>(b)]) best = b;
      }
    }
    int root = std::max(best, 0);
    for (int steps = 0; steps <= B; ++steps) {
      const int p = c.model.bones[static_cast<size_t>(root)].parent;
      if (p < 0 || !driven[static_cast<size_t>(p)]) break;
      root = p;
    }
    root_of[static_cast<size_t>(i)] = root;
    if (std::find(roots.begin(), roots.end(), root) == roots.end()) roots.push_back(root);
  }

  PmxDatasetCharacter out;
  std::vector<int>& order = out.vertex_order;
  for (int i = 0; i < N; ++i) {
    if (!c.apparel_mask[static_cast<size_t>(i)]) order.push_back(i);
  }
  out.body_vertices = static_cast<int>(order.size());
  const MatrixX3f& joints = c.rest.skeleton.rest_joints;
  for (const int root : roots) {
    PmxApparelPiece piece;
    piece.root_bone = root;
    piece.attachment_joint = c.carrier[static_cast<size_t>(root)];
    piece.first_vertex = static_cast<int>(order.size());
    for (int i = 0; i < N; ++i) {
      if (root_of[static_cast<size_t>(i)] != root) continue;
      order.push_back(i);
      piece.chain_length = std::max(piece.chain_length, (c.mesh.V.row(i) - joints.row(piece.attachment_joint)).norm());
    }
    piece.chain_length = std::max(piece.chain_length, 1e-3f);
    piece.end_vertex = static_cast<int>(order.size());
    out.pieces.push_back(piece);
  }
  std::vector<int> position(static_cast<size_t>(N));
  for (int k = 0; k < N; ++k) position[static_cast<size_t>(order[static_cast<size_t>(k)])] = k;

  CharacterData& d = out.data;
  d.name = name;
  d.split = split;
  d.skeleton = c.rest.skeleton;
  d.mesh.V.resize(N, 3);
  d.apparel_mask.resize(static_cast<size_t>(N));
  const MatrixXfR body_weights = pmx_body_weights(c);
  d.body_weights.resize(N, J);
  Rig rig;
  rig.skin_indices = MatrixXiR::Zero(N, kMaxInfluences);
  rig.skin_weights = MatrixXfR::Zero(N, kMaxInfluences);
  for (int k = 0; k < N; ++k) {
    const int i = order[static_cast<size_t>(k)];
    d.mesh.V.row(k) = c.mesh.V.row(i);
    d.apparel_mask[static_cast<size_t>(k)] = c.apparel_mask[static_cast<size_t>(i)];
    d.body_weights.row(k) = body_weights.row(i);
    for (int s = 0; s < kMaxInfluences; ++s) {
      const int b = c.skin.indices(i, s);
      const float w = c.skin.weights(i, s);
      if (b < 0 || b >= B || !(w > 0)) continue;  // unused slots stay (bone 0, weight 0)
      rig.skin_indices(k, s) = b;
      rig.skin_weights(k, s) = w;
    }
  }
  // Faces among body vertices first (the body surface of the quality gates), then the others, each in file order.
  std::vector<Eigen::Vector3i> body, other;
  for (int f = 0; f < c.mesh.num_faces(); ++f) {
    const Eigen::Vector3i face(position[static_cast<size_t>(c.mesh.F(f, 0))],
                               position[static_cast<size_t>(c.mesh.F(f, 1))],
                               position[static_cast<size_t>(c.mesh.F(f, 2))]);
    (face.maxCoeff() < out.body_vertices ? body : other).push_back(face);
  }
  out.body_faces = static_cast<int>(body.size());
  d.mesh.F.resize(static_cast<Eigen::Index>(body.size() + other.size()), 3);
  for (size_t f = 0; f < body.size(); ++f) d.mesh.F.row(static_cast<Eigen::Index>(f)) = body[f].transpose();
  for (size_t f = 0; f < other.size(); ++f)
    d.mesh.F.row(static_cast<Eigen::Index>(body.size() + f)) = other[f].transpose();

  rig.bone_names = c.file_skeleton.names;
  rig.bone_parents.assign(c.file_skeleton.parents.begin(), c.file_skeleton.parents.end());
  for (int b = 0; b < B; ++b) {
    rig.rest_transforms.push_back(
        make_transform(Eigen::Matrix3f::Identity(), c.file_skeleton.rest_joints.row(b).transpose()));
  }
  d.rig = std::move(rig);
  return out;
}

}  // namespace amt
