// OBJ import and export: bit-exact round trips (a sphere, extreme float values, the Fox's rest mesh),
// polygons, groups, relative indices and texture/normal indices in a hand-written file, the joint
// sidecar (round trip, hand-written order, bad files), OBJ sequences, and bad input.
#include "data_tools/formats/obj_io.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

#include "data_tools/formats/gltf_import.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/shapes.h"

namespace amt {
namespace {

using test::error_of;
using test::temp_dir;

std::string asset(const std::string& name) {
  return std::string(AMT_TEST_ASSETS_DIR) + "/obj/" + name;
}

void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// True when every coordinate has the same bits.
bool bitwise_equal(const MatrixX3f& a, const MatrixX3f& b) {
  return a.rows() == b.rows() && std::memcmp(a.data(), b.data(), size_t(a.size()) * sizeof(float)) == 0;
}

// === Meshes

TEST(ObjIo, RoundTripIsBitExact) {
  const auto dir = temp_dir("round_trip");
  TriMesh mesh = uv_sphere(Eigen::Vector3f(0.1f, 1.7f, -0.3f), 0.37f, 16, 9);
  // Values that need all 9 digits, tiny and large magnitudes (up to the plausibility bound of
  // data_tools/geometry/mesh.h), negative zero, denormals.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uniform(-1.0f, 1.0f);
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    for (int c = 0; c < 3; ++c) mesh.V(i, c) += uniform(rng) * 1e-3f;
  }
  mesh.V(0, 0) = -0.0f;
  mesh.V(1, 0) = 1e-30f;
  mesh.V(2, 1) = -98.7654321f;
  mesh.V(3, 2) = std::numeric_limits<float>::denorm_min();
  mesh.V(4, 0) = 123.456789f;
  mesh.V(5, 1) = 0.1f;
  const std::string path = (dir / "sphere.obj").string();
  write_obj(path, mesh);
  EXPECT_FALSE(std::filesystem::exists(path + ".amt-tmp"));
  const TriMesh back = read_obj(path);
  EXPECT_TRUE(bitwise_equal(back.V, mesh.V));
  EXPECT_EQ(back.F, mesh.F);
}

TEST(ObjIo, FoxRestMeshRoundTrip) {
  const GltfCharacter fox = gltf_character(read_gltf(std::string(AMT_ASSET_DIR) + "/characters/Fox.glb"));
  const std::string path = (temp_dir("fox") / "fox.obj").string();
  write_obj(path, fox.mesh);
  const TriMesh back = read_obj(path);
  EXPECT_TRUE(bitwise_equal(back.V, fox.mesh.V));
  EXPECT_EQ(back.F, fox.mesh.F);
}

TEST(ObjIo, PolygonsGroupsAndRelativeIndices) {
  // Two objects: a quad with v/vt/vn indices, and a pentagon and a triangle with relative indices.
  const TriMesh mesh = read_obj(asset("shapes_and_polygons.obj"));
  ASSERT_EQ(mesh.num_vertices(), 9);
  EXPECT_TRUE(mesh.V.row(8).isApprox(Eigen::RowVector3f(2.5f, 1.5f, -1.0f)));
  // quad -> 2 triangles, pentagon -> 3, triangle -> 1.
  ASSERT_EQ(mesh.num_faces(), 6);
  // The quad is split along one of its diagonals (tinyobjloader takes the shorter; here they are equal).
  const bool split02 = mesh.F.row(0) == Eigen::RowVector3i(0, 1, 2) && mesh.F.row(1) == Eigen::RowVector3i(0, 2, 3);
  const bool split13 = mesh.F.row(0) == Eigen::RowVector3i(0, 1, 3) && mesh.F.row(1) == Eigen::RowVector3i(1, 2, 3);
  EXPECT_TRUE(split02 || split13) << mesh.F.topRows(2);
  // The last triangle is "f -3 -2 -1" after all 9 vertices: 6 7 8.
  EXPECT_EQ(mesh.F.row(5), Eigen::RowVector3i(6, 7, 8));
  for (int f = 2; f < 5; ++f) {
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(mesh.F(f, k) >= 4 && mesh.F(f, k) <= 8);
  }
}

TEST(ObjIo, BadFiles) {
  EXPECT_EQ(error_of([] { read_obj(asset("bad/nan_vertex.obj")); }),
            asset("bad/nan_vertex.obj") + ":3: v: expected 3 finite numbers, found 'nan' as coordinate 2");
  EXPECT_EQ(error_of([] { read_obj(asset("bad/short_vertex.obj")); }),
            asset("bad/short_vertex.obj") + ":2: v: expected 3 finite numbers, found 'nothing' as coordinate 3");
  EXPECT_EQ(error_of([] { read_obj(asset("bad/index_out_of_range.obj")); }),
            asset("bad/index_out_of_range.obj") + ":5: f: expected vertex indices in [1, 3], found 4");
  EXPECT_EQ(error_of([] { read_obj(asset("bad/relative_index_too_far.obj")); }),
            asset("bad/relative_index_too_far.obj") +
                ":4: f: expected relative vertex indices in [-2, -1] (2 vertices above the line), found -3");
  EXPECT_EQ(error_of([] { read_obj(asset("bad/no_faces.obj")); }),
            asset("bad/no_faces.obj") + ": f: expected at least 1 triangle, found none");
  EXPECT_EQ(error_of([] { read_obj(asset("missing.obj")); }),
            asset("missing.obj") + ": cannot open: no such file (expected an OBJ file)");
}

TEST(ObjIo, AbsurdVertexIsRejected) {
  const std::string path = (temp_dir("absurd") / "flipped.obj").string();
  std::ofstream(path) << "v 0 0 0\nv 1 0 0\nv 0 1e15 0\nf 1 2 3\n";
  EXPECT_EQ(error_of([&] { read_obj(path); }),
            path + ": vertices: expected coordinates within 10000 of the origin, found 0 1e+15 0 at vertex 2");
}

TEST(ObjIo, WriteRejectsInvalidMeshes) {
  const std::string path = (temp_dir("invalid") / "bad.obj").string();
  TriMesh mesh = uv_sphere(Eigen::Vector3f(0, 0, 0), 1.0f, 6, 3);
  mesh.V(2, 0) = std::numeric_limits<float>::infinity();
  EXPECT_NE(error_of([&] { write_obj(path, mesh); }).find(path + ": vertices: expected finite values"),
            std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(path));
}

// === Sequences

TEST(ObjIo, SequenceWritesOneFilePerFrame) {
  const auto dir = temp_dir("sequence") / "frames";
  const TriMesh mesh = uv_sphere(Eigen::Vector3f(0, 0, 0), 1.0f, 8, 4);
  std::vector<MatrixX3f> frames;
  for (int k = 0; k < 3; ++k) frames.push_back(mesh.V * (1.0f + 0.1f * float(k)));
  const std::vector<std::string> paths = write_obj_sequence(dir.string(), mesh.F, frames);
  ASSERT_EQ(paths.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(paths[size_t(k)], (dir / ("frame_000" + std::to_string(k) + ".obj")).string());
    const TriMesh back = read_obj(paths[size_t(k)]);
    EXPECT_TRUE(bitwise_equal(back.V, frames[size_t(k)]));
    EXPECT_EQ(back.F, mesh.F);
  }
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    EXPECT_EQ(entry.path().extension(), ".obj");
    ++files;
  }
  EXPECT_EQ(files, 3);
}

