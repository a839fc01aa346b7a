#pragma once
// The metrics of data_tools/geometry/metrics.h on torch tensors, for training-time validation and the
// evaluation of batched predictions. Same definitions; results agree with the Eigen forms.
#include <ATen/core/Tensor.h>

#include "data_tools/geometry/metrics.h"

namespace amt {

/// PMD in cm, averaged over the selected vertices of each frame, then over frames:
///   pred, gt (T, N, 3) or (N, 3) metres; mask (N) bool selecting vertices, or undefined for all.
/// Returns a 0-dim tensor (NaN when the mask selects nothing). Differentiable in pred.
at::Tensor point_mesh_distance_cm(const at::Tensor& pred, const at::Tensor& gt, const at::Tensor& mask = {});

/// ELS averaged over edges of each frame, then over frames:
///   pred, gt (T, N, 3) or (N, 3); edges (E, 2) int64. Edges of zero ground-truth length are skipped.
at::Tensor edge_length_score(const at::Tensor& pred, const at::Tensor& gt, const at::Tensor& edges);

/// Segmentation scores of apparel probabilities or a mask: predicted (N) float (thresholded at 0.5)
/// or bool; truth (N) bool or 0/1.
SegmentationScores segmentation_scores(const at::Tensor& predicted, const at::Tensor& truth);

/// Penetration of points (P, 3) float into the body behind `body`.
Penetration penetration(const at::Tensor& points, const WindingNumberTree& body);

}  // namespace amt
