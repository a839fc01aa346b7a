#include "data_tools/geometry/apparel_topology.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
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

TEST(LinkedTopology, ApparelCopiesOfABodyVertexStayLinkedToEachOther) {
  // The seamed quads and a third quad (8-11) whose left edge is a third copy of the shared edge (8 = 1 = 4,
  // 9 = 3 = 5). Left quad body, the other two apparel: each weld group's smallest vertex (1, 3) is body, and the
  // two apparel copies of each are linked to each other instead of left apart.
  MatrixX3f V;
  MatrixX3i F;
  seamed_quads(V, F);
  V.conservativeResize(12, 3);
  V.bottomRows(4) << 0.01f, 0, 0, 0.01f, 0.01f, 0, 0.01f, 0, 0.01f, 0.01f, 0.01f, 0.01f;
  F.conservativeResize(6, 3);
  F.bottomRows(2) << 8, 10, 11, 8, 11, 9;
  const std::vector<uint8_t> mask = {0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1};
  const LinkedTopology t = linked_topology(V, F, mask);
  EXPECT_EQ(t.weld[8], 1);
  EXPECT_EQ(t.refused_links, 4);
  EXPECT_EQ(t.seam_links, 2);
  EXPECT_TRUE(has_edge(t.edges, 4, 8));
  EXPECT_TRUE(has_edge(t.edges, 5, 9));
  EXPECT_FALSE(has_edge(t.edges, 1, 4));
  EXPECT_FALSE(has_edge(t.edges, 1, 8));
  EXPECT_EQ(t.welded_parts, 2);  // the body quad; the two apparel quads as one
  const std::vector<int32_t> canon = canonical_copies(t.weld, mask);
  const std::vector<int32_t> expected = {0, 1, 2, 3, 4, 5, 6, 7, 4, 5, 10, 11};
  EXPECT_EQ(canon, expected);
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

// A hair chain as a rig holds it: vertex 0 on the neck (body), vertices 1-6 hanging 1 cm apart below it.
// Rig bones: 0 neck (a body joint), 1 hair0 (head y = 0), 2 hair1 (y = -3 cm), 3 hair2 (y = -6 cm), 4 tip (under
// hair2, weighing nothing). Skin weights: v1 neck 0.5 + hair0 0.5, v2 hair0, v3 hair0 0.25 + hair1 0.75, v4 hair1,
// v5 hair1 0.5 + hair2 0.5, v6 neck alone (apparel that the rig does not move: a mask wider than the rig).
struct RiggedChain {
  MatrixX3f V, heads;
  std::vector<std::string> names{"neck", "hair0", "hair1", "hair2", "tip"};
  std::vector<int32_t> parents{-1, 0, 1, 2, 3};
  Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> indices;
  MatrixXfR weights;
  std::vector<int32_t> apparel{1, 2, 3, 4, 5, 6};
};

RiggedChain rigged_chain() {
  RiggedChain c;
  c.V.resize(7, 3);
  for (int i = 0; i < 7; ++i) c.V.row(i) << 0.0f, -0.01f * float(i), 0.0f;
  c.heads.resize(5, 3);
  c.heads << 0, 0.05f, 0, 0, 0, 0, 0, -0.03f, 0, 0, -0.06f, 0, 0, -0.09f, 0;
  c.indices.setConstant(7, 2, -1);
  c.weights.setZero(7, 2);
  const auto set = [&](int v, int b0, float w0, int b1 = -1, float w1 = 0.0f) {
    c.indices(v, 0) = b0, c.weights(v, 0) = w0, c.indices(v, 1) = b1, c.weights(v, 1) = w1;
  };
  set(0, 0, 1.0f);
  set(1, 0, 0.5f, 1, 0.5f);
  set(2, 1, 1.0f);
  set(3, 1, 0.25f, 2, 0.75f);
  set(4, 2, 1.0f);
  set(5, 2, 0.5f, 3, 0.5f);
  set(6, 0, 1.0f);
  return c;
}

TEST(BoneHandles, SelectApparelBonesRenumbersAndDropsBodyInfluences) {
  const RiggedChain c = rigged_chain();
  // Keep hair0 and hair2 only: hair2's parent becomes hair0 (its nearest kept ancestor).
  const ApparelBones b = select_apparel_bones(c.names, c.heads, c.parents, c.indices, c.weights, {0, 1, 0, 1, 0});
  ASSERT_EQ(b.num_bones(), 2);
  EXPECT_EQ(b.names, (std::vector<std::string>{"hair0", "hair2"}));
  EXPECT_EQ(b.parents, (std::vector<int32_t>{-1, 0}));
  EXPECT_FLOAT_EQ(b.heads(1, 1), -0.06f);
  EXPECT_EQ(b.indices(1, 0), -1);  // the neck's half of v1 dropped
  EXPECT_EQ(b.weights(1, 0), 0.0f);
  EXPECT_EQ(b.indices(1, 1), 0);  // hair0
  EXPECT_EQ(b.weights(1, 1), 0.5f);
  EXPECT_EQ(b.indices(3, 0), 0);  // v3's quarter on hair0 stays, its hair1 part (not kept) is dropped
  EXPECT_EQ(b.weights(3, 0), 0.25f);
  EXPECT_EQ(b.indices(3, 1), -1);
  EXPECT_EQ(b.weights(3, 1), 0.0f);
  EXPECT_EQ(b.indices(4, 0), -1);  // v4 on hair1 alone: nothing kept
  EXPECT_EQ(b.indices(5, 1), 1);   // v5's half on hair2, renumbered
  EXPECT_EQ(b.weights(5, 1), 0.5f);
  EXPECT_THROW(select_apparel_bones(c.names, c.heads, c.parents, c.indices, c.weights, {1, 1}), Error);
}

TEST(BoneHandles, OneHandlePerBoneAtTheVertexItWeighsMostWithTheVerticesOwnWeights) {
  const RiggedChain c = rigged_chain();
  const ApparelBones b = select_apparel_bones(c.names, c.heads, c.parents, c.indices, c.weights, {0, 1, 1, 1, 1});
  const ApparelHandles h = bone_handles(c.V, c.apparel, b, 4);
  // hair0 at v2 (its only full weight), hair1 at v4, hair2 at v5 (its one vertex); the tip weighs nothing.
  // Rows are positions in the apparel list (vertex - 1).
  ASSERT_EQ(h.num_handles(), 3);
  EXPECT_EQ(h.handles, (std::vector<int32_t>{1, 3, 4}));
  ASSERT_EQ(h.vertex_weights.cols(), 4);
  const auto expect_row = [&](int row, std::vector<std::pair<int, float>> want) {
    for (int k = 0; k < 4; ++k) {
      const int handle = k < int(want.size()) ? want[size_t(k)].first : want[0].first;
      const float weight = k < int(want.size()) ? want[size_t(k)].second : 0.0f;
      EXPECT_EQ(h.vertex_handles(row, k), handle) << "row " << row << " slot " << k;
      EXPECT_FLOAT_EQ(h.vertex_weights(row, k), weight) << "row " << row << " slot " << k;
    }
  };
  expect_row(0, {{0, 1.0f}});                // v1: half on the neck, all of its apparel half on hair0
  expect_row(1, {{0, 1.0f}});                // v2
  expect_row(2, {{1, 0.75f}, {0, 0.25f}});   // v3: heaviest first
  expect_row(3, {{1, 1.0f}});                // v4
  expect_row(4, {{1, 0.5f}, {2, 0.5f}});     // v5
  expect_row(5, {{2, 1.0f}});                // v6: on no apparel bone, the nearest handle (v5, 1 cm)
  // Handles that share a vertex, and each bone's with its parent's: hair0-hair1, hair1-hair2, nothing else.
  ASSERT_EQ(h.handle_edges.rows(), 2);
  EXPECT_EQ(h.handle_edges(0, 0), 0);
  EXPECT_EQ(h.handle_edges(0, 1), 1);
  EXPECT_EQ(h.handle_edges(1, 0), 1);
  EXPECT_EQ(h.handle_edges(1, 1), 2);
}

TEST(BoneHandles, ABoneWithNoVertexOfItsOwnJoinsTheHandleThereAndBadInputIsRefused) {
  MatrixX3f V(1, 3);
  V << 0, 0, 0;
  ApparelBones b;
  b.names = {"a", "b"};
  b.parents = {-1, -1};
  b.heads.setZero(2, 3);
  b.indices.resize(1, 2);
  b.indices << 0, 1;
  b.weights.resize(1, 2);
  b.weights << 0.5f, 0.5f;
  const ApparelHandles h = bone_handles(V, {0}, b);
  ASSERT_EQ(h.num_handles(), 1);  // b's one vertex is a's handle: b moves with it
  EXPECT_EQ(h.vertex_handles(0, 0), 0);
  EXPECT_FLOAT_EQ(h.vertex_weights(0, 0), 1.0f);
  EXPECT_EQ(h.handle_edges.rows(), 0);
  EXPECT_THROW(bone_handles(V, {0}, b, 0), Error);  // max_handles
  EXPECT_THROW(bone_handles(V, {1}, b), Error);     // apparel vertex out of range
  b.weights.setZero();
  try {
    bone_handles(V, {0}, b);
    ADD_FAILURE() << "expected an error: no bone weighs the apparel";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("none of the 2 apparel bones weighs any of the 1 apparel vertices"),
              std::string::npos)
        << e.what();
  }
}

