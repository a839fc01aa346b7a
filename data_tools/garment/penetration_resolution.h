#pragma once
// Penetration resolution, the post-process of the runtime (issue 6, item 5) and of cloth retargeting
// (issue 13): apparel vertices found inside the body are pushed out along the body surface normal by
// their depth plus a small margin, as in the paper "Cloth Motion Retargeting"
// (section 3.2: "moving the penetrating cloth vertices in the direction of the normal vectors ... by the
// extent of the penetrations"); the push is then spread to the untouched apparel neighbours with a decaying
// weight, so that a pushed vertex does not become a spike in its garment. Apparel that moves on handles is pushed
// through them instead (set_rig): a piece moves out as a piece, and a few passes give the moved vertices back their
// edge lengths (PenetrationOptions::length_iterations).
//
// Inside test: the generalized winding number (data_tools/geometry/winding_number.h) against the body part,
// the faces whose three vertices are body vertices, posed as in the frame, with the holes left where
// apparel was cut away (or where the segmenter took body vertices for apparel) closed by fans to the
// mean of each hole's boundary (data_tools/geometry/mesh.h fill_holes): a closed surface, whose winding number
// is an integer off it. The direction out is from the vertex to its closest body point: for a
// closest point inside a triangle this is the triangle's normal, and it stays correct at edges and
// corners where face normals disagree.
//
// Bodies of many open, overlapping parts (real MMD/PMX models: a face, a hair cap, sleeves, a body with
// holes under the clothes; data_tools/builder/open_parts.h is a stand-in): closing every part's holes
// makes each part a closed surface and the body their union, whose winding number is at least 1 inside
// any part (overlaps count twice), so the inside test keeps its meaning. What changes is the way out:
// the fans that close a part's seam, the seam ring a part tucks under its neighbour and a cap's rim
// inside the head are surfaces inside the body, and a vertex pushed to them stays inside. So the
// faces are classified once, on the first pose the resolver sees (prepare(), the rest pose in the
// runtime): a face is exposed when the point a millimetre out of its centroid along its normal is not
// inside the body, internal otherwise; a fan whose centre lies deep in the body (farther from the skin
// than half the hole's radius: a seam loop, or one rim of a band of skin dropped around a waist, which
// the fan crosses the body to close) is internal too; a penetrating vertex is pushed to its closest
// exposed body point. On a closed body without overlaps every face is exposed and nothing changes. A vertex still
// inside after its push (between two overlapping parts) is pushed again, up to kMaxPushes times.
//
// Per frame cost: the winding-number tree over the body is built once, on the first frame, and then
// refitted to each frame's posed body (WindingNumberTree::refit, O(#F) without sorting) instead of
// rebuilt: the body's faces do not change between frames, only its positions. And since that surface
// is closed, an apparel vertex keeps the previous frame's verdict without a winding-number query when,
// seen from the vertex, no part of the body moved far enough to reach it (WindingNumberTree::stays_clear):
// the verdict is then exactly what the query would say, and vertices away from the skin or moving with the
// skin under them skip it. The refit
// moves only the tree's triangles and boxes, all that stays_clear and the distances read; the far-field
// expansions of the winding number, most of a refit's cost, are refitted only in a frame where some
// vertex needs a query (WindingNumberTree::update_far_field).
#include <cstdint>
#include <memory>
#include <vector>

#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/metrics.h"
#include "data_tools/geometry/types.h"
#include "data_tools/geometry/winding_number.h"

namespace amt {

/// Choices of the resolution.
///   margin          distance outside the body surface a pushed vertex ends at, metres
///   smoothing_rings rings of apparel neighbours around a pushed vertex that follow it, each ring
///                   with `falloff` times the previous ring's share of the push (0: no smoothing)
///   keep_rest_penetration  apparel vertices inside the body on the pose prepare() sees (the rest pose) are left
///                   where they are: an artist's model tucks hair roots into the scalp and hems under a collar,
///                   and its own physics keeps them there (no collision between the two); pushing them out moves
///                   them centimetres off the model. Off for a garment fitted to another body (cloth retargeting).
///   length_iterations  with a rig (set_rig): passes, after the pushes, in which the moved apparel vertices take back
///                   the edge lengths they had before the push (one Jacobi projection over the apparel edges, then
///                   a per-vertex push of any vertex that went back inside; vertices at one point before the push,
///                   a split seam's copies, take one step); 0: none
struct PenetrationOptions {
  float margin = 0.003f;
  int length_iterations = 4;
  int smoothing_rings = 2;
  float falloff = 0.5f;
  bool keep_rest_penetration = false;
};

/// What a frame's resolution did.
///   before, after   apparel vertices inside the body before and after (data_tools/geometry/metrics.h)
///   pushed          vertices moved out of the body; smoothed: neighbours moved with them
///   carried         apparel vertices whose inside verdict carried over from the previous frame
///                   (no winding-number query; see the file comment)
///   tucked          apparel vertices inside the body now and at rest, left alone (keep_rest_penetration); they
///                   count in before and after
struct PenetrationReport {
  Penetration before, after;
  int pushed = 0, smoothed = 0, carried = 0, tucked = 0;
};

/// Pushes of a vertex in one resolve(): the first, and more while it is still inside (see the file
/// comment).
inline constexpr int kMaxPushes = 3;

/// Resolves the penetration of a character's apparel into its body, frame after frame. Built once per
/// character from its faces and apparel mask; resolve() is then called with each posed frame. It keeps
/// the body's winding-number tree between calls (refitted to each frame), so one resolver serves one
/// frame at a time: do not call measure() or resolve() of the same resolver from two threads at once.
class PenetrationResolver {
 public:
  /// F #F by 3 faces; apparel_mask #V entries (1 = apparel). A character without apparel or without
  /// a closed body part (no face with three body vertices) is accepted: resolve() then does nothing.
  PenetrationResolver(const MatrixX3i& F, const std::vector<uint8_t>& apparel_mask, PenetrationOptions options = {});

