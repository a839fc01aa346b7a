#pragma once
// A dressed generated character remade the way real MMD/PMX characters are built: the body is not one
// closed surface but many open, overlapping parts. Real models cannot be redistributed, so the runtime's
// figures on "real meshes" (issue 17, item 5) and the tests of the penetration resolution on open bodies
// use this stand-in (`amt bench --suite runtime --open-parts`).
//
// From a DressedCharacter (data_tools/builder/apparel.h):
//   - the body surface is cut into one part per dominant joint (the joint with the largest summed weight
//     over a face's corners); every part gets its own copy of its vertices, so seams are open boundaries,
//     as a model's material or UV splits leave them;
//   - each part also takes the ring of faces around it from its neighbours, with the borrowed vertices
//     moved `overlap_inset` metres inwards: neighbouring parts overlap and cross each other, as a neck
//     pushed into a head or a hand into a cuff;
//   - body faces nearer than `hole_distance` to the clothes at rest (garment bands and apparel) are
//     dropped, holes where a modeller deletes the skin under clothing;
//   - a separate open hair cap, a dome over the top and back of the head that cuts through the head
//     surface, is added as a body part skinned rigidly to the head.
// Garment bands and apparel are kept as they are (same faces, same order, after the body parts).
#include <cstdint>
#include <vector>

#include "data_tools/builder/apparel.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Open-parts character

/// Choices of open_parts_character.
///   hole_distance   body faces whose centroid is nearer than this to a garment or apparel face at rest
///                   are dropped (metres, >= 0; 0 keeps every face)
///   overlap_inset   how far inwards (metres, >= 0) the vertices a part borrows from its neighbours'
///                   seam ring are moved along the rest normal
///   head_cap        add the hair cap
///   cap_scale       cap radius over the head part's median distance to its centroid (> 0)
struct OpenPartsOptions {
  float hole_distance = 0.012f;
  float overlap_inset = 0.002f;
  bool head_cap = true;
  float cap_scale = 1.06f;
};

/// The remade character. Vertices: the body parts one after the other (part 0 first), the cap, then the
/// dressed character's garment and apparel vertices in their order.
///   mesh            the surface; faces of the parts, the cap, then the dressed mesh's other faces
///   apparel_mask    #V entries, 1 = apparel (the dressed character's mask; parts and cap are 0)
///   body_weights    #V by 22 rest skinning, rows sum to 1: each copy takes its source vertex's weights,
///                   the cap weight 1 on the head
///   part            #V entries: the body part of each vertex (the cap is the last part), -1 for garment
///                   and apparel vertices
///   source          #V entries: the vertex of the dressed mesh each one copies, -1 for the cap
///   num_parts       body parts including the cap; dropped_faces: body faces left out (the holes)
struct OpenPartsCharacter {
  TriMesh mesh;
  std::vector<uint8_t> apparel_mask;
  MatrixXfR body_weights;
  std::vector<int32_t> part, source;
  int num_parts = 0;
  int dropped_faces = 0;
};

/// Remakes `dressed` into open, overlapping body parts as described in the file comment. Deterministic.
/// Throws amt::Error on options out of range.
OpenPartsCharacter open_parts_character(const DressedCharacter& dressed, const OpenPartsOptions& options = {});

}  // namespace amt
