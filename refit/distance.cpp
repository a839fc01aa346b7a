#include "refit/distance.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "refit/jet.h"

namespace amt::refit {
namespace {

using Eigen::Vector3d;

// --- Closed-form pieces (IPC supplement, section 2), templated on double or Jet<12>

template <typename T>
T point_point_sq(const Vec3<T>& p, const Vec3<T>& q) {
  const Vec3<T> d = p - q;
  return dot(d, d);
}

// |(e0 - p) × (e1 - p)|² / |e1 - e0|²: twice the triangle area over the base, squared.
template <typename T>
T point_line_sq(const Vec3<T>& p, const Vec3<T>& e0, const Vec3<T>& e1) {
  const Vec3<T> c = cross(e0 - p, e1 - p);
  const Vec3<T> e = e1 - e0;
  return dot(c, c) * reciprocal(dot(e, e));
}

// ((p - t0)·n)² / |n|², n = (t1 - t0) × (t2 - t0).
template <typename T>
T point_plane_sq(const Vec3<T>& p, const Vec3<T>& t0, const Vec3<T>& t1, const Vec3<T>& t2) {
  const Vec3<T> n = cross(t1 - t0, t2 - t0);
  const T h = dot(p - t0, n);
  return h * h * reciprocal(dot(n, n));
}

// ((eb0 - ea0)·n)² / |n|², n = (ea1 - ea0) × (eb1 - eb0).
template <typename T>
T line_line_sq(const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1) {
  const Vec3<T> n = cross(ea1 - ea0, eb1 - eb0);
  const T h = dot(eb0 - ea0, n);
  return h * h * reciprocal(dot(n, n));
}

template <typename T>
T point_triangle_piece(const Vec3<T>& p, const Vec3<T>& t0, const Vec3<T>& t1, const Vec3<T>& t2,
                       PointTriangleType type) {
  switch (type) {
    case PointTriangleType::P_T0: return point_point_sq(p, t0);
    case PointTriangleType::P_T1: return point_point_sq(p, t1);
    case PointTriangleType::P_T2: return point_point_sq(p, t2);
    case PointTriangleType::P_E0: return point_line_sq(p, t0, t1);
    case PointTriangleType::P_E1: return point_line_sq(p, t1, t2);
    case PointTriangleType::P_E2: return point_line_sq(p, t2, t0);
    case PointTriangleType::P_T: return point_plane_sq(p, t0, t1, t2);
  }
  return T(0.0);
}

template <typename T>
T edge_edge_piece(const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1,
                  EdgeEdgeType type) {
  switch (type) {
    case EdgeEdgeType::EA0_EB0: return point_point_sq(ea0, eb0);
    case EdgeEdgeType::EA0_EB1: return point_point_sq(ea0, eb1);
    case EdgeEdgeType::EA1_EB0: return point_point_sq(ea1, eb0);
    case EdgeEdgeType::EA1_EB1: return point_point_sq(ea1, eb1);
    case EdgeEdgeType::EA_EB0: return point_line_sq(eb0, ea0, ea1);
    case EdgeEdgeType::EA_EB1: return point_line_sq(eb1, ea0, ea1);
    case EdgeEdgeType::EA0_EB: return point_line_sq(ea0, eb0, eb1);
    case EdgeEdgeType::EA1_EB: return point_line_sq(ea1, eb0, eb1);
    case EdgeEdgeType::EA_EB: return line_line_sq(ea0, ea1, eb0, eb1);
  }
  return T(0.0);
}

// --- Classification helpers

// Where the closest point of segment [e0, e1] to p lies: 0 = e0, 1 = e1, 2 = interior.
// A zero-length segment is its end point e0.
int point_segment_region(const Vector3d& p, const Vector3d& e0, const Vector3d& e1) {
  const Vector3d e = e1 - e0;
  const double len_sq = e.squaredNorm();
  if (len_sq <= 0.0) return 0;
  const double t = (p - e0).dot(e);
  if (t <= 0.0) return 0;
  if (t >= len_sq) return 1;
  return 2;
}

double point_segment_distance_sq(const Vector3d& p, const Vector3d& e0, const Vector3d& e1) {
  const Vector3d e = e1 - e0;
  const double len_sq = e.squaredNorm();
  const double t = len_sq > 0.0 ? std::clamp((p - e0).dot(e) / len_sq, 0.0, 1.0) : 0.0;
  return (p - (e0 + t * e)).squaredNorm();
}

// The point-triangle type of p against the edge `edge` (0, 1, 2) with the segment region `region`.
PointTriangleType edge_region_type(int edge, int region) {
  static constexpr PointTriangleType vertex[3] = {PointTriangleType::P_T0, PointTriangleType::P_T1,
                                                  PointTriangleType::P_T2};
  static constexpr PointTriangleType interior[3] = {PointTriangleType::P_E0, PointTriangleType::P_E1,
                                                    PointTriangleType::P_E2};
  if (region == 2) return interior[edge];
  return vertex[(edge + region) % 3];  // edge k runs from vertex k to vertex k+1
}

// The nearest edge feature of p (for degenerate triangles, where the face region is meaningless).
PointTriangleType nearest_edge_type(const Vector3d& p, const Vector3d* t) {
  int best = 0;
  double best_d = point_segment_distance_sq(p, t[0], t[1]);
  for (int k = 1; k < 3; ++k) {
    const double d = point_segment_distance_sq(p, t[k], t[(k + 1) % 3]);
    if (d < best_d) best_d = d, best = k;
  }
  return edge_region_type(best, point_segment_region(p, t[best], t[(best + 1) % 3]));
}

// Closest points of two segments: parameters s on [ea0, ea1] and t on [eb0, eb1], each clamped to
// [0, 1] (Ericson 2005, section 5.1.9). Nearly parallel edges take s = 0 (an end point of ea), as the
// line-line system is singular there.
void segment_segment_parameters(const Vector3d& ea0, const Vector3d& ea1, const Vector3d& eb0, const Vector3d& eb1,
                                double* s_out, double* t_out) {
  const Vector3d d1 = ea1 - ea0, d2 = eb1 - eb0, r = ea0 - eb0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0.0, t = 0.0;
  if (a <= 0.0 && e <= 0.0) {
    s = t = 0.0;
  } else if (a <= 0.0) {
    s = 0.0;
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 0.0) {
      t = 0.0;
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2);
      const double cross_sq = d1.cross(d2).squaredNorm();  // = a e - b², computed without cancellation
      s = cross_sq > 1e-20 * a * e ? std::clamp((b * f - c * e) / cross_sq, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  *s_out = s;
  *t_out = t;
}

template <typename Piece>
Derivatives12 jet_derivatives(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d,
                              Piece piece) {
  const Jet<12> r = piece(jet_point<12>(a, 0), jet_point<12>(b, 1), jet_point<12>(c, 2), jet_point<12>(d, 3));
  Derivatives12 out;
  out.value = r.v;
  out.gradient = r.g;
  out.hessian = r.h;
  return out;
}

}  // namespace

PointTriangleType point_triangle_type(const Vector3d& p, const Vector3d& t0, const Vector3d& t1,
                                      const Vector3d& t2) {
  // Ericson (2005), section 5.1.5: the signs of dot products against the edges locate p's Voronoi region.
  const Vector3d ab = t1 - t0, ac = t2 - t0, ap = p - t0;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  PointTriangleType type = PointTriangleType::P_T;
  const Vector3d bp = p - t1;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  const Vector3d cp = p - t2;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
  if (d1 <= 0.0 && d2 <= 0.0) {
    type = PointTriangleType::P_T0;
  } else if (d3 >= 0.0 && d4 <= d3) {
    type = PointTriangleType::P_T1;
  } else if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    type = PointTriangleType::P_E0;
  } else if (d6 >= 0.0 && d5 <= d6) {
    type = PointTriangleType::P_T2;
  } else if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    type = PointTriangleType::P_E2;
  } else if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    type = PointTriangleType::P_E1;
  }
  const Vector3d t[3] = {t0, t1, t2};
  if (type == PointTriangleType::P_T) {
    // va + vb + vc = |ab × ac|²: a (nearly) degenerate triangle has no interior to be closest to.
    if (ab.cross(ac).squaredNorm() <= 1e-20 * ab.squaredNorm() * ac.squaredNorm()) return nearest_edge_type(p, t);
    return type;
  }
  // A region test can pick a zero-length edge; its closest feature is then its end point.
  const int edge = type == PointTriangleType::P_E0 ? 0 : type == PointTriangleType::P_E1 ? 1 : type == PointTriangleType::P_E2 ? 2 : -1;
  if (edge >= 0 && (t[(edge + 1) % 3] - t[edge]).squaredNorm() <= 0.0) return nearest_edge_type(p, t);
  return type;
}

