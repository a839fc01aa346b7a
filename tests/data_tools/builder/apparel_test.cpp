#include "data_tools/builder/apparel.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>
#include <string>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/winding_number.h"
#include "tests/test_support.h"

namespace amt {
namespace {

// One small body per process: a chibi (seed 1000) and a taller adult (seed 1009) of 1500 vertices.
const GeneratedBody& test_body(int which = 0) {
  static const GeneratedBody chibi = generate_body(sample_body_params(uint64_t{1000}), 1500);
  static const GeneratedBody adult = generate_body(sample_body_params(uint64_t{1009}), 1500);
  return which == 0 ? chibi : adult;
}

// Checks everything a valid dressed character promises; `what` names it in failures.
void expect_valid(const DressedCharacter& c, const std::string& what) {
  SCOPED_TRACE(what);
  const int nb = c.body.mesh.num_vertices();
  const int n = c.mesh.num_vertices();
  ASSERT_GT(n, nb);
  EXPECT_NO_THROW(validate_mesh(c.mesh, what));
  EXPECT_TRUE(c.mesh.V.topRows(nb).isApprox(c.body.mesh.V, 0.0f));
  ASSERT_EQ(static_cast<int>(c.apparel_mask.size()), n);
  ASSERT_EQ(static_cast<int>(c.vertex_piece.size()), n);
  ASSERT_EQ(c.rig_weights.num_vertices(), n);
  ASSERT_EQ(c.body_weights.rows(), n);
  ASSERT_EQ(c.body_weights.cols(), kCanonicalJointCount);
  EXPECT_NO_THROW(validate_physics_rig(c.rig, what));
  ASSERT_GE(c.rig.num_bones(), kCanonicalJointCount);
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    EXPECT_EQ(c.rig.bones[j].name, canonical_joint_names()[j]);
    EXPECT_EQ(c.rig.bones[j].parent, canonical_joint_parents()[j]);
    EXPECT_TRUE(c.rig.bones[j].rest_position.isApprox(c.body.skeleton.rest_joints.row(j).transpose()));
  }
  for (int b = kCanonicalJointCount; b < c.rig.num_bones(); ++b) EXPECT_LT(c.rig.bones[b].parent, b);
  // Apparel bodies are simulated, body bodies kinematic and on body bones.
  for (const PhysicsBody& body : c.rig.bodies) {
    if (body.bone < kCanonicalJointCount) {
      EXPECT_EQ(body.mode, PhysicsMode::kFollowBone) << body.name;
    } else {
      EXPECT_EQ(body.mode, PhysicsMode::kDynamic) << body.name;
    }
  }
  int apparel = 0;
  for (int v = 0; v < n; ++v) {
    float sum = 0, body_sum = 0;
    bool on_apparel_bone = false;
    for (int k = 0; k < kMaxInfluences; ++k) {
      const int b = c.rig_weights.indices(v, k);
      const float w = c.rig_weights.weights(v, k);
      ASSERT_GE(b, 0);
      ASSERT_LT(b, c.rig.num_bones());
      ASSERT_GE(w, 0.0f);
      sum += w;
      if (w > 0 && b >= kCanonicalJointCount) on_apparel_bone = true;
    }
    for (int j = 0; j < kCanonicalJointCount; ++j) body_sum += c.body_weights(v, j);
    ASSERT_NEAR(sum, 1.0f, 1e-5f) << "vertex " << v;
    ASSERT_NEAR(body_sum, 1.0f, 1e-5f) << "vertex " << v;
    // The mask says exactly which vertices simulated bones drive, and vertex_piece agrees with it.
    ASSERT_EQ(c.apparel_mask[v], on_apparel_bone ? 1 : 0) << "vertex " << v;
    ASSERT_EQ(c.vertex_piece[v] >= 0, c.apparel_mask[v] == 1) << "vertex " << v;
    if (v < nb) {
      ASSERT_EQ(c.apparel_mask[v], 0);
    }
    apparel += c.apparel_mask[v];
  }
  EXPECT_GT(apparel, 0);
  // Pieces: vertex ranges tile the apparel part of the mesh; chains start with bones hanging from the body.
  int next = nb;
  for (size_t p = 0; p < c.pieces.size(); ++p) {
    const ApparelPiece& piece = c.pieces[p];
    EXPECT_EQ(piece.first_vertex, next);
    EXPECT_GT(piece.end_vertex, piece.first_vertex);
    next = piece.end_vertex;
    ASSERT_FALSE(piece.chain_roots.empty());
    for (int root : piece.chain_roots) {
      ASSERT_GE(root, kCanonicalJointCount);
      EXPECT_EQ(c.rig.bones[root].parent, piece.attachment_joint);
    }
    // At rest every vertex of the piece is within its reach of the attachment joint (well under the 1.5 bound).
    const Eigen::Vector3f joint = c.body.skeleton.rest_joints.row(piece.attachment_joint).transpose();
    for (int v = piece.first_vertex; v < piece.end_vertex; ++v) {
      EXPECT_LT((c.mesh.V.row(v).transpose() - joint).norm(), 1.2f * piece.chain_length) << "vertex " << v;
      if (c.vertex_piece[v] >= 0) {
        EXPECT_EQ(c.vertex_piece[v], static_cast<int>(p));
      }
    }
  }
  EXPECT_EQ(next, n);
  // Apparel and garment vertices start outside the body.
  const WindingNumberTree tree(c.body.mesh.V, c.body.mesh.F);
  int inside = 0;
  for (int v = nb; v < n; ++v) inside += tree.inside(c.mesh.V.row(v).transpose()) ? 1 : 0;
  EXPECT_EQ(inside, 0);
}

TEST(Apparel, KindNamesAreDistinct) {
  std::set<std::string> names;
  for (int k = 0; k < kApparelKindCount; ++k) names.insert(apparel_kind_name(static_cast<ApparelKind>(k)));
  EXPECT_EQ(names.size(), static_cast<size_t>(kApparelKindCount));
  EXPECT_STREQ(apparel_kind_name(ApparelKind::kPleatedSkirt), "pleated_skirt");
  EXPECT_STREQ(apparel_kind_name(ApparelKind::kCoatTails), "coat_tails");
}

TEST(Apparel, CollisionCapsulesEncloseTheBodySurface) {
  const GeneratedBody& body = test_body(1);
  std::vector<int32_t> joint_body;
  const float margin = 0.006f;
  const std::vector<PhysicsBody> caps = body_collision_capsules(body, margin, &joint_body);
  ASSERT_EQ(joint_body.size(), static_cast<size_t>(kCanonicalJointCount));
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    ASSERT_GE(joint_body[j], 0);
    ASSERT_LT(joint_body[j], static_cast<int>(caps.size()));
  }
  // Every capsule is kinematic, on a body bone, and no thicker than a fifth of the height.
  for (const PhysicsBody& c : caps) {
    EXPECT_EQ(c.mode, PhysicsMode::kFollowBone);
    EXPECT_EQ(c.shape, PhysicsShape::kCapsule);
    EXPECT_LT(c.size.x(), 0.2f * body.params.height) << c.name;
  }
  // Most surface vertices lie inside the union of the capsules (they are fitted slightly larger than the
  // surface); the rest lie within a couple of centimetres (blends between parts, fingertips).
  int inside = 0;
  float worst = 0;
  for (int v = 0; v < body.mesh.num_vertices(); ++v) {
    const Eigen::Vector3f p = body.mesh.V.row(v).transpose();
    float best = 1e9f;
    for (const PhysicsBody& c : caps) {
      const Eigen::Vector3f axis = c.rest.rotation * Eigen::Vector3f::UnitY();
      const Eigen::Vector3f a = c.rest.position - 0.5f * c.size.y() * axis;
      const float t = std::clamp((p - a).dot(axis), 0.0f, c.size.y());
      best = std::min(best, (p - (a + t * axis)).norm() - c.size.x());
    }
    inside += best <= 0 ? 1 : 0;
    worst = std::max(worst, best);
  }
  EXPECT_GT(inside, 0.9 * body.mesh.num_vertices());
  EXPECT_LT(worst, 0.03f);
}

