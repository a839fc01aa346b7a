#include "data_tools/geometry/apparel_topology.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

// Two unit-cm quads side by side, as an artist's UV seam leaves them: the right quad has its own copies
// (vertices 4, 5) of the shared edge's vertices (1, 3). Vertices 0-3 left quad, 4-7 right quad.
void seamed_quads(MatrixX3f& V, MatrixX3i& F) {
  V.resize(8, 3);
  V << 0, 0, 0, 0.01f, 0, 0, 0, 0.01f, 0, 0.01f, 0.01f, 0,         // left: 0 1 / 2 3
      0.01f, 0, 0, 0.01f, 0.01f, 0, 0.02f, 0, 0, 0.02f, 0.01f, 0;  // right: 4 (= 1), 5 (= 3), 6, 7
  F.resize(4, 3);
  F << 0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5;
}

bool has_edge(const MatrixX2i& E, int a, int b) {
  if (a > b) std::swap(a, b);
  for (Eigen::Index k = 0; k < E.rows(); ++k)
    if (E(k, 0) == a && E(k, 1) == b) return true;
  return false;
}

TEST(LinkedTopology, SeamCopiesAreLinkedToTheVertexTheyWeldTo) {
  MatrixX3f V;
  MatrixX3i F;
  seamed_quads(V, F);
  const LinkedTopology t = linked_topology(V, F, {});
  EXPECT_EQ(t.parts, 2);
  EXPECT_EQ(t.welded_parts, 1);
  EXPECT_EQ(t.linked_parts, 1);
  EXPECT_EQ(t.seam_links, 2);
  EXPECT_EQ(t.refused_links, 0);
  EXPECT_EQ(t.proximity_links, 0);
  EXPECT_TRUE(has_edge(t.edges, 1, 4));
  EXPECT_TRUE(has_edge(t.edges, 3, 5));
  EXPECT_EQ(t.weld[4], 1);
  EXPECT_EQ(t.weld[5], 3);
  // 5 + 5 mesh edges and the two links.
  EXPECT_EQ(t.edges.rows(), 12);
}

TEST(LinkedTopology, AWeldAcrossTheMaskIsRefusedAndCounted) {
  MatrixX3f V;
  MatrixX3i F;
  seamed_quads(V, F);
  // The left quad body, the right quad apparel: both seam pairs straddle the mask.
  const std::vector<uint8_t> mask = {0, 0, 0, 0, 1, 1, 1, 1};
  const LinkedTopology t = linked_topology(V, F, mask);
  EXPECT_EQ(t.seam_links, 0);
  EXPECT_EQ(t.refused_links, 2);
  EXPECT_EQ(t.welded_parts, 2);
  EXPECT_FALSE(has_edge(t.edges, 1, 4));
  // weld_consistent_mask would instead give each copy its group's value.
  int changed = 0;
  const std::vector<uint8_t> same = weld_consistent_mask(mask, t.weld, &changed);
  EXPECT_EQ(changed, 2);
  EXPECT_EQ(same[4], 0);
  EXPECT_EQ(same[5], 0);
  EXPECT_EQ(same[6], 1);
}

// A strip of `rows` rows of two vertices (x0 and x0 + width), 1 cm apart downwards from y = 0, in the plane z.
void add_strip(MatrixX3f& V, MatrixX3i& F, int rows, float x0, float width, float z) {
  const Eigen::Index base = V.rows(), faces = F.rows();
  V.conservativeResize(base + 2 * rows, 3);
  for (int r = 0; r < rows; ++r) {
    V.row(base + 2 * r) << x0, -0.01f * float(r), z;
    V.row(base + 2 * r + 1) << x0 + width, -0.01f * float(r), z;
  }
  F.conservativeResize(faces + 2 * (rows - 1), 3);
  for (int r = 0; r + 1 < rows; ++r) {
    const int a = int(base) + 2 * r;
    F.row(faces + 2 * r) << a, a + 1, a + 3;
    F.row(faces + 2 * r + 1) << a, a + 3, a + 2;
  }
}

TEST(LinkedTopology, ProximityLinksJoinOverlappingStripsAndNotDistantOnes) {
  MatrixX3f V(0, 3);
  MatrixX3i F(0, 3);
  add_strip(V, F, 5, 0.0f, 0.01f, 0.0f);
  add_strip(V, F, 5, 0.0f, 0.01f, 0.002f);  // the back side of the first, 2 mm behind
  add_strip(V, F, 5, 0.2f, 0.01f, 0.0f);    // a strip 19 cm away
  const LinkedTopology t = linked_topology(V, F, {});
  EXPECT_EQ(t.parts, 3);
  EXPECT_EQ(t.welded_parts, 3);
  EXPECT_EQ(t.linked_parts, 2);
  EXPECT_GT(t.proximity_links, 0);
  for (Eigen::Index k = 0; k < t.edges.rows(); ++k) {
    const bool far_a = t.edges(k, 0) >= 20, far_b = t.edges(k, 1) >= 20;
    EXPECT_EQ(far_a, far_b) << "an edge joins the distant strip: " << t.edges(k, 0) << " " << t.edges(k, 1);
  }
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(has_edge(t.edges, i, i + 10)) << i;  // each vertex to the one behind it
  // A mask that calls the back strip body: no proximity link reaches it.
  std::vector<uint8_t> mask(30, 1);
  std::fill(mask.begin() + 10, mask.begin() + 20, 0);
  EXPECT_EQ(linked_topology(V, F, mask).proximity_links, 0);
  // No proximity links when the radius is 0.
  TopologyOptions none;
  none.proximity_radius = 0;
  EXPECT_EQ(linked_topology(V, F, {}, none).linked_parts, 3);
}

