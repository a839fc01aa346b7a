// Geodesic distances along the (bridged) edge graph, against distances worked out by hand on grids
// and triangles whose shortest paths are obvious; anchors against a brute-force nearest vertex.
#include "data_tools/geometry/geodesic.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"

namespace amt {
namespace {

const float kSqrt2 = std::sqrt(2.0f);

// A planar n x n grid in z = 0 with the given spacing and offset; vertex (x, y) has index y * n + x.
// Every cell is split along its (x, y)-(x+1, y+1) diagonal, so the edges are the horizontal and
// vertical grid lines plus those diagonals.
TriMesh grid(int n, float spacing = 1.0f, const Eigen::Vector3f& offset = Eigen::Vector3f::Zero()) {
  TriMesh mesh;
  mesh.V.resize(n * n, 3);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) mesh.V.row(y * n + x) = (offset + spacing * Eigen::Vector3f(x, y, 0)).transpose();
  }
  mesh.F.resize(2 * (n - 1) * (n - 1), 3);
  int f = 0;
  for (int y = 0; y + 1 < n; ++y) {
    for (int x = 0; x + 1 < n; ++x) {
      const int v00 = y * n + x, v10 = v00 + 1, v01 = v00 + n, v11 = v00 + n + 1;
      mesh.F.row(f++) << v00, v10, v11;
      mesh.F.row(f++) << v00, v11, v01;
    }
  }
  return mesh;
}

// The disjoint union of two meshes (b's indices shifted past a's vertices).
TriMesh join(const TriMesh& a, const TriMesh& b) {
  TriMesh mesh;
  mesh.V.resize(a.V.rows() + b.V.rows(), 3);
  mesh.V << a.V, b.V;
  mesh.F.resize(a.F.rows() + b.F.rows(), 3);
  mesh.F << a.F, (b.F.array() + static_cast<int32_t>(a.V.rows())).matrix();
  return mesh;
}

MatrixX3f points(std::initializer_list<Eigen::Vector3f> list) {
  MatrixX3f P(static_cast<Eigen::Index>(list.size()), 3);
  Eigen::Index i = 0;
  for (const auto& p : list) P.row(i++) = p.transpose();
  return P;
}

// Hand-computed path length on the 5 x 5 grid from corner (0, 0) to (x, y): min(x, y) diagonal
// steps of sqrt(2), then |x - y| unit steps.
float from_origin_corner(int x, int y) {
  return std::min(x, y) * kSqrt2 + std::abs(x - y);
}

TEST(GeodesicDistances, GridFromCornersByHand) {
  const TriMesh mesh = grid(5);
  // Joint 0 near corner (0, 0); joint 1 near corner (4, 0), from which no diagonal edge leads
  // towards (0, 4), so the path there is 8 unit steps.
  const MatrixX3f joints = points({{-0.1f, -0.2f, 0.3f}, {4.2f, -0.1f, 0.0f}});
  const MatrixXfR G = geodesic_distances(mesh.V, mesh.F, joints);
  ASSERT_EQ(G.rows(), 25);
  ASSERT_EQ(G.cols(), 2);
  EXPECT_FLOAT_EQ(G(0, 0), 0.0f);
  EXPECT_FLOAT_EQ(G(24, 0), 4 * kSqrt2);             // (4, 4): four diagonals
  EXPECT_FLOAT_EQ(G(4, 0), 4.0f);                    // (4, 0): along the bottom row
  EXPECT_FLOAT_EQ(G(2 * 5 + 4, 0), 2 * kSqrt2 + 2);  // (4, 2)
  EXPECT_FLOAT_EQ(G(3 * 5 + 1, 0), kSqrt2 + 2);      // (1, 3)
  EXPECT_FLOAT_EQ(G(20, 0), 4.0f);                   // (0, 4)
  EXPECT_FLOAT_EQ(G(4, 1), 0.0f);
  EXPECT_FLOAT_EQ(G(20, 1), 8.0f);  // (4, 0) to (0, 4): Manhattan
  EXPECT_FLOAT_EQ(G(24, 1), 4.0f);  // (4, 0) to (4, 4): up the right column
  EXPECT_FLOAT_EQ(G(0, 1), 4.0f);
  for (int y = 0; y < 5; ++y) {
    for (int x = 0; x < 5; ++x) EXPECT_FLOAT_EQ(G(y * 5 + x, 0), from_origin_corner(x, y)) << x << ", " << y;
  }
}

TEST(GeodesicDistances, ShortestPathLengthsMatchTheMatrix) {
  const TriMesh mesh = grid(5);
  const WeightedGraph graph = bridged_edge_graph(mesh.V, mesh.F);
  ASSERT_EQ(graph.num_vertices(), 25);
  // 40 grid edges plus 16 diagonals, each stored in both directions.
  EXPECT_EQ(graph.neighbors.size(), 2u * 56u);
  const std::vector<double> d = shortest_path_lengths(graph, 0);
  const MatrixXfR G = geodesic_distances(mesh.V, mesh.F, points({{0, 0, 0}}));
  for (int i = 0; i < 25; ++i) EXPECT_FLOAT_EQ(static_cast<float>(d[i]), G(i, 0));
  EXPECT_THROW(shortest_path_lengths(graph, 25), Error);
}