  /// Builds the body's tree on V (#V by 3, metres; the rest pose) and classifies its faces as exposed or
  /// internal there (file comment), ahead of the first frame; without it the first measure() or resolve()
  /// does this on its frame. With keep_rest_penetration it also records which apparel vertices are inside the
  /// body on V (rest_inside()). Nothing when the tree is already built.
  void prepare(const MatrixX3f& V);

  /// Spreads the pushes through the apparel's handles instead of rings of neighbours: every handle takes the mean
  /// push of the penetrating vertices it carries (weighted by their weights on it) and every apparel vertex moves by
  /// the weighted pushes of its handles, as the apparel follows its handles (models/apparel_handles.h); a vertex
  /// still inside after that is pushed on its own. A piece pushed out by one vertex at a time is squashed and
  /// stretched across the body's surface (a hair strand swung two centimetres into the back has its one-centimetre
  /// edges torn); pushed by its handles it moves out as a piece.
  ///   vertex_handles, vertex_weights (num_apparel(), K): each apparel vertex's handles in [0, num_handles) and
  ///   weights (by apparel position, ascending mesh order). Throws amt::Error on shapes or indices that do not match.
  void set_rig(const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& vertex_handles,
               const MatrixXfR& vertex_weights, int num_handles);

  /// Measures the apparel's penetration into the body of V (#V by 3, metres) without changing it.
  /// `carried`, when given, receives the number of verdicts carried over from the previous call.
  Penetration measure(const MatrixX3f& V, int* carried = nullptr);

  /// Pushes the penetrating apparel vertices of V (#V by 3, metres) out, in place, and reports the
  /// penetration before and after. Deterministic; the queries run on the OpenMP threads.
  PenetrationReport resolve(MatrixX3f& V);

  /// Apparel and body vertex counts; faces of the closed body part.
  int num_apparel() const { return int(apparel_.size()); }
  int num_body() const { return int(body_.size()); }
  int num_body_faces() const { return int(body_faces_.rows()); }
  /// Whether the body surface tested against is closed (holes filled), so that verdicts may carry
  /// over between frames; and the number of holes filled.
  bool closed_body() const { return closed_body_; }
  int num_filled_holes() const { return int(holes_.size()); }
  /// Per face of the closed body part (num_body_faces(), the fans last): 1 exposed, 0 internal (file
  /// comment); empty until the first pose.
  const std::vector<uint8_t>& exposed_faces() const { return exposed_; }
  /// Per apparel vertex (ascending mesh order): 1 when it was inside the body on prepare()'s pose and
  /// keep_rest_penetration leaves it there; empty otherwise.
  const std::vector<uint8_t>& rest_inside() const { return rest_inside_; }

 private:
  // The tree over the body surface (holes filled) posed as in V: built on the first call, refitted after.
  const WindingNumberTree& posed_body(const MatrixX3f& V);

  // The edge-length passes of a push through the rig (PenetrationOptions::length_iterations) on V, whose apparel was
  // at `start` (num_apparel() x 3) before the push: `moved` marks the vertices the push moved, `inside` (1: inside)
  // and `depth` the verdicts after the push, updated.
  void keep_lengths(MatrixX3f& V, const MatrixX3f& start, const std::vector<uint8_t>& moved,
                    std::vector<uint8_t>& inside, std::vector<float>& depth) const;

  // The pushes of the vertices marked in `pushing` (by apparel position) spread through the rig (set_rig): `push`
  // receives every carried vertex's move; returns the carried vertices, ascending.
  std::vector<int> spread_through_rig(const std::vector<uint8_t>& pushing, std::vector<Eigen::Vector3f>& push) const;

  // Inside verdicts of V's apparel vertices into inside_ (by apparel position), with the tree posed
  // as in V (posed_body); returns how many carried over from the previous call. The tree's far field
  // is brought up to date only when some vertex needs a winding-number query.
  int classify(const MatrixX3f& V);

  PenetrationOptions options_;
  std::vector<int32_t> apparel_, body_;  // vertex ids of each part, ascending
  MatrixX3i body_faces_;                 // faces with three body vertices, renumbered into body_, then
                                         // the fans closing the holes (centre of hole h: body_.size() + h)
  std::vector<std::vector<int32_t>> holes_;  // boundary vertices of each hole, positions in body_
  int num_fan_faces_ = 0;                // the last rows of body_faces_
  Adjacency apparel_adjacency_;          // over apparel_ positions (edges inside the apparel)
  std::unique_ptr<WindingNumberTree> tree_;  // over body_faces_, posed as in the last call
  std::vector<uint8_t> exposed_;         // per row of body_faces_: exposed (1) or internal, on the tree's first pose
  MatrixX3f body_scratch_;               // body positions of the last call
  bool closed_body_ = false;             // is_closed_surface(body_faces_): false only without body faces
  MatrixX3f previous_;                   // apparel positions of the last call (empty before the first)
  std::vector<uint8_t> inside_;          // their verdicts
  std::vector<uint8_t> rest_inside_;     // apparel inside at rest, left alone (keep_rest_penetration); empty: none
  std::vector<int> query_;               // apparel positions whose verdict classify() queried
  // The apparel's handles (set_rig): per apparel position its handles and weights; no rows: rings spread the pushes.
  Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rig_handles_;
  MatrixXfR rig_weights_;
  int rig_size_ = 0;
  std::vector<std::vector<int>> rig_neighbors_;  // handles that share a vertex, ascending
};

}  // namespace amt
