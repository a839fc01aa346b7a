// PMX writer: write -> read gives the model field for field and write -> read -> write the same bytes (both
// encodings, index sizes 1, 2 and 4, every deform type, PMX 2.0 and 2.1); the sections it writes for a valid file;
// files written atomically and only when they read back; what cannot be encoded is a one-line amt::Error.
#include "data_tools/formats/pmx_export.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/geometry/error.h"
#include "tests/data_tools/formats/pmx_test_models.h"
#include "tests/test_support.h"

namespace amt {
namespace {

using test::error_of;
using test::expect_same_model;
using test::sample_model;

PmxModel parse(const std::vector<uint8_t>& bytes) {
  return parse_pmx(bytes.data(), bytes.size(), "model.pmx");
}

void set_index_sizes(PmxModel& m, int vertex_size, int size) {
  m.header.vertex_index_size = vertex_size;
  m.header.texture_index_size = m.header.material_index_size = m.header.bone_index_size = m.header.morph_index_size =
      m.header.rigid_body_index_size = size;
}

// === Round trips

TEST(PmxExport, WriteReadWriteGivesTheSameBytesAndTheSameModel) {
  for (bool v21 : {false, true}) {
    for (PmxTextEncoding encoding : {PmxTextEncoding::kUtf16Le, PmxTextEncoding::kUtf8}) {
      for (int size : {1, 2, 4}) {
        SCOPED_TRACE(testing::Message() << "2.1 " << v21 << " encoding " << int(encoding) << " size " << size);
        PmxModel m = sample_model(v21);
        m.header.encoding = encoding;
        set_index_sizes(m, size, size);
        const std::vector<uint8_t> bytes = pmx_to_bytes(m);
        const PmxModel back = parse(bytes);
        expect_same_model(m, back);
        EXPECT_EQ(back.header.encoding, encoding);
        EXPECT_EQ(back.header.vertex_index_size, size);
        EXPECT_EQ(back.header.bone_index_size, size);
        EXPECT_EQ(back.header.rigid_body_index_size, size);
        EXPECT_EQ(pmx_to_bytes(back), bytes);
      }
    }
  }
}

TEST(PmxExport, WritesOneMaterialForEveryFaceAndMmdsDisplayFrames) {
  const PmxModel m = sample_model(false);
  PmxFieldOffsets offsets;
  const std::vector<uint8_t> bytes = pmx_to_bytes(m, &offsets);
  const PmxModel back = parse(bytes);
  EXPECT_EQ(back.texture_count, 0);
  EXPECT_EQ(back.material_count, 1);
  EXPECT_EQ(back.morph_count, 0);
  EXPECT_EQ(back.display_frame_count, 2);
  EXPECT_EQ(back.soft_body_count, 0);
  // The material's face index count (the last 4 bytes before the bone count) is every face's three indices.
  const size_t count_at = offsets.at("bones") - 4;
  int32_t count = 0;
  for (int k = 0; k < 4; ++k) count |= int32_t(bytes[count_at + k]) << (8 * k);
  EXPECT_EQ(count, 3 * m.faces.rows());
  // Offsets name the fields the reader names: a rigid body's bone index holds the bone.
  EXPECT_EQ(bytes[offsets.at("rigid_bodies[1].bone")], m.rigid_bodies[1].bone);  // 2-byte little-endian, < 256
  EXPECT_EQ(offsets.at("end_of_joints"), bytes.size());
}

// A model's own textures and materials are written as they are, and read back field for field.
TEST(PmxExport, TexturesAndMaterialsRoundTrip) {
  PmxModel m = sample_model(false);
  m.textures = {"tex\\肌.png", "toon.bmp", "sphere.spa"};
  PmxMaterial a;
  a.name = "肌";
  a.name_english = "skin";
  a.diffuse = {1, 0.8f, 0.7f, 0.5f};
  a.specular = {0.1f, 0.2f, 0.3f};
  a.specular_strength = 12;
  a.ambient = {0.5f, 0.4f, 0.35f};
  a.flags = kPmxMaterialDoubleSided | kPmxMaterialEdge;
  a.edge_colour = {0.1f, 0, 0, 1};
  a.edge_size = 0.5f;
  a.texture = 0;
  a.sphere_texture = 2;
  a.sphere_mode = PmxSphereMode::kAdd;
  a.toon = 1;
  a.memo = "メモ";
  a.face_count = 3;
  PmxMaterial b;
  b.name = "髪";
  b.shared_toon = true;
  b.toon = 9;
  b.face_count = 1;
  m.materials = {a, b};
  const std::vector<uint8_t> bytes = pmx_to_bytes(m);
  const PmxModel back = parse(bytes);
  expect_same_model(m, back);  // textures and materials too
  ASSERT_EQ(back.materials.size(), 2u);
  EXPECT_EQ(back.materials[1].toon, 9);
  EXPECT_EQ(pmx_to_bytes(back), bytes);
  // The grey material of a model without any reads back as one drawing every face, and writes the same bytes.
  const PmxModel grey = parse(pmx_to_bytes(sample_model(false)));
  ASSERT_EQ(grey.materials.size(), 1u);
  EXPECT_EQ(grey.materials[0].face_count, 4);
  EXPECT_TRUE(grey.materials[0].double_sided());
  EXPECT_EQ(pmx_to_bytes(grey), pmx_to_bytes(sample_model(false)));
}

TEST(PmxExport, Utf16TextWithSurrogatesAndIllFormedUtf8) {
  EXPECT_EQ(utf8_to_utf16le("A\xC3\xA9\xE3\x82\xBB\xF0\x9F\x98\x80"),
            (std::vector<uint8_t>{0x41, 0x00, 0xE9, 0x00, 0xBB, 0x30, 0x3D, 0xD8, 0x00, 0xDE}));  // A é セ U+1F600
  // A truncated sequence, an encoded surrogate and a lone continuation byte become U+FFFD each byte.
  EXPECT_EQ(utf8_to_utf16le(std::string("a\xC3(\x80", 4)),
            (std::vector<uint8_t>{0x61, 0x00, 0xFD, 0xFF, 0x28, 0x00, 0xFD, 0xFF}));
  EXPECT_EQ(utf8_to_utf16le(std::string("\xED\xA0\x80", 3)),
            (std::vector<uint8_t>{0xFD, 0xFF, 0xFD, 0xFF, 0xFD, 0xFF}));
  EXPECT_TRUE(utf8_to_utf16le("").empty());
  // Through the writer and the reader, names come back as they were.
  PmxModel m = sample_model(false);
  m.bones[0].name = "センター😀";
  EXPECT_EQ(parse(pmx_to_bytes(m)).bones[0].name, "センター😀");
}

TEST(PmxExport, EulerAnglesInvertTheEulerRotation) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> angle(-3.1f, 3.1f), pitch(-1.5f, 1.5f);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Vector3f e(pitch(rng), angle(rng), angle(rng));
    EXPECT_TRUE(pmx_euler_angles(pmx_euler_rotation(e)).isApprox(e, 1e-4f)) << e.transpose();
  }
  // At x = +-pi/2 only y -+ z is defined: z comes out 0 and the rotation is the same.
  for (float x : {1.5707963f, -1.5707963f}) {
    const Eigen::Vector3f e(x, 0.7f, -0.4f);
    const Eigen::Vector3f back = pmx_euler_angles(pmx_euler_rotation(e));
    EXPECT_EQ(back.z(), 0.0f);
    EXPECT_TRUE(pmx_euler_rotation(back).isApprox(pmx_euler_rotation(e), 1e-5f)) << back.transpose();
  }
}

