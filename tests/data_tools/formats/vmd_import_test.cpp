// VMD reader: bytes laid out by hand against the reader, the writer's round trip (Shift-JIS names, curves), the
// Bézier weight against hand-computed values, keyframe interpolation, and malformed files (every truncation, wrong
// headers, absurd counts, non-finite numbers, a folder) as one-line errors naming the file and the field.
#include "data_tools/formats/vmd_import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "data_tools/geometry/error.h"
#include "tests/data_tools/formats/vmd_dance.h"
#include "tests/test_support.h"

namespace amt {
namespace {

void put_u32(std::vector<uint8_t>& out, uint32_t v) {
  for (int k = 0; k < 4; ++k) out.push_back(uint8_t(v >> (8 * k)));
}

void put_f32(std::vector<uint8_t>& out, float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, 4);
  put_u32(out, bits);
}

void put_field(std::vector<uint8_t>& out, const std::string& bytes, size_t field) {
  out.insert(out.end(), bytes.begin(), bytes.end());
  out.insert(out.end(), field - bytes.size(), uint8_t(0));
}

// A version-1 file laid out by hand: one bone key on "センター" (Shift-JIS 83 5A 83 93 83 5E 81 5B) with garbage
// after the NUL, then one morph, one camera and one light key, no self-shadow or IK sections.
std::vector<uint8_t> hand_made_v1() {
  std::vector<uint8_t> out;
  put_field(out, "Vocaloid Motion Data file", 30);
  put_field(out, "model", 10);
  put_u32(out, 1);
  std::string name = "\x83\x5A\x83\x93\x83\x5E\x81\x5B";
  name += '\0';
  name += "\xFF\x12";  // garbage after the NUL
  put_field(out, name, 15);
  put_u32(out, 7);
  put_f32(out, 1.0f);
  put_f32(out, 2.0f);
  put_f32(out, -3.0f);
  const Eigen::Quaternionf q(Eigen::AngleAxisf(0.5f, Eigen::Vector3f::UnitY()));
  put_f32(out, q.x());
  put_f32(out, q.y());
  put_f32(out, q.z());
  put_f32(out, q.w());
  std::vector<uint8_t> block(64, 0);
  const uint8_t curves[4][4] = {{1, 2, 3, 4}, {5, 6, 7, 8}, {9, 10, 11, 12}, {13, 14, 15, 16}};  // x1 y1 x2 y2
  for (int a = 0; a < 4; ++a)
    for (int c = 0; c < 4; ++c) block[size_t(a + 4 * c)] = curves[a][c];
  out.insert(out.end(), block.begin(), block.end());
  put_u32(out, 1);  // morph
  out.insert(out.end(), 23, uint8_t(0));
  put_u32(out, 1);  // camera
  out.insert(out.end(), 61, uint8_t(0));
  put_u32(out, 1);  // light
  out.insert(out.end(), 28, uint8_t(0));
  return out;
}

TEST(VmdImport, ReadsAHandMadeVersion1File) {
  const std::vector<uint8_t> bytes = hand_made_v1();
  const VmdMotion m = parse_vmd(bytes.data(), bytes.size(), "dance.vmd");
  EXPECT_EQ(m.version, 1);
  EXPECT_EQ(m.model_name, "model");
  ASSERT_EQ(m.bone_keys.size(), 1u);
  const VmdBoneKey& k = m.bone_keys[0];
  EXPECT_EQ(k.bone, "センター");
  EXPECT_EQ(k.frame, 7u);
  EXPECT_EQ(k.translation, Eigen::Vector3f(1, 2, -3));
  EXPECT_NEAR(k.rotation.angularDistance(Eigen::Quaternionf(Eigen::AngleAxisf(0.5f, Eigen::Vector3f::UnitY()))), 0,
              1e-6f);
  for (int a = 0; a < 4; ++a) {
    EXPECT_EQ(k.curves[size_t(a)].x1, 4 * a + 1);
    EXPECT_EQ(k.curves[size_t(a)].y1, 4 * a + 2);
    EXPECT_EQ(k.curves[size_t(a)].x2, 4 * a + 3);
    EXPECT_EQ(k.curves[size_t(a)].y2, 4 * a + 4);
  }
  EXPECT_EQ(m.morph_keys, 1u);
  EXPECT_EQ(m.camera_keys, 1u);
  EXPECT_EQ(m.light_keys, 1u);
  EXPECT_EQ(m.ignored_note(), "morph, camera and light tracks ignored (3 keyframes)");
}

TEST(VmdImport, WriterRoundTripsNamesKeysAndCurves) {
  VmdMotion m;
  m.model_name = "初音ミク";
  m.bone_keys.push_back(test::vmd_key("左足ＩＫ", 0, {0.5f, 0, -1}, Eigen::Quaternionf::Identity()));
  m.bone_keys.push_back(
      test::vmd_key("右ひじ", 30, {0, 0, 0}, Eigen::Quaternionf(Eigen::AngleAxisf(1, Eigen::Vector3f::UnitZ()))));
  m.bone_keys[1].curves[kVmdCurveRotation] = {0, 0, 127, 127};
  const std::string path = (test::temp_dir("vmd_round_trip") / "m.vmd").string();
  write_vmd(m, path);
  EXPECT_EQ(std::filesystem::file_size(path), 30u + 20 + 4 + 2 * 111 + 5 * 4);
  const VmdMotion r = read_vmd(path);
  EXPECT_EQ(r.version, 2);
  EXPECT_EQ(r.model_name, "初音ミク");
  ASSERT_EQ(r.bone_keys.size(), 2u);
  EXPECT_EQ(r.bone_keys[0].bone, "左足ＩＫ");
  EXPECT_EQ(r.bone_keys[1].bone, "右ひじ");
  EXPECT_EQ(r.bone_keys[1].frame, 30u);
  EXPECT_EQ(r.bone_keys[0].translation, Eigen::Vector3f(0.5f, 0, -1));
  EXPECT_NEAR(r.bone_keys[1].rotation.angularDistance(m.bone_keys[1].rotation), 0, 1e-6f);
  EXPECT_EQ(r.bone_keys[1].curves[kVmdCurveRotation].x1, 0);
  EXPECT_EQ(r.bone_keys[1].curves[kVmdCurveRotation].x2, 127);
  EXPECT_EQ(r.bone_keys[1].curves[kVmdCurveX].x1, 20);
  EXPECT_EQ(r.last_frame(), 30u);
  EXPECT_EQ(r.ignored_note(), "");
}

TEST(VmdImport, LongNamesAreCutToTheFieldWithoutSplittingACharacter) {
  // 8 double-byte characters are 16 bytes: the field keeps 7 (14 bytes).
  EXPECT_EQ(vmd_field_name("あいうえおかきく"), "あいうえおかき");
  EXPECT_EQ(vmd_field_name("左足首"), "左足首");
  // A field cut in the middle of a character drops the half character.
  const std::string sjis = utf8_to_shift_jis("あい");
  EXPECT_EQ(shift_jis_to_utf8(reinterpret_cast<const uint8_t*>(sjis.data()), 3), "あ");
}

TEST(VmdImport, BezierWeightAgainstHandValues) {
  // MMD's default curve is the diagonal.
  for (const float t : {0.0f, 0.1f, 0.5f, 0.77f, 1.0f}) EXPECT_NEAR(vmd_bezier_weight(20, 20, 107, 107, t), t, 1e-6f);
  // x control points (0, 127): x(s) = 3 s^2 - 2 s^3 (smoothstep); y control points (0, 0): y(s) = s^3.
  // t = 0.5 is x(0.5), so the weight is 0.5^3; t = x(0.25) = 0.15625 gives 0.25^3.
  EXPECT_NEAR(vmd_bezier_weight(0, 0, 127, 0, 0.5f), 0.125f, 1e-5f);
  EXPECT_NEAR(vmd_bezier_weight(0, 0, 127, 0, 0.15625f), 0.015625f, 1e-5f);
  // Ends are fixed and out-of-range t is clamped.
  EXPECT_NEAR(vmd_bezier_weight(0, 0, 127, 0, 0.0f), 0.0f, 1e-6f);
  EXPECT_NEAR(vmd_bezier_weight(0, 0, 127, 0, 1.0f), 1.0f, 1e-6f);
  EXPECT_NEAR(vmd_bezier_weight(0, 0, 127, 0, 2.0f), 1.0f, 1e-6f);
}

TEST(VmdImport, InterpolatesBetweenKeysWithTheLaterKeysCurves) {
  VmdMotion m;
  const Eigen::Quaternionf turned(Eigen::AngleAxisf(1.0f, Eigen::Vector3f::UnitX()));
  m.bone_keys.push_back(test::vmd_key("頭", 10, {0, 0, 0}, Eigen::Quaternionf::Identity()));
  m.bone_keys.push_back(test::vmd_key("頭", 20, {2, 4, 6}, turned));
  m.bone_keys[1].curves[kVmdCurveY] = {0, 0, 127, 0};         // the smoothstep / cube curve above
  m.bone_keys[1].curves[kVmdCurveRotation] = {0, 0, 127, 0};  // same for the rotation
  m.bone_keys[0].curves[kVmdCurveX] = {0, 0, 127, 0};         // the first key's curve is never used
  m.bone_keys.push_back(m.bone_keys[1]);                      // same frame, later in the file: wins
  m.bone_keys.back().translation.z() = 8;
  const auto tracks = vmd_bone_tracks(m);
  ASSERT_EQ(tracks.size(), 1u);
  const std::vector<VmdBoneKey>& track = tracks.at("頭");
  ASSERT_EQ(track.size(), 2u);
  EXPECT_EQ(track[1].translation.z(), 8.0f);

  const VmdBonePose before = vmd_sample(track, 3);
  EXPECT_EQ(before.translation, Eigen::Vector3f::Zero());
  const VmdBonePose after = vmd_sample(track, 40);
  EXPECT_EQ(after.translation, Eigen::Vector3f(2, 4, 8));

  const VmdBonePose half = vmd_sample(track, 15);
  // Key 20's curves: X and Z linear (the defaults, Z now up to 8), Y and rotation the cube curve: 0.125 at t = 0.5.
  EXPECT_NEAR(half.translation.x(), 1.0f, 1e-5f);
  EXPECT_NEAR(half.translation.y(), 0.5f, 1e-4f);
  EXPECT_NEAR(half.translation.z(), 4.0f, 1e-5f);
  EXPECT_NEAR(Eigen::AngleAxisf(half.rotation).angle(), 0.125f, 1e-4f);
}

TEST(VmdImport, MalformedFilesAreOneLineErrorsNamingTheFileAndField) {
  VmdMotion m;
  m.bone_keys.push_back(test::vmd_key("センター", 0, {0, 1, 0}, Eigen::Quaternionf::Identity()));
  m.bone_keys.push_back(test::vmd_key("頭", 5, {0, 0, 0}, Eigen::Quaternionf::Identity()));
  const std::vector<uint8_t> good = vmd_bytes(m);
  ASSERT_NO_THROW(parse_vmd(good.data(), good.size(), "bad.vmd"));

  // Every truncation inside the header, name and bone keys; a file may end after a complete section.
  const size_t bone_end = 30 + 20 + 4 + 2 * 111;
  for (size_t n = 0; n < good.size(); ++n) {
    const std::string e = test::error_of([&] { parse_vmd(good.data(), n, "bad.vmd"); });
    const bool complete =
        n == bone_end || n == bone_end + 4 || n == bone_end + 8 || n == bone_end + 12 || n == bone_end + 16;
    if (complete) {
      EXPECT_EQ(e, "") << n;
      continue;
    }
    ASSERT_NE(e, "") << "no error at length " << n;
    EXPECT_EQ(e.rfind("bad.vmd: ", 0), 0u) << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
    EXPECT_NE(e.find("expected"), std::string::npos) << e;
  }

  std::vector<uint8_t> header = good;
  header[0] = 'X';
  EXPECT_NE(
      test::error_of([&] { parse_vmd(header.data(), header.size(), "bad.vmd"); }).find("bad.vmd: header: expected"),
      std::string::npos);

  std::vector<uint8_t> count = good;
  count[50] = 0xFF;  // bone key count 255 with two keys' bytes left
  const std::string e = test::error_of([&] { parse_vmd(count.data(), count.size(), "bad.vmd"); });
  EXPECT_NE(e.find("bad.vmd: bone keyframe count: expected at most"), std::string::npos) << e;

  std::vector<uint8_t> nan = good;
  const float q = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&nan[54 + 15 + 4 + 4], &q, 4);  // first key, position y
  EXPECT_NE(test::error_of([&] {
              parse_vmd(nan.data(), nan.size(), "bad.vmd");
            }).find("bad.vmd: bone keyframe 0 position: expected a finite number"),
            std::string::npos);

