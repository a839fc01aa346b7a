#include "data_tools/geometry/handle_fit.h"

#include <gtest/gtest.h>

#include <cmath>

#include "data_tools/geometry/error.h"
#include "tests/test_support.h"

namespace amt {
namespace {

// A 6 by 3 grid of vertices 2 cm apart in the x-y plane (a strip of cloth), two handles at vertices 0 and 17:
// each vertex weighted by both, linearly along x.
struct Strip {
  MatrixX3f V;
  HandleSkin skin;
};

Strip make_strip() {
  Strip s;
  s.V.resize(18, 3);
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 3; ++j) s.V.row(i * 3 + j) << 0.02f * float(i), -0.02f * float(j), 0.0f;
  }
  s.skin.vertices.resize(18);
  s.skin.handles.resize(18, 2);
  s.skin.weights.resize(18, 2);
  for (int v = 0; v < 18; ++v) {
    s.skin.vertices[size_t(v)] = v;
    const float a = float(v / 3) / 5.0f;
    s.skin.handles.row(v) << 0, 1;
    s.skin.weights.row(v) << 1.0f - a, a;
  }
  s.skin.rest.resize(2, 3);
  s.skin.rest.row(0) = s.V.row(0);
  s.skin.rest.row(1) = s.V.row(17);
  return s;
}

Quaternions identities(int n) {
  return Quaternions(size_t(n), Eigen::Quaternionf::Identity());
}

TEST(HandleFit, ARigidlyMovedStripGivesBothHandlesItsRotationAndPositionsExactly) {
  const Strip s = make_strip();
  const HandleFit fit(s.V, s.skin);
  const Eigen::Matrix3f R = Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3f t(0.3f, -0.1f, 0.05f);
  MatrixX3f Y = (s.V * R.transpose()).rowwise() + t.transpose();
  Quaternions rotations;
  MatrixX3f positions;
  fit.fit(Y, identities(2), rotations, positions);
  for (int h = 0; h < 2; ++h) {
    EXPECT_LT((rotations[size_t(h)].toRotationMatrix() - R).norm(), 1e-5f) << h;
    const Eigen::Vector3f expected = R * s.skin.rest.row(h).transpose() + t;
    EXPECT_LT((positions.row(h).transpose() - expected).norm(), 1e-6f) << h;
  }
  MatrixX3f X = MatrixX3f::Zero(18, 3);
  fit.skin_vertices(rotations, positions, X);
  EXPECT_LT((X - Y).cwiseAbs().maxCoeff(), 1e-6f);
}

TEST(HandleFit, HandleOffsetsAsTheLearnedModuleMakesThemAreReproducedExactly) {
  // y_v = p_v + sum_k w_vk d_k: the handle form of the apparel module under a still anchor.
  const Strip s = make_strip();
  const HandleFit fit(s.V, s.skin);
  const Eigen::Vector3f d0(0.01f, 0.0f, 0.0f), d1(0.0f, -0.03f, 0.04f);
  MatrixX3f Y = s.V;
  for (int v = 0; v < 18; ++v)
    Y.row(v) += s.skin.weights(v, 0) * d0.transpose() + s.skin.weights(v, 1) * d1.transpose();
  Quaternions rotations;
  MatrixX3f positions;
  fit.fit(Y, identities(2), rotations, positions);
  MatrixX3f X = MatrixX3f::Zero(18, 3);
  fit.skin_vertices(rotations, positions, X);
  // Kabsch would turn the stretched regions; the anchor's rotation (the identity here) fits them exactly.
  EXPECT_LT((X - Y).rowwise().norm().maxCoeff(), 1e-6f);
  EXPECT_LT(rotations[0].angularDistance(Eigen::Quaternionf::Identity()), 1e-6f);
}

TEST(HandleFit, AHandleWhoseVerticesLieOnALineTakesTheFallbackRotation) {
  MatrixX3f V(3, 3);
  V << 0, 0, 0, 0.02f, 0, 0, 0.04f, 0, 0;
  HandleSkin skin;
  skin.vertices = {0, 1, 2};
  skin.handles = decltype(skin.handles)::Zero(3, 1);
  skin.weights = MatrixXfR::Ones(3, 1);
  skin.rest = V.topRows(1);
  const HandleFit fit(V, skin);
  const Eigen::Quaternionf fallback(Eigen::AngleAxisf(0.5f, Eigen::Vector3f::UnitY()));
  // Step 1 alone: points on a line leave the rotation about it free, so Kabsch must not pick one.
  Quaternions rotations;
  MatrixX3f Y = V;
  Y.col(1).array() += 0.1f;
  fit.kabsch(Y, Quaternions{fallback}, rotations);
  EXPECT_LT(rotations[0].angularDistance(fallback), 1e-6f);
}

TEST(HandleFit, ASkinOfTheWrongShapeOrWeightsIsAOneLineError) {
  Strip s = make_strip();
  s.skin.handles(4, 1) = 7;
  EXPECT_NE(test::error_of([&] { HandleFit(s.V, s.skin); }).find("expected indices in [0, 2), found 7 at vertex 4"),
            std::string::npos);
  s = make_strip();
  s.skin.weights.row(2).setZero();
  EXPECT_NE(test::error_of([&] { HandleFit(s.V, s.skin); }).find("found none at vertex 2"), std::string::npos);
  s = make_strip();
  s.skin.weights(3, 0) = -1.0f;
  EXPECT_NE(test::error_of([&] { HandleFit(s.V, s.skin); }).find("non-negative"), std::string::npos);
}

TEST(FitError, QuantilesAndMaxOfHandMadeDistances) {
  // Distances 1, 2, ..., 100 mm along x.
  MatrixX3f A = MatrixX3f::Zero(100, 3), B = MatrixX3f::Zero(100, 3);
  for (int i = 0; i < 100; ++i) B(i, 0) = 0.001f * float(i + 1);
  FitError e;
  e.add(A, B);
  EXPECT_EQ(e.count(), 100);
  EXPECT_NEAR(e.quantile(0.95), 0.095, 2e-5);
  EXPECT_NEAR(e.quantile(0.5), 0.050, 2e-5);
  EXPECT_NEAR(e.max(), 0.100, 1e-7);
  FitError rows;
  rows.add(A, B, {0, 9});
  EXPECT_EQ(rows.count(), 2);
  EXPECT_NEAR(rows.max(), 0.010, 1e-7);
}

}  // namespace
}  // namespace amt
