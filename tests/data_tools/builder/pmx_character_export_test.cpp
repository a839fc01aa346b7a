// A dressed procedural character as a PMX model: the mesh, skinning, bones, bodies and joints convert back to the
// character's with pmx_to_amt_frame; the MMD bone names map back onto the canonical joints; the physics rig is
// accepted and gives the character's apparel mask exactly; the file round-trips; and the rig simulated in PMX units
// under MMD's gravity stays finite with its apparel attached, moving as the procedural rig does when the units make
// MMD's gravity the procedural one (0.1 m per unit).
#include "data_tools/builder/pmx_character_export.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <string>

#include "data_tools/builder/pmx_physics.h"
#include "data_tools/formats/joint_map.h"
#include "data_tools/formats/pmx_export.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/motion.h"
#include "tests/data_tools/builder/tiny_build.h"
#include "tests/data_tools/formats/pmx_test_models.h"
#include "tests/test_support.h"

namespace amt {
namespace {

// A small character (about 1000 body vertices) in a pleated skirt (ring joints with linear limits) and twin tails.
const DressedCharacter& character() {
  static const DressedCharacter c = dress_character_with(generate_body(sample_body_params(uint64_t{1000}), 1000),
                                                         {ApparelKind::kPleatedSkirt, ApparelKind::kTwinTails}, 3);
  return c;
}

const PmxModel& exported() {
  static const PmxModel m = pmx_from_character(character());
  return m;
}

// S R S for the reflection S = diag(1, 1, -1).
Eigen::Matrix3f mirrored(const Eigen::Matrix3f& R) {
  const Eigen::Matrix3f S = Eigen::Vector3f(1, 1, -1).asDiagonal();
  return S * R * S;
}

TEST(PmxCharacterExport, MeshAndSkinningConvertBack) {
  const DressedCharacter& c = character();
  const PmxModel& m = exported();
  EXPECT_EQ(m.frame, PmxFrame::kMmd);
  const PmxModel back = pmx_to_amt_frame(m, kPmxMetresPerUnit);
  ASSERT_EQ(back.vertices.size(), c.mesh.V.rows());
  EXPECT_LT((back.vertices.positions - c.mesh.V).cwiseAbs().maxCoeff(), 1e-5f);
  EXPECT_EQ(back.faces, c.mesh.F);
  EXPECT_LT((back.vertices.normals - vertex_normals(c.mesh.V, c.mesh.F)).cwiseAbs().maxCoeff(), 1e-6f);
  const int bones = c.rig.num_bones();
  EXPECT_LT(
      (densify_weights(pmx_skin_weights(back), bones) - densify_weights(c.rig_weights, bones)).cwiseAbs().maxCoeff(),
      1e-6f);
  for (int i = 0; i < m.vertices.size(); ++i) {
    const PmxDeform d = m.vertices.deform[static_cast<size_t>(i)];
    ASSERT_TRUE(d == PmxDeform::kBdef1 || d == PmxDeform::kBdef4) << i;
  }
}

TEST(PmxCharacterExport, BodyBonesHaveMmdNamesThatMapBackToTheCanonicalJoints) {
  const DressedCharacter& c = character();
  const PmxModel& m = exported();
  ASSERT_EQ(static_cast<int>(m.bones.size()), c.rig.num_bones());
  std::vector<std::string> names;
  std::vector<int> parents;
  for (const PmxBone& b : m.bones) {
    names.push_back(b.name);
    parents.push_back(b.parent);
  }
  EXPECT_EQ(names[kPelvis], "下半身");
  EXPECT_EQ(names[kLeftShoulder], "左腕");
  EXPECT_EQ(names[kRightKnee], "右ひざ");
  EXPECT_EQ(names[kSpine2], "上半身2");
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size()) << "bone names are unique";
  const JointMapping mapping = map_to_canonical(names, parents, std::nullopt, "character.pmx");
  EXPECT_EQ(mapping.convention, "MMD");
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    EXPECT_EQ(mapping.source_joint[static_cast<size_t>(j)], j) << canonical_joint_names()[static_cast<size_t>(j)];
    const bool spine = j == kSpine1 || j == kSpine2 || j == kSpine3;
    EXPECT_EQ(mapping.kind[static_cast<size_t>(j)], spine ? JointMatchKind::kStructure : JointMatchKind::kNameTable);
  }
  const PmxModel back = pmx_to_amt_frame(m, kPmxMetresPerUnit);
  for (int b = 0; b < c.rig.num_bones(); ++b) {
    EXPECT_EQ(back.bones[static_cast<size_t>(b)].parent, c.rig.bones[static_cast<size_t>(b)].parent);
    EXPECT_LT((back.bones[static_cast<size_t>(b)].position - c.rig.bones[static_cast<size_t>(b)].rest_position)
                  .cwiseAbs()
                  .maxCoeff(),
              1e-5f)
        << b;
  }
}