TEST(Apparel, DressingIsDeterministicAndValid) {
  const DressedCharacter a = dress_character(test_body(0), 42);
  const DressedCharacter b = dress_character(test_body(0), 42);
  expect_valid(a, "seed 42");
  EXPECT_TRUE(a.mesh.V == b.mesh.V);
  EXPECT_TRUE(a.mesh.F == b.mesh.F);
  EXPECT_TRUE(a.rig_weights.weights == b.rig_weights.weights);
  EXPECT_TRUE(a.rig_weights.indices == b.rig_weights.indices);
  EXPECT_TRUE(a.body_weights == b.body_weights);
  ASSERT_EQ(a.rig.num_bodies(), b.rig.num_bodies());
  for (int i = 0; i < a.rig.num_bodies(); ++i) {
    EXPECT_TRUE(a.rig.bodies[i].size == b.rig.bodies[i].size);
    EXPECT_TRUE(a.rig.bodies[i].rest.position == b.rig.bodies[i].rest.position);
  }
  // Another seed dresses differently.
  const DressedCharacter c = dress_character(test_body(0), 43);
  EXPECT_FALSE(c.mesh.num_vertices() == a.mesh.num_vertices() && c.mesh.V == a.mesh.V);
}

TEST(Apparel, EveryKindCanBeGenerated) {
  for (int k = 0; k < kApparelKindCount; ++k) {
    const ApparelKind kind = static_cast<ApparelKind>(k);
    const DressedCharacter c = dress_character_with(test_body(k % 2), {kind}, 5);
    expect_valid(c, apparel_kind_name(kind));
    ASSERT_FALSE(c.pieces.empty());
    for (const ApparelPiece& p : c.pieces) EXPECT_EQ(p.kind, kind);
    const bool connected = kind == ApparelKind::kPleatedSkirt || kind == ApparelKind::kFlaredSkirt ||
                           kind == ApparelKind::kSleeves || kind == ApparelKind::kCoatTails;
    EXPECT_EQ(c.pieces[0].connected_to_body, connected) << apparel_kind_name(kind);
    EXPECT_EQ(c.pieces.size(), kind == ApparelKind::kSleeves ? 2u : 1u);
    // Body-connected garments have body-skinned band vertices in the piece's mesh, separate pieces have only
    // the root rows (which sit on the attachment joint).
    int garment = 0;
    for (int v = c.pieces[0].first_vertex; v < c.pieces[0].end_vertex; ++v) garment += c.apparel_mask[v] ? 0 : 1;
    EXPECT_GT(garment, 0);
  }
  // Skirts have ring joints: more joints than bones.
  const DressedCharacter skirt = dress_character_with(test_body(1), {ApparelKind::kPleatedSkirt}, 3);
  EXPECT_GT(skirt.rig.num_joints(), skirt.num_apparel_bodies());
  EXPECT_GE(skirt.pieces[0].chain_roots.size(), 8u);
}

