#pragma once
// A real PMX model (MikuMikuDance) as a character of the dataset (`amt dataset build --pmx`) and of
// `amt animate --apparel physics`: its whole rig posed by a canonical 22-joint motion and its own rigid bodies and
// joints simulated in its native units, as its artist tuned them (docs/dataset.md, "Your own PMX models"), the result
// in amt's frame.
//
// Per output frame (PmxRigSimulator::step):
//   1. bone pass: canonical joint transforms (amt's frame, metres; forward kinematics of a motion retargeted onto
//      the model's proportions, as for procedural characters) -> every PMX bone's animated pose in the file's frame
//      (pmx_bone_pose): mapped bones take their canonical joint's transform; every other bone, apparel chains
//      included, follows its carrier (PmxCharacter::carrier) rigidly;
//   2. physics: kinematic bodies (mode 0) follow their bones, Bullet steps, simulated bodies (modes 1 and 2) write
//      their bones back and the bones below them follow (data_tools/builder/physics.h);
//   3. the bones to amt's frame (pmx_transforms_to_amt) and their skinning matrices.
//
// MMD's conventions, which "as authored" means here, and where they come from:
//   - Physics after the bone pass. saba (github.com/benikabocha/saba, src/Saba/Model/MMD/MMDModel.cpp,
//     MMDModel::UpdateAllAnimation) evaluates the motion, runs UpdateNodeAnimation(false) (every bone without the
//     PMX 2.0 flag 0x1000 "physics after deform"), then UpdatePhysicsAnimation(elapsed), then
//     UpdateNodeAnimation(true) for the flagged bones. Here every bone's animated pose comes from the canonical
//     motion before the step; bones below simulated ones (flagged or not) are placed after it from their simulated
//     parent, which is what the second pass gives for bones without a motion of their own.
//   - Kinematic bodies follow their bones. PMX 2.0 specification (PmxEditor's PMX仕様.txt, rigid body field
//     "剛体の物理演算 - 0:ボーン追従(static) 1:物理演算(dynamic) 2:物理演算 + Bone位置合わせ"); saba
//     src/Saba/Model/MMD/MMDPhysics.cpp, MMDRigidBody::Create: mode 0 gets a KinematicMotionState (bone global
//     transform times the body's rest offset, read by Bullet every substep) and CF_KINEMATIC_OBJECT, mass 0; a body
//     that names no bone follows bone 0 and drives no bone ("kinematicNode = GetMMDNode(0); overrideNode =
//     false"). Bullet derives a kinematic body's velocity from its motion (btRigidBody::saveKinematicState), so the
//     body pushes apparel with the animated speed.
//   - MMD's gravity. saba MMDPhysics::Create: setGravity(btVector3(0, -9.8f * 10.0f, 0)): 98 PMX units/s^2 down,
//     in the model's units (1 unit ~ 8 cm), the world in which PMX masses, damping and spring constants were tuned
//     (pmx_physics_settings).
// Real models' physics is not clean: repair_pmx_physics fixes what it can, with a warning naming the body or joint.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "data_tools/builder/physics.h"
#include "data_tools/formats/canonical_rest.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/joint_map.h"
#include "data_tools/formats/pmx_import.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Repairs

/// Size (PMX units) given to a shape dimension stored as 0 or less: about 4 mm.
constexpr float kPmxMinimumBodySize = 0.05f;

/// A copy of `model` (PmxFrame::kMmd) whose physics Bullet can run, and one warning line per change in
/// `warnings`, each naming the file, the element and the field ("hero.pmx: rigid_bodies[3] 'skirt1': mass: 0 on a
/// simulated body; it follows its bone (mode 0)"):
///   - a simulated body (mode 1 or 2) of mass <= 0 follows its bone (mode 0): Bullet would make it a static body
///     left behind at its rest place (saba passes the mass as it is);
///   - a shape dimension <= 0 becomes kPmxMinimumBodySize;
///   - a body that names no bone (-1): a kinematic one follows bone 0, as in saba; a simulated one is simulated
///     and drives no bone (a warning only);
///   - damping outside [0, 1] is clamped; negative friction or restitution becomes 0; a group above 15 becomes 15;
///   - a joint naming no body, the same body twice, or two bodies that are both kinematic (after the repairs
///     above: it can move nothing) is dropped; negative spring stiffness becomes 0.
/// Non-finite numbers never get here: read_pmx refuses them. Throws amt::Error (one line: file, element, field,
/// expectation) for what cannot be repaired: a model in amt's frame, a model without bones, a joint type other
/// than PMX 2.0's spring 6-DOF.
PmxModel repair_pmx_physics(const PmxModel& model, std::vector<std::string>& warnings);

