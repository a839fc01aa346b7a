#pragma once
// A dataset character remade the way artists build MMD/PMX and VRoid-style models, as test data for what the
// procedural builder never makes: every surface split into many small UV islands whose seam vertices are
// duplicated (coincident copies that must move as one), hair and narrow pieces cut into separate strips, every
// apparel strip or panel double-sided with a reverse copy a few millimetres off, skirts and capes layered, and
// 15-60k vertices. Torch-free (Eigen), like open_parts.h, which it builds on.
//
// The remake, deterministic from ArtistStyleOptions::seed:
//   1. subdivision (target_vertices > 0): the longest edges of the source mesh are split at their midpoints (one
//      level, faces split 1-to-2, 3 or 4 so that no crack opens), as many as bring the remake near the target;
//   2. the body is cut into open, overlapping parts with a hair cap (open_parts_character);
//   3. every connected piece of garment and apparel is cut into strips (hair: a piece hanging from the head or
//      neck, and any long narrow piece; `strip_width` wide) or panels (skirts, capes, sleeves: `panel_width`),
//      lengthwise, by its position across its length axis (or its angle around it, for tubes and skirt rings);
//   4. every strip and panel gets a reverse side: a copy of its faces with reversed winding, offset along the
//      rest normal by a distance drawn per strip in [back_offset_min, back_offset_max] on a 0.25 mm grid (never
//      coincident with its front: linked by proximity only; neighbouring strips' reverse sides meet exactly or
//      lie a step apart); panels get a second layer with probability `layer_share`, a same-winding copy offset
//      `layer_offset_min`-`layer_offset_max` outside, drawn the same way;
//   5. every body part, strip, panel, reverse side and layer is cut into UV islands of about `island_faces`
//      faces (breadth-first regions over shared edges), each with its own copies of its vertices.
// Coincident copies share their source vertex and offset, so their rest positions and remade ground truth are
// bit-identical.
//
// Ground truth (remake_frame): the source frame is subdivided as the rest mesh was (a midpoint is the mean of its
// edge's two endpoints in that frame), the subdivided frame's vertex normals are computed over its faces, and
// remade vertex i is  subdivided[source[i]] + offset[i] * normal[source[i]]: a reverse side or layer follows its
// front vertex along that vertex's per-frame normal at its rest offset distance (the open parts' inset seam
// rings likewise, with a negative offset). Vertices of the hair cap (source -1) are rigid to `joint[i]`:
// R_j (rest_i - J_j) + t_j.
#include <cstdint>
#include <string>
#include <vector>

#include "data_tools/builder/open_parts.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Remake

/// Choices of artist_style_character. Lengths in metres.
///   seed              every random draw (cut positions, offsets, layers, island sizes)
///   target_vertices   0: no subdivision; else the remake's vertex count to aim at (>= 1000), reached within a
///                     few per cent when one level of midpoint subdivision can (at most #V + #E source vertices)
///   open_parts        the body's cut (open_parts_character)
///   strip_width       width across a hair strip (> 0)
///   panel_width       width across a skirt / cape panel (> 0)
///   back_offset_*     the reverse side's offset along the rest normal, drawn per strip (> 1 mm: never welded
///                     at kWeldTolerance to its front; min <= max)
///   layer_share       share of panels given a second layer, in [0, 1]
///   layer_offset_*    the second layer's offset outside (> back_offset_max; min <= max)
///   island_faces      mean faces per UV island (>= 2); each island's size is drawn in [0.5, 1.5] times it
struct ArtistStyleOptions {
  uint64_t seed = 1;
  int target_vertices = 0;
  OpenPartsOptions open_parts;
  float strip_width = 0.02f;
  float panel_width = 0.12f;
  float back_offset_min = 0.0015f, back_offset_max = 0.003f;
  float layer_share = 0.5f;
  float layer_offset_min = 0.004f, layer_offset_max = 0.006f;
  int island_faces = 24;
};

/// The side of a remade surface a vertex belongs to.
enum class ArtistSide : uint8_t {
  kFront = 0,    ///< the body or the garment's own surface
  kReverse = 1,  ///< the reverse side of a double-sided strip or panel
  kLayer = 2,    ///< a panel's second layer
};