TEST(PmxExport, FitIndexSizesToTheTables) {
  PmxModel m = sample_model(false, 249);  // 255 vertices, 5 bones, 3 bodies
  pmx_fit_index_sizes(m);
  EXPECT_EQ(m.header.vertex_index_size, 1);
  EXPECT_EQ(m.header.bone_index_size, 1);
  EXPECT_EQ(m.header.rigid_body_index_size, 1);
  EXPECT_EQ(m.header.material_index_size, 1);
  expect_same_model(m, parse(pmx_to_bytes(m)));
  m = sample_model(false, 250);  // 256 vertices: indices up to 255 still fit one unsigned byte
  pmx_fit_index_sizes(m);
  EXPECT_EQ(m.header.vertex_index_size, 1);
  m = sample_model(false, 251);
  const PmxBone extra = m.bones[1];
  m.bones.resize(129, extra);  // 129 bones need index 128: two signed bytes
  pmx_fit_index_sizes(m);
  EXPECT_EQ(m.header.vertex_index_size, 2);
  EXPECT_EQ(m.header.bone_index_size, 2);
  expect_same_model(m, parse(pmx_to_bytes(m)));
}

TEST(PmxExport, AnEmptyModelRoundTrips) {
  PmxModel m;  // no vertices, faces, bones, bodies or joints: "Root" has no bone to show
  const std::vector<uint8_t> bytes = pmx_to_bytes(m);
  const PmxModel back = parse(bytes);
  expect_same_model(m, back);
  EXPECT_EQ(back.display_frame_count, 2);
  EXPECT_EQ(pmx_to_bytes(back), bytes);
}

// === Files

