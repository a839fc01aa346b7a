#pragma once
// Second-order forward-mode differentiation: a value with its exact gradient and Hessian with respect
// to N inputs. The distance kernels (distance.cpp, barrier.cpp) evaluate their closed-form formulas on
// Jet<12> to get gradients and Hessians without hand-expanded code; the result is exact up to rounding,
// and the tests compare it against finite differences.
//
// Internal to refit/: include it from .cpp files only (it instantiates 12x12 Eigen products).
#include <Eigen/Core>
#include <cmath>

namespace amt::refit {

/// f, ∇f (N) and ∇²f (N, N) at one point.
template <int N>
struct Jet {
  using Gradient = Eigen::Matrix<double, N, 1>;
  using Hessian = Eigen::Matrix<double, N, N>;
  double v = 0.0;
  Gradient g = Gradient::Zero();
  Hessian h = Hessian::Zero();

  Jet() = default;
  explicit Jet(double value) : v(value) {}

  /// The input x_index with value `value`: gradient e_index, zero Hessian.
  static Jet variable(double value, int index) {
    Jet j(value);
    j.g[index] = 1.0;
    return j;
  }
};

template <int N>
Jet<N> operator+(const Jet<N>& a, const Jet<N>& b) {
  Jet<N> r;
  r.v = a.v + b.v;
  r.g = a.g + b.g;
  r.h = a.h + b.h;
  return r;
}

template <int N>
Jet<N> operator-(const Jet<N>& a, const Jet<N>& b) {
  Jet<N> r;
  r.v = a.v - b.v;
  r.g = a.g - b.g;
  r.h = a.h - b.h;
  return r;
}

template <int N>
Jet<N> operator-(const Jet<N>& a) {
  Jet<N> r;
  r.v = -a.v;
  r.g = -a.g;
  r.h = -a.h;
  return r;
}

/// (ab)'' = a''b + ab'' + a'b'ᵀ + b'a'ᵀ.
template <int N>
Jet<N> operator*(const Jet<N>& a, const Jet<N>& b) {
  Jet<N> r;
  r.v = a.v * b.v;
  r.g = a.g * b.v + b.g * a.v;
  r.h = a.h * b.v + b.h * a.v + a.g * b.g.transpose() + b.g * a.g.transpose();
  return r;
}

template <int N>
Jet<N> operator*(double s, const Jet<N>& a) {
  Jet<N> r;
  r.v = s * a.v;
  r.g = s * a.g;
  r.h = s * a.h;
  return r;
}

/// f(a) for a scalar function with f(a.v) = f0, f'(a.v) = f1, f''(a.v) = f2 (chain rule).
template <int N>
Jet<N> chain(const Jet<N>& a, double f0, double f1, double f2) {
  Jet<N> r;
  r.v = f0;
  r.g = f1 * a.g;
  r.h = f1 * a.h + f2 * a.g * a.g.transpose();
  return r;
}

/// 1 / a, with (1/a)' = -1/a², (1/a)'' = 2/a³.
template <int N>
Jet<N> reciprocal(const Jet<N>& a) {
  const double inv = 1.0 / a.v;
  return chain(a, inv, -inv * inv, 2.0 * inv * inv * inv);
}

template <int N>
Jet<N> operator/(const Jet<N>& a, const Jet<N>& b) {
  return a * reciprocal(b);
}

// Scalar overloads so that one template formula serves double and Jet.
inline double reciprocal(double a) { return 1.0 / a; }

/// A 3-vector of doubles or jets, with the few operations the distance formulas use.
template <typename T>
struct Vec3 {
  T x, y, z;
};

template <typename T>
Vec3<T> operator-(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}

template <typename T>
T dot(const Vec3<T>& a, const Vec3<T>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

template <typename T>
Vec3<T> cross(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

template <typename T>
Vec3<T> operator+(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}

/// s a for a scalar s of the vector's own type (double or Jet).
template <typename T>
Vec3<T> times(const T& s, const Vec3<T>& a) {
  return {s * a.x, s * a.y, s * a.z};
}

/// c a for a constant c.
template <int N>
Vec3<Jet<N>> scale(double c, const Vec3<Jet<N>>& a) {
  return {c * a.x, c * a.y, c * a.z};
}
inline Vec3<double> scale(double c, const Vec3<double>& a) { return {c * a.x, c * a.y, c * a.z}; }

/// a^p, with (a^p)' = p a^(p-1) and (a^p)'' = p (p-1) a^(p-2); a > 0.
inline double power(double a, double p) { return std::pow(a, p); }
template <int N>
Jet<N> power(const Jet<N>& a, double p) {
  return chain(a, std::pow(a.v, p), p * std::pow(a.v, p - 1), p * (p - 1) * std::pow(a.v, p - 2));
}

/// The 3 coordinates of `p` as the inputs [3 slot, 3 slot + 3) of a Jet<N>.
template <int N>
Vec3<Jet<N>> jet_point(const Eigen::Vector3d& p, int slot) {
  return {Jet<N>::variable(p.x(), 3 * slot), Jet<N>::variable(p.y(), 3 * slot + 1),
          Jet<N>::variable(p.z(), 3 * slot + 2)};
}

inline Vec3<double> plain_point(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }

}  // namespace amt::refit
