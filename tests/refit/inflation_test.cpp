#include "refit/inflation.h"

#include "refit/garment_fit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "exact_intersection.h"
#include "test_meshes.h"

namespace amt::refit {
namespace {

// Shoulder, elbow and wrist on the x axis.
Positions arm(double length) {
  Positions J(3, 3);
  J << 0, 0, 0, 0.5 * length, 0, 0, length, 0, 0;
  return J;
}

TEST(Inflation, ASleeveRefitOntoALongerArmEndsIntersectionFree) {
  // A sleeve (radius 6 cm, 10 sides) made for a 30 cm arm; the target arm is 45 cm long and of radius
  // 10 cm (8 sides, faces 9.2 cm from the axis). Stretched 1.5 times along the arm, the sleeve would keep
  // its shape at radius 9 cm (the shape terms allow uniform scaling): the arm must push it out further,
  // through the barrier, as it inflates.
  const MatrixX2i bones = skeleton_bones({-1, 0, 1});
  const Positions source_joints = arm(0.30), target_joints = arm(0.45);
  Positions sleeve, body;
  MatrixX3i sleeve_F, body_F;
  test::tube(6, 10, 0.02, 0.28, 0.06, &sleeve, &sleeve_F, 0.0, /*staggered=*/true);
  test::tube(8, 8, 0.0, 0.45, 0.10, &body, &body_F, 0.0, /*staggered=*/true);
  const ShrunkAvatar avatar = shrink_to_skeleton(body, body_F, target_joints, source_joints, bones,
                                                 nearest_bones(body, target_joints, bones));
  InflationOptions options;
  int steps = 0, crossings = 0;
  const InflationResult result = inflate_avatar(
      sleeve, sleeve_F, avatar, source_joints, target_joints, bones, options,
      [&](const InflationProgress& p) {
        std::printf("inflation %d: t %.4f, energy %.6g, min distance %.3g mm, %d Newton iterations\n",
                    p.outer_iteration, p.t, p.energy, 1e3 * p.min_distance, p.newton_iterations);
        EXPECT_GT(p.min_distance, 0.0) << "outer iteration " << p.outer_iteration;
      },
      [&](const NewtonStep& st) {
        ++steps;
        crossings += test::count_crossings(*st.collisions, *st.before, *st.after);
      });
  EXPECT_TRUE(result.snapped) << result.stop_reason << ", t = " << result.t;
  EXPECT_EQ(result.t, 1.0);
  EXPECT_GT(steps, 0);
  EXPECT_EQ(crossings, 0);
  // Step 3 (without the fit term): the garment relaxes onto the target skeleton; every step checked.
  Positions fitted;
  const NewtonResult fit = fit_garment(sleeve, sleeve_F, result.garment, body, body_F, source_joints, target_joints,
                                       bones, &fitted, {}, [&](const NewtonStep& st) {
                                         ++steps;
                                         crossings += test::count_crossings(*st.collisions, *st.before, *st.after);
                                       });
  std::printf("inflation: %s after %d outer iterations; garment fit: %s after %d iterations; %d steps checked\n",
              result.stop_reason.c_str(), result.outer_iterations, fit.stop_reason.c_str(), fit.iterations, steps);
  EXPECT_TRUE(fit.converged) << fit.stop_reason;
  EXPECT_EQ(crossings, 0);
  // The exact check of both results against the target arm itself (not the shrunk one).
  const CollisionMesh mesh = make_garment_avatar_mesh(sleeve, sleeve_F, body, body_F);
  Positions scene(mesh.num_vertices, 3);
  scene << result.garment, body;
  EXPECT_EQ(test::count_intersecting_triangle_pairs(scene, mesh.F, mesh.vertex_obstacle), 0);
  scene << fitted, body;
  EXPECT_EQ(test::count_intersecting_triangle_pairs(scene, mesh.F, mesh.vertex_obstacle), 0);
  // The cuff followed the longer forearm: from x = 0.28 towards 0.22 + 0.87 x 0.23 = 0.42.
  double cuff_x = 0.0;
  for (int k = 0; k < 10; ++k) cuff_x += fitted(5 * 10 + k, 0) / 10;
  double radius = 0.0;
  for (int v = 0; v < fitted.rows(); ++v) radius += fitted.row(v).tail<2>().norm() / fitted.rows();
  std::printf("cuff at x = %.4f m (source 0.28), mean sleeve radius %.4f m (source 0.06)\n", cuff_x, radius);
  EXPECT_GT(cuff_x, 0.35);
  EXPECT_GT(radius, 0.095);  // wider than its uniformly scaled shape (0.09): pushed by the arm
}

}  // namespace
}  // namespace amt::refit
