#pragma once
// Broad phase: a bounding-volume hierarchy of axis-aligned boxes (median split on the longest axis of
// the box centres), queried with a box for every stored box that overlaps it.
#include <Eigen/Core>
#include <vector>

namespace amt::refit {

/// An axis-aligned box; empty (min > max) by default.
struct Aabb {
  Eigen::Vector3d min = Eigen::Vector3d::Constant(1e300);
  Eigen::Vector3d max = Eigen::Vector3d::Constant(-1e300);

  /// Grows the box to hold p.
  void extend(const Eigen::Vector3d& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
  /// Grows the box by r on every side.
  void inflate(double r) {
    min.array() -= r;
    max.array() += r;
  }
  /// True when the two closed boxes share a point.
  bool intersects(const Aabb& o) const {
    return (min.array() <= o.max.array()).all() && (o.min.array() <= max.array()).all();
  }
};

/// A static hierarchy over boxes; indices in queries are positions in the vector it was built from.
class AabbTree {
 public:
  AabbTree() = default;
  explicit AabbTree(std::vector<Aabb> boxes);

  /// Appends to *hits the index of every stored box that intersects `box` (in no particular order).
  void query(const Aabb& box, std::vector<int>* hits) const;

  int size() const { return static_cast<int>(boxes_.size()); }

 private:
  struct Node {
    Aabb box;
    int begin = 0, end = 0;      // range of order_ (leaves)
    int left = -1, right = -1;   // children (inner nodes)
  };
  int build(int begin, int end);

  std::vector<Aabb> boxes_;
  std::vector<int> order_;  // box indices, grouped by leaf
  std::vector<Node> nodes_;
};

}  // namespace amt::refit