TEST(PmxCharacterExport, PhysicsRigIsAcceptedAndGivesTheApparelMask) {
  const DressedCharacter& c = character();
  const PmxModel& m = exported();
  EXPECT_EQ(pmx_physics_apparel_mask(m), c.apparel_mask);
  EXPECT_EQ(pmx_physics_apparel_mask(pmx_to_amt_frame(m)), c.apparel_mask);
  const PhysicsRig rig = pmx_physics_rig(m);
  ASSERT_EQ(rig.num_bodies(), c.rig.num_bodies());
  ASSERT_EQ(rig.num_joints(), c.rig.num_joints());
  const float s = kPmxMetresPerUnit;
  const float gamma = 98.0f * s / 9.8f;  // MMD's gravity in metres over the procedural one
  for (int b = 0; b < rig.num_bodies(); ++b) {
    SCOPED_TRACE("body " + std::to_string(b));
    const PhysicsBody& source = c.rig.bodies[static_cast<size_t>(b)];
    const PmxRigidBody& body = m.rigid_bodies[static_cast<size_t>(b)];
    EXPECT_EQ(body.mode,
              source.mode == PhysicsMode::kFollowBone ? PmxPhysicsMode::kFollowBone : PmxPhysicsMode::kDynamic);
    EXPECT_EQ(body.bone, source.bone);
    EXPECT_EQ(body.group, source.group);
    EXPECT_EQ(rig.bodies[static_cast<size_t>(b)].non_collision_mask, source.non_collision_mask);
    EXPECT_FLOAT_EQ(body.mass, s * s * source.mass);
    EXPECT_EQ(body.linear_damping, source.linear_damping);
    EXPECT_TRUE((s * body.size).isApprox(source.size, 1e-5f));
    const RigidPose rest = body_rest_pose(c.rig, b);
    const RigidPose pmx_rest = body_rest_pose(rig, b);
    EXPECT_LT((pmx_to_amt_position(pmx_rest.position, s) - rest.position).norm(), 1e-5f);
    EXPECT_TRUE(mirrored(pmx_rest.rotation.toRotationMatrix()).isApprox(rest.rotation.toRotationMatrix(), 1e-5f));
  }
  for (int j = 0; j < rig.num_joints(); ++j) {
    SCOPED_TRACE("joint " + std::to_string(j));
    const PhysicsJoint& source = c.rig.joints[static_cast<size_t>(j)];
    const PhysicsJoint& joint = rig.joints[static_cast<size_t>(j)];
    EXPECT_EQ(joint.body_a, source.body_a);
    EXPECT_EQ(joint.body_b, source.body_b);
    EXPECT_LT((pmx_to_amt_position(joint.rest.position, s) - source.rest.position).norm(), 1e-5f);
    EXPECT_TRUE(
        mirrored(joint.rest.rotation.toRotationMatrix()).isApprox(source.rest.rotation.toRotationMatrix(), 1e-5f));
    Eigen::Vector3f lo, hi;
    pmx_to_amt_length_range(joint.linear_min, joint.linear_max, s, lo, hi);
    EXPECT_TRUE(lo.isApprox(source.linear_min, 1e-5f) || (lo - source.linear_min).norm() < 1e-6f);
    EXPECT_TRUE(hi.isApprox(source.linear_max, 1e-5f) || (hi - source.linear_max).norm() < 1e-6f);
    pmx_to_amt_angle_range(joint.angular_min, joint.angular_max, lo, hi);
    EXPECT_EQ(lo, source.angular_min);
    EXPECT_EQ(hi, source.angular_max);
    EXPECT_TRUE((joint.angular_stiffness / gamma).isApprox(source.angular_stiffness, 1e-5f) ||
                source.angular_stiffness.isZero());
    EXPECT_TRUE((joint.linear_stiffness / (gamma * s * s)).isApprox(source.linear_stiffness, 1e-5f) ||
                source.linear_stiffness.isZero());
  }
}

TEST(PmxCharacterExport, FileRoundTripGivesTheSameModelAndBytes) {
  const std::filesystem::path dir = test::temp_dir("pmx_character_export");
  const std::string path = (dir / "character.pmx").string();
  write_pmx(exported(), path);
  const PmxModel read = read_pmx(path);
  test::expect_same_model(exported(), read);
  EXPECT_EQ(read.header.encoding, PmxTextEncoding::kUtf16Le);
  const std::vector<uint8_t> bytes = pmx_to_bytes(read);
  EXPECT_EQ(test::read_file_bytes(path), std::string(bytes.begin(), bytes.end()));
}

TEST(PmxCharacterExport, DatasetCharacterIsTheBuildersAndBadInputIsAnError) {
  const DatasetBuildOptions options = test::tiny_build_options("unused", 3);
  const DressedCharacter c = dataset_character(options, 2);
  const DatasetPlan plan = plan_dataset(options, {});
  const DressedCharacter expected =
      dress_character(generate_body(sample_body_params(plan.characters[2].body_seed), options.vertices),
                      plan.characters[2].apparel_seed, options.apparel);
  EXPECT_EQ(c.mesh.V, expected.mesh.V);
  EXPECT_EQ(c.apparel_mask, expected.apparel_mask);
  EXPECT_EQ(test::error_of([&] { dataset_character(options, 3); }),
            "dataset character: expected an index from 0 to 2, found 3");
  PmxCharacterExportOptions export_options;
  export_options.metres_per_unit = 0;
  EXPECT_EQ(test::error_of([&] { pmx_from_character(character(), export_options); }),
            "pmx_from_character: metres_per_unit: expected a finite value > 0, found 0");
}

