// `amt dataset pairs` and `amt retarget-cloth` from the command line, as the docs run them: a tiny pair set, then
// one body's apparel carried onto the other body of its pair into a GLB read back frame by frame (the validator
// runs on the same writer's GLBs in tests/infer).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/gltf_import.h"
#include "tests/app/amt_cli.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

TEST(RetargetClothCommand, PairsThenRetargetClothWriteAGlb) {
  const fs::path dir = test::temp_dir("retarget_cloth_cli");
  const test::CommandResult pairs =
      test::expect_success(dir, {"dataset", "pairs", "--out", "pairs.h5", "--pairs", "1", "--motions", "",
                                 "--procedural", "1", "--frames", "6", "--vertices", "1000", "--threads", "1"});
  EXPECT_EQ(pairs.out.rfind("wrote pairs.h5: 2 characters, 2 clips, 12 frames in ", 0), 0u) << pairs.out;
  const DatasetReader reader((dir / "pairs.h5").string());
  EXPECT_EQ(reader.character_names(), (std::vector<std::string>{"pair-00-a", "pair-00-b"}));
  std::string source;
  for (const std::string& clip : reader.clip_names())
    if (reader.clip_info(clip).character == "pair-00-a") source = clip;
  ASSERT_FALSE(source.empty());

  const test::CommandResult retargeted =
      test::expect_success(dir, {"retarget-cloth", "--source", "pairs.h5:" + source, "--target", "pairs.h5:pair-00-b",
                                 "--out", "b.glb", "--quiet", "--threads", "1"});
  EXPECT_EQ(retargeted.out.rfind("wrote b.glb", 0), 0u) << retargeted.out;
  EXPECT_EQ(retargeted.err, "");
  const GltfVertexAnimation frames = gltf_vertex_animation(read_gltf((dir / "b.glb").string()), "", 30.0f);
  ASSERT_EQ(frames.frames.size(), 6u);
  EXPECT_EQ(frames.frames[0].rows(), reader.read_character("pair-00-b").mesh.num_vertices());

  // Its output onto its own source is refused, the pair set untouched.
  const std::string before = test::read_file_bytes(dir / "pairs.h5");
  test::expect_one_line_error(test::run_amt(dir, {"retarget-cloth", "--source", "pairs.h5:" + source, "--target",
                                                  "pairs.h5:pair-00-b", "--out", "pairs.h5", "--quiet"}),
                              {"pairs.h5: --out: expected a new file, found the run's own input"});
  EXPECT_EQ(test::read_file_bytes(dir / "pairs.h5"), before);
}

}  // namespace
}  // namespace amt
