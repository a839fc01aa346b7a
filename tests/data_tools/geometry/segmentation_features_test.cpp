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

}  // namespace
}  // namespace amt
