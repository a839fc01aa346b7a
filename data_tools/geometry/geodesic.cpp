#include "data_tools/geometry/geodesic.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <functional>
#include <limits>
#include <nanoflann.hpp>
#include <numeric>
#include <queue>
#include <set>
#include <tuple>
#include <utility>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"

namespace amt {
namespace {

// === KD-tree plumbing (nanoflann)

// nanoflann dataset adaptor over rows of V: all rows, or the listed ones (ascending vertex indices),
// in which case the tree's point indices are positions in that list.
struct VertexCloud {
  const MatrixX3f& V;
  const std::vector<int32_t>* rows = nullptr;

  size_t kdtree_get_point_count() const { return rows ? rows->size() : static_cast<size_t>(V.rows()); }
  float kdtree_get_pt(size_t index, size_t dim) const {
    return V(rows ? (*rows)[index] : static_cast<Eigen::Index>(index), static_cast<Eigen::Index>(dim));
  }
  template <class BoundingBox>
  bool kdtree_get_bbox(BoundingBox&) const {
    return false;  // let nanoflann compute it
  }
};

using VertexTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, VertexCloud>, VertexCloud, 3, uint32_t>;

constexpr size_t kLeafSize = 16;

// nanoflann result set keeping the single nearest point, ties going to the lowest point index, and
// optionally skipping every point whose group (groups[point]) is `excluded`. Starting from a finite
// `bound` (squared distance) prunes the search to points at most that far.
class NearestResult {
 public:
  explicit NearestResult(float bound = std::numeric_limits<float>::infinity(),
                         const std::vector<int32_t>* groups = nullptr, int32_t excluded = -1)
      : groups_(groups), excluded_(excluded), best_dist_(bound) {}

  bool addPoint(float dist, uint32_t index) {
    if (groups_ && (*groups_)[index] == excluded_) return true;
    if (dist < best_dist_ || (dist == best_dist_ && static_cast<int64_t>(index) < best_index_)) {
      best_dist_ = dist;
      best_index_ = index;
    }
    return true;  // keep searching
  }
  // nanoflann only offers points strictly closer than this: one step above the best keeps ties.
  float worstDist() const { return std::nextafter(best_dist_, std::numeric_limits<float>::infinity()); }
  bool full() const { return best_index_ >= 0; }

  /// Squared distance and index of the nearest point; index -1 when none was within the bound.
  float dist() const { return best_dist_; }
  int64_t index() const { return best_index_; }

