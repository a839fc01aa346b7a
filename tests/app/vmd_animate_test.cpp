// `amt animate --motion dance.vmd` from the command line: a VMD dance on the PMX humanoid it is played on, with the
// model's own physics; the keys on bones the humanoid lacks (its leg IK bones) counted in the mapping lines; and the
// one-line errors of a VMD without its model, a --motion-model that is not a PMX, and a truncated VMD.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/pmx_export.h"
#include "data_tools/formats/vmd_import.h"
#include "tests/app/amt_cli.h"
#include "tests/data_tools/builder/pmx_humanoid.h"
#include "tests/data_tools/formats/vmd_dance.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

TEST(VmdAnimate, DanceOnItsPmxModelWithPhysics) {
  const fs::path dir = test::temp_dir("vmd_animate");
  write_pmx(test::pmx_humanoid(), (dir / "model.pmx").string());
  write_vmd(test::vmd_dance(), (dir / "dance.vmd").string());
  const test::CommandResult run =
      test::expect_success(dir, {"animate", "--character", "model.pmx", "--motion", "dance.vmd", "--apparel", "physics",
                                 "--frames", "8", "--out", "x.glb", "--threads", "1"});
  EXPECT_EQ(run.out.rfind("wrote x.glb", 0), 0u) << run.out;
  EXPECT_NE(run.err.find("animate: motion dance (121 frames at 30 fps)"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("from a VMD motion on model.pmx: 90 bone keyframes on 8 of the model's 28 bones"),
            std::string::npos)
      << run.err;
  // The humanoid has no leg IK bones: their 18 keys are counted and ignored.
  EXPECT_NE(run.err.find("18 keyframes on bones the model does not have, ignored: 右足ＩＫ 左足ＩＫ"),
            std::string::npos)
      << run.err;
  const GltfVertexAnimation frames = gltf_vertex_animation(read_gltf((dir / "x.glb").string()), "", 30.0f);
  ASSERT_EQ(frames.frames.size(), 8u);
  for (const MatrixX3f& V : frames.frames) EXPECT_TRUE(V.allFinite());
  // The dance moves the model: the last frame is not the first.
  EXPECT_GT((frames.frames.back() - frames.frames.front()).cwiseAbs().maxCoeff(), 0.01f);

  // The same with the model named explicitly and a character that is the same file.
  test::expect_success(dir, {"animate", "--character", "model.pmx", "--motion", "dance.vmd", "--motion-model",
                             "model.pmx", "--apparel", "physics", "--frames", "2", "--out", "y.glb", "--threads", "1"});
}

TEST(VmdAnimate, OneLineErrors) {
  const fs::path dir = test::temp_dir("vmd_animate_errors");
  write_pmx(test::pmx_humanoid(), (dir / "model.pmx").string());
  write_vmd(test::vmd_dance(), (dir / "dance.vmd").string());
  const std::vector<uint8_t> bytes = vmd_bytes(test::vmd_dance());
  std::ofstream((dir / "cut.vmd").string(), std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), 200);
  test::expect_errors_writing_nothing(
      dir, {{{"animate", "--character", "generated:3", "--motion", "dance.vmd", "--out", "g.glb"},
             {"dance.vmd: motion: a VMD motion has no skeleton and needs the PMX model it was made for",
              "--motion-model MODEL.pmx"}},
            {{"animate", "--character", "model.pmx", "--motion", "dance.vmd", "--motion-model", "dance.vmd",
              "--apparel", "physics", "--out", "g.glb"},
             {"dance.vmd: --motion-model: expected the .pmx model"}},
            {{"animate", "--character", "model.pmx", "--motion", "cut.vmd", "--apparel", "physics", "--out", "g.glb"},
             {"cut.vmd: bone keyframe count: expected at most 1 (records of at least 111 bytes", "found 90"}}});
}

}  // namespace
}  // namespace amt
