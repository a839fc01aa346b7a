#include "refit/curve_shape.h"

#include <map>

#include "data_tools/geometry/error.h"
#include "refit/assembly.h"
#include "refit/jet.h"

namespace amt::refit {
namespace {

template <typename T>
Vec3<T> unit(const Vec3<T>& a) {
  return times(power(dot(a, a), -0.5), a);
}

// P(v, u) = v - (u·v) u: v projected onto the plane of unit normal u.
template <typename T>
Vec3<T> project(const Vec3<T>& v, const Vec3<T>& u) {
  return v - times(dot(u, v), u);
}

// (α, β, γ) at v_i from the four loop vertices v_(i-1), v_i, v_(i+1), v_(i+2) (section 3.4.5).
template <typename T>
std::array<T, 3> curve_invariants(const Vec3<T>& p0, const Vec3<T>& p1, const Vec3<T>& p2, const Vec3<T>& p3) {
  const Vec3<T> e_prev = unit(p1 - p0), e = unit(p2 - p1), e_next = unit(p3 - p2);
  const Vec3<T> a = project(e_next, e), b = project(scale(-1.0, e_prev), e);
  return {-dot(e_prev, e), dot(a, b), dot(cross(a, b), e)};
}

}  // namespace

std::vector<std::vector<int>> boundary_loops(const MatrixX3i& F) {
  std::map<std::pair<int, int>, int> sides;  // directed side -> count
  for (int f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) ++sides[{F(f, k), F(f, (k + 1) % 3)}];
  std::map<int, int> next;  // boundary side a -> b, keyed by a
  for (const auto& [side, count] : sides)
    if (!sides.count({side.second, side.first}))
      AMT_CHECK(next.emplace(side.first, side.second).second, "garment: vertex ", side.first,
                " starts two boundary edges (two boundary loops touch there); the boundary must be simple loops");
  std::vector<std::vector<int>> loops;
  while (!next.empty()) {
    std::vector<int> loop;
    int v = next.begin()->first;
    while (true) {
      const auto it = next.find(v);
      if (it == next.end()) break;
      loop.push_back(v);
      v = it->second;
      next.erase(it);
    }
    AMT_CHECK(v == loop.front(), "garment: the boundary through vertex ", loop.front(), " does not close");
    loops.push_back(std::move(loop));
  }
  return loops;
}

CurveShapeTerm::CurveShapeTerm(const Positions& source, const MatrixX3i& F, double weight) {
  for (const std::vector<int>& loop : boundary_loops(F)) {
    const int m = static_cast<int>(loop.size());
    if (m < 3) continue;
    ++loops_;
    for (int i = 0; i < m; ++i) {
      const std::array<int, 4> v = {loop[(i + m - 1) % m], loop[i], loop[(i + 1) % m], loop[(i + 2) % m]};
      const std::array<double, 3> s =
          curve_invariants(plain_point(source.row(v[0]).transpose()), plain_point(source.row(v[1]).transpose()),
                           plain_point(source.row(v[2]).transpose()), plain_point(source.row(v[3]).transpose()));
      const double w = 0.5 * ((source.row(v[1]) - source.row(v[0])).norm() + (source.row(v[2]) - source.row(v[1])).norm());
      stencils_.push_back({v, s, weight * w});
    }
  }
}

double CurveShapeTerm::value(const Positions& x) const {
  double e = 0.0;
  for (const Stencil& s : stencils_) {
    const std::array<double, 3> c =
        curve_invariants(plain_point(x.row(s.v[0]).transpose()), plain_point(x.row(s.v[1]).transpose()),
                         plain_point(x.row(s.v[2]).transpose()), plain_point(x.row(s.v[3]).transpose()));
    for (int k = 0; k < 3; ++k) e += s.weight * (s.source[k] - c[k]) * (s.source[k] - c[k]);
  }
  return e;
}

double CurveShapeTerm::derivatives(const Positions& x, Eigen::VectorXd* gradient,
                                   std::vector<Eigen::Triplet<double>>* hessian) const {
  double e = 0.0;
  for (const Stencil& s : stencils_) {
    const std::array<Jet<12>, 3> c =
        curve_invariants(jet_point<12>(x.row(s.v[0]).transpose(), 0), jet_point<12>(x.row(s.v[1]).transpose(), 1),
                         jet_point<12>(x.row(s.v[2]).transpose(), 2), jet_point<12>(x.row(s.v[3]).transpose(), 3));
    Jet<12> l;
    for (int k = 0; k < 3; ++k) {
      const Jet<12> r = Jet<12>(s.source[k]) - c[k];
      l = l + r * r;
    }
    e += s.weight * l.v;
    add_element(s.v.data(), 4, s.weight * l.g, s.weight * l.h, true, gradient, hessian);
  }
  return e;
}

}  // namespace amt::refit
