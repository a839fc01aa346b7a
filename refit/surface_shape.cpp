#include "refit/surface_shape.h"

#include <Eigen/Dense>
#include <cmath>
#include <map>

#include "data_tools/geometry/error.h"
#include "refit/assembly.h"
#include "refit/jet.h"

namespace amt::refit {
namespace {

using Eigen::Vector3d;

// τx = c1 e1 + c2 e2 + c3 n of triangle (p0, p1, p2), n = (e1 × e2) / |e1 × e2|^½ (see the header).
template <typename T>
Vec3<T> deformed(const Vec3<T>& p0, const Vec3<T>& p1, const Vec3<T>& p2, const Vector3d& c) {
  const Vec3<T> e1 = p1 - p0, e2 = p2 - p0;
  const Vec3<T> n = cross(e1, e2);
  const Vec3<T> n_scaled = times(power(dot(n, n), -0.25), n);
  return scale(c[0], e1) + scale(c[1], e2) + scale(c[2], n_scaled);
}

// |τ1 x - τ2 x|² for t1 = (v1, v2, v3), t2 = (v2, v1, v4) (section 3.4.2).
template <typename T>
T pair_energy(const Vec3<T>& v1, const Vec3<T>& v2, const Vec3<T>& v3, const Vec3<T>& v4, const Vector3d& c1,
              const Vector3d& c2) {
  const Vec3<T> d = deformed(v1, v2, v3, c1) - deformed(v2, v1, v4, c2);
  return dot(d, d);
}

// The source frame [e1, e2, n] of triangle (p0, p1, p2) as columns.
Eigen::Matrix3d frame(const Vector3d& p0, const Vector3d& p1, const Vector3d& p2) {
  const Vector3d e1 = p1 - p0, e2 = p2 - p0, n = e1.cross(e2);
  Eigen::Matrix3d M;
  M << e1, e2, n / std::pow(n.squaredNorm(), 0.25);
  return M;
}

}  // namespace

SurfaceShapeTerm::SurfaceShapeTerm(const Positions& source, const MatrixX3i& F, double weight) {
  // Each directed side a -> b of a face, with the corner opposite it.
  std::map<std::pair<int, int>, std::pair<int, int>> side;  // (a, b) -> (face, opposite corner)
  for (int f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k), b = F(f, (k + 1) % 3), c = F(f, (k + 2) % 3);
      AMT_CHECK(a >= 0 && a < source.rows() && b >= 0 && b < source.rows() && c >= 0 && c < source.rows(),
                "garment: face ", f, " has a vertex index outside [0, ", source.rows(), ")");
      AMT_CHECK(side.emplace(std::make_pair(a, b), std::make_pair(f, c)).second, "garment: the edge (", a, ", ", b,
                ") is used twice in the same direction (faces of opposite orientation or a non-manifold edge); the "
                "garment must be an oriented manifold");
    }
  for (const auto& [ab, fc] : side) {
    const auto [a, b] = ab;
    if (a > b) continue;  // each interior edge once, from its side a -> b with a < b
    const auto other = side.find({b, a});
    if (other == side.end()) continue;  // a boundary edge
    const int v3 = fc.second, v4 = other->second.second;
    const Vector3d s1 = source.row(a), s2 = source.row(b), s3 = source.row(v3), s4 = source.row(v4);
    const Vector3d x = (s4 - s3).normalized();
    const Eigen::Matrix3d F1 = frame(s1, s2, s3), F2 = frame(s2, s1, s4);
    const double area = 0.5 * ((s2 - s1).cross(s3 - s1).norm() + (s1 - s2).cross(s4 - s2).norm());
    AMT_CHECK(std::abs(F1.determinant()) > 0 && std::abs(F2.determinant()) > 0 && std::isfinite(x.squaredNorm()),
              "garment: a degenerate triangle next to the edge (", a, ", ", b, ") (faces ", fc.first, " and ",
              other->second.first, ")");
    pairs_.push_back({{a, b, v3, v4}, F1.inverse() * x, F2.inverse() * x, weight * area});
  }
}

std::vector<double> SurfaceShapeTerm::pair_distortion(const Positions& x) const {
  std::vector<double> out;
  out.reserve(pairs_.size());
  for (const Pair& p : pairs_)
    out.push_back(pair_energy(plain_point(x.row(p.v[0]).transpose()), plain_point(x.row(p.v[1]).transpose()),
                              plain_point(x.row(p.v[2]).transpose()), plain_point(x.row(p.v[3]).transpose()), p.c1,
                              p.c2));
  return out;
}

double SurfaceShapeTerm::value(const Positions& x) const {
  const std::vector<double> l = pair_distortion(x);
  double e = 0.0;
  for (size_t i = 0; i < pairs_.size(); ++i) e += pairs_[i].weight * l[i];
  return e;
}

double SurfaceShapeTerm::derivatives(const Positions& x, Eigen::VectorXd* gradient,
                                     std::vector<Eigen::Triplet<double>>* hessian) const {
  double e = 0.0;
  for (const Pair& p : pairs_) {
    const Jet<12> l = pair_energy(jet_point<12>(x.row(p.v[0]).transpose(), 0), jet_point<12>(x.row(p.v[1]).transpose(), 1),
                                  jet_point<12>(x.row(p.v[2]).transpose(), 2), jet_point<12>(x.row(p.v[3]).transpose(), 3),
                                  p.c1, p.c2);
    e += p.weight * l.v;
    add_element(p.v.data(), 4, p.weight * l.g, p.weight * l.h, true, gradient, hessian);
  }
  return e;
}

}  // namespace amt::refit
