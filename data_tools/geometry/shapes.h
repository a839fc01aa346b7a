#pragma once
// Closed primitive meshes (spheres, capsules, grids) and mesh merging: stand-in characters for
// tests and benchmarks, and parts for the procedural body generator.
#include <vector>

#include "data_tools/geometry/mesh.h"

namespace amt {

/// A closed UV sphere, outward-facing: `segments` around, `rings` from pole to pole (>= 2).
TriMesh uv_sphere(const Eigen::Vector3f& center, float radius, int segments, int rings);

/// A closed capsule around the segment a-b, outward-facing: two hemispheres of `hemisphere_rings`
/// rings each and `length_rings` - 1 extra rings along the cylinder, `segments` around.
TriMesh capsule(const Eigen::Vector3f& a, const Eigen::Vector3f& b, float radius, int segments, int hemisphere_rings,
                int length_rings);

/// A flat grid of nx by ny vertices spaced `spacing` apart in the XY plane from the origin, each
/// cell split into two triangles along the (i,j)-(i+1,j+1) diagonal. Vertex (i, j) has index j nx + i.
TriMesh grid(int nx, int ny, float spacing);

/// Concatenates meshes (face indices offset). `part_of_vertex`, if given, receives for every vertex
/// the index of the mesh it came from.
TriMesh merge_meshes(const std::vector<TriMesh>& parts, std::vector<int32_t>* part_of_vertex = nullptr);

/// A stand-in character for benchmarks: one capsule per bone of `skeleton` plus a head sphere,
/// separate closed parts, with about `target_vertices` vertices in all. `joint_of_vertex`, if given,
/// receives the joint each vertex rigidly follows (a bone's capsule follows the bone's parent joint).
TriMesh capsule_character(const MatrixX3f& rest_joints, const std::vector<int32_t>& parents, int target_vertices,
                          std::vector<int32_t>* joint_of_vertex = nullptr);

}  // namespace amt
