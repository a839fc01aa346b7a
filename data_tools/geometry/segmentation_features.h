#pragma once
// Per-vertex shape features of a rest character for the apparel segmenter (models/apparel_segmenter.h),
// beside its rest positions: what a mesh and its skeleton say about a vertex that its position alone
// does not. Rest positions alone leave the segmenter guessing from where a vertex is (held-out IoU
// 0.72 with a boosted-tree probe on data/default); with these columns the same probe reaches 0.97.
#include <cstdint>
#include <string>
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

/// Number of columns of segmentation_features().
inline constexpr int kSegmentationFeatures = 6;

/// Shape features (N, kSegmentationFeatures) of the rest mesh (V, F) with rest joints `joints`
/// (J, 3) and `parents` (J, -1 for a root), all in metres:
///   0-2  the area-weighted unit vertex normal (zero on no non-degenerate face);
///   3    the share of the mesh's vertices in the vertex's connected component (over F's edges):
///        about 0.7 on a procedural body, small on a separate hair strand or skirt;
///   4    the distance to the nearest bone segment (joint to parent), divided by the height;
///   5    the distance to the nearest vertex of the largest connected component (0 on it), divided
///        by the height: where a separate piece hangs from the body.
/// The height is the Y extent of V, the segmenter's own normalisation (models/pointnet.h,
/// character_frame). Throws amt::Error on an empty V, a mesh that validate_mesh rejects, joints and
/// parents of different counts or a parent out of range.
MatrixXfR segmentation_features(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints,
                                const std::vector<int32_t>& parents);

// === Features that do not depend on how the mesh is split into parts

/// Vertices nearer than this (metres) are one point for welded_segmentation_features: a real model's
/// parts duplicate their seam vertices (material and UV splits), a millimetre apart at most.
inline constexpr float kWeldTolerance = 1e-3f;

/// weld (N): for each vertex of V (N, 3) the smallest index of the vertices it is welded to, the
/// vertices chained by distances <= tolerance (metres, >= 0; 0 welds exactly coincident vertices).
std::vector<int32_t> weld_vertices(const MatrixX3f& V, float tolerance = kWeldTolerance);

/// The same columns as segmentation_features(), computed on the welded mesh (weld_vertices): the
/// mesh's vertices within `tolerance` are one point, so a surface cut into open parts that duplicate
/// their seam vertices gives the same values as the closed surface:
///   0-2  the area-weighted unit normal summed over the faces of every copy of the point;
///   3    the share of the welded points in the point's connected part;
///   4    the distance to the nearest bone segment over the height (as segmentation_features);
///   5    the distance to the nearest point of the largest welded part over the height.
/// Same errors as segmentation_features, and on a tolerance < 0.
MatrixXfR welded_segmentation_features(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints,
                                       const std::vector<int32_t>& parents, float tolerance = kWeldTolerance);

/// The features an ApparelSegmenter with options.inputs `inputs` reads: "shape" segmentation_features,
/// "welded" welded_segmentation_features; (N, 0) for "positions". Throws amt::Error on another name.
MatrixXfR segmenter_input_features(const std::string& inputs, const MatrixX3f& V, const MatrixX3i& F,
                                   const MatrixX3f& joints, const std::vector<int32_t>& parents);

}  // namespace amt