 private:
  const std::vector<int32_t>* groups_;
  int32_t excluded_;
  float best_dist_;
  int64_t best_index_ = -1;
};

// Runs `result` (a NearestResult) over the tree for the query point p.
void find_nearest(const VertexTree& tree, const Eigen::Vector3f& p, NearestResult& result) {
  tree.findNeighbors(result, p.data(), nanoflann::SearchParams());
}

void check_finite_rows(const MatrixX3f& P, const char* source, const char* field) {
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    AMT_CHECK(P.row(i).allFinite(), source, ": ", field, ": expected finite values, found ", P(i, 0), " ", P(i, 1), " ",
              P(i, 2), " at row ", i);
  }
}

// === Component bridging

// A possible bridge: squared length, then its endpoints (i < j); ordered by length, ties by indices.
using Candidate = std::tuple<float, int32_t, int32_t>;

Candidate make_candidate(float dist, int32_t a, int32_t b) {
  return {dist, std::min(a, b), std::max(a, b)};
}

// Vertices each vertex asks the KD-tree for (itself included) when collecting bridge candidates.
constexpr int kCandidateNeighbours = 10;

// Stage 1: every vertex's k nearest vertices that lie in another component are candidates; Kruskal
// joins them shortest first. Returns the bridges added; `sets` ends with the merged components.
std::vector<std::pair<int32_t, int32_t>> kruskal_over_nearest_neighbours(const MatrixX3f& V,
                                                                         const std::vector<int32_t>& component,
                                                                         const VertexTree& tree, DisjointSets& sets) {
  const int n = static_cast<int>(V.rows());
  const int k = std::min(kCandidateNeighbours, n);
  std::vector<uint32_t> neighbour(static_cast<size_t>(n) * k);
  std::vector<float> dist(static_cast<size_t>(n) * k);
  std::vector<int32_t> found(static_cast<size_t>(n));
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f p = V.row(i);
    found[i] = static_cast<int32_t>(tree.knnSearch(p.data(), k, &neighbour[size_t(i) * k], &dist[size_t(i) * k]));
  }
  std::vector<Candidate> candidates;
  for (int i = 0; i < n; ++i) {
    for (int m = 0; m < found[i]; ++m) {
      const auto j = static_cast<int32_t>(neighbour[size_t(i) * k + m]);
      if (component[j] != component[i]) candidates.push_back(make_candidate(dist[size_t(i) * k + m], i, j));
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<std::pair<int32_t, int32_t>> bridges;
  for (const auto& [d, a, b] : candidates) {
    if (sets.unite(component[a], component[b])) bridges.emplace_back(a, b);
    if (sets.num_sets() == 1) break;
  }
  return bridges;
}

// The nearest pair (i in `members`, j outside group `g`) as a candidate with squared length. Small
// groups search the shared tree, skipping their own vertices (cost up to |g|^2 point tests); large
// groups build a tree over all other vertices (cost about #V log #V) and ask it plainly.
Candidate nearest_pair_leaving_group(const MatrixX3f& V, const VertexTree& all_vertices,
                                     const std::vector<int32_t>& group, int32_t g,
                                     const std::vector<int32_t>& members) {
  const auto n = static_cast<double>(V.rows());
  const auto size = static_cast<double>(members.size());
  Candidate best{std::numeric_limits<float>::infinity(), -1, -1};
  auto consider = [&best](float d, int32_t i, int32_t j) {
    const Candidate c = make_candidate(d, i, j);
    if (c < best) best = c;
  };
  if (size * size <= n * std::log2(n + 1)) {
    for (const int32_t i : members) {
      const Eigen::Vector3f p = V.row(i);
      NearestResult result(std::get<0>(best), &group, g);
      find_nearest(all_vertices, p, result);
      if (result.full()) consider(result.dist(), i, static_cast<int32_t>(result.index()));
    }
  } else {
    std::vector<int32_t> others;
    others.reserve(static_cast<size_t>(V.rows()) - members.size());
    for (int32_t v = 0; v < static_cast<int32_t>(V.rows()); ++v) {
      if (group[v] != g) others.push_back(v);
    }
    const VertexCloud cloud{V, &others};
    const VertexTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize));
    for (const int32_t i : members) {
      const Eigen::Vector3f p = V.row(i);
      NearestResult result(std::get<0>(best));
      find_nearest(tree, p, result);
      if (result.full()) consider(result.dist(), i, others[result.index()]);
    }
  }
  return best;
}

// Stage 2: while groups remain apart, the smallest group (ties: the one holding the lowest vertex) is
// joined to the rest through its exact nearest outside vertex. Appends to `bridges`.
void merge_remaining_groups(const MatrixX3f& V, const std::vector<int32_t>& component, const VertexTree& tree,
                            DisjointSets& sets, std::vector<std::pair<int32_t, int32_t>>& bridges) {
  const auto n = static_cast<int32_t>(V.rows());
  // group[v] names the group of vertex v; members[g] lists its vertices, lowest[g] the lowest of them.
  // A merge moves the smaller member list into the larger, so each vertex moves O(log #V) times.
  std::vector<int32_t> group(static_cast<size_t>(n)), lowest(static_cast<size_t>(n), -1);
  std::vector<std::vector<int32_t>> members(static_cast<size_t>(n));
  for (int32_t v = 0; v < n; ++v) {
    const int32_t g = sets.find(component[v]);  // a component label, < n
    group[v] = g;
    members[g].push_back(v);
    if (lowest[g] < 0) lowest[g] = v;
  }
  std::set<std::tuple<size_t, int32_t, int32_t>> by_size;  // (size, lowest vertex, name) of every live group
  for (int32_t g = 0; g < n; ++g) {
    if (!members[g].empty()) by_size.emplace(members[g].size(), lowest[g], g);
  }
  while (by_size.size() > 1) {
    const int32_t g = std::get<2>(*by_size.begin());
    const auto [dist, a, b] = nearest_pair_leaving_group(V, tree, group, g, members[g]);
    assert(a >= 0 && b >= 0);
    bridges.emplace_back(a, b);
    int32_t keep = group[a], gone = group[b];
    if (members[keep].size() < members[gone].size()) std::swap(keep, gone);
    by_size.erase({members[keep].size(), lowest[keep], keep});
    by_size.erase({members[gone].size(), lowest[gone], gone});
    for (const int32_t v : members[gone]) group[v] = keep;
    members[keep].insert(members[keep].end(), members[gone].begin(), members[gone].end());
    std::vector<int32_t>().swap(members[gone]);
    lowest[keep] = std::min(lowest[keep], lowest[gone]);
    by_size.emplace(members[keep].size(), lowest[keep], keep);
  }
}