TEST(GeodesicAnchors, PickTheNearestVertex) {
  const TriMesh mesh = grid(5, 0.5f, Eigen::Vector3f(1, 2, 3));
  EXPECT_EQ(joint_anchor_vertices(mesh.V, points({{1.0f, 2.0f, 3.0f}}))[0], 0);
  EXPECT_EQ(joint_anchor_vertices(mesh.V, points({{3.1f, 2.1f, 2.0f}}))[0], 4);     // beyond corner (4, 0)
  EXPECT_EQ(joint_anchor_vertices(mesh.V, points({{2.05f, 3.45f, 3.2f}}))[0], 17);  // near (2, 3)

  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coordinate(0.0f, 5.0f);
  MatrixX3f joints(50, 3);
  for (Eigen::Index j = 0; j < joints.rows(); ++j) {
    joints.row(j) << coordinate(rng), coordinate(rng), coordinate(rng);
  }
  const std::vector<int32_t> anchors = joint_anchor_vertices(mesh.V, joints);
  ASSERT_EQ(anchors.size(), 50u);
  for (Eigen::Index j = 0; j < joints.rows(); ++j) {
    Eigen::Index nearest = 0;
    (mesh.V.rowwise() - joints.row(j)).rowwise().squaredNorm().minCoeff(&nearest);
    EXPECT_EQ(anchors[j], nearest) << "joint " << j;
  }
}

TEST(GeodesicBridges, TwoTrianglesGetOneBridgeBetweenTheNearestPair) {
  // Two right triangles 2 apart along x: vertex 1 at (1, 0, 0) and vertex 3 at (3, 0, 0) are the
  // nearest pair. Few vertices, so the k-nearest-neighbour candidates find it.
  TriMesh mesh;
  mesh.V = points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {3, 0, 0}, {4, 0, 0}, {3, 1, 0}});
  mesh.F.resize(2, 3);
  mesh.F << 0, 1, 2, 3, 4, 5;
  MatrixX2i bridges;
  const WeightedGraph graph = bridged_edge_graph(mesh.V, mesh.F, &bridges);
  ASSERT_EQ(bridges.rows(), 1);
  EXPECT_EQ(bridges(0, 0), 1);
  EXPECT_EQ(bridges(0, 1), 3);
  EXPECT_EQ(graph.degree(1), 3);

  const MatrixXfR G = geodesic_distances(mesh.V, mesh.F, points({{-0.1f, 0, 0}}));
  EXPECT_FLOAT_EQ(G(1, 0), 1.0f);
  EXPECT_FLOAT_EQ(G(3, 0), 1.0f + 2.0f);
  EXPECT_FLOAT_EQ(G(4, 0), 1.0f + 2.0f + 1.0f);
  EXPECT_FLOAT_EQ(G(5, 0), 1.0f + 2.0f + 1.0f);
  EXPECT_FLOAT_EQ(G(2, 0), 1.0f);
}

TEST(GeodesicBridges, TwoGridsGetOneBridgeBetweenTheNearestPair) {
  // Grid B is grid A moved by (7, 8): A's corner (4, 4) (vertex 24) and B's corner (0, 0) at (7, 8)
  // (vertex 25) are 5 apart, every other pair is farther. Every vertex has more than 10 vertices of
  // its own grid closer than 5, so the bridge comes from the exact nearest-pair fallback.
  const TriMesh mesh = join(grid(5), grid(5, 1.0f, Eigen::Vector3f(7, 8, 0)));
  MatrixX2i bridges;
  bridged_edge_graph(mesh.V, mesh.F, &bridges);
  ASSERT_EQ(bridges.rows(), 1);
  EXPECT_EQ(bridges(0, 0), 24);
  EXPECT_EQ(bridges(0, 1), 25);

  // From A's corner (0, 0): 4 diagonals to vertex 24, the bridge of length 5, then within B.
  const MatrixXfR G = geodesic_distances(mesh.V, mesh.F, points({{0, 0, 0}, {11, 12, 0}}));
  const float to_bridge = 4 * kSqrt2, gap = 5.0f;
  EXPECT_FLOAT_EQ(G(24, 0), to_bridge);
  EXPECT_FLOAT_EQ(G(25, 0), to_bridge + gap);
  EXPECT_FLOAT_EQ(G(25 + 24, 0), to_bridge + gap + 4 * kSqrt2);            // B (4, 4)
  EXPECT_FLOAT_EQ(G(25 + 4, 0), to_bridge + gap + 4.0f);                   // B (4, 0)
  EXPECT_FLOAT_EQ(G(25 + 3 * 5 + 1, 0), to_bridge + gap + kSqrt2 + 2.0f);  // B (1, 3)
  // From B's corner (4, 4) back into A's corner (0, 4) (vertex 20): to B (0, 0), across, then from
  // A (4, 4) to A (0, 4) along the top row.
  EXPECT_FLOAT_EQ(G(20, 1), 4 * kSqrt2 + gap + 4.0f);
}

