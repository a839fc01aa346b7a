#include "refit/ccd.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "refit/distance.h"

namespace amt::refit {
namespace {

using Eigen::Vector3d;

// The pair's kind: which distance, and which bound on how fast it can shrink (line 4 of Algorithm 1).
enum class Pair { kPointTriangle, kEdgeEdge };

double distance_sq(Pair pair, const Vector3d* y) {
  return pair == Pair::kPointTriangle ? point_triangle_distance_sq(y[0], y[1], y[2], y[3])
                                      : edge_edge_distance_sq(y[0], y[1], y[2], y[3]);
}

// Algorithm 1 of Li, Kaufman and Jiang (2021) on four points x0[i] moving by d0[i], with the true
// (unclassified) squared distance of the pair.
bool additive_ccd(Pair pair, const std::array<Vector3d, 4>& x0, const std::array<Vector3d, 4>& d0, double t_max,
                  double* toi, const CcdOptions& options) {
  std::array<Vector3d, 4> x = x0, d = d0;
  // Lines 2-3: only relative motion changes a distance; remove the mean displacement.
  const Vector3d mean = 0.25 * (d[0] + d[1] + d[2] + d[3]);
  for (Vector3d& di : d) di -= mean;
  // Line 4, l_p: the closest point of a triangle (an edge) is a convex combination of its corners, so it
  // moves no faster than the fastest corner.
  const double speed_bound = pair == Pair::kPointTriangle
                                 ? d[0].norm() + std::max({d[1].norm(), d[2].norm(), d[3].norm()})
                                 : std::max(d[0].norm(), d[1].norm()) + std::max(d[2].norm(), d[3].norm());
  const double xi = options.thickness;
  const double s = options.gap_fraction;
  // (d² - ξ²) / (d + ξ) = d - ξ, the gap, written as in the paper to work from squared distances.
  auto gap_of = [xi](double dist_sq) { return (dist_sq - xi * xi) / (std::sqrt(dist_sq) + xi); };

  double dist_sq = distance_sq(pair, x.data());
  if (dist_sq <= xi * xi) {
    *toi = 0.0;
    return true;
  }
  if (speed_bound <= 0.0) return false;  // no relative motion: the distance stays what it is
  const double g = s * gap_of(dist_sq);  // line 7
  double t = 0.0;
  double t_l = (1.0 - s) * gap_of(dist_sq) / speed_bound;  // line 9
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    for (int i = 0; i < 4; ++i) x[i] += t_l * d[i];  // line 11
    dist_sq = distance_sq(pair, x.data());
    if (t > 0.0 && (dist_sq <= xi * xi || gap_of(dist_sq) < g)) {  // line 13
      *toi = t;
      return true;
    }
    t += t_l;  // line 14
    if (t > t_max) return false;
    t_l = 0.9 * gap_of(dist_sq) / speed_bound;  // line 16
  }
  *toi = t;  // still safe: every step so far was shorter than the gap allowed
  return true;
}

}  // namespace

bool point_triangle_ccd(const Vector3d& p, const Vector3d& t0, const Vector3d& t1, const Vector3d& t2,
                        const Vector3d& dp, const Vector3d& dt0, const Vector3d& dt1, const Vector3d& dt2,
                        double t_max, double* toi, const CcdOptions& options) {
  return additive_ccd(Pair::kPointTriangle, {p, t0, t1, t2}, {dp, dt0, dt1, dt2}, t_max, toi, options);
}

bool edge_edge_ccd(const Vector3d& ea0, const Vector3d& ea1, const Vector3d& eb0, const Vector3d& eb1,
                   const Vector3d& dea0, const Vector3d& dea1, const Vector3d& deb0, const Vector3d& deb1,
                   double t_max, double* toi, const CcdOptions& options) {
  return additive_ccd(Pair::kEdgeEdge, {ea0, ea1, eb0, eb1}, {dea0, dea1, deb0, deb1}, t_max, toi, options);
}

}  // namespace amt::refit