// === The character

/// A PMX model ready to pose and simulate.
///   model          the repaired model in the file's frame and units (PmxFrame::kMmd)
///   warnings       the repairs (repair_pmx_physics)
///   scale          metres per PMX unit
///   physics        pmx_physics_rig(model)
///   mesh           #V vertices, #F faces in amt's frame (metres)
///   skin           (#V) the model's own skinning over its B bones (pmx_skin_weights)
///   file_skeleton  the B bones in amt's frame (metres), names made unique ("name_7" for a repeat)
///   rest           the canonical skeleton on the model's rest joints (canonical_rest of file_skeleton)
///   carrier        (B) the canonical joint each bone follows in the bone pass: its own for a mapped bone; for a
///                  bone that inherits its rotation fully from another (MMD's "D" bones, 足D), that bone's carrier;
///                  else its parent's carrier (the pelvis above the root): rest.carrier with inheritance
///   apparel_mask   (#V) 1 for vertices on physics-driven bones (pmx_physics_apparel_mask), else 0
///   simulated_bodies  bodies in modes 1 and 2 that name a bone
struct PmxCharacter {
  std::string source;
  PmxModel model;
  std::vector<std::string> warnings;
  float scale = kPmxMetresPerUnit;
  PhysicsRig physics;
  TriMesh mesh;
  SparseWeights skin;
  Skeleton file_skeleton;
  CanonicalRest rest;
  std::vector<int> carrier;
  std::vector<uint8_t> apparel_mask;
  int simulated_bodies = 0;

  int num_bones() const { return static_cast<int>(model.bones.size()); }
  /// The canonical skeleton motions are retargeted onto (rest.skeleton).
  const Skeleton& skeleton() const { return rest.skeleton; }
};

/// The bones of a PMX model as a skeleton in the model's frame (names made unique: a repeated name gets "_<index>";
/// an empty name takes the English name). Not topological: parents as in the file.
Skeleton pmx_skeleton(const PmxModel& model);

/// The physics half of pmx_character: repairs, physics rig, mesh, skinning, file skeleton and apparel mask, without
/// the canonical skeleton (rest and carrier stay empty): enough for PmxRigSimulator's start_bones / step_bones on
/// any model, e.g. the two-bone constraint fixtures. Throws what repair_pmx_physics throws.
PmxCharacter pmx_physics_character(PmxModel model, float scale = kPmxMetresPerUnit);

/// The character of `model` (PmxFrame::kMmd, e.g. from read_pmx): pmx_physics_character, then the canonical
/// skeleton (joint names mapped by the MMD name table, or `joint_map`) and carriers. Throws amt::Error naming the
/// model for what repair_pmx_physics refuses or a skeleton that cannot be mapped onto the canonical joints.
PmxCharacter pmx_character(PmxModel model, const std::optional<JointMapFile>& joint_map = std::nullopt,
                           float scale = kPmxMetresPerUnit);

/// read_pmx then pmx_character.
PmxCharacter load_pmx_character(const std::string& path, const std::optional<JointMapFile>& joint_map = std::nullopt,
                                float scale = kPmxMetresPerUnit);

/// The bone pass: every PMX bone's animated joint transform (B transforms [R | t] in the file's frame and units,
/// see physics.h) for canonical joint transforms `canonical` (22, amt's frame, metres, on c.skeleton()): bone b
/// with carrier j gets R = S R_j S and t = R (p_b - S J_j / s) + S t_j / s, with S = diag(1, 1, -1), p_b its rest
/// position and J_j the carrier's rest joint: rigid with its carrier, exactly its joint's transform for a mapped bone.
Transforms pmx_bone_pose(const PmxCharacter& c, const Transforms& canonical);

// === Simulation

/// How a PMX character is simulated: the builder's settings (data_tools/builder/dataset_builder.h) in MMD's world
/// (pmx_physics_settings: gravity 98 units/s^2, box margin 0.04 units).
///   fps               output frame rate; one step() is 1 / fps seconds
///   physics_step      Bullet substep (seconds)
///   solver_iterations sequential-impulse iterations per substep
///   settle_seconds    seconds the bodies relax at the first pose before recording (start)
struct PmxSimulationOptions {
  float fps = 30.0f;
  float physics_step = 1.0f / 240.0f;
  int solver_iterations = 20;
  float settle_seconds = 1.0f;
};