  std::vector<uint8_t> zero = good;
  std::memset(&zero[54 + 15 + 4 + 12], 0, 16);  // first key, zero quaternion
  EXPECT_NE(test::error_of([&] { parse_vmd(zero.data(), zero.size(), "bad.vmd"); }).find("non-zero quaternion"),
            std::string::npos);

  const auto dir = test::temp_dir("vmd_folder");
  std::filesystem::create_directories(dir / "folder.vmd");
  const std::string folder = test::error_of([&] { read_vmd((dir / "folder.vmd").string()); });
  EXPECT_NE(folder.find("folder.vmd"), std::string::npos) << folder;
  EXPECT_EQ(folder.find('\n'), std::string::npos) << folder;
}

TEST(VmdImport, RandomlyCorruptedFilesReadOrFailWithAnError) {
  // Bytes overwritten at random (counts, names, numbers, the header): every result is a motion or an amt::Error.
  const std::vector<uint8_t> good = vmd_bytes(test::vmd_dance());
  std::mt19937 random(7);
  int failures = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<uint8_t> bytes = good;
    const int edits = 1 + int(random() % 4);
    for (int k = 0; k < edits; ++k) bytes[random() % bytes.size()] = uint8_t(random());
    const size_t size = trial % 3 == 0 ? random() % (bytes.size() + 1) : bytes.size();
    try {
      const VmdMotion m = parse_vmd(bytes.data(), size, "noise.vmd");
      for (const VmdBoneKey& k : m.bone_keys) ASSERT_TRUE(k.translation.allFinite() && k.rotation.coeffs().allFinite());
    } catch (const Error& e) {
      ++failures;
      ASSERT_EQ(std::string(e.what()).rfind("noise.vmd: ", 0), 0u) << e.what();
    }
  }
  EXPECT_GT(failures, 0);
}

TEST(VmdImport, TheCommittedDanceIsTheWritersOutput) {
  // AMT_WRITE_VMD_DANCE=data/mocap/vmd/sway.vmd regenerates it.
  if (const char* out = std::getenv("AMT_WRITE_VMD_DANCE")) write_vmd(test::vmd_dance(), out);
  const std::string path = std::string(AMT_ASSET_DIR) + "/mocap/vmd/sway.vmd";
  const std::vector<uint8_t> bytes = vmd_bytes(test::vmd_dance());
  EXPECT_EQ(test::read_file_bytes(path), std::string(bytes.begin(), bytes.end()));
  const VmdMotion m = read_vmd(path);
  EXPECT_EQ(m.bone_keys.size(), 90u);
  EXPECT_EQ(m.last_frame(), 120u);
  EXPECT_EQ(vmd_bone_tracks(m).size(), 10u);
}

}  // namespace
}  // namespace amt
