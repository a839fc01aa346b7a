#pragma once
// Variants of a rest character for training the apparel segmenter (models/apparel_segmenter.h) to not
// depend on how a mesh is built: the same character mirrored left to right, remade of open, overlapping
// parts as real MMD models are (open_parts.h), and stripped of its apparel (a bare body, whose mask is
// all zero). Each variant carries the apparel mask over vertex by vertex.
#include <cstdint>
#include <string>
#include <vector>

#include "data_tools/builder/open_parts.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Segmenter examples

/// A rest character as the segmenter's training sees it.
///   mesh           V (N, 3) metres, F faces
///   skeleton       the rest skeleton (J joints)
///   body_weights   (N, J) skinning weights, rows sum to 1 (may be empty: 0 columns)
///   apparel_mask   N entries, 1 = apparel
struct SegmenterExample {
  TriMesh mesh;
  Skeleton skeleton;
  MatrixXfR body_weights;
  std::vector<uint8_t> apparel_mask;
};

/// The joint that mirrors `name` left to right: "left_x" <-> "right_x", any other name itself.
std::string mirrored_joint_name(const std::string& name);

/// The example mirrored through the plane x = 0 (the character's left on +X becomes its right): x
/// negated, faces' winding reversed (so normals stay outward), the joints renamed by
/// mirrored_joint_name and their positions mirrored (joint order and parents kept, each joint takes
/// the mirrored position of its mirror joint), weight columns swapped with their joints, mask kept.
/// Throws amt::Error when a joint's mirror name is missing from the skeleton.
SegmenterExample mirrored_example(const SegmenterExample& example);

/// The bare body: the vertices of the largest connected part whose mask is 0, with the faces between
/// them; mask all zero. A generated character's largest part is its body (the builder lists it first,
/// as one closed surface).
SegmenterExample bare_body_example(const SegmenterExample& example);

/// Whether the example is laid out as the builder's characters are, which bare_body_example and open_parts_example
/// assume: the canonical skeleton, and the body (the largest connected part) first, from vertex 0. An artist's model
/// read from a file is not.
bool builder_layout(const SegmenterExample& example);

/// The example remade of open, overlapping body parts (open_parts_character) from what a dataset
/// shard holds: the body is the run of leading vertices of the largest connected part, the weights'
/// columns are the 22 canonical joints. `bare` keeps the body parts and the cap alone (mask all zero).
/// Throws amt::Error when the skeleton is not the canonical one or the body is not where expected.
SegmenterExample open_parts_example(const SegmenterExample& example, bool bare = false,
                                    const OpenPartsOptions& options = {});

}  // namespace amt
