// The apparel segmenter's shape features on a hand-made mesh with hand-computed values.
#include "data_tools/geometry/segmentation_features.h"

#include <gtest/gtest.h>

#include <cmath>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

// A 1 x 2 quad in z = 0 (the "body", 4 vertices) and a separate triangle at z = 0.5 (a "piece", 3
// vertices), both facing +z; one bone from (0.5, 0, 0) to (0.5, 2, 0). The height (Y extent) is 2.
struct Scene {
  MatrixX3f V{7, 3};
  MatrixX3i F{3, 3};
  MatrixX3f joints{2, 3};
  std::vector<int32_t> parents{-1, 0};
  Scene() {
    V << 0, 0, 0, 1, 0, 0, 1, 2, 0, 0, 2, 0,  // body
        0, 1, 0.5f, 1, 1, 0.5f, 0.5f, 1.5f, 0.5f;  // piece
    F << 0, 1, 2, 0, 2, 3, 4, 5, 6;
    joints << 0.5f, 0, 0, 0.5f, 2, 0;
  }
};

TEST(SegmentationFeatures, HandComputedValues) {
  const Scene s;
  const MatrixXfR X = segmentation_features(s.V, s.F, s.joints, s.parents);
  ASSERT_EQ(X.rows(), 7);
  ASSERT_EQ(X.cols(), kSegmentationFeatures);
  for (int i = 0; i < 7; ++i) {
    EXPECT_NEAR(X(i, 0), 0.0f, 1e-6f);
    EXPECT_NEAR(X(i, 1), 0.0f, 1e-6f);
    EXPECT_NEAR(X(i, 2), 1.0f, 1e-6f);  // +z normals
    EXPECT_FLOAT_EQ(X(i, 3), i < 4 ? 4.0f / 7 : 3.0f / 7);
  }
  // Distance to the bone (x = 0.5, z = 0, y in [0, 2]) over the height 2.
  EXPECT_NEAR(X(0, 4), 0.5f / 2, 1e-6f);
  EXPECT_NEAR(X(2, 4), 0.5f / 2, 1e-6f);
  EXPECT_NEAR(X(4, 4), std::sqrt(0.5f) / 2, 1e-6f);  // (0, 1, 0.5): 0.5 in x and z
  EXPECT_NEAR(X(6, 4), 0.5f / 2, 1e-6f);              // (0.5, 1.5, 0.5): 0.5 in z
  // Distance to the nearest body vertex over the height; zero on the body.
  for (int i = 0; i < 4; ++i) EXPECT_EQ(X(i, 5), 0.0f);
  EXPECT_NEAR(X(4, 5), std::sqrt(1.25f) / 2, 1e-6f);  // (0, 1, 0.5) to (0, 0, 0) or (0, 2, 0)
  EXPECT_NEAR(X(5, 5), std::sqrt(1.25f) / 2, 1e-6f);
  EXPECT_NEAR(X(6, 5), std::sqrt(0.75f) / 2, 1e-6f);  // (0.5, 1.5, 0.5) to (0, 2, 0)
}

TEST(SegmentationFeatures, InvariantToTranslationAndScale) {
  Scene s;
  const MatrixXfR X = segmentation_features(s.V, s.F, s.joints, s.parents);
  const Eigen::RowVector3f shift(3.0f, -1.0f, 2.0f);
  MatrixX3f V2 = (s.V * 1.7f).rowwise() + shift, J2 = (s.joints * 1.7f).rowwise() + shift;
  EXPECT_LT((segmentation_features(V2, s.F, J2, s.parents) - X).cwiseAbs().maxCoeff(), 1e-5f);
}

TEST(SegmentationFeatures, RootOnlyJointsMeasureToTheJoints) {
  Scene s;
  const MatrixXfR X = segmentation_features(s.V, s.F, s.joints, {-1, -1});
  EXPECT_NEAR(X(1, 4), 0.5f / 2, 1e-6f);                 // (1, 0, 0) to (0.5, 0, 0)
  EXPECT_NEAR(X(4, 4), std::sqrt(1.5f) / 2, 1e-6f);       // (0, 1, 0.5) to either joint
}

