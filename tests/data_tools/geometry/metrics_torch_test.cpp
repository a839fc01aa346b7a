// The tensor metrics agree with the Eigen ones and with hand-computed values.
#include "data_tools/geometry/metrics_torch.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "data_tools/geometry/mesh.h"

namespace amt {
namespace {

TEST(MetricsTorch, AgreesWithEigenOnRandomFrames) {
  at::manual_seed(1);
  const int64_t T = 4, N = 30;
  const at::Tensor gt = at::randn({T, N, 3});
  const at::Tensor pred = gt + 0.02 * at::randn({T, N, 3});
  // A strip of triangles (i, i+1, i+2) for edges.
  MatrixX3i F(N - 2, 3);
  for (int i = 0; i < N - 2; ++i) F.row(i) << i, i + 1, i + 2;
  const MatrixX2i E = unique_edges(F);
  const at::Tensor edges = at::from_blob(const_cast<int32_t*>(E.data()), {E.rows(), 2}, at::kInt).to(at::kLong);
  std::vector<uint8_t> mask(N);
  for (int i = 0; i < N; ++i) mask[i] = i % 3 == 0;
  const at::Tensor mask_t = at::from_blob(mask.data(), {N}, at::kByte).to(at::kBool);

  double pmd = 0, pmd_a = 0, els = 0;
  for (int64_t t = 0; t < T; ++t) {
    const at::Tensor p = pred[t].contiguous(), g = gt[t].contiguous();
    const MatrixX3f pe = Eigen::Map<const MatrixX3f>(p.data_ptr<float>(), N, 3);
    const MatrixX3f ge = Eigen::Map<const MatrixX3f>(g.data_ptr<float>(), N, 3);
    pmd += point_mesh_distance_cm(pe, ge) / T;
    pmd_a += point_mesh_distance_cm(pe, ge, &mask, 1) / T;
    els += edge_length_score(pe, ge, E) / T;
  }
  EXPECT_NEAR(point_mesh_distance_cm(pred, gt).item<double>(), pmd, 1e-4);
  EXPECT_NEAR(point_mesh_distance_cm(pred, gt, mask_t).item<double>(), pmd_a, 1e-4);
  EXPECT_NEAR(edge_length_score(pred, gt, edges).item<double>(), els, 1e-5);
}

TEST(MetricsTorch, KnownOffsetAndSegmentation) {
  const at::Tensor gt = at::zeros({2, 5, 3});
  const at::Tensor pred = gt.clone();
  pred.select(2, 1).fill_(0.07);  // every vertex 7 cm up
  EXPECT_NEAR(point_mesh_distance_cm(pred, gt).item<double>(), 7.0, 1e-4);
  const at::Tensor prob = at::tensor({0.9f, 0.8f, 0.2f, 0.6f});
  const at::Tensor truth = at::tensor({1, 1, 0, 0});
  const SegmentationScores s = segmentation_scores(prob, truth);  // TP 2, FP 1, FN 0
  EXPECT_NEAR(s.iou, 2.0 / 3.0, 1e-12);
  EXPECT_NEAR(s.f1, 4.0 / 5.0, 1e-12);
}

}  // namespace
}  // namespace amt
