#pragma once
// Vertex-to-joint geodesic distances G (N, J) for the skinning predictor's geodesic attention
// (docs/architecture.md, "The pipeline"; paper section 4.2): shortest paths along mesh edges from each joint's anchor
// vertex, over an edge graph whose disconnected parts (hair, eyes, accessories) are joined by
// nearest-point "bridge" edges so that every entry of G is finite.
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

// === Anchors

/// The anchor of every joint: the index of the mesh vertex closest to it (paper footnote 3).
/// V #V by 3 vertex positions (at least one vertex), joints #J by 3 joint positions (finite).
/// Returns #J vertex indices in [0, #V). Ties between equally close vertices are resolved the same
/// way on every run (by the KD-tree's fixed traversal order).
std::vector<int32_t> joint_anchor_vertices(const MatrixX3f& V, const MatrixX3f& joints);

/// For each vertex listed in `queries`, the index (into V) of the Euclidean-nearest vertex listed in
/// `candidates` (at least one); ties go to the earlier candidate. Indices must be in [0, #V).
std::vector<int32_t> nearest_listed_vertices(const MatrixX3f& V, const std::vector<int32_t>& candidates,
                                             const std::vector<int32_t>& queries);

// === Bridged edge graph

/// An undirected graph with positive edge weights in compressed (CSR) form, like Adjacency: the
/// neighbours of vertex i are neighbors[offsets[i] .. offsets[i+1]), sorted ascending, and weights[k]
/// is the length (metres) of the edge to neighbors[k]. Every edge is stored once in each direction.
struct WeightedGraph {
  std::vector<int32_t> offsets;    // #V + 1
  std::vector<int32_t> neighbors;  // 2 #E
  std::vector<float> weights;      // 2 #E

  int num_vertices() const { return offsets.empty() ? 0 : static_cast<int>(offsets.size()) - 1; }
  int degree(int i) const { return offsets[i + 1] - offsets[i]; }
};

/// Bridge edges that join the connected components of the edge set E into one component.
/// V #V by 3 vertex positions, E #E by 2 undirected edges (vertices on no edge count as components
/// of their own). Returns #B by 2 vertex pairs (i, j), i < j, one per merge, so #B = components - 1.
///
/// The bridges approximate a Euclidean minimum spanning tree over the components: candidates are the
/// k nearest neighbours of every vertex that lie in another component, joined shortest first
/// (Kruskal); groups that no candidate reaches are then merged one at a time, the smallest group
/// first, through the exact nearest pair between it and all other vertices. A bridge therefore joins
/// two nearby vertices of different parts, though not always the closest pair of those two parts.
/// Deterministic, O(#V log #V) for any number of components; no dense #V by #V structure.
MatrixX2i component_bridges(const MatrixX3f& V, const MatrixX2i& E);

/// The mesh edge graph of (V, F), weighted by Euclidean edge length, plus the component bridges of
/// component_bridges() weighted by the distance between their endpoints: one connected graph over
/// all #V vertices. V #V by 3, F #F by 3. `bridges`, when given, receives the #B by 2 bridge edges.
/// Throws amt::Error on a mesh that validate_mesh rejects.
WeightedGraph bridged_edge_graph(const MatrixX3f& V, const MatrixX3i& F, MatrixX2i* bridges = nullptr);

// === Geodesic distances

/// Single-source shortest-path lengths (Dijkstra) on a connected graph from `source`; returns one
/// distance per vertex (+infinity for vertices the graph does not connect to `source`).
std::vector<double> shortest_path_lengths(const WeightedGraph& graph, int source);

/// Geodesic distance matrix G (N, J): G(i, j) is the shortest-path length (metres) along the bridged
/// edge graph (bridged_edge_graph) from joint j's anchor vertex (joint_anchor_vertices) to vertex i.
/// Every entry is finite and G(anchor_j, j) = 0. V #V by 3 rest vertices, F #F by 3 faces,
/// joints #J by 3 rest joint positions. The J searches run in parallel with OpenMP.
/// Throws amt::Error on a mesh that validate_mesh rejects, on zero joints or non-finite joints.
MatrixXfR geodesic_distances(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints);

}  // namespace amt
