// The README's example of `amt refit-garment` (the builder's flared skirt from generated body 3 onto generated
// body 11, 3000 vertices each) through the library, its result checked exactly: the picture in the README
// shows an intersection-free garment.
#include <gtest/gtest.h>

#include <cstdio>

#include "data_tools/builder/apparel.h"
#include "data_tools/builder/body_generator.h"
#include "exact_intersection.h"
#include "refit/contact.h"
#include "refit/garment_refit.h"

namespace amt::refit {
namespace {

RiggedMesh rigged(const GeneratedBody& body) {
  return {body.mesh.V.cast<double>(), body.mesh.F, body.skeleton.rest_joints.cast<double>()};
}

TEST(ReadmeExample, TheFlaredSkirtOnBody11EndsIntersectionFree) {
  const GeneratedBody source = generate_body(sample_body_params(uint64_t(3)), 3000);
  const GeneratedBody target = generate_body(sample_body_params(uint64_t(11)), 3000);
  // The garment as `--garment generated:flared_skirt` makes it: the apparel faces of the dressed source.
  const DressedCharacter dressed = dress_character_with(source, {ApparelKind::kFlaredSkirt}, 1);
  const int first = source.mesh.num_vertices(), n = dressed.mesh.num_vertices() - first;
  const Positions garment = dressed.mesh.V.bottomRows(n).cast<double>();
  std::vector<Eigen::RowVector3i> faces;
  for (int f = 0; f < dressed.mesh.num_faces(); ++f)
    if (dressed.mesh.F.row(f).minCoeff() >= first) faces.push_back(dressed.mesh.F.row(f).array() - first);
  MatrixX3i F(static_cast<int>(faces.size()), 3);
  for (size_t i = 0; i < faces.size(); ++i) F.row(static_cast<int>(i)) = faces[i];
  ASSERT_EQ(garment.rows(), 1248);  // the README's "1248 vertices"

  const RiggedMesh tgt = rigged(target);
  const GarmentRefitResult r = refit_garment(garment, F, rigged(source), tgt, source.skeleton.parents);
  std::printf("README example: distortion RMS %.4f, fit distance %.2f -> %.2f mm, min distance %.3f mm\n",
              r.distortion_rms, 1e3 * r.source_fit_distance, 1e3 * r.fit_distance, 1e3 * r.min_distance);
  const CollisionMesh mesh = make_garment_avatar_mesh(garment, F, tgt.V, tgt.F);
  Positions scene(mesh.num_vertices, 3);
  scene << r.garment, tgt.V;
  EXPECT_EQ(test::count_intersecting_triangle_pairs(scene, mesh.F, mesh.vertex_obstacle), 0);
  EXPECT_GT(r.min_distance, 0.0);
}

}  // namespace
}  // namespace amt::refit
