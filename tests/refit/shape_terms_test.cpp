// The garment refit's shape objectives: surface shape (surface_shape.h) and positional (positional.h).
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>

#include "data_tools/geometry/error.h"
#include "finite_difference.h"
#include "test_meshes.h"
#include "refit/curve_shape.h"
#include "refit/positional.h"
#include "refit/skeleton_shrink.h"
#include "refit/surface_shape.h"

namespace amt::refit {
namespace {

// A bumpy n by n sheet (non-coplanar neighbours everywhere), side 1, in the xz plane.
void bumpy_sheet(int n, Positions* V, MatrixX3i* F) {
  V->resize(n * n, 3);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double x = double(j) / (n - 1), z = double(i) / (n - 1);
      V->row(i * n + j) << x, 0.1 * std::sin(5 * x) * std::cos(4 * z), z;
    }
  F->resize(2 * (n - 1) * (n - 1), 3);
  int f = 0;
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j + 1 < n; ++j) {
      const int a = i * n + j, b = a + 1, c = a + n, d = c + 1;
      F->row(f++) << a, c, b;
      F->row(f++) << b, c, d;
    }
}

// Gradient against finite differences of the value; at a minimiser (where the projection changes nothing)
// also the Hessian against finite differences of the gradient.
void check_derivatives(const Objective& term, const Positions& x, bool at_minimum) {
  const int n = static_cast<int>(x.size());
  auto f = [&](const Positions& y) { return term.value(y); };
  auto g = [&](const Positions& y) {
    Eigen::VectorXd grad = Eigen::VectorXd::Zero(n);
    term.derivatives(y, &grad, nullptr);
    return grad;
  };
  Eigen::VectorXd grad = Eigen::VectorXd::Zero(n);
  std::vector<Eigen::Triplet<double>> triplets;
  EXPECT_NEAR(term.derivatives(x, &grad, &triplets), term.value(x), 1e-12);
  const Eigen::MatrixXd H = test::dense(triplets, n);
  // Relative to the gradient, or (at a minimiser, where it vanishes) to the curvature times a unit step.
  const Eigen::VectorXd fd = test::fd_position_gradient(f, x, 1e-6);
  EXPECT_LT((grad - fd).cwiseAbs().maxCoeff(), 1e-6 * std::max(fd.cwiseAbs().maxCoeff(), 1e-3 * H.cwiseAbs().maxCoeff()));
  EXPECT_GE(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues().minCoeff(), -1e-9 * H.cwiseAbs().maxCoeff());
  if (at_minimum) {
    EXPECT_LT(test::relative_error(H, test::fd_position_jacobian(g, x, 1e-6)), 1e-5);
  }
}

TEST(SurfaceShape, ZeroUnderRotationTranslationAndUniformScaling) {
  Positions V;
  MatrixX3i F;
  bumpy_sheet(6, &V, &F);
  const SurfaceShapeTerm term(V, F);
  EXPECT_EQ(term.num_pairs(), 85 - 20);  // a 6 by 6 grid has 85 edges, 20 of them on the rim
  EXPECT_NEAR(term.value(V), 0.0, 1e-20);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  for (double scale : {1.0, 0.5, 3.0}) {
    Positions moved = (scale * V * R.transpose()).rowwise() + Eigen::RowVector3d(0.3, -2, 5);
    EXPECT_NEAR(term.value(moved), 0.0, 1e-20) << "scale " << scale;
    check_derivatives(term, moved, /*at_minimum=*/true);
  }
}

TEST(SurfaceShape, PositiveWhereTheShapeChangesAndDerivativesMatch) {
  Positions V;
  MatrixX3i F;
  bumpy_sheet(5, &V, &F);
  const SurfaceShapeTerm term(V, F, 2.0);
  Positions bent = V;
  for (int i = 0; i < bent.rows(); ++i) bent(i, 1) += 0.2 * bent(i, 0) * bent(i, 0);  // a bend, not an affine map
  EXPECT_GT(term.value(bent), 1e-6);
  // Stretching one half only (anisotropic and not global) distorts pairs across the seam.
  Positions stretched = V;
  for (int i = 0; i < stretched.rows(); ++i)
    if (stretched(i, 0) > 0.5) stretched(i, 0) = 0.5 + 2.0 * (stretched(i, 0) - 0.5);
  EXPECT_GT(term.value(stretched), 1e-6);
  check_derivatives(term, bent, false);
  const std::vector<double> per_pair = term.pair_distortion(bent);
  ASSERT_EQ(static_cast<int>(per_pair.size()), term.num_pairs());
  EXPECT_GT(*std::max_element(per_pair.begin(), per_pair.end()), 0.0);
}

