// glTF export: mesh sequences and rigged characters written, validated by the Khronos glTF validator
// (tools/gltf-validator/validate.mjs, installed by scripts/setup.sh) and read back by the importer
// (vertex positions of every frame, skeleton, weights, joint positions by forward kinematics), the
// Fox re-exported, and bad input (no file written, no temporary left).
#include "data_tools/formats/gltf_export.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "data_tools/formats/gltf_import.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/shapes.h"

namespace amt {
namespace {

using test::error_of;
using test::expect_valid_gltf;
using test::temp_dir;

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// A deforming sphere: frame k is the rest sphere moved along +Z, with a travelling radial wave.
std::vector<MatrixX3f> wave_frames(const TriMesh& mesh, int frames) {
  std::vector<MatrixX3f> out;
  for (int k = 0; k < frames; ++k) {
    MatrixX3f V = mesh.V;
    for (int i = 0; i < V.rows(); ++i) {
      const float wave = 0.1f * std::sin(3.0f * V(i, 1) + 0.7f * float(k));
      V.row(i) *= 1.0f + wave;
      V(i, 2) += 0.05f * float(k);
    }
    out.push_back(V);
  }
  return out;
}

float max_distance(const MatrixX3f& a, const MatrixX3f& b) {
  return (a - b).rowwise().norm().maxCoeff();
}

void expect_sequence_round_trip(const std::filesystem::path& path, const TriMesh& mesh,
                                const std::vector<MatrixX3f>& frames, float fps) {
  const GltfVertexAnimation back = gltf_vertex_animation(read_gltf(path.string()), "", fps);
  EXPECT_EQ(back.faces, mesh.F);
  ASSERT_EQ(back.frames.size(), frames.size());
  for (size_t k = 0; k < frames.size(); ++k) {
    EXPECT_LT(max_distance(back.frames[k], frames[k]), 1e-5f) << "frame " << k;
  }
}

// === Mesh sequences

TEST(GltfExport, MeshSequenceGlbRoundTripAndValidator) {
  const auto dir = temp_dir("sequence_glb");
  const TriMesh sphere = uv_sphere(Eigen::Vector3f(0, 1, 0), 0.5f, 24, 12);
  const std::vector<MatrixX3f> frames = wave_frames(sphere, 12);
  const auto path = dir / "wave.glb";
  GltfExportOptions options;
  options.clip = "wave";
  export_gltf_mesh_sequence(path.string(), sphere.F, frames, 30.0f, options);
  ASSERT_TRUE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path.string() + ".amt-tmp"));
  expect_valid_gltf(path);
  expect_sequence_round_trip(path, sphere, frames, 30.0f);
  const GltfAsset asset = read_gltf(path.string());
  ASSERT_EQ(asset.animations().size(), 1u);
  EXPECT_EQ(asset.animations()[0].name, "wave");
  EXPECT_NEAR(asset.animations()[0].duration(), 11.0 / 30.0, 1e-6);

  // Size: 12 N bytes per frame plus a few bytes of keys; frame 0 and the indices once; the JSON.
  const size_t N = size_t(sphere.num_vertices()), F = size_t(sphere.num_faces()), T = frames.size();
  const size_t size = std::filesystem::file_size(path);
  const size_t payload = 12 * N * T + 12 * T + 2 * 3 * F;
  std::cout << "mesh sequence: N = " << N << ", F = " << F << ", T = " << T << ": " << size << " bytes, "
            << double(size - 6 * F) / double(T) << " bytes per frame (12 N = " << 12 * N << ")\n";
  EXPECT_GE(size, payload);
  EXPECT_LT(size, payload + 8192);
}

TEST(GltfExport, MeshSequenceEmbeddedGltfRoundTripAndValidator) {
  const auto dir = temp_dir("sequence_gltf");
  const TriMesh sphere = uv_sphere(Eigen::Vector3f(0, 0, 0), 1.0f, 12, 6);
  const std::vector<MatrixX3f> frames = wave_frames(sphere, 5);
  const auto path = dir / "wave.gltf";
  export_gltf_mesh_sequence(path.string(), sphere.F, frames, 24.0f);
  EXPECT_EQ(read_text(path).rfind("{", 0), 0u);  // JSON, buffer embedded
  EXPECT_NE(read_text(path).find("data:application/octet-stream;base64,"), std::string::npos);
  expect_valid_gltf(path);
  expect_sequence_round_trip(path, sphere, frames, 24.0f);
}