TEST(SegmentationFeatures, BadInputIsNamed) {
  const Scene s;
  auto message = [&](const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints, std::vector<int32_t> parents) {
    try {
      segmentation_features(V, F, joints, parents);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message(s.V, s.F, s.joints, {-1}), "segmentation features: parents: expected 2 (one per joint), found 1");
  EXPECT_EQ(message(s.V, s.F, s.joints, {-1, 2}),
            "segmentation features: parents: expected -1 or a joint in [0, 2), found 2 for joint 1");
  MatrixX3f bad_joints = s.joints;
  bad_joints(1, 1) = NAN;
  EXPECT_EQ(message(s.V, s.F, bad_joints, s.parents),
            "segmentation features: joints: expected finite positions, found joint 1 at 0.5 nan 0");
  EXPECT_EQ(message(s.V, MatrixX3i(0, 3), s.joints, s.parents),
            "segmentation features: faces: expected at least 1 triangle, found none");
}

// === Welded features

// A closed octahedron (6 vertices: +x, -x, +y, -y, +z, -z at distance 0.5 around (0, 1, 0)) and a
// separate triangle beside it; one bone from (0, 0.5, 0) to (0, 1.5, 0).
struct Octahedron {
  MatrixX3f V{9, 3};
  MatrixX3i F{9, 3};
  MatrixX3f joints{2, 3};
  std::vector<int32_t> parents{-1, 0};
  Octahedron() {
    V << 0.5f, 1, 0, -0.5f, 1, 0, 0, 1.5f, 0, 0, 0.5f, 0, 0, 1, 0.5f, 0, 1, -0.5f,  // octahedron
        1, 1, 0, 1.2f, 1, 0, 1.1f, 1.2f, 0;                                         // piece
    F << 0, 2, 4, 4, 2, 1, 1, 2, 5, 5, 2, 0,  // top half (around +y)
        0, 4, 3, 4, 1, 3, 1, 5, 3, 5, 0, 3,   // bottom half (around -y)
        6, 7, 8;
    joints << 0, 0.5f, 0, 0, 1.5f, 0;
  }
};

TEST(WeldedSegmentationFeatures, InvariantToSplittingIntoOpenPartsWithDuplicatedSeams) {
  const Octahedron s;
  // The same surface as two open parts: the bottom half gets its own copies of the four equator
  // vertices (0, 1, 4, 5 -> 9, 10, 11, 12), so its seam is an open boundary of each part.
  MatrixX3f V2(13, 3);
  V2.topRows(9) = s.V;
  const int copies[4] = {0, 1, 4, 5};
  std::vector<int> source{0, 1, 2, 3, 4, 5, 6, 7, 8};
  for (int k = 0; k < 4; ++k) V2.row(9 + k) = s.V.row(copies[k]), source.push_back(copies[k]);
  MatrixX3i F2 = s.F;
  const auto copy_of = [&](int v) {
    for (int k = 0; k < 4; ++k)
      if (copies[k] == v) return 9 + k;
    return v;
  };
  for (int f = 4; f < 8; ++f)
    for (int k = 0; k < 3; ++k) F2(f, k) = copy_of(s.F(f, k));
  // As given, the split mesh's parts differ: the old features see two halves.
  const MatrixXfR split_shape = segmentation_features(V2, F2, s.joints, s.parents);
  EXPECT_NEAR(split_shape(3, 3), 5.0f / 13.0f, 1e-6f);  // -y tip: the bottom half's 5 of 13 vertices

  const MatrixXfR closed = welded_segmentation_features(s.V, s.F, s.joints, s.parents);
  const MatrixXfR split = welded_segmentation_features(V2, F2, s.joints, s.parents);
  for (int i = 0; i < 13; ++i)
    for (int c = 0; c < kSegmentationFeatures; ++c)
      EXPECT_NEAR(split(i, c), closed(source[size_t(i)], c), 1e-6f) << "vertex " << i << " column " << c;
  // Hand values on the closed mesh: the octahedron is 6 of 9 points, the piece 3; the +x tip's
  // normal is +x; the piece is 0.5 from the +x tip over a height (Y extent) of 1.
  EXPECT_NEAR(closed(0, 3), 6.0f / 9.0f, 1e-6f);
  EXPECT_NEAR(closed(6, 3), 3.0f / 9.0f, 1e-6f);
  EXPECT_NEAR(closed(0, 0), 1.0f, 1e-6f);
  EXPECT_NEAR(closed(0, 5), 0.0f, 1e-6f);
  EXPECT_NEAR(closed(6, 5), 0.5f, 1e-6f);
  EXPECT_NEAR(closed(6, 4), 1.0f, 1e-6f);  // 1 from the bone along x
  // And the closed mesh has no coincident vertices: its welded features are the old ones.
  EXPECT_LT((closed - segmentation_features(s.V, s.F, s.joints, s.parents)).cwiseAbs().maxCoeff(), 1e-5f);
}

TEST(WeldedSegmentationFeatures, WeldsVerticesWithinTheTolerance) {
  MatrixX3f V(4, 3);
  V << 0, 0, 0, 0.0009f, 0, 0, 0.0018f, 0, 0, 0.01f, 0, 0;  // a chain of 0.9 mm steps, then 8.2 mm away
  EXPECT_EQ(weld_vertices(V), (std::vector<int32_t>{0, 0, 0, 3}));
  EXPECT_EQ(weld_vertices(V, 0.0f), (std::vector<int32_t>{0, 1, 2, 3}));
  EXPECT_THROW(weld_vertices(V, -1.0f), Error);
  EXPECT_THROW(segmenter_input_features("colours", V, MatrixX3i(0, 3), MatrixX3f(0, 3), {}), Error);
}

}  // namespace
}  // namespace amt