EdgeEdgeType edge_edge_type(const Vector3d& ea0, const Vector3d& ea1, const Vector3d& eb0, const Vector3d& eb1) {
  double s, t;
  segment_segment_parameters(ea0, ea1, eb0, eb1, &s, &t);
  const int a = s <= 0.0 ? 0 : s >= 1.0 ? 1 : 2;  // 0: ea0, 1: ea1, 2: interior of ea
  const int b = t <= 0.0 ? 0 : t >= 1.0 ? 1 : 2;
  static constexpr EdgeEdgeType table[3][3] = {
      {EdgeEdgeType::EA0_EB0, EdgeEdgeType::EA0_EB1, EdgeEdgeType::EA0_EB},
      {EdgeEdgeType::EA1_EB0, EdgeEdgeType::EA1_EB1, EdgeEdgeType::EA1_EB},
      {EdgeEdgeType::EA_EB0, EdgeEdgeType::EA_EB1, EdgeEdgeType::EA_EB},
  };
  return table[a][b];
}

double point_triangle_distance_sq(const Vector3d& p, const Vector3d& t0, const Vector3d& t1, const Vector3d& t2) {
  return point_triangle_distance_sq(p, t0, t1, t2, point_triangle_type(p, t0, t1, t2));
}

double point_triangle_distance_sq(const Vector3d& p, const Vector3d& t0, const Vector3d& t1, const Vector3d& t2,
                                  PointTriangleType type) {
  return point_triangle_piece(plain_point(p), plain_point(t0), plain_point(t1), plain_point(t2), type);
}