TEST(LinkedTopology, RefusesOptionsOutOfRangeAndAMaskOfAnotherLength) {
  MatrixX3f V;
  MatrixX3i F;
  seamed_quads(V, F);
  TopologyOptions bad;
  bad.proximity_radius = -1;
  EXPECT_THROW(linked_topology(V, F, {}, bad), Error);
  EXPECT_THROW(linked_topology(V, F, std::vector<uint8_t>(3, 0)), Error);
}

// A chain of 21 vertices 1 cm apart hanging from y = 0, and its twin 2 mm behind, joined rung by rung.
struct Chains {
  MatrixX3f V;
  MatrixX2i E;
  std::vector<int32_t> apparel;
  std::vector<float> hang;
};

Chains twin_chains() {
  Chains c;
  const int n = 21;
  c.V.resize(2 * n, 3);
  std::vector<std::pair<int, int>> edges;
  for (int side = 0; side < 2; ++side)
    for (int r = 0; r < n; ++r) {
      c.V.row(side * n + r) << 0.0f, -0.01f * float(r), 0.002f * float(side);
      if (r > 0) edges.emplace_back(side * n + r - 1, side * n + r);
      c.apparel.push_back(side * n + r);
      c.hang.push_back(0.01f * float(r));
    }
  for (int r = 0; r < n; ++r) edges.emplace_back(r, n + r);
  c.E.resize(Eigen::Index(edges.size()), 2);
  for (size_t k = 0; k < edges.size(); ++k) c.E.row(Eigen::Index(k)) << edges[k].first, edges[k].second;
  return c;
}

TEST(ApparelHandles, AStripBundleGetsOneChainOfHandlesSharedByBothStrips) {
  const Chains c = twin_chains();
  HandleOptions o;
  o.spacing = 0.035f;  // rows 4 apart (4 cm) are beyond it, rows 3 apart within, whatever the float rounding
  o.radius = 0.09f;
  o.max_handles = 4;
  const ApparelHandles h = apparel_handles(c.V, c.E, c.apparel, c.hang, o);
  // One handle every 4 rows down the first chain (rows 0, 4, ..., 20), in chain order; the twin is covered.
  ASSERT_EQ(h.num_handles(), 6);
  for (int k = 0; k < 6; ++k) EXPECT_EQ(h.handles[size_t(k)], 4 * k);
  for (Eigen::Index i = 0; i < h.vertex_weights.rows(); ++i) {
    EXPECT_NEAR(h.vertex_weights.row(i).sum(), 1.0f, 1e-6f) << i;
    EXPECT_GE(h.vertex_weights.row(i).minCoeff(), 0.0f);
  }
  // Row 2: handles at rows 0 and 4 (2 cm), 8 (6 cm); row 12 is 10 cm away, beyond the radius.
  const auto kernel = [&](double d) { return std::pow(1 - (d / 0.09) * (d / 0.09), 2); };
  const double w0 = kernel(0.02), w8 = kernel(0.06), total = 2 * w0 + w8;
  EXPECT_EQ(h.vertex_handles(2, 0), 0);
  EXPECT_EQ(h.vertex_handles(2, 1), 1);
  EXPECT_EQ(h.vertex_handles(2, 2), 2);
  EXPECT_NEAR(h.vertex_weights(2, 0), w0 / total, 1e-5);
  EXPECT_NEAR(h.vertex_weights(2, 1), w0 / total, 1e-5);
  EXPECT_NEAR(h.vertex_weights(2, 2), w8 / total, 1e-5);
  EXPECT_EQ(h.vertex_weights(2, 3), 0.0f);
  // The twin's row 2 has the same handles, its weights from 2 mm further.
  for (int k = 0; k < 3; ++k) EXPECT_EQ(h.vertex_handles(21 + 2, k), h.vertex_handles(2, k));
  // A handle is its own heaviest handle; neighbouring handles are graph neighbours, distant ones not.
  EXPECT_EQ(h.vertex_handles(8, 0), 2);
  std::set<std::pair<int, int>> edges;
  for (Eigen::Index k = 0; k < h.handle_edges.rows(); ++k) edges.emplace(h.handle_edges(k, 0), h.handle_edges(k, 1));
  EXPECT_TRUE(edges.count({0, 1}));
  EXPECT_TRUE(edges.count({1, 2}));
  EXPECT_FALSE(edges.count({0, 5}));
}

TEST(ApparelHandles, AreDeterministicAndRefuseBadOptions) {
  const Chains c = twin_chains();
  const ApparelHandles a = apparel_handles(c.V, c.E, c.apparel, c.hang),
                       b = apparel_handles(c.V, c.E, c.apparel, c.hang);
  EXPECT_EQ(a.handles, b.handles);
  EXPECT_TRUE(a.vertex_weights == b.vertex_weights);
  HandleOptions bad;
  bad.radius = bad.spacing;
  EXPECT_THROW(apparel_handles(c.V, c.E, c.apparel, c.hang, bad), Error);
  EXPECT_THROW(apparel_handles(c.V, c.E, c.apparel, std::vector<float>(3, 0.0f)), Error);
}

}  // namespace
}  // namespace amt
