#pragma once
// Squared distances between the primitives of triangle meshes, for the IPC barrier (Li et al. 2020,
// "Incremental Potential Contact", section 4 and supplement): point-triangle and edge-edge, each split
// by its closest features (vertex, edge interior, face interior) so that the distance is a smooth
// closed-form function of the vertex positions on each piece, with its gradient and Hessian.
//
// Every distance here is squared (metres²), as in IPC's implementation: the barrier is a function of
// d² with threshold d̂², which avoids the square root and keeps the derivatives polynomial-rational.
#include <Eigen/Core>

namespace amt::refit {

using Vector12d = Eigen::Matrix<double, 12, 1>;
using Matrix12d = Eigen::Matrix<double, 12, 12>;

// === Closest-feature classification

/// Which features of triangle (t0, t1, t2) are closest to point p. Edges are E0 = t0t1, E1 = t1t2,
/// E2 = t2t0 (the IPC Toolkit's numbering).
enum class PointTriangleType { P_T0, P_T1, P_T2, P_E0, P_E1, P_E2, P_T };

/// Which features of edges (ea0, ea1) and (eb0, eb1) are closest: an end point (EA0, ...) or the
/// interior of the edge (EA, EB). EA_EB is the line-line case.
enum class EdgeEdgeType { EA0_EB0, EA0_EB1, EA1_EB0, EA1_EB1, EA_EB0, EA_EB1, EA0_EB, EA1_EB, EA_EB };

/// The closest-feature (Voronoi) region of p with respect to the triangle, by the region tests of
/// Ericson, "Real-Time Collision Detection" (2005), section 5.1.5 (ClosestPtPointTriangle). A degenerate
/// triangle (zero area) never gives P_T: its closest feature is then the nearest edge or vertex.
PointTriangleType point_triangle_type(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                      const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);

/// The closest features of two segments, from the clamped closest-point parameters of Ericson (2005),
/// section 5.1.9 (ClosestPtSegmentSegment). Nearly parallel edges (|ea × eb|² below 1e-20 |ea|² |eb|²)
/// never give EA_EB, whose line-line formula is singular there; they give an end point against an edge.
EdgeEdgeType edge_edge_type(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
                            const Eigen::Vector3d& eb1);

// === Squared distances

/// Squared distance from p to the triangle (as a closed set).
double point_triangle_distance_sq(const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1,
                                  const Eigen::Vector3d& t2);

/// The squared distance of the closest-feature piece `type`: point-point |p - q|², point-line
/// |(e0 - p) × (e1 - p)|² / |e1 - e0|², point-plane ((p - t0)·n)² / |n|² with n = (t1 - t0) × (t2 - t0)
/// (IPC supplement, section 2). Equal to point_triangle_distance_sq when `type` is the classified one.
double point_triangle_distance_sq(const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1,
                                  const Eigen::Vector3d& t2, PointTriangleType type);

/// Squared distance between the two segments.
double edge_edge_distance_sq(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
                             const Eigen::Vector3d& eb1);

/// The squared distance of the piece `type`: point-point, point-line, or line-line
/// ((eb0 - ea0)·n)² / |n|² with n = (ea1 - ea0) × (eb1 - eb0) (IPC supplement, section 2).
double edge_edge_distance_sq(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
                             const Eigen::Vector3d& eb1, EdgeEdgeType type);

// === Derivatives

/// A scalar function of 12 coordinates with its gradient (12) and Hessian (12, 12).
struct Derivatives12 {
  double value = 0.0;
  Vector12d gradient = Vector12d::Zero();
  Matrix12d hessian = Matrix12d::Zero();
};

/// The piece `type` of the point-triangle squared distance and its exact derivatives with respect to
/// x = [p, t0, t1, t2] (12 coordinates, 3 per point).
Derivatives12 point_triangle_distance_sq_derivatives(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                                     const Eigen::Vector3d& t1, const Eigen::Vector3d& t2,
                                                     PointTriangleType type);

/// The piece `type` of the edge-edge squared distance and its exact derivatives with respect to
/// x = [ea0, ea1, eb0, eb1].
Derivatives12 edge_edge_distance_sq_derivatives(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                                const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1,
                                                EdgeEdgeType type);

}  // namespace amt::refit
