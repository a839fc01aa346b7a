// Tests of data_tools/builder/dataset_quality.h on a hand-made dataset whose figures are computed by hand: a sphere
// body skinned to the pelvis at rest, a 2x2-vertex apparel patch half a metre in front of the pelvis that the
// "simulation" moves by known amounts.
#include "data_tools/builder/dataset_quality.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/shapes.h"
#include "tests/test_support.h"

namespace amt {
namespace {

using test::error_of;
namespace fs = std::filesystem;

// Writes DIR/character-0000.h5 and its record. Clip "a" (3 frames): the patch moves 10 cm along +X per frame.
// Clip "b" (2 frames): the patch jumps 35 cm into the body at frame 1. With `seam_gap` > 0 the patch has a fifth
// vertex, a seam copy of its vertex 3 (on a face of its own with vertices 0 and 1), that moves `seam_gap` metres
// away from it along +Y at frame 2 of clip a.
void write_hand_made_dataset(const fs::path& dir, Eigen::Vector3f* pelvis_out, float seam_gap = 0) {
  const Skeleton skeleton = canonical_skeleton();
  const Eigen::Vector3f P = skeleton.rest_joints.row(kPelvis).transpose();
  *pelvis_out = P;
  TriMesh body = uv_sphere(P, 0.3f, 16, 8);
  TriMesh patch = grid(2, 2, 0.01f);  // (0,0), (0.01,0), (0,0.01), (0.01,0.01) in XY
  for (int i = 0; i < 4; ++i) patch.V.row(i) += (P + Eigen::Vector3f(0, -0.01f, 0.5f)).transpose();
  if (seam_gap > 0) {
    patch.V.conservativeResize(5, 3);
    patch.V.row(4) = patch.V.row(3);
    patch.F.conservativeResize(3, 3);
    patch.F.row(2) << 0, 1, 4;
  }
  const TriMesh mesh = merge_meshes({body, patch});
  const int Nb = body.num_vertices(), N = mesh.num_vertices();

  CharacterData character;
  character.name = "character-0000";
  character.mesh = mesh;
  character.skeleton = skeleton;
  character.apparel_mask.assign(N, 0);
  for (int i = Nb; i < N; ++i) character.apparel_mask[i] = 1;
  character.body_weights = MatrixXfR::Zero(N, kCanonicalJointCount);
  character.body_weights.col(kPelvis).setOnes();
  character.split = "train";

  const fs::path shard = dir / "character-0000.h5";
  DatasetWriter writer(shard.string(), 30.0f, canonical_joint_names());
  writer.add_character(character);
  const Transforms rest = forward_kinematics(skeleton, rest_motion(skeleton, 1), 0);
  auto write_clip = [&](const std::string& name, const std::vector<Eigen::Vector3f>& offsets, bool into_body) {
    writer.begin_clip({name, character.name, "hand", "train", 30.0f, 0, GroundTruth::kVertices});
    for (size_t t = 0; t < offsets.size(); ++t) {
      MatrixX3f V = mesh.V;
      for (int i = Nb; i < N; ++i) {
        if (into_body && t > 0) {
          V.row(i) = mesh.V.row(i) - Eigen::RowVector3f(0, 0, 0.35f);  // 15 cm in front of the pelvis: inside
        } else {
          V.row(i) += offsets[t].transpose();
        }
      }
      if (seam_gap > 0 && name.back() == 'a' && t == 2) V(N - 1, 1) += seam_gap;
      writer.append_frame(rest, V);
    }
    writer.end_clip();
  };
  write_clip("character-0000__a", {{0, 0, 0}, {0.1f, 0, 0}, {0.2f, 0, 0}}, false);
  write_clip("character-0000__b", {{0, 0, 0}, {0, 0, 0}}, true);
  writer.commit();

  std::ofstream(dir / "character-0000.json")
      << "{\"format\": \"amt-character-record\", \"version\": 1, \"params\": {\"height\": 1.7, \"head_ratio\": 0.13, "
         "\"leg_ratio\": 0.62, \"arm_angle_deg\": 30}, \"body_vertices\": "
      << Nb << ", \"body_faces\": " << body.num_faces()
      << ", \"apparel_bodies\": 1, \"pieces\": [{\"kind\": \"cape\", \"attachment_joint\": 0, \"chain_length\": 0.5, "
         "\"first_vertex\": "
      << Nb << ", \"end_vertex\": " << N << "}]}\n";
}

TEST(DatasetQuality, HandMadeDatasetGivesHandComputedFigures) {
  const fs::path dir = test::temp_dir("dataset_quality_hand");
  Eigen::Vector3f P;
  write_hand_made_dataset(dir, &P);
  QualityOptions options;
  options.penetration_stride = 1;
  options.max_jump_cm = 30.0;  // below the 35 cm move of clip b
  options.report_dir = (dir / "quality").string();
  const DatasetQuality q = check_dataset(dir.string(), options);

  ASSERT_EQ(q.characters.size(), 1u);
  EXPECT_EQ(q.clips, 2);
  EXPECT_EQ(q.frames, 5);
  // Rigid skinning keeps the patch at rest. Clip a: 0, 10, 20 cm -> 10 cm; clip b: 0, 35 cm -> 17.5 cm.
  EXPECT_NEAR(q.lag_cm, (10.0 + 17.5) / 2, 1e-3);
  EXPECT_NEAR(q.characters[0].lag_cm, 13.75, 1e-3);
  EXPECT_NEAR(q.max_jump_cm, 35.0, 1e-3);  // rigid skinning holds the patch still: relative = absolute
  EXPECT_NEAR(q.max_relative_jump_cm, 35.0, 1e-3);
  EXPECT_EQ(q.max_joint_jump_cm, 0.0);
  EXPECT_EQ(q.max_jump_where, "character-0000__b frame 1");
  // Farthest: vertex (0.01, 0) of the patch at frame 2 of clip a, at (0.21, -0.01, 0.5) from the pelvis.
  EXPECT_NEAR(q.max_stretch, std::sqrt(0.21 * 0.21 + 0.01 * 0.01 + 0.25) / 0.5, 1e-5);
  EXPECT_EQ(q.max_stretch_where, "character-0000__a frame 2");
  // One of five measured frames has the whole patch inside the sphere.
  EXPECT_EQ(q.penetration_frames, 5);
  EXPECT_NEAR(q.penetration_share, 0.2, 1e-9);
  EXPECT_EQ(q.non_finite, 0);

  ASSERT_EQ(q.gates.size(), 6u);
  EXPECT_TRUE(q.gates[0].passed);   // lag 13.75 cm in [3, 15]
  EXPECT_TRUE(q.gates[1].passed);   // no NaN
  EXPECT_TRUE(q.gates[2].passed);   // stretch 1.08 <= 1.5
  EXPECT_FALSE(q.gates[3].passed);  // jump 35 cm > 30
  EXPECT_FALSE(q.gates[4].passed);  // penetration 20 % >= 2 %
  EXPECT_TRUE(q.gates[5].passed);   // seams: nothing moves apart
  EXPECT_TRUE(q.flagged.empty());
  EXPECT_EQ(q.failed_gates(), 2);

  // Stride 2 measures frames 0 and 2 of clip a and frame 0 of clip b: no penetration.
  options.penetration_stride = 2;
  const DatasetQuality strided = check_dataset(dir.string(), options);
  EXPECT_EQ(strided.penetration_frames, 3);
  EXPECT_EQ(strided.penetration_share, 0.0);

  write_quality_report(q, options);
  std::ifstream report(dir / "quality" / "report.md");
  std::stringstream text;
  text << report.rdbuf();
  EXPECT_NE(text.str().find("| no jump | FAIL |"), std::string::npos);
  EXPECT_NE(text.str().find("| character-0000 | train | 1.70 | 0.130 | 0.62 | A-pose 30 deg | cape |"),
            std::string::npos)
      << text.str();
  std::ifstream png(dir / "quality" / "characters.png", std::ios::binary);
  char signature[8] = {};
  png.read(signature, 8);
  EXPECT_EQ(std::string(signature + 1, 3), "PNG");
  std::ostringstream lines;
  print_gates(q, lines);
  EXPECT_NE(lines.str().find("FAIL no jump: largest frame-to-frame apparel vertex move 35.0 cm"), std::string::npos)
      << lines.str();
  EXPECT_NE(lines.str().find("PASS apparel lag"), std::string::npos);
}

// A seam copy that moves 8 mm away in one of the five frames: the largest gap is over 5 mm, the character is
// flagged with one line naming it; 0.4 mm passes (with the sphere's seams, if any, the 95th percentile of the
// pair-frames is at most that one gap).
TEST(DatasetQuality, CoincidentVerticesMovingApartFlagTheCharacter) {
  const fs::path dir = test::temp_dir("dataset_quality_seam");
  Eigen::Vector3f P;
  write_hand_made_dataset(dir, &P, 0.008f);
  const DatasetQuality q = check_dataset(dir.string(), {});
  ASSERT_EQ(q.characters.size(), 1u);
  const CharacterQuality& c = q.characters[0];
  EXPECT_GE(c.seam_pairs, 1);
  EXPECT_NEAR(c.seam_gap_max_mm, 8.0, 1e-3);
  // The one pair-frame of 8 mm is under 5 % of them when the sphere has seams of its own, else the 95th
  // percentile is that 8 mm too.
  EXPECT_LE(c.seam_gap_p95_mm, 8.0 + 1e-3);
  ASSERT_EQ(q.flagged.size(), 1u);
  EXPECT_EQ(q.flagged[0].rfind("character-0000 (character-0000.h5): coincident vertices move apart in its own ground "
                               "truth: 95th percentile ",
                               0),
            0u)
      << q.flagged[0];
  EXPECT_NE(q.flagged[0].find("largest 8.00 mm over "), std::string::npos) << q.flagged[0];
  EXPECT_EQ(q.flagged[0].find('\n'), std::string::npos);
  ASSERT_EQ(q.gates.back().name, "seams hold");
  EXPECT_FALSE(q.gates.back().passed);
  std::ostringstream lines;
  print_gates(q, lines);
  EXPECT_NE(lines.str().find("FAIL seams hold: 1 of 1 characters"), std::string::npos) << lines.str();
  EXPECT_NE(lines.str().find("FLAG character-0000 (character-0000.h5): coincident vertices move apart"),
            std::string::npos);

  const fs::path small = test::temp_dir("dataset_quality_seam_small");
  write_hand_made_dataset(small, &P, 0.0004f);
  const DatasetQuality ok = check_dataset(small.string(), {});
  EXPECT_NEAR(ok.characters[0].seam_gap_max_mm, 0.4, 1e-3);
  EXPECT_TRUE(ok.flagged.empty());
  EXPECT_TRUE(ok.gates.back().passed);
}

TEST(DatasetQuality, FoldersWithoutShardsOrRecordsGiveErrors) {
  const fs::path empty = test::temp_dir("dataset_quality_empty");
  EXPECT_NE(error_of([&] { check_dataset(empty.string(), {}); }).find("no shard"), std::string::npos);
  const fs::path dir = test::temp_dir("dataset_quality_no_record");
  Eigen::Vector3f P;
  write_hand_made_dataset(dir, &P);
  fs::remove(dir / "character-0000.json");
  const std::string message = error_of([&] { check_dataset(dir.string(), {}); });
  EXPECT_NE(message.find("character-0000.json: missing"), std::string::npos) << message;
}

}  // namespace
}  // namespace amt
