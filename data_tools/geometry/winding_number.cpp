#include "data_tools/geometry/winding_number.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"

namespace amt {
namespace {

constexpr double kFourPi = 4.0 * M_PI;
// Triangles per leaf: small enough that near-field leaves are cheap, large enough to keep the tree
// shallow (Barill et al. use a few per leaf as well).
constexpr int32_t kLeafSize = 8;
// Traversal stack size. Splits are at the median triangle, so the depth is at most
// ceil(log2(#F / kLeafSize)) + 1 and a depth-first stack never holds more than depth + 1 nodes.
constexpr int kMaxStack = 64;

Eigen::Vector3d to_double(const Eigen::Vector3f& v) {
  return v.cast<double>();
}

// Signed solid angle of triangle (a, b, c) seen from the origin (corners already relative to the query
// point), by Van Oosterom and Strackee (1983): tan(omega / 2) = det[a b c] / (|a||b||c| + (a.b)|c| +
// (b.c)|a| + (c.a)|b|). Positive when the origin lies behind the triangle, i.e. on the side its
// counter-clockwise normal points away from.
double solid_angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double numerator = a.dot(b.cross(c));
  const double denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
  return 2.0 * std::atan2(numerator, denominator);
}

// The same in single precision, for the queries' near field: corners are single-precision positions,
// and their differences to a nearby query point are exact or nearly so.
float solid_angle(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c) {
  const float la = a.norm(), lb = b.norm(), lc = c.norm();
  const float numerator = a.dot(b.cross(c));
  const float denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
  return 2.0f * std::atan2(numerator, denominator);
}

// Closest point to p on segment [a, b].
Eigen::Vector3d closest_point_on_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double length2 = ab.squaredNorm();
  if (length2 <= 0) return a;
  const double t = std::clamp((p - a).dot(ab) / length2, 0.0, 1.0);
  return a + t * ab;
}

// Closest point to p on triangle (a, b, c): Ericson, Real-Time Collision Detection (2005), section
// 5.1.5, closestPtPointTriangle. Classifies p against the Voronoi regions of the corners, then of the
// edges, then projects onto the face. Degenerate (zero-area) triangles fall back to their edges.
Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                          const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  if (ab.cross(ac).squaredNorm() <= 0) {
    const Eigen::Vector3d candidates[3] = {closest_point_on_segment(p, a, b), closest_point_on_segment(p, b, c),
                                           closest_point_on_segment(p, c, a)};
    return *std::min_element(std::begin(candidates), std::end(candidates),
                             [&p](const Eigen::Vector3d& x, const Eigen::Vector3d& y) {
                               return (x - p).squaredNorm() < (y - p).squaredNorm();
                             });
  }
  // Corner region a.
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  // Corner region b.
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  // Edge region ab.
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + (d1 / (d1 - d3)) * ab;
  // Corner region c.
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  // Edge region ac.
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + (d2 / (d2 - d6)) * ac;
  // Edge region bc.
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  // Face region: barycentric coordinates (u, v, w) = (va, vb, vc) / (va + vb + vc).
  const double denominator = 1.0 / (va + vb + vc);
  return a + ab * (vb * denominator) + ac * (vc * denominator);
}

}  // namespace

