#pragma once
// Procedural apparel for generated bodies, built as MMD artists build it (docs/dataset.md, "What the builder makes"):
// skirts, long hair, twin tails, capes, sleeves, ribbons and coat tails, each a mesh skinned to chains of apparel bones
// that carry dynamic rigid bodies, hung from the body's bones by spring 6-DOF joints; and kinematic collision capsules
// on the body bones that approximate the generated body surface. The result is a DressedCharacter: the dressed mesh,
// its apparel mask, ground-truth body weights, the physics rig and the rig skinning that the dataset stores.
//
// Conventions: metres, Y up, facing +Z (data_tools/builder/body_generator.h). Rig bones 0..21 are the canonical joints
// in order at the skeleton's rest positions; apparel bones follow, every bone after its parent. A bone's rest transform
// is [I | rest position] (rotations are relative to rest, as everywhere in the project), so a bone's skinning matrix is
// [R | t - R rest_position] for its posed joint transform [R | t].
#include <cstdint>
#include <string>
#include <vector>

#include "data_tools/builder/body_generator.h"
#include "data_tools/builder/physics.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Apparel kinds

/// The kinds of apparel pieces dress_character draws from.
enum class ApparelKind : uint8_t {
  kPleatedSkirt,  ///< a ring of chains around the pelvis with ring joints, pleated; waist band (body-connected)
  kFlaredSkirt,   ///< the same, wider flare and no pleats (body-connected)
  kHairSheet,     ///< a sheet of long hair from the back of the head (separate mesh)
  kHairStrands,   ///< separate tube strands from the back and sides of the head
  kTwinTails,     ///< two thick tapered tubes from the sides of the head
  kCape,          ///< a sheet from the shoulders (spine3) down the back (separate mesh)
  kSleeves,       ///< a flared sleeve around one forearm, hanging from the elbow, with an elbow band (connected)
  kRibbons,       ///< two narrow ribbons from a wrist, the back of the head or the back of the waist (separate)
  kCoatTails,     ///< two flaps at the back from the pelvis, with a band across the back (body-connected)
};

/// Number of ApparelKind values.
constexpr int kApparelKindCount = 9;

/// The kind's snake_case name: "pleated_skirt", "flared_skirt", "hair_sheet", "hair_strands", "twin_tails",
/// "cape", "sleeves", "ribbons", "coat_tails" ("unknown" for a value out of range).
const char* apparel_kind_name(ApparelKind kind);

// === Options

/// The counts that fix the connectivity of a dressed character's apparel, which dress_character otherwise
/// measures on the body (skirt bones from the skirt's length, sheet grids from the sheets' width and length,
/// vertex budgets from the body's vertex count). Dressing another body with the same seed, options and
/// topology gives apparel of the same connectivity, only positions differ: one garment template on several
/// bodies (cloth retargeting's pair sets, data_tools/builder/garment_pairs.h).
struct ApparelTopology {
  /// Vertex count of the body the budgets were computed for.
  int body_vertices = 0;
  /// Bones per chain of each piece (in DressedCharacter::pieces order, before the max_bodies trim).
  std::vector<int> bones;
  /// Rows and columns of each sheet's grid, in build order (piece by piece).
  std::vector<Eigen::Vector2i> sheets;
  bool empty() const { return bones.empty(); }
};

/// Choices of dress_character.
struct ApparelOptions {
  /// Number of apparel items drawn, uniformly in [min_pieces, max_pieces] (1 <= min <= max <= 6). Sleeves give one
  /// piece per arm, so a character can have more pieces than items.
  int min_pieces = 1;
  int max_pieces = 3;
  /// Kinds to draw from (distinct items; a skirt excludes the other skirt kind). Empty: every kind.
  std::vector<ApparelKind> kinds;
  /// Target share of apparel-and-garment vertices in the dressed mesh, in [0.05, 0.8]: the apparel meshes get
  /// about fraction / (1 - fraction) times the body's vertex count, shared between the pieces.
  float vertex_fraction = 0.3f;
  /// Cap on the number of dynamic apparel bodies (= apparel bones) over all pieces, >= 4; pieces use fewer chains
  /// and bones to fit.
  int max_bodies = 100;
  /// Gap (metres, >= 0) kept at rest between an apparel body's surface and the body collision capsules.
  float clearance = 0.006f;
  /// How much (metres, >= 0) the body collision capsules exceed the body surface they were fitted to.
  float capsule_margin = 0.006f;
  /// Scale (> 0) on the angular spring stiffness of apparel joints: higher is stiffer, less lag.
  float stiffness_scale = 1.0f;
  /// Scale (> 0) on the damping of apparel bodies (clamped to [0, 1] after scaling).
  float damping_scale = 1.0f;
  /// Per-piece spread of the physics, in [0, 4]: each piece's body mass, damping, spring stiffness and angular
  /// limits are multiplied by their own factors drawn log-uniformly in [1 / (1 + v), 1 + v] (damping clamped to
  /// [0, 1], limits to 80 degrees),
  /// from a stream of the seed apart from the layout's draws. 0 (the default): every piece of a kind has the
  /// kind's physics, and the dressing is what it was before this option existed.
  float physics_variation = 0.0f;
  /// When not empty: the counts of another dressing (DressedCharacter::topology) used instead of the ones
  /// measured on this body. Throws amt::Error when the items drawn do not fit it (another seed or options).
  ApparelTopology topology;
};