TEST(PmxExport, WriteFileReadsBackAndLeavesNoTemporary) {
  const std::filesystem::path dir = test::temp_dir("pmx_export_file");
  const std::string path = (dir / "sub" / "model.pmx").string();
  const PmxModel m = sample_model(true);
  write_pmx(m, path);
  EXPECT_FALSE(std::filesystem::exists(temporary_path(path)));
  const std::string bytes = test::read_file_bytes(path);
  const std::vector<uint8_t> expected = pmx_to_bytes(m);
  EXPECT_EQ(bytes, std::string(expected.begin(), expected.end()));
  expect_same_model(m, read_pmx(path));
}

TEST(PmxExport, ModelsTheReaderWouldRejectAreNotWritten) {
  const std::filesystem::path dir = test::temp_dir("pmx_export_rejected");
  const std::string path = (dir / "model.pmx").string();
  PmxModel m = sample_model(false);
  m.bones[3].parent = 7;
  PmxFieldOffsets offsets;
  pmx_to_bytes(m, &offsets);                        // the bytes can be made (tests damage files this way) ...
  EXPECT_EQ(error_of([&] { write_pmx(m, path); }),  // ... but not written as a file
            path + " (as written): offset " + std::to_string(offsets.at("bones[3].parent")) +
                ": bones[3].parent: expected -1 or an index below 5, found 7");
  EXPECT_FALSE(std::filesystem::exists(path));
  m = sample_model(false);
  m.rigid_bodies[1].mass = -1;
  EXPECT_NE(error_of([&] { write_pmx(m, path); }).find("rigid_bodies[1].mass: expected a mass in [0, 1e+06], found -1"),
            std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(PmxExport, BadPathsAreOneLineErrors) {
  const std::filesystem::path dir = test::temp_dir("pmx_export_paths");
  const PmxModel m = sample_model(false);
  // A folder where the file should go.
  std::filesystem::create_directories(dir / "folder.pmx");
  const std::string folder_error = error_of([&] { write_pmx(m, (dir / "folder.pmx").string()); });
  EXPECT_NE(folder_error.find("folder.pmx"), std::string::npos) << folder_error;
  EXPECT_NE(folder_error.find("a folder"), std::string::npos) << folder_error;
  // A file where a parent folder should be.
  write_pmx(m, (dir / "file.pmx").string());
  const std::string parent_error = error_of([&] { write_pmx(m, (dir / "file.pmx" / "model.pmx").string()); });
  EXPECT_NE(parent_error.find("file.pmx"), std::string::npos) << parent_error;
  for (const std::string& message : {folder_error, parent_error}) EXPECT_EQ(message.find('\n'), std::string::npos);
}

// === What cannot be encoded

TEST(PmxExport, WhatCannotBeEncodedIsAnError) {
  PmxModel m = sample_model(false);
  m.source = "test.pmx";
  EXPECT_EQ(
      error_of([&] { pmx_to_bytes(pmx_to_amt_frame(m)); }),
      "test.pmx: frame: expected a model in PMX's own frame and units (PmxFrame::kMmd), found one in amt's frame");
  PmxModel bad = m;
  bad.header.version = 2.2f;
  EXPECT_EQ(error_of([&] { pmx_to_bytes(bad); }), "test.pmx: header.version: expected 2.0 or 2.1, found 2.2");
  bad = m;
  bad.header.bone_index_size = 3;
  EXPECT_EQ(error_of([&] { pmx_to_bytes(bad); }), "test.pmx: header.bone_index_size: expected 1, 2 or 4, found 3");
  bad = m;
  bad.bones.resize(200, m.bones[1]);
  bad.header.bone_index_size = 1;
  EXPECT_EQ(error_of([&] { pmx_to_bytes(bad); }),
            "test.pmx: header.bone_index_size: expected a size whose indices reach all 200 entries, found 1 (128 at "
            "most)");
  bad = m;
  bad.header.bone_index_size = 1;
  bad.bones[2].parent = 300;
  EXPECT_EQ(error_of([&] { pmx_to_bytes(bad); }),
            "test.pmx: bones[2].parent: expected an index from -128 to 127 (1-byte indices), found 300");
  bad = m;
  bad.header.vertex_index_size = 1;
  bad.faces(1, 2) = 256;
  EXPECT_EQ(error_of([&] { pmx_to_bytes(bad); }),
            "test.pmx: faces[1][2]: expected a vertex index from 0 to 255 (1-byte vertex indices), found 256");
  bad = m;
  bad.vertices.normals.conservativeResize(5, 3);
  EXPECT_EQ(error_of([&] { pmx_to_bytes(bad); }),
            "test.pmx: vertices.normals: expected 6 rows (one per position), found 5");
  bad = m;
  bad.vertices.additional_uvs.clear();
  EXPECT_EQ(error_of([&] { pmx_to_bytes(bad); }),
            "test.pmx: vertices.additional_uvs: expected header.additional_uv_count = 1 matrices, found 0");
}

}  // namespace
}  // namespace amt
