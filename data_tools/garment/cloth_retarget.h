#pragma once
// Cloth motion retargeting (papers: cloth_motion_retargeting, sections 2.2 and 3; issue 13): the motion
// of a source character's apparel, simulated on the source body, carried onto a target character whose
// apparel has the same connectivity, frame by frame:
//   registration (once)  the rest apparel of each character bound to its own rest body with the wrap
//                        deformer (data_tools/garment/wrap_deformer.h; steps 1, 2 and 4's registration);
//   per frame            body-oriented source apparel S_s = wrap of the source body (step 3),
//                        detail vectors d = A_s - S_s (step 5), body-oriented target apparel
//                        S_t = wrap of the target body (step 4), target apparel A_t = S_t + s d (step 6),
//                        s = 1 as in the paper or, with scale_details, per vertex the target apparel's
//                        size around the vertex over the source's (their rest edge lengths): a chibi's skirt
//                        swings less far than a tall body's, and where the body-oriented apparel stretches
//                        (a skirt split by the legs) the detail vectors that undo the stretch must match it;
//                        then the apparel's edges relaxed towards their rest lengths (relax_iterations, not
//                        in the paper: see there);
//                        then collisions (section 3):
//     3.1  a detail vector is shortened when it would carry its vertex through the body-oriented
//          target apparel towards the body. First-order version of the paper's test (a full
//          segment-against-mesh query per vertex would cost more than the whole frame): the
//          body-oriented vertex lies at clearance c (its registration's weighted distance to the
//          planes of its body faces) above the body, and every layer of the body-oriented apparel under
//          it lies within that clearance; a detail vector whose component along the inward normal of
//          those faces exceeds detail_clearance * c is scaled down to that length.
//     3.2  apparel vertices still inside the target body are pushed out by their depth
//          (data_tools/garment/penetration_resolution.h): the inside test is the generalized winding number
//          against the body part closed by fans over its holes, not the paper's "dot product of the
//          cloth normal with the vector to the nearest body vertex" (Figure 7). That test needs a
//          consistent cloth normal, which the two-sided sheets and tubes of MMD apparel do not have
//          (the inner layer faces the body), and a nearest body *vertex* misjudges points over large
//          faces and in concave places (armpits, between the legs); the winding number of a closed
//          surface is exact off the surface. The push goes to the closest body point (the body's
//          normal there, correct at edges and corners), by the depth plus a margin.
// The penetration before and after the resolution is measured per frame and reported (section 3.2
// admits residual penetration; the resolver re-tests every vertex it moved).
//
// Characters are whole meshes split by their apparel mask, as in the dataset (docs/dataset.md, "The dataset file"):
// the body part is the faces whose three vertices are body vertices (garment bands included), the
// apparel the vertices of mask 1, in ascending index order on both characters.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/metrics.h"
#include "data_tools/garment/penetration_resolution.h"
#include "data_tools/geometry/types.h"
#include "data_tools/garment/wrap_deformer.h"

namespace amt {

// === Options and reports

/// Choices of the retargeting.
struct ClothRetargetOptions {
  /// Registration of the apparel to its body (both characters): weights by the distance to each face
  /// (WrapOptions::triangle_distance_weights), not to its plane.
  WrapOptions wrap = [] {
    WrapOptions o;
    o.triangle_distance_weights = true;
    return o;
  }();
  /// Scale each detail vector by the target apparel's size over the source's around its vertex (the summed
  /// rest lengths of its apparel edges); false: add them unchanged, as the paper does.
  bool scale_details = true;
  /// Section 3.1: longest inward component of a detail vector as a share of the body-oriented vertex's
  /// clearance above the body (> 0); <= 0 switches the shortening off.
  float detail_clearance = 1.0f;
  /// Iterations of edge relaxation after step 6 and 3.1 (0: none): each apparel edge pulled towards its rest length on
  /// the target (Jacobi position-based constraint projection, half the correction to each end, averaged per
  /// vertex). Not in the paper: where the source's and the target's wraps bind neighbouring vertices to
  /// different body parts (a vertex between the torso and a leg), the body-oriented apparel tears open
  /// differently on the two bodies and the detail vectors no longer close the tear.
  int relax_iterations = 20;
  /// Section 3.2: push apparel vertices out of the target body.
  bool resolve = true;
  /// Without the push-out: still measure the penetration (a winding-number query per apparel vertex, most of
  /// a frame's cost); false leaves ClothRetargetReport::before and after empty.
  bool measure = true;
  PenetrationOptions penetration;
};

/// What the retargeting of one frame did.
///   before, after  target apparel vertices inside the target body before and after the resolution
///                  (after = before when the resolution is off)
///   shortened      detail vectors shortened by section 3.1
struct ClothRetargetReport {
  Penetration before, after;
  int shortened = 0;
};

/// One side of a retargeting: a character's rest mesh and apparel mask, and a name for messages.
struct ClothCharacter {
  std::string name;
  TriMesh mesh;
  std::vector<uint8_t> apparel_mask;
};

/// Throws amt::Error naming both characters unless their apparel has the same connectivity: the same
/// number of apparel vertices, and the same faces among them (faces whose three vertices are apparel,
/// numbered by apparel position) in the same order.
void check_same_apparel_connectivity(const ClothCharacter& source, const ClothCharacter& target);

// === The retargeter

/// Registered source and target; retarget() then runs frame by frame. Holds the target body's
/// winding-number tree between frames (refitted, data_tools/garment/penetration_resolution.h) and the working
/// space of steps 3-6, 3.1 and the relaxation (sized by the first frame, reused after): one frame at a
/// time, not from two threads at once.
class ClothRetargeter {
 public:
  /// Registers both characters' rest apparel to their rest bodies. Throws amt::Error for masks of the
  /// wrong length, characters without apparel or without body faces, and different apparel
  /// connectivity (check_same_apparel_connectivity).
  ClothRetargeter(const ClothCharacter& source, const ClothCharacter& target, const ClothRetargetOptions& options = {});

