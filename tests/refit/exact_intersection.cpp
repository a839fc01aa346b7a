#include "exact_intersection.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Intersections_3/Segment_3_Triangle_3.h>
#include <CGAL/Intersections_3/Triangle_3_Triangle_3.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace amt::refit::test {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using P3 = K::Point_3;

// Two triangles that share the corners listed in `shared` (positions in each triangle) intersect beyond
// them: the decision of CGAL's self-intersection test for adjacent faces.
bool triangles_intersect(const std::array<P3, 3>& a, const std::array<P3, 3>& b, const std::array<int, 3>& fa,
                         const std::array<int, 3>& fb) {
  int shared = 0, ia = -1, ib = -1;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (fa[i] == fb[j]) ++shared, ia = i, ib = j;
  if (shared == 0) return CGAL::do_intersect(K::Triangle_3(a[0], a[1], a[2]), K::Triangle_3(b[0], b[1], b[2]));
  if (shared == 1) {
    // Sharing corner ia / ib: they meet elsewhere iff an opposite edge meets the other triangle.
    const K::Segment_3 opposite_a(a[(ia + 1) % 3], a[(ia + 2) % 3]), opposite_b(b[(ib + 1) % 3], b[(ib + 2) % 3]);
    return CGAL::do_intersect(opposite_a, K::Triangle_3(b[0], b[1], b[2])) ||
           CGAL::do_intersect(opposite_b, K::Triangle_3(a[0], a[1], a[2]));
  }
  if (shared == 2) {
    // Sharing an edge (u, v): they overlap iff the opposite corners are coplanar with it and on the same side.
    int ua = -1, ub = -1;  // the corners not shared
    for (int i = 0; i < 3; ++i) {
      if (std::find(fb.begin(), fb.end(), fa[i]) == fb.end()) ua = i;
      if (std::find(fa.begin(), fa.end(), fb[i]) == fa.end()) ub = i;
    }
    const P3& u = a[(ua + 1) % 3];
    const P3& v = a[(ua + 2) % 3];
    if (CGAL::orientation(u, v, a[ua], b[ub]) != CGAL::COPLANAR) return false;
    return CGAL::coplanar_orientation(u, v, a[ua], b[ub]) == CGAL::POSITIVE;
  }
  return true;  // the same triangle twice
}

// --- Root-finding continuous check

// A polynomial of degree ≤ 3 in t, c[0] + c[1] t + c[2] t² + c[3] t³.
struct Cubic {
  std::array<double, 4> c{};
  double operator()(double t) const { return ((c[3] * t + c[2]) * t + c[1]) * t + c[0]; }
};

// Linear coordinates q0 + t dq; products of up to three of them.
struct Lin {
  double a, b;  // a + b t
};
Cubic mul3(const Lin& x, const Lin& y, const Lin& z) {
  Cubic r;
  const double xy0 = x.a * y.a, xy1 = x.a * y.b + x.b * y.a, xy2 = x.b * y.b;
  r.c = {xy0 * z.a, xy0 * z.b + xy1 * z.a, xy1 * z.b + xy2 * z.a, xy2 * z.b};
  return r;
}

// det[u, v, w] of three linearly moving vectors: a cubic in t.
Cubic triple_product(const std::array<Lin, 3>& u, const std::array<Lin, 3>& v, const std::array<Lin, 3>& w) {
  Cubic r;
  auto add = [&r](const Cubic& term, double sign) {
    for (int k = 0; k < 4; ++k) r.c[k] += sign * term.c[k];
  };
  add(mul3(u[0], v[1], w[2]), 1);
  add(mul3(u[0], v[2], w[1]), -1);
  add(mul3(u[1], v[2], w[0]), 1);
  add(mul3(u[1], v[0], w[2]), -1);
  add(mul3(u[2], v[0], w[1]), 1);
  add(mul3(u[2], v[1], w[0]), -1);
  return r;
}