double edge_edge_distance_sq(const Vector3d& ea0, const Vector3d& ea1, const Vector3d& eb0, const Vector3d& eb1) {
  // The closest points themselves: robust for every configuration, including parallel edges.
  double s, t;
  segment_segment_parameters(ea0, ea1, eb0, eb1, &s, &t);
  return ((ea0 + s * (ea1 - ea0)) - (eb0 + t * (eb1 - eb0))).squaredNorm();
}

double edge_edge_distance_sq(const Vector3d& ea0, const Vector3d& ea1, const Vector3d& eb0, const Vector3d& eb1,
                             EdgeEdgeType type) {
  return edge_edge_piece(plain_point(ea0), plain_point(ea1), plain_point(eb0), plain_point(eb1), type);
}

Derivatives12 point_triangle_distance_sq_derivatives(const Vector3d& p, const Vector3d& t0, const Vector3d& t1,
                                                     const Vector3d& t2, PointTriangleType type) {
  return jet_derivatives(p, t0, t1, t2, [type](const auto& a, const auto& b, const auto& c, const auto& d) {
    return point_triangle_piece(a, b, c, d, type);
  });
}

Derivatives12 edge_edge_distance_sq_derivatives(const Vector3d& ea0, const Vector3d& ea1, const Vector3d& eb0,
                                                const Vector3d& eb1, EdgeEdgeType type) {
  return jet_derivatives(ea0, ea1, eb0, eb1, [type](const auto& a, const auto& b, const auto& c, const auto& d) {
    return edge_edge_piece(a, b, c, d, type);
  });
}

}  // namespace amt::refit