WindingNumberTree::WindingNumberTree(const MatrixX3f& V, const MatrixX3i& F, double beta) : beta_(beta) {
  validate_mesh(TriMesh{V, F}, "WindingNumberTree");
  AMT_CHECK(std::isfinite(beta) && beta > 0, "WindingNumberTree: beta: expected a positive number, found ", beta);
  faces_ = F;
  vertices_ = V;
  triangles_.resize(static_cast<size_t>(F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    triangles_[f] = {V.row(F(f, 0)).transpose(), V.row(F(f, 1)).transpose(), V.row(F(f, 2)).transpose(),
                     static_cast<int32_t>(f)};
  }
  nodes_.reserve(2 * triangles_.size() / kLeafSize + 2);
  build(0, static_cast<int32_t>(triangles_.size()), 0);
  compact();
  const float inf = std::numeric_limits<float>::infinity();
  for (BoundsNode& b : bounds_) {  // no refit yet: unbounded
    b.displacement = Eigen::AlignedBox3f(Eigen::Vector3f::Constant(-inf), Eigen::Vector3f::Constant(inf));
  }
}

// Far field (Barill et al. 2018). The solid angle of a set of triangles seen from q is the flux of
// f(x) = (x - q) / |x - q|^3 through them, sum_t a_t n_t . (mean of f over triangle t). Taylor-expanded
// about the centre c, with r = c - q and x - c = d:
//   f_i(x) ~ f_i(c) + D_ij d_j + 1/2 D_ijk d_j d_k,
//   D_ij  = delta_ij / |r|^3 - 3 r_i r_j / |r|^5,
//   D_ijk = -3 (delta_ij r_k + delta_ik r_j + delta_jk r_i) / |r|^5 + 15 r_i r_j r_k / |r|^7,
// the flux is r . N / |r|^3 + D_ij M_ij + 1/2 D_ijk Q_ijk with Q_ijk = (Q_i)_jk. Contracting:
//   D_ij M_ij    = tr M / |r|^3 - 3 r^T M r / |r|^5
//   D_ijk Q_ijk  = -3 (2 sum_i (Q_i r)_i + sum_i r_i tr Q_i) / |r|^5 + 15 sum_i r_i r^T Q_i r / |r|^7.
// Each order shrinks the error by about radius / |r|. Only the symmetric parts of M and Q enter the
// contractions, which is what QueryNode keeps (compact() below).
float WindingNumberTree::QueryNode::solid_angle(const Eigen::Vector3f& r) const {
  const float x = r.x(), y = r.y(), z = r.z();
  const float inv2 = 1.0f / r.squaredNorm(), inv1 = std::sqrt(inv2);
  const float inv3 = inv2 * inv1, inv5 = inv3 * inv2, inv7 = inv5 * inv2;
  const float rMr = m_sym[0] * x * x + m_sym[1] * y * y + m_sym[2] * z * z +
                    2.0f * (m_sym[3] * x * y + m_sym[4] * x * z + m_sym[5] * y * z);
  const float c = x * x * (cubic[0] * x + cubic[1] * y + cubic[2] * z) + x * (cubic[3] * y * y + cubic[4] * y * z + cubic[5] * z * z) +
                  y * y * (cubic[6] * y + cubic[7] * z) + z * z * (cubic[8] * y + cubic[9] * z);
  return (r.dot(normal_sum) + trace_m) * inv3 - (3.0f * rMr + 1.5f * r.dot(w)) * inv5 + 7.5f * c * inv7;
}

void WindingNumberTree::compact() {
  query_nodes_.resize(nodes_.size());
  bounds_.resize(nodes_.size());
  const double beta2 = beta_ * beta_;
#pragma omp parallel for schedule(static, 256)
  for (int64_t n = 0; n < int64_t(nodes_.size()); ++n) {
    const Node& node = nodes_[size_t(n)];
    const FarField& far = node.far_field;
    QueryNode& q = query_nodes_[size_t(n)];
    BoundsNode& b = bounds_[size_t(n)];
    b.box = node.box;
    b.left = node.left, b.right = node.right, b.first = node.first, b.count = node.count;
    q.center = far.center.cast<float>();
    q.open2 = float(beta2 * node.radius * node.radius);
    q.normal_sum = far.normal_sum.cast<float>();
    q.trace_m = float(far.first_moment.trace());
    const Eigen::Matrix3d& M = far.first_moment;
    const double m_sym[6] = {M(0, 0), M(1, 1), M(2, 2), 0.5 * (M(0, 1) + M(1, 0)), 0.5 * (M(0, 2) + M(2, 0)),
                             0.5 * (M(1, 2) + M(2, 1))};
    for (int k = 0; k < 6; ++k) q.m_sym[k] = float(m_sym[k]);
    // Q_ijk = (Q_i)_jk. Monomial r_i r_j r_k with i <= j <= k, numbered as in QueryNode::cubic.
    static constexpr int kMonomial[3][3][3] = {{{0, 1, 2}, {1, 3, 4}, {2, 4, 5}},
                                               {{1, 3, 4}, {3, 6, 7}, {4, 7, 8}},
                                               {{2, 4, 5}, {4, 7, 8}, {5, 8, 9}}};
    double cubic[10] = {};
    Eigen::Vector3d w = Eigen::Vector3d::Zero();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        w[j] += 2.0 * far.second_moment[i](i, j);  // 2 sum_i Q_iij
        w[i] += far.second_moment[i](j, j);        // sum_j Q_ijj
        for (int k = 0; k < 3; ++k) cubic[kMonomial[i][j][k]] += far.second_moment[i](j, k);
      }
    }
    q.w = w.cast<float>();
    for (int k = 0; k < 10; ++k) q.cubic[k] = float(cubic[k]);
    q.left = node.left, q.right = node.right, q.first = node.first, q.count = node.count;
  }
}

