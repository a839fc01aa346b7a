#include "data_tools/formats/render.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#define STB_IMAGE_STATIC
#define STB_IMAGE_IMPLEMENTATION
#include <stb/stb_image.h>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/shapes.h"
#include "tests/test_support.h"

namespace amt {
namespace {

// A square in the z = 0 plane, x and y in [-1, 1], facing +Z.
TriMesh square() {
  TriMesh mesh;
  mesh.V.resize(4, 3);
  mesh.V << -1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0;
  mesh.F.resize(2, 3);
  mesh.F << 0, 1, 2, 0, 2, 3;
  return mesh;
}

const uint8_t* pixel(const Image& image, int x, int y) { return &image.rgb[(static_cast<size_t>(y) * image.width + x) * 3]; }

TEST(Render, FrontalSquareFillsTheFittedFrameWithItsShadedColour) {
  RenderOptions options;
  options.width = 40;
  options.height = 40;
  options.yaw_degrees = 0.0f;
  options.pitch_degrees = 0.0f;
  options.margin = 0.25f;
  options.light = Eigen::Vector3f(0, 0, 1);  // head-on: full Lambert term
  options.ambient = 0.5f;
  options.background = Eigen::Vector3f(0, 0, 0);
  const TriMesh mesh = square();
  const MatrixX3f colors = MatrixX3f::Constant(4, 3, 0.8f);
  const Image image = render_mesh(mesh.V, mesh.F, colors, options);
  ASSERT_EQ(image.width, 40);
  ASSERT_EQ(image.height, 40);
  // The square spans pixels 10..29 (margin 25 % per side); the head-on light gives the full colour 0.8.
  EXPECT_EQ(pixel(image, 20, 20)[0], 204);
  EXPECT_EQ(pixel(image, 11, 28)[1], 204);
  EXPECT_EQ(pixel(image, 5, 20)[0], 0);   // left margin
  EXPECT_EQ(pixel(image, 20, 34)[2], 0);  // bottom margin
  // Seen edge-on from the side, the light grazes it: ambient only.
  options.light = Eigen::Vector3f(1, 0, 0);
  const Image grazing = render_mesh(mesh.V, mesh.F, colors, options);
  EXPECT_EQ(pixel(grazing, 20, 20)[0], 102);  // 0.8 * 0.5
}

TEST(Render, NearerFacesHideFartherOnesFromEitherSide) {
  // Two squares: red at z = 0, blue at z = 0.5 (nearer to a viewer on +Z).
  TriMesh a = square(), b = square();
  b.V.col(2).setConstant(0.5f);
  const TriMesh both = merge_meshes({a, b});
  MatrixX3f colors(8, 3);
  colors.topRows(4).rowwise() = Eigen::RowVector3f(1, 0, 0);
  colors.bottomRows(4).rowwise() = Eigen::RowVector3f(0, 0, 1);
  RenderOptions options;
  options.width = options.height = 32;
  options.pitch_degrees = 0.0f;
  options.ambient = 1.0f;
  options.yaw_degrees = 0.0f;
  const uint8_t* front = pixel(render_mesh(both.V, both.F, colors, options), 16, 16);
  EXPECT_EQ(front[0], 0);
  EXPECT_EQ(front[2], 255);
  options.yaw_degrees = 180.0f;  // from behind, the red square is nearer
  const Image back = render_mesh(both.V, both.F, colors, options);
  EXPECT_EQ(pixel(back, 16, 16)[0], 255);
  EXPECT_EQ(pixel(back, 16, 16)[2], 0);
}

TEST(Render, WorldHeightPutsTheFloorOnTheBottomMarginAndKeepsScale) {
  // Two capsule characters of different heights keep their ratio when rendered with one world height.
  RenderOptions options;
  options.width = 64;
  options.height = 128;
  options.world_height = 2.0f;
  options.margin = 0.0f;
  options.pitch_degrees = 0.0f;
  options.background = Eigen::Vector3f(1, 1, 1);
  auto top_row = [&](float height) {
    TriMesh mesh = uv_sphere(Eigen::Vector3f::Zero(), 0.1f, 12, 8);
    mesh.V.col(1).array() = (mesh.V.col(1).array() + 0.1f) * (height / 0.2f);  // from y = 0 to y = height
    const Image image = render_character(mesh, {}, options);
    for (int y = 0; y < image.height; ++y)
      for (int x = 0; x < image.width; ++x)
        if (pixel(image, x, y)[2] != 255) return y;
    return image.height;
  };
  EXPECT_NEAR(top_row(1.0f), 64, 1);  // half of 2 m: the middle row
  EXPECT_NEAR(top_row(1.5f), 32, 1);
}

TEST(Render, PngRoundTripAndGrid) {
  Image a{2, 1, {255, 0, 0, 0, 255, 0}}, b{1, 2, {0, 0, 255, 10, 20, 30}};
  const Image grid = image_grid({a, b}, 2, 1, Eigen::Vector3f(0, 0, 0));
  ASSERT_EQ(grid.width, 2 * 2 + 3);
  ASSERT_EQ(grid.height, 2 + 2);
  EXPECT_EQ(pixel(grid, 1, 1)[0], 255);  // a, centred vertically in its 2 x 2 cell: row 1 (offset 0)
  EXPECT_EQ(pixel(grid, 4, 1)[2], 255);  // b in the second cell: column 1 + (2 + 1) + (2 - 1) / 2 = 4
  EXPECT_EQ(pixel(grid, 4, 2)[1], 20);
  EXPECT_EQ(pixel(grid, 5, 1)[2], 0);    // b is one pixel wide: the rest of its cell is background
  EXPECT_EQ(pixel(grid, 0, 0)[0], 0);    // padding

  const std::string path = (test::temp_dir("render") / "grid.png").string();
  write_png(grid, path);
  int w = 0, h = 0, channels = 0;
  unsigned char* data = stbi_load(path.c_str(), &w, &h, &channels, 3);
  ASSERT_NE(data, nullptr);
  EXPECT_EQ(w, grid.width);
  EXPECT_EQ(h, grid.height);
  EXPECT_TRUE(std::equal(grid.rgb.begin(), grid.rgb.end(), data));
  stbi_image_free(data);
}

TEST(Render, BadInputIsAnError) {
  const TriMesh mesh = square();
  EXPECT_NE(test::error_of([&] { render_mesh(mesh.V, mesh.F, MatrixX3f::Zero(3, 3)); }).find("colors"),
            std::string::npos);
  RenderOptions tiny;
  tiny.width = 2;
  EXPECT_NE(test::error_of([&] { render_mesh(mesh.V, mesh.F, MatrixX3f::Zero(4, 3), tiny); }).find("image size"),
            std::string::npos);
  EXPECT_NE(test::error_of([&] { image_grid({}, 2); }).find("at least one image"), std::string::npos);
  EXPECT_NE(test::error_of([&] { write_png(Image{}, "x.png"); }).find("non-empty"), std::string::npos);
}

}  // namespace
}  // namespace amt
