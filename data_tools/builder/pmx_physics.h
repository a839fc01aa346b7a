#pragma once
// The physics rig of a PMX model (data_tools/formats/pmx_import.h) for data_tools/builder/physics.h, in the file's own frame and
// units (PmxFrame::kMmd), where MMD simulates it and where its tuned masses, damping and springs behave as authored
// (docs/dataset.md, "Your own PMX models"). Simulated bone transforms are brought to amt's frame with pmx_transforms_to_amt.
#include <cstdint>
#include <vector>

#include "data_tools/builder/physics.h"
#include "data_tools/formats/pmx_import.h"

namespace amt {

/// The rig of `model` (which must be in PmxFrame::kMmd): every bone (name, parent, rest position), every rigid body
/// (rest transform from its position and Euler angles via pmx_euler_rotation; non_collision_mask is the complement
/// of the stored collision mask) and every joint between two bodies (joints naming body -1 are skipped, as MMD
/// does). Throws amt::Error naming the model and the element for a frame other than kMmd, a joint type other than
/// the spring 6-DOF of PMX 2.0, or a rig that fails validate_physics_rig (e.g. a simulated body of mass 0).
PhysicsRig pmx_physics_rig(const PmxModel& model);

/// (B) 1 for every physics-driven bone of `model` (as pmx_physics_apparel_mask defines them), else 0. `drivers`,
/// when given, receives the number of simulated bodies that name a bone. Any frame; never throws on a valid model.
std::vector<uint8_t> pmx_physics_driven_bones(const PmxModel& model, int* drivers = nullptr);

/// The apparel a PMX model's physics rig implies (`amt animate --apparel-mask rig`, the PMX dataset's ground
/// truth): 1 for every vertex with a non-zero weight on a physics-driven bone, else 0. A bone is physics-driven
/// when a simulated rigid body (PmxPhysicsMode kDynamic or kDynamicWithBonePosition) names it, or when it hangs
/// below such a bone without a body of its own that follows its bone (a chain's tip bone moves with the chain).
/// `drivers`, when given, receives the number of simulated bodies that name a bone. Any frame; never throws on a
/// valid model (bodies naming no bone, or a bone out of range, are skipped). All zeros when nothing is simulated.
std::vector<uint8_t> pmx_physics_apparel_mask(const PmxModel& model, int* drivers = nullptr);

/// MMD's world for a rig from pmx_physics_rig: gravity 98 PMX units/s^2 along -Y, Bullet's box margin of 0.04
/// units (mmd_physics_settings).
PhysicsSettings pmx_physics_settings();

/// Joint transforms in the PMX file's frame (PMX units, left-handed; #bones, see physics.h) to amt's frame with
/// `scale` metres per unit, as pmx_to_amt_frame maps the model: R -> S R S, t -> scale S t with S = diag(1, 1, -1).
Transforms pmx_transforms_to_amt(const Transforms& transforms, float scale = kPmxMetresPerUnit);

}  // namespace amt