// === Joint sidecar

TEST(ObjIo, JointSidecarRoundTrip) {
  const auto dir = temp_dir("joints");
  const Skeleton skeleton = canonical_skeleton();
  const std::string path = (dir / "hero.joints.json").string();
  write_joints_json(path, skeleton);
  const Skeleton back = read_joints_json(path);
  EXPECT_EQ(back.names, skeleton.names);
  EXPECT_EQ(back.parents, skeleton.parents);
  EXPECT_TRUE(bitwise_equal(back.rest_joints, skeleton.rest_joints));
  // Written with short numbers: 0.95, not 0.949999988079071.
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_NE(text.str().find("0.95"), std::string::npos);
  EXPECT_EQ(text.str().find("0.9499999"), std::string::npos);
}

TEST(ObjIo, ObjCharacterWithHandWrittenSidecar) {
  // Children listed before their parents, parents by name and by index: reordered parents first.
  const ObjCharacter character = read_obj_character(asset("stick.obj"));
  EXPECT_EQ(character.mesh.num_vertices(), 4);
  EXPECT_EQ(character.skeleton.names, (std::vector<std::string>{"hips", "spine", "head", "leg"}));
  EXPECT_EQ(character.skeleton.parents, (std::vector<int32_t>{-1, 0, 1, 0}));
  EXPECT_TRUE(character.skeleton.rest_joints.row(2).isApprox(Eigen::RowVector3f(0, 1.6f, 0)));
  EXPECT_EQ(joints_sidecar_path("a/b/hero.obj"), "a/b/hero.joints.json");
}

