// PMX reader: the four babylon-mmd fixtures against values read off their hex dumps at fixed byte offsets; round
// trips of every field through the writer (data_tools/formats/pmx_export.h; both encodings, index sizes 1, 2 and 4,
// every deform type, PMX 2.0 and 2.1, with sections of every kind the writer does not model spliced in); every
// malformed input we could think of, including every truncation of a valid file; and the conversion to amt's
// frame.
#include "data_tools/formats/pmx_import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "data_tools/formats/pmx_export.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"
#include "tests/data_tools/formats/pmx_test_models.h"

namespace amt {
namespace {

using test::bone;
using test::expect_same_model;
using test::sample_model;

constexpr float kPi = 3.14159265358979f;

// === Independent byte access (little-endian), for fixtures and patches

std::vector<uint8_t> file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << path;
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

uint32_t u32_at(const std::vector<uint8_t>& b, size_t at) {
  return uint32_t(b.at(at)) | uint32_t(b.at(at + 1)) << 8 | uint32_t(b.at(at + 2)) << 16 | uint32_t(b.at(at + 3)) << 24;
}
int32_t i32_at(const std::vector<uint8_t>& b, size_t at) {
  return static_cast<int32_t>(u32_at(b, at));
}
float f32_at(const std::vector<uint8_t>& b, size_t at) {
  const uint32_t u = u32_at(b, at);
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}
Eigen::Vector3f vec3_at(const std::vector<uint8_t>& b, size_t at) {
  return Eigen::Vector3f(f32_at(b, at), f32_at(b, at + 4), f32_at(b, at + 8));
}
void patch_u32(std::vector<uint8_t>& b, size_t at, uint32_t v) {
  for (int k = 0; k < 4; ++k) b.at(at + k) = uint8_t(v >> (8 * k));
}
void patch_f32(std::vector<uint8_t>& b, size_t at, float v) {
  uint32_t u;
  std::memcpy(&u, &v, 4);
  patch_u32(b, at, u);
}

PmxModel parse(const std::vector<uint8_t>& bytes, const std::string& name = "model.pmx") {
  return parse_pmx(bytes.data(), bytes.size(), name);
}

// The message of the amt::Error that parsing throws ("" and a test failure when it parses).
std::string parse_error(const std::vector<uint8_t>& bytes) {
  try {
    parse(bytes);
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected amt::Error";
  return "";
}

std::string fixture(const std::string& name) {
  return std::string(AMT_ASSET_DIR) + "/pmx/" + name;
}

// === The babylon-mmd fixtures (2596 bytes each; offsets read off `xxd`)

// Offsets in all four files: UTF-16LE, 1-byte indices, 48 BDEF1 vertices of 38 bytes from 0x25, 72 face indices,
// 2 materials, 2 bones from 0x855, 0 morphs, 2 display frames, 2 rigid bodies from 0x905 and 0x955, 1 joint from
// 0x9a9 to the end of the file.
constexpr size_t kVertex0 = 0x25, kVertexStride = 38, kFaceCount = 0x745;
constexpr size_t kBone0Position = 0x871, kBone0Parent = 0x87d, kBone0Flags = 0x882, kBone0Tail = 0x884;
constexpr size_t kBone1Position = 0x8a4, kBone1Parent = 0x8b0, kBone1Flags = 0x8b5;
constexpr size_t kBody0 = 0x917, kBody1 = 0x967;  // each body's bone index; group, mask, shape, ... follow
constexpr size_t kJointType = 0x9c1;              // type, A, B, then 8 vec3s from 0x9c4

TEST(PmxFixtures, HeaderVerticesAndFacesMatchTheBytes) {
  for (const char* name :
       {"constraint_test.pmx", "constraint_test2.pmx", "constraint_test3.pmx", "constraint_test4.pmx"}) {
    SCOPED_TRACE(name);
    const std::vector<uint8_t> b = file_bytes(fixture(name));
    ASSERT_EQ(b.size(), 2596u);
    const PmxModel m = read_pmx(fixture(name));
    EXPECT_EQ(m.frame, PmxFrame::kMmd);
    EXPECT_EQ(m.header.version, 2.0f);
    EXPECT_EQ(f32_at(b, 4), 2.0f);
    EXPECT_EQ(m.header.encoding, PmxTextEncoding::kUtf16Le);
    EXPECT_EQ(m.header.additional_uv_count, 0);
    EXPECT_EQ(m.header.vertex_index_size, 1);
    EXPECT_EQ(m.header.bone_index_size, 1);
    EXPECT_EQ(m.header.rigid_body_index_size, 1);
    EXPECT_EQ(m.header.name, "");

    ASSERT_EQ(m.vertices.size(), 48);
    EXPECT_EQ(i32_at(b, 0x21), 48);
    // Vertex 0: position bytes b6b364bf 6081c1bd fc7a6fbf = (-0.8933672, -0.0944850, -0.9354703), normal -X.
    EXPECT_TRUE(
        m.vertices.positions.row(0).transpose().isApprox(Eigen::Vector3f(-0.8933672f, -0.0944850f, -0.9354703f)));
    EXPECT_EQ(Eigen::Vector3f(m.vertices.positions.row(0)), vec3_at(b, kVertex0));
    EXPECT_EQ(Eigen::Vector3f(m.vertices.normals.row(0)), Eigen::Vector3f(-1, 0, 0));
    EXPECT_EQ(m.vertices.deform[0], PmxDeform::kBdef1);
    EXPECT_EQ(b[kVertex0 + 32], 0);  // BDEF1
    // Vertex 47 (the second box): position (2, 6.0792828, -2), bone 1.
    const size_t v47 = kVertex0 + 47 * kVertexStride;
    EXPECT_EQ(Eigen::Vector3f(m.vertices.positions.row(47)), vec3_at(b, v47));
    EXPECT_EQ(Eigen::Vector3f(m.vertices.positions.row(47)), Eigen::Vector3f(2, f32_at(b, v47 + 4), -2));
    EXPECT_NEAR(m.vertices.positions(47, 1), 6.0792828f, 1e-6f);
    EXPECT_EQ(b[v47 + 33], 1);
    EXPECT_EQ(m.vertices.bone_indices(47, 0), 1);
    EXPECT_EQ(m.vertices.bone_weights(47, 0), 1.0f);
    EXPECT_EQ(m.vertices.edge_scale[47], f32_at(b, v47 + 34));

    EXPECT_EQ(i32_at(b, kFaceCount), 72);
    ASSERT_EQ(m.faces.rows(), 24);
    EXPECT_EQ(m.faces.row(0), Eigen::RowVector3i(0, 1, 2));
    EXPECT_EQ(m.faces.row(23),
              Eigen::RowVector3i(b[kFaceCount + 4 + 69], b[kFaceCount + 4 + 70], b[kFaceCount + 4 + 71]));
    EXPECT_EQ(m.faces.row(23), Eigen::RowVector3i(46, 47, 44));
    EXPECT_EQ(m.texture_count, 0);
    EXPECT_EQ(m.material_count, 2);
    EXPECT_EQ(m.morph_count, 0);
    EXPECT_EQ(m.display_frame_count, 2);
    EXPECT_EQ(m.soft_body_count, 0);
  }
}

TEST(PmxFixtures, BonesMatchTheBytes) {
  const std::vector<uint8_t> b = file_bytes(fixture("constraint_test.pmx"));
  const PmxModel m = read_pmx(fixture("constraint_test.pmx"));
  ASSERT_EQ(m.bones.size(), 2u);
  // Bone 0: "センター" (UTF-16LE bb30 f330 bf30 fc30) / "center", at the origin, no parent, flags 0x001e.
  EXPECT_EQ(m.bones[0].name, "\xE3\x82\xBB\xE3\x83\xB3\xE3\x82\xBF\xE3\x83\xBC");
  EXPECT_EQ(m.bones[0].name, "センター");
  EXPECT_EQ(m.bones[0].name_english, "center");
  EXPECT_EQ(m.bones[0].position, vec3_at(b, kBone0Position));
  EXPECT_EQ(m.bones[0].position, Eigen::Vector3f::Zero());
  EXPECT_EQ(b[kBone0Parent], 0xff);
  EXPECT_EQ(m.bones[0].parent, -1);
  EXPECT_EQ(b[kBone0Flags], 0x1e);
  EXPECT_EQ(m.bones[0].flags, 0x001e);
  EXPECT_TRUE(m.bones[0].rotatable && m.bones[0].translatable && m.bones[0].visible && m.bones[0].enabled);
  EXPECT_FALSE(m.bones[0].tail_is_bone || m.bones[0].is_ik || m.bones[0].inherit_rotation);
  EXPECT_EQ(m.bones[0].tail_offset, vec3_at(b, kBone0Tail));
  EXPECT_EQ(m.bones[0].tail_offset, Eigen::Vector3f(0, 5, 0));
  // Bone 1: "新規ボーン1" at (0, 5, 0), parent 0, flags 0x001a (rotatable, visible, enabled).
  EXPECT_EQ(m.bones[1].name, "新規ボーン1");
  EXPECT_EQ(m.bones[1].name_english, "");
  EXPECT_EQ(m.bones[1].position, vec3_at(b, kBone1Position));
  EXPECT_EQ(m.bones[1].position, Eigen::Vector3f(0, 5, 0));
  EXPECT_EQ(b[kBone1Parent], 0);
  EXPECT_EQ(m.bones[1].parent, 0);
  EXPECT_EQ(b[kBone1Flags], 0x1a);
  EXPECT_TRUE(m.bones[1].rotatable && !m.bones[1].translatable && m.bones[1].visible && m.bones[1].enabled);
}

TEST(PmxFixtures, RigidBodiesMatchTheBytes) {
  const std::vector<uint8_t> b = file_bytes(fixture("constraint_test.pmx"));
  const PmxModel m = read_pmx(fixture("constraint_test.pmx"));
  ASSERT_EQ(m.rigid_bodies.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    SCOPED_TRACE(i);
    const size_t at = i == 0 ? kBody0 : kBody1;
    const PmxRigidBody& r = m.rigid_bodies[static_cast<size_t>(i)];
    EXPECT_EQ(r.bone, b[at]);
    EXPECT_EQ(r.group, b[at + 1]);
    EXPECT_EQ(r.collision_mask, b[at + 2] | b[at + 3] << 8);
    EXPECT_EQ(static_cast<int>(r.shape), b[at + 4]);
    EXPECT_EQ(r.size, vec3_at(b, at + 5));
    EXPECT_EQ(r.position, vec3_at(b, at + 17));
    EXPECT_EQ(r.rotation, vec3_at(b, at + 29));
    EXPECT_EQ(r.mass, f32_at(b, at + 41));
    EXPECT_EQ(r.linear_damping, f32_at(b, at + 45));
    EXPECT_EQ(r.angular_damping, f32_at(b, at + 49));
    EXPECT_EQ(r.restitution, f32_at(b, at + 53));
    EXPECT_EQ(r.friction, f32_at(b, at + 57));
    EXPECT_EQ(static_cast<int>(r.mode), b[at + 61]);
  }
  // By hand from the dump: "新規剛体1" on bone 0, a 1x2x1 half-extent box at (0, 2, 0) that follows its bone;
  // "新規剛体2" on bone 1, a 2x2x2 box at (0, 8.1, 0), physics-driven. Both: group 0, mask ffff, mass 1, damping
  // 0.5 / 0.5, restitution 0, friction 0.5.
  const PmxRigidBody& a = m.rigid_bodies[0];
  const PmxRigidBody& c = m.rigid_bodies[1];
  EXPECT_EQ(a.name, "新規剛体1");
  EXPECT_EQ(c.name, "新規剛体2");
  EXPECT_EQ(a.bone, 0);
  EXPECT_EQ(c.bone, 1);
  EXPECT_EQ(a.shape, PmxShape::kBox);
  EXPECT_EQ(c.shape, PmxShape::kBox);
  EXPECT_EQ(a.size, Eigen::Vector3f(1, 2, 1));
  EXPECT_EQ(c.size, Eigen::Vector3f(2, 2, 2));
  EXPECT_EQ(a.position, Eigen::Vector3f(0, 2, 0));
  EXPECT_EQ(c.position, Eigen::Vector3f(0, 8.1f, 0));
  EXPECT_EQ(a.mode, PmxPhysicsMode::kFollowBone);
  EXPECT_EQ(c.mode, PmxPhysicsMode::kDynamic);
  for (const PmxRigidBody* r : {&a, &c}) {
    EXPECT_EQ(r->group, 0);
    EXPECT_EQ(r->collision_mask, 0xFFFF);
    EXPECT_EQ(r->mass, 1.0f);
    EXPECT_EQ(r->linear_damping, 0.5f);
    EXPECT_EQ(r->angular_damping, 0.5f);
    EXPECT_EQ(r->restitution, 0.0f);
    EXPECT_EQ(r->friction, 0.5f);
    EXPECT_EQ(r->rotation, Eigen::Vector3f::Zero());
  }
}

TEST(PmxFixtures, JointsMatchTheBytesAndDifferAsDocumented) {
  struct Expected {
    const char* file;
    Eigen::Vector3f rotation, angular_max;
  };
  // data/README.md: the four files differ in angular limits and joint rotations. cmp -l shows differences only in
  // joint.rotation (0x9d0..0x9db) and joint.angular_max (0xa00..0xa0b): 0x3fc90fdb = pi/2, 0x3f490fdb = pi/4,
  // 0xbd8efa35 = -0.0698132 (-4 degrees).
  const Expected expected[] = {
      {"constraint_test.pmx", {0, 0, 0}, {kPi / 2, 0, 0}},
      {"constraint_test2.pmx", {0, 0, 0}, {0, 0, kPi / 2}},
      {"constraint_test3.pmx", {-0.0698132f, 0, 0}, {kPi / 2, 0, 0}},
      {"constraint_test4.pmx", {0, kPi / 4, 0}, {0, 0, kPi / 2}},
  };
  for (const Expected& e : expected) {
    SCOPED_TRACE(e.file);
    const std::vector<uint8_t> b = file_bytes(fixture(e.file));
    const PmxModel m = read_pmx(fixture(e.file));
    ASSERT_EQ(m.joints.size(), 1u);
    const PmxJoint& j = m.joints[0];
    EXPECT_EQ(j.name, "新規Joint1");
    EXPECT_EQ(j.name_english, "");
    EXPECT_EQ(static_cast<int>(j.type), b[kJointType]);
    EXPECT_EQ(j.type, PmxJointType::kSpring6Dof);
    EXPECT_EQ(j.rigid_body_a, b[kJointType + 1]);
    EXPECT_EQ(j.rigid_body_b, b[kJointType + 2]);
    EXPECT_EQ(j.rigid_body_a, 0);
    EXPECT_EQ(j.rigid_body_b, 1);
    const Eigen::Vector3f* fields[] = {&j.position,    &j.rotation,    &j.linear_min,    &j.linear_max,
                                       &j.angular_min, &j.angular_max, &j.spring_linear, &j.spring_angular};
    for (int k = 0; k < 8; ++k) EXPECT_EQ(*fields[k], vec3_at(b, kJointType + 3 + 12 * static_cast<size_t>(k))) << k;
    EXPECT_EQ(kJointType + 3 + 12 * 8, b.size());  // the joint is the last thing in the file
    EXPECT_EQ(j.position, Eigen::Vector3f(0, 5, 0));
    EXPECT_TRUE(j.rotation.isApprox(e.rotation, 1e-6f) || (e.rotation.isZero() && j.rotation.isZero()));
    EXPECT_TRUE(j.angular_max.isApprox(e.angular_max, 1e-6f));
    EXPECT_EQ(j.angular_min, Eigen::Vector3f::Zero());
    EXPECT_EQ(j.linear_min, Eigen::Vector3f::Zero());
    EXPECT_EQ(j.linear_max, Eigen::Vector3f::Zero());
    EXPECT_EQ(j.spring_linear, Eigen::Vector3f::Zero());
    EXPECT_EQ(j.spring_angular, Eigen::Vector3f::Zero());
  }
  for (size_t a = 0; a < 4; ++a) {
    for (size_t c = a + 1; c < 4; ++c) {
      EXPECT_FALSE(expected[a].rotation == expected[c].rotation && expected[a].angular_max == expected[c].angular_max);
    }
  }
}

TEST(PmxFixtures, SkinWeightsAreTheBdef1Bones) {
  const PmxModel m = read_pmx(fixture("constraint_test.pmx"));
  const SparseWeights w = pmx_skin_weights(m);
  ASSERT_EQ(w.num_vertices(), 48);
  for (int i = 0; i < 48; ++i) {
    EXPECT_EQ(w.indices(i, 0), i < 24 ? 0 : 1) << i;  // the first box is skinned to bone 0, the second to bone 1
    EXPECT_EQ(w.weights.row(i), Eigen::RowVector4f(1, 0, 0, 0)) << i;
  }
}

TEST(PmxFixtures, ConversionToAmtFrame) {
  const PmxModel raw = read_pmx(fixture("constraint_test4.pmx"));
  const PmxModel m = pmx_to_amt_frame(raw);
  EXPECT_EQ(m.frame, PmxFrame::kAmt);
  EXPECT_EQ(m.scale, 0.08f);
  // Vertex 0 (-0.8933672, -0.0944850, -0.9354703) -> 0.08 (x, y, -z).
  EXPECT_TRUE(m.vertices.positions.row(0).isApprox(Eigen::RowVector3f(-0.07146938f, -0.0075588f, 0.07483762f), 1e-5f));
  EXPECT_EQ(m.faces.row(0), Eigen::RowVector3i(0, 2, 1));
  // Bone 1 at 5 units = 0.4 m up; body 2 at 8.1 units = 0.648 m, half extents 2 units = 0.16 m.
  EXPECT_TRUE(m.bones[1].position.isApprox(Eigen::Vector3f(0, 0.4f, 0)));
  EXPECT_TRUE(m.rigid_bodies[1].position.isApprox(Eigen::Vector3f(0, 0.648f, 0)));
  EXPECT_TRUE(m.rigid_bodies[1].size.isApprox(Eigen::Vector3f(0.16f, 0.16f, 0.16f)));
  EXPECT_EQ(m.rigid_bodies[1].mass, 1.0f);  // as authored
  // Joint rotation (0, pi/4, 0) about MMD's Y becomes (0, -pi/4, 0): a turn about +Y reverses in a mirrored frame.
  EXPECT_TRUE(m.joints[0].rotation.isApprox(Eigen::Vector3f(0, -kPi / 4, 0)));
  // Angular limit z in [0, pi/2] is kept (rotations about the mirror's normal keep their sense).
  EXPECT_TRUE(m.joints[0].angular_min.isZero());
  EXPECT_TRUE(m.joints[0].angular_max.isApprox(Eigen::Vector3f(0, 0, kPi / 2)));
  // constraint_test.pmx: limit x in [0, pi/2] becomes [-pi/2, 0].
  const PmxModel m1 = pmx_to_amt_frame(read_pmx(fixture("constraint_test.pmx")));
  EXPECT_TRUE(m1.joints[0].angular_min.isApprox(Eigen::Vector3f(-kPi / 2, 0, 0)));
  EXPECT_TRUE(m1.joints[0].angular_max.isZero());
  // constraint_test3.pmx: joint rotation x -4 degrees becomes +4 degrees.
  const PmxModel m3 = pmx_to_amt_frame(read_pmx(fixture("constraint_test3.pmx")));
  EXPECT_TRUE(m3.joints[0].rotation.isApprox(Eigen::Vector3f(0.0698132f, 0, 0)));
}

TEST(PmxFixtures, ConvertedWindingMatchesConvertedNormals) {
  const PmxModel raw = read_pmx(fixture("constraint_test.pmx"));
  // In the file, (b - a) x (c - a) agrees with the stored normals (MMD's left-handed clockwise-front convention).
  const MatrixX3f raw_normals = vertex_normals(raw.vertices.positions, raw.faces);
  const PmxModel m = pmx_to_amt_frame(raw);
  const TriMesh mesh = pmx_mesh(m);
  EXPECT_NO_THROW(validate_mesh(mesh, "constraint_test.pmx"));
  const MatrixX3f normals = vertex_normals(mesh.V, mesh.F);
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    EXPECT_GT(raw_normals.row(i).dot(raw.vertices.normals.row(i)), 0.99f) << i;
    EXPECT_GT(normals.row(i).dot(m.vertices.normals.row(i)), 0.99f) << i;
  }
}

// === Conversion on known values

TEST(PmxConversion, PositionsDirectionsAndRanges) {
  EXPECT_TRUE(pmx_to_amt_position(Eigen::Vector3f(1, 2, 3)).isApprox(Eigen::Vector3f(0.08f, 0.16f, -0.24f)));
  EXPECT_TRUE(pmx_to_amt_position(Eigen::Vector3f(1, 2, 3), 1.0f).isApprox(Eigen::Vector3f(1, 2, -3)));
  EXPECT_EQ(pmx_to_amt_direction(Eigen::Vector3f(0.6f, 0, -0.8f)), Eigen::Vector3f(0.6f, 0, 0.8f));
  EXPECT_EQ(pmx_to_amt_euler(Eigen::Vector3f(0.1f, 0.2f, 0.3f)), Eigen::Vector3f(-0.1f, -0.2f, 0.3f));
  Eigen::Vector3f lo, hi;
  pmx_to_amt_angle_range(Eigen::Vector3f(-0.1f, -0.2f, -0.3f), Eigen::Vector3f(0.4f, 0.5f, 0.6f), lo, hi);
  EXPECT_EQ(lo, Eigen::Vector3f(-0.4f, -0.5f, -0.3f));
  EXPECT_EQ(hi, Eigen::Vector3f(0.1f, 0.2f, 0.6f));
  pmx_to_amt_length_range(Eigen::Vector3f(-1, -2, -3), Eigen::Vector3f(4, 5, 6), 0.5f, lo, hi);
  EXPECT_EQ(lo, Eigen::Vector3f(-0.5f, -1, -3));
  EXPECT_EQ(hi, Eigen::Vector3f(2, 2.5f, 1.5f));
}

TEST(PmxConversion, EulerOrderIsYawPitchRoll) {
  // R = Ry Rx Rz: a point on +Z turned by pitch 90 degrees (about X) goes to -Y, then yaw 90 (about Y) keeps it.
  const Eigen::Matrix3f R = pmx_euler_rotation(Eigen::Vector3f(kPi / 2, kPi / 2, 0));
  EXPECT_TRUE((R * Eigen::Vector3f::UnitZ()).isApprox(Eigen::Vector3f(0, -1, 0), 1e-6f));
  // Roll first: +X rolled 90 about Z -> +Y, pitched 90 about X -> +Z, yawed 90 about Y -> +X.
  const Eigen::Matrix3f R2 = pmx_euler_rotation(Eigen::Vector3f(kPi / 2, kPi / 2, kPi / 2));
  EXPECT_TRUE((R2 * Eigen::Vector3f::UnitX()).isApprox(Eigen::Vector3f(1, 0, 0), 1e-6f));
}

TEST(PmxConversion, EulerMapIsConjugationByTheMirror) {
  // The converted angles must give S R S for every rotation, so that R_amt (S d) = S (R_mmd d).
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> angle(-kPi, kPi);
  const Eigen::Matrix3f S = Eigen::Vector3f(1, 1, -1).asDiagonal();
  for (int t = 0; t < 100; ++t) {
    const Eigen::Vector3f e(angle(rng), angle(rng), angle(rng));
    const Eigen::Matrix3f expected = S * pmx_euler_rotation(e) * S;
    EXPECT_TRUE(pmx_euler_rotation(pmx_to_amt_euler(e)).isApprox(expected, 1e-5f)) << e.transpose();
  }
}

// === Files from the product writer (data_tools/formats/pmx_export.h), plus the sections it does not model

struct WriteOptions {
  float version = 2.0f;
  PmxTextEncoding encoding = PmxTextEncoding::kUtf16Le;
  int vertex_index_size = 2;
  int index_size = 2;            // texture, material, bone, morph and rigid body indices
  int extra_globals = 0;         // globals past the first 8 (PMX 2.1)
  bool skipped_sections = true;  // textures, materials, morphs, display frames (and 2.1 soft bodies) of every kind
};

// Bytes of a PMX file and the offset of each field the writer marks ("bones[3].parent").
struct Written {
  std::vector<uint8_t> bytes;
  PmxFieldOffsets offsets;
  int texture_count = 0, material_count = 0, morph_count = 0, display_frame_count = 0, soft_body_count = 0;
};

// Replaces bytes [begin, end) of `w` with `section`, whose fields `marks` are relative to its start: the offsets
// inside the old bytes are dropped, one at `begin` stays there (unless nothing is replaced: an insertion moves it),
// and those after them move.
void splice(Written& w, size_t begin, size_t end, const std::vector<uint8_t>& section, const PmxFieldOffsets& marks) {
  const int64_t delta = static_cast<int64_t>(section.size()) - static_cast<int64_t>(end - begin);
  for (auto it = w.offsets.begin(); it != w.offsets.end();) {
    const size_t at = it->second;
    if (at > begin && at < end) {
      it = w.offsets.erase(it);
      continue;
    }
    if (at >= end && !(at == begin && begin < end)) it->second = static_cast<size_t>(static_cast<int64_t>(at) + delta);
    ++it;
  }
  w.bytes.erase(w.bytes.begin() + static_cast<std::ptrdiff_t>(begin), w.bytes.begin() + static_cast<std::ptrdiff_t>(end));
  w.bytes.insert(w.bytes.begin() + static_cast<std::ptrdiff_t>(begin), section.begin(), section.end());
  for (const auto& [field, at] : marks) w.offsets[field] = begin + at;
}

// Two textures and two materials, one of each toon kind.
std::vector<uint8_t> textures_and_materials(const PmxModel& m, int index_size, PmxFieldOffsets& marks) {
  PmxEncoder e(m.header);
  e.i32(2);
  e.text("tex/body.png");
  e.text("toon/肌.bmp");
  marks["materials"] = e.bytes.size();
  e.i32(2);
  for (int i = 0; i < 2; ++i) {
    e.text(i == 0 ? "肌" : "スカート");
    e.text(i == 0 ? "skin" : "skirt");
    for (int k = 0; k < 4 + 3 + 1 + 3; ++k) e.f32(0.25f * k);  // diffuse, specular, strength, ambient
    e.u8(0x1F);                                                 // flags
    for (int k = 0; k < 4 + 1; ++k) e.f32(1);                   // edge colour, edge size
    e.index(0, index_size, "texture");
    e.index(-1, index_size, "sphere texture");
    e.u8(1);                                                    // sphere mode
    e.u8(static_cast<uint8_t>(i));                              // toon: 0 texture index, 1 shared toon byte
    if (i == 0) {
      e.index(1, index_size, "toon");
    } else {
      e.u8(3);
    }
    e.text("memo");
    e.i32(static_cast<int32_t>(i == 0 ? 3 : 3 * (m.faces.rows() - 1)));
  }
  return e.bytes;
}

// Two offsets of each morph type of the version, and two display frames.
std::vector<uint8_t> morphs_and_display_frames(const PmxModel& m, int index_size, bool v21, PmxFieldOffsets& marks) {
  PmxEncoder e(m.header);
  const int types = v21 ? 11 : 9;
  e.i32(types);
  for (int t = 0; t < types; ++t) {
    e.text("モーフ" + std::to_string(t));
    e.text("morph " + std::to_string(t));
    e.u8(static_cast<uint8_t>(t % 5));  // panel
    e.u8(static_cast<uint8_t>(t));      // type
    e.i32(2);                           // offsets
    for (int k = 0; k < 2; ++k) {
      switch (t) {
        case 0:  // group
        case 9:  // flip
          e.index(0, index_size, "morph");
          e.f32(0.5f);
          break;
        case 1:  // vertex
          e.vertex_index(1, "vertex");
          e.vec3(Eigen::Vector3f(0.1f, 0.2f, 0.3f));
          break;
        case 2:  // bone
          e.index(1, index_size, "bone");
          e.vec3(Eigen::Vector3f(0, 1, 0));
          for (int c = 0; c < 4; ++c) e.f32(c == 3 ? 1.0f : 0.0f);
          break;
        case 8:  // material
          e.index(-1, index_size, "material");
          e.u8(1);
          for (int c = 0; c < 28; ++c) e.f32(1);
          break;
        case 10:  // impulse
          e.index(0, index_size, "rigid body");
          e.u8(1);
          e.vec3(Eigen::Vector3f(1, 2, 3));
          e.vec3(Eigen::Vector3f(4, 5, 6));
          break;
        default:  // uv and additional uv
          e.vertex_index(2, "vertex");
          for (int c = 0; c < 4; ++c) e.f32(0.125f);
      }
    }
  }
  marks["display_frames"] = e.bytes.size();
  e.i32(2);
  for (int i = 0; i < 2; ++i) {
    e.text(i == 0 ? "Root" : "表情");
    e.text(i == 0 ? "Root" : "Exp");
    e.u8(1);
    e.i32(2);
    e.u8(0);  // bone element
    e.index(static_cast<int32_t>(m.bones.size()) - 1, index_size, "bone");
    e.u8(1);  // morph element
    e.index(0, index_size, "morph");
  }
  return e.bytes;
}

// One soft body with two anchors and three pins (PMX 2.1).
std::vector<uint8_t> soft_bodies(const PmxModel& m, int index_size) {
  PmxEncoder e(m.header);
  e.i32(1);
  e.text("スカート布");
  e.text("skirt cloth");
  e.u8(0);                                           // shape: triangle mesh
  e.index(1, index_size, "material");                // material
  e.u8(2);                                           // group
  e.u16(0xFFFB);                                     // mask
  e.u8(0x03);                                        // flags
  e.i32(2);                                          // B-link distance
  e.i32(4);                                          // clusters
  e.f32(1.5f);                                       // total mass
  e.f32(0.05f);                                      // margin
  e.i32(1);                                          // aerodynamics model
  for (int k = 0; k < 12 + 6; ++k) e.f32(0.1f * k);  // config, cluster
  for (int k = 0; k < 4; ++k) e.i32(k + 1);          // iterations
  for (int k = 0; k < 3; ++k) e.f32(1);              // material
  e.i32(2);                                          // anchors
  for (int k = 0; k < 2; ++k) {
    e.index(k, index_size, "rigid body");
    e.vertex_index(k, "vertex");
    e.u8(static_cast<uint8_t>(k));
  }
  e.i32(3);  // pins
  for (int k = 0; k < 3; ++k) e.vertex_index(k, "vertex");
  return e.bytes;
}

// The model written by pmx_to_bytes with the options' header; with `skipped_sections` its textures, material,
// morphs and display frames are replaced by ones of every kind (and 2.1 soft bodies are added), with
// `extra_globals` unknown globals are inserted; a 2.1 file without skipped sections ends after the joints.
Written write_with(PmxModel m, const WriteOptions& o) {
  const bool v21 = o.version > 2.05f;
  m.header.version = o.version;
  m.header.encoding = o.encoding;
  m.header.vertex_index_size = o.vertex_index_size;
  m.header.texture_index_size = m.header.material_index_size = m.header.bone_index_size =
      m.header.morph_index_size = m.header.rigid_body_index_size = o.index_size;
  Written w;
  w.bytes = pmx_to_bytes(m, &w.offsets);
  w.material_count = 1;  // the writer's one material and two display frames
  w.display_frame_count = 2;
  if (v21) {  // drop the writer's empty soft body section, or replace it
    PmxFieldOffsets none;
    splice(w, w.offsets.at("soft_bodies"), w.bytes.size(),
           o.skipped_sections ? soft_bodies(m, o.index_size) : std::vector<uint8_t>(), none);
    w.soft_body_count = o.skipped_sections ? 1 : 0;
  }
  if (o.skipped_sections) {
    PmxFieldOffsets marks{{"morphs", 0}};
    splice(w, w.offsets.at("morphs"), w.offsets.at("rigid_bodies"),
           morphs_and_display_frames(m, o.index_size, v21, marks), marks);
    marks = {{"textures", 0}};
    splice(w, w.offsets.at("textures"), w.offsets.at("bones"), textures_and_materials(m, o.index_size, marks), marks);
    w.texture_count = 2;
    w.material_count = 2;
    w.morph_count = v21 ? 11 : 9;
  }
  if (o.extra_globals > 0) {
    w.bytes[8] = static_cast<uint8_t>(8 + o.extra_globals);
    splice(w, 17, 17, std::vector<uint8_t>(static_cast<size_t>(o.extra_globals), 0x5A), {});
  }
  return w;
}

void expect_round_trip(bool v21, const WriteOptions& o) {
  const PmxModel expected = sample_model(v21);
  const Written w = write_with(expected, o);
  const PmxModel m = parse(w.bytes);
  EXPECT_EQ(m.source, "model.pmx");
  EXPECT_EQ(m.header.encoding, o.encoding);
  EXPECT_EQ(m.header.vertex_index_size, o.vertex_index_size);
  EXPECT_EQ(m.header.texture_index_size, o.index_size);
  EXPECT_EQ(m.header.material_index_size, o.index_size);
  EXPECT_EQ(m.header.bone_index_size, o.index_size);
  EXPECT_EQ(m.header.morph_index_size, o.index_size);
  EXPECT_EQ(m.header.rigid_body_index_size, o.index_size);
  expect_same_model(expected, m);
  EXPECT_EQ(m.texture_count, w.texture_count);
  EXPECT_EQ(m.material_count, w.material_count);
  EXPECT_EQ(m.morph_count, w.morph_count);
  EXPECT_EQ(m.display_frame_count, w.display_frame_count);
  EXPECT_EQ(m.soft_body_count, w.soft_body_count);
}

// The two textures and two materials the skipped sections hold (textures_and_materials), field for field.
TEST(PmxMaterials, TexturePathsAndMaterialsAreRead) {
  const PmxModel expected = sample_model(false);
  for (const PmxTextEncoding encoding : {PmxTextEncoding::kUtf16Le, PmxTextEncoding::kUtf8}) {
    WriteOptions o;
    o.encoding = encoding;
    const PmxModel m = parse(write_with(expected, o).bytes);
    EXPECT_EQ(m.textures, (std::vector<std::string>{"tex/body.png", "toon/肌.bmp"}));
    ASSERT_EQ(m.materials.size(), 2u);
    for (int i = 0; i < 2; ++i) {
      SCOPED_TRACE(i);
      const PmxMaterial& mat = m.materials[size_t(i)];
      EXPECT_EQ(mat.name, i == 0 ? "肌" : "スカート");
      EXPECT_EQ(mat.name_english, i == 0 ? "skin" : "skirt");
      EXPECT_EQ(mat.diffuse, Eigen::Vector4f(0, 0.25f, 0.5f, 0.75f));
      EXPECT_EQ(mat.specular, Eigen::Vector3f(1, 1.25f, 1.5f));
      EXPECT_EQ(mat.specular_strength, 1.75f);
      EXPECT_EQ(mat.ambient, Eigen::Vector3f(2, 2.25f, 2.5f));
      EXPECT_EQ(mat.flags, 0x1F);
      EXPECT_TRUE(mat.double_sided());
      EXPECT_EQ(mat.edge_colour, Eigen::Vector4f::Ones());
      EXPECT_EQ(mat.edge_size, 1.0f);
      EXPECT_EQ(mat.texture, 0);
      EXPECT_EQ(mat.sphere_texture, -1);
      EXPECT_EQ(mat.sphere_mode, PmxSphereMode::kMultiply);
      EXPECT_EQ(mat.shared_toon, i == 1);
      EXPECT_EQ(mat.toon, i == 0 ? 1 : 3);  // a texture index, then shared toon04
      EXPECT_EQ(mat.memo, "memo");
      EXPECT_EQ(mat.face_count, i == 0 ? 1 : expected.faces.rows() - 1);
    }
  }
}

// A material's face count beyond the faces left, or not whole triangles, and texture indices outside the table are
// one-line errors naming the field.
TEST(PmxMaterials, FaceCountsAndTextureIndicesAreChecked) {
  PmxModel m = sample_model(false);  // 4 faces
  m.textures = {"a.png"};
  PmxMaterial first;
  first.name = "first";
  first.face_count = 3;
  PmxMaterial second = first;
  second.name = "second";
  second.face_count = 2;
  m.materials = {first, second};
  EXPECT_NE(parse_error(pmx_to_bytes(m))
                .find(": materials[1].face_index_count: expected a multiple of 3 from 0 to 3 "
                      "(the face indices no earlier material draws), found 6"),
            std::string::npos);
  m.materials[1].face_count = 1;
  const PmxModel back = parse(pmx_to_bytes(m));
  ASSERT_EQ(back.materials.size(), 2u);
  EXPECT_EQ(back.materials[0].face_count + back.materials[1].face_count, 4);
  m.materials[0].texture = 1;
  EXPECT_NE(parse_error(pmx_to_bytes(m)).find(": materials[0].texture: expected -1 or an index below 1, found 1"),
            std::string::npos);
  m.materials[0].texture = -1;
  m.materials[1].toon = 2;
  EXPECT_NE(parse_error(pmx_to_bytes(m)).find(": materials[1].toon: expected -1 or an index below 1, found 2"),
            std::string::npos);
  m.materials[1].toon = -1;
  m.materials[1].sphere_mode = static_cast<PmxSphereMode>(4);
  EXPECT_NE(parse_error(pmx_to_bytes(m))
                .find(": materials[1].sphere_mode: expected 0 (none), 1 (multiply), 2 (add) or "
                      "3 (sub-texture), found 4"),
            std::string::npos);
  // A face index count that is not whole triangles, written by hand over the second material's count.
  m.materials[1].sphere_mode = PmxSphereMode::kNone;
  PmxFieldOffsets offsets;
  std::vector<uint8_t> bytes = pmx_to_bytes(m, &offsets);
  patch_u32(bytes, offsets.at("bones") - 4, 2);
  EXPECT_NE(parse_error(bytes).find(": materials[1].face_index_count: expected a multiple of 3 from 0 to 3 (the face "
                                    "indices no earlier material draws), found 2"),
            std::string::npos);
}

// === Round trips

TEST(PmxRoundTrip, Utf16WithOneByteIndices) {
  WriteOptions o;
  o.encoding = PmxTextEncoding::kUtf16Le;
  o.vertex_index_size = 1;
  o.index_size = 1;
  expect_round_trip(false, o);
}

TEST(PmxRoundTrip, Utf8WithTwoByteIndices) {
  WriteOptions o;
  o.encoding = PmxTextEncoding::kUtf8;
  o.vertex_index_size = 2;
  o.index_size = 2;
  expect_round_trip(false, o);
}

TEST(PmxRoundTrip, Utf16WithFourByteIndices) {
  WriteOptions o;
  o.vertex_index_size = 4;
  o.index_size = 4;
  expect_round_trip(false, o);
}

TEST(PmxRoundTrip, WithoutSkippedSections) {
  WriteOptions o;
  o.skipped_sections = false;
  expect_round_trip(false, o);
}

TEST(PmxRoundTrip, Version21WithQdefHingeSoftBodiesAndExtraGlobals) {
  for (int size : {1, 2, 4}) {
    SCOPED_TRACE(size);
    WriteOptions o;
    o.version = 2.1f;
    o.encoding = size == 2 ? PmxTextEncoding::kUtf8 : PmxTextEncoding::kUtf16Le;
    o.vertex_index_size = size;
    o.index_size = size;
    o.extra_globals = 3;
    expect_round_trip(true, o);
  }
}

TEST(PmxRoundTrip, Version21EndingAfterTheJointsHasNoSoftBodies) {
  WriteOptions o;
  o.version = 2.1f;
  o.skipped_sections = false;
  const Written w = write_with(sample_model(true), o);
  EXPECT_EQ(w.offsets.at("end_of_joints"), w.bytes.size());
  const PmxModel m = parse(w.bytes);
  EXPECT_EQ(m.header.version, 2.1f);
  EXPECT_EQ(m.soft_body_count, 0);
  EXPECT_EQ(m.joints[1].type, PmxJointType::kHinge);
  EXPECT_EQ(m.vertices.deform[5], PmxDeform::kQdef);
}

TEST(PmxRoundTrip, JapaneseNamesComeOutAsUtf8InBothEncodings) {
  for (PmxTextEncoding encoding : {PmxTextEncoding::kUtf16Le, PmxTextEncoding::kUtf8}) {
    WriteOptions o;
    o.encoding = encoding;
    const PmxModel m = parse(write_with(sample_model(false), o).bytes);
    EXPECT_EQ(m.bones[2].name, "\xE5\xB7\xA6\xE8\x85\x95");  // 左腕: U+5DE6 U+8155
    EXPECT_EQ(m.header.comment, "\xE3\x82\xB3\xE3\x83\xA1\xE3\x83\xB3\xE3\x83\x88 \xF0\x9F\x98\x80 (MIT)");
    EXPECT_EQ(m.bones[4].name, "左腕ＩＫ");
  }
}

TEST(PmxRoundTrip, UnsignedOneAndTwoByteVertexIndices) {
  // Vertex indices of 1 and 2 bytes are unsigned: 249 and 39999 must not come out negative.
  for (int size : {1, 2}) {
    SCOPED_TRACE(size);
    const int extra = size == 1 ? 244 : 39994;  // 250 or 40000 vertices
    PmxModel expected = sample_model(false, extra);
    WriteOptions o;
    o.vertex_index_size = size;
    o.index_size = 1;
    o.skipped_sections = false;
    const PmxModel m = parse(write_with(expected, o).bytes);
    ASSERT_EQ(m.vertices.size(), 6 + extra);
    EXPECT_EQ(m.faces.bottomRows<1>(), expected.faces.bottomRows<1>());
    EXPECT_EQ(m.faces.maxCoeff(), 5 + extra);
    EXPECT_EQ(m.faces, expected.faces);
  }
}

TEST(PmxRoundTrip, FlagsDecodeToBooleans) {
  const PmxModel m = parse(write_with(sample_model(false), WriteOptions()).bytes);
  const PmxBone& arm = m.bones[2];  // 0x0D1A
  EXPECT_TRUE(arm.rotatable && arm.visible && arm.enabled && arm.inherit_rotation && arm.has_fixed_axis &&
              arm.has_local_axes);
  EXPECT_FALSE(arm.translatable || arm.tail_is_bone || arm.is_ik || arm.inherit_translation || arm.inherit_local ||
               arm.physics_after_deform || arm.has_external_parent);
  const PmxBone& elbow = m.bones[3];  // 0x329B
  EXPECT_TRUE(elbow.tail_is_bone && elbow.inherit_local && elbow.inherit_translation && elbow.physics_after_deform &&
              elbow.has_external_parent);
  EXPECT_FALSE(elbow.inherit_rotation || elbow.is_ik);
  EXPECT_EQ(elbow.tail_bone, 4);
  EXPECT_TRUE(m.bones[4].is_ik);
  EXPECT_EQ(m.bones[4].ik.links.size(), 2u);
}

// === Skinning weights and mesh

TEST(PmxSkinning, AllDeformTypesBecomeNormalisedSparseWeights) {
  for (bool v21 : {false, true}) {
    SCOPED_TRACE(v21);
    WriteOptions o;
    o.version = v21 ? 2.1f : 2.0f;
    const PmxModel m = parse(write_with(sample_model(v21), o).bytes);
    const SparseWeights w = pmx_skin_weights(m);
    ASSERT_EQ(w.num_vertices(), 6);
    const auto expect_row = [&w](int i, Eigen::RowVector4i indices, Eigen::RowVector4f weights) {
      EXPECT_EQ(w.indices.row(i), indices) << "vertex " << i;
      EXPECT_TRUE(w.weights.row(i).isApprox(weights, 1e-6f)) << "vertex " << i << ": " << w.weights.row(i);
    };
    expect_row(0, {0, 0, 0, 0}, {1, 0, 0, 0});           // BDEF1
    expect_row(1, {1, 2, 0, 0}, {0.25f, 0.75f, 0, 0});   // BDEF2
    expect_row(2, {0, 1, 2, 0}, {0.5f, 0.3f, 0.2f, 0});  // BDEF4 with a -1 slot
    expect_row(3, {2, 3, 0, 0}, {0.6f, 0.4f, 0, 0});     // SDEF as BDEF2
    expect_row(4, {3, 4, 0, 0}, {0.5f, 0.5f, 0, 0});     // BDEF4 summing to 4, zero-weight slots dropped
    if (v21) {
      expect_row(5, {1, 2, 3, 4}, {0.1f, 0.2f, 0.3f, 0.4f});  // QDEF as BDEF4
    } else {
      expect_row(5, {3, 0, 0, 0}, {1, 0, 0, 0});  // BDEF2 with the bone twice: merged
    }
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(w.weights.row(i).sum(), 1.0f, 1e-6f);
  }
}

TEST(PmxSkinning, NegativeAndZeroWeightsFallBackToTheFirstBone) {
  PmxModel m = sample_model(false);
  m.vertices.bone_weights.row(2) << -1, 0, 0, 0;  // no positive weight
  m.vertices.bone_weights.row(4) << -2, 3, 0, 0;  // the negative weight counts as 0
  const SparseWeights w = pmx_skin_weights(parse(write_with(m, WriteOptions()).bytes));
  EXPECT_EQ(w.indices.row(2), Eigen::RowVector4i(0, 0, 0, 0));
  EXPECT_EQ(w.weights.row(2), Eigen::RowVector4f(1, 0, 0, 0));
  EXPECT_EQ(w.indices(4, 0), 4);
  EXPECT_EQ(w.weights.row(4), Eigen::RowVector4f(1, 0, 0, 0));
}

TEST(PmxSkinning, VerticesWithoutBonesAreAnError) {
  PmxModel m = sample_model(false);
  m.vertices.deform.assign(6, PmxDeform::kBdef1);
  m.vertices.bone_indices.setConstant(-1);
  m.vertices.bone_weights.setZero();
  m.vertices.bone_weights.col(0).setOnes();
  m.vertices.sdef_c.setZero();
  m.vertices.sdef_r0.setZero();
  m.vertices.sdef_r1.setZero();
  m.bones.clear();
  m.rigid_bodies[0].bone = -1;
  m.rigid_bodies[1].bone = -1;
  WriteOptions o;
  o.skipped_sections = false;
  const PmxModel parsed = parse(write_with(m, o).bytes);
  EXPECT_EQ(parsed.vertices.bone_indices(0, 0), -1);
  EXPECT_THROW(pmx_skin_weights(parsed), Error);
}

TEST(PmxMesh, ConversionMapsEveryGeometricField) {
  const PmxModel raw = parse(write_with(sample_model(false), WriteOptions()).bytes);
  const PmxModel m = pmx_to_amt_frame(raw, 0.5f);
  EXPECT_EQ(m.scale, 0.5f);
  EXPECT_THROW(pmx_to_amt_frame(m), Error);  // already converted
  EXPECT_THROW(pmx_to_amt_frame(raw, 0.0f), Error);
  const auto mirrored = [](Eigen::Vector3f p, float s) { return Eigen::Vector3f(s * p.x(), s * p.y(), -s * p.z()); };
  for (int i = 0; i < raw.vertices.size(); ++i) {
    EXPECT_TRUE(Eigen::Vector3f(m.vertices.positions.row(i)).isApprox(mirrored(raw.vertices.positions.row(i), 0.5f)));
    EXPECT_TRUE(Eigen::Vector3f(m.vertices.normals.row(i)).isApprox(mirrored(raw.vertices.normals.row(i), 1)));
  }
  EXPECT_TRUE(Eigen::Vector3f(m.vertices.sdef_c.row(3)).isApprox(Eigen::Vector3f(0.05f, 5.75f, 0.1f)));
  EXPECT_EQ(m.vertices.uvs, raw.vertices.uvs);
  EXPECT_EQ(m.vertices.bone_weights, raw.vertices.bone_weights);
  for (int f = 0; f < raw.faces.rows(); ++f) {
    EXPECT_EQ(m.faces.row(f), Eigen::RowVector3i(raw.faces(f, 0), raw.faces(f, 2), raw.faces(f, 1)));
  }
  EXPECT_TRUE(m.bones[2].position.isApprox(Eigen::Vector3f(0.5f, 6, -0.125f)));
  EXPECT_TRUE(m.bones[2].tail_offset.isApprox(Eigen::Vector3f(0.5f, -0.25f, 0)));
  EXPECT_TRUE(m.bones[2].fixed_axis.isApprox(Eigen::Vector3f(0.6f, 0, 0.8f)));
  EXPECT_TRUE(m.bones[2].local_axis_z.isApprox(Eigen::Vector3f(0, 0.6f, -0.8f)));
  EXPECT_EQ(m.bones[4].ik.links[0].limit_min, Eigen::Vector3f(-0.2f, -0.5f, 0));
  EXPECT_EQ(m.bones[4].ik.links[0].limit_max, Eigen::Vector3f(1, 0.5f, 1));
  EXPECT_TRUE(m.rigid_bodies[1].position.isApprox(Eigen::Vector3f(0.25f, 4.5f, 0.5f)));
  EXPECT_TRUE(m.rigid_bodies[1].size.isApprox(Eigen::Vector3f(0.25f, 0.125f, 0.05f)));
  EXPECT_TRUE(m.rigid_bodies[1].rotation.isApprox(Eigen::Vector3f(-0.1f, -0.2f, -0.3f)));
  const PmxJoint& j = m.joints[0];
  EXPECT_TRUE(j.position.isApprox(Eigen::Vector3f(0.25f, 4.75f, 0.4f)));
  EXPECT_TRUE(j.rotation.isApprox(Eigen::Vector3f(-0.05f, 0.1f, 0.15f)));
  EXPECT_TRUE(j.linear_min.isApprox(Eigen::Vector3f(-0.05f, -0.1f, -0.2f)));
  EXPECT_TRUE(j.linear_max.isApprox(Eigen::Vector3f(0.05f, 0.1f, 0.15f)));
  EXPECT_EQ(j.angular_min, Eigen::Vector3f(-0.75f, -0.5f, -0.125f));
  EXPECT_EQ(j.angular_max, Eigen::Vector3f(0.5f, 0.25f, 0.25f));
  EXPECT_EQ(j.spring_linear, raw.joints[0].spring_linear);
  EXPECT_EQ(j.spring_angular, raw.joints[0].spring_angular);
  const TriMesh mesh = pmx_mesh(m);
  EXPECT_EQ(mesh.V, m.vertices.positions);
  EXPECT_EQ(mesh.F, m.faces);
}

TEST(PmxText, Utf16SurrogatesAndUnpairedUnits) {
  const uint8_t emoji[] = {0x3D, 0xD8, 0x00, 0xDE};  // U+1F600
  EXPECT_EQ(utf16le_to_utf8(emoji, 4), "\xF0\x9F\x98\x80");
  const uint8_t lone_high[] = {0x3D, 0xD8, 0x41, 0x00};  // unpaired high surrogate, then 'A'
  EXPECT_EQ(utf16le_to_utf8(lone_high, 4),
            "\xEF\xBF\xBD"
            "A");
  const uint8_t lone_low[] = {0x00, 0xDE};
  EXPECT_EQ(utf16le_to_utf8(lone_low, 2), "\xEF\xBF\xBD");
  const uint8_t odd[] = {0x41, 0x00, 0x42};
  EXPECT_EQ(utf16le_to_utf8(odd, 3), "A\xEF\xBF\xBD");
  const uint8_t kana[] = {0xBB, 0x30, 0xFC, 0x30, 0x7F, 0x00, 0xE9, 0x00};  // セー, DEL, é
  EXPECT_EQ(utf16le_to_utf8(kana, 8), "\xE3\x82\xBB\xE3\x83\xBC\x7F\xC3\xA9");
}

TEST(PmxText, InvalidUtf8IsReplaced) {
  PmxModel m = sample_model(false);
  m.bones[1].name = std::string("a\xC3(\xED\xA0\x80z", 7);  // a truncated sequence and an encoded surrogate
  WriteOptions o;
  o.encoding = PmxTextEncoding::kUtf8;
  const PmxModel parsed = parse(write_with(m, o).bytes);
  EXPECT_EQ(parsed.bones[1].name, "a\xEF\xBF\xBD(\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBDz");
}

// === Bad input

std::string offset_of(const Written& w, const std::string& field) {
  return std::to_string(w.offsets.at(field));
}

TEST(PmxErrors, WrongMagicVersionAndGlobals) {
  const std::vector<uint8_t> good = write_with(sample_model(false), WriteOptions()).bytes;
  std::vector<uint8_t> b = good;
  b[2] = 'D';
  EXPECT_EQ(parse_error(b),
            "model.pmx: offset 0: header.magic: expected the bytes 50 4d 58 20 (\"PMX \"), found 50 4d 44 20");
  b = good;
  patch_f32(b, 4, 3.0f);
  EXPECT_EQ(parse_error(b), "model.pmx: offset 4: header.version: expected 2.0 or 2.1, found 3");
  b = good;
  b[8] = 9;  // 2.0 has exactly 8 globals
  EXPECT_EQ(parse_error(b), "model.pmx: offset 8: header.globals_count: expected 8 for PMX 2.0, found 9");
  b = good;
  b[9] = 2;
  EXPECT_EQ(parse_error(b), "model.pmx: offset 9: header.encoding: expected 0 (UTF-16LE) or 1 (UTF-8), found 2");
  b = good;
  b[10] = 5;
  EXPECT_EQ(parse_error(b), "model.pmx: offset 10: header.additional_uv_count: expected 0 to 4, found 5");
  b = good;
  b[14] = 3;
  EXPECT_EQ(parse_error(b), "model.pmx: offset 14: header.bone_index_size: expected 1, 2 or 4, found 3");
  EXPECT_EQ(parse_error({}),
            "model.pmx: offset 0: header.magic: expected 4 more bytes, found 0 before the end of the file");
  EXPECT_NE(parse_error(std::vector<uint8_t>(100, 0)).find("header.magic"), std::string::npos);
}

TEST(PmxErrors, FaceIndexPastTheVertexCount) {
  PmxModel m = sample_model(false);
  m.faces(2, 1) = 6;
  const Written w = write_with(m, WriteOptions());
  EXPECT_EQ(parse_error(w.bytes),
            "model.pmx: offset " + offset_of(w, "faces[2][1]") + ": faces[2][1]: expected an index below 6, found 6");
}

TEST(PmxErrors, FaceCountNotAMultipleOfThree) {
  Written w = write_with(sample_model(false), WriteOptions());
  patch_u32(w.bytes, w.offsets.at("faces"), 11);
  EXPECT_EQ(parse_error(w.bytes), "model.pmx: offset " + offset_of(w, "faces") +
                                      ": faces: expected a multiple of 3 vertex indices, found 11");
}

TEST(PmxErrors, BoneParentOutOfRange) {
  PmxModel m = sample_model(false);
  m.bones[3].parent = 7;
  const Written w = write_with(m, WriteOptions());
  EXPECT_EQ(parse_error(w.bytes), "model.pmx: offset " + offset_of(w, "bones[3].parent") +
                                      ": bones[3].parent: expected -1 or an index below 5, found 7");
  m = sample_model(false);
  m.bones[2].parent = -2;
  EXPECT_NE(parse_error(write_with(m, WriteOptions()).bytes)
                .find("bones[2].parent: expected -1 or an index below 5, found -2"),
            std::string::npos);
}

TEST(PmxErrors, BoneParentCycles) {
  PmxModel m = sample_model(false);
  m.bones[1].parent = 3;  // 1 -> 3 -> 2 -> 1
  const Written w = write_with(m, WriteOptions());
  const std::string message = parse_error(w.bytes);
  EXPECT_NE(message.find("parent cycle"), std::string::npos) << message;
  m = sample_model(false);
  m.bones[2].parent = 2;
  const Written self = write_with(m, WriteOptions());
  EXPECT_EQ(parse_error(self.bytes), "model.pmx: offset " + offset_of(self, "bones[2].parent") +
                                         ": bones[2].parent: expected another bone or -1, found the bone itself (2)");
}

TEST(PmxErrors, OtherIndicesOutOfRange) {
  PmxModel m = sample_model(false);
  m.vertices.bone_indices(2, 1) = 9;  // checked once the bone table is known; the offset is still the field's
  Written w = write_with(m, WriteOptions());
  const size_t bones_at = w.offsets.at("vertices[2].bones");
  EXPECT_EQ(parse_error(w.bytes), "model.pmx: offset " + std::to_string(bones_at + 2) +
                                      ": vertices[2].bones[1]: expected -1 or an index below 5, found 9");
  m = sample_model(false);
  m.bones[4].ik.target = -1;  // an IK target is required
  w = write_with(m, WriteOptions());
  EXPECT_EQ(parse_error(w.bytes), "model.pmx: offset " + offset_of(w, "bones[4].ik.target") +
                                      ": bones[4].ik.target: expected an index below 5, found -1");
  m = sample_model(false);
  m.bones[2].inherit_parent = 5;
  w = write_with(m, WriteOptions());
  EXPECT_NE(parse_error(w.bytes).find("bones[2].inherit_parent: expected -1 or an index below 5, found 5"),
            std::string::npos);
  m = sample_model(false);
  m.rigid_bodies[2].bone = 5;
  w = write_with(m, WriteOptions());
  EXPECT_EQ(parse_error(w.bytes), "model.pmx: offset " + offset_of(w, "rigid_bodies[2].bone") +
                                      ": rigid_bodies[2].bone: expected -1 or an index below 5, found 5");
  m = sample_model(false);
  m.joints[1].rigid_body_b = 3;
  w = write_with(m, WriteOptions());
  EXPECT_EQ(parse_error(w.bytes), "model.pmx: offset " + offset_of(w, "joints[1].rigid_body_b") +
                                      ": joints[1].rigid_body_b: expected -1 or an index below 3, found 3");
}

TEST(PmxErrors, HugeAndNegativeCounts) {
  const Written w = write_with(sample_model(false), WriteOptions());
  for (const char* section : {"vertices", "faces", "materials", "bones", "morphs", "rigid_bodies", "joints"}) {
    SCOPED_TRACE(section);
    std::vector<uint8_t> b = w.bytes;
    patch_u32(b, w.offsets.at(section), 0x7FFFFFFFu);  // 2^31 - 1 elements in a file of a few KB
    const std::string message = parse_error(b);
    EXPECT_EQ(message.rfind(
                  "model.pmx: offset " + offset_of(w, section) + ": " + section + ": expected a count of at most ", 0),
              0u)
        << message;
    EXPECT_NE(message.find("found 2147483647"), std::string::npos) << message;
    patch_u32(b, w.offsets.at(section), 0xFFFFFFF0u);
    EXPECT_EQ(parse_error(b),
              "model.pmx: offset " + offset_of(w, section) + ": " + section + ": expected a count >= 0, found -16");
  }
}

TEST(PmxErrors, AbsurdPositionIsRejected) {
  const Written w = write_with(sample_model(false), WriteOptions());
  std::vector<uint8_t> b = w.bytes;
  patch_f32(b, w.offsets.at("vertices[2].position"), 1e15f);
  EXPECT_EQ(parse_error(b), "model.pmx: vertices: expected coordinates within 10000 of the origin, found 1e+15 11 -0.3 "
                            "at vertex 2");
}

// Finite but absurd physics and bones (a flipped exponent byte): refused by name, where the simulation would
// have written them into the ground truth and the output. The bound is 10 times the largest vertex coordinate.
TEST(PmxErrors, AbsurdPhysicsAndBonePositionsAreRejected) {
  const PmxModel model = sample_model(false);
  const Written w = write_with(model, WriteOptions());
  const float reach = model.vertices.positions.cwiseAbs().maxCoeff();
  for (const char* field : {"rigid_bodies[1].position", "rigid_bodies[0].size", "joints[0].position",
                            "bones[1].position"}) {
    std::vector<uint8_t> b = w.bytes;
    patch_f32(b, w.offsets.at(field), 1e30f);
    const std::string error = parse_error(b);
    EXPECT_NE(error.find(std::string(field) + ": expected a "), std::string::npos) << error;
    EXPECT_NE(error.find("within " + std::to_string(int(10 * reach))), std::string::npos) << error;
    EXPECT_NE(error.find("found 1e+30"), std::string::npos) << error;
    // Just inside the bound parses.
    b = w.bytes;
    patch_f32(b, w.offsets.at(field), 9.5f * reach);
    EXPECT_NO_THROW(parse(b)) << field;
  }
  std::vector<uint8_t> b = w.bytes;
  patch_f32(b, w.offsets.at("rigid_bodies[1].mass"), 1e9f);
  EXPECT_NE(parse_error(b).find("rigid_bodies[1].mass: expected a mass in [0, 1e+06], found 1e+09"),
            std::string::npos);
}

TEST(PmxErrors, NonFiniteAndOutOfRangeNumbers) {
  const Written w = write_with(sample_model(false), WriteOptions());
  std::vector<uint8_t> b = w.bytes;
  patch_f32(b, w.offsets.at("vertices[2].position"), std::nanf(""));
  EXPECT_EQ(parse_error(b), "model.pmx: offset " + offset_of(w, "vertices[2].position") +
                                ": vertices[2].position: expected finite values, found nan 11 -0.3");
  b = w.bytes;
  patch_f32(b, w.offsets.at("rigid_bodies[1].size") + 4, INFINITY);
  EXPECT_NE(parse_error(b).find("rigid_bodies[1].size: expected finite values, found 0.5 inf 0.1"), std::string::npos);
  b = w.bytes;
  patch_f32(b, w.offsets.at("rigid_bodies[1].size"), -0.5f);
  EXPECT_NE(parse_error(b).find("rigid_bodies[1].size: expected sizes >= 0"), std::string::npos);
  b = w.bytes;
  patch_f32(b, w.offsets.at("rigid_bodies[1].mass"), std::nanf(""));
  EXPECT_EQ(parse_error(b), "model.pmx: offset " + offset_of(w, "rigid_bodies[1].mass") +
                                ": rigid_bodies[1].mass: expected a finite number, found nan");
  b = w.bytes;
  patch_f32(b, w.offsets.at("rigid_bodies[1].mass"), -1);
  EXPECT_NE(parse_error(b).find("rigid_bodies[1].mass: expected a mass in [0, 1e+06], found -1"), std::string::npos);
  b = w.bytes;
  b[w.offsets.at("vertices[3].bones") - 1] = 7;  // deform type
  EXPECT_NE(parse_error(b).find("vertices[3].deform: expected 0 (BDEF1)"), std::string::npos);
  b = w.bytes;
  b[w.offsets.at("rigid_bodies[1].size") - 1] = 3;  // shape
  EXPECT_NE(parse_error(b).find("rigid_bodies[1].shape: expected 0 (sphere), 1 (box) or 2 (capsule), found 3"),
            std::string::npos);
  b = w.bytes;
  b[w.offsets.at("rigid_bodies[1].size") - 4] = 16;  // group
  EXPECT_NE(parse_error(b).find("rigid_bodies[1].group: expected 0 to 15, found 16"), std::string::npos);
}

TEST(PmxErrors, TextLengths) {
  const Written w = write_with(sample_model(false), WriteOptions());
  std::vector<uint8_t> b = w.bytes;
  patch_u32(b, 17, 3);  // header.name: odd UTF-16 length
  EXPECT_EQ(parse_error(b),
            "model.pmx: offset 17: header.name: expected an even byte length for UTF-16LE text, found 3");
  patch_u32(b, 17, 0x10000000u);
  EXPECT_EQ(parse_error(b).rfind("model.pmx: offset 17: header.name: expected a text byte length of at most ", 0), 0u);
  patch_u32(b, 17, 0xFFFFFFFFu);
  EXPECT_EQ(parse_error(b), "model.pmx: offset 17: header.name: expected a text byte length >= 0, found -1");
}

// Every proper prefix of a valid file is an amt::Error, never a crash or another exception (run it under ASan to
// also catch out-of-bounds reads). Copies each prefix so that ASan sees the exact end.
void expect_every_truncation_fails(const Written& w, size_t allowed_length) {
  for (size_t length = 0; length < w.bytes.size(); ++length) {
    const std::vector<uint8_t> prefix(w.bytes.begin(), w.bytes.begin() + static_cast<std::ptrdiff_t>(length));
    if (length == allowed_length) {
      EXPECT_NO_THROW(parse(prefix)) << length;
      continue;
    }
    try {
      parse(prefix);
      ADD_FAILURE() << "a prefix of " << length << " bytes parsed";
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.find('\n'), std::string::npos);
      EXPECT_EQ(message.rfind("model.pmx: offset ", 0), 0u) << message;
    }
  }
}

TEST(PmxErrors, EveryTruncationIsAnError) {
  for (int size : {1, 2, 4}) {
    SCOPED_TRACE(size);
    WriteOptions o;
    o.vertex_index_size = size;
    o.index_size = size;
    o.encoding = size == 2 ? PmxTextEncoding::kUtf8 : PmxTextEncoding::kUtf16Le;
    expect_every_truncation_fails(write_with(sample_model(false), o), SIZE_MAX);
  }
  WriteOptions o;
  o.version = 2.1f;
  o.extra_globals = 2;
  const Written w = write_with(sample_model(true), o);
  // A 2.1 file cut exactly after the joints is a valid file without soft bodies.
  expect_every_truncation_fails(w, w.offsets.at("end_of_joints"));
}

TEST(PmxErrors, RandomCorruptionNeverCrashes) {
  WriteOptions o;
  o.version = 2.1f;
  const std::vector<uint8_t> good = write_with(sample_model(true), o).bytes;
  std::mt19937 rng(1234);
  std::uniform_int_distribution<size_t> position(0, good.size() - 1);
  std::uniform_int_distribution<int> byte(0, 255), edits(1, 8);
  int parsed = 0, rejected = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<uint8_t> b = good;
    for (int e = edits(rng); e > 0; --e) b[position(rng)] = static_cast<uint8_t>(byte(rng));
    try {
      const PmxModel m = parse(b);
      const PmxModel converted = pmx_to_amt_frame(m);
      const SparseWeights w = pmx_skin_weights(converted);
      EXPECT_TRUE(w.weights.allFinite());
      ++parsed;
    } catch (const Error&) {
      ++rejected;
    }
  }
  EXPECT_GT(parsed, 0);
  EXPECT_GT(rejected, 0);
}