TEST(GeodesicBridges, FiftyTrianglesAreAllReached) {
  // 50 small triangles on a 5 x 5 x 2 lattice, 2 apart: the nearest-neighbour candidates join them.
  TriMesh mesh;
  mesh.V.resize(150, 3);
  mesh.F.resize(50, 3);
  for (int t = 0; t < 50; ++t) {
    const Eigen::Vector3f origin(2.0f * (t % 5), 2.0f * ((t / 5) % 5), 2.0f * (t / 25));
    mesh.V.row(3 * t) = origin.transpose();
    mesh.V.row(3 * t + 1) = (origin + Eigen::Vector3f(0.5f, 0, 0)).transpose();
    mesh.V.row(3 * t + 2) = (origin + Eigen::Vector3f(0, 0.5f, 0.1f)).transpose();
    mesh.F.row(t) << 3 * t, 3 * t + 1, 3 * t + 2;
  }
  MatrixX2i bridges;
  bridged_edge_graph(mesh.V, mesh.F, &bridges);
  EXPECT_EQ(bridges.rows(), 49);
  const MatrixXfR G = geodesic_distances(mesh.V, mesh.F, points({{0, 0, 0}, {8, 8, 2}, {4, 3, 1}}));
  EXPECT_TRUE(G.allFinite());
  EXPECT_EQ((G.array() == 0).count(), 3);
  EXPECT_GT(G.minCoeff(), -1e-6f);
}

TEST(GeodesicBridges, SeparatedGridsAreJoinedByTheFallback) {
  // 40 grids of 4 x 4 vertices (0.3 wide) in a row, 1 apart: each grid is farther from the next
  // (0.7) than its own vertices are from each other, so no nearest-neighbour candidate crosses and
  // every bridge comes from the nearest-pair fallback, with length exactly the gap.
  TriMesh mesh = grid(4, 0.1f);
  for (int k = 1; k < 40; ++k) mesh = join(mesh, grid(4, 0.1f, Eigen::Vector3f(1.0f * k, 0, 0)));
  MatrixX2i bridges;
  const WeightedGraph graph = bridged_edge_graph(mesh.V, mesh.F, &bridges);
  ASSERT_EQ(bridges.rows(), 39);
  for (Eigen::Index b = 0; b < bridges.rows(); ++b) {
    EXPECT_NEAR((mesh.V.row(bridges(b, 0)) - mesh.V.row(bridges(b, 1))).norm(), 0.7f, 1e-5f);
    EXPECT_EQ(bridges(b, 1) / 16 - bridges(b, 0) / 16, 1);  // neighbouring grids
  }
  const std::vector<double> d = shortest_path_lengths(graph, 0);
  for (const double x : d) EXPECT_TRUE(std::isfinite(x));
  // Deterministic: the same input gives the same bridges.
  MatrixX2i again;
  bridged_edge_graph(mesh.V, mesh.F, &again);
  EXPECT_EQ(again, bridges);
}

TEST(GeodesicBridges, UnreferencedVerticesAreBridgedToo) {
  TriMesh mesh = grid(3);
  mesh.V.conservativeResize(10, 3);
  mesh.V.row(9) << 1, 1, 2;  // on no face, 2 above the grid's centre (vertex 4)
  const MatrixXfR G = geodesic_distances(mesh.V, mesh.F, points({{0, 0, 0}}));
  EXPECT_FLOAT_EQ(G(9, 0), kSqrt2 + 2.0f);
}

TEST(GeodesicDistances, RejectsBadInput) {
  const TriMesh mesh = grid(3);
  const MatrixX3f joint = points({{0, 0, 0}});
  EXPECT_THROW(geodesic_distances(MatrixX3f(0, 3), MatrixX3i(0, 3), joint), Error);
  TriMesh nan_vertex = mesh;
  nan_vertex.V(4, 1) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(geodesic_distances(nan_vertex.V, nan_vertex.F, joint), Error);
  TriMesh bad_face = mesh;
  bad_face.F(2, 1) = 9;
  EXPECT_THROW(geodesic_distances(bad_face.V, bad_face.F, joint), Error);
  EXPECT_THROW(geodesic_distances(mesh.V, mesh.F, MatrixX3f(0, 3)), Error);
  EXPECT_THROW(geodesic_distances(mesh.V, mesh.F, points({{0, std::numeric_limits<float>::infinity(), 0}})), Error);
  EXPECT_THROW(joint_anchor_vertices(MatrixX3f(0, 3), joint), Error);
  MatrixX2i bad_edge(1, 2);
  bad_edge << 0, 9;
  EXPECT_THROW(component_bridges(mesh.V, bad_edge), Error);
  try {
    geodesic_distances(mesh.V, mesh.F, MatrixX3f(0, 3));
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "geodesic_distances: joints: expected at least 1 joint, found 0");
  }
}

}  // namespace
}  // namespace amt
