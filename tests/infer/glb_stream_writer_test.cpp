// The streaming GLB writer: read back by the glTF importer frame for frame, the same frames as
// export_gltf_mesh_sequence, valid for the Khronos validator, bounded memory, nothing left behind.
#include "infer/glb_stream_writer.h"

#include <gtest/gtest.h>

#include <cstring>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "data_tools/formats/gltf_export.h"
#include "data_tools/formats/gltf_import.h"
#include "data_tools/geometry/shapes.h"
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
  EXPECT_FALSE(std::filesystem::exists(path + ".frames.amt-tmp"));
  EXPECT_FALSE(std::filesystem::exists(path + ".amt-tmp"));
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

// The JSON chunk of a GLB file and the bytes of accessor `a` (tightly packed, no sparse).
struct GlbParts {
  nlohmann::json json;
  std::string bin;
};
GlbParts glb_parts(const std::string& path) {
  const std::string bytes = test::read_file_bytes(path);
  uint32_t json_length = 0, bin_length = 0;
  std::memcpy(&json_length, bytes.data() + 12, 4);
  std::memcpy(&bin_length, bytes.data() + 20 + json_length, 4);
  return {nlohmann::json::parse(bytes.substr(20, json_length)), bytes.substr(28 + json_length, bin_length)};
}
std::string accessor_bytes(const GlbParts& glb, int a, size_t element_size) {
  const nlohmann::json& accessor = glb.json["accessors"][a];
  const nlohmann::json& view = glb.json["bufferViews"][accessor["bufferView"].get<int>()];
  return glb.bin.substr(view["byteOffset"].get<size_t>(), accessor["count"].get<size_t>() * element_size);
}

TEST(GlbStreamWriter, TheApparelMaskTravelsAsVertexColours) {
  const auto dir = test::temp_dir("glb_stream_colours");
  const TriMesh mesh = uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 8, 6);
  std::vector<uint8_t> mask(size_t(mesh.num_vertices()), 0);
  for (size_t i = 0; i < mask.size(); i += 3) mask[i] = 1;
  const int apparel = int(std::count(mask.begin(), mask.end(), 1));
  std::vector<MatrixX3f> frames = {wave(mesh, 0), wave(mesh, 1), wave(mesh, 2)};
  const std::string streamed = (dir / "streamed.glb").string(), in_memory = (dir / "in_memory.glb").string();
  {
    GlbStreamWriter writer(streamed, mesh.F, mesh.num_vertices(), 30.0f, "m", "c", mask);
    for (const MatrixX3f& V : frames) writer.append(V);
    writer.finish();
  }
  GltfExportOptions options;
  options.apparel_mask = mask;
  export_gltf_mesh_sequence(in_memory, mesh.F, frames, 30.0f, options);
  for (const std::string& path : {streamed, in_memory}) {
    const GlbParts glb = glb_parts(path);
    const nlohmann::json& primitive = glb.json["meshes"][0]["primitives"][0];
    ASSERT_TRUE(primitive["attributes"].contains("COLOR_0")) << path;
    const int a = primitive["attributes"]["COLOR_0"];
    EXPECT_EQ(glb.json["accessors"][a]["componentType"], 5121) << path;
    EXPECT_EQ(glb.json["accessors"][a]["normalized"], true) << path;
    EXPECT_EQ(glb.json["accessors"][a]["type"], "VEC4") << path;
    const std::string colors = accessor_bytes(glb, a, 4);
    ASSERT_EQ(colors.size(), mask.size() * 4) << path;
    for (size_t i = 0; i < mask.size(); ++i) {
      const auto* rgba = reinterpret_cast<const uint8_t*>(colors.data() + 4 * i);
      EXPECT_EQ(std::memcmp(rgba, mask[i] ? kApparelColor : kBodyColor, 4), 0) << path << " vertex " << i;
    }
    EXPECT_EQ(glb.json["asset"]["extras"]["apparel_vertices"], apparel) << path;
    EXPECT_EQ(glb.json["asset"]["extras"]["apparel_color"][2], int(kApparelColor[2])) << path;
    // The frames still read back.
    const GltfVertexAnimation back = gltf_vertex_animation(read_gltf(path), "", 30.0f);
    ASSERT_EQ(back.frames.size(), frames.size()) << path;
    EXPECT_LT((back.frames[2] - frames[2]).cwiseAbs().maxCoeff(), 1e-5f) << path;
    test::expect_valid_gltf(path);
  }
  mask[0] = 2;
  EXPECT_NE(test::error_of([&] {
              GlbStreamWriter(streamed, mesh.F, mesh.num_vertices(), 30.0f, "m", "c", mask);
            }).find("apparel mask: expected 0 or 1, found 2 at vertex 0"),
            std::string::npos);
  mask.pop_back();
  EXPECT_NE(test::error_of([&] {
              GlbStreamWriter(streamed, mesh.F, mesh.num_vertices(), 30.0f, "m", "c", mask);
            }).find("apparel mask: expected"),
            std::string::npos);
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
  const size_t on_disk = std::filesystem::file_size(dir / "long.glb.frames.amt-tmp");
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