void expect_read_error(const std::string& path, const std::string& expected) {
  try {
    read_pmx(path);
    ADD_FAILURE() << "expected amt::Error";
  } catch (const Error& e) {
    EXPECT_EQ(e.what(), expected);
  }
}

TEST(PmxErrors, MissingFileAndDirectory) {
  expect_read_error("/nonexistent/model.pmx",
                    "/nonexistent/model.pmx: cannot open: no such file (expected a PMX model)");
  expect_read_error(AMT_ASSET_DIR, std::string(AMT_ASSET_DIR) +
                                       ": cannot read: expected a PMX model as a regular file, found a folder");
}

}  // namespace
}  // namespace amt

namespace amt {
namespace {

// Inputs the fuzzer (scripts/fuzz.sh pmx) found crashing once; each must import or fail cleanly.
TEST(PmxFuzzRegressions, EmptySectionsConvertToTheAmtFrame) {
  // A model with no vertices, faces, bones, bodies or joints: the conversion once offset a null
  // pointer here (caught by the sanitizers of scripts/fuzz.sh); it is a valid, empty model.
  const std::string path = std::string(AMT_TEST_ASSETS_DIR) + "/pmx/fuzz_empty_sections.pmx";
  const PmxModel model = pmx_to_amt_frame(read_pmx(path));
  EXPECT_EQ(model.frame, PmxFrame::kAmt);
  EXPECT_EQ(model.vertices.positions.rows(), 0);
  EXPECT_EQ(model.faces.rows(), 0);
  EXPECT_TRUE(model.bones.empty());
  EXPECT_TRUE(model.rigid_bodies.empty());
  EXPECT_TRUE(model.joints.empty());
}

}  // namespace
}  // namespace amt