// === Simulation

// The whole body swung side to side and turned about the vertical through the pelvis (joint transforms of every
// rig bone in amt's frame, metres): a simple motion that makes the apparel swing.
Transforms swung_pose(const PhysicsRig& rig, float t) {
  const float pi = 3.14159265f;
  const Eigen::Vector3f centre = rig.bones[kPelvis].rest_position;
  const Eigen::Matrix3f R = Eigen::AngleAxisf(0.6f * std::sin(2 * pi * t), Eigen::Vector3f::UnitY()).toRotationMatrix();
  const Eigen::Vector3f shift(0.15f * std::sin(2 * pi * 1.3f * t), 0.05f * std::sin(2 * pi * t), 0);
  Transforms pose;
  for (const PhysicsBone& b : rig.bones)
    pose.push_back(make_transform(R, R * (b.rest_position - centre) + centre + shift));
  return pose;
}

// Simulates the character's rig in metres (the builder's world) and the exported rig in PMX units (MMD's world)
// under the same motion; returns the largest distance (metres) between their bone positions over `frames` frames at
// 30 fps, after checking every frame is finite and every apparel bone stays near its parent.
float simulate_both(const DressedCharacter& c, float metres_per_unit, int frames) {
  PmxCharacterExportOptions options;
  options.metres_per_unit = metres_per_unit;
  const PmxModel model = pmx_from_character(c, options);
  PhysicsWorld procedural(c.rig);
  PhysicsWorld mmd(pmx_physics_rig(model), pmx_physics_settings());
  const float to_units = 1.0f / metres_per_unit;
  procedural.reset(swung_pose(c.rig, 0));
  mmd.reset(pmx_transforms_to_amt(swung_pose(c.rig, 0), to_units));  // the same map back, S and 1 / scale
  float largest = 0;
  for (int frame = 1; frame <= frames; ++frame) {
    const Transforms pose = swung_pose(c.rig, frame / 30.0f);
    procedural.set_bone_pose(pose);
    procedural.step(1.0f / 30.0f);
    mmd.set_bone_pose(pmx_transforms_to_amt(pose, to_units));
    mmd.step(1.0f / 30.0f);
    const Transforms simulated = pmx_transforms_to_amt(mmd.bone_transforms(), metres_per_unit);
    for (int b = 0; b < c.rig.num_bones(); ++b) {
      const Eigen::Vector3f p = simulated[static_cast<size_t>(b)].col(3);
      EXPECT_TRUE(simulated[static_cast<size_t>(b)].allFinite()) << "frame " << frame << " bone " << b;
      const int parent = c.rig.bones[static_cast<size_t>(b)].parent;
      if (b >= kCanonicalJointCount) {  // apparel stays attached: a bone keeps about its rest distance to its parent
        const float rest =
            (c.rig.bones[static_cast<size_t>(b)].rest_position - c.rig.bones[static_cast<size_t>(parent)].rest_position)
                .norm();
        const float now = (p - Eigen::Vector3f(simulated[static_cast<size_t>(parent)].col(3))).norm();
        EXPECT_LT(std::abs(now - rest), 0.2f * rest + 0.01f) << "frame " << frame << " bone " << b;
      }
      largest =
          std::max(largest, (p - Eigen::Vector3f(procedural.bone_transforms()[static_cast<size_t>(b)].col(3))).norm());
    }
  }
  return largest;
}

TEST(PmxCharacterExport, SimulatedInPmxUnitsStaysFiniteAndAttached) {
  const float largest = simulate_both(character(), kPmxMetresPerUnit, 30);
  // MMD's gravity is 0.8 times the procedural one at 0.08 m per unit: the swings differ, but not by much.
  std::printf("bones of the PMX rig at 0.08 m per unit vs the procedural rig over 1 s: %.4f m apart at most\n",
              largest);
  EXPECT_LT(largest, 0.25f);
}

TEST(PmxCharacterExport, MovesAsTheProceduralRigAtATenthOfAMetrePerUnit) {
  // Without contacts (twin tails swinging free of the body for the first frames) the change of units is exact up
  // to float rounding.
  const DressedCharacter tails =
      dress_character_with(generate_body(sample_body_params(uint64_t{1000}), 1000), {ApparelKind::kTwinTails}, 3);
  EXPECT_LT(simulate_both(tails, 0.1f, 5), 1e-4f);
  // With contacts (a skirt on the legs) Bullet's absolute contact thresholds (metres in one world, PMX units in the
  // other) make the two drift apart slowly: 2.7 cm after 1 s of swinging when this test was written.
  const float largest = simulate_both(character(), 0.1f, 30);
  std::printf("bones of the PMX rig at 0.1 m per unit vs the procedural rig over 1 s: %.4f m apart at most\n", largest);
  EXPECT_LT(largest, 0.05f);
}

}  // namespace
}  // namespace amt