template <typename Sum>
Eigen::AlignedBox3f WindingNumberTree::fit(Node& node) const {
  // Per-triangle terms in single precision (corners are single precision), sums in Sum: float over a
  // leaf's few triangles, which every frame's refit fits; double over the many of a node the build fits.
  using Vector = Eigen::Matrix<Sum, 3, 1>;
  const int32_t first = node.first, count = node.count;
  FarField& far = node.far_field;
  node.box.setEmpty();
  // First pass: bounds, area-weighted centroid and normal sum, and the bounds of the triangle
  // centroids, which choose the split.
  Eigen::AlignedBox3f centroid_box;
  Vector weighted_centroids = Vector::Zero(), plain_centroids = Vector::Zero(), normal_sum = Vector::Zero();
  Sum area = 0;
  for (int32_t t = first; t < first + count; ++t) {
    const Triangle& tri = triangles_[size_t(t)];
    node.box.extend(tri.a).extend(tri.b).extend(tri.c);
    const Eigen::Vector3f centroid = (tri.a + tri.b + tri.c) / 3.0f;
    centroid_box.extend(centroid);
    const Eigen::Vector3f area_normal = 0.5f * (tri.b - tri.a).cross(tri.c - tri.a);  // a_t n_t
    const float triangle_area = area_normal.norm();
    normal_sum += area_normal.cast<Sum>();
    weighted_centroids += Sum(triangle_area) * centroid.cast<Sum>();
    plain_centroids += centroid.cast<Sum>();
    area += triangle_area;
  }
  far.normal_sum = normal_sum.template cast<double>();
  far.center = area > 0 ? Eigen::Vector3d((weighted_centroids / area).template cast<double>())
                        : Eigen::Vector3d((plain_centroids / Sum(count)).template cast<double>());
  node.area = double(area);

  // Second pass, about the centre: moments and radius. Over a triangle with centroid x_t, the mean of
  // (x - c)(x - c)^T is S_t = d d^T + 1/12 sum_corners (v - x_t)(v - x_t)^T, d = x_t - c; symmetric,
  // kept as its 6 entries xx, yy, zz, xy, xz, yz.
  const Eigen::Vector3f center = far.center.cast<float>();
  // Row i of first_moment is M's row i; row i of second_moment Q_i's 6 entries.
  Eigen::Matrix<Sum, 3, 3> first_moment = Eigen::Matrix<Sum, 3, 3>::Zero();
  Eigen::Matrix<Sum, 3, 6> second_moment = Eigen::Matrix<Sum, 3, 6>::Zero();
  float radius2 = 0;
  for (int32_t t = first; t < first + count; ++t) {
    const Triangle& tri = triangles_[size_t(t)];
    const Eigen::Vector3f area_normal = 0.5f * (tri.b - tri.a).cross(tri.c - tri.a);
    const Eigen::Vector3f centroid = (tri.a + tri.b + tri.c) / 3.0f, d = centroid - center;
    const Eigen::Vector3f ea = tri.a - centroid, eb = tri.b - centroid, ec = tri.c - centroid;
    const auto spread = [&](int i, int j) { return d[i] * d[j] + (ea[i] * ea[j] + eb[i] * eb[j] + ec[i] * ec[j]) / 12.0f; };
    Eigen::Matrix<float, 1, 6> S;
    S << spread(0, 0), spread(1, 1), spread(2, 2), spread(0, 1), spread(0, 2), spread(1, 2);
    first_moment += (area_normal * d.transpose()).template cast<Sum>();
    second_moment += (area_normal * S).template cast<Sum>();
    radius2 = std::max(radius2, std::max((tri.a - center).squaredNorm(),
                                         std::max((tri.b - center).squaredNorm(), (tri.c - center).squaredNorm())));
  }
  far.first_moment = first_moment.template cast<double>();
  for (int i = 0; i < 3; ++i) {
    const Eigen::Matrix<double, 1, 6> q = second_moment.row(i).template cast<double>();
    far.second_moment[i] << q[0], q[3], q[4], q[3], q[1], q[5], q[4], q[5], q[2];
  }
  // Rounded up by a relative 1e-6 so that single-precision rounding never makes it smaller than exact.
  node.radius = std::sqrt(double(radius2)) * (1.0 + 1e-6);
  return centroid_box;
}