TEST(BoneResponse, SelectKeepsTheKeptBonesRowsAndVerticesAverageTheirMovedBones) {
  const RiggedChain c = rigged_chain();
  MatrixXfR response(5, kRigResponseChannels);
  response << 0, 0, 0,  // neck: not simulated
      1, 0.2f, 0.1f,    // hair0
      1, 0.6f, 0.3f,    // hair1
      1, 1.0f, 0.5f,    // hair2
      1, 2.0f, 1.0f;    // tip
  const ApparelBones b =
      select_apparel_bones(c.names, c.heads, c.parents, c.indices, c.weights, {0, 1, 0, 1, 0}, response);
  ASSERT_EQ(b.response.rows(), 2);
  EXPECT_FLOAT_EQ(b.response(0, 1), 0.2f);  // hair0
  EXPECT_FLOAT_EQ(b.response(1, 2), 0.5f);  // hair2
  EXPECT_EQ(select_apparel_bones(c.names, c.heads, c.parents, c.indices, c.weights, {0, 1, 0, 1, 0}).response.rows(),
            0);
  EXPECT_THROW(select_apparel_bones(c.names, c.heads, c.parents, c.indices, c.weights, {0, 1, 0, 1, 0},
                                    MatrixXfR::Zero(4, kRigResponseChannels)),
               Error);

  // Over the whole rig: v1 half neck (not moved) + half hair0; v3 0.25 hair0 + 0.75 hair1; v5 hair1 + hair2 halves;
  // v6 neck alone.
  const MatrixXfR r = vertex_response(c.indices, c.weights, response, {1, 3, 5, 6});
  ASSERT_EQ(r.rows(), 4);
  ASSERT_EQ(r.cols(), kRigResponseChannels);
  EXPECT_FLOAT_EQ(r(0, 0), 0.5f);
  EXPECT_FLOAT_EQ(r(0, 1), 0.2f);  // the moved bones' mean: hair0 alone
  EXPECT_FLOAT_EQ(r(0, 2), 0.1f);
  EXPECT_FLOAT_EQ(r(1, 0), 1.0f);
  EXPECT_FLOAT_EQ(r(1, 1), 0.25f * 0.2f + 0.75f * 0.6f);
  EXPECT_FLOAT_EQ(r(1, 2), 0.25f * 0.1f + 0.75f * 0.3f);
  EXPECT_FLOAT_EQ(r(2, 1), 0.5f * 0.6f + 0.5f * 1.0f);
  EXPECT_FLOAT_EQ(r(2, 2), 0.5f * 0.3f + 0.5f * 0.5f);
  EXPECT_EQ(r.row(3), Eigen::RowVector3f::Zero());  // on the neck alone: nothing moves it
  EXPECT_THROW(vertex_response(c.indices, c.weights, response, {7}), Error);
  EXPECT_THROW(vertex_response(c.indices, c.weights, MatrixXfR::Zero(5, 2), {1}), Error);
}

}  // namespace
}  // namespace amt
