#pragma once
// Small meshes for the refit tests.
#include <cmath>

#include "data_tools/geometry/types.h"
#include "refit/contact.h"

namespace amt::refit::test {

/// An open tube (a sleeve, an arm) of `rings` rings of `around` vertices around the x axis, from x0 to
/// x1, radius r. `wobble` moves the vertices along x by wobble sin(3φ) (non-planar rims, for torsion);
/// `staggered` turns every other ring by half a step.
inline void tube(int rings, int around, double x0, double x1, double r, Positions* V, MatrixX3i* F,
                 double wobble = 0.0, bool staggered = false) {
  V->resize(rings * around, 3);
  for (int i = 0; i < rings; ++i)
    for (int k = 0; k < around; ++k) {
      const double phi = 2 * M_PI * (k + (staggered ? 0.5 * (i % 2) : 0.0)) / around;
      V->row(i * around + k) << x0 + (x1 - x0) * i / (rings - 1) + wobble * std::sin(3 * phi), r * std::cos(phi),
          r * std::sin(phi);
    }
  F->resize(2 * (rings - 1) * around, 3);
  int f = 0;
  for (int i = 0; i + 1 < rings; ++i)
    for (int k = 0; k < around; ++k) {
      const int a = i * around + k, b = i * around + (k + 1) % around, c = a + around, d = b + around;
      F->row(f++) << a, b, d;
      F->row(f++) << a, d, c;
    }
}

/// A closed UV sphere of radius r about `center`: `rings` - 1 rings of `around` vertices between two
/// poles, outward-facing (counter-clockwise seen from outside).
inline void sphere(int rings, int around, double r, const Eigen::RowVector3d& center, Positions* V, MatrixX3i* F) {
  const int n = (rings - 1) * around + 2, north = n - 2, south = n - 1;
  V->resize(n, 3);
  for (int i = 1; i < rings; ++i)
    for (int k = 0; k < around; ++k) {
      const double theta = M_PI * i / rings, phi = 2 * M_PI * k / around;
      V->row((i - 1) * around + k) =
          center + r * Eigen::RowVector3d(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
    }
  V->row(north) = center + Eigen::RowVector3d(0, r, 0);
  V->row(south) = center - Eigen::RowVector3d(0, r, 0);
  F->resize(2 * (rings - 1) * around, 3);
  int f = 0;
  for (int k = 0; k < around; ++k) {
    const int k1 = (k + 1) % around;
    F->row(f++) << north, k1, k;
    F->row(f++) << south, (rings - 2) * around + k, (rings - 2) * around + k1;
  }
  for (int i = 0; i + 2 < rings; ++i)
    for (int k = 0; k < around; ++k) {
      const int a = i * around + k, b = i * around + (k + 1) % around, c = a + around, d = b + around;
      F->row(f++) << a, b, d;
      F->row(f++) << a, d, c;
    }
}

}  // namespace amt::refit::test