// Roots of f in [0, 1]: split at the roots of f' (monotone pieces), bisect every sign change; an
// (almost) identically zero f gives a dense sampling instead (coplanar motion).
std::vector<double> roots_in_unit_interval(const Cubic& f) {
  const double scale = std::max({std::abs(f.c[0]), std::abs(f.c[1]), std::abs(f.c[2]), std::abs(f.c[3])});
  std::vector<double> roots;
  if (scale < 1e-300 || (std::abs(f(0)) < 1e-15 * scale && std::abs(f(0.5)) < 1e-15 * scale &&
                         std::abs(f(1)) < 1e-15 * scale && std::abs(f(0.25)) < 1e-15 * scale)) {
    for (int i = 0; i <= 64; ++i) roots.push_back(i / 64.0);
    return roots;
  }
  std::vector<double> cuts = {0.0, 1.0};
  const double a = 3 * f.c[3], b = 2 * f.c[2], c = f.c[1];  // f' = a t² + b t + c
  if (std::abs(a) > 1e-300) {
    const double disc = b * b - 4 * a * c;
    if (disc >= 0) {
      const double s = std::sqrt(disc);
      for (double t : {(-b - s) / (2 * a), (-b + s) / (2 * a)})
        if (t > 0 && t < 1) cuts.push_back(t);
    }
  } else if (std::abs(b) > 1e-300) {
    const double t = -c / b;
    if (t > 0 && t < 1) cuts.push_back(t);
  }
  std::sort(cuts.begin(), cuts.end());
  for (size_t i = 0; i + 1 < cuts.size(); ++i) {
    double lo = cuts[i], hi = cuts[i + 1];
    double flo = f(lo), fhi = f(hi);
    if (flo == 0) roots.push_back(lo);
    if (fhi == 0) roots.push_back(hi);
    if (flo * fhi >= 0) continue;
    for (int k = 0; k < 100 && hi - lo > 1e-17; ++k) {
      const double mid = 0.5 * (lo + hi);
      const double fm = f(mid);
      if ((fm < 0) == (flo < 0)) lo = mid, flo = fm;
      else hi = mid;
    }
    roots.push_back(0.5 * (lo + hi));
  }
  return roots;
}

std::array<Lin, 3> moving(const Positions& x0, const Positions& x1, int i, int j) {
  // x_i(t) - x_j(t)
  std::array<Lin, 3> r;
  for (int k = 0; k < 3; ++k) {
    const double a = x0(i, k) - x0(j, k);
    r[k] = {a, (x1(i, k) - x1(j, k)) - a};
  }
  return r;
}

Eigen::Vector3d at(const Positions& x0, const Positions& x1, int i, double t) {
  return ((1 - t) * x0.row(i) + t * x1.row(i)).transpose();
}

// p within `tol` of the triangle (a, b, c), by its barycentric coordinates in the triangle's plane and its
// height over it.
bool point_in_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                       const Eigen::Vector3d& c, double tol) {
  const Eigen::Vector3d e1 = b - a, e2 = c - a, r = p - a;
  const double g11 = e1.dot(e1), g12 = e1.dot(e2), g22 = e2.dot(e2);
  const double det = g11 * g22 - g12 * g12;
  if (det <= 1e-30) return false;  // a degenerate triangle: the static check reports it instead
  const double r1 = r.dot(e1), r2 = r.dot(e2);
  const double u = (g22 * r1 - g12 * r2) / det, v = (g11 * r2 - g12 * r1) / det;
  const Eigen::Vector3d q = a + u * e1 + v * e2;
  const double slack = tol / std::sqrt(std::max(g11, g22));
  return u >= -slack && v >= -slack && u + v <= 1 + slack && (p - q).norm() <= tol;
}

bool segments_meet(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1, const Eigen::Vector3d& b0,
                   const Eigen::Vector3d& b1, double tol) {
  // Closest points of the two lines; parallel lines fall back to end points against segments.
  const Eigen::Vector3d da = a1 - a0, db = b1 - b0, r = a0 - b0;
  const double aa = da.dot(da), bb = db.dot(db), ab = da.dot(db), ar = da.dot(r), br = db.dot(r);
  const double det = aa * bb - ab * ab;
  auto point_segment = [](const Eigen::Vector3d& p, const Eigen::Vector3d& s0, const Eigen::Vector3d& s1) {
    const Eigen::Vector3d d = s1 - s0;
    const double t = std::clamp((p - s0).dot(d) / std::max(d.dot(d), 1e-300), 0.0, 1.0);
    return (p - (s0 + t * d)).norm();
  };
  if (det <= 1e-12 * aa * bb) {
    return std::min({point_segment(a0, b0, b1), point_segment(a1, b0, b1), point_segment(b0, a0, a1),
                     point_segment(b1, a0, a1)}) <= tol;
  }
  const double s = (ab * br - bb * ar) / det, u = (aa * br - ab * ar) / det;
  const double sa = tol / std::sqrt(aa), sb = tol / std::sqrt(bb);
  if (s < -sa || s > 1 + sa || u < -sb || u > 1 + sb) return false;
  return ((a0 + s * da) - (b0 + u * db)).norm() <= tol;
}

}  // namespace

