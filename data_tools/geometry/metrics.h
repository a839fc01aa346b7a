#pragma once
// Evaluation metrics of docs/evaluation.md, "Metrics" (paper 5.3): PMD, PMD_a, PMD_b (cm), the edge length
// score ELS, body-apparel penetration, and apparel segmentation IoU / F1. The same measures on
// torch tensors are in data_tools/geometry/metrics_torch.h.
#include <vector>

#include "data_tools/geometry/types.h"

namespace amt {

class WindingNumberTree;

// === Per-frame measures

/// Point-wise mesh Euclidean distance of one frame, in centimetres: the mean of |pred_i - gt_i|
/// over the vertices i with mask[i] == keep (all vertices when mask is null). pred, gt #V by 3
/// (metres). No alignment or centring. Returns NaN when no vertex is selected.
double point_mesh_distance_cm(const MatrixX3f& pred, const MatrixX3f& gt, const std::vector<uint8_t>* mask = nullptr,
                              uint8_t keep = 1);

/// Edge length score of one frame: mean over edges E (#E by 2) of 1 - | |e_pred| / |e_gt| - 1 |,
/// with e_gt the same edge on the ground-truth mesh of the frame. Edges of zero ground-truth length
/// are skipped. 1 is perfect. Returns NaN when no edge counts.
double edge_length_score(const MatrixX3f& pred, const MatrixX3f& gt, const MatrixX2i& E);

/// Penetration of points (e.g. posed apparel vertices) into a closed body surface.
struct Penetration {
  int inside = 0;            // points with winding number > 0.5
  int total = 0;             // points tested
  double depth_sum_cm = 0;   // sum of the inside points' distances to the body surface
  /// Share of points inside, in [0, 1] (0 for no points).
  double share() const { return total > 0 ? static_cast<double>(inside) / total : 0.0; }
  /// Mean depth of the inside points in cm (0 when none is inside).
  double mean_depth_cm() const { return inside > 0 ? depth_sum_cm / inside : 0.0; }
};

/// Tests every row of points (#P by 3, metres) against the body's winding-number tree (OpenMP).
Penetration penetration(const MatrixX3f& points, const WindingNumberTree& body);

/// Binary segmentation quality of a predicted apparel mask against the ground truth (1 = apparel).
struct SegmentationScores {
  double iou = 0, f1 = 0, precision = 0, recall = 0;
};

/// IoU, F1, precision and recall of the apparel class; both masks #V entries of 0 or 1. When
/// neither mask has apparel the prediction is perfect (all scores 1).
SegmentationScores segmentation_scores(const std::vector<uint8_t>& predicted, const std::vector<uint8_t>& truth);

// === Aggregation over a test set

/// Scores of a set of clips, each averaged over vertices, then frames, then clips (section 5).
struct MotionScores {
  double pmd = 0, pmd_a = 0, pmd_b = 0;  // cm; NaN when no clip had such vertices
  double els = 0;
  double penetration_share = 0;         // share of apparel vertices inside the body
  double penetration_depth_cm = 0;      // mean depth of the penetrating apparel vertices
  int clips = 0, frames = 0;
};

/// Accumulates frames clip by clip: begin_clip(), add_frame() per frame, end_clip(); result().
class ScoreAccumulator {
 public:
  void begin_clip();
  /// Adds one frame: pred, gt #V by 3 (metres); apparel_mask #V (1 = apparel) splits PMD_a and
  /// PMD_b; E the mesh's unique edges for ELS; penetration of the frame's apparel vertices if measured.
  void add_frame(const MatrixX3f& pred, const MatrixX3f& gt, const std::vector<uint8_t>& apparel_mask,
                 const MatrixX2i& E, const Penetration* penetration = nullptr);
  void end_clip();
  /// The averages over the finished clips.
  MotionScores result() const;

 private:
  struct Sum {
    double value = 0;
    int count = 0;
    void add(double v) {
      if (v == v) value += v, ++count;  // NaN (nothing selected) does not count
    }
    double mean() const;
  };
  // Frame-level sums of the current clip.
  Sum frame_pmd_, frame_pmd_a_, frame_pmd_b_, frame_els_, frame_share_;
  Penetration clip_penetration_;
  int clip_frames_ = 0;
  // Clip-level sums.
  Sum pmd_, pmd_a_, pmd_b_, els_, share_, depth_;
  int clips_ = 0, frames_ = 0;
};

}  // namespace amt