  /// Retargets one frame. source_frame (#V_s by 3, metres): the source character posed, body and
  /// simulated apparel; target_frame (#V_t by 3): the target character with its body posed (its apparel
  /// rows are ignored and replaced by the retargeted apparel). Throws amt::Error for other row counts.
  ClothRetargetReport retarget(const MatrixX3f& source_frame, MatrixX3f& target_frame);

  /// Step 3: the body-oriented source apparel of a source frame (#A by 3, apparel order).
  MatrixX3f body_oriented_source(const MatrixX3f& source_frame) const;
  /// Step 4: the body-oriented target apparel of a target frame (#A by 3).
  MatrixX3f body_oriented_target(const MatrixX3f& target_frame) const;
  /// Step 5: the detail vectors of a source frame, source apparel minus body-oriented (#A by 3).
  MatrixX3f detail_vectors(const MatrixX3f& source_frame) const;

  /// Apparel vertex count and the vertex ids of the apparel on each side (ascending).
  int num_apparel() const { return int(source_apparel_.size()); }
  const std::vector<int32_t>& source_apparel() const { return source_apparel_; }
  const std::vector<int32_t>& target_apparel() const { return target_apparel_; }
  /// The factors s on the detail vectors, per apparel vertex (1 without scale_details).
  const Eigen::VectorXf& detail_scale() const { return detail_scale_; }
  /// Registration wall time of both sides, seconds.
  double registration_seconds() const { return registration_seconds_; }

 private:
  struct Side {
    WrapDeformer wrap;          // the apparel (apparel order) on the rest body part, read from whole frames
    Eigen::VectorXf clearance;  // per apparel vertex: weighted signed distance to its faces' planes
    int num_vertices = 0;
  };
  // The edge relaxation's edges, per apparel vertex (both ends apparel, by apparel position), laid out
  // for a sweep vectorised over vertices: vertices in chunks of kRelaxLanes (the last one padded), chunk
  // c's edges as slots s of lanes l at slot_begin[c] + s * kRelaxLanes + l, as many slots as its vertex
  // with the most edges; empty slots name the lane's own vertex (a zero-length edge, skipped).
  static constexpr int kRelaxLanes = 4;
  struct Relaxation {
    std::vector<int32_t> slot_begin;  // per chunk, then the total
    std::vector<int32_t> neighbour;   // per slot: the edge's other end
    std::vector<float> rest_length;   // per slot: the edge's rest length on the target
    std::vector<float> positions;     // per padded vertex x, y, z, 0; then the same for the next sweep
  };
  static Side make_side(const ClothCharacter& c, const std::vector<int32_t>& apparel, const WrapOptions& wrap);
  void relax(MatrixX3f& A);

  ClothRetargetOptions options_;
  std::string source_name_, target_name_;
  std::vector<int32_t> source_apparel_, target_apparel_;
  Side source_, target_;
  Relaxation relaxation_;
  std::optional<PenetrationResolver> resolver_;  // built once the inputs are checked
  double registration_seconds_ = 0;
  Eigen::VectorXf detail_scale_;
  // Per-frame working space, kept between frames.
  WrapDeformer::Frames frames_;
  MatrixX3f oriented_source_, oriented_target_, normals_, apparel_;
};

}  // namespace amt
