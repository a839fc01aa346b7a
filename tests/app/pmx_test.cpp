// PMX models on the command line: `amt dataset build --pmx` on the MMD-style test humanoid, then `amt dataset
// check` and `amt dataset info` on the result, and `amt animate --apparel physics` writing a GLB from the model's
// own physics, with its one-line errors (a character without a physics rig, a PMX without simulated bodies).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/pmx_export.h"
#include "tests/app/amt_cli.h"
#include "tests/data_tools/builder/pmx_humanoid.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

std::string cmu_walk() {
  return std::string(AMT_ASSET_DIR) + "/mocap/cmu/02_01.bvh";
}

// The model with its vertices in reverse file order (faces follow; PMX morphs are not read).
PmxModel with_reversed_vertices(PmxModel m) {
  PmxVertices& v = m.vertices;
  const int n = int(v.positions.rows());
  v.positions = v.positions.colwise().reverse().eval();
  v.normals = v.normals.colwise().reverse().eval();
  v.uvs = v.uvs.colwise().reverse().eval();
  for (auto& extra : v.additional_uvs) extra = extra.colwise().reverse().eval();
  std::reverse(v.deform.begin(), v.deform.end());
  v.bone_indices = v.bone_indices.colwise().reverse().eval();
  v.bone_weights = v.bone_weights.colwise().reverse().eval();
  v.sdef_c = v.sdef_c.colwise().reverse().eval();
  v.sdef_r0 = v.sdef_r0.colwise().reverse().eval();
  v.sdef_r1 = v.sdef_r1.colwise().reverse().eval();
  v.edge_scale = v.edge_scale.reverse().eval();
  m.faces = (n - 1 - m.faces.array()).matrix();
  return m;
}

