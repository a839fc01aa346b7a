#pragma once
// Triangle meshes: the character surface and its derived connectivity (edges, adjacency,
// connected components, normals).
#include <string>
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

// === Mesh

/// A triangle mesh. V #V by 3 positions (metres), F #F by 3 vertex indices into V.
struct TriMesh {
  MatrixX3f V;
  MatrixX3i F;

  int num_vertices() const { return static_cast<int>(V.rows()); }
  int num_faces() const { return static_cast<int>(F.rows()); }
};

/// Throws amt::Error unless the mesh is usable: at least one vertex and one face, finite and
/// plausible positions (check_plausible_extent), face indices in [0, #V). `source` names the file or
/// object in the message ("a.h5: /characters/x").
void validate_mesh(const TriMesh& mesh, const std::string& source);

/// The plausibility bounds of positions (finite but absurd values, such as one vertex at 1e15 from a
/// flipped byte): no coordinate beyond kMaxCoordinate (10 km in metres), and no vertex farther from
/// the mesh's centre (the per-axis median of V) than kMaxEdgeLengths times the median length of the
/// faces' sides (skipped when that median is 0). Throws amt::Error naming `source`, the vertex and its
/// value.
inline constexpr float kMaxCoordinate = 1e4f;
inline constexpr float kMaxEdgeLengths = 1e4f;
void check_plausible_extent(const TriMesh& mesh, const std::string& source);

// === Connectivity

/// Unique undirected edges of the faces, each as (i, j) with i < j, sorted lexicographically.
/// Returns #E by 2.
MatrixX2i unique_edges(const MatrixX3i& F);

/// The sub-mesh of the vertices `ids` (indices into V, in the order given, no repeats) and of the faces
/// whose three corners are among them, renumbered to positions in `ids` (the body part of a character,
/// its largest connected part). Throws amt::Error on an index out of range.
TriMesh submesh(const MatrixX3f& V, const MatrixX3i& F, const std::vector<int32_t>& ids);

/// True when the oriented faces have no boundary: every edge is crossed as often from i to j as from
/// j to i (a closed, consistently oriented surface, possibly with several parts, touching or
/// self-intersecting). Off such a surface the winding number is an integer. An empty F is closed.
bool is_closed_surface(const MatrixX3i& F);

/// The holes of a surface closed with fans. The holes are the connected groups of boundary sides
/// (sides i -> j of F that no side j -> i balances); each boundary side a -> b gets the triangle
/// (b, a, c) to a new centre vertex c = num_vertices + h of its hole h. F together with `faces` is a
/// closed surface (is_closed_surface). A closed F gives no holes. Hand-written: CGAL's hole filling
/// (libcgal-dev) triangulates each loop for quality on a halfedge mesh; a winding-number inside test
/// only needs the surface closed, by a fan whose centre can follow the moving boundary.
struct HoleFill {
  MatrixX3i faces;                          // fan triangles
  std::vector<std::vector<int32_t>> holes;  // boundary vertices of each hole; its centre is their mean
};
HoleFill fill_holes(const MatrixX3i& F, int num_vertices);

/// Compressed vertex adjacency: the neighbours of vertex i are
/// neighbors[offsets[i] .. offsets[i+1]), sorted ascending.
struct Adjacency {
  std::vector<int32_t> offsets;    // #V + 1
  std::vector<int32_t> neighbors;  // 2 #E
  int degree(int i) const { return offsets[i + 1] - offsets[i]; }
};

/// Adjacency of `num_vertices` vertices from undirected edges E (#E by 2).
Adjacency vertex_adjacency(int num_vertices, const MatrixX2i& E);

/// Union-find over `count` elements with path halving; the representative of a set is its
/// smallest element, so results do not depend on the order of unions.
class DisjointSets {
 public:
  explicit DisjointSets(int count);
  /// Representative (smallest element) of x's set.
  int32_t find(int32_t x);
  /// Joins the sets of a and b; false when they were already one set.
  bool unite(int32_t a, int32_t b);
  /// Number of disjoint sets.
  int num_sets() const { return sets_; }

 private:
  std::vector<int32_t> parent_;
  int sets_;
};

/// Connected components over undirected edges E. Returns one label per vertex in [0, count), labels
/// numbered in order of each component's smallest vertex; `count` receives the number of components.
std::vector<int32_t> connected_components(int num_vertices, const MatrixX2i& E, int* count = nullptr);

// === Geometry

/// Area-weighted vertex normals (unit length; zero for vertices on no non-degenerate face). #V by 3.
MatrixX3f vertex_normals(const MatrixX3f& V, const MatrixX3i& F);

/// Edge lengths |V_i - V_j| for E (#E by 2). Returns #E values.
Eigen::VectorXf edge_lengths(const MatrixX3f& V, const MatrixX2i& E);

}  // namespace amt