// Bridges for already-validated input.
MatrixX2i bridges_of_valid_input(const MatrixX3f& V, const MatrixX2i& E) {
  const int n = static_cast<int>(V.rows());
  int count = 0;
  const std::vector<int32_t> component = connected_components(n, E, &count);
  if (count <= 1) return MatrixX2i(0, 2);

  const VertexCloud cloud{V, nullptr};
  const VertexTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize));
  DisjointSets sets(count);
  std::vector<std::pair<int32_t, int32_t>> bridges = kruskal_over_nearest_neighbours(V, component, tree, sets);
  if (sets.num_sets() > 1) merge_remaining_groups(V, component, tree, sets, bridges);

  MatrixX2i B(static_cast<Eigen::Index>(bridges.size()), 2);
  for (size_t e = 0; e < bridges.size(); ++e) {
    B(static_cast<Eigen::Index>(e), 0) = std::min(bridges[e].first, bridges[e].second);
    B(static_cast<Eigen::Index>(e), 1) = std::max(bridges[e].first, bridges[e].second);
  }
  return B;
}

WeightedGraph graph_of_valid_mesh(const MatrixX3f& V, const MatrixX3i& F, MatrixX2i* bridges_out) {
  const int n = static_cast<int>(V.rows());
  const MatrixX2i E = unique_edges(F);
  const MatrixX2i B = bridges_of_valid_input(V, E);
  MatrixX2i all_edges(E.rows() + B.rows(), 2);
  all_edges << E, B;
  const Adjacency adjacency = vertex_adjacency(n, all_edges);

  WeightedGraph graph;
  graph.offsets = adjacency.offsets;
  graph.neighbors = adjacency.neighbors;
  graph.weights.resize(graph.neighbors.size());
  for (int i = 0; i < n; ++i) {
    for (int32_t k = graph.offsets[i]; k < graph.offsets[i + 1]; ++k) {
      graph.weights[k] = (V.row(i) - V.row(graph.neighbors[k])).norm();
    }
  }
  if (bridges_out) *bridges_out = B;
  return graph;
}

// === Shortest paths

// Dijkstra with a binary heap and lazy deletion; writes one distance per vertex into `dist`.
void dijkstra(const WeightedGraph& graph, int source, std::vector<double>& dist) {
  using Entry = std::pair<double, int32_t>;
  dist.assign(static_cast<size_t>(graph.num_vertices()), std::numeric_limits<double>::infinity());
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap;
  dist[source] = 0.0;
  heap.emplace(0.0, source);
  while (!heap.empty()) {
    const auto [d, v] = heap.top();
    heap.pop();
    if (d > dist[v]) continue;  // stale entry: v was settled through a shorter path
    for (int32_t k = graph.offsets[v]; k < graph.offsets[v + 1]; ++k) {
      const int32_t u = graph.neighbors[k];
      const double through_v = d + graph.weights[k];
      if (through_v < dist[u]) {
        dist[u] = through_v;
        heap.emplace(through_v, u);
      }
    }
  }
}

}  // namespace