TEST(PmxCommands, DatasetBuildFromAPmxThenCheckAndInfo) {
  const fs::path dir = test::temp_dir("pmx_dataset_cli");
  fs::create_directories(dir / "models");
  write_pmx(test::pmx_humanoid(), (dir / "models" / "humanoid.pmx").string());
  const test::CommandResult built =
      test::expect_success(dir, {"dataset", "build", "--out", "data", "--pmx", "models", "--motions", "",
                                 "--procedural", "2", "--frames", "12", "--threads", "1"});
  EXPECT_EQ(built.out, "wrote data\n");
  EXPECT_NE(built.err.find("pmx-0000 <- models/humanoid.pmx: 168 vertices, 28 bones, 5 rigid bodies (3 simulated)"),
            std::string::npos)
      << built.err;
  EXPECT_NE(built.err.find("built 1 characters (0 already done), 2 clips"), std::string::npos) << built.err;
  for (const char* file : {"manifest.json", "pmx-0000.h5", "pmx-0000.json"})
    EXPECT_TRUE(fs::is_regular_file(dir / "data" / file)) << file;
  const DatasetReader reader((dir / "data" / "pmx-0000.h5").string());
  const CharacterData character = reader.read_character("pmx-0000");
  EXPECT_EQ(character.rig->num_bones(), 28);
  int apparel = 0;
  for (const uint8_t m : character.apparel_mask) apparel += m;
  EXPECT_EQ(apparel, 24);  // the three hair boxes

  // amt animate on a PMX whose hair comes first in the file, scored against the dataset built from it, which puts
  // the body first: matched by rest position, the body exact with the model's own weights.
  fs::create_directories(dir / "reversed");
  write_pmx(with_reversed_vertices(test::pmx_humanoid()), (dir / "reversed" / "humanoid.pmx").string());
  test::expect_success(dir, {"dataset", "build", "--out", "reversed_data", "--pmx", "reversed", "--motions", "",
                             "--procedural", "2", "--frames", "12", "--threads", "1"});
  std::string held_out;
  const DatasetReader reversed((dir / "reversed_data" / "pmx-0000.h5").string());
  for (const std::string& clip : reversed.clip_names())
    if (reversed.clip_info(clip).split == "test") held_out = clip;
  ASSERT_FALSE(held_out.empty());
  test::expect_success(
      dir, {"animate", "--character", "reversed/humanoid.pmx", "--motion", "reversed_data/pmx-0000.h5:" + held_out,
            "--apparel", "physics", "--out", "pred.h5", "--threads", "1", "--quiet"});
  const test::CommandResult scored =
      test::expect_success(dir, {"eval", "--data", "reversed_data", "--predictions", "pred.h5", "--out", "scored",
                                 "--no-plots", "--no-penetration", "--threads", "1", "--quiet"});
  EXPECT_NE(scored.err.find("pred.h5: /characters/humanoid: vertices in another order than pmx-0000's, matched by "
                            "rest position"),
            std::string::npos)
      << scored.err;
  const size_t body = scored.out.find("PMD_b ");
  ASSERT_NE(body, std::string::npos) << scored.out;
  EXPECT_LT(std::stod(scored.out.substr(body + 6)), 1e-3) << scored.out;  // cm

  const test::CommandResult info = test::expect_success(dir, {"dataset", "info", "data", "--threads", "1"});
  EXPECT_NE(info.out.find("totals: 1 character"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("missing, damaged or not in the manifest: none"), std::string::npos) << info.out;

  // check runs its gates on the PMX shard (whether the hair's lag is in the procedural bounds is a figure, not
  // this test's business): every gate line is printed and the report written.
  const test::CommandResult check = test::run_amt(dir, {"dataset", "check", "data", "--threads", "1"});
  for (const char* gate : {"apparel lag", "no NaN: 0 non-finite", "no explosion", "no jump", "penetration"})
    EXPECT_NE(check.out.find(gate), std::string::npos) << gate << " not in: " << check.out << check.err;
  EXPECT_NE(check.out.find("PASS no NaN"), std::string::npos) << check.out;
  EXPECT_NE(check.out.find("PASS no explosion"), std::string::npos) << check.out;
  EXPECT_TRUE(fs::is_regular_file(dir / "data" / "quality" / "report.md"));

  // A model with broken physics is repaired with a warning line naming the file, the body and the field.
  PmxModel broken = test::pmx_humanoid();
  broken.rigid_bodies[3].mass = 0;
  fs::create_directories(dir / "broken");
  write_pmx(broken, (dir / "broken" / "broken.pmx").string());
  const test::CommandResult repaired =
      test::expect_success(dir, {"dataset", "build", "--out", "repaired", "--pmx", "broken/broken.pmx", "--motions", "",
                                 "--procedural", "1", "--frames", "4", "--threads", "1"});
  EXPECT_NE(repaired.err.find("build: warning: broken/broken.pmx: rigid_bodies[3] '髪2': mass: expected a positive "
                              "mass on a simulated body (mode 1), found 0; it follows its bone (mode 0)"),
            std::string::npos)
      << repaired.err;

  // A rerun naming another model in the folder's place is refused, writing nothing.
  PmxModel other = test::pmx_humanoid();
  other.rigid_bodies[2].mass = 3.0f;
  write_pmx(other, (dir / "models" / "humanoid.pmx").string());
  test::expect_errors_writing_nothing(
      dir, {{{"dataset", "build", "--out", "data", "--pmx", "models", "--motions", "", "--procedural", "2", "--frames",
              "12"},
             {"data: the folder holds a dataset built with other settings", "pmx_files.0.fnv1a64"}},
            {{"dataset", "build", "--out", "other", "--pmx", "nowhere.pmx", "--motions", ""},
             {"nowhere.pmx: --pmx: expected a PMX file or a folder of them"}}});
}

// A build that fails before its first shard (a simulation that stops on the model, say) leaves its manifest.json
// alone in the folder; the rerun with the model fixed, into the same folder, builds without the folder being
// deleted by hand. The failed run's folder is made here from the manifest of a build of the model before the fix.
TEST(PmxCommands, ARerunAfterAFailedPmxBuildNeedsNoCleanUp) {
  const fs::path dir = test::temp_dir("pmx_dataset_rerun");
  fs::create_directories(dir / "models");
  PmxModel before = test::pmx_humanoid();
  before.rigid_bodies[2].mass = 3.0f;
  write_pmx(before, (dir / "models" / "humanoid.pmx").string());
  const std::vector<std::string> build = {"dataset",   "build", "--out",        "data", "--pmx",    "models",
                                          "--motions", "",      "--procedural", "1",    "--frames", "4",
                                          "--threads", "1"};
  test::expect_success(dir, build);
  fs::rename(dir / "data", dir / "first");
  fs::create_directories(dir / "data");
  fs::copy_file(dir / "first" / "manifest.json", dir / "data" / "manifest.json");

  write_pmx(test::pmx_humanoid(), (dir / "models" / "humanoid.pmx").string());  // the model, fixed
  const test::CommandResult rerun = test::expect_success(dir, build);
  EXPECT_NE(rerun.err.find("built 1 characters (0 already done), 1 clips"), std::string::npos) << rerun.err;
  EXPECT_TRUE(fs::is_regular_file(dir / "data" / "pmx-0000.h5"));
  EXPECT_NE(test::read_file_bytes(dir / "data" / "manifest.json"),
            test::read_file_bytes(dir / "first" / "manifest.json"));
  // With a shard beside it the manifest stays: the model before the fix is refused there.
  write_pmx(before, (dir / "models" / "humanoid.pmx").string());
  const test::CommandResult refused = test::run_amt(dir, build);
  EXPECT_NE(refused.status, 0);
  EXPECT_NE(refused.err.find("data: the folder holds a dataset built with other settings"), std::string::npos)
      << refused.err;
}

TEST(PmxCommands, AnimateWithTheModelsOwnPhysicsWritesAGlb) {
  const fs::path dir = test::temp_dir("pmx_animate_physics");
  write_pmx(test::pmx_humanoid(), (dir / "humanoid.pmx").string());
  const test::CommandResult run =
      test::expect_success(dir, {"animate", "--character", "humanoid.pmx", "--motion", cmu_walk(), "--apparel",
                                 "physics", "--frames", "6", "--out", "walk.glb", "--threads", "1"});
  EXPECT_EQ(run.out.rfind("wrote walk.glb", 0), 0u) << run.out;
  EXPECT_NE(run.out.find("apparel: physics (the PMX model's own 3 simulated rigid bodies and 3 joints"),
            std::string::npos)
      << run.out;
  EXPECT_NE(run.err.find("animate: apparel: physics"), std::string::npos) << run.err;
  // (The Khronos validator on such a GLB: tests/infer/pmx_physics_player_test.cpp.)
  const GltfVertexAnimation frames = gltf_vertex_animation(read_gltf((dir / "walk.glb").string()), "", 30.0f);
  ASSERT_EQ(frames.frames.size(), 6u);
  for (const MatrixX3f& V : frames.frames) {
    EXPECT_TRUE(V.allFinite());
    EXPECT_EQ(V.rows(), 168);
  }
  EXPECT_FALSE(fs::exists(dir / "walk.bind"));  // no network, no bind

  // Errors: a character without a physics rig of its own, and a PMX whose bodies all follow their bones.
  PmxModel still = test::pmx_humanoid("still.pmx");
  for (PmxRigidBody& r : still.rigid_bodies) r.mode = PmxPhysicsMode::kFollowBone;
  write_pmx(still, (dir / "still.pmx").string());
  test::expect_errors_writing_nothing(
      dir,
      {{{"animate", "--character", "generated:3", "--motion", cmu_walk(), "--apparel", "physics", "--out", "g.glb"},
        {"generated:3: --apparel physics: expected a PMX model with rigid bodies", "use --apparel learned"}},
       {{"animate", "--character", "still.pmx", "--motion", cmu_walk(), "--apparel", "physics", "--out", "s.glb"},
        {"still.pmx: --apparel physics: expected a PMX model with simulated rigid bodies", "none simulated"}},
       {{"animate", "--character", "humanoid.pmx", "--motion", cmu_walk(), "--apparel", "physics", "--html", "v"},
        {"--html: expected no viewer folder with --apparel physics"}}});
  test::expect_one_line_error(test::run_amt(dir, {"animate", "--character", "humanoid.pmx", "--motion", cmu_walk(),
                                                  "--apparel", "cloth", "--out", "c.glb"}),
                              {"--apparel"}, 2);
}

}  // namespace
}  // namespace amt
