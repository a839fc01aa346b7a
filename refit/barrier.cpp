#include "refit/barrier.h"

#include <Eigen/Geometry>
#include <cmath>
#include <limits>

#include "refit/jet.h"

namespace amt::refit {

ScalarDerivatives barrier(double s, double s_hat) {
  ScalarDerivatives b;
  if (s >= s_hat) return b;
  if (s <= 0.0) {
    b.value = std::numeric_limits<double>::infinity();
    return b;
  }
  // IPC (Li et al. 2020) eq. 6 with d -> d², differentiated by hand (the tests check them).
  const double r = s - s_hat;
  const double log_ratio = std::log(s / s_hat);
  b.value = -r * r * log_ratio;
  b.first = -2.0 * r * log_ratio - r * r / s;
  b.second = -2.0 * log_ratio - 4.0 * r / s + r * r / (s * s);
  return b;
}

double edge_edge_mollifier_threshold(double ea_rest_length_sq, double eb_rest_length_sq) {
  return 1e-3 * ea_rest_length_sq * eb_rest_length_sq;  // IPC section 4.3
}

Mollifier edge_edge_mollifier(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
                              const Eigen::Vector3d& eb1, double eps_x) {
  Mollifier m;
  const double c_plain = (ea1 - ea0).cross(eb1 - eb0).squaredNorm();
  if (c_plain >= eps_x) return m;
  const Vec3<Jet<12>> a0 = jet_point<12>(ea0, 0), a1 = jet_point<12>(ea1, 1), b0 = jet_point<12>(eb0, 2),
                      b1 = jet_point<12>(eb1, 3);
  const Vec3<Jet<12>> n = cross(a1 - a0, b1 - b0);
  const Jet<12> c = dot(n, n);
  // m(c) = -c²/ε² + 2c/ε = (c/ε)(2 - c/ε); m' = 2(1 - c/ε)/ε; m'' = -2/ε².
  const double q = c.v / eps_x;
  const Jet<12> r = chain(c, q * (2.0 - q), 2.0 * (1.0 - q) / eps_x, -2.0 / (eps_x * eps_x));
  m.value = r.v;
  m.gradient = r.g;
  m.hessian = r.h;
  m.active = true;
  return m;
}

}  // namespace amt::refit