TEST(Apparel, BudgetsOfVerticesAndBodies) {
  ApparelOptions options;
  options.min_pieces = 3;
  options.max_pieces = 3;
  options.max_bodies = 40;
  const DressedCharacter c = dress_character(test_body(1), 9, options);
  EXPECT_LE(c.num_apparel_bodies(), 40);
  const int added = c.mesh.num_vertices() - c.body.mesh.num_vertices();
  const float share = static_cast<float>(added) / c.mesh.num_vertices();
  EXPECT_GT(share, 0.15f);
  EXPECT_LT(share, 0.45f);
}

TEST(Apparel, CharacterDataIsAcceptedByTheDatasetWriter) {
  const DressedCharacter c = dress_character_with(test_body(0), {ApparelKind::kTwinTails, ApparelKind::kCape}, 2);
  const CharacterData data = c.character_data("dressed", "train");
  ASSERT_TRUE(data.rig.has_value());
  EXPECT_EQ(data.rig->num_bones(), c.rig.num_bones());
  const std::string path = (test::temp_dir("apparel_writer") / "d.h5").string();
  DatasetWriter writer(path, 30.0f, canonical_joint_names());
  EXPECT_NO_THROW(writer.add_character(data));
  writer.commit();
  DatasetReader reader(path);
  const CharacterData back = reader.read_character("dressed");
  EXPECT_TRUE(back.apparel_mask == c.apparel_mask);
  EXPECT_TRUE(back.rig->skin_indices == c.rig_weights.indices);
}