/// The world settings of a simulation with options `o` (PMX units); throws amt::Error naming `source` and the field
/// for an option out of range.
PhysicsSettings pmx_simulation_settings(const PmxSimulationOptions& o, const std::string& source);

/// The character's Bullet world driven by canonical poses. Deterministic: start() rebuilds the world, so a clip does
/// not depend on what was simulated before (one per thread). Not copyable; movable.
class PmxRigSimulator {
 public:
  /// Builds the world from c.physics with MMD's settings and `options`. Throws amt::Error for options out of range
  /// (fps and substep > 0, iterations >= 1, settle >= 0). `c` must outlive the simulator.
  PmxRigSimulator(const PmxCharacter& c, const PmxSimulationOptions& options = {});

  /// Resets the world at the bone pass of `canonical` (22 transforms) with zero velocities and lets the bodies
  /// settle for options.settle_seconds with that pose held (MMD clips start from the rest pose and relax).
  void start(const Transforms& canonical);

  /// One output frame of 1 / fps seconds towards `canonical` (22 transforms): bone pass, physics. Returns every
  /// bone's joint transform in amt's frame (B, metres); valid until the next call.
  const Transforms& step(const Transforms& canonical);

  /// start and step from a bone pass made elsewhere: `bones` holds every PMX bone's animated joint transform in the
  /// file's frame and units (B, as pmx_bone_pose gives them). For characters without a canonical skeleton.
  void start_bones(const Transforms& bones);
  const Transforms& step_bones(const Transforms& bones);

  /// Joint transforms (amt's frame, metres, B) after the last start() or step().
  const Transforms& bone_transforms() const { return amt_; }

  /// Skinning matrices [R | t - R p_b] (B, amt's frame, p_b the bone's rest position in metres) after the last
  /// start() or step(): the dataset's rig_transforms of that frame.
  Transforms skinning() const;

  /// The world (bodies in PMX units, e.g. for tests).
  const PhysicsWorld& world() const { return world_; }

 private:
  void update();

  const PmxCharacter* character_;
  PmxSimulationOptions options_;
  PhysicsWorld world_;
  Transforms amt_;
};

/// One clip as the builder records it: start at frame 0 of `joints` (T * 22 canonical transforms, frame-major, on
/// c.skeleton()), then a step per later frame. Returns T * B skinning matrices (frame-major, amt's frame).
/// `simulator` is built on first use and reused.
Transforms simulate_pmx_clip(const PmxCharacter& c, const Transforms& joints, int frames,
                             const PmxSimulationOptions& options, std::unique_ptr<PmxRigSimulator>& simulator);

// === As a dataset character

/// (#V, 22) body weights of the model's vertices in file order, rows summing to 1: each bone's skinning weight given
/// to its carrier (weights on bones between canonical ones go to the nearest canonical ancestor, weights on apparel
/// bones to the joint their chain hangs from: what plain skinning would give apparel).
MatrixXfR pmx_body_weights(const PmxCharacter& c);

/// A group of apparel vertices hanging from one chain of physics-driven bones.
///   root_bone         the chain's top physics-driven bone (PMX index)
///   attachment_joint  the canonical joint that carries the chain's parent bone
///   chain_length      largest rest distance (metres) from the attachment joint to a vertex of the piece
///   first_vertex, end_vertex  the piece's vertices in the dataset character's order
struct PmxApparelPiece {
  int root_bone = -1;
  int attachment_joint = 0;
  float chain_length = 0;
  int first_vertex = 0, end_vertex = 0;
};

/// A PMX character in the dataset's terms. Vertices are reordered: body vertices (mask 0) first in file order,
/// then the apparel vertices piece by piece; faces whose three vertices are body vertices come first.
///   data           mesh (metres), canonical skeleton, apparel mask, body weights (N, 22): the model's weights on
///                  each bone given to its carrier (weights on bones between canonical ones go to the nearest
///                  canonical ancestor, apparel bones to the joint their chain hangs from), the full rig (B bones:
///                  PMX names made unique, parents, rest [I | p_b], the model's 4 skin weights per vertex)
///   vertex_order   (N) file vertex index of each dataset vertex
///   body_vertices, body_faces  counts of the leading body vertices and of the faces among them
///   pieces         apparel pieces by chain, in vertex order
struct PmxDatasetCharacter {
  CharacterData data;
  std::vector<int> vertex_order;
  int body_vertices = 0, body_faces = 0;
  std::vector<PmxApparelPiece> pieces;
};

/// The dataset character `name` (split "train" or "test") of `c`.
PmxDatasetCharacter pmx_dataset_character(const PmxCharacter& c, const std::string& name, const std::string& split);

}  // namespace amt
