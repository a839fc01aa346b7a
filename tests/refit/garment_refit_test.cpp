#include "refit/garment_refit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "data_tools/geometry/error.h"
#include "exact_intersection.h"
#include "refit/contact.h"
#include "test_meshes.h"

namespace amt::refit {
namespace {

// A closed ellipsoidal "torso and thighs" about the y axis: radius r, from y = 0.6 to 1.3 (24 by 24), on a
// chain of three joints (knee line 0.62, pelvis 0.95, chest 1.28) along its axis.
RiggedMesh waist(double r) {
  RiggedMesh m;
  test::sphere(24, 24, 1.0, Eigen::RowVector3d::Zero(), &m.V, &m.F);
  m.V.col(0) *= r;
  m.V.col(2) *= r;
  m.V.col(1) = 0.95 + 0.35 * m.V.col(1).array();
  m.joints.resize(3, 3);
  m.joints << 0, 0.62, 0, 0, 0.95, 0, 0, 1.28, 0;
  return m;
}

// A skirt: a cone of 6 rings of 16 from the waist (y = 1.0, radius 13.5 cm) flaring to the hem (y = 0.75,
// radius 20 cm).
void skirt(Positions* V, MatrixX3i* F) {
  test::tube(6, 16, 1.0, 0.75, 1.0, V, F, 0.0, /*staggered=*/true);
  for (int v = 0; v < V->rows(); ++v) {
    const double s = (1.0 - (*V)(v, 0)) / 0.25, radius = 0.135 + s * (0.20 - 0.135);
    const Eigen::RowVector3d p = V->row(v);
    V->row(v) << radius * p[1], p[0], radius * p[2];  // the tube's axis x becomes y
  }
}

// The exact check of the result against the target avatar (every garment x garment and garment x avatar
// triangle pair).
int intersecting_pairs(const Positions& garment, const MatrixX3i& garment_F, const RiggedMesh& avatar) {
  const CollisionMesh mesh = make_garment_avatar_mesh(garment, garment_F, avatar.V, avatar.F);
  Positions scene(mesh.num_vertices, 3);
  scene << garment, avatar.V;
  return test::count_intersecting_triangle_pairs(scene, mesh.F, mesh.vertex_obstacle);
}

double mean_radius_at_waist(const Positions& V) {
  double sum = 0.0;
  for (int k = 0; k < 16; ++k) sum += Eigen::Vector2d(V(k, 0), V(k, 2)).norm() / 16;
  return sum;
}

TEST(RefitGarment, ASkirtOntoAWiderWaistEndsIntersectionFree) {
  // Source waist radius 12 cm (11.9 cm at the skirt's waist line, 1.6 cm inside it); the target's is 16 cm
  // (15.8 cm there): the skirt's waist must widen by 2.3 cm more than it has room for.
  const RiggedMesh source = waist(0.12), target = waist(0.16);
  Positions garment;
  MatrixX3i F;
  skirt(&garment, &F);
  ASSERT_EQ(intersecting_pairs(garment, F, source), 0);
  ASSERT_GT(intersecting_pairs(garment, F, target), 0);  // as it is, the skirt would cut into the target
  int lines = 0;
  const GarmentRefitResult r =
      refit_garment(garment, F, source, target, {-1, 0, 1}, {}, [&](const GarmentRefitProgress& p) {
        ++lines;
        EXPECT_GT(p.min_distance, 0.0) << p.stage << " " << p.iteration;
      });
  std::printf(
      "skirt: %d outer iterations, %d fit iterations (%s), distortion RMS %.4f max %.4f, fit distance "
      "%.2f -> %.2f mm over %d vertices, min distance %.3f mm, waist radius %.4f m\n",
      r.outer_iterations, r.fit_iterations, r.fit_stop_reason.c_str(), r.distortion_rms, r.distortion_max,
      1e3 * r.source_fit_distance, 1e3 * r.fit_distance, r.fit_vertices, 1e3 * r.min_distance,
      mean_radius_at_waist(r.garment));
  EXPECT_GE(lines, r.outer_iterations);
  EXPECT_EQ(intersecting_pairs(r.garment, F, target), 0);
  EXPECT_EQ(r.crossing_pairs, 0);
  EXPECT_GT(r.min_distance, 0.0);
  EXPECT_GT(mean_radius_at_waist(r.garment), 0.158);  // around the target's waist
  EXPECT_EQ(r.fit_vertices, 16);                      // the waist ring: 1.6 cm from the source, within 2 cm
  EXPECT_LT(r.fit_distance, r.source_fit_distance);   // drawn onto the target
  EXPECT_LT(r.distortion_rms, 0.2);
}

// Shoulder, elbow and wrist on the x axis.
Positions arm_joints(double length) {
  Positions J(3, 3);
  J << 0, 0, 0, 0.5 * length, 0, 0, length, 0, 0;
  return J;
}

TEST(RefitGarment, ASleeveOntoALongerArmEndsIntersectionFreeAndFollowsTheWrist) {
  // The inflation test's sleeve (radius 6 cm, cuff at 28 cm) from a 30 cm arm of radius 4 cm onto a 45 cm
  // arm of radius 10 cm, through the whole refit with the fit term.
  RiggedMesh source, target;
  test::tube(6, 8, 0.0, 0.30, 0.04, &source.V, &source.F, 0.0, true);
  test::tube(8, 8, 0.0, 0.45, 0.10, &target.V, &target.F, 0.0, true);
  source.joints = arm_joints(0.30);
  target.joints = arm_joints(0.45);
  Positions sleeve;
  MatrixX3i F;
  test::tube(6, 10, 0.02, 0.28, 0.06, &sleeve, &F, 0.0, /*staggered=*/true);
  const GarmentRefitResult r = refit_garment(sleeve, F, source, target, {-1, 0, 1});
  EXPECT_EQ(intersecting_pairs(r.garment, F, target), 0);
  double cuff_x = 0.0;
  for (int k = 0; k < 10; ++k) cuff_x += r.garment(5 * 10 + k, 0) / 10;
  std::printf("sleeve: cuff at x = %.4f m (source 0.28), distortion RMS %.4f, min distance %.3f mm\n", cuff_x,
              r.distortion_rms, 1e3 * r.min_distance);
  EXPECT_GT(cuff_x, 0.35);
}

// The one-line message of refit_garment on bad input.
std::string error_of(const Positions& garment, const MatrixX3i& F, const RiggedMesh& source, const RiggedMesh& target,
                     const std::vector<int32_t>& parents = {-1, 0, 1}) {
  try {
    refit_garment(garment, F, source, target, parents, {}, {}, "skirt.obj", "a.glb", "b.glb");
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(RefitGarment, BadInputIsAOneLineErrorNamingTheFile) {
  const RiggedMesh source = waist(0.12), target = waist(0.16);
  Positions garment;
  MatrixX3i F;
  skirt(&garment, &F);
  // A garment that crosses the source avatar (its waist pulled in to 10 cm).
  Positions tight = garment;
  for (int k = 0; k < 16; ++k) tight.row(k).array() *= Eigen::Array3d(0.1 / 0.135, 1.0, 0.1 / 0.135).transpose();
  EXPECT_NE(error_of(tight, F, source, target).find("skirt.obj on a.glb: garment face "), std::string::npos);
  EXPECT_NE(error_of(tight, F, source, target).find("crosses the source avatar's face"), std::string::npos);
  // A degenerate triangle: a vertex moved onto the middle of its face's opposite side.
  Positions flat = garment;
  flat.row(F(40, 0)) = 0.5 * (garment.row(F(40, 1)) + garment.row(F(40, 2)));
  EXPECT_NE(error_of(flat, F, source, target).find("skirt.obj: face "), std::string::npos);
  EXPECT_NE(error_of(flat, F, source, target).find("is degenerate, expected a triangle of non-zero area"),
            std::string::npos);
  // NaN.
  Positions nan = garment;
  nan(7, 1) = std::nan("");
  EXPECT_NE(error_of(nan, F, source, target).find("skirt.obj: vertex 7 is ("), std::string::npos);
  // Skeletons that do not map: another joint count, a bone of zero length.
  RiggedMesh two = target;
  two.joints.conservativeResize(2, 3);
  EXPECT_EQ(error_of(garment, F, source, two), "b.glb: skeleton: 2 joints, expected 3 (the source's)");
  RiggedMesh folded = target;
  folded.joints.row(2) = folded.joints.row(1);
  EXPECT_EQ(error_of(garment, F, source, folded),
            "b.glb: skeleton: bone 1 (joints 1 to 2) has zero length, expected a bone of positive length");
}

}  // namespace
}  // namespace amt::refit
