// The open-parts stand-in for a real model (data_tools/builder/open_parts.h).
#include "data_tools/builder/open_parts.h"

#include <gtest/gtest.h>


#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/retarget.h"

namespace amt {
namespace {

// One small dressed character per process (a 3000-vertex body with the items: skirt, twin
// tails, ribbons) and its open-parts remake.
struct Character {
  DressedCharacter dressed;
  OpenPartsCharacter open;
};
const Character& test_character() {
  static const Character c = [] {
    Character c;
    ApparelOptions dress;
    dress.vertex_fraction = 0.2f;
    const GeneratedBody body = generate_body(sample_body_params(uint64_t{7}), 3000);
    c.dressed = dress_character_with(body, {ApparelKind::kPleatedSkirt, ApparelKind::kTwinTails, ApparelKind::kRibbons},
                                     7, dress);
    c.open = open_parts_character(c.dressed);
    return c;
  }();
  return c;
}

// The faces of the body parts (three corners with a part) of an open-parts mesh.
MatrixX3i body_faces(const TriMesh& mesh, const std::vector<int32_t>& part) {
  std::vector<Eigen::Vector3i> faces;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3i face = mesh.F.row(f).transpose();
    if (part[size_t(face[0])] >= 0 && part[size_t(face[1])] >= 0 && part[size_t(face[2])] >= 0) faces.push_back(face);
  }
  MatrixX3i F(Eigen::Index(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) F.row(Eigen::Index(f)) = faces[f].transpose();
  return F;
}

TEST(OpenPartsCharacter, BodyIsManyOpenOverlappingPartsAndApparelIsKept) {
  const Character& c = test_character();
  const OpenPartsCharacter& o = c.open;
  const int N = o.mesh.num_vertices();
  EXPECT_NO_THROW(validate_mesh(o.mesh, "open parts"));
  ASSERT_EQ(int(o.apparel_mask.size()), N);
  ASSERT_EQ(int(o.part.size()), N);
  ASSERT_EQ(int(o.source.size()), N);
  ASSERT_EQ(o.body_weights.rows(), N);
  EXPECT_GE(o.num_parts, 15);  // one per dominant joint with faces, plus the cap
  EXPECT_GT(o.dropped_faces, 0);
  // Apparel unchanged: same count and positions as the dressed character's.
  int apparel = 0, dressed_apparel = 0;
  for (int v = 0; v < N; ++v) {
    EXPECT_NEAR(o.body_weights.row(v).sum(), 1.0f, 1e-5f) << "vertex " << v;
    if (!o.apparel_mask[size_t(v)]) continue;
    ++apparel;
    EXPECT_EQ(o.part[size_t(v)], -1);
    EXPECT_EQ(o.mesh.V.row(v), c.dressed.mesh.V.row(o.source[size_t(v)]));
  }
  for (const uint8_t m : c.dressed.apparel_mask) dressed_apparel += m;
  EXPECT_EQ(apparel, dressed_apparel);
  EXPECT_GT(double(apparel) / N, 0.10);
  EXPECT_LT(double(apparel) / N, 0.30);
  // More body vertices than the generated body had (the seams are duplicated), and every part is open.
  int body = 0;
  for (const int32_t p : o.part) body += p >= 0;
  EXPECT_GT(body, c.dressed.body.mesh.num_vertices());
  const MatrixX3i F = body_faces(o.mesh, o.part);
  for (int p = 0; p < o.num_parts; ++p) {
    std::vector<Eigen::Vector3i> faces;
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      if (o.part[size_t(F(f, 0))] == p) faces.push_back(F.row(f).transpose());
    MatrixX3i Fp(Eigen::Index(faces.size()), 3);
    for (size_t f = 0; f < faces.size(); ++f) Fp.row(Eigen::Index(f)) = faces[f].transpose();
    EXPECT_FALSE(is_closed_surface(Fp)) << "part " << p;
  }
}

}  // namespace
}  // namespace amt