std::vector<int32_t> joint_anchor_vertices(const MatrixX3f& V, const MatrixX3f& joints) {
  AMT_CHECK(V.rows() > 0, "joint_anchor_vertices: vertices: expected at least 1 vertex, found 0");
  check_finite_rows(V, "joint_anchor_vertices", "vertices");
  check_finite_rows(joints, "joint_anchor_vertices", "joints");
  const VertexCloud cloud{V, nullptr};
  const VertexTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize));
  std::vector<int32_t> anchors(static_cast<size_t>(joints.rows()));
  for (Eigen::Index j = 0; j < joints.rows(); ++j) {
    const Eigen::Vector3f p = joints.row(j);
    NearestResult result;
    find_nearest(tree, p, result);
    anchors[j] = static_cast<int32_t>(result.index());
  }
  return anchors;
}

std::vector<int32_t> nearest_listed_vertices(const MatrixX3f& V, const std::vector<int32_t>& candidates,
                                             const std::vector<int32_t>& queries) {
  AMT_CHECK(!candidates.empty(), "nearest_listed_vertices: candidates: expected at least 1 vertex, found 0");
  for (const std::vector<int32_t>* list : {&candidates, &queries}) {
    for (const int32_t i : *list) {
      AMT_CHECK(i >= 0 && i < V.rows(), "nearest_listed_vertices: expected vertex indices in [0, ", V.rows(),
                "), found ", i);
    }
  }
  check_finite_rows(V, "nearest_listed_vertices", "vertices");
  const VertexCloud cloud{V, &candidates};
  const VertexTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize));
  std::vector<int32_t> nearest(queries.size());
  for (size_t q = 0; q < queries.size(); ++q) {
    const Eigen::Vector3f p = V.row(queries[q]);
    NearestResult result;
    find_nearest(tree, p, result);
    nearest[q] = candidates[static_cast<size_t>(result.index())];
  }
  return nearest;
}

MatrixX2i component_bridges(const MatrixX3f& V, const MatrixX2i& E) {
  check_finite_rows(V, "component_bridges", "vertices");
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    for (int k = 0; k < 2; ++k) {
      AMT_CHECK(E(e, k) >= 0 && E(e, k) < V.rows(), "component_bridges: edges: expected vertex indices in [0, ",
                V.rows(), "), found ", E(e, k), " in edge ", e);
    }
  }
  if (V.rows() == 0) return MatrixX2i(0, 2);
  return bridges_of_valid_input(V, E);
}

WeightedGraph bridged_edge_graph(const MatrixX3f& V, const MatrixX3i& F, MatrixX2i* bridges) {
  validate_mesh(TriMesh{V, F}, "bridged_edge_graph");
  return graph_of_valid_mesh(V, F, bridges);
}

std::vector<double> shortest_path_lengths(const WeightedGraph& graph, int source) {
  AMT_CHECK(source >= 0 && source < graph.num_vertices(), "shortest_path_lengths: source: expected a vertex in [0, ",
            graph.num_vertices(), "), found ", source);
  std::vector<double> dist;
  dijkstra(graph, source, dist);
  return dist;
}

MatrixXfR geodesic_distances(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints) {
  validate_mesh(TriMesh{V, F}, "geodesic_distances");
  AMT_CHECK(joints.rows() >= 1, "geodesic_distances: joints: expected at least 1 joint, found 0");
  check_finite_rows(joints, "geodesic_distances", "joints");

  const std::vector<int32_t> anchors = joint_anchor_vertices(V, joints);
  const WeightedGraph graph = graph_of_valid_mesh(V, F, nullptr);
  const int n = graph.num_vertices();
  const int num_joints = static_cast<int>(joints.rows());

  // Column-major scratch: each search writes one contiguous column, so threads share no cache lines
  // except at column ends; converted to the row-major (N, J) result at the end.
  Eigen::MatrixXf by_joint(n, num_joints);
#pragma omp parallel
  {
    std::vector<double> dist;
#pragma omp for schedule(dynamic, 1)
    for (int j = 0; j < num_joints; ++j) {
      dijkstra(graph, anchors[j], dist);
      for (int i = 0; i < n; ++i) by_joint(i, j) = static_cast<float>(dist[i]);
    }
  }
  assert(by_joint.allFinite());  // the bridged graph is connected
  return by_joint;
}

}  // namespace amt
