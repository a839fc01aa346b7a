#include "refit/skeleton_shrink.h"

#include <algorithm>
#include <array>
#include <limits>
#include <map>

#include "data_tools/geometry/error.h"

namespace amt::refit {
namespace {

constexpr int kUnreachable = std::numeric_limits<int>::max() / 4;

// Hop counts between joints over the bones, with next-hop links for the paths: Floyd-Warshall, as in
// section 3.3 (there over bones with joints as edges; the joint counts come out the same).
struct JointGraph {
  int n = 0;
  std::vector<int> hops;  // n by n
  std::vector<int> next;  // n by n: the joint after i on a shortest path from i to j

  int d(int i, int j) const { return hops[i * n + j]; }
  // Joints from i to j, both included.
  std::vector<int> path(int i, int j) const {
    std::vector<int> out = {i};
    while (i != j) {
      i = next[i * n + j];
      out.push_back(i);
    }
    return out;
  }
};

JointGraph joint_graph(int num_joints, const MatrixX2i& bones) {
  JointGraph g;
  g.n = num_joints;
  g.hops.assign(num_joints * num_joints, kUnreachable);
  g.next.assign(num_joints * num_joints, -1);
  for (int i = 0; i < num_joints; ++i) g.hops[i * num_joints + i] = 0, g.next[i * num_joints + i] = i;
  for (int b = 0; b < bones.rows(); ++b) {
    const int i = bones(b, 0), j = bones(b, 1);
    g.hops[i * num_joints + j] = g.hops[j * num_joints + i] = 1;
    g.next[i * num_joints + j] = j;
    g.next[j * num_joints + i] = i;
  }
  for (int k = 0; k < num_joints; ++k)
    for (int i = 0; i < num_joints; ++i)
      for (int j = 0; j < num_joints; ++j)
        if (g.hops[i * num_joints + k] + g.hops[k * num_joints + j] < g.hops[i * num_joints + j]) {
          g.hops[i * num_joints + j] = g.hops[i * num_joints + k] + g.hops[k * num_joints + j];
          g.next[i * num_joints + j] = g.next[i * num_joints + k];
        }
  return g;
}

struct Shrinker {
  const MatrixX2i& bones;
  JointGraph graph;
  std::vector<SkeletonPoint> joint_point;  // a skeleton point at each joint

  // The joint a point sits at, or -1 for a bone interior.
  int joint_of(const SkeletonPoint& p) const {
    if (p.t <= 0.0) return bones(p.bone, 0);
    if (p.t >= 1.0) return bones(p.bone, 1);
    return -1;
  }

