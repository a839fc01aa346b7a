#include "data_tools/geometry/metrics.h"

#include <cmath>
#include <limits>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/winding_number.h"

namespace amt {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}

double point_mesh_distance_cm(const MatrixX3f& pred, const MatrixX3f& gt, const std::vector<uint8_t>* mask,
                              uint8_t keep) {
  AMT_CHECK(pred.rows() == gt.rows(), "metrics: PMD: expected predicted and ground-truth meshes of the same size, found ",
            pred.rows(), " and ", gt.rows(), " vertices");
  AMT_CHECK(!mask || static_cast<Eigen::Index>(mask->size()) == gt.rows(), "metrics: PMD: expected a mask of ", gt.rows(),
            " entries, found ", mask ? mask->size() : 0);
  double sum = 0;
  Eigen::Index count = 0;
  for (Eigen::Index i = 0; i < gt.rows(); ++i) {
    if (mask && (*mask)[i] != keep) continue;
    sum += (pred.row(i) - gt.row(i)).cast<double>().norm();
    ++count;
  }
  return count > 0 ? 100.0 * sum / count : kNaN;
}

double edge_length_score(const MatrixX3f& pred, const MatrixX3f& gt, const MatrixX2i& E) {
  AMT_CHECK(pred.rows() == gt.rows(), "metrics: ELS: expected predicted and ground-truth meshes of the same size, found ",
            pred.rows(), " and ", gt.rows(), " vertices");
  double sum = 0;
  Eigen::Index count = 0;
  for (Eigen::Index e = 0; e < E.rows(); ++e) {
    const double l_gt = (gt.row(E(e, 0)) - gt.row(E(e, 1))).cast<double>().norm();
    if (l_gt <= 0) continue;
    const double l_pred = (pred.row(E(e, 0)) - pred.row(E(e, 1))).cast<double>().norm();
    sum += 1.0 - std::abs(l_pred / l_gt - 1.0);
    ++count;
  }
  return count > 0 ? sum / count : kNaN;
}

Penetration penetration(const MatrixX3f& points, const WindingNumberTree& body) {
  Penetration out;
  out.total = static_cast<int>(points.rows());
  int inside = 0;
  double depth = 0;
#pragma omp parallel for reduction(+ : inside, depth) schedule(dynamic, 256)
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Eigen::Vector3f p = points.row(i).transpose();
    if (body.inside(p)) {
      ++inside;
      depth += 100.0 * body.distance(p);
    }
  }
  out.inside = inside;
  out.depth_sum_cm = depth;
  return out;
}

SegmentationScores segmentation_scores(const std::vector<uint8_t>& predicted, const std::vector<uint8_t>& truth) {
  AMT_CHECK(predicted.size() == truth.size(), "metrics: segmentation: expected masks of the same size, found ",
            predicted.size(), " and ", truth.size());
  double tp = 0, fp = 0, fn = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    const bool p = predicted[i] != 0, t = truth[i] != 0;
    tp += p && t;
    fp += p && !t;
    fn += !p && t;
  }
  SegmentationScores s;
  if (tp + fp + fn == 0) return {1, 1, 1, 1};
  s.iou = tp / (tp + fp + fn);
  s.f1 = 2 * tp / (2 * tp + fp + fn);
  s.precision = tp + fp > 0 ? tp / (tp + fp) : 0;
  s.recall = tp + fn > 0 ? tp / (tp + fn) : 0;
  return s;
}

double ScoreAccumulator::Sum::mean() const { return count > 0 ? value / count : kNaN; }

void ScoreAccumulator::begin_clip() {
  frame_pmd_ = frame_pmd_a_ = frame_pmd_b_ = frame_els_ = frame_share_ = Sum{};
  clip_penetration_ = Penetration{};
  clip_frames_ = 0;
}

void ScoreAccumulator::add_frame(const MatrixX3f& pred, const MatrixX3f& gt, const std::vector<uint8_t>& apparel_mask,
                                 const MatrixX2i& E, const Penetration* pen) {
  frame_pmd_.add(point_mesh_distance_cm(pred, gt));
  frame_pmd_a_.add(point_mesh_distance_cm(pred, gt, &apparel_mask, 1));
  frame_pmd_b_.add(point_mesh_distance_cm(pred, gt, &apparel_mask, 0));
  frame_els_.add(edge_length_score(pred, gt, E));
  if (pen) {
    frame_share_.add(pen->share());
    clip_penetration_.inside += pen->inside;
    clip_penetration_.total += pen->total;
    clip_penetration_.depth_sum_cm += pen->depth_sum_cm;
  }
  ++clip_frames_;
}

void ScoreAccumulator::end_clip() {
  if (clip_frames_ == 0) return;
  pmd_.add(frame_pmd_.mean());
  pmd_a_.add(frame_pmd_a_.mean());
  pmd_b_.add(frame_pmd_b_.mean());
  els_.add(frame_els_.mean());
  share_.add(frame_share_.mean());
  if (clip_penetration_.inside > 0) depth_.add(clip_penetration_.mean_depth_cm());
  ++clips_;
  frames_ += clip_frames_;
  clip_frames_ = 0;
}

MotionScores ScoreAccumulator::result() const {
  MotionScores s;
  s.pmd = pmd_.mean();
  s.pmd_a = pmd_a_.mean();
  s.pmd_b = pmd_b_.mean();
  s.els = els_.mean();
  s.penetration_share = share_.count > 0 ? share_.mean() : 0.0;
  s.penetration_depth_cm = depth_.count > 0 ? depth_.mean() : 0.0;
  s.clips = clips_;
  s.frames = frames_;
  return s;
}

}  // namespace amt