TEST(ObjIo, BadJointSidecars) {
  const auto dir = temp_dir("bad_joints");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"joints": [{"name": "a", "parent": null, "position": [0, 0, 0]},
                      {"name": "b", "parent": null, "position": [0, 1, 0]}]})",
       "joints: expected exactly one root joint (parent null), found 2: 'a', 'b'"},
      {R"({"joints": [{"name": "a", "parent": null, "position": [0, 0, 0]},
                      {"name": "b", "parent": "c", "position": [0, 1, 0]}]})",
       "joints[1].parent: expected the name of another joint, found \"c\""},
      {R"({"joints": [{"name": "r", "parent": null, "position": [0, 0, 0]},
                      {"name": "a", "parent": "b", "position": [0, 0, 0]},
                      {"name": "b", "parent": "a", "position": [0, 1, 0]}]})",
       "joints: expected a hierarchy without cycles, found a cycle through 'a'"},
      {R"({"joints": [{"name": "a", "position": [0, "x", 0]}]})",
       "joints[0].position: expected 3 finite numbers, found [0,\"x\",0]"},
      {R"({"joints": [{"name": "a", "position": [0, 0, 0]}, {"name": "a", "parent": 0, "position": [0, 0, 0]}]})",
       "joints[1].name: expected a unique name, found 'a' again"},
      {R"({"format": "amt-joints", "version": 2, "joints": []})",
       "version: expected 1 (the version this amt reads), found 2"},
      {R"({"joints": [})", "JSON: expected valid JSON, found a syntax error at byte 13"},
      {R"({"joints": [{"name": "a", "position": [1e999, 0, 0]}]})",
       "JSON: expected valid JSON, found [json.exception.out_of_range.406] number overflow parsing '1e999'"},
      {R"({"joints": [{"name": "a", "position": [0, 0, 0]}, {"name": "b", "parent": 18446744073709551615,
                       "position": [0, 0, 0]}]})",
       "joints[1].parent: expected a joint index in [0, 2) other than 1, or -1, found 18446744073709551615"},
  };
  for (const auto& [text, expected] : cases) {
    const std::string path = (dir / "bad.joints.json").string();
    write_text(path, text);
    EXPECT_EQ(error_of([&] { read_joints_json(path); }), path + ": " + expected);
  }
  EXPECT_EQ(error_of([&] { read_obj_character((dir / "lonely.obj").string()); }),
            (dir / "lonely.obj").string() + ": cannot open: no such file (expected an OBJ file)");
  write_text(dir / "lonely.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_EQ(error_of([&] { read_obj_character((dir / "lonely.obj").string()); }),
            (dir / "lonely.joints.json").string() + ": file: expected the joint sidecar of " +
                (dir / "lonely.obj").string() + ", found none");
}

}  // namespace
}  // namespace amt
