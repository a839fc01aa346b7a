// Metrics on meshes with known offsets and edge stretches, worked out by hand.
#include "data_tools/geometry/metrics.h"

#include <gtest/gtest.h>

#include <cmath>

#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/winding_number.h"

namespace amt {
namespace {

// A 2-triangle unit square in the XY plane (4 vertices, 5 edges); vertices 2, 3 are "apparel".
TriMesh square() {
  TriMesh m;
  m.V.resize(4, 3);
  m.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;
  m.F.resize(2, 3);
  m.F << 0, 1, 2, 0, 2, 3;
  return m;
}

TEST(Metrics, PmdSplitsApparelAndBody) {
  const TriMesh m = square();
  MatrixX3f pred = m.V;
  pred.row(2) += Eigen::RowVector3f(0.03f, 0, 0);  // 3 cm
  pred.row(3) += Eigen::RowVector3f(0, 0, 0.05f);  // 5 cm
  const std::vector<uint8_t> mask = {0, 0, 1, 1};
  EXPECT_NEAR(point_mesh_distance_cm(pred, m.V), (3.0 + 5.0) / 4, 1e-5);
  EXPECT_NEAR(point_mesh_distance_cm(pred, m.V, &mask, 1), 4.0, 1e-5);
  EXPECT_NEAR(point_mesh_distance_cm(pred, m.V, &mask, 0), 0.0, 1e-9);
  const std::vector<uint8_t> none = {0, 0, 0, 0};
  EXPECT_TRUE(std::isnan(point_mesh_distance_cm(pred, m.V, &none, 1)));
}

TEST(Metrics, ElsOfUniformStretchAndRigidMotion) {
  const TriMesh m = square();
  const MatrixX2i E = unique_edges(m.F);
  ASSERT_EQ(E.rows(), 5);
  // Every edge 10 % longer: 1 - |1.1 - 1| = 0.9.
  EXPECT_NEAR(edge_length_score(m.V * 1.1f, m.V, E), 0.9, 1e-6);
  // A rigid motion keeps every edge: perfect score.
  const Eigen::Matrix3f R = Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 2, 3).normalized()).toRotationMatrix();
  MatrixX3f moved = (m.V * R.transpose()).rowwise() + Eigen::RowVector3f(1, 2, 3);
  EXPECT_NEAR(edge_length_score(moved, m.V, E), 1.0, 1e-6);
  // Move vertex 1 to x = 2: edge 0-1 doubles (score 0), edge 1-2 becomes sqrt(2) long (score
  // 2 - sqrt 2); edges 0-2, 0-3 and 2-3 keep their lengths (score 1 each).
  MatrixX3f stretched = m.V;
  stretched(1, 0) = 2;
  const double expected = (0.0 + (2 - std::sqrt(2.0)) + 1 + 1 + 1) / 5;
  EXPECT_NEAR(edge_length_score(stretched, m.V, E), expected, 1e-6);
}

TEST(Metrics, SegmentationScoresByHand) {
  // truth: 4 apparel of 8; prediction: 3 of them plus 1 body vertex. TP 3, FP 1, FN 1.
  const std::vector<uint8_t> truth = {1, 1, 1, 1, 0, 0, 0, 0};
  const std::vector<uint8_t> pred = {1, 1, 1, 0, 1, 0, 0, 0};
  const SegmentationScores s = segmentation_scores(pred, truth);
  EXPECT_NEAR(s.iou, 3.0 / 5.0, 1e-12);
  EXPECT_NEAR(s.f1, 6.0 / 8.0, 1e-12);
  EXPECT_NEAR(s.precision, 0.75, 1e-12);
  EXPECT_NEAR(s.recall, 0.75, 1e-12);
}

TEST(Metrics, PenetrationIntoAUnitCube) {
  TriMesh cube;
  cube.V.resize(8, 3);
  cube.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1;
  cube.F.resize(12, 3);
  cube.F << 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 2, 3, 7, 2, 7, 6, 1, 2, 6, 1, 6, 5, 0, 4, 7, 0, 7, 3;
  const WindingNumberTree body(cube.V, cube.F);
  MatrixX3f points(4, 3);
  points << 0.5, 0.5, 0.9,  // inside, 10 cm deep
      0.5, 0.98, 0.5,       // inside, 2 cm deep
      0.5, 0.5, 1.2,        // outside
      3, 3, 3;              // outside
  const Penetration p = penetration(points, body);
  EXPECT_EQ(p.inside, 2);
  EXPECT_EQ(p.total, 4);
  EXPECT_NEAR(p.share(), 0.5, 1e-12);
  EXPECT_NEAR(p.mean_depth_cm(), 6.0, 1e-4);
}

TEST(Metrics, AccumulatorAveragesVerticesThenFramesThenClips) {
  const TriMesh m = square();
  const MatrixX2i E = unique_edges(m.F);
  const std::vector<uint8_t> mask = {0, 0, 1, 1};
  ScoreAccumulator acc;
  // Clip 1: two frames with every vertex 1 cm and 3 cm off (PMD 1 and 3: clip mean 2).
  acc.begin_clip();
  for (float off : {0.01f, 0.03f}) acc.add_frame(m.V.array() + off, m.V, mask, E);
  acc.end_clip();
  // Clip 2: one frame, apparel 4 cm off, body exact (PMD 2, PMD_a 4, PMD_b 0).
  acc.begin_clip();
  MatrixX3f pred = m.V;
  pred.bottomRows(2).col(2).array() += 0.04f;
  acc.add_frame(pred, m.V, mask, E);
  acc.end_clip();
  const MotionScores s = acc.result();
  EXPECT_EQ(s.clips, 2);
  EXPECT_EQ(s.frames, 3);
  EXPECT_NEAR(s.pmd, (2.0 * std::sqrt(3.0) + 2.0) / 2, 1e-4);  // clip 1: offsets along all 3 axes
  EXPECT_NEAR(s.pmd_a, (2.0 * std::sqrt(3.0) + 4.0) / 2, 1e-4);
  EXPECT_NEAR(s.pmd_b, (2.0 * std::sqrt(3.0) + 0.0) / 2, 1e-4);
}

}  // namespace
}  // namespace amt