TEST(Apparel, PhysicsVariationScalesEachPieceWithinItsBoundsAndChangesNothingElse) {
  ApparelOptions varied;
  varied.physics_variation = 0.5f;
  varied.min_pieces = 3;
  const ApparelOptions plain = [&] {
    ApparelOptions o = varied;
    o.physics_variation = 0;
    return o;
  }();
  const DressedCharacter a = dress_character(test_body(1), 42, plain);
  const DressedCharacter b = dress_character(test_body(1), 42, varied);
  EXPECT_TRUE(a.mesh.V == b.mesh.V);  // the layout's draws are untouched
  EXPECT_TRUE(a.rig_weights.weights == b.rig_weights.weights);
  ASSERT_EQ(a.rig.num_bodies(), b.rig.num_bodies());
  ASSERT_EQ(a.rig.num_joints(), b.rig.num_joints());
  EXPECT_TRUE(dress_character(test_body(1), 42, varied).rig.bodies.back().mass == b.rig.bodies.back().mass);
  // Per piece (bones named <kind><index>_c...): one mass factor and one damping factor, within [1/1.5, 1.5].
  std::map<std::string, std::set<float>> mass_factors, damping_factors;
  for (int i = 0; i < a.rig.num_bodies(); ++i) {
    const PhysicsBody &x = a.rig.bodies[i], &y = b.rig.bodies[i];
    if (x.mode == PhysicsMode::kFollowBone) {
      EXPECT_EQ(x.mass, y.mass);
      continue;
    }
    const std::string piece = x.name.substr(0, x.name.find("_c"));
    const float m = y.mass / x.mass, d = y.angular_damping / x.angular_damping;
    EXPECT_GE(m, 1 / 1.5f - 1e-5f) << x.name;
    EXPECT_LE(m, 1.5f + 1e-5f) << x.name;
    EXPECT_GE(d, 1 / 1.5f - 1e-5f) << x.name;
    EXPECT_LE(d, 1.5f + 1e-5f) << x.name;
    mass_factors[piece].insert(std::round(m * 1e4f) / 1e4f);
    damping_factors[piece].insert(std::round(d * 1e4f) / 1e4f);
  }
  ASSERT_GE(mass_factors.size(), 2u);
  std::set<float> pieces_factors;
  for (const auto& [piece, factors] : mass_factors) {
    EXPECT_EQ(factors.size(), 1u) << piece;
    EXPECT_EQ(damping_factors[piece].size(), 1u) << piece;
    pieces_factors.insert(*factors.begin());
  }
  EXPECT_EQ(pieces_factors.size(), mass_factors.size());  // each piece draws its own
  // Stiffness: the spring is stiffness x the chain's gravity torque (which carries the mass), so the joint's
  // factor is the mass factor times the stiffness factor: two factors within [1/1.5, 1.5] each.
  for (int k = 0; k < a.rig.num_joints(); ++k) {
    const float x = a.rig.joints[k].angular_stiffness.x(), y = b.rig.joints[k].angular_stiffness.x();
    if (x == 0) continue;
    EXPECT_GE(y / x, 1 / 2.25f - 1e-4f) << a.rig.joints[k].name;
    EXPECT_LE(y / x, 2.25f + 1e-4f) << a.rig.joints[k].name;
  }
  // Angular limits: the piece's own factor within [1/1.5, 1.5], at most 80 degrees.
  int changed = 0;
  for (int k = 0; k < a.rig.num_joints(); ++k) {
    for (int axis = 0; axis < 3; ++axis) {
      const float x = a.rig.joints[k].angular_max(axis), y = b.rig.joints[k].angular_max(axis);
      if (!(x > 0) || a.rig.joints[k].angular_min(axis) > x) continue;  // locked or free
      EXPECT_GE(y / x, 1 / 1.5f - 1e-4f) << a.rig.joints[k].name;
      EXPECT_LE(y / x, 1.5f + 1e-4f) << a.rig.joints[k].name;
      EXPECT_LE(y, 80.0f * 3.14159265f / 180.0f + 1e-5f) << a.rig.joints[k].name;
      changed += std::abs(y / x - 1) > 1e-3f;
    }
  }
  EXPECT_GT(changed, 0);
}

TEST(Apparel, BadOptionsGiveErrors) {
  ApparelOptions o;
  o.min_pieces = 0;
  EXPECT_NE(test::error_of([&] { dress_character(test_body(0), 1, o); }).find("min_pieces"), std::string::npos);
  o = {};
  o.max_pieces = 0;
  EXPECT_NE(test::error_of([&] { dress_character(test_body(0), 1, o); }).find("max_pieces"), std::string::npos);
  o = {};
  o.vertex_fraction = 0.95f;
  EXPECT_NE(test::error_of([&] { dress_character(test_body(0), 1, o); }).find("vertex_fraction"), std::string::npos);
  o = {};
  o.stiffness_scale = std::nanf("");
  EXPECT_NE(test::error_of([&] { dress_character(test_body(0), 1, o); }).find("stiffness_scale"), std::string::npos);
  o = {};
  o.physics_variation = 5;
  EXPECT_EQ(test::error_of([&] { dress_character(test_body(0), 1, o); }),
            "apparel options: physics_variation: expected a value in [0, 4], found 5");
  EXPECT_NE(test::error_of([&] { dress_character_with(test_body(0), {}, 1); }).find("at least one"), std::string::npos);
  GeneratedBody broken = test_body(0);
  broken.skeleton.names[3] = "chest";
  EXPECT_NE(test::error_of([&] { dress_character(broken, 1); }).find("canonical"), std::string::npos);
}

}  // namespace
}  // namespace amt