TEST(GltfExport, SingleFrameSequenceIsAStaticMesh) {
  const auto dir = temp_dir("single");
  const TriMesh sphere = uv_sphere(Eigen::Vector3f(0, 0, 0), 1.0f, 8, 4);
  const auto path = dir / "static.glb";
  export_gltf_mesh_sequence(path.string(), sphere.F, {sphere.V}, 30.0f);
  expect_valid_gltf(path);
  EXPECT_TRUE(read_gltf(path.string()).animations().empty());
  expect_sequence_round_trip(path, sphere, {sphere.V}, 30.0f);
}

TEST(GltfExport, LargeMeshUsesUnsignedIntIndices) {
  const auto dir = temp_dir("large");
  const TriMesh plane = grid(300, 250, 0.01f);  // 75 000 vertices
  std::vector<MatrixX3f> frames = {plane.V, plane.V};
  frames[1].col(2).array() += 0.25f;
  const auto path = dir / "plane.glb";
  export_gltf_mesh_sequence(path.string(), plane.F, frames, 10.0f);
  expect_valid_gltf(path);
  expect_sequence_round_trip(path, plane, frames, 10.0f);
}

// === Rigged characters

struct Rigged {
  TriMesh mesh;
  Skeleton skeleton;
  SparseWeights weights;
  Motion motion;
};

// The canonical skeleton walking, with a capsule body whose vertices blend their bone's joint (0.7)
// with its parent (0.3).
Rigged walking_capsules() {
  Rigged r;
  r.skeleton = canonical_skeleton();
  std::vector<int32_t> joint_of_vertex;
  r.mesh = capsule_character(r.skeleton.rest_joints, r.skeleton.parents, 1500, &joint_of_vertex);
  r.weights.indices.setZero(r.mesh.num_vertices(), kMaxInfluences);
  r.weights.weights.setZero(r.mesh.num_vertices(), kMaxInfluences);
  for (int i = 0; i < r.mesh.num_vertices(); ++i) {
    const int j = joint_of_vertex[size_t(i)];
    const int p = r.skeleton.parents[size_t(j)];
    r.weights.indices(i, 0) = j;
    r.weights.weights(i, 0) = p >= 0 ? 0.7f : 1.0f;
    if (p >= 0) {
      r.weights.indices(i, 1) = p;
      r.weights.weights(i, 1) = 0.3f;
    }
  }
  r.motion = walk_motion(24, 30.0f);
  return r;
}

TEST(GltfExport, RiggedRoundTripAndValidator) {
  const auto dir = temp_dir("rigged");
  const Rigged r = walking_capsules();
  for (const char* name : {"walk.glb", "walk.gltf"}) {
    const auto path = dir / name;
    export_gltf_rigged(path.string(), r.mesh, r.skeleton, r.weights, r.motion);
    expect_valid_gltf(path);

    const GltfAsset asset = read_gltf(path.string());
    const GltfCharacter ch = gltf_character(asset);
    EXPECT_EQ(ch.skeleton.names, r.skeleton.names);
    EXPECT_EQ(ch.skeleton.parents, r.skeleton.parents);
    EXPECT_LT((ch.skeleton.rest_joints - r.skeleton.rest_joints).cwiseAbs().maxCoeff(), 1e-6f);
    EXPECT_LT(max_distance(ch.mesh.V, r.mesh.V), 1e-6f);
    EXPECT_EQ(ch.mesh.F, r.mesh.F);
    const MatrixXfR W = densify_weights(ch.weights, 22), W0 = densify_weights(r.weights, 22);
    EXPECT_LT((W - W0).cwiseAbs().maxCoeff(), 1e-6f);

    const GltfMotion m = gltf_motion(asset, ch, "", r.motion.fps);
    ASSERT_EQ(m.motion.num_frames(), r.motion.num_frames());
    EXPECT_LT(m.joint_position_error, 1e-5f);
    for (int t = 0; t < r.motion.num_frames(); ++t) {
      const Transforms a = forward_kinematics(r.skeleton, r.motion, t),
                       b = forward_kinematics(ch.skeleton, m.motion, t);
      for (int j = 0; j < 22; ++j) {
        EXPECT_LT((a[size_t(j)].col(3) - b[size_t(j)].col(3)).norm(), 1e-5f) << "frame " << t << " joint " << j;
        EXPECT_GT(std::abs(r.motion.rotation(t, j).coeffs().dot(m.motion.rotation(t, j).coeffs())), 1.0f - 1e-5f);
      }
    }
    // glTF's own skinning of the file equals amt's linear blend skinning of the motion.
    const GltfVertexAnimation playback = gltf_vertex_animation(asset, "", r.motion.fps);
    ASSERT_EQ(int(playback.frames.size()), r.motion.num_frames());
    for (int t = 0; t < r.motion.num_frames(); t += 5) {
      MatrixX3f V;
      linear_blend_skinning(r.mesh.V, r.weights,
                            skinning_matrices(r.skeleton, forward_kinematics(r.skeleton, r.motion, t)), V);
      EXPECT_LT(max_distance(playback.frames[size_t(t)], V), 1e-5f) << "frame " << t;
    }
  }
}