// Parallel-axis shifts of the moments from a child's centre c_k to the parent's c, d = c_k - c:
//   M   = sum_k M_k + N_k d^T                         (x_t - c = (x_t - c_k) + d)
//   Q_i = sum_k Q_i,k + m_i d^T + d m_i^T + N_k[i] d d^T,   m_i = row i of M_k, as a column
// (the mean of (x - c)(x - c)^T over a triangle expands the same way, its mean of x - c_k being x_t - c_k).
void WindingNumberTree::merge_children(int32_t index) {
  Node& node = nodes_[index];
  const Node* children[2] = {&nodes_[node.left], &nodes_[node.right]};
  node.box = children[0]->box.merged(children[1]->box);
  node.area = children[0]->area + children[1]->area;
  FarField& far = node.far_field;
  if (node.area > 0) {
    far.center = (children[0]->area * children[0]->far_field.center + children[1]->area * children[1]->far_field.center) /
                 node.area;
  } else {  // both children degenerate: their centres are plain centroid means
    far.center = (children[0]->count * children[0]->far_field.center + children[1]->count * children[1]->far_field.center) /
                 double(node.count);
  }
  far.normal_sum.setZero();
  far.first_moment.setZero();
  for (Eigen::Matrix3d& Q : far.second_moment) Q.setZero();
  node.radius = 0;
  for (const Node* child : children) {
    const FarField& c = child->far_field;
    const Eigen::Vector3d d = c.center - far.center;
    far.normal_sum += c.normal_sum;
    far.first_moment += c.first_moment + c.normal_sum * d.transpose();
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d m = c.first_moment.row(i).transpose();
      far.second_moment[i] += c.second_moment[i] + m * d.transpose() + d * m.transpose() + c.normal_sum[i] * d * d.transpose();
    }
    node.radius = std::max(node.radius, child->radius + d.norm());
  }
  // Every corner lies in the box, so the box's farthest corner bounds the radius too: more tightly
  // than the children's bounds high in the tree, where they add up (a larger radius than needed
  // makes queries open nodes whose far field would do).
  const Eigen::Vector3d lo = node.box.min().cast<double>() - far.center, hi = node.box.max().cast<double>() - far.center;
  node.radius = std::min(node.radius, lo.cwiseAbs().cwiseMax(hi.cwiseAbs()).norm());
}

int32_t WindingNumberTree::build(int32_t first, int32_t count, int depth) {
  assert(depth < kMaxStack - 1);
  Node node;
  node.first = first;
  node.count = count;
  const Eigen::AlignedBox3f centroid_box = count <= kLeafSize ? fit<float>(node) : fit<double>(node);

  const auto index = static_cast<int32_t>(nodes_.size());
  nodes_.push_back(node);
  if (count <= kLeafSize) return index;

  // Median split along the longest axis of the centroid bounds.
  int axis = 0;
  centroid_box.sizes().maxCoeff(&axis);
  const int32_t half = count / 2;
  std::nth_element(triangles_.begin() + first, triangles_.begin() + first + half, triangles_.begin() + first + count,
                   [axis](const Triangle& x, const Triangle& y) {
                     return (x.a[axis] + x.b[axis] + x.c[axis]) < (y.a[axis] + y.b[axis] + y.c[axis]);
                   });
  const int32_t left = build(first, half, depth + 1);
  const int32_t right = build(first + half, count - half, depth + 1);
  nodes_[index].left = left;
  nodes_[index].right = right;
  return index;
}

double WindingNumberTree::winding_number(const Eigen::Vector3f& q) const {
  AMT_CHECK(far_field_current_, "WindingNumberTree::winding_number: expected the far field of the last refit, "
            "found it not yet updated (call update_far_field() after refit(V, false))");
  double omega = 0;  // total solid angle
  int32_t stack[kMaxStack];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const QueryNode& node = query_nodes_[size_t(stack[--top])];
    const Eigen::Vector3f r = node.center - q;
    if (r.squaredNorm() > node.open2) {
      omega += node.solid_angle(r);
    } else if (node.is_leaf()) {
      float leaf = 0;
      for (int32_t t = node.first; t < node.first + node.count; ++t) {
        const Triangle& tri = triangles_[size_t(t)];
        leaf += solid_angle(Eigen::Vector3f(tri.a - q), Eigen::Vector3f(tri.b - q), Eigen::Vector3f(tri.c - q));
      }
      omega += leaf;
    } else {
      stack[top++] = node.left;
      stack[top++] = node.right;
    }
  }
  return omega / kFourPi;
}