TEST(SurfaceShape, FacesOfOppositeOrientationAreAnError) {
  Positions V(4, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 1;
  MatrixX3i F(2, 3);
  F << 0, 2, 1, 1, 2, 3;  // the shared edge: 2 -> 1 in the first face, 1 -> 2 in the second
  EXPECT_NO_THROW(SurfaceShapeTerm(V, F));
  F.row(1) << 1, 3, 2;  // now 2 -> 1 in both
  try {
    SurfaceShapeTerm term(V, F);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("oriented manifold"), std::string::npos) << e.what();
  }
}

TEST(SurfaceShape, DegenerateTrianglesAreAnError) {
  Positions V(4, 3);
  V << 0, 0, 0, 1, 0, 0, 2, 0, 0, 1, 0, 1;  // corners 0, 1, 2 on a line
  MatrixX3i F(2, 3);
  F << 0, 2, 1, 1, 2, 3;
  try {
    SurfaceShapeTerm term(V, F);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("degenerate triangle next to the edge (1, 2)"), std::string::npos) << e.what();
  }
}

TEST(Positional, HoldsTheBoundaryCoordinateAlongTheBone) {
  // A 4 by 4 sheet beside a bone parallel to the x axis.
  Positions V;
  MatrixX3i F;
  bumpy_sheet(4, &V, &F);
  Positions joints(2, 3);
  joints << -0.2, 0.5, 0, 1.2, 0.5, 0;
  const MatrixX2i bones = skeleton_bones({-1, 0});
  PositionalTerm term(V, F, joints, bones, 10.0);
  EXPECT_EQ(term.boundary_vertices().size(), 12u);  // the rim of a 4 by 4 grid
  EXPECT_NEAR(term.value(V), 0.0, 1e-20);
  // Moving along the bone costs; moving around it does not.
  Positions along = V, around = V;
  along.col(0).array() += 0.1;
  around.col(1).array() += 0.1;
  EXPECT_GT(term.value(along), 0.0);
  EXPECT_NEAR(term.value(around), 0.0, 1e-20);
  // A bone twice as long: the garment scaled with it along x is at rest again.
  Positions longer = joints, scaled = V;
  longer.row(1) << 2.6, 0.5, 0;  // from -0.2, length 2.8 = 2 x 1.4
  scaled.col(0) = (scaled.col(0).array() + 0.2) * 2.0 - 0.2;
  term.set_skeleton(longer);
  EXPECT_NEAR(term.value(scaled), 0.0, 1e-20);
  EXPECT_GT(term.value(V), 0.0);
  check_derivatives(term, V, /*at_minimum=*/true);  // quadratic: its Hessian is exact everywhere
  Positions zero = longer;
  zero.row(1) = zero.row(0);
  EXPECT_THROW(term.set_skeleton(zero), Error);
}

TEST(BoundaryLoops, OneLoopForASheetTwoForATube) {
  Positions V;
  MatrixX3i F;
  bumpy_sheet(4, &V, &F);
  const auto sheet = boundary_loops(F);
  ASSERT_EQ(sheet.size(), 1u);
  EXPECT_EQ(sheet[0].size(), 12u);
  test::tube(3, 8, 0.0, 0.2, 0.05, &V, &F, 0.02);
  const auto sleeve = boundary_loops(F);
  ASSERT_EQ(sleeve.size(), 2u);
  EXPECT_EQ(sleeve[0].size(), 8u);
  EXPECT_EQ(sleeve[1].size(), 8u);
}

TEST(CurveShape, InvariantUnderSimilaritiesButNotUnderAnisotropicScaling) {
  Positions V;
  MatrixX3i F;
  test::tube(4, 10, 0.0, 0.3, 0.05, &V, &F, 0.02);
  const CurveShapeTerm term(V, F);
  EXPECT_EQ(term.num_loops(), 2);
  EXPECT_NEAR(term.value(V), 0.0, 1e-24);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(-1.1, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix();
  const Positions moved = (2.5 * V * R.transpose()).rowwise() + Eigen::RowVector3d(1, 2, 3);
  EXPECT_NEAR(term.value(moved), 0.0, 1e-20);
  // A round cuff squashed into an ellipse (the paper: it should not do that freely).
  Positions ellipse = V;
  ellipse.col(2) *= 0.5;
  EXPECT_GT(term.value(ellipse), 1e-4);
  check_derivatives(term, ellipse, false);
  check_derivatives(term, moved, true);
}

}  // namespace
}  // namespace amt::refit
