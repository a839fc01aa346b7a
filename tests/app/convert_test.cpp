// `amt convert`: a PMX model from `amt dataset export-pmx` to .vrm and .glb (the summary's figures against the model's
// own chains and colliders, the springs read back, both files through the Khronos validator), the .vrm animated
// with its spring bones; bad input is a one-line error that writes nothing.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/pmx_export.h"
#include "data_tools/formats/pmx_gltf.h"
#include "data_tools/formats/pmx_import.h"
#include "tests/app/amt_cli.h"
#include "tests/data_tools/builder/pmx_humanoid.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

TEST(ConvertCommand, ExportedPmxToVrmAndGlbThenAnimatedWithItsSprings) {
  const fs::path dir = test::temp_dir("convert_cli");
  test::expect_success(dir, {"dataset", "export-pmx", "--seed", "1", "--character", "0", "--vertices", "1000", "--out",
                             "models/c0.pmx", "--threads", "1"});
  const PmxModel model = pmx_to_amt_frame(read_pmx((dir / "models" / "c0.pmx").string()));
  const std::vector<PmxSpringChain> chains = pmx_spring_chains(model);
  int joints = 0, turning = 0;
  for (const PmxSpringChain& chain : chains) {
    joints += int(chain.bones.size()) + (chain.tip ? 1 : 0);
    turning += int(chain.parameters.size());
  }
  const size_t colliders = pmx_spring_colliders(model).size();
  ASSERT_GT(chains.size(), 0u);
  ASSERT_GT(colliders, 0u);

  const test::CommandResult vrm = test::expect_success(dir, {"convert", "models/c0.pmx", "--out", "c0.vrm"});
  EXPECT_EQ(vrm.out.rfind("wrote c0.vrm (VRM 1.0, ", 0), 0u) << vrm.out;
  EXPECT_NE(vrm.out.find(std::to_string(model.vertices.size()) + " vertices (" + std::to_string(model.vertices.size()) +
                         " in the PMX), " + std::to_string(model.faces.rows()) + " faces in 1 primitives, " +
                         std::to_string(model.bones.size()) + " bones, 1 materials, textures 0 embedded / 0 left out"),
            std::string::npos)
      << vrm.out;
  EXPECT_NE(vrm.out.find("spring bones: " + std::to_string(chains.size()) + " springs with " + std::to_string(joints) +
                         " joints (" + std::to_string(turning) + " turning), " + std::to_string(colliders) +
                         " colliders in 1 groups"),
            std::string::npos)
      << vrm.out;
  EXPECT_NE(vrm.out.find("humanoid: hips=下半身, spine=上半身, chest=上半身2, upperChest=上半身3, neck=首, head=頭"),
            std::string::npos)
      << vrm.out;
  EXPECT_NE(vrm.out.find("note: 2 display frame(s): dropped"), std::string::npos) << vrm.out;
  EXPECT_NE(vrm.out.find("note: rest pose: the PMX's own"), std::string::npos) << vrm.out;
  EXPECT_EQ(vrm.err, "");

  // The springs read back as amt animate reads them: every turning joint, one spring per chain, every collider.
  const GltfAsset asset = read_gltf((dir / "c0.vrm").string());
  const GltfCharacter character = gltf_character(asset);
  EXPECT_EQ(character.mesh.V.rows(), model.vertices.size());
  const SpringRig rig = gltf_vrm_spring_rig(asset, character);
  EXPECT_EQ(rig.num_joints(), turning);
  EXPECT_EQ(rig.spring_colliders.size(), chains.size());
  EXPECT_EQ(rig.colliders.size(), colliders);
  test::expect_valid_gltf(dir / "c0.vrm");

  const test::CommandResult glb = test::expect_success(dir, {"convert", "models/c0.pmx", "--out", "c0.glb"});
  EXPECT_EQ(glb.out.rfind("wrote c0.glb (glTF 2.0, ", 0), 0u) << glb.out;
  EXPECT_EQ(glb.out.find("humanoid:"), std::string::npos) << glb.out;
  test::expect_valid_gltf(dir / "c0.glb");

  const test::CommandResult animated = test::expect_success(
      dir, {"animate", "--character", "c0.vrm", "--motion", std::string(AMT_ASSET_DIR) + "/mocap/cmu/02_01.bvh",
            "--apparel", "spring-bones", "--frames", "20", "--out", "animated.glb", "--threads", "2"});
  EXPECT_NE(animated.out.find("apparel: spring bones (the avatar's own " + std::to_string(turning) +
                              " spring segments and " + std::to_string(colliders) + " colliders"),
            std::string::npos)
      << animated.out;
  EXPECT_NE(animated.out.find("frames: 20 at 30 fps"), std::string::npos) << animated.out;
  EXPECT_GT(fs::file_size(dir / "animated.glb"), 0u);
}

TEST(ConvertCommand, BadInputIsAOneLineErrorThatWritesNothing) {
  const fs::path dir = test::temp_dir("convert_cli_errors");
  std::ofstream(dir / "notes.pmx") << "not a model\n";
  write_pmx(test::pmx_humanoid(), (dir / "humanoid.pmx").string());
  const std::string whole = test::read_file_bytes(dir / "humanoid.pmx");
  std::ofstream(dir / "cut.pmx", std::ios::binary) << whole.substr(0, whole.size() / 2);
  fs::create_hard_link(dir / "humanoid.pmx", dir / "same.glb");
  PmxModel props = test::pmx_humanoid();
  props.bones[5].name = "atama";
  write_pmx(props, (dir / "props.pmx").string());
  test::expect_errors_writing_nothing(
      dir,
      {{{"convert", "notes.pmx", "--out", "x.glb"},
        {"notes.pmx: offset 0: header.magic: expected the bytes 50 4d 58 20 (\"PMX \"), found 6e 6f 74 20"}},
       {{"convert", "cut.pmx", "--out", "x.glb"}, {"cut.pmx: offset ", ": expected "}},
       {{"convert", "missing.pmx", "--out", "x.glb"}, {"missing.pmx"}},
       {{"convert", "humanoid.pmx", "--out", "x.obj"},
        {"x.obj: --out: expected a file name ending in .glb (glTF) or .vrm (VRM 1.0), found '.obj'"}},
       {{"convert", "humanoid.pmx", "--out", "x"}, {"x: --out: expected a file name ending in .glb", "found none"}},
       {{"convert", "humanoid.pmx", "--out", "same.glb"},
        {"same.glb: --out: expected a new file, found the run's own input humanoid.pmx (MODEL)"}},
       {{"convert", "props.pmx", "--out", "props.vrm"},
        {"props.pmx: humanoid: expected a bone for each of the VRM humanoid bones head (頭)", "write a .glb"}},
       {{"convert", "humanoid.pmx", "--out", "x.glb", "--metres-per-unit", "0"},
        {"convert: --metres-per-unit: expected a number > 0, found 0"}}});
  // The same model without a humanoid converts to .glb.
  test::expect_success(dir, {"convert", "props.pmx", "--out", "props.glb"});
  EXPECT_TRUE(fs::is_regular_file(dir / "props.glb"));
}

}  // namespace
}  // namespace amt