double WindingNumberTree::exact_winding_number(const Eigen::Vector3f& p) const {
  const Eigen::Vector3d q = to_double(p);
  double omega = 0;
  for (const Triangle& tri : triangles_) {
    omega += solid_angle(Eigen::Vector3d(to_double(tri.a) - q), Eigen::Vector3d(to_double(tri.b) - q),
                         Eigen::Vector3d(to_double(tri.c) - q));
  }
  return omega / kFourPi;
}

bool WindingNumberTree::inside(const Eigen::Vector3f& p) const {
  return winding_number(p) > 0.5;
}

float WindingNumberTree::distance(const Eigen::Vector3f& p, Eigen::Vector3f* closest,
                                  const std::vector<uint8_t>* faces) const {
  AMT_CHECK(!faces || faces->size() == triangles_.size(), "WindingNumberTree::distance: faces: expected ",
            triangles_.size(), " flags (one per triangle), found ", faces ? faces->size() : 0);
  const Eigen::Vector3d q = to_double(p);
  double best2 = std::numeric_limits<double>::infinity();
  Eigen::Vector3d best_point = q;
  // Depth first, nearer child first, skipping every box farther than the best distance so far.
  int32_t stack[kMaxStack];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const BoundsNode& node = bounds_[size_t(stack[--top])];
    if (static_cast<double>(node.box.squaredExteriorDistance(p)) >= best2) continue;
    if (node.is_leaf()) {
      for (int32_t t = node.first; t < node.first + node.count; ++t) {
        const Triangle& tri = triangles_[t];
        if (faces && !(*faces)[size_t(tri.face)]) continue;
        const Eigen::Vector3d x = closest_point_on_triangle(q, to_double(tri.a), to_double(tri.b), to_double(tri.c));
        const double d2 = (x - q).squaredNorm();
        if (d2 < best2) {
          best2 = d2;
          best_point = x;
        }
      }
    } else {
      const float d_left = bounds_[size_t(node.left)].box.squaredExteriorDistance(p);
      const float d_right = bounds_[size_t(node.right)].box.squaredExteriorDistance(p);
      const bool left_first = d_left <= d_right;
      const int32_t near = left_first ? node.left : node.right, far = left_first ? node.right : node.left;
      const float d_near = std::min(d_left, d_right), d_far = std::max(d_left, d_right);
      if (d_far < best2) stack[top++] = far;  // pushed first, popped last
      if (d_near < best2) stack[top++] = near;
    }
  }
  if (closest) *closest = best_point.cast<float>();
  return static_cast<float>(std::sqrt(best2));
}

bool WindingNumberTree::within(const Eigen::Vector3f& p, float r) const {
  if (!(r >= 0.0f) || triangles_.empty()) return false;
  const Eigen::Vector3d q = to_double(p);
  const double r2 = double(r) * double(r);
  int32_t stack[kMaxStack];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const BoundsNode& node = bounds_[size_t(stack[--top])];
    if (static_cast<double>(node.box.squaredExteriorDistance(p)) > r2) continue;
    if (node.is_leaf()) {
      for (int32_t t = node.first; t < node.first + node.count; ++t) {
        const Triangle& tri = triangles_[t];
        const Eigen::Vector3d x = closest_point_on_triangle(q, to_double(tri.a), to_double(tri.b), to_double(tri.c));
        if ((x - q).squaredNorm() <= r2) return true;
      }
    } else {
      stack[top++] = node.left;
      stack[top++] = node.right;
    }
  }
  return false;
}

