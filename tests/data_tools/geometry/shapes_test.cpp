// Primitive meshes are closed, outward-facing and of the documented size.
#include "data_tools/geometry/shapes.h"

#include <gtest/gtest.h>

#include "data_tools/geometry/skeleton.h"

namespace amt {
namespace {

// Signed volume by the divergence theorem: positive for a closed outward-facing mesh.
double signed_volume(const TriMesh& m) {
  double v = 0;
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d a = m.V.row(m.F(f, 0)).cast<double>(), b = m.V.row(m.F(f, 1)).cast<double>(),
                          c = m.V.row(m.F(f, 2)).cast<double>();
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

// Every edge of a closed manifold mesh borders exactly two faces: V - E + F = 2 for a sphere.
TEST(Shapes, SphereAndCapsuleAreClosedAndOutward) {
  const TriMesh s = uv_sphere(Eigen::Vector3f(1, 2, 3), 0.5f, 32, 16);
  EXPECT_EQ(s.num_vertices(), 2 + 32 * 15);
  EXPECT_EQ(s.num_vertices() - unique_edges(s.F).rows() + s.num_faces(), 2);
  EXPECT_NEAR(signed_volume(s), 4.0 / 3.0 * M_PI * 0.125, 0.02);

  const TriMesh c = capsule(Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(0, 1, 0), 0.1f, 24, 6, 4);
  EXPECT_EQ(c.num_vertices() - unique_edges(c.F).rows() + c.num_faces(), 2);
  const double expected = M_PI * 0.01 * 1.0 + 4.0 / 3.0 * M_PI * 0.001;
  EXPECT_NEAR(signed_volume(c), expected, 0.03 * expected);
  EXPECT_NEAR(c.V.col(1).maxCoeff(), 1.1f, 1e-5f);
  EXPECT_NEAR(c.V.col(1).minCoeff(), -0.1f, 1e-5f);
}

TEST(Shapes, GridAndMerge) {
  const TriMesh g = grid(3, 2, 0.5f);
  EXPECT_EQ(g.num_vertices(), 6);
  EXPECT_EQ(g.num_faces(), 4);
  EXPECT_EQ(g.V(5, 0), 1.0f);
  std::vector<int32_t> part;
  const TriMesh m = merge_meshes({g, g}, &part);
  EXPECT_EQ(m.num_vertices(), 12);
  EXPECT_EQ(m.F(4, 0), g.F(0, 0) + 6);
  EXPECT_EQ(part[7], 1);
  int components = 0;
  connected_components(m.num_vertices(), unique_edges(m.F), &components);
  EXPECT_EQ(components, 2);
}

TEST(Shapes, CapsuleCharacterHitsTheTargetSize) {
  const Skeleton s = canonical_skeleton();
  std::vector<int32_t> joint;
  const TriMesh m = capsule_character(s.rest_joints, s.parents, 20000, &joint);
  ASSERT_EQ(joint.size(), static_cast<size_t>(m.num_vertices()));
  EXPECT_EQ(joint.front(), kPelvis);  // the first capsule is the bone pelvis -> left_hip
  EXPECT_EQ(joint.back(), kHead);  // the head sphere follows the highest joint
  EXPECT_GT(m.num_vertices(), 15000);
  EXPECT_LE(m.num_vertices(), 20000);
  int components = 0;
  connected_components(m.num_vertices(), unique_edges(m.F), &components);
  EXPECT_EQ(components, 22);
}

}  // namespace
}  // namespace amt