/// Throws amt::Error naming the field unless the options are in the ranges documented above.
void validate_apparel_options(const ApparelOptions& options);

// === Dressed character

/// One apparel piece of a dressed character.
struct ApparelPiece {
  ApparelKind kind;
  /// Part of a body-connected garment: its mesh is connected to body-skinned (mask 0) garment vertices.
  bool connected_to_body = false;
  /// Canonical joint the piece hangs from (its first joints attach to this joint's collision body).
  int32_t attachment_joint = 0;
  /// Rig bone index of the first bone of each chain.
  std::vector<int32_t> chain_roots;
  /// Longest reach of a chain from the attachment joint (metres): the distance from the joint to the chain's root
  /// plus the chain's length along its bones. Every vertex of the piece is within this distance of the attachment
  /// joint's position at rest (up to the sheet's width between chains), so a vertex farther than 1.5 times it
  /// means the simulation stretched or exploded (the builder's "no explosions" gate).
  float chain_length = 0.0f;
  /// First and one-past-last vertex of the piece's mesh (apparel and its garment band) in DressedCharacter::mesh.
  int32_t first_vertex = 0;
  int32_t end_vertex = 0;
};

/// A generated body dressed with apparel, with everything the dataset and the simulation need.
struct DressedCharacter {
  /// The naked body it was dressed from.
  GeneratedBody body;
  /// Body vertices first, in body.mesh order (same indices), then garment and apparel vertices, piece by piece.
  /// Apparel meshes are two-sided thin sheets or closed tubes; they are separate components except where a garment
  /// band connects them.
  TriMesh mesh;
  /// (N) 1 exactly for vertices with a non-zero skinning weight on an apparel (simulated) bone, else 0.
  std::vector<uint8_t> apparel_mask;
  /// (N, 22) ground-truth body skinning, rows sum to 1: body vertices carry body.weights, garment bands (mask 0)
  /// their rig weights; apparel vertices what plain skinning would give them: the weights of the nearest body
  /// vertex for body-connected garments, the attachment joint for separate pieces.
  MatrixXfR body_weights;
  /// Bones 0..21 = the canonical joints in order (kinematic capsule bodies on body bones, group 0), then apparel
  /// bones (one dynamic body each, group 1, not colliding with other apparel) joined by spring 6-DOF joints: the
  /// first of each chain to its attachment joint's body, then bone to bone, plus ring joints between neighbouring
  /// chains of skirts, capes, hair sheets and coat tails.
  PhysicsRig rig;
  /// (N) skinning over the rig bones, <= 4 influences, rows sum to 1 (body vertices: their body weights).
  SparseWeights rig_weights;
  std::vector<ApparelPiece> pieces;
  /// (N) index into pieces of each apparel vertex (mask 1), -1 for body and garment vertices (mask 0).
  std::vector<int32_t> vertex_piece;
  /// Index of each canonical joint's main collision body in rig.bodies (22 entries, all valid).
  std::vector<int32_t> joint_body;
  /// The counts that fixed the apparel's connectivity (pass as ApparelOptions::topology to dress another body
  /// with the same garment).
  ApparelTopology topology;

  /// The dataset_file.h Rig: bone names and parents, rest transforms [I | rest position], skin indices and weights
  /// (N, 4) from rig_weights.
  Rig dataset_rig() const;
  /// The dataset character: mesh, body.skeleton, apparel mask, body weights, dataset_rig(), `name` and `split`.
  CharacterData character_data(const std::string& name, const std::string& split) const;
  /// Number of dynamic (apparel) bodies in the rig.
  int num_apparel_bodies() const;
};

/// Kinematic collision capsules (PhysicsMode::kFollowBone, group 0, no contact among themselves) on the body's
/// bones, fitted to the generated surface: one capsule per bone segment (spine, neck, limbs, hands, feet) and one
/// for the head, each enclosing the surface near its segment plus `margin` metres. Bodies are listed in canonical
/// joint order of their bones; `joint_body` (if given) receives each joint's main body index (22 entries; joints
/// without their own segment, such as the feet, take the body of the nearest segment they are on).
std::vector<PhysicsBody> body_collision_capsules(const GeneratedBody& body, float margin,
                                                 std::vector<int32_t>* joint_body = nullptr);

/// Dresses `body` with apparel items drawn from `seed`: kinds, sizes (scaled with the body's proportions: skirt
/// length from the legs, hair from the head size), resolution and physics. Apparel starts outside the body and its
/// collision capsules. Deterministic: the same body, seed and options give bit-identical results. Throws amt::Error
/// on invalid options or a body that does not have the canonical skeleton.
DressedCharacter dress_character(const GeneratedBody& body, uint64_t seed, const ApparelOptions& options = {});

/// The same with exactly the given items (one entry per item; sleeves give a piece per arm), for tests and tools.
DressedCharacter dress_character_with(const GeneratedBody& body, const std::vector<ApparelKind>& items, uint64_t seed,
                                      const ApparelOptions& options = {});

}  // namespace amt