// The walking capsules with two extra joints (handles) that are not in the canonical hierarchy's chain: one under
// the left hip moving by its own translation and rotation, one under the root; half the vertices of the left leg on
// the first. Written by append_node_frame's node-local transforms, glTF's own skinning of the file equals amt's
// linear blend skinning with the global transforms, and the apparel tint is kept.
TEST(GltfExport, SkinnedAnimationWithHandlesRoundTripsAndValidates) {
  const auto dir = temp_dir("skinned");
  const Rigged r = walking_capsules();
  Skeleton skeleton = r.skeleton;
  const int J = r.skeleton.num_joints();
  skeleton.names.push_back("apparel_handle_0000");
  skeleton.parents.push_back(kLeftHip);
  skeleton.names.push_back("apparel_handle_0001");
  skeleton.parents.push_back(0);
  skeleton.rest_joints.conservativeResize(J + 2, 3);
  skeleton.rest_joints.row(J) = r.skeleton.rest_joints.row(kLeftKnee) + Eigen::RowVector3f(0.05f, 0.0f, 0.1f);
  skeleton.rest_joints.row(J + 1) = Eigen::RowVector3f(0.0f, 0.9f, -0.15f);
  SparseWeights weights = r.weights;
  std::vector<uint8_t> mask(size_t(r.mesh.num_vertices()), 0);
  int moved = 0;
  for (int i = 0; i < r.mesh.num_vertices(); ++i) {
    if (r.weights.indices(i, 0) == kLeftKnee && (i % 2 == 0)) {
      weights.indices.row(i) << J, J + 1, 0, 0;
      weights.weights.row(i) << 0.75f, 0.25f, 0.0f, 0.0f;
      mask[size_t(i)] = 1, ++moved;
    }
  }
  ASSERT_GT(moved, 10);
  NodeAnimation animation;
  animation.fps = r.motion.fps;
  animation.translated.assign(size_t(J + 2), 0);
  animation.translated[0] = animation.translated[size_t(J)] = animation.translated[size_t(J + 1)] = 1;
  std::vector<Transforms> global;
  for (int t = 0; t < r.motion.num_frames(); ++t) {
    Transforms T = forward_kinematics(r.skeleton, r.motion, t);
    // Handle globals: a swing about x growing with t and a drift, not what their parents do.
    const Eigen::Matrix3f swing = Eigen::AngleAxisf(0.05f * float(t), Eigen::Vector3f::UnitX()).toRotationMatrix();
    T.push_back(make_transform(swing, skeleton.rest_joints.row(J).transpose() + Eigen::Vector3f(0, 0, 0.01f * t)));
    T.push_back(make_transform(swing.transpose(), skeleton.rest_joints.row(J + 1).transpose()));
    append_node_frame(skeleton, T, animation);
    global.push_back(T);
  }
  GltfExportOptions options;
  options.apparel_mask = mask;
  const auto path = dir / "skinned.glb";
  export_gltf_skinned_animation(path.string(), r.mesh, skeleton, weights, animation, options);
  expect_valid_gltf(path);
  const GltfAsset asset = read_gltf(path.string());
  const GltfCharacter ch = gltf_character(asset);
  EXPECT_EQ(ch.skeleton.names, skeleton.names);
  const GltfVertexAnimation playback = gltf_vertex_animation(asset, "", r.motion.fps);
  ASSERT_EQ(int(playback.frames.size()), r.motion.num_frames());
  for (int t = 0; t < r.motion.num_frames(); t += 3) {
    MatrixX3f V;
    linear_blend_skinning(r.mesh.V, weights, skinning_matrices(skeleton, global[size_t(t)]), V);
    // Rotations are stored as normalized shorts (about 3e-5 rad): within 0.1 mm on a 1.5 m character.
    EXPECT_LT(max_distance(playback.frames[size_t(t)], V), 1e-4f) << "frame " << t;
  }
  const std::string json = read_text(path);
  EXPECT_NE(json.find("\"skinned-animation\""), std::string::npos);
  EXPECT_NE(json.find("\"apparel_vertices\":" + std::to_string(moved)), std::string::npos);
}

