// Strain limiting: hand-computed projections (two free ends share the excess, a free end of a fixed edge takes
// all of it; a squashed edge opened to the floor), edges within the bounds and their slack untouched, welded copies
// moved as one point, free copies of a fixed vertex pinned to it, the result independent of the edges' order and equal
// to testing every edge every iteration, convergence on a stretched chain, and bad input.
#include "data_tools/geometry/strain_limit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "data_tools/geometry/error.h"
#include "tests/test_support.h"

namespace amt {
namespace {

MatrixX2i edge_list(std::initializer_list<std::pair<int, int>> pairs) {
  MatrixX2i E(Eigen::Index(pairs.size()), 2);
  Eigen::Index k = 0;
  for (const auto& [a, b] : pairs) E.row(k++) << a, b;
  return E;
}

TEST(StrainLimiter, TwoFreeEndsShareTheExcessAndAFreeEndOfAFixedEdgeTakesAllOfIt) {
  // Rest 1, stretched to 2, bound 1.5: each end moves 0.25 towards the other.
  const StrainLimiter both(edge_list({{0, 1}}), {1.0f}, 2, 0, 1.5f, 1);
  float free2[6] = {0, 0, 0, 2, 0, 0};
  both.apply(free2, nullptr);
  EXPECT_FLOAT_EQ(free2[0], 0.25f);
  EXPECT_FLOAT_EQ(free2[3], 1.75f);
  EXPECT_FLOAT_EQ(free2[1], 0.0f);

  // Free vertex 0 at (3, 0, 0) on a fixed vertex (index 1 = fixed 0) at the origin, rest 1, bound 1.2: to 1.2.
  const StrainLimiter pinned(edge_list({{1, 0}}), {1.0f}, 1, 1, 1.2f, 1);
  float free1[3] = {3, 0, 0};
  const float fixed1[3] = {0, 0, 0};
  pinned.apply(free1, fixed1);
  EXPECT_FLOAT_EQ(free1[0], 1.2f);
  EXPECT_FLOAT_EQ(free1[1], 0.0f);
  EXPECT_FLOAT_EQ(free1[2], 0.0f);

  // Within the bound (and compressed): untouched, exactly.
  float within[6] = {0, 0, 0, 0.3f, 1.1f, 0};
  both.apply(within, nullptr);
  EXPECT_EQ(within[3], 0.3f);
  EXPECT_EQ(within[4], 1.1f);
}

TEST(StrainLimiter, ASquashedEdgeOpensToTheFloorAndEdgesWithinTheSlackStayPut) {
  // Rest 1, squashed to 0.3, floor 0.7: each end moves 0.2 away from the other.
  const StrainLimiter both(edge_list({{0, 1}}), {1.0f}, 2, 0, 1.5f, 1, 0.0f, 0.7f);
  float squashed[6] = {0, 0, 0, 0.3f, 0, 0};
  both.apply(squashed, nullptr);
  EXPECT_FLOAT_EQ(squashed[0], -0.2f);
  EXPECT_FLOAT_EQ(squashed[3], 0.5f);
  // A free end on a fixed vertex: all of it, to 0.7 along the edge.
  const StrainLimiter pinned(edge_list({{1, 0}}), {1.0f}, 1, 1, 1.2f, 1, 0.0f, 0.7f);
  float free1[3] = {0, 0.1f, 0};
  const float fixed1[3] = {0, 0, 0};
  pinned.apply(free1, fixed1);
  EXPECT_FLOAT_EQ(free1[1], 0.7f);
  EXPECT_FLOAT_EQ(free1[0], 0.0f);
  // Within the slack of either bound (0.7 x 0.99 > 0.686, 1.2 x 1.01 < 1.224): untouched, exactly. A collapsed edge
  // has no direction to open along: untouched.
  for (const float x : {0.69f, 1.21f, 0.0f}) {
    float p[3] = {0, x, 0};
    pinned.apply(p, fixed1);
    EXPECT_EQ(p[1], x) << x;
  }
  // Past the slack: onto the bound itself.
  float p[3] = {0, 1.23f, 0};
  pinned.apply(p, fixed1);
  EXPECT_FLOAT_EQ(p[1], 1.2f);
  EXPECT_NE(test::error_of([] {
              StrainLimiter(edge_list({{0, 1}}), {1.0f}, 2, 0, 1.2f, 1, 0.0f, 1.0f);
            }).find("expected a smallest stretch in [0, 1), found 1"),
            std::string::npos);
}

// Jacobi projections that test every edge every iteration, as StrainLimiter::apply documents them (no weld).
void reference_limit(const MatrixX2i& E, const std::vector<float>& rest, int num_free, float* x, float high, float low,
                     int iterations) {
  for (int it = 0; it < iterations; ++it) {
    std::vector<float> delta(size_t(num_free) * 3, 0.0f);
    std::vector<int> hits(size_t(num_free), 0);
    for (Eigen::Index e = 0; e < E.rows(); ++e) {
      const int a = E(e, 0), b = E(e, 1);
      float d[3], squared = 0;
      for (int k = 0; k < 3; ++k) d[k] = x[3 * b + k] - x[3 * a + k], squared += d[k] * d[k];
      const float r = rest[size_t(e)];
      const float up = (1 + kStrainSlack) * high * r, down = (1 - kStrainSlack) * low * r;
      const bool stretched = squared > up * up;
      if (!(stretched || squared < down * down) || !(squared > 0)) continue;
      const float length = std::sqrt(squared);
      const float s = (length - (stretched ? high : low) * r) / length * 0.5f;
      for (int k = 0; k < 3; ++k) delta[size_t(a) * 3 + k] += s * d[k], delta[size_t(b) * 3 + k] -= s * d[k];
      ++hits[size_t(a)], ++hits[size_t(b)];
    }
    for (int v = 0; v < num_free; ++v)
      for (int k = 0; k < 3; ++k)
        if (hits[size_t(v)] > 0) x[3 * v + k] += (1.0f / float(hits[size_t(v)])) * delta[size_t(v) * 3 + k];
  }
}

TEST(StrainLimiter, LaterIterationsTestingOnlyTheMovedVerticesEdgesGiveTheSameResult) {
  // A 6 x 6 grid of free vertices, spacing 0.1, jittered by up to +-0.06 per coordinate: edges from about 0.2 to
  // 2 times their rest length.
  const int n = 6;
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      if (j + 1 < n) pairs.emplace_back(i * n + j, i * n + j + 1);
      if (i + 1 < n) pairs.emplace_back(i * n + j, (i + 1) * n + j);
      if (i + 1 < n && j + 1 < n) pairs.emplace_back(i * n + j, (i + 1) * n + j + 1);
    }
  MatrixX2i E(Eigen::Index(pairs.size()), 2);
  std::vector<float> rest;
  for (size_t e = 0; e < pairs.size(); ++e) {
    E.row(Eigen::Index(e)) << pairs[e].first, pairs[e].second;
    const bool diagonal = pairs[e].second - pairs[e].first == n + 1;
    rest.push_back(diagonal ? 0.1f * std::sqrt(2.0f) : 0.1f);
  }
  std::mt19937 random(7);
  std::uniform_real_distribution<float> jitter(-0.06f, 0.06f);
  std::vector<float> a(size_t(n * n) * 3);
  for (int v = 0; v < n * n; ++v) {
    a[size_t(v) * 3] = 0.1f * float(v % n) + jitter(random);
    a[size_t(v) * 3 + 1] = 0.1f * float(v / n) + jitter(random);
    a[size_t(v) * 3 + 2] = jitter(random);
  }
  const std::vector<float> start = a;
  std::vector<float> b = a;
  const StrainLimiter limiter(E, rest, n * n, 0, 1.1f, 6, 0.0f, 0.8f);
  limiter.apply(a.data(), nullptr);
  reference_limit(E, rest, n * n, b.data(), 1.1f, 0.8f, 6);
  for (size_t k = 0; k < a.size(); ++k) EXPECT_EQ(a[k], b[k]) << k;
  // And it moved: the jitter left edges past the bounds.
  float moved = 0;
  for (size_t k = 0; k < a.size(); ++k) moved = std::max(moved, std::abs(a[k] - start[k]));
  EXPECT_GT(moved, 0.01f);
}

TEST(StrainLimiter, WeldedCopiesMoveAsOnePointAndAClosedSeamStaysClosed) {
  // Free 0 and 1 are the two copies of a seam vertex (a link of rest length 0); each has its own edge to a fixed
  // vertex (2 and 3) that it is stretched from.
  const MatrixX2i E = edge_list({{0, 1}, {0, 2}, {1, 3}});
  const StrainLimiter limiter(E, {0.0f, 1.0f, 1.0f}, 2, 2, 1.2f, 4, 1e-3f);
  float free_xyz[6] = {0, 2, 0, 0, 2, 0};
  const float fixed_xyz[6] = {0, 0, 0, 2.0f, 0, 0};
  limiter.apply(free_xyz, fixed_xyz);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(free_xyz[k], free_xyz[3 + k]) << k;
  // Pulled towards both fixed vertices (it moved, down from y = 2).
  EXPECT_LT(free_xyz[1], 1.9f);
  // Without the weld the link only asks the copies to meet, among other requests, once they have parted: after
  // one iteration (the link has no length to act on yet) the seam is open.
  const StrainLimiter unwelded(E, {0.0f, 1.0f, 1.0f}, 2, 2, 1.2f, 1, 0.0f);
  float open[6] = {0, 2, 0, 0, 2, 0};
  unwelded.apply(open, fixed_xyz);
  const float gap = Eigen::Vector3f(open[0] - open[3], open[1] - open[4], open[2] - open[5]).norm();
  EXPECT_GT(gap, 1e-3f) << open[0] << " " << open[1] << " " << open[3] << " " << open[4];
}

TEST(StrainLimiter, AFreeCopyOfAFixedVertexIsPinnedToItAgainstTheFloor) {
  // Free 0 is the apparel copy of fixed vertex 2 (a link of rest length 0); free 1 is welded to free 0 too. Edge
  // 0-3 (rest 1) is squashed to 0.5 by the body it hangs from, below the floor 0.7: the floor asks 0 to move away
  // from 3, the weld to stay on 2. Pinned, both copies sit exactly on 2 and the squashed edge is left as the body has
  // it; the edge 1-4 between a copy and another fixed vertex is not limited either (both ends are fixed now).
  const MatrixX2i E = edge_list({{0, 2}, {0, 1}, {0, 3}, {1, 4}});
  const StrainLimiter limiter(E, {0.0f, 0.0f, 1.0f, 1.0f}, 2, 3, 1.2f, 32, 1e-3f, 0.7f);
  EXPECT_EQ(limiter.num_edges(), 0);
  float free_xyz[6] = {0.1f, 0.2f, 0.0f, -0.1f, 0.0f, 0.3f};
  const float fixed_xyz[9] = {0, 0, 0, 0.5f, 0, 0, 0, 3.0f, 0};
  limiter.apply(free_xyz, fixed_xyz);
  for (int k = 0; k < 6; ++k) EXPECT_EQ(free_xyz[k], fixed_xyz[k % 3]) << k;
  // A free vertex with an edge to a pinned group is limited against the fixed vertex the group is pinned to.
  const StrainLimiter chain(edge_list({{0, 2}, {1, 0}}), {0.0f, 1.0f}, 2, 1, 1.2f, 1, 1e-3f);
  EXPECT_EQ(chain.num_edges(), 1);
  float moved[6] = {5, 5, 5, 0, 3, 0};
  const float body[3] = {0, 0, 0};
  chain.apply(moved, body);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(moved[k], body[k]) << k;
  EXPECT_NEAR(moved[4], 1.2f, 1e-6f);  // pulled all the way to the bound (a free end of a fixed edge)
}

TEST(StrainLimiter, TheResultDoesNotDependOnTheEdgesOrderAndAChainConverges) {
  // A chain of 6 free vertices hanging from fixed vertex 6, rest 0.1 each, stretched to 0.3 each along a zigzag.
  const MatrixX2i forward = edge_list({{6, 0}, {0, 1}, {1, 2}, {2, 3}, {3, 4}, {4, 5}});
  const MatrixX2i backward = edge_list({{5, 4}, {3, 4}, {2, 3}, {2, 1}, {1, 0}, {0, 6}});
  const std::vector<float> rest(6, 0.1f);
  float a[18], b[18];
  for (int v = 0; v < 6; ++v) {
    a[3 * v] = b[3 * v] = 0.05f * float(v % 2);
    a[3 * v + 1] = b[3 * v + 1] = -0.3f * float(v + 1);
    a[3 * v + 2] = b[3 * v + 2] = 0.0f;
  }
  const float fixed[3] = {0, 0, 0};
  StrainLimiter(forward, rest, 6, 1, 1.1f, 8).apply(a, fixed);
  StrainLimiter(backward, rest, 6, 1, 1.1f, 8).apply(b, fixed);
  for (int k = 0; k < 18; ++k) EXPECT_FLOAT_EQ(a[k], b[k]) << k;
  // Many iterations: every edge within the bound and its slack.
  StrainLimiter(forward, rest, 6, 1, 1.1f, 1000).apply(a, fixed);
  const auto point = [&](int v) { return v == 6 ? Eigen::Vector3f(0, 0, 0) : Eigen::Vector3f(a[3 * v], a[3 * v + 1], a[3 * v + 2]); };
  for (Eigen::Index e = 0; e < forward.rows(); ++e)
    EXPECT_LE((point(forward(e, 0)) - point(forward(e, 1))).norm(), 0.11f * (1 + kStrainSlack) + 1e-5f) << e;
}

TEST(StrainLimiter, BadInputIsAClearError) {
  EXPECT_NE(test::error_of([] { StrainLimiter(edge_list({{0, 5}}), {1.0f}, 2, 1, 1.2f); })
                .find("strain limit: edge 0: expected two vertices in [0, 3), found (0, 5)"),
            std::string::npos);
  EXPECT_NE(test::error_of([] { StrainLimiter(edge_list({{0, 1}}), {-1.0f}, 2, 0, 1.2f); })
                .find("expected a rest length >= 0, found -1"),
            std::string::npos);
  EXPECT_NE(test::error_of([] { StrainLimiter(edge_list({{0, 1}}), {1.0f}, 2, 0, 1.0f); })
                .find("expected a largest stretch in (1, 100], found 1"),
            std::string::npos);
  EXPECT_NE(test::error_of([] { StrainLimiter(edge_list({{0, 1}}), {}, 2, 0, 1.2f); })
                .find("expected a rest length per edge (1), found 0"),
            std::string::npos);
}

}  // namespace
}  // namespace amt
