#pragma once
// Contact between the triangles of a scene made of free surfaces (the garment) and obstacles (the
// avatar): candidate primitive pairs from the broad phase, the IPC barrier potential over them with its
// PSD-projected Hessian (Li et al. 2020, eq. 8 and section 4), and the largest collision-free fraction of
// a step by continuous collision detection (ccd.h).
//
// Pairs are the non-incident point-triangle pairs and the edge-edge pairs that share no vertex; pairs
// between two obstacle primitives are left out (the paper, section 3.4.1: the avatar may intersect
// itself).
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <cstdint>
#include <vector>

#include "data_tools/geometry/types.h"
#include "refit/ccd.h"

namespace amt::refit {

/// #V by 3 positions (metres), row-major so that the data is the stacked coordinate vector x (3 #V).
using Positions = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// === Scene

/// The connectivity of the colliding surfaces, with what the potential caches from the rest shape.
struct CollisionMesh {
  int num_vertices = 0;
  MatrixX3i F;                           // #F by 3 triangles
  MatrixX2i E;                           // #E by 2 unique edges (i < j)
  std::vector<uint8_t> vertex_obstacle;  // #V: 1 for obstacle (avatar) vertices
  std::vector<uint8_t> face_obstacle;    // #F: all three corners are obstacle vertices
  std::vector<uint8_t> edge_obstacle;    // #E: both ends are obstacle vertices
  Eigen::VectorXd edge_rest_length_sq;   // #E squared rest lengths (the mollifier's ε×)
};

/// Builds the collision mesh of triangles F over `rest` positions (#V by 3); `obstacle` (#V, or empty
/// for none) marks the obstacle vertices. Throws amt::Error on a face index out of range.
CollisionMesh make_collision_mesh(const Positions& rest, const MatrixX3i& F, std::vector<uint8_t> obstacle = {});

/// The scene of a refit: a garment (#Vg vertices over garment_rest, faces F_garment) and after it an
/// avatar, an obstacle (avatar_rest, F_avatar): vertices [garment; avatar], faces
/// [F_garment; F_avatar + #Vg]. The rest positions give the mollifier its edge lengths.
CollisionMesh make_garment_avatar_mesh(const Positions& garment_rest, const MatrixX3i& F_garment,
                                       const Positions& avatar_rest, const MatrixX3i& F_avatar);

// === Candidates

/// Primitive pairs that the broad phase could not rule out.
struct Candidates {
  std::vector<std::array<int, 2>> point_triangle;  // (vertex, face)
  std::vector<std::array<int, 2>> edge_edge;       // (edge a, edge b), a < b
};

/// Pairs whose bounding boxes at positions x come within `inflation` (metres) of each other: every pair
/// closer than `inflation` is among them.
Candidates proximity_candidates(const CollisionMesh& mesh, const Positions& x, double inflation);

/// Pairs whose boxes swept over the motion x -> x + dx (#V by 3) overlap: every pair that comes into
/// contact during the motion is among them.
Candidates motion_candidates(const CollisionMesh& mesh, const Positions& x, const Positions& dx);

/// The smallest squared distance over the candidate pairs (+infinity for none).
double min_distance_sq(const CollisionMesh& mesh, const Positions& x, const Candidates& candidates);

/// The largest t in [0, 1] such that the motion x -> x + t dx is collision-free, conservatively: the
/// smallest additive-CCD time of impact over the swept candidates (1 when nothing is hit).
double max_collision_free_step(const CollisionMesh& mesh, const Positions& x, const Positions& dx,
                               const CcdOptions& options = {});

// === Barrier potential

/// κ Σ_k b(d_k², d̂²) over the point-triangle pairs and κ Σ m_k b(d_k², d̂²) over the edge-edge pairs
/// closer than d̂ (IPC eq. 8 with the edge-edge mollifier m of section 4.3). A point-triangle pair whose
/// closest feature is an edge or a vertex is counted once per (point, edge) or (point, vertex), not once
/// per triangle sharing that feature.
class BarrierPotential {
 public:
  /// d_hat: the activation distance d̂ (metres); stiffness: κ.
  BarrierPotential(const CollisionMesh& mesh, double d_hat, double stiffness);

  /// The potential at x; +infinity when some pair touches or crosses (distance 0).
  double value(const Positions& x) const;

  /// The potential, and when non-null, its gradient added to *gradient (3 #V) and its Hessian added to
  /// *hessian as triplets on the stacked coordinates, each pair's 12 by 12 block projected to positive
  /// semi-definite (clamped eigenvalues) when project_psd is set.
  double derivatives(const Positions& x, Eigen::VectorXd* gradient, std::vector<Eigen::Triplet<double>>* hessian,
                     bool project_psd = true) const;

  double d_hat() const { return d_hat_; }
  double stiffness() const { return stiffness_; }
  const CollisionMesh& mesh() const { return mesh_; }

 private:
  const CollisionMesh& mesh_;
  double d_hat_;
  double stiffness_;
};

}  // namespace amt::refit
