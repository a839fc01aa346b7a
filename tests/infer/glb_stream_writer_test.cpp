// The streaming GLB writer: read back by the glTF importer frame for frame, the same frames as
// export_gltf_mesh_sequence, valid for the Khronos validator, bounded memory, nothing left behind.
#include "infer/glb_stream_writer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "data_tools/gltf_export.h"
#include "data_tools/gltf_import.h"
#include "data_tools/shapes.h"
#include "tests/test_support.h"

namespace amt {
namespace {

MatrixX3f wave(const TriMesh& mesh, int k) {
  MatrixX3f V = mesh.V;
  for (int i = 0; i < V.rows(); ++i) {
    V.row(i) *= 1.0f + 0.1f * std::sin(3.0f * V(i, 1) + 0.7f * float(k));
    V(i, 2) += 0.05f * float(k);
  }
  return V;
}

TEST(GlbStreamWriter, FramesReadBackAndMatchTheInMemoryExport) {
  const auto dir = test::temp_dir("glb_stream");
  const TriMesh mesh = uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 12, 8);
  const int T = 9;
  const std::string path = (dir / "seq.glb").string();
  std::vector<MatrixX3f> frames;
  {
    GlbStreamWriter writer(path, mesh.F, mesh.num_vertices(), 24.0f);
    for (int k = 0; k < T; ++k) frames.push_back(wave(mesh, k)), writer.append(frames.back());
    EXPECT_EQ(writer.num_frames(), T);
    EXPECT_FALSE(std::filesystem::exists(path));  // nothing at the path until finish()
    const size_t bytes = writer.finish();
    EXPECT_EQ(bytes, std::filesystem::file_size(path));
  }
  EXPECT_FALSE(std::filesystem::exists(path + ".frames.tmp"));
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  const GltfVertexAnimation back = gltf_vertex_animation(read_gltf(path), "", 24.0f);
  ASSERT_EQ(back.frames.size(), size_t(T));
  EXPECT_EQ(back.faces, mesh.F);
  for (int k = 0; k < T; ++k) EXPECT_LT((back.frames[size_t(k)] - frames[size_t(k)]).cwiseAbs().maxCoeff(), 1e-5f) << k;
  // The in-memory exporter writes the same frames.
  const std::string reference = (dir / "reference.glb").string();
  export_gltf_mesh_sequence(reference, mesh.F, frames, 24.0f);
  const GltfVertexAnimation ref = gltf_vertex_animation(read_gltf(reference), "", 24.0f);
  for (int k = 0; k < T; ++k) EXPECT_EQ(ref.frames[size_t(k)], back.frames[size_t(k)]) << k;
  test::expect_valid_gltf(path);
}

TEST(GlbStreamWriter, SingleFrameIsAStaticMesh) {
  const auto dir = test::temp_dir("glb_stream_single");
  const TriMesh mesh = uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 6, 4);
  const std::string path = (dir / "one.glb").string();
  GlbStreamWriter writer(path, mesh.F, mesh.num_vertices(), 30.0f);
  writer.append(mesh.V);
  writer.finish();
  const GltfVertexAnimation back = gltf_vertex_animation(read_gltf(path), "", 30.0f);
  ASSERT_EQ(back.frames.size(), 1u);
  EXPECT_EQ(back.frames[0], mesh.V);
  test::expect_valid_gltf(path);
}

TEST(GlbStreamWriter, BufferedBytesDoNotGrowWithTheFrameCount) {
  const auto dir = test::temp_dir("glb_stream_memory");
  const TriMesh mesh = uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 16, 8);
  size_t after_two = 0;
  GlbStreamWriter writer((dir / "long.glb").string(), mesh.F, mesh.num_vertices(), 30.0f);
  for (int k = 0; k < 400; ++k) {
    writer.append(wave(mesh, k));
    if (k == 1) after_two = writer.buffered_bytes();
  }
  EXPECT_EQ(writer.buffered_bytes(), after_two);
  // Frame 0, one delta scratch frame and the 16-bit indices.
  EXPECT_EQ(after_two, size_t(mesh.num_vertices()) * 24 + size_t(mesh.num_faces()) * 6);
  // The frame data went to disk as it came (all but what stdio still buffers).
  const size_t on_disk = std::filesystem::file_size(dir / "long.glb.frames.tmp");
  const size_t deltas = size_t(399) * size_t(mesh.num_vertices()) * 12;
  EXPECT_LE(on_disk, deltas);
  EXPECT_GE(on_disk + 65536, deltas);
}

TEST(GlbStreamWriter, AbandonedOrBadInputLeavesNothing) {
  const auto dir = test::temp_dir("glb_stream_abandon");
  const TriMesh mesh = uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 6, 4);
  const std::string path = (dir / "gone.glb").string();
  {
    GlbStreamWriter writer(path, mesh.F, mesh.num_vertices(), 30.0f);
    writer.append(mesh.V);
    MatrixX3f bad = mesh.V;
    bad(0, 0) = std::nanf("");
    EXPECT_NE(test::error_of([&] { writer.append(bad); }).find("frame 1: expected finite positions"),
              std::string::npos);
    EXPECT_NE(test::error_of([&] {
                writer.append(mesh.V.topRows(3));
              }).find("expected " + std::to_string(mesh.num_vertices())),
              std::string::npos);
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  // An unwritable location: a folder below a regular file.
  std::ofstream(dir / "file") << "x";
  const std::string error =
      test::error_of([&] { GlbStreamWriter((dir / "file" / "x.glb").string(), mesh.F, mesh.num_vertices(), 30.0f); });
  EXPECT_NE(error.find("x.glb"), std::string::npos) << error;
}

}  // namespace
}  // namespace amt
