// The artist-style remake of a dataset character (data_tools/builder/artist_style.h): counts like real models',
// coincident copies that stay one point in the remade ground truth, reverse sides at their offset, determinism,
// welding back to the source's parts, subdivision, errors; and the measures of a prediction falling apart on a
// hand-made mesh.
#include "data_tools/builder/artist_style.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <tuple>

#include "data_tools/builder/apparel.h"
#include "data_tools/builder/body_generator.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/segmentation_features.h"
#include "data_tools/geometry/skeleton.h"

namespace amt {
namespace {

// One small dressed character per process (a 3000-vertex body with a skirt, hair strands and a cape) as the
// dataset stores it, and its remake with the default options.
struct Character {
  CharacterData source;
  ArtistStyleCharacter remake;
};
const Character& test_character() {
  static const Character c = [] {
    Character c;
    const GeneratedBody body = generate_body(sample_body_params(uint64_t{5}), 3000);
    c.source =
        dress_character_with(body, {ApparelKind::kPleatedSkirt, ApparelKind::kHairStrands, ApparelKind::kCape}, 5)
            .character_data("tiny", "test");
    c.remake = artist_style_character(c.source);
    return c;
  }();
  return c;
}

// Connected parts of (V, F) after welding the vertices within kCoincidentTolerance.
int welded_parts(const MatrixX3f& V, const MatrixX3i& F) {
  return mesh_construction(V, F).welded_parts;
}

// The identity pose of the skeleton: [I | rest joint].
Transforms rest_pose(const Skeleton& skeleton) {
  Transforms pose;
  for (int j = 0; j < skeleton.num_joints(); ++j)
    pose.push_back(make_transform(Eigen::Matrix3f::Identity(), skeleton.rest_joints.row(j).transpose()));
  return pose;
}

// Frame 12 of a walk: the source skinned, its apparel vertices moved by a deterministic wobble (not rigid).
std::pair<MatrixX3f, Transforms> posed_source(const CharacterData& c) {
  const Motion walk = walk_motion(20, 30.0f, 1.0f);
  const Transforms joints = forward_kinematics(c.skeleton, walk, 12);
  MatrixX3f V;
  linear_blend_skinning(c.mesh.V, c.body_weights, skinning_matrices(c.skeleton, joints), V);
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    if (c.apparel_mask[size_t(i)]) V.row(i) += 0.01f * Eigen::RowVector3f(std::sin(0.7f * i), std::cos(1.3f * i), 0.5f);
  return {V, joints};
}

TEST(ArtistStyle, CountsLookLikeRealModels) {
  const Character& c = test_character();
  const CharacterData& r = c.remake.character;
  const int M = r.mesh.num_vertices();
  EXPECT_NO_THROW(validate_mesh(r.mesh, "artist style"));
  ASSERT_EQ(int(r.apparel_mask.size()), M);
  ASSERT_EQ(r.body_weights.rows(), M);
  ASSERT_EQ(int(c.remake.source.size()), M);
  ASSERT_EQ(int(c.remake.offset.size()), M);
  ASSERT_EQ(int(c.remake.side.size()), M);
  for (int i = 0; i < M; ++i) ASSERT_NEAR(r.body_weights.row(i).sum(), 1.0f, 1e-5f) << "vertex " << i;
  const MeshConstruction source = mesh_construction(c.source.mesh.V, c.source.mesh.F);
  const MeshConstruction m = mesh_construction(r.mesh.V, r.mesh.F);
  std::printf(
      "source: %d vertices, %d faces, %d parts; remake: %d vertices, %d faces, %d parts, %d welded, %.1f %% "
      "coincident, %d strips\n",
      source.vertices, source.faces, source.parts, m.vertices, m.faces, m.parts, m.welded_parts,
      100 * m.coincident_share, c.remake.num_strips);
  EXPECT_LT(source.coincident_share, 0.01);  // the builder's characters have (almost) no seams
  // Real models: 68-84 % of vertices with a coincident copy, hundreds to thousands of parts, welding ~10x fewer.
  // This character has 11 source parts, so its welded parts are few and the ratio is about 20x (71 %, 1055 parts,
  // 53 welded).
  EXPECT_GE(m.coincident_share, 0.68);
  EXPECT_LE(m.coincident_share, 0.84);
  EXPECT_GE(m.parts, 300);
  EXPECT_GE(m.parts, 6 * m.welded_parts);
  EXPECT_LE(m.parts, 40 * m.welded_parts);
  // Apparel share about the source's (the reverse sides double it, minus the body's duplicated seams).
  int apparel = 0;
  for (const uint8_t a : r.apparel_mask) apparel += a;
  EXPECT_GT(apparel, 0);
  EXPECT_LT(apparel, M);
}

TEST(ArtistStyle, CoincidentCopiesHaveIdenticalRestPositionsAndGroundTruth) {
  const Character& c = test_character();
  const ArtistStyleCharacter& a = c.remake;
  const MatrixX2i pairs = coincident_pairs(a.character.mesh.V, a.character.mesh.F);
  ASSERT_GT(pairs.rows(), a.character.mesh.num_vertices() / 3);
  // The rest pose remade is the remake's rest mesh.
  const MatrixX3f rest = remake_frame(a, c.source.mesh.V, rest_pose(c.source.skeleton));
  EXPECT_LT((rest - a.character.mesh.V).cwiseAbs().maxCoeff(), 1e-6f);
  const auto [frame, joints] = posed_source(c.source);
  const MatrixX3f posed = remake_frame(a, frame, joints);
  // Every pair is two copies of one source vertex at one offset, or copies of two vertices the source itself
  // has at one point (a few of the generated body's).
  int copies = 0, exact_rest = 0, exact_posed = 0;
  for (Eigen::Index p = 0; p < pairs.rows(); ++p) {
    const int i = pairs(p, 0), j = pairs(p, 1), si = a.source[size_t(i)], sj = a.source[size_t(j)];
    if (si != sj) {
      ASSERT_TRUE(si >= 0 && sj >= 0 && (c.source.mesh.V.row(si) - c.source.mesh.V.row(sj)).norm() < 1e-4f)
          << i << " " << j;
      continue;
    }
    ++copies;
    EXPECT_EQ(a.offset[size_t(i)], a.offset[size_t(j)]) << i << " " << j;
    exact_rest += a.character.mesh.V.row(i) == a.character.mesh.V.row(j);
    exact_posed += posed.row(i) == posed.row(j);
  }
  EXPECT_GT(copies, 0.99 * pairs.rows());
  EXPECT_EQ(exact_rest, copies);
  EXPECT_EQ(exact_posed, copies);
  // Front copies follow their source vertex exactly; the stacked form is frame by frame.
  for (int i = 0; i < a.character.mesh.num_vertices(); ++i) {
    if (a.source[size_t(i)] < 0 || a.offset[size_t(i)] != 0.0f) continue;
    ASSERT_EQ(posed.row(i), frame.row(a.source[size_t(i)])) << "vertex " << i;
  }
  MatrixX3f two(2 * frame.rows(), 3);
  two << c.source.mesh.V, frame;
  Transforms both = rest_pose(c.source.skeleton);
  both.insert(both.end(), joints.begin(), joints.end());
  const MatrixX3f stacked = remake_frames(a, two, both);
  EXPECT_EQ(stacked.bottomRows(posed.rows()), posed);
  // The hair cap follows the head rigidly.
  const int head = c.source.skeleton.index_of("head");
  for (int i = 0; i < a.character.mesh.num_vertices(); ++i) {
    if (a.source[size_t(i)] >= 0) continue;
    ASSERT_EQ(a.joint[size_t(i)], head);
    const Eigen::Vector3f expected =
        apply(joints[size_t(head)], a.character.mesh.V.row(i).transpose()) -
        joints[size_t(head)].leftCols<3>() * c.source.skeleton.rest_joints.row(head).transpose();
    ASSERT_LT((posed.row(i).transpose() - expected).norm(), 1e-5f);
  }
}

TEST(ArtistStyle, ReverseSidesAreOffsetAlongTheRestNormalWithReversedWinding) {
  const Character& c = test_character();
  const ArtistStyleCharacter& a = c.remake;
  const ArtistStyleOptions o;
  const MatrixX3f normals = vertex_normals(c.source.mesh.V, c.source.mesh.F);  // no subdivision: same vertices
  ASSERT_EQ(a.midpoints.rows(), 0);
  // Faces of each side as source triples, rotated to start at their smallest corner.
  using Triple = std::tuple<int, int, int>;
  const auto triple = [&](int f) {
    int s[3];
    for (int k = 0; k < 3; ++k) s[k] = a.source[size_t(a.character.mesh.F(f, k))];
    const int r = int(std::min_element(s, s + 3) - s);
    return Triple{s[r], s[(r + 1) % 3], s[(r + 2) % 3]};
  };
  std::set<Triple> front;
  int reverse_faces = 0, reverse_vertices = 0;
  for (int f = 0; f < a.character.mesh.num_faces(); ++f)
    if (a.side[size_t(a.character.mesh.F(f, 0))] == ArtistSide::kFront) front.insert(triple(f));
  for (int f = 0; f < a.character.mesh.num_faces(); ++f) {
    if (a.side[size_t(a.character.mesh.F(f, 0))] != ArtistSide::kReverse) continue;
    ++reverse_faces;
    const auto [x, y, z] = triple(f);
    ASSERT_TRUE(front.count(Triple{x, z, y})) << "reverse face " << f << " is no front face reversed";
    ASSERT_FALSE(front.count(Triple{x, y, z})) << "reverse face " << f << " has its front's winding";
  }
  EXPECT_GT(reverse_faces, 0);
  for (int i = 0; i < a.character.mesh.num_vertices(); ++i) {
    if (a.side[size_t(i)] == ArtistSide::kFront) continue;
    const int s = a.source[size_t(i)];
    const float d = a.offset[size_t(i)];
    reverse_vertices += a.side[size_t(i)] == ArtistSide::kReverse;
    if (a.side[size_t(i)] == ArtistSide::kReverse) {
      ASSERT_GE(d, o.back_offset_min);
      ASSERT_LE(d, o.back_offset_max);
    } else {
      ASSERT_GE(d, o.layer_offset_min);
      ASSERT_LE(d, o.layer_offset_max);
    }
    const Eigen::RowVector3f expected = c.source.mesh.V.row(s) + d * normals.row(s);
    ASSERT_LT((a.character.mesh.V.row(i) - expected).norm(), 1e-6f) << "vertex " << i;
    ASSERT_NEAR((a.character.mesh.V.row(i) - c.source.mesh.V.row(s)).norm(), d, 1e-6f);
  }
  EXPECT_GT(reverse_vertices, 0);
  // Never welded to their front: the reverse sides are their own welded parts, linked by proximity.
  EXPECT_GT(o.back_offset_min, kWeldTolerance);
}

TEST(ArtistStyle, WeldingGivesBackAboutTheSourceParts) {
  const Character& c = test_character();
  const ArtistStyleCharacter& a = c.remake;
  const MeshConstruction source = mesh_construction(c.source.mesh.V, c.source.mesh.F);
  // The front side alone welds back into the source's parts (plus the hair cap, minus or plus what the holes
  // under the clothes cut off the body).
  std::vector<Eigen::Vector3i> front;
  for (int f = 0; f < a.character.mesh.num_faces(); ++f)
    if (a.side[size_t(a.character.mesh.F(f, 0))] == ArtistSide::kFront) front.push_back(a.character.mesh.F.row(f));
  MatrixX3i F(Eigen::Index(front.size()), 3);
  for (size_t f = 0; f < front.size(); ++f) F.row(Eigen::Index(f)) = front[f].transpose();
  std::vector<int32_t> used;
  for (const auto& f : front) used.insert(used.end(), {f[0], f[1], f[2]});
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  const TriMesh front_mesh = submesh(a.character.mesh.V, F, used);
  const int front_welded = welded_parts(front_mesh.V, front_mesh.F);
  EXPECT_GE(front_welded, source.parts);
  EXPECT_LE(front_welded, source.parts + 4);
  // Everything: each strip's reverse side and layer is its own welded part at most (neighbouring strips' reverse
  // sides at the same offset weld together).
  const int all = welded_parts(a.character.mesh.V, a.character.mesh.F);
  EXPECT_GT(all, front_welded);
  EXPECT_LE(all, front_welded + 2 * a.num_strips);
}

TEST(ArtistStyle, DeterministicFromTheSeed) {
  const Character& c = test_character();
  const ArtistStyleCharacter again = artist_style_character(c.source);
  EXPECT_EQ(again.character.mesh.V, c.remake.character.mesh.V);
  EXPECT_EQ(again.character.mesh.F, c.remake.character.mesh.F);
  EXPECT_EQ(again.source, c.remake.source);
  EXPECT_EQ(again.offset, c.remake.offset);
  ArtistStyleOptions other;
  other.seed = 2;
  const ArtistStyleCharacter different = artist_style_character(c.source, other);
  EXPECT_FALSE(different.character.mesh.F.rows() == c.remake.character.mesh.F.rows() &&
               different.character.mesh.F == c.remake.character.mesh.F);
}

TEST(ArtistStyle, SubdivisionReachesTheTargetAndInterpolatesTheGroundTruth) {
  const Character& c = test_character();
  ArtistStyleOptions o;
  o.target_vertices = 20000;
  const ArtistStyleCharacter a = artist_style_character(c.source, o);
  const int M = a.character.mesh.num_vertices();
  std::printf("subdivided: %d vertices (target %d), %d midpoints\n", M, o.target_vertices, int(a.midpoints.rows()));
  EXPECT_NEAR(M, o.target_vertices, 0.05 * o.target_vertices);
  ASSERT_GT(a.midpoints.rows(), 0);
  const MeshConstruction m = mesh_construction(a.character.mesh.V, a.character.mesh.F);
  EXPECT_GE(m.coincident_share, 0.68);
  EXPECT_LE(m.coincident_share, 0.84);
  const auto [frame, joints] = posed_source(c.source);
  const MatrixX3f posed = remake_frame(a, frame, joints);
  const MatrixX2i pairs = coincident_pairs(a.character.mesh.V, a.character.mesh.F);
  for (Eigen::Index p = 0; p < pairs.rows(); ++p) {
    if (a.source[size_t(pairs(p, 0))] != a.source[size_t(pairs(p, 1))]) continue;
    ASSERT_EQ(posed.row(pairs(p, 0)), posed.row(pairs(p, 1)));
  }
  // A front copy of a midpoint is the mean of its source edge's ends, in the two-source form too.
  int midpoints = 0;
  for (int i = 0; i < M; ++i) {
    if (a.source[size_t(i)] < 0 || a.offset[size_t(i)] != 0.0f) continue;
    const int p0 = a.source_pairs(i, 0), p1 = a.source_pairs(i, 1);
    const Eigen::RowVector3f expected = a.source_weights(i, 0) * frame.row(p0) + a.source_weights(i, 1) * frame.row(p1);
    ASSERT_LT((posed.row(i) - expected).norm(), 1e-6f) << "vertex " << i;
    midpoints += p0 != p1;
    if (p0 != p1) {
      ASSERT_TRUE(a.source_weights(i, 0) == 0.5f && a.source_weights(i, 1) == 0.5f);
    }
  }
  EXPECT_GT(midpoints, 0);
}

TEST(ArtistStyle, BadOptionsAndCharactersThrowOneLine) {
  const Character& c = test_character();
  const auto error = [&](const CharacterData& character, const ArtistStyleOptions& o) {
    try {
      artist_style_character(character, o);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  // One option out of range each, and the message it gives.
  const std::vector<std::pair<void (*)(ArtistStyleOptions&), std::string>> cases = {
      {[](ArtistStyleOptions& o) { o.target_vertices = 10; },
       "artist style: target vertices: expected 0 (no subdivision) or >= 1000, found 10"},
      {[](ArtistStyleOptions& o) { o.back_offset_min = 0.0005f; }, "artist style: reverse side offset: expected"},
      {[](ArtistStyleOptions& o) { o.layer_offset_min = 0.002f; }, "artist style: layer offset: expected"},
      {[](ArtistStyleOptions& o) { o.strip_width = 0; }, "artist style: strip width: expected > 0 metres, found 0"},
      {[](ArtistStyleOptions& o) { o.island_faces = 1; }, "artist style: island faces: expected >= 2, found 1"},
      {[](ArtistStyleOptions& o) { o.layer_share = 2; }, "artist style: layer share: expected in [0, 1], found 2"},
  };
  for (const auto& [change, expected] : cases) {
    ArtistStyleOptions o;
    change(o);
    const std::string message = error(c.source, o);
    EXPECT_NE(message.find(expected), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
  CharacterData other = c.source;
  other.skeleton.names[0] = "hips";
  EXPECT_NE(error(other, {}).find("artist style: tiny: expected the canonical skeleton's 22 joints"),
            std::string::npos);
  // A frame of another size.
  EXPECT_THROW(remake_frame(c.remake, MatrixX3f::Zero(3, 3), rest_pose(c.source.skeleton)), Error);
}

// === Measures of falling apart, by hand

// Two apparel triangles: A = (0, 1, 2), and B = (3, 4, 5) whose vertex 3 coincides with vertex 1 at rest.
TEST(SeparationMeasures, TearingSeamGapAndApparelElsByHand) {
  MatrixX3f rest(6, 3);
  rest << 0, 0, 0, 0.1f, 0, 0, 0, 0.1f, 0,  // A
      0.1f, 0, 0, 1.1f, 0, 0, 0.1f, 1, 0;   // B
  MatrixX3i F(2, 3);
  F << 0, 1, 2, 3, 4, 5;
  const MatrixX2i pairs = coincident_pairs(rest, F);
  ASSERT_EQ(pairs.rows(), 1);
  EXPECT_EQ(pairs(0, 0), 1);
  EXPECT_EQ(pairs(0, 1), 3);
  const std::vector<uint8_t> mask(6, 1);
  const MatrixX2i edges = apparel_edges(unique_edges(F), mask);
  ASSERT_EQ(edges.rows(), 6);
  EXPECT_EQ(apparel_edges(unique_edges(F), {1, 0, 0, 0, 0, 0}).rows(), 2);  // the edges at vertex 0

  // Four frames of ground truth at rest. Frame 1: vertex 0 moved to x = -0.06 (edge 0-1 60 % longer: torn; edge
  // 0-2 from 0.1 to 0.1166, 17 % longer: not torn). Frame 2: vertex 3 moved 3 cm along z (the seam opens 3 cm;
  // edges 3-4 and 3-5 lengthen by a factor sqrt(1 + 0.03^2)).
  SeparationAccumulator acc(pairs, edges);
  acc.begin_clip();
  for (int t = 0; t < 4; ++t) {
    MatrixX3f pred = rest;
    if (t == 1) pred(0, 0) = -0.06f;
    if (t == 2) pred(3, 2) = 0.03f;
    acc.add_frame(pred, rest);
  }
  acc.end_clip();
  const SeparationScores s = acc.result();
  EXPECT_EQ(s.pairs, 1);
  EXPECT_EQ(s.pair_frames, 4);
  EXPECT_EQ(s.edge_frames, 24);
  EXPECT_NEAR(s.tearing, 1.0 / 24.0, 1e-12);
  // Gaps 0, 0, 3, 0 cm: the nearest-rank 95th percentile is the 4th smallest, 3 cm; the largest 3 cm.
  EXPECT_NEAR(s.seam_gap_p95_cm, 3.0, 1e-5);
  EXPECT_NEAR(s.seam_gap_max_cm, 3.0, 1e-5);
  const double e02 = std::sqrt(0.06 * 0.06 + 0.01) / 0.1;  // 1.1662
  const double frame1 = (4.0 + (1.0 - 0.6) + (1.0 - (e02 - 1.0))) / 6.0;
  const double stretch = std::sqrt(1.0 + 0.03 * 0.03) - 1.0;
  const double frame2 = (4.0 + 2.0 * (1.0 - stretch)) / 6.0;
  EXPECT_NEAR(s.apparel_els, (1.0 + frame1 + frame2 + 1.0) / 4.0, 1e-6);

  // Without frame 1: gaps 0, 3, 0 over three frames, nothing torn; the 95th percentile still the 3 cm.
  SeparationAccumulator quiet(pairs, edges);
  quiet.begin_clip();
  for (int t = 0; t < 3; ++t) {
    MatrixX3f pred = rest;
    if (t == 1) pred(3, 2) = 0.03f;
    quiet.add_frame(pred, rest);
  }
  quiet.end_clip();
  EXPECT_EQ(quiet.result().tearing, 0.0);
  EXPECT_NEAR(quiet.result().seam_gap_p95_cm, 3.0, 1e-5);
  EXPECT_TRUE(std::isnan(quiet.result().rest_tearing));  // no rest mesh given

  // Against rest lengths: a ground truth with vertex 0 at x = -0.15 (edge 0-1 2.5 times its rest length, edge 0-2
  // 1.80 times) and a prediction at rest. Edge 0-1 is torn (0.1 / 0.25: off by 60 %) where the ground truth deforms;
  // edge 0-2 is not (0.1 / 0.180: off by 44.5 %); the prediction's own edges are all at rest.
  SeparationAccumulator against_rest(pairs, edges, rest);
  against_rest.begin_clip();
  MatrixX3f deformed = rest;
  deformed(0, 0) = -0.15f;
  against_rest.add_frame(rest, deformed);
  against_rest.end_clip();
  const SeparationScores r = against_rest.result();
  EXPECT_NEAR(r.tearing, 1.0 / 6.0, 1e-12);
  EXPECT_NEAR(r.tearing_ground_truth_deformed, 1.0 / 6.0, 1e-12);
  EXPECT_NEAR(r.ground_truth_rest_tearing, 2.0 / 6.0, 1e-12);
  EXPECT_EQ(r.rest_tearing, 0.0);

  // No pairs, no apparel edges: NaN, not zero.
  SeparationAccumulator none(MatrixX2i(0, 2), MatrixX2i(0, 2));
  none.begin_clip();
  none.add_frame(rest, rest);
  none.end_clip();
  EXPECT_TRUE(std::isnan(none.result().tearing));
  EXPECT_TRUE(std::isnan(none.result().seam_gap_p95_cm));
  EXPECT_TRUE(std::isnan(none.result().apparel_els));
}

}  // namespace
}  // namespace amt
