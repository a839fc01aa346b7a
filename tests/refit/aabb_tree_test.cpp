#include "refit/aabb_tree.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace amt::refit {
namespace {

TEST(AabbTree, QueriesFindExactlyTheOverlappingBoxes) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> pos(-1.0, 1.0), size(0.0, 0.2);
  std::vector<Aabb> boxes(500);
  for (auto& b : boxes) {
    const Eigen::Vector3d c(pos(rng), pos(rng), pos(rng)), h(size(rng), size(rng), size(rng));
    b.extend(c - h);
    b.extend(c + h);
  }
  const AabbTree tree(boxes);
  EXPECT_EQ(tree.size(), 500);
  for (int q = 0; q < 200; ++q) {
    Aabb query;
    const Eigen::Vector3d c(pos(rng), pos(rng), pos(rng));
    query.extend(c);
    query.inflate(size(rng));
    std::vector<int> hits, expected;
    tree.query(query, &hits);
    for (int i = 0; i < 500; ++i)
      if (boxes[i].intersects(query)) expected.push_back(i);
    std::sort(hits.begin(), hits.end());
    EXPECT_EQ(hits, expected);
  }
}

TEST(AabbTree, TouchingBoxesOverlapAndAnEmptyTreeFindsNothing) {
  Aabb a, b;
  a.extend({0, 0, 0});
  a.extend({1, 1, 1});
  b.extend({1, 0, 0});  // shares the face x = 1
  b.extend({2, 1, 1});
  EXPECT_TRUE(a.intersects(b));
  std::vector<int> hits;
  AabbTree().query(a, &hits);
  EXPECT_TRUE(hits.empty());
  AabbTree({b}).query(a, &hits);
  EXPECT_EQ(hits, std::vector<int>{0});
}

}  // namespace
}  // namespace amt::refit
