#include "data_tools/geometry/metrics_torch.h"

#include <ATen/ATen.h>

#include "data_tools/geometry/winding_number.h"

namespace amt {

namespace {
// Adds a leading frame dimension to an (N, 3) tensor.
at::Tensor as_frames(const at::Tensor& x) { return x.dim() == 2 ? x.unsqueeze(0) : x; }
}  // namespace

at::Tensor point_mesh_distance_cm(const at::Tensor& pred, const at::Tensor& gt, const at::Tensor& mask) {
  TORCH_CHECK(pred.sizes() == gt.sizes(), "point_mesh_distance_cm: pred ", pred.sizes(), " and gt ", gt.sizes(),
              " differ");
  at::Tensor d = (as_frames(pred) - as_frames(gt)).norm(2, -1);  // (T, N)
  if (mask.defined()) {
    TORCH_CHECK(mask.dim() == 1 && mask.size(0) == d.size(1), "point_mesh_distance_cm: mask must be (N), got ",
                mask.sizes());
    d = d.index_select(1, mask.to(at::kBool).nonzero().squeeze(1));
  }
  return 100.0 * d.mean(1).mean();
}

at::Tensor edge_length_score(const at::Tensor& pred, const at::Tensor& gt, const at::Tensor& edges) {
  TORCH_CHECK(edges.dim() == 2 && edges.size(1) == 2, "edge_length_score: edges must be (E, 2), got ", edges.sizes());
  const at::Tensor p = as_frames(pred), g = as_frames(gt);
  const at::Tensor i = edges.select(1, 0).to(at::kLong), j = edges.select(1, 1).to(at::kLong);
  const at::Tensor l_pred = (p.index_select(1, i) - p.index_select(1, j)).norm(2, -1);  // (T, E)
  const at::Tensor l_gt = (g.index_select(1, i) - g.index_select(1, j)).norm(2, -1);
  const at::Tensor valid = l_gt > 0;
  const at::Tensor score = at::where(valid, 1.0 - (l_pred / at::where(valid, l_gt, at::ones_like(l_gt)) - 1.0).abs(),
                                     at::zeros_like(l_gt));
  return (score.sum(1) / valid.sum(1)).mean();
}

SegmentationScores segmentation_scores(const at::Tensor& predicted, const at::Tensor& truth) {
  const at::Tensor p = (predicted.scalar_type() == at::kBool ? predicted : predicted > 0.5).to(at::kByte).contiguous();
  const at::Tensor t = truth.to(at::kBool).to(at::kByte).contiguous();
  TORCH_CHECK(p.numel() == t.numel(), "segmentation_scores: predicted has ", p.numel(), " entries, truth ", t.numel());
  const std::vector<uint8_t> pv(p.data_ptr<uint8_t>(), p.data_ptr<uint8_t>() + p.numel());
  const std::vector<uint8_t> tv(t.data_ptr<uint8_t>(), t.data_ptr<uint8_t>() + t.numel());
  return segmentation_scores(pv, tv);
}

Penetration penetration(const at::Tensor& points, const WindingNumberTree& body) {
  TORCH_CHECK(points.dim() == 2 && points.size(1) == 3, "penetration: points must be (P, 3), got ", points.sizes());
  const at::Tensor c = points.detach().to(at::kFloat).contiguous();
  const Eigen::Map<const MatrixX3f> map(c.data_ptr<float>(), c.size(0), 3);
  return penetration(MatrixX3f(map), body);
}

}  // namespace amt
