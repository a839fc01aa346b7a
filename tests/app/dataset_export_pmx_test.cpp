// `amt dataset export-pmx`: a character of a dataset build as a PMX file that reads back with the character's
// mesh and apparel; bad options are one-line errors that write nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "data_tools/builder/pmx_character_export.h"
#include "data_tools/builder/pmx_physics.h"
#include "data_tools/formats/pmx_import.h"
#include "tests/app/amt_cli.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

TEST(DatasetExportPmxCommand, WritesTheBuildsCharacterWithItsApparelRig) {
  const fs::path dir = test::temp_dir("dataset_export_pmx");
  const test::CommandResult r =
      test::expect_success(dir, {"dataset", "export-pmx", "--seed", "11", "--character", "1", "--vertices", "1000",
                                 "--out", "models/character-0001.pmx", "--threads", "1"});
  EXPECT_EQ(r.out.rfind("wrote models/character-0001.pmx: ", 0), 0u) << r.out;
  const PmxModel model = read_pmx((dir / "models" / "character-0001.pmx").string());
  EXPECT_EQ(model.header.name, "character-0001");

  DatasetBuildOptions options;
  options.seed = 11;
  options.characters = 2;
  options.vertices = 1000;
  const DressedCharacter expected = dataset_character(options, 1);
  ASSERT_EQ(model.vertices.size(), expected.mesh.V.rows());
  EXPECT_LT((pmx_to_amt_frame(model).vertices.positions - expected.mesh.V).cwiseAbs().maxCoeff(), 1e-5f);
  EXPECT_EQ(pmx_physics_apparel_mask(model), expected.apparel_mask);
  EXPECT_EQ(pmx_physics_rig(model).num_bodies(), expected.rig.num_bodies());
  EXPECT_NE(r.out.find(std::to_string(expected.num_apparel_bodies()) + " simulated"), std::string::npos) << r.out;
}

TEST(DatasetExportPmxCommand, BadOptionsAreOneLineErrorsThatWriteNothing) {
  const fs::path dir = test::temp_dir("dataset_export_pmx_bad");
  test::users_folder(dir, "mine.pmx");
  std::ofstream(dir / "notes.txt") << "the user's notes\n";
  // A valid run's options with `option` set to `value`.
  const auto export_pmx = [](const std::string& option, const std::string& value) {
    std::map<std::string, std::string> options = {{"--out", "c.pmx"}, {"--vertices", "1000"}, {"--threads", "1"}};
    options[option] = value;
    std::vector<std::string> args = {"dataset", "export-pmx"};
    for (const auto& [name, v] : options) args.insert(args.end(), {name, v});
    return args;
  };
  test::expect_errors_writing_nothing(
      dir, {{export_pmx("--out", "c.obj"), {"c.obj: --out: expected a file name ending in .pmx"}},
            {export_pmx("--character", "-1"), {"dataset export-pmx: --character: expected 0 to 99999, found -1"}},
            {export_pmx("--vertices", "10"), {"dataset export-pmx: --vertices: expected 1000 to", "found 10"}},
            {export_pmx("--metres-per-unit", "0"),
             {"dataset export-pmx: --metres-per-unit: expected a number > 0, found 0"}},
            {export_pmx("--out", "mine.pmx"), {"mine.pmx", "a folder"}}});
}

// The apparel physics options dress the character as `amt dataset build` with the same options does: the exported
// rigid bodies are those of that character, and not those of the default build.
TEST(DatasetExportPmxCommand, ApparelPhysicsOptionsDressAsTheBuildDoes) {
  const fs::path dir = test::temp_dir("dataset_export_pmx_physics");
  test::expect_success(dir, {"dataset", "export-pmx", "--seed", "11", "--character", "1", "--vertices", "1000",
                             "--apparel-damping", "1.5", "--apparel-stiffness", "0.5", "--apparel-variation", "0.5",
                             "--out", "c.pmx", "--threads", "1"});
  const PmxModel model = read_pmx((dir / "c.pmx").string());
  DatasetBuildOptions options;
  options.seed = 11;
  options.characters = 2;
  options.vertices = 1000;
  const PmxModel plain = pmx_from_character(dataset_character(options, 1), {});
  options.apparel.damping_scale = 1.5f;
  options.apparel.stiffness_scale = 0.5f;
  options.apparel.physics_variation = 0.5f;
  const PmxModel expected = pmx_from_character(dataset_character(options, 1), {});
  ASSERT_EQ(model.rigid_bodies.size(), expected.rigid_bodies.size());
  ASSERT_EQ(model.joints.size(), expected.joints.size());
  float differs = 0.0f;
  for (size_t b = 0; b < model.rigid_bodies.size(); ++b) {
    EXPECT_FLOAT_EQ(model.rigid_bodies[b].mass, expected.rigid_bodies[b].mass) << b;
    EXPECT_FLOAT_EQ(model.rigid_bodies[b].linear_damping, expected.rigid_bodies[b].linear_damping) << b;
    EXPECT_FLOAT_EQ(model.rigid_bodies[b].angular_damping, expected.rigid_bodies[b].angular_damping) << b;
    differs = std::max(differs, std::abs(model.rigid_bodies[b].angular_damping - plain.rigid_bodies[b].angular_damping));
  }
  for (size_t k = 0; k < model.joints.size(); ++k) {
    EXPECT_LT((model.joints[k].spring_angular - expected.joints[k].spring_angular).cwiseAbs().maxCoeff(), 1e-6f) << k;
  }
  EXPECT_GT(differs, 0.01f) << "the options changed nothing";
  test::expect_errors_writing_nothing(
      dir, {{{"dataset", "export-pmx", "--vertices", "1000", "--apparel-damping", "0", "--out", "d.pmx"},
             {"apparel options: damping_scale: expected a positive value, found 0"}}});
}

}  // namespace
}  // namespace amt
