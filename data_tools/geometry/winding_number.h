#pragma once
// Inside test and distance against a closed body surface, for the penetration metric (docs/evaluation.md,
// "Metrics"): the generalized winding number (Jacobson et al. 2013, "Robust inside-outside
// segmentation using generalized winding numbers"), accelerated with a bounding-volume hierarchy and
// a far-field expansion of each subtree about its centre (Barill et al. 2018, "Fast winding numbers
// for soups and clouds", their second-order Taylor expansion); and the unsigned distance to the
// surface (closest point on a triangle: Ericson 2005, "Real-Time Collision Detection", 5.1.5).
//
// Written here by hand: no Debian package offers a fast winding number. libigl, which has one, is not
// packaged; CGAL (libcgal-dev) has only ray-cast inside tests, which need a watertight mesh; OpenVDB's
// signed distance fields need a voxelisation whose resolution would limit the penetration depth.
#include <cstdint>
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

// === Winding number tree

/// An axis-aligned bounding-volume hierarchy over the triangles of a surface, built once
/// (O(#F log #F)) and queried many times. Queries are const and safe to run from many threads at
/// once. The tree keeps its own copy of the triangles: (V, F) may go away after construction.
///
/// The winding number is about 1 inside a closed surface whose triangles are ordered
/// counter-clockwise seen from outside (outward normals), about 0 outside, -1 inside with reversed
/// orientation; on open or self-intersecting surfaces it degrades gracefully (fractional values).
class WindingNumberTree {
 public:
  /// Builds the tree. V #V by 3 surface vertices (metres), F #F by 3 triangles, ideally a closed,
  /// outward-oriented surface. `beta` is the far-field accuracy: a subtree is replaced by its
  /// expansion when the query point is more than beta times the subtree's radius from its centre
  /// (larger is more exact and slower; Barill et al. use 2, which keeps the error within 3e-3 of the
  /// exact sum on a closed sphere of 5k triangles). Throws amt::Error on a mesh that validate_mesh
  /// rejects or on beta <= 0.
  WindingNumberTree(const MatrixX3f& V, const MatrixX3i& F, double beta = 2.0);

  /// Generalized winding number of the surface at p: the sum of the signed solid angles of the
  /// triangles seen from p (Van Oosterom and Strackee 1983) over 4 pi, with far subtrees
  /// approximated by their expansions. Points on the surface give values between the two sides.
  double winding_number(const Eigen::Vector3f& p) const;

  /// The same sum over every triangle, without the approximation: O(#F), for reference.
  double exact_winding_number(const Eigen::Vector3f& p) const;

  /// True when p is inside the surface: winding_number(p) > 0.5.
  bool inside(const Eigen::Vector3f& p) const;

  /// Unsigned distance (metres) from p to the nearest point of the surface; `closest`, when given,
  /// receives that point. Inside the body this is the penetration depth. `faces`, when given, holds
  /// #F flags in the order of the construction's F: only the triangles flagged non-zero count
  /// (infinity, and p as the closest point, when none is).
  float distance(const Eigen::Vector3f& p, Eigen::Vector3f* closest = nullptr,
                 const std::vector<uint8_t>* faces = nullptr) const;

  /// Whether the surface comes within r (metres, >= 0) of p: distance(p) <= r, visiting only the boxes within r and
  /// stopping at the first triangle that near (a point far from the body costs a few box tests, where distance()
  /// has to find the nearest triangle).
  bool within(const Eigen::Vector3f& p, float r) const;

  /// winding_number() of every row of P (#P by 3), in parallel with OpenMP. Returns #P values.
  Eigen::VectorXd winding_numbers(const MatrixX3f& P) const;

  /// distance() of every row of P (#P by 3), in parallel with OpenMP. Returns #P values.
  Eigen::VectorXf distances(const MatrixX3f& P) const;

  /// Number of triangles the tree was built from.
  int num_triangles() const { return static_cast<int>(triangles_.size()); }

  /// Moves the surface to new positions of the same vertices (V #V by 3, metres, as many rows as at
  /// construction; the faces stay those given then) and refits the tree to them in O(#F) without
  /// re-sorting: leaves recompute their boxes and expansions from their triangles (in parallel with
  /// OpenMP), inner nodes merge their children's (boxes by union, moments shifted to the new centre,
  /// radius bounded by the smaller of child radius plus centre offset and the distance to the box's
  /// farthest corner, never smaller than the exact one). The far
  /// field stays as accurate as after a fresh build; queries get slower only when the motion makes
  /// the boxes overlap much more than at construction (a posed body of a skinned character does not).
  /// This is what the runtime does per frame instead of building a tree over the posed body.
  /// Throws amt::Error on a row count other than the construction's or on non-finite positions.
  ///
  /// A refit also records how far each vertex moved since the previous positions, for stays_clear().
  ///
  /// With far_field false only the triangles, boxes and displacements are refitted: distance() and
  /// stays_clear() are then exact for V, while winding_number() and inside() throw until
  /// update_far_field() has brought the expansions up to date (most of a refit's cost, which a caller
  /// whose points all keep their verdicts through stays_clear() never pays).
  void refit(const MatrixX3f& V, bool far_field = true);

  /// Refits the expansions to the positions of the last refit (nothing when they are current): after
  /// it the tree is what refit(V) would have made of it.
  void update_far_field();

  /// Whether the expansions are those of the current positions (false after refit(V, false) until
  /// update_far_field()).
  bool far_field_current() const { return far_field_current_; }

