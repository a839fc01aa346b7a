// `amt dataset artist-style` underneath: the remade shard holds each character as artist_style_character makes
// it and each clip's ground truth as remake_frames makes it, frame for frame; bad input is refused by name.
#include "data_tools/builder/artist_style_dataset.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "data_tools/builder/dataset_builder.h"
#include "data_tools/formats/dataset_file.h"
#include "tests/data_tools/builder/tiny_build.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

TEST(ArtistStyleDataset, TheShardHoldsTheRemakeAndItsGroundTruthFrameForFrame) {
  const fs::path dir = test::temp_dir("artist_style_dataset");
  build_dataset(test::tiny_build_options(dir / "proc", 1));
  const std::string in = (dir / "proc" / "character-0000.h5").string(), out = (dir / "remade.h5").string();
  ArtistStyleDatasetOptions options;
  options.max_clips = 2;
  options.progress = false;
  options.remake.seed = 3;
  const ArtistStyleDatasetSummary s = write_artist_style_dataset(in, out, options);
  EXPECT_EQ(s.characters, 1);
  EXPECT_EQ(s.clips, 2);

  const DatasetReader source(in), remade(out);
  const CharacterData c = source.read_character("character-0000");
  const ArtistStyleCharacter expected = artist_style_character(c, options.remake);
  const CharacterData r = remade.read_character("character-0000");
  ASSERT_EQ(r.mesh.num_vertices(), expected.character.mesh.num_vertices());
  EXPECT_GT(r.mesh.num_vertices(), c.mesh.num_vertices());
  EXPECT_EQ(s.vertices, r.mesh.num_vertices());
  EXPECT_EQ(r.split, c.split);
  EXPECT_EQ(r.apparel_mask, expected.character.apparel_mask);
  EXPECT_EQ((r.mesh.V - expected.character.mesh.V).cwiseAbs().maxCoeff(), 0.0f);
  ASSERT_EQ(remade.clip_names().size(), 2u);
  int64_t frames = 0;
  for (const std::string& clip : remade.clip_names()) {
    const ClipInfo info = remade.clip_info(clip), was = source.clip_info(clip);
    EXPECT_EQ(info.num_frames, was.num_frames);
    EXPECT_EQ(info.split, was.split);
    EXPECT_EQ(info.ground_truth, GroundTruth::kVertices);
    frames += info.num_frames;
    const MatrixX3f truth =
        remake_frames(expected, source.read_vertices(clip, 0, was.num_frames),
                      source.read_joint_transforms(clip, 0, was.num_frames));
    EXPECT_LT((remade.read_vertices(clip, 0, info.num_frames) - truth).cwiseAbs().maxCoeff(), 1e-6f) << clip;
  }
  EXPECT_EQ(s.frames, frames);
}

TEST(ArtistStyleDataset, BadInputIsRefusedByName) {
  const fs::path dir = test::temp_dir("artist_style_dataset_bad");
  build_dataset(test::tiny_build_options(dir / "proc", 1));
  const std::string in = (dir / "proc" / "character-0000.h5").string();
  ArtistStyleDatasetOptions options;
  options.progress = false;
  EXPECT_NE(test::error_of([&] { write_artist_style_dataset(in, in, options); }).find("the output is the input"),
            std::string::npos);
  EXPECT_NE(test::error_of([&] { write_artist_style_dataset((dir / "none.h5").string(), (dir / "x.h5").string()); })
                .find("none.h5: no such dataset file"),
            std::string::npos);
  options.character = "character-0099";
  EXPECT_NE(test::error_of([&] { write_artist_style_dataset(in, (dir / "x.h5").string(), options); })
                .find("/characters/character-0099: no such character"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "x.h5"));
}

}  // namespace
}  // namespace amt