void WindingNumberTree::refit(const MatrixX3f& V, bool far_field) {
  AMT_CHECK(V.rows() == vertices_.rows(), "WindingNumberTree::refit: V: expected ", vertices_.rows(),
            " vertices (those the tree was built from), found ", V.rows());
  AMT_CHECK(V.allFinite(), "WindingNumberTree::refit: V: expected finite positions");
  // Each vertex's displacement from its stored (previous) position; then the new position is stored.
  displacement_ = V - vertices_;
  vertices_ = V;
  // What stays_clear() and distance() read is refitted on bounds_ alone (boxes, displacement boxes); the
  // full nodes' boxes and expansions wait for update_far_field(). Leaves own disjoint triangle ranges:
  // refresh their corners and boxes in parallel.
  const int32_t num_nodes = static_cast<int32_t>(bounds_.size());
#pragma omp parallel for schedule(dynamic, 32)
  for (int32_t n = 0; n < num_nodes; ++n) {
    BoundsNode& node = bounds_[size_t(n)];
    if (!node.is_leaf()) continue;
    node.box.setEmpty();
    node.displacement.setEmpty();
    for (int32_t t = node.first; t < node.first + node.count; ++t) {
      Triangle& tri = triangles_[size_t(t)];
      const int32_t i = faces_(tri.face, 0), j = faces_(tri.face, 1), k = faces_(tri.face, 2);
      tri.a = V.row(i).transpose(), tri.b = V.row(j).transpose(), tri.c = V.row(k).transpose();
      node.box.extend(tri.a).extend(tri.b).extend(tri.c);
      node.displacement.extend(displacement_.row(i).transpose())
          .extend(displacement_.row(j).transpose())
          .extend(displacement_.row(k).transpose());
    }
  }
  // Nodes are stored parent before children (pre-order), so a reverse sweep sees children first.
  for (int32_t n = num_nodes - 1; n >= 0; --n) {
    BoundsNode& node = bounds_[size_t(n)];
    if (node.is_leaf()) continue;
    const BoundsNode &left = bounds_[size_t(node.left)], &right = bounds_[size_t(node.right)];
    node.box = left.box.merged(right.box);
    node.displacement = left.displacement.merged(right.displacement);
  }
  far_field_current_ = false;
  if (far_field) update_far_field();
}

void WindingNumberTree::update_far_field() {
  if (far_field_current_) return;
  const int32_t num_nodes = static_cast<int32_t>(nodes_.size());
#pragma omp parallel for schedule(dynamic, 32)
  for (int32_t n = 0; n < num_nodes; ++n) {
    if (nodes_[n].is_leaf()) fit<float>(nodes_[n]);
  }
  for (int32_t n = num_nodes - 1; n >= 0; --n) {
    if (!nodes_[n].is_leaf()) merge_children(n);
  }
  compact();
  far_field_current_ = true;
}

bool WindingNumberTree::stays_clear(const Eigen::Vector3f& p, const Eigen::Vector3f& displacement) const {
  if (!displacement.allFinite()) return false;
  const Eigen::Vector3d q = to_double(p);
  int32_t stack[kMaxStack];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const BoundsNode& node = bounds_[size_t(stack[--top])];
    // The farthest any of the node's corners moved relative to the point: to the farthest corner of its
    // displacement box; 1 um of slack covers the rounding of the single-precision boxes. Infinite
    // before the first refit.
    const Eigen::Vector3f farthest =
        (node.displacement.min() - displacement).cwiseAbs().cwiseMax((node.displacement.max() - displacement).cwiseAbs());
    const float reach = farthest.norm() + 1e-6f;
    if (!(node.box.squaredExteriorDistance(p) > reach * reach)) {
      if (!node.is_leaf()) {
        stack[top++] = node.left;
        stack[top++] = node.right;
        continue;
      }
      for (int32_t t = node.first; t < node.first + node.count; ++t) {
        const Triangle& tri = triangles_[size_t(t)];
        const Eigen::Vector3d x = closest_point_on_triangle(q, to_double(tri.a), to_double(tri.b), to_double(tri.c));
        if (!((x - q).squaredNorm() > double(reach) * double(reach))) return false;
      }
    }
  }
  return true;
}

Eigen::VectorXd WindingNumberTree::winding_numbers(const MatrixX3f& P) const {
  AMT_CHECK(far_field_current_, "WindingNumberTree::winding_numbers: expected the far field of the last refit, "
            "found it not yet updated (call update_far_field() after refit(V, false))");
  Eigen::VectorXd w(P.rows());
#pragma omp parallel for schedule(dynamic, 64)
  for (Eigen::Index i = 0; i < P.rows(); ++i) w[i] = winding_number(P.row(i).transpose());
  return w;
}

Eigen::VectorXf WindingNumberTree::distances(const MatrixX3f& P) const {
  Eigen::VectorXf d(P.rows());
#pragma omp parallel for schedule(dynamic, 64)
  for (Eigen::Index i = 0; i < P.rows(); ++i) d[i] = distance(P.row(i).transpose());
  return d;
}

}  // namespace amt