  // The joints a path from p to q crosses, in order (excluding p and q when they sit at joints); empty when
  // p and q lie on one bone. Throws when they are not connected.
  std::vector<int> joints_between(const SkeletonPoint& p, const SkeletonPoint& q, int face) const {
    if (p.bone == q.bone) return {};
    const int jp = joint_of(p), jq = joint_of(q);
    const std::array<int, 2> ends_p = {bones(p.bone, 0), bones(p.bone, 1)};
    const std::array<int, 2> ends_q = {bones(q.bone, 0), bones(q.bone, 1)};
    int best = kUnreachable, bx = -1, by = -1;
    for (int x : ends_p) {
      if (jp >= 0 && x != jp) continue;
      for (int y : ends_q) {
        if (jq >= 0 && y != jq) continue;
        const int d = graph.d(x, y);
        if (d >= kUnreachable) continue;
        // joints on the path x .. y, less p and q themselves when they are x and y
        const int count = d + 1 - (x == jp) - (y == jq) + (x == jp && y == jq && x == y);
        if (count < best) best = count, bx = x, by = y;
      }
    }
    AMT_CHECK(bx >= 0, "shrink to skeleton: triangle ", face, " spans bones ", p.bone, " and ", q.bone,
              ", which the skeleton does not connect");
    std::vector<int> path = graph.path(bx, by);
    if (bx == jp) path.erase(path.begin());
    if (!path.empty() && by == jq) path.pop_back();
    return path;
  }
};

}  // namespace

MatrixX2i skeleton_bones(const std::vector<int32_t>& parents) {
  std::vector<std::array<int, 2>> list;
  for (int j = 0; j < static_cast<int>(parents.size()); ++j)
    if (parents[j] >= 0) list.push_back({parents[j], j});
  MatrixX2i bones(static_cast<int>(list.size()), 2);
  for (int b = 0; b < bones.rows(); ++b) bones.row(b) << list[b][0], list[b][1];
  return bones;
}

std::vector<int> nearest_bones(const Positions& V, const Positions& joints, const MatrixX2i& bones) {
  AMT_CHECK(bones.rows() > 0, "nearest bones: the skeleton has no bones");
  std::vector<int> out(V.rows(), 0);
  for (int i = 0; i < V.rows(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (int b = 0; b < bones.rows(); ++b) {
      const Eigen::RowVector3d a = joints.row(bones(b, 0)), e = joints.row(bones(b, 1)) - a;
      const double len_sq = e.squaredNorm();
      const double t = len_sq > 0 ? std::clamp((V.row(i) - a).dot(e) / len_sq, 0.0, 1.0) : 0.0;
      const double d = (V.row(i) - (a + t * e)).squaredNorm();
      if (d < best) best = d, out[i] = b;
    }
  }
  return out;
}

ShrunkAvatar shrink_to_skeleton(const Positions& V, const MatrixX3i& F, const Positions& target_joints,
                                const Positions& source_joints, const MatrixX2i& bones,
                                const std::vector<int>& vertex_bone) {
  const int num_joints = static_cast<int>(target_joints.rows());
  const int num_bones = static_cast<int>(bones.rows());
  AMT_CHECK(source_joints.rows() == num_joints, "shrink to skeleton: the source skeleton has ", source_joints.rows(),
            " joints, the target ", num_joints);
  AMT_CHECK(static_cast<int>(vertex_bone.size()) == V.rows(), "shrink to skeleton: ", vertex_bone.size(),
            " vertex bones for ", V.rows(), " vertices");
  for (int b = 0; b < num_bones; ++b) {
    for (int k = 0; k < 2; ++k)
      AMT_CHECK(bones(b, k) >= 0 && bones(b, k) < num_joints, "shrink to skeleton: bone ", b, " has joint ",
                bones(b, k), ", expected one in [0, ", num_joints, ")");
    AMT_CHECK((target_joints.row(bones(b, 0)) - target_joints.row(bones(b, 1))).squaredNorm() > 0.0 &&
                  (source_joints.row(bones(b, 0)) - source_joints.row(bones(b, 1))).squaredNorm() > 0.0,
              "shrink to skeleton: bone ", b, " (joints ", bones(b, 0), ", ", bones(b, 1), ") has zero length");
  }
  for (int i = 0; i < V.rows(); ++i)
    AMT_CHECK(vertex_bone[i] >= 0 && vertex_bone[i] < num_bones, "shrink to skeleton: vertex ", i, " has bone ",
              vertex_bone[i], ", expected one in [0, ", num_bones, ")");
  for (int f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      AMT_CHECK(F(f, k) >= 0 && F(f, k) < V.rows(), "shrink to skeleton: face ", f, " has vertex index ", F(f, k),
                ", expected one in [0, ", V.rows(), ")");

  Shrinker shrinker{bones, joint_graph(num_joints, bones), {}};
  shrinker.joint_point.assign(num_joints, SkeletonPoint{-1, 0.0});
  for (int b = num_bones - 1; b >= 0; --b) {
    shrinker.joint_point[bones(b, 0)] = {b, 0.0};
    shrinker.joint_point[bones(b, 1)] = {b, 1.0};
  }

  // Each avatar vertex onto the closest point of its bone on the target skeleton.
  std::vector<SkeletonPoint> at(V.rows());
  std::vector<Eigen::RowVector3d> target(V.rows());
  for (int i = 0; i < V.rows(); ++i) {
    const int b = vertex_bone[i];
    const Eigen::RowVector3d a = target_joints.row(bones(b, 0)), e = target_joints.row(bones(b, 1)) - a;
    at[i] = {b, std::clamp((V.row(i) - a).dot(e) / e.squaredNorm(), 0.0, 1.0)};
    target[i] = V.row(i);
  }

  // Split until no triangle spans a joint. An edge split once is shared by whichever triangles split it.
  std::map<std::pair<int, int>, std::vector<int>> split_edges;  // (low, high) -> inserted, low to high
  std::vector<std::array<int, 3>> pending(F.rows()), done;
  for (int f = 0; f < F.rows(); ++f) pending[f] = {F(f, 0), F(f, 1), F(f, 2)};
  int rounds = 0;
  while (!pending.empty()) {
    AMT_CHECK(rounds <= 2 * num_bones + 4, "shrink to skeleton: the subdivision did not finish within ", 2 * num_bones + 4,
              " rounds (internal error)");
    ++rounds;
    std::vector<std::array<int, 3>> next;
    for (size_t f = 0; f < pending.size(); ++f) {
      const auto tri = pending[f];
      const int face = static_cast<int>(f);
      int best_edge = -1;
      std::vector<int> best_joints;
      for (int k = 0; k < 3; ++k) {
        const int lo = std::min(tri[k], tri[(k + 1) % 3]), hi = std::max(tri[k], tri[(k + 1) % 3]);
        std::vector<int> joints = shrinker.joints_between(at[lo], at[hi], face);
        if (joints.size() > best_joints.size() || (best_edge < 0 && !joints.empty()))
          best_edge = k, best_joints = std::move(joints);
      }
      if (best_edge < 0) {
        done.push_back(tri);
        continue;
      }
      const int a = tri[best_edge], b = tri[(best_edge + 1) % 3], o = tri[(best_edge + 2) % 3];
      const int lo = std::min(a, b), hi = std::max(a, b);
      auto [it, inserted] = split_edges.try_emplace({lo, hi});
      if (inserted) {
        const int count = static_cast<int>(best_joints.size());
        for (int k = 0; k < count; ++k) {
          const int id = static_cast<int>(at.size());
          at.push_back(shrinker.joint_point[best_joints[k]]);
          const double s = double(k + 1) / (count + 1);
          target.push_back((1 - s) * target[lo] + s * target[hi]);
          it->second.push_back(id);
        }
      }
      // The chain a -> ... -> b along the split edge, then the fan from o (orientation kept).
      std::vector<int> chain = {lo};
      chain.insert(chain.end(), it->second.begin(), it->second.end());
      chain.push_back(hi);
      if (a != lo) std::reverse(chain.begin(), chain.end());
      for (size_t k = 0; k + 1 < chain.size(); ++k) next.push_back({chain[k], chain[k + 1], o});
    }
    pending = std::move(next);
  }

  ShrunkAvatar out;
  out.subdivision_rounds = rounds;
  out.F.resize(static_cast<int>(done.size()), 3);
  for (int f = 0; f < out.F.rows(); ++f) out.F.row(f) << done[f][0], done[f][1], done[f][2];
  const int n = static_cast<int>(at.size());
  out.shrunk.resize(n, 3);
  out.target.resize(n, 3);
  for (int i = 0; i < n; ++i) {
    const Eigen::RowVector3d a = source_joints.row(bones(at[i].bone, 0)), e = source_joints.row(bones(at[i].bone, 1)) - a;
    out.shrunk.row(i) = a + at[i].t * e;
    out.target.row(i) = target[i];
  }
  out.at = std::move(at);
  return out;
}

}  // namespace amt::refit