/// The remade character and how the source's ground truth maps onto it.
///   character        mesh (V (#V, 3), F), skeleton, apparel mask and body weights (#V, J) of the remake; name
///                    and split of the source; no rig (the remake's ground truth is vertices)
///   source_vertices  #S: the source mesh's N vertices, then the subdivision's midpoints
///   midpoints        (#S - N, 2) the source edge (two source vertices) of each midpoint
///   subdivided_faces the subdivided source mesh's faces, indices into the #S vertices (per-frame normals)
///   source           #V: the subdivided source vertex each remade vertex copies, -1 for the hair cap
///   offset           #V: metres along the subdivided source's vertex normal (0 on front copies)
///   joint            #V: the joint a cap vertex is rigid to, -1 elsewhere
///   side             #V: ArtistSide of each vertex
///   strip            #V: the body part, strip or panel each vertex belongs to (reverse sides and layers keep
///                    their front's), numbered from 0
///   source_pairs     (#V, 2) and source_weights (#V, 2): the same map in source vertices, for readers that do
///                    not subdivide: remade vertex i follows w0 x[p0] + w1 x[p1] (p0 == p1, w = (1, 0) off
///                    midpoints; p = (-1, -1) on the cap), plus the offset along the normal
struct ArtistStyleCharacter {
  CharacterData character;
  int source_vertices = 0;
  MatrixX2i midpoints;
  MatrixX3i subdivided_faces;
  std::vector<int32_t> source;
  std::vector<float> offset;
  std::vector<int32_t> joint;
  std::vector<ArtistSide> side;
  std::vector<int32_t> strip;
  MatrixX2i source_pairs;
  MatrixXfR source_weights;
  int num_strips = 0;
};

/// Remakes the dataset character `source` (a generated or built character: the canonical skeleton, the body the
/// run of leading vertices of its largest connected part, garment and apparel after it) as described in the
/// file comment. Deterministic. Throws amt::Error on options out of range or a character of another layout.
ArtistStyleCharacter artist_style_character(const CharacterData& source, const ArtistStyleOptions& options = {});

/// The remade ground truth of one frame: source_frame (N, 3) positions of the source character's vertices,
/// joint_transforms its J joint transforms [R_j | t_j] (only the cap's joint is read). Returns (#V, 3).
/// Throws amt::Error on a frame of another vertex or joint count.
MatrixX3f remake_frame(const ArtistStyleCharacter& remake, const MatrixX3f& source_frame,
                       const Transforms& joint_transforms);

/// The same for T frames stacked (T * N, 3), as DatasetReader::read_vertices returns them, with T * J joint
/// transforms (read_joint_transforms). Returns (T * #V, 3).
MatrixX3f remake_frames(const ArtistStyleCharacter& remake, const MatrixX3f& source_frames,
                        const Transforms& joint_transforms);

// === What real models look like

/// Vertices nearer than this (metres) coincide: a seam's duplicated vertices, at the same position in the file.
inline constexpr float kCoincidentTolerance = 1e-4f;

/// Counts of a mesh's construction, to compare with real models (two of them: 68-84 % of vertices with a
/// coincident copy, hundreds to thousands of parts, about 10x fewer parts once coincident vertices are welded).
///   parts          connected parts over the faces' edges
///   welded_parts   the same after welding vertices within kCoincidentTolerance
///   coincident_share  share of vertices with another vertex within kCoincidentTolerance
struct MeshConstruction {
  int vertices = 0, faces = 0, parts = 0, welded_parts = 0;
  double coincident_share = 0;
};

/// The counts of (V (#V, 3), F).
MeshConstruction mesh_construction(const MatrixX3f& V, const MatrixX3i& F);

// === Measures of falling apart