int count_intersecting_triangle_pairs(const Positions& V, const MatrixX3i& F, const std::vector<uint8_t>& obstacle) {
  const int m = static_cast<int>(F.rows());
  std::vector<std::array<P3, 3>> tri(m);
  std::vector<std::array<int, 3>> idx(m);
  std::vector<Eigen::Vector3d> lo(m), hi(m);
  std::vector<uint8_t> fixed(m, 0);
  for (int f = 0; f < m; ++f) {
    lo[f] = hi[f] = V.row(F(f, 0)).transpose();
    bool all = !obstacle.empty();
    for (int k = 0; k < 3; ++k) {
      const int v = F(f, k);
      idx[f][k] = v;
      tri[f][k] = P3(V(v, 0), V(v, 1), V(v, 2));
      lo[f] = lo[f].cwiseMin(V.row(v).transpose());
      hi[f] = hi[f].cwiseMax(V.row(v).transpose());
      all = all && obstacle[v];
    }
    fixed[f] = all;
  }
  int count = 0;
  for (int f = 0; f < m; ++f)
    for (int g = f + 1; g < m; ++g) {
      if (fixed[f] && fixed[g]) continue;
      // Exact box rejection: min and max of the coordinates are exact.
      if ((hi[f].array() < lo[g].array()).any() || (hi[g].array() < lo[f].array()).any()) continue;
      if (triangles_intersect(tri[f], tri[g], idx[f], idx[g])) ++count;
    }
  return count;
}

int count_crossings(const CollisionMesh& mesh, const Positions& x0, const Positions& x1, double tolerance) {
  // A pair of four moving points (i, j, k, l) touches when, at a root of the coplanarity of (j - i, k - i,
  // l - i), `meet` holds at the four positions of that time.
  auto touches = [&](int i, int j, int k, int l, auto meet) {
    const Cubic coplanar = triple_product(moving(x0, x1, j, i), moving(x0, x1, k, i), moving(x0, x1, l, i));
    for (double t : roots_in_unit_interval(coplanar))
      if (meet(at(x0, x1, i, t), at(x0, x1, j, t), at(x0, x1, k, t), at(x0, x1, l, t))) return true;
    return false;
  };
  // Swept boxes reject pairs that cannot meet (a plain loop, not the refit's broad phase).
  const int n = mesh.num_vertices;
  std::vector<Eigen::Array3d> lo(n), hi(n);
  for (int v = 0; v < n; ++v) {
    lo[v] = x0.row(v).transpose().array().min(x1.row(v).transpose().array());
    hi[v] = x0.row(v).transpose().array().max(x1.row(v).transpose().array());
  }
  auto swept = [&](std::initializer_list<int> vs, Eigen::Array3d* l, Eigen::Array3d* h) {
    *l = Eigen::Array3d::Constant(1e300), *h = Eigen::Array3d::Constant(-1e300);
    for (int v : vs) *l = l->min(lo[v]), *h = h->max(hi[v]);
  };
  auto apart = [tolerance](const Eigen::Array3d& l1, const Eigen::Array3d& h1, const Eigen::Array3d& l2,
                           const Eigen::Array3d& h2) { return (h1 < l2 - tolerance).any() || (h2 < l1 - tolerance).any(); };
  const auto& F = mesh.F;
  const auto& E = mesh.E;
  int count = 0;
  for (int v = 0; v < n; ++v)
    for (int f = 0; f < F.rows(); ++f) {
      const int a = F(f, 0), b = F(f, 1), c = F(f, 2);
      if (v == a || v == b || v == c || (mesh.vertex_obstacle[v] && mesh.face_obstacle[f])) continue;
      Eigen::Array3d fl, fh;
      swept({a, b, c}, &fl, &fh);
      if (apart(lo[v], hi[v], fl, fh)) continue;
      count += touches(a, b, c, v, [&](const auto& pa, const auto& pb, const auto& pc, const auto& pv) {
        return point_in_triangle(pv, pa, pb, pc, tolerance);
      });
    }
  for (int i = 0; i < E.rows(); ++i)
    for (int j = i + 1; j < E.rows(); ++j) {
      const int a0 = E(i, 0), a1 = E(i, 1), b0 = E(j, 0), b1 = E(j, 1);
      if (a0 == b0 || a0 == b1 || a1 == b0 || a1 == b1 || (mesh.edge_obstacle[i] && mesh.edge_obstacle[j])) continue;
      Eigen::Array3d al, ah, bl, bh;
      swept({a0, a1}, &al, &ah);
      swept({b0, b1}, &bl, &bh);
      if (apart(al, ah, bl, bh)) continue;
      count += touches(a0, a1, b0, b1, [&](const auto& p0, const auto& p1, const auto& q0, const auto& q1) {
        return segments_meet(p0, p1, q0, q1, tolerance);
      });
    }
  return count;
}

}  // namespace amt::refit::test
