#include "refit/skeleton_shrink.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "data_tools/geometry/error.h"

namespace amt::refit {
namespace {

// A straight chain of 3 bones along x: joints at x = 0, 1, 2, 3.
Positions chain_joints(double scale, double shift) {
  Positions J(4, 3);
  for (int j = 0; j < 4; ++j) J.row(j) << scale * j + shift, 0, 0;
  return J;
}

double point_segment_distance(const Eigen::RowVector3d& p, const Eigen::RowVector3d& a, const Eigen::RowVector3d& b) {
  const Eigen::RowVector3d e = b - a;
  const double t = std::clamp((p - a).dot(e) / e.squaredNorm(), 0.0, 1.0);
  return (p - (a + t * e)).norm();
}

// One avatar triangle around the chain, its corners over the middle of bones 0, 2 and 1.
void one_triangle(Positions* V, MatrixX3i* F) {
  V->resize(3, 3);
  *V << 0.5, 0.3, 0, 2.5, 0, 0.3, 1.5, -0.3, -0.2;
  F->resize(1, 3);
  *F << 0, 1, 2;
}

// Every face of the shrunk avatar lies on one bone of the skeleton `joints`.
void expect_faces_on_bones(const ShrunkAvatar& s, const Positions& joints, const MatrixX2i& bones) {
  for (int f = 0; f < s.F.rows(); ++f) {
    bool on_some_bone = false;
    for (int b = 0; b < bones.rows() && !on_some_bone; ++b) {
      bool all = true;
      for (int k = 0; k < 3; ++k)
        all = all && point_segment_distance(s.shrunk.row(s.F(f, k)), joints.row(bones(b, 0)), joints.row(bones(b, 1))) < 1e-12;
      on_some_bone = all;
    }
    EXPECT_TRUE(on_some_bone) << "face " << f;
  }
}

TEST(SkeletonBones, FromParents) {
  const MatrixX2i bones = skeleton_bones({-1, 0, 1, 1});
  ASSERT_EQ(bones.rows(), 3);
  EXPECT_EQ(bones.row(0), Eigen::RowVector2i(0, 1).cast<int32_t>());
  EXPECT_EQ(bones.row(2), Eigen::RowVector2i(1, 3).cast<int32_t>());
}

TEST(ShrinkToSkeleton, SplitsATriangleSpanningThreeBonesUntilEveryFaceIsOnOneBone) {
  const MatrixX2i bones = skeleton_bones({-1, 0, 1, 2});
  const Positions target_joints = chain_joints(1.0, 0.0), source_joints = chain_joints(2.0, 5.0);
  Positions V;
  MatrixX3i F;
  one_triangle(&V, &F);
  const std::vector<int> vertex_bone = nearest_bones(V, target_joints, bones);
  EXPECT_EQ(vertex_bone, (std::vector<int>{0, 2, 1}));
  const ShrunkAvatar s = shrink_to_skeleton(V, F, target_joints, source_joints, bones, vertex_bone);
  // The avatar's own vertices: at the middle of their bones, carried onto the source skeleton.
  EXPECT_LT((s.shrunk.row(0) - Eigen::RowVector3d(6, 0, 0)).norm(), 1e-12);
  EXPECT_LT((s.shrunk.row(1) - Eigen::RowVector3d(10, 0, 0)).norm(), 1e-12);
  EXPECT_LT((s.shrunk.row(2) - Eigen::RowVector3d(8, 0, 0)).norm(), 1e-12);
  EXPECT_GT(s.F.rows(), 1);
  EXPECT_GT(s.shrunk.rows(), 3);
  EXPECT_LE(s.subdivision_rounds, 4);  // the paper: 2 to 4 passes in practice
  expect_faces_on_bones(s, source_joints, bones);
  // At t = 1 every vertex is on the original triangle: the originals where they were, inserted vertices
  // on its edges; the fans cover the triangle with the same orientation.
  EXPECT_EQ(s.target.topRows(3), V);
  const Eigen::Vector3d n = (V.row(1) - V.row(0)).cross(V.row(2) - V.row(0)).transpose();
  double area = 0;
  for (int f = 0; f < s.F.rows(); ++f) {
    const Eigen::Vector3d a = s.target.row(s.F(f, 0)), b = s.target.row(s.F(f, 1)), c = s.target.row(s.F(f, 2));
    const Eigen::Vector3d nf = (b - a).cross(c - a);
    EXPECT_GE(nf.dot(n), -1e-12) << "face " << f << " flipped";
    area += 0.5 * nf.norm();
  }
  EXPECT_NEAR(area, 0.5 * n.norm(), 1e-12);
  for (int i = 3; i < s.target.rows(); ++i)
    EXPECT_NEAR((s.target.row(i) - V.row(0)).dot(n.transpose()), 0.0, 1e-12) << "vertex " << i << " off the plane";
}

TEST(ShrinkToSkeleton, TrianglesOnOneBoneAreKeptAsTheyAre) {
  const MatrixX2i bones = skeleton_bones({-1, 0, 1, 2});
  const Positions J = chain_joints(1.0, 0.0);
  Positions V(3, 3);
  V << 1.2, 0.3, 0, 1.5, 0, 0.3, 1.8, -0.3, -0.2;
  MatrixX3i F(1, 3);
  F << 0, 1, 2;
  const ShrunkAvatar s = shrink_to_skeleton(V, F, J, J, bones, {1, 1, 1});
  EXPECT_EQ(s.F, F);
  EXPECT_EQ(s.shrunk.rows(), 3);
  EXPECT_EQ(s.subdivision_rounds, 1);
  EXPECT_NEAR(s.shrunk(0, 0), 1.2, 1e-12);
  EXPECT_NEAR(s.shrunk.col(1).cwiseAbs().maxCoeff() + s.shrunk.col(2).cwiseAbs().maxCoeff(), 0.0, 1e-12);
}

TEST(ShrinkToSkeleton, ATubeAroundABentArm) {
  // Shoulder - elbow - wrist - hand tip, bent at the elbow; a tube of 12 rings of 8 vertices around it.
  Positions J(4, 3);
  J << 0, 0, 0, 0.3, 0, 0, 0.3, -0.25, 0, 0.3, -0.35, 0;
  const MatrixX2i bones = skeleton_bones({-1, 0, 1, 2});
  const int rings = 12, around = 8;
  Positions V(rings * around, 3);
  for (int r = 0; r < rings; ++r) {
    const double s = 0.35 * (r + 0.5) / rings * 2;  // arc length along the chain, 0 .. 0.65
    const Eigen::RowVector3d centre = s < 0.3 ? Eigen::RowVector3d(s, 0, 0) : Eigen::RowVector3d(0.3, -(s - 0.3), 0);
    const Eigen::RowVector3d axis_a = s < 0.3 ? Eigen::RowVector3d(0, 1, 0) : Eigen::RowVector3d(1, 0, 0);
    const Eigen::RowVector3d axis_b(0, 0, 1);
    for (int k = 0; k < around; ++k) {
      const double phi = 2 * M_PI * k / around;
      V.row(r * around + k) = centre + 0.04 * (std::cos(phi) * axis_a + std::sin(phi) * axis_b);
    }
  }
  MatrixX3i F(2 * (rings - 1) * around, 3);
  int f = 0;
  for (int r = 0; r + 1 < rings; ++r)
    for (int k = 0; k < around; ++k) {
      const int a = r * around + k, b = r * around + (k + 1) % around, c = a + around, d = b + around;
      F.row(f++) << a, b, d;
      F.row(f++) << a, d, c;
    }
  const ShrunkAvatar s = shrink_to_skeleton(V, F, J, J, bones, nearest_bones(V, J, bones));
  expect_faces_on_bones(s, J, bones);
  EXPECT_LE(s.subdivision_rounds, 4);
  EXPECT_GT(s.F.rows(), F.rows());
  for (int i = 0; i < V.rows(); ++i) EXPECT_EQ(s.target.row(i), V.row(i));
}

TEST(ShrinkToSkeleton, BonesTheSkeletonDoesNotConnectAreAnError) {
  // Two separate chains (parents -1 twice): a triangle spanning both cannot be shrunk.
  Positions J(4, 3);
  J << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0;
  const MatrixX2i bones = skeleton_bones({-1, 0, -1, 2});
  Positions V(3, 3);
  V << 0.5, 0, 0.1, 0.5, 1, 0.1, 0.6, 0.5, 0.2;
  MatrixX3i F(1, 3);
  F << 0, 1, 2;
  try {
    shrink_to_skeleton(V, F, J, J, bones, {0, 1, 0});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("which the skeleton does not connect"), std::string::npos) << e.what();
  }
}

TEST(ShrinkToSkeleton, BadInputIsAnError) {
  const MatrixX2i bones = skeleton_bones({-1, 0, 1, 2});
  const Positions J = chain_joints(1.0, 0.0);
  Positions V;
  MatrixX3i F;
  one_triangle(&V, &F);
  auto message = [&](auto&& f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message([&] { shrink_to_skeleton(V, F, J, J, bones, {0, 7, 1}); }).find("vertex 1 has bone 7"),
            std::string::npos);
  EXPECT_NE(message([&] { shrink_to_skeleton(V, F, J, J.topRows(3), bones, {0, 2, 1}); }).find("source skeleton"),
            std::string::npos);
  Positions flat = J;
  flat.row(2) = flat.row(1);
  EXPECT_NE(message([&] { shrink_to_skeleton(V, F, flat, J, bones, {0, 2, 1}); }).find("zero length"),
            std::string::npos);
}

}  // namespace
}  // namespace amt::refit