/// The seams of (V (#V, 3), F): the pairs of vertices within `tolerance` metres at rest (found by weld_vertices, so
/// chains within the tolerance count) that both lie on an open boundary of F (an edge of one face), as a seam's
/// duplicated vertices do; two vertices of a closed surface that merely touch (a generated body's legs at the
/// crotch) are no seam. Each such vertex is paired with the smallest index of its group: (P, 2) rows (smallest,
/// other) in ascending order of `other`; a group of k copies gives k - 1 pairs.
MatrixX2i coincident_pairs(const MatrixX3f& V, const MatrixX3i& F, float tolerance = kCoincidentTolerance);

/// The edges E (#E, 2) with an apparel vertex (mask 1) at either end, in E's order.
MatrixX2i apparel_edges(const MatrixX2i& E, const std::vector<uint8_t>& apparel_mask);

/// Figures of a method on one character (or a set of characters), from SeparationAccumulator.
///   tearing          share of apparel edge-frames whose predicted length is off the ground truth's by more
///                    than 50 % (| |e_pred| / |e_gt| - 1 | > 0.5); NaN without apparel edges
///   seam_gap_p95_cm, seam_gap_max_cm  over every frame of every pair of vertices coincident at rest, their
///                    distance apart in the prediction beyond their distance apart in the ground truth (cm; 0 on a
///                    seam the ground truth keeps closed, so it is their distance apart; a source's touching
///                    points that the ground truth parts do not count): the 95th percentile and the largest; NaN
///                    without pairs
///   apparel_els      ELS over apparel edges only: per frame the mean over them of
///                    1 - | |e_pred| / |e_gt| - 1 |, averaged over frames, then clips; NaN without apparel edges
///   pairs            coincident pairs; edge_frames, pair_frames: the counts measured
/// With the rest mesh given (NaN without it), against rest lengths instead of the ground truth's:
///   rest_tearing     share of apparel edge-frames whose predicted length is off its rest length by more than 50 %
///                    (the prediction's own stretch and squash, whatever the ground truth does)
///   ground_truth_rest_tearing  the same share of the ground truth
///   tearing_ground_truth_deformed  share of apparel edge-frames torn (as `tearing`) where the ground truth's own
///                    edge is off its rest length by more than 50 % (a prediction that keeps such an edge near rest
///                    counts as torn)
struct SeparationScores {
  double tearing = 0, seam_gap_p95_cm = 0, seam_gap_max_cm = 0, apparel_els = 0;
  double rest_tearing = 0, ground_truth_rest_tearing = 0, tearing_ground_truth_deformed = 0;
  int64_t pairs = 0, edge_frames = 0, pair_frames = 0;
};

/// Accumulates the measures of a prediction falling apart over the clips of one character: begin_clip(),
/// add_frame() per frame, end_clip(), result(). The seam gap's percentile comes from a histogram of log-spaced
/// bins (1 % wide) from 1e-4 cm, below which a gap counts as 0.
class SeparationAccumulator {
 public:
  /// pairs (P, 2) coincident_pairs of the rest mesh; edges (#E_a, 2) its apparel_edges; rest (#V, 3) the rest
  /// mesh for the measures against rest lengths (empty: those are NaN).
  SeparationAccumulator(MatrixX2i pairs, MatrixX2i edges, const MatrixX3f& rest = MatrixX3f());
  void begin_clip();
  /// pred, gt (#V, 3) metres. A ground truth's own seam gaps: add_frame(gt, rest) (the rest's pairs are
  /// within kCoincidentTolerance).
  void add_frame(const MatrixX3f& pred, const MatrixX3f& gt);
  void end_clip();
  SeparationScores result() const;

 private:
  MatrixX2i pairs_, edges_;
  std::vector<double> rest_lengths_;  // of edges_, empty without a rest mesh
  int64_t torn_ = 0, edge_frames_ = 0, pair_frames_ = 0;
  int64_t rest_torn_ = 0, gt_rest_torn_ = 0, torn_gt_deformed_ = 0, rest_edge_frames_ = 0;
  std::vector<int64_t> histogram_;  // pair-frames per gap bin ([0]: below the first)
  std::vector<double> bin_max_cm_;  // the largest gap of each bin
  double max_gap_cm_ = 0;
  double frame_els_sum_ = 0, clip_els_sum_ = 0;
  int frame_els_count_ = 0, clip_els_count_ = 0;
};

}  // namespace amt