TEST(GltfExport, FoxReexportedKeepsItsWalk) {
  const GltfAsset fox_asset = read_gltf(std::string(AMT_ASSET_DIR) + "/characters/Fox.glb");
  const GltfCharacter fox = gltf_character(fox_asset);
  const GltfMotion walk = gltf_motion(fox_asset, fox, "Walk", 30.0f);
  const auto path = temp_dir("fox") / "fox_walk.glb";
  GltfExportOptions options;
  options.name = "fox";
  options.clip = "Walk";
  export_gltf_rigged(path.string(), fox.mesh, fox.skeleton, fox.weights, walk.motion, options);
  expect_valid_gltf(path);
  const GltfAsset asset = read_gltf(path.string());
  const GltfCharacter back = gltf_character(asset);
  EXPECT_EQ(back.skeleton.names, fox.skeleton.names);
  const GltfMotion back_walk = gltf_motion(asset, back, "Walk", 30.0f);
  ASSERT_EQ(back_walk.motion.num_frames(), walk.motion.num_frames());
  for (int t = 0; t < walk.motion.num_frames(); ++t) {
    const Transforms a = forward_kinematics(fox.skeleton, walk.motion, t);
    const Transforms b = forward_kinematics(back.skeleton, back_walk.motion, t);
    for (int j = 0; j < fox.skeleton.num_joints(); ++j) {
      EXPECT_LT((a[size_t(j)].col(3) - b[size_t(j)].col(3)).norm(), 1e-3f) << "frame " << t << " joint " << j;
    }
  }
}

// === Bad input

TEST(GltfExport, BadInputWritesNothing) {
  const auto dir = temp_dir("bad");
  const TriMesh sphere = uv_sphere(Eigen::Vector3f(0, 0, 0), 1.0f, 8, 4);
  const std::string path = (dir / "bad.glb").string();
  std::vector<MatrixX3f> frames = {sphere.V, sphere.V};

  frames[1] = sphere.V.topRows(10);
  EXPECT_EQ(error_of([&] { export_gltf_mesh_sequence(path, sphere.F, frames, 30.0f); }),
            path + ": frames: expected " + std::to_string(sphere.num_vertices()) +
                " vertices in every frame, found 10 in frame 1");
  frames[1] = sphere.V;
  frames[1](3, 1) = std::nanf("");
  EXPECT_EQ(error_of([&] { export_gltf_mesh_sequence(path, sphere.F, frames, 30.0f); }),
            path + ": frames: expected finite positions, found NaN or infinity in frame 1");
  EXPECT_EQ(error_of([&] { export_gltf_mesh_sequence(path, sphere.F, {}, 30.0f); }),
            path + ": frames: expected at least 1 frame, found none");
  EXPECT_EQ(error_of([&] { export_gltf_mesh_sequence(path, sphere.F, {sphere.V}, 0.0f); }),
            path + ": fps: expected a positive frame rate, found 0");
  MatrixX3i F = sphere.F;
  F(0, 0) = sphere.num_vertices();
  EXPECT_NE(error_of([&] { export_gltf_mesh_sequence(path, F, {sphere.V}, 30.0f); }).find("faces: expected"),
            std::string::npos);

  const Rigged r = walking_capsules();
  SparseWeights weights = r.weights;
  weights.indices(5, 0) = 40;
  EXPECT_EQ(error_of([&] { export_gltf_rigged(path, r.mesh, r.skeleton, weights, r.motion); }),
            path + ": weights: expected joint indices in [0, 22), found 40 at vertex 5");
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path + ".amt-tmp"));

  // A folder that does not exist: the error names the temporary file.
  // A missing folder is created; a folder that cannot be (a file is in the way) is an error.
  std::ofstream(dir / "blocker") << "not a folder";
  const std::string nowhere = (dir / "blocker" / "out.glb").string();
  const std::string message = error_of([&] { export_gltf_mesh_sequence(nowhere, sphere.F, {sphere.V}, 30.0f); });
  EXPECT_EQ(message.rfind(nowhere + ": folder: expected to create", 0), 0u) << message;
  const std::string created = (dir / "missing" / "out.glb").string();
  export_gltf_mesh_sequence(created, sphere.F, {sphere.V}, 30.0f);
  EXPECT_TRUE(std::filesystem::exists(created));
}

TEST(GltfExport, ReplacesAnExistingFile) {
  const auto dir = temp_dir("replace");
  const std::string path = (dir / "mesh.glb").string();
  { std::ofstream(path) << "old"; }
  const TriMesh sphere = uv_sphere(Eigen::Vector3f(0, 0, 0), 1.0f, 8, 4);
  export_gltf_mesh_sequence(path, sphere.F, {sphere.V}, 30.0f);
  EXPECT_EQ(read_text(path).substr(0, 4), "glTF");
  EXPECT_FALSE(std::filesystem::exists(path + ".amt-tmp"));
}

}  // namespace
}  // namespace amt
