// The segmenter's training variants on a hand-made character.
#include "data_tools/builder/segmenter_augmentation.h"

#include <gtest/gtest.h>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/segmentation_features.h"
#include "data_tools/geometry/skeleton.h"

namespace amt {
namespace {

// A pelvis at the origin with a left hip at +x and a right hip at -x (the canonical convention: the
// character's left on +X). Two triangles facing +z: one around the left hip (vertices 0-2, weighted
// to left_hip, apparel) and one around the right hip (vertices 3-5, weighted to right_hip, body).
SegmenterExample hips() {
  SegmenterExample e;
  e.skeleton.names = {"pelvis", "left_hip", "right_hip"};
  e.skeleton.parents = {-1, 0, 0};
  e.skeleton.rest_joints.resize(3, 3);
  e.skeleton.rest_joints << 0, 1, 0, 0.1f, 0.9f, 0, -0.1f, 0.9f, 0;
  e.mesh.V.resize(6, 3);
  e.mesh.V << 0.05f, 0.85f, 0, 0.15f, 0.85f, 0, 0.1f, 0.95f, 0,  // left
      -0.15f, 0.85f, 0, -0.05f, 0.85f, 0, -0.1f, 0.95f, 0;       // right
  e.mesh.F.resize(2, 3);
  e.mesh.F << 0, 1, 2, 3, 4, 5;
  e.body_weights = MatrixXfR::Zero(6, 3);
  e.body_weights.block(0, 1, 3, 1).setOnes();
  e.body_weights.block(3, 2, 3, 1).setOnes();
  e.apparel_mask = {1, 1, 1, 0, 0, 0};
  return e;
}

TEST(SegmenterAugmentation, MirrorNamesJoints) {
  EXPECT_EQ(mirrored_joint_name("left_hip"), "right_hip");
  EXPECT_EQ(mirrored_joint_name("right_wrist"), "left_wrist");
  EXPECT_EQ(mirrored_joint_name("spine1"), "spine1");
}

TEST(SegmenterAugmentation, MirrorMapsTheLeftJointsVerticesToTheRightAndCarriesTheMask) {
  const SegmenterExample e = hips();
  const SegmenterExample m = mirrored_example(e);
  ASSERT_EQ(m.mesh.num_vertices(), 6);
  // The left triangle is now on -x, about the right hip's (unchanged) position, weighted to right_hip.
  const int right = m.skeleton.index_of("right_hip"), left = m.skeleton.index_of("left_hip");
  EXPECT_EQ(m.skeleton.names, e.skeleton.names);
  EXPECT_EQ(m.skeleton.parents, e.skeleton.parents);
  EXPECT_LT((m.skeleton.rest_joints - e.skeleton.rest_joints).cwiseAbs().maxCoeff(), 1e-7f);
  for (int v = 0; v < 3; ++v) {
    EXPECT_FLOAT_EQ(m.mesh.V(v, 0), -e.mesh.V(v, 0));
    EXPECT_FLOAT_EQ(m.body_weights(v, right), 1.0f);
    EXPECT_FLOAT_EQ(m.body_weights(v, left), 0.0f);
    EXPECT_EQ(m.apparel_mask[size_t(v)], 1);
  }
  const Eigen::RowVector3f centre = m.mesh.V.topRows(3).colwise().mean();
  EXPECT_LT((centre - m.skeleton.rest_joints.row(right)).norm(), 0.06f);
  for (int v = 3; v < 6; ++v) {
    EXPECT_FLOAT_EQ(m.body_weights(v, left), 1.0f);
    EXPECT_EQ(m.apparel_mask[size_t(v)], 0);
  }
  // The winding is reversed, so the normals stay the mirror images of the original ones (+z here),
  // and the welded features are the original's with x of the normal negated.
  const MatrixXfR X = welded_segmentation_features(e.mesh.V, e.mesh.F, e.skeleton.rest_joints, e.skeleton.parents);
  const MatrixXfR Xm = welded_segmentation_features(m.mesh.V, m.mesh.F, m.skeleton.rest_joints, m.skeleton.parents);
  MatrixXfR expected = X;
  expected.col(0) = -X.col(0);
  EXPECT_LT((Xm - expected).cwiseAbs().maxCoeff(), 1e-6f);
  EXPECT_FLOAT_EQ(Xm(0, 2), 1.0f);
}

TEST(SegmenterAugmentation, MirrorNeedsTheMirrorJoints) {
  SegmenterExample e = hips();
  e.skeleton.names[2] = "tail";
  EXPECT_THROW(mirrored_example(e), Error);
}

TEST(SegmenterAugmentation, BareBodyKeepsTheLargestPartWithAnAllZeroMask) {
  SegmenterExample e = hips();
  // Make the right (body) triangle the larger part: a second face on it.
  e.mesh.V.conservativeResize(7, 3);
  e.mesh.V.row(6) << -0.1f, 0.8f, 0;
  e.mesh.F.conservativeResize(3, 3);
  e.mesh.F.row(2) << 3, 6, 4;
  e.body_weights.conservativeResize(7, 3);
  e.body_weights.row(6) << 0, 0, 1;
  e.apparel_mask.push_back(0);
  const SegmenterExample bare = bare_body_example(e);
  ASSERT_EQ(bare.mesh.num_vertices(), 4);
  EXPECT_EQ(bare.mesh.num_faces(), 2);
  EXPECT_EQ(bare.apparel_mask, (std::vector<uint8_t>(4, 0)));
  EXPECT_FLOAT_EQ(bare.mesh.V(0, 0), -0.15f);
  EXPECT_FLOAT_EQ(bare.body_weights(3, 2), 1.0f);
}

TEST(SegmenterAugmentation, OpenPartsNeedTheCanonicalSkeleton) {
  EXPECT_THROW(open_parts_example(hips()), Error);
}

// The builder's layout (what bare_body_example and open_parts_example read the body from): the canonical skeleton and
// the largest part first. An artist's model has neither.
TEST(SegmenterAugmentation, BuilderLayoutIsTheCanonicalSkeletonWithTheLargestPartFirst) {
  SegmenterExample e = hips();
  EXPECT_FALSE(builder_layout(e));  // three joints of its own
  const auto& names = canonical_joint_names();
  e.skeleton.names.assign(names.begin(), names.end());
  // Two parts of one face each: a tie, and the first part counts as the largest.
  EXPECT_TRUE(builder_layout(e));
  // A second face on the right triangle makes it the largest part: the body no longer comes first.
  e.mesh.V.conservativeResize(7, 3);
  e.mesh.V.row(6) << -0.1f, 0.8f, 0;
  e.mesh.F.conservativeResize(3, 3);
  e.mesh.F.row(2) << 3, 6, 4;
  EXPECT_FALSE(builder_layout(e));
  // The same mesh with the larger part moved to the front (faces renumbered) is in the builder's layout.
  SegmenterExample front = e;
  const int order[7] = {3, 4, 5, 6, 0, 1, 2};  // new vertex k is old vertex order[k]
  int place[7];
  for (int k = 0; k < 7; ++k) front.mesh.V.row(k) = e.mesh.V.row(order[k]), place[order[k]] = k;
  for (int f = 0; f < 3; ++f)
    for (int c = 0; c < 3; ++c) front.mesh.F(f, c) = place[e.mesh.F(f, c)];
  EXPECT_TRUE(builder_layout(front));
  EXPECT_FALSE(builder_layout(SegmenterExample{}));
}

}  // namespace
}  // namespace amt
