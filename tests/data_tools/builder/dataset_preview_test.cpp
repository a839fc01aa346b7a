// A previewed clip plays back in glTF with the dataset's vertices, frame for frame.
#include "data_tools/builder/dataset_preview.h"

#include <gtest/gtest.h>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/builder/example_dataset.h"
#include "data_tools/formats/gltf_import.h"
#include "tests/test_support.h"

namespace amt {
namespace {

TEST(DatasetPreview, GlbFramesEqualTheClipsVertices) {
  const auto dir = test::temp_dir("dataset_preview");
  const std::string data = (dir / "example.h5").string(), glb = (dir / "preview.glb").string();
  ExampleDatasetOptions options;
  options.vertices = 300;
  options.frames = 12;
  write_example_dataset(data, options);
  DatasetPreviewOptions preview;
  preview.first_frame = 2;
  preview.max_frames = 8;
  EXPECT_EQ(export_dataset_preview(data, glb, preview), 8);

  const DatasetReader reader(data);
  const std::string clip = reader.clip_names().front();
  const int N = reader.read_character(reader.clip_info(clip).character).mesh.num_vertices();
  const MatrixX3f expected = reader.read_vertices(clip, 2, 8);
  const GltfVertexAnimation played = gltf_vertex_animation(read_gltf(glb), "", 30.0f);
  ASSERT_EQ(played.frames.size(), 8u);
  for (int t = 0; t < 8; ++t) {
    EXPECT_LT((played.frames[t] - expected.middleRows(t * N, N)).cwiseAbs().maxCoeff(), 1e-5f) << "frame " << t;
  }
}

TEST(DatasetPreview, MissingClipAndFrameRangeAreErrors) {
  const auto dir = test::temp_dir("dataset_preview_bad");
  const std::string data = (dir / "example.h5").string(), glb = (dir / "preview.glb").string();
  ExampleDatasetOptions options;
  options.vertices = 200;
  options.frames = 4;
  write_example_dataset(data, options);
  DatasetPreviewOptions missing;
  missing.clip = "nope";
  EXPECT_NE(test::error_of([&] { export_dataset_preview(data, glb, missing); }).find("/clips/nope: missing"),
            std::string::npos);
  DatasetPreviewOptions late;
  late.first_frame = 4;
  EXPECT_NE(test::error_of([&] { export_dataset_preview(data, glb, late); }).find("first frame: expected a frame in [0, 4)"),
            std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(glb));
}

}  // namespace
}  // namespace amt
