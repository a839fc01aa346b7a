#include "refit/aabb_tree.h"

#include <algorithm>
#include <numeric>

namespace amt::refit {
namespace {
constexpr int kLeafSize = 4;
}

AabbTree::AabbTree(std::vector<Aabb> boxes) : boxes_(std::move(boxes)) {
  order_.resize(boxes_.size());
  std::iota(order_.begin(), order_.end(), 0);
  if (!boxes_.empty()) {
    nodes_.reserve(2 * boxes_.size() / kLeafSize + 2);
    build(0, static_cast<int>(boxes_.size()));
  }
}

int AabbTree::build(int begin, int end) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  Aabb box, centres;
  for (int i = begin; i < end; ++i) {
    const Aabb& b = boxes_[order_[i]];
    box.extend(b.min);
    box.extend(b.max);
    centres.extend(0.5 * (b.min + b.max));
  }
  nodes_[index].box = box;
  nodes_[index].begin = begin;
  nodes_[index].end = end;
  if (end - begin <= kLeafSize) return index;
  int axis;
  (centres.max - centres.min).maxCoeff(&axis);
  const int mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end, [&](int a, int b) {
    return boxes_[a].min[axis] + boxes_[a].max[axis] < boxes_[b].min[axis] + boxes_[b].max[axis];
  });
  const int left = build(begin, mid);
  const int right = build(mid, end);
  nodes_[index].left = left;
  nodes_[index].right = right;
  return index;
}

void AabbTree::query(const Aabb& box, std::vector<int>* hits) const {
  if (nodes_.empty()) return;
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (!node.box.intersects(box)) continue;
    if (node.left < 0) {
      for (int i = node.begin; i < node.end; ++i)
        if (boxes_[order_[i]].intersects(box)) hits->push_back(order_[i]);
    } else {
      stack[top++] = node.left;  // median splits: depth ≤ log2(n) + 1, far below 128
      stack[top++] = node.right;
    }
  }
}

}  // namespace amt::refit