  /// True when a point now at p, which moved by `displacement` since the previous refit, cannot have
  /// met the surface meanwhile: with the point and every vertex moving on straight lines over the same
  /// time, no triangle came within the point's path. Then the point is on the same side of a closed
  /// surface as before (its winding number, an integer off the surface, could not change). The test, in
  /// the frame that moves with the point (where it stands still): every triangle T is farther from p
  /// than the largest displacement of T's corners less `displacement`, checked top-down with the
  /// subtrees' boxes and the boxes of their corners' displacements; it stops at the first triangle too
  /// near. Apparel that moves with the body near it keeps its verdicts however fast the body moves.
  /// Always false before the first refit and for a non-finite displacement. This is what lets the
  /// runtime skip the winding number of most apparel vertices from one frame to the next
  /// (data_tools/garment/penetration_resolution.h).
  bool stays_clear(const Eigen::Vector3f& p, const Eigen::Vector3f& displacement) const;

 private:
  // One triangle's corners, stored in tree order so that a leaf's triangles are contiguous.
  struct Triangle {
    Eigen::Vector3f a, b, c;
    int32_t face;  // row of the construction's F
  };

  // What a subtree looks like from far away: the moments of its area-weighted normals about its
  // centre c, over its triangles t with area a_t, unit normal n_t and centroid x_t.
  struct FarField {
    Eigen::Vector3d center;            // c, the area-weighted centroid of the triangles
    Eigen::Vector3d normal_sum;        // N = sum_t a_t n_t
    Eigen::Matrix3d first_moment;      // M = sum_t a_t n_t (x_t - c)^T
    Eigen::Matrix3d second_moment[3];  // Q_i = sum_t a_t n_t[i] S_t, S_t = mean of (x - c)(x - c)^T over t
  };

  // A tree node as built and refitted: a leaf owns triangles_[first, first + count); an inner node has
  // two children. Double precision, full moments: merging children shifts them to the parent's centre.
  struct Node {
    Eigen::AlignedBox3f box;        // bounds of the subtree's triangles
    FarField far_field;             // expansion used when the query point is far
    double radius = 0;              // largest distance from far_field.center to a triangle corner
                                    // (an upper bound of it after refit)
    double area = 0;                // total triangle area of the subtree
    int32_t left = -1, right = -1;  // children, -1 for a leaf
    int32_t first = 0, count = 0;   // leaf triangles triangles_[first, first + count)
    bool is_leaf() const { return left < 0; }
  };

  // What a winding-number query reads of a node: the far field contracted to the coefficients its
  // evaluation uses, in single precision (124 bytes against the Node's 420), so that the hot part of a
  // body's tree stays in cache. The flux of the expansion seen from q = center - r (FarField::solid_angle)
  // only depends on the symmetric part of M and on the fully symmetrised Q:
  //   r.N / |r|^3 + tr M / |r|^3 - 3 r^T M r / |r|^5 - 3/2 r.w / |r|^5 + 15/2 C(r) / |r|^7,
  //   w_k = 2 sum_i Q_iik + sum_j Q_kjj,   C(r) = sum_ijk Q_ijk r_i r_j r_k (10 monomial coefficients).
  struct QueryNode {
    Eigen::Vector3f center;
    float open2 = 0;             // (beta radius)^2: nearer than this the node is opened
    Eigen::Vector3f normal_sum;  // N
    float trace_m = 0;           // tr M
    float m_sym[6] = {};         // M's symmetric part: xx, yy, zz, xy, xz, yz
    Eigen::Vector3f w;
    float cubic[10] = {};        // C's coefficients of x^3, x^2 y, x^2 z, x y^2, x y z, x z^2, y^3, y^2 z, y z^2, z^3
    int32_t left = -1, right = -1, first = 0, count = 0;
    bool is_leaf() const { return left < 0; }
    // Solid angle of the subtree seen from q = center - r, by its second-order expansion.
    float solid_angle(const Eigen::Vector3f& r) const;
  };

  // What distance(), stays_clear() and a refit without the far field read and write of a node (64 bytes,
  // a cache line): its box and the box of its corners' displacements in the last refit (unbounded before
  // the first), kept up to date by every refit.
  struct BoundsNode {
    Eigen::AlignedBox3f box, displacement;
    int32_t left = -1, right = -1, first = 0, count = 0;
    bool is_leaf() const { return left < 0; }
  };

  // Builds the subtree over triangles_[first, first + count) and returns its node index.
  int32_t build(int32_t first, int32_t count, int depth);

  // Sets node's box, far field, radius and area from its triangles triangles_[first, first + count);
  // returns the bounds of the triangle centroids (which choose the split). Sums in Sum (float for a
  // leaf, double for a larger node).
  template <typename Sum>
  Eigen::AlignedBox3f fit(Node& node) const;

  // Sets inner node `index`'s box, far field, radius and area from its two (already fitted) children.
  void merge_children(int32_t index);

  // Rewrites query_nodes_ and bounds_ from nodes_ (after a build or a refit), all but the displacements.
  void compact();

  MatrixX3i faces_;     // the construction's F, for refit
  MatrixX3f vertices_;  // positions of the last build or refit, for the displacements of the next
  MatrixX3f displacement_;  // refit's working space: per vertex its displacement
  bool far_field_current_ = true;  // false between refit(V, false) and update_far_field()
  std::vector<Triangle> triangles_;
  std::vector<Node> nodes_;
  std::vector<QueryNode> query_nodes_;  // nodes_ as the winding-number queries read them, same indices
  std::vector<BoundsNode> bounds_;       // nodes_' boxes and displacement boxes, same indices
  double beta_;
};

}  // namespace amt
