#pragma once
// Continuous collision detection for linearly moving primitives: additive CCD (ACCD) of Li, Kaufman and
// Jiang 2021, "Codimensional Incremental Potential Contact", section 5 and Algorithm 1. It is
// conservative by construction: it steps forward by a fraction of the current gap divided by an upper
// bound on how fast the gap can shrink, so it never steps past a contact, and it reports a time at which
// the primitives are still at least s times their initial gap apart.
#include <Eigen/Core>

namespace amt::refit {

/// Parameters of additive CCD.
struct CcdOptions {
  /// s of Algorithm 1: the reported time keeps at least this fraction of the initial gap (IPC's
  /// line search uses 0.1, i.e. a conservative rescaling of 0.9).
  double gap_fraction = 0.1;
  /// ξ of Algorithm 1: a thickness subtracted from the distance (0: the surfaces themselves).
  double thickness = 0.0;
  /// A cap on the iterations (grazing motion that stays just above s times the gap can need many);
  /// on reaching it the current time, which is still safe, is reported as a collision.
  int max_iterations = 1000000;
};

/// The primitives move from x to x + t·dx for t in [0, t_max]. Returns true and sets *toi to a time in
/// [0, t_max) at which the primitives are still apart (by at least gap_fraction times the initial gap)
/// and before which they never touch, when the motion may bring them within that fraction of the
/// initial gap before t_max; returns false when they stay apart on the whole interval. Primitives that
/// start touching (distance ≤ thickness) give true with *toi = 0.
bool point_triangle_ccd(const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1,
                        const Eigen::Vector3d& t2, const Eigen::Vector3d& dp, const Eigen::Vector3d& dt0,
                        const Eigen::Vector3d& dt1, const Eigen::Vector3d& dt2, double t_max, double* toi,
                        const CcdOptions& options = {});

/// Additive CCD of two edges (ea0, ea1) and (eb0, eb1) moving by (dea0, dea1, deb0, deb1); as above.
bool edge_edge_ccd(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
                   const Eigen::Vector3d& eb1, const Eigen::Vector3d& dea0, const Eigen::Vector3d& dea1,
                   const Eigen::Vector3d& deb0, const Eigen::Vector3d& deb1, double t_max, double* toi,
                   const CcdOptions& options = {});

}  // namespace amt::refit
