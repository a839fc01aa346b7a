// The dataset file (docs/dataset.md, "The dataset file"): write -> read round trips, streaming frame ranges, rig
// ground truth against hand-computed skinning, the writer's atomic commit, and one amt::Error naming
// the file and the field for every kind of bad input.
#include "data_tools/formats/dataset_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

// The tests edit written files through the HDF5 C API to make them bad.
#include <hdf5.h>

#include "data_tools/geometry/error.h"
#include "tests/file_size_limit.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

// === Fixtures

// A unique file name under the test temporary folder, removed (with its writer's temporary file)
// at the end of the test.
class TempPath {
 public:
  TempPath() {
    static int counter = 0;
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = (fs::path(::testing::TempDir()) / ("amt_dataset_" + std::string(test->name()) + "_" +
                                               std::to_string(getpid()) + "_" + std::to_string(counter++) + ".h5"))
                .string();
    remove();
  }
  ~TempPath() { remove(); }
  const std::string& str() const { return path_; }

 private:
  void remove() const {
    std::error_code ignored;
    fs::remove(path_, ignored);
    fs::remove(path_ + ".amt-tmp", ignored);
  }
  std::string path_;
};

// A chain along +X: root at the origin, joint 1 at (1,0,0), joint 2 at (2,0,0).
Skeleton chain() {
  Skeleton s;
  s.names = {"root", "mid", "tip"};
  s.parents = {-1, 0, 1};
  s.rest_joints.resize(3, 3);
  s.rest_joints << 0, 0, 0, 1, 0, 0, 2, 0, 0;
  return s;
}

// A tetrahedron whose last vertex is apparel (mask 1 of 4: 25 %), each vertex bound to one joint.
CharacterData tetrahedron(const std::string& name, const Skeleton& skeleton, const std::string& split = "train") {
  CharacterData c;
  c.name = name;
  c.mesh.V.resize(4, 3);
  c.mesh.V << 0.1f, 0.2f, 0.3f, 1.0f / 3.0f, 0.0f, 0.0f, 0.0f, 1.7f, 0.0f, 0.0f, 0.0f, -2.25f;
  c.mesh.F.resize(4, 3);
  c.mesh.F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  c.skeleton = skeleton;
  c.apparel_mask = {0, 0, 0, 1};
  const int J = skeleton.num_joints();
  c.body_weights = MatrixXfR::Zero(4, J);
  for (int i = 0; i < 4; ++i) c.body_weights(i, i % J) = 1.0f;
  c.body_weights.row(3).setZero();
  c.body_weights(3, 0) = 0.25f;
  c.body_weights(3, 1) = 0.75f;
  c.split = split;
  return c;
}

// A two-bone rig for the tetrahedron: vertices 0 and 1 follow bone 0 ("hips"), vertex 2 bone 1
// ("skirt"), vertex 3 half and half.
Rig two_bone_rig() {
  Rig rig;
  rig.bone_names = {"hips", "skirt"};
  rig.bone_parents = {-1, 0};
  rig.rest_transforms = {make_transform(Eigen::Matrix3f::Identity(), Eigen::Vector3f(0, 0.9f, 0)),
                         make_transform(Eigen::Matrix3f::Identity(), Eigen::Vector3f(0, 0.8f, 0.1f))};
  rig.skin_indices.resize(4, 2);
  rig.skin_indices << 0, 1, 0, 1, 1, 0, 0, 1;
  rig.skin_weights.resize(4, 2);
  rig.skin_weights << 1, 0, 1, 0, 1, 0, 0.5f, 0.5f;
  return rig;
}

// Joint transforms of frame t: every joint turned about Z by 0.1 t rad and moved by (0.01 t, 0, 0).
Transforms joint_frame(const Skeleton& skeleton, int t) {
  Transforms T;
  const Eigen::Matrix3f R = Eigen::AngleAxisf(0.1f * t, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  for (int j = 0; j < skeleton.num_joints(); ++j) {
    T.push_back(make_transform(R, skeleton.rest_joints.row(j).transpose() + Eigen::Vector3f(0.01f * t, 0, 0)));
  }
  return T;
}

// Ground-truth vertices of frame t: the rest mesh moved by awkward, non-round offsets.
MatrixX3f vertex_frame(const CharacterData& c, int t) {
  MatrixX3f V = c.mesh.V;
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    V.row(i) += Eigen::RowVector3f(std::sin(0.3f * t + i), 0.1f * t / 3.0f, std::cos(0.7f * t * i));
  }
  return V;
}

bool bitwise_equal(const float* a, const float* b, size_t count) {
  return std::memcmp(a, b, count * sizeof(float)) == 0;
}

bool bitwise_equal(const Transforms& a, const Transforms& b) {
  return a.size() == b.size() && (a.empty() || bitwise_equal(a.front().data(), b.front().data(), 12 * a.size()));
}

// Writes a file with character "bob" (chain skeleton) and a clip "c1" of `frames` frames with
// vertex ground truth.
void write_vertex_dataset(const std::string& path, int frames = 4) {
  const Skeleton s = chain();
  const CharacterData bob = tetrahedron("bob", s);
  DatasetWriter writer(path, 30.0f, s.names);
  writer.add_character(bob);
  writer.begin_clip({"c1", "bob", "walk", "train", 30.0f, 0, GroundTruth::kVertices});
  for (int t = 0; t < frames; ++t) writer.append_frame(joint_frame(s, t), vertex_frame(bob, t));
  writer.end_clip();
  writer.commit();
}

// Expects `action` to throw amt::Error whose message contains every one of `parts`.
template <typename Action>
void expect_error(Action&& action, const std::vector<std::string>& parts) {
  try {
    action();
    ADD_FAILURE() << "expected an amt::Error containing '" << parts.front() << "'";
  } catch (const Error& e) {
    const std::string message = e.what();
    for (const std::string& part : parts) EXPECT_NE(message.find(part), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << "expected one line: " << message;
  }
}

// === Raw HDF5 edits that make a good file bad

// An HDF5 file opened for editing through the C API.
class RawFile {
 public:
  explicit RawFile(const std::string& path) : id_(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT)) {
    EXPECT_GE(id_, 0) << path;
  }
  ~RawFile() { H5Fclose(id_); }
  RawFile(const RawFile&) = delete;
  RawFile& operator=(const RawFile&) = delete;
  hid_t id() const { return id_; }

  // Replaces the attribute `name` of the root with a fixed-length string.
  void set_string_attribute(const char* name, const std::string& value) {
    H5Adelete(id_, name);
    const hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, value.size());
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t attribute = H5Acreate2(id_, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
    EXPECT_GE(H5Awrite(attribute, type, value.data()), 0);
    H5Aclose(attribute);
    H5Sclose(space);
    H5Tclose(type);
  }

  // Replaces the attribute `name` of the root with an int64 scalar.
  void set_int_attribute(const char* name, int64_t value) {
    H5Adelete(id_, name);
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t attribute = H5Acreate2(id_, name, H5T_STD_I64LE, space, H5P_DEFAULT, H5P_DEFAULT);
    EXPECT_GE(H5Awrite(attribute, H5T_NATIVE_INT64, &value), 0);
    H5Aclose(attribute);
    H5Sclose(space);
  }

  // Deletes the link at `object` ("/characters/bob/faces").
  void remove(const char* object) { EXPECT_GE(H5Ldelete(id_, object, H5P_DEFAULT), 0) << object; }

  // Replaces the dataset at `object` with one of `shape` holding `data` as `memory_type`.
  void replace(const char* object, std::vector<hsize_t> shape, hid_t file_type, hid_t memory_type, const void* data) {
    H5Ldelete(id_, object, H5P_DEFAULT);
    const hid_t space = H5Screate_simple(static_cast<int>(shape.size()), shape.data(), nullptr);
    const hid_t dataset = H5Dcreate2(id_, object, file_type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    EXPECT_GE(dataset, 0) << object;
    EXPECT_GE(H5Dwrite(dataset, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), 0) << object;
    H5Dclose(dataset);
    H5Sclose(space);
  }

  // Overwrites the whole dataset at `object` in place (same shape) with float data.
  void overwrite(const char* object, const std::vector<float>& data) {
    const hid_t dataset = H5Dopen2(id_, object, H5P_DEFAULT);
    EXPECT_GE(H5Dwrite(dataset, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()), 0) << object;
    H5Dclose(dataset);
  }

 private:
  hid_t id_;
};

// The vertices of `c` flattened, with entry `index` replaced by NaN.
std::vector<float> with_nan(const MatrixX3f& V, size_t index) {
  std::vector<float> data(V.data(), V.data() + V.size());
  data[index] = std::numeric_limits<float>::quiet_NaN();
  return data;
}

// === Round trips

TEST(DatasetFile, RoundTripsCharacterAndVertexClipBitwise) {
  TempPath path;
  const Skeleton s = canonical_skeleton();
  const CharacterData bob = tetrahedron("bob", s, "test");
  const int frames = 5;
  {
    DatasetWriter writer(path.str(), 24.0f, s.names);
    writer.add_character(bob);
    writer.begin_clip({"bob_walk", "bob", "walk_01", "test", 24.0f, 0, GroundTruth::kVertices});
    for (int t = 0; t < frames; ++t) writer.append_frame(joint_frame(s, t), vertex_frame(bob, t));
    EXPECT_EQ(writer.num_frames_in_clip(), frames);
    writer.end_clip();
    writer.commit();
  }
  EXPECT_FALSE(fs::exists(path.str() + ".amt-tmp"));

  const DatasetReader reader(path.str());
  EXPECT_EQ(reader.fps(), 24.0f);
  EXPECT_EQ(reader.joint_names(), canonical_joint_names());
  EXPECT_EQ(reader.character_names(), std::vector<std::string>{"bob"});
  EXPECT_EQ(reader.clip_names(), std::vector<std::string>{"bob_walk"});
  EXPECT_TRUE(reader.has_character("bob"));
  EXPECT_FALSE(reader.has_clip("bob"));

  const CharacterData read = reader.read_character("bob");
  EXPECT_EQ(read.name, "bob");
  EXPECT_TRUE(bitwise_equal(read.mesh.V.data(), bob.mesh.V.data(), 12));
  EXPECT_EQ(read.mesh.F, bob.mesh.F);
  EXPECT_EQ(read.skeleton.names, s.names);
  EXPECT_EQ(read.skeleton.parents, s.parents);
  EXPECT_TRUE(bitwise_equal(read.skeleton.rest_joints.data(), s.rest_joints.data(), s.rest_joints.size()));
  EXPECT_EQ(read.apparel_mask, bob.apparel_mask);
  ASSERT_EQ(read.body_weights.rows(), 4);
  ASSERT_EQ(read.body_weights.cols(), kCanonicalJointCount);
  EXPECT_TRUE(bitwise_equal(read.body_weights.data(), bob.body_weights.data(), bob.body_weights.size()));
  EXPECT_EQ(read.split, "test");
  EXPECT_FALSE(read.rig.has_value());

  const ClipInfo info = reader.clip_info("bob_walk");
  EXPECT_EQ(info.character, "bob");
  EXPECT_EQ(info.motion, "walk_01");
  EXPECT_EQ(info.split, "test");
  EXPECT_EQ(info.fps, 24.0f);
  EXPECT_EQ(info.num_frames, frames);
  EXPECT_EQ(info.ground_truth, GroundTruth::kVertices);

  const Transforms joints = reader.read_joint_transforms("bob_walk", 0, frames);
  const MatrixX3f vertices = reader.read_vertices("bob_walk", 0, frames);
  ASSERT_EQ(joints.size(), static_cast<size_t>(frames * kCanonicalJointCount));
  ASSERT_EQ(vertices.rows(), frames * 4);
  for (int t = 0; t < frames; ++t) {
    const Transforms expected = joint_frame(s, t);
    EXPECT_TRUE(bitwise_equal(joints[t * kCanonicalJointCount].data(), expected.front().data(), 12 * expected.size()))
        << "frame " << t;
    const MatrixX3f V = vertex_frame(bob, t);
    EXPECT_TRUE(bitwise_equal(vertices.middleRows(t * 4, 4).eval().data(), V.data(), 12)) << "frame " << t;
  }
}

TEST(DatasetFile, RigClipSkinsVerticesAsComputedByHand) {
  TempPath path;
  const Skeleton s = chain();
  CharacterData bob = tetrahedron("bob", s);
  bob.rig = two_bone_rig();
  bob.rig->response.resize(2, kRigResponseChannels);
  bob.rig->response << 0, 0, 0, 1, 0.75f, 0.25f;  // the hips kinematic, the skirt simulated
  // Frame 0: rest (identity skinning matrices). Frame 1: the skirt bone moves up by (0, 1, 0).
  // Frame 2: the hips bone turns 90 degrees about Y about the origin, the skirt bone stays.
  const Transforms rest = {Transform34::Identity(), Transform34::Identity()};
  Transforms lifted = rest;
  lifted[1].col(3) = Eigen::Vector3f(0, 1, 0);
  Transforms turned = rest;
  turned[0].leftCols<3>() = Eigen::AngleAxisf(float(M_PI) / 2, Eigen::Vector3f::UnitY()).toRotationMatrix();
  {
    DatasetWriter writer(path.str(), 30.0f, s.names);
    writer.add_character(bob);
    writer.begin_clip({"sim", "bob", "idle", "train", 30.0f, 0, GroundTruth::kRig});
    writer.append_frame(joint_frame(s, 0), rest);
    writer.append_frame(joint_frame(s, 1), lifted);
    writer.append_frame(joint_frame(s, 2), turned);
    writer.end_clip();
    writer.commit();
  }
  const DatasetReader reader(path.str());
  const CharacterData read = reader.read_character("bob");
  ASSERT_TRUE(read.rig.has_value());
  EXPECT_EQ(read.rig->bone_names, bob.rig->bone_names);
  EXPECT_EQ(read.rig->bone_parents, bob.rig->bone_parents);
  EXPECT_TRUE(bitwise_equal(read.rig->rest_transforms, bob.rig->rest_transforms));
  EXPECT_EQ(read.rig->skin_indices, bob.rig->skin_indices);
  EXPECT_EQ(read.rig->skin_weights, bob.rig->skin_weights);
  EXPECT_EQ(read.rig->response, bob.rig->response);

  const ClipInfo info = reader.clip_info("sim");
  EXPECT_EQ(info.ground_truth, GroundTruth::kRig);
  EXPECT_EQ(info.num_frames, 3);
  EXPECT_TRUE(bitwise_equal(reader.read_rig_transforms("sim", 1, 1), lifted));

  const MatrixX3f V = reader.read_vertices("sim", 0, 3);
  ASSERT_EQ(V.rows(), 12);
  const MatrixX3f& R = bob.mesh.V;
  // Rest frame: every vertex where it was.
  EXPECT_EQ(V.topRows(4), R);
  // Lifted: vertex 2 (all skirt) moves by exactly (0, 1, 0); vertex 3 (half skirt) by (0, 0.5, 0).
  EXPECT_EQ(V.row(4 + 0), R.row(0));
  EXPECT_EQ(V.row(4 + 1), R.row(1));
  EXPECT_EQ(V.row(4 + 2), (R.row(2) + Eigen::RowVector3f(0, 1, 0)).eval());
  EXPECT_EQ(V.row(4 + 3), (R.row(3) + Eigen::RowVector3f(0, 0.5f, 0)).eval());
  // Turned: (x, y, z) -> (z, y, -x) for hips vertices; vertex 3 blends the turned and rest positions.
  EXPECT_NEAR((V.row(8 + 0) - Eigen::RowVector3f(0.3f, 0.2f, -0.1f)).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR((V.row(8 + 1) - Eigen::RowVector3f(0.0f, 0.0f, -1.0f / 3.0f)).norm(), 0.0f, 1e-6f);
  EXPECT_EQ(V.row(8 + 2), R.row(2));
  EXPECT_NEAR((V.row(8 + 3) - Eigen::RowVector3f(-1.125f, 0.0f, -1.125f)).norm(), 0.0f, 1e-6f);
}

TEST(DatasetFile, StreamsAFrameRange) {
  TempPath path;
  write_vertex_dataset(path.str(), 10);
  const Skeleton s = chain();
  const CharacterData bob = tetrahedron("bob", s);
  const DatasetReader reader(path.str());
  ASSERT_EQ(reader.clip_info("c1").num_frames, 10);
  const Transforms joints = reader.read_joint_transforms("c1", 2, 3);
  const MatrixX3f vertices = reader.read_vertices("c1", 2, 3);
  ASSERT_EQ(joints.size(), 9u);
  ASSERT_EQ(vertices.rows(), 12);
  for (int k = 0; k < 3; ++k) {
    const Transforms expected = joint_frame(s, 2 + k);
    for (int j = 0; j < 3; ++j) EXPECT_EQ(joints[k * 3 + j], expected[j]) << "frame " << 2 + k << " joint " << j;
    EXPECT_EQ(vertices.middleRows(k * 4, 4), vertex_frame(bob, 2 + k)) << "frame " << 2 + k;
  }
  EXPECT_TRUE(reader.read_joint_transforms("c1", 10, 0).empty());
  expect_error([&] { reader.read_vertices("c1", 8, 3); }, {path.str(), "/clips/c1", "[8, 11)", "within [0, 10)"});
  expect_error([&] { reader.read_joint_transforms("c1", -1, 2); }, {path.str(), "/clips/c1", "[-1, 1)"});
  expect_error([&] { reader.read_rig_transforms("c1", 0, 1); }, {path.str(), "/clips/c1/rig_transforms"});
  expect_error([&] { reader.clip_info("nope"); }, {path.str(), "/clips/nope: missing"});
  expect_error([&] { reader.read_character("nope"); }, {path.str(), "/characters/nope: missing"});
}

TEST(DatasetFile, AppendResumesAnExistingFile) {
  TempPath path;
  write_vertex_dataset(path.str(), 3);
  const Skeleton s = chain();
  const CharacterData bob = tetrahedron("bob", s);
  {
    DatasetWriter writer = DatasetWriter::append(path.str());
    EXPECT_EQ(writer.fps(), 30.0f);
    EXPECT_EQ(writer.joint_names(), s.names);
    EXPECT_TRUE(writer.has_character("bob"));
    EXPECT_TRUE(writer.has_clip("c1"));
    // A clip of a character written before the append: its N comes from the file.
    writer.begin_clip({"c2", "bob", "run", "test", 60.0f, 0, GroundTruth::kVertices});
    expect_error([&] { writer.append_frame(joint_frame(s, 0), MatrixX3f(MatrixX3f::Zero(5, 3))); },
                 {path.str(), "/clips/c2/vertices", "expected N = 4 vertices per frame", "found 5"});
    writer.append_frame(joint_frame(s, 0), vertex_frame(bob, 7));
    writer.end_clip();
    writer.add_character(tetrahedron("ann", s, "test"));
    writer.commit();
  }
  const DatasetReader reader(path.str());
  EXPECT_EQ(reader.character_names(), (std::vector<std::string>{"ann", "bob"}));
  EXPECT_EQ(reader.clip_names(), (std::vector<std::string>{"c1", "c2"}));
  EXPECT_EQ(reader.clip_info("c1").num_frames, 3);
  EXPECT_EQ(reader.clip_info("c2").fps, 60.0f);
  EXPECT_EQ(reader.read_vertices("c2", 0, 1), vertex_frame(bob, 7));
  EXPECT_EQ(reader.read_vertices("c1", 2, 1), vertex_frame(bob, 2));
}

// Files of predictions carry the root attribute `predictions` (what made them); ground truth does not.
TEST(DatasetFile, PredictionsAreMarkedAndGroundTruthIsNot) {
  TempPath path;
  write_vertex_dataset(path.str(), 2);
  EXPECT_EQ(DatasetReader(path.str()).predictions(), "");
  {
    DatasetWriter writer = DatasetWriter::append(path.str());
    writer.mark_predictions("amt animate");
    writer.mark_predictions("amt retarget-cloth");  // a second mark replaces the first
    expect_error([&] { writer.mark_predictions(""); },
                 {path.str(), "attribute 'predictions'", "expected what made the predictions"});
    writer.commit();
  }
  const DatasetReader reader(path.str());
  EXPECT_EQ(reader.predictions(), "amt retarget-cloth");
  EXPECT_EQ(reader.read_vertices("c1", 1, 1), vertex_frame(tetrahedron("bob", chain()), 1));  // the frames kept
}

TEST(DatasetFile, WriterAndReaderMove) {
  TempPath path;
  const Skeleton s = chain();
  DatasetWriter first(path.str(), 30.0f, s.names);
  first.add_character(tetrahedron("bob", s));
  DatasetWriter second = std::move(first);
  EXPECT_EQ(second.path(), path.str());
  EXPECT_TRUE(second.has_character("bob"));
  DatasetWriter third(path.str() + "-other", 30.0f, s.names);
  third = std::move(second);  // the other writer's temporary file goes
  EXPECT_FALSE(fs::exists(path.str() + "-other.tmp"));
  third.commit();

  DatasetReader reader(path.str());
  DatasetReader moved = std::move(reader);
  EXPECT_EQ(moved.path(), path.str());
  EXPECT_EQ(moved.num_joints(), 3);
  EXPECT_EQ(moved.read_character("bob").mesh.num_vertices(), 4);
}

// === Atomic commit

TEST(DatasetFile, WriterWithoutCommitLeavesNoFile) {
  TempPath path;
  const Skeleton s = chain();
  {
    DatasetWriter writer(path.str(), 30.0f, s.names);
    writer.add_character(tetrahedron("bob", s));
    EXPECT_TRUE(fs::exists(writer.temporary_path()));
    EXPECT_FALSE(fs::exists(path.str()));
  }
  EXPECT_FALSE(fs::exists(path.str()));
  EXPECT_FALSE(fs::exists(path.str() + ".amt-tmp"));
}

TEST(DatasetFile, WriterWithoutCommitKeepsTheGoodFile) {
  TempPath path;
  write_vertex_dataset(path.str(), 2);
  const auto size = fs::file_size(path.str());
  const Skeleton s = chain();
  {
    DatasetWriter writer(path.str(), 30.0f, s.names);
    writer.add_character(tetrahedron("ann", s));
    writer.begin_clip({"c9", "ann", "jump", "train", 30.0f, 0, GroundTruth::kVertices});
    writer.append_frame(joint_frame(s, 0), tetrahedron("ann", s).mesh.V);
    // Bad input midway: the writer throws and is then destroyed.
    expect_error([&] { writer.append_frame(Transforms(2), tetrahedron("ann", s).mesh.V); },
                 {path.str(), "/clips/c9/joint_transforms", "expected J = 3", "found 2"});
  }
  EXPECT_FALSE(fs::exists(path.str() + ".amt-tmp"));
  ASSERT_TRUE(fs::exists(path.str()));
  EXPECT_EQ(fs::file_size(path.str()), size);
  const DatasetReader reader(path.str());
  EXPECT_EQ(reader.character_names(), std::vector<std::string>{"bob"});
  EXPECT_EQ(reader.clip_names(), std::vector<std::string>{"c1"});
}

TEST(DatasetFile, CommitReplacesTheOldFile) {
  TempPath path;
  write_vertex_dataset(path.str(), 2);
  const Skeleton s = chain();
  DatasetWriter writer(path.str(), 60.0f, s.names);
  writer.add_character(tetrahedron("ann", s));
  writer.commit();
  expect_error([&] { writer.add_character(tetrahedron("bob", s)); }, {path.str(), "already committed"});
  const DatasetReader reader(path.str());
  EXPECT_EQ(reader.fps(), 60.0f);
  EXPECT_EQ(reader.character_names(), std::vector<std::string>{"ann"});
  EXPECT_TRUE(reader.clip_names().empty());
}

TEST(DatasetFile, AFullDiskIsAOneLineErrorAndKeepsTheGoodFile) {
  TempPath path;
  write_vertex_dataset(path.str(), 2);
  const auto size = fs::file_size(path.str());
  const Skeleton s = chain();
  std::string error = "(no error)";
  {
    const test::FileSizeLimit full_disk(1024);
    if (!full_disk.active())
      GTEST_SKIP() << "the file size limit (RLIMIT_FSIZE) cannot be set: no full disk to simulate";
    try {
      DatasetWriter writer(path.str(), 30.0f, s.names);
      writer.add_character(tetrahedron("ann", s));
      writer.begin_clip({"c9", "ann", "jump", "train", 30.0f, 0, GroundTruth::kVertices});
      for (int t = 0; t < 8; ++t) writer.append_frame(joint_frame(s, t), tetrahedron("ann", s).mesh.V);
      writer.end_clip();
      writer.commit();
    } catch (const Error& e) {
      error = e.what();
    }
  }
  // One line naming the file and the system's reason; the temporary is gone, the good file kept.
  EXPECT_EQ(error.rfind(path.str() + ": ", 0), 0u) << error;
  EXPECT_NE(error.find("file write failed (File too large)"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(path.str() + ".amt-tmp"));
  EXPECT_EQ(fs::file_size(path.str()), size);
  EXPECT_EQ(DatasetReader(path.str()).clip_names(), std::vector<std::string>{"c1"});
}

// === Bad files: each error names the file and the field

TEST(DatasetFileErrors, MissingFile) {
  TempPath path;
  expect_error([&] { DatasetReader reader(path.str()); }, {path.str(), "no such file"});
  expect_error([&] { DatasetWriter::append(path.str()); }, {path.str(), "no such file"});
}

TEST(DatasetFileErrors, NotAnHdf5File) {
  TempPath path;
  std::ofstream(path.str()) << "name,vertices\nbob,4\n";
  expect_error([&] { DatasetReader reader(path.str()); }, {path.str(), "HDF5", "not HDF5"});
}

TEST(DatasetFileErrors, TruncatedFile) {
  TempPath path;
  write_vertex_dataset(path.str(), 40);
  fs::resize_file(path.str(), fs::file_size(path.str()) / 2);
  expect_error([&] { DatasetReader reader(path.str()); }, {path.str(), "truncated"});
}

TEST(DatasetFileErrors, WrongFormat) {
  TempPath path;
  write_vertex_dataset(path.str());
  RawFile(path.str()).set_string_attribute("format", "mesh-cache");
  expect_error([&] { DatasetReader reader(path.str()); },
               {path.str(), "attribute 'format'", "expected \"amt-dataset\"", "found \"mesh-cache\""});
}

TEST(DatasetFileErrors, MissingFormat) {
  TempPath path;
  write_vertex_dataset(path.str());
  { RawFile(path.str()).set_string_attribute("units", "inches"); }
  expect_error([&] { DatasetReader reader(path.str()); },
               {path.str(), "attribute 'units'", "expected \"metres\"", "found \"inches\""});
  { EXPECT_GE(H5Adelete(RawFile(path.str()).id(), "format"), 0); }
  expect_error([&] { DatasetReader reader(path.str()); }, {path.str(), "attribute 'format': missing"});
}

TEST(DatasetFileErrors, WrongVersion) {
  TempPath path;
  write_vertex_dataset(path.str());
  RawFile(path.str()).set_int_attribute("version", 7);
  expect_error([&] { DatasetReader reader(path.str()); },
               {path.str(), "attribute 'version': expected 1 to 2, found 7", "newer amt"});
  expect_error([&] { DatasetWriter::append(path.str()); }, {path.str(), "attribute 'version'"});
  // The append failed before anything changed: no temporary file is left behind.
  EXPECT_FALSE(fs::exists(path.str() + ".amt-tmp"));
}

TEST(DatasetFileErrors, MissingField) {
  TempPath path;
  write_vertex_dataset(path.str());
  RawFile(path.str()).remove("/characters/bob/faces");
  const DatasetReader reader(path.str());
  expect_error([&] { reader.read_character("bob"); },
               {path.str() + ": /characters/bob/faces: missing (expected dataset (F,3) int32)"});
  expect_error([&] { reader.character_summary("bob"); }, {path.str(), "/characters/bob/faces: missing"});
}

TEST(DatasetFileErrors, MissingGroundTruth) {
  TempPath path;
  write_vertex_dataset(path.str());
  RawFile(path.str()).remove("/clips/c1/vertices");
  const DatasetReader reader(path.str());
  expect_error([&] { reader.clip_info("c1"); }, {path.str(), "/clips/c1/vertices: missing", "rig_transforms"});
}

TEST(DatasetFileErrors, WrongElementType) {
  TempPath path;
  write_vertex_dataset(path.str());
  const float faces[] = {0, 1, 2};
  RawFile(path.str()).replace("/characters/bob/faces", {1, 3}, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, faces);
  expect_error([&] { DatasetReader(path.str()).read_character("bob"); },
               {path.str(), "/characters/bob/faces", "expected int32 elements, found float32"});
}

TEST(DatasetFileErrors, RigResponseOfTheWrongShapeOrRange) {
  TempPath path;
  const Skeleton s = chain();
  CharacterData bob = tetrahedron("bob", s);
  bob.rig = two_bone_rig();
  {
    DatasetWriter writer(path.str(), 30.0f, s.names);
    writer.add_character(bob);
    writer.commit();
  }
  EXPECT_EQ(DatasetReader(path.str()).read_character("bob").rig->response.rows(), 0);  // none written: none read
  const float narrow[] = {0, 0, 1, 0.5f};
  RawFile(path.str()).replace("/characters/bob/rig/response", {2, 2}, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, narrow);
  expect_error([&] { DatasetReader(path.str()).read_character("bob"); },
               {path.str(), "/characters/bob/rig/response", "(B,3)"});
  const float absurd[] = {0, 0, 0, 1, 50, 0};
  RawFile(path.str()).replace("/characters/bob/rig/response", {2, 3}, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, absurd);
  expect_error([&] { DatasetReader(path.str()).read_character("bob"); },
               {path.str(), "/characters/bob/rig/response", "[0, 4]", "for bone 1"});
}

TEST(DatasetFileErrors, ApparelMaskLengthDisagrees) {
  TempPath path;
  write_vertex_dataset(path.str());
  const uint8_t mask[] = {0, 1, 0};
  RawFile(path.str()).replace("/characters/bob/apparel_mask", {3}, H5T_STD_U8LE, H5T_NATIVE_UINT8, mask);
  const DatasetReader reader(path.str());
  expect_error([&] { reader.read_character("bob"); },
               {path.str(), "/characters/bob/apparel_mask", "expected N = 4", "found 3"});
  expect_error([&] { reader.character_summary("bob"); }, {path.str(), "/characters/bob/apparel_mask", "found 3"});
}

TEST(DatasetFileErrors, ClipVertexCountDisagreesWithCharacter) {
  TempPath path;
  write_vertex_dataset(path.str());
  const std::vector<float> vertices(4 * 3 * 3, 0.5f);
  RawFile(path.str()).replace("/clips/c1/vertices", {4, 3, 3}, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, vertices.data());
  expect_error([&] { DatasetReader(path.str()).clip_info("c1"); },
               {path.str() + ": /clips/c1/vertices: expected N = 4 vertices per frame (as "
                             "/characters/bob/rest_vertices), found 3"});
}

TEST(DatasetFileErrors, ClipFrameCountsDisagree) {
  TempPath path;
  write_vertex_dataset(path.str());
  const std::vector<float> vertices(3 * 4 * 3, 0.5f);
  RawFile(path.str()).replace("/clips/c1/vertices", {3, 4, 3}, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, vertices.data());
  expect_error([&] { DatasetReader(path.str()).clip_info("c1"); },
               {path.str(), "/clips/c1/vertices: expected T = 4 frames (as joint_transforms), found 3"});
}

TEST(DatasetFileErrors, NanInRestVertices) {
  TempPath path;
  write_vertex_dataset(path.str());
  const CharacterData bob = tetrahedron("bob", chain());
  RawFile(path.str()).overwrite("/characters/bob/rest_vertices", with_nan(bob.mesh.V, 7));
  expect_error([&] { DatasetReader(path.str()).read_character("bob"); },
               {path.str(), "/characters/bob/rest_vertices", "expected finite values", "vertex 2"});
}

TEST(DatasetFileErrors, NanInClipFrames) {
  TempPath path;
  write_vertex_dataset(path.str());
  const CharacterData bob = tetrahedron("bob", chain());
  std::vector<float> vertices;
  for (int t = 0; t < 4; ++t) {
    const MatrixX3f V = vertex_frame(bob, t);
    vertices.insert(vertices.end(), V.data(), V.data() + V.size());
  }
  vertices[2 * 12 + 4] = std::numeric_limits<float>::infinity();  // frame 2, vertex 1
  RawFile(path.str()).overwrite("/clips/c1/vertices", vertices);
  const DatasetReader reader(path.str());
  EXPECT_EQ(reader.read_vertices("c1", 0, 2).rows(), 8);  // frames before the bad one read fine
  expect_error([&] { reader.read_vertices("c1", 1, 3); },
               {path.str(), "/clips/c1/vertices", "expected finite values", "frame 2, vertex 1"});
}

TEST(DatasetFileErrors, FaceIndexPastVertexCount) {
  TempPath path;
  write_vertex_dataset(path.str());
  const int32_t faces[] = {0, 1, 2, 1, 2, 7};
  RawFile(path.str()).replace("/characters/bob/faces", {2, 3}, H5T_STD_I32LE, H5T_NATIVE_INT32, faces);
  expect_error([&] { DatasetReader(path.str()).read_character("bob"); },
               {path.str(), "/characters/bob", "faces", "[0, 4)", "found 7"});
}

TEST(DatasetFileErrors, EmptyMesh) {
  TempPath path;
  write_vertex_dataset(path.str());
  {
    RawFile file(path.str());
    file.replace("/characters/bob/rest_vertices", {0, 3}, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, nullptr);
    file.replace("/characters/bob/faces", {0, 3}, H5T_STD_I32LE, H5T_NATIVE_INT32, nullptr);
  }
  const DatasetReader reader(path.str());
  expect_error([&] { reader.read_character("bob"); }, {path.str(), "/characters/bob", "vertices", "empty mesh"});
  expect_error([&] { reader.character_summary("bob"); }, {path.str(), "/characters/bob/rest_vertices", "empty mesh"});
}

// === The writer rejects bad input with the same kind of message

TEST(DatasetWriterErrors, RejectsBadCharacters) {
  TempPath path;
  const Skeleton s = chain();
  DatasetWriter writer(path.str(), 30.0f, s.names);

  CharacterData empty = tetrahedron("empty", s);
  empty.mesh = TriMesh();
  empty.apparel_mask.clear();
  empty.body_weights.resize(0, 3);
  expect_error([&] { writer.add_character(empty); }, {path.str(), "/characters/empty", "vertices", "empty mesh"});

  CharacterData nan = tetrahedron("nan", s);
  nan.mesh.V(1, 2) = std::numeric_limits<float>::quiet_NaN();
  expect_error([&] { writer.add_character(nan); },
               {path.str(), "/characters/nan/rest_vertices", "expected finite values", "vertex 1"});

  CharacterData mask = tetrahedron("mask", s);
  mask.apparel_mask[2] = 2;
  expect_error([&] { writer.add_character(mask); }, {path.str(), "/characters/mask/apparel_mask", "found 2"});

  CharacterData short_mask = tetrahedron("short_mask", s);
  short_mask.apparel_mask.pop_back();
  expect_error([&] { writer.add_character(short_mask); },
               {path.str(), "/characters/short_mask/apparel_mask", "expected N = 4", "found 3"});

  CharacterData weights = tetrahedron("weights", s);
  weights.body_weights(0, 1) = 0.5f;
  expect_error([&] { writer.add_character(weights); },
               {path.str(), "/characters/weights/body_weights", "summing to 1", "vertex 0"});

  CharacterData faces = tetrahedron("faces", s);
  faces.mesh.F(3, 1) = 4;
  expect_error([&] { writer.add_character(faces); }, {path.str(), "/characters/faces", "faces", "found 4"});

  CharacterData other_skeleton = tetrahedron("other", canonical_skeleton());
  expect_error([&] { writer.add_character(other_skeleton); },
               {path.str(), "/characters/other: skeleton", "expected the file's 3 joints"});

  CharacterData split = tetrahedron("split", s, "validation");
  expect_error([&] { writer.add_character(split); },
               {path.str(), "/characters/split: attribute 'split'", "found \"validation\""});

  CharacterData slash = tetrahedron("a/b", s);
  expect_error([&] { writer.add_character(slash); }, {path.str(), "name", "without '/'"});

  CharacterData rig = tetrahedron("rig", s);
  rig.rig = two_bone_rig();
  rig.rig->skin_indices(2, 0) = 5;
  expect_error([&] { writer.add_character(rig); }, {path.str(), "/characters/rig/rig/skin_indices", "found 5"});
  rig.rig = two_bone_rig();
  rig.rig->skin_weights.conservativeResize(3, 2);
  expect_error([&] { writer.add_character(rig); }, {path.str(), "/characters/rig/rig/skin_weights", "found (3,2)"});
  rig.rig = two_bone_rig();
  rig.rig->bone_parents = {-1, 1};
  expect_error([&] { writer.add_character(rig); }, {path.str(), "/characters/rig/rig/bone_parents", "for bone 1"});
  rig.rig = two_bone_rig();
  rig.rig->response = MatrixXfR::Zero(2, 2);
  expect_error([&] { writer.add_character(rig); },
               {path.str(), "/characters/rig/rig/response", "expected (B,3) = (2,3)", "found (2,2)"});
  rig.rig->response = MatrixXfR::Zero(2, kRigResponseChannels);
  rig.rig->response(1, 2) = std::numeric_limits<float>::quiet_NaN();
  expect_error([&] { writer.add_character(rig); }, {path.str(), "/characters/rig/rig/response", "for bone 1"});
  rig.rig->response(1, 2) = 0.0f;
  rig.rig->response(1, 0) = 2.0f;  // the moved share is at most 1
  expect_error([&] { writer.add_character(rig); }, {path.str(), "/characters/rig/rig/response", "in [0, 1]"});

  writer.add_character(tetrahedron("bob", s));
  expect_error([&] { writer.add_character(tetrahedron("bob", s)); },
               {path.str(), "/characters/bob", "already in the file"});
  writer.commit();
  EXPECT_EQ(DatasetReader(path.str()).character_names(), std::vector<std::string>{"bob"});
}

TEST(DatasetWriterErrors, RejectsBadClips) {
  TempPath path;
  const Skeleton s = chain();
  const CharacterData bob = tetrahedron("bob", s);
  DatasetWriter writer(path.str(), 30.0f, s.names);
  expect_error([&] { DatasetWriter(path.str() + "x", 0.0f, s.names); }, {path.str() + "x", "fps", "found 0"});
  writer.add_character(bob);
  expect_error([&] { writer.append_frame(joint_frame(s, 0), bob.mesh.V); }, {path.str(), "expected an open clip"});
  expect_error(
      [&] {
        writer.begin_clip({"c", "zed", "walk", "train", 30.0f, 0, GroundTruth::kVertices});
      },
      {path.str(), "/clips/c: attribute 'character'", "found \"zed\""});
  expect_error(
      [&] {
        writer.begin_clip({"c", "bob", "walk", "train", 30.0f, 0, GroundTruth::kRig});
      },
      {path.str(), "/clips/c", "rig_transforms", "/characters/bob/rig"});

  writer.begin_clip({"c", "bob", "walk", "train", 30.0f, 0, GroundTruth::kVertices});
  expect_error(
      [&] {
        writer.begin_clip({"d", "bob", "walk", "train", 30.0f, 0, GroundTruth::kVertices});
      },
      {path.str(), "clip 'c' still open"});
  expect_error([&] { writer.end_clip(); }, {path.str(), "/clips/c", "at least 1 frame"});
  expect_error([&] { writer.commit(); }, {path.str(), "clip 'c' still open"});
  expect_error([&] { writer.append_frame(joint_frame(s, 0), Transforms(2)); },
               {path.str(), "/clips/c", "expected vertices", "found rig_transforms"});
  MatrixX3f nan = bob.mesh.V;
  nan(3, 0) = std::numeric_limits<float>::quiet_NaN();
  expect_error([&] { writer.append_frame(joint_frame(s, 0), nan); },
               {path.str(), "/clips/c/vertices", "expected finite values", "vertex 3"});
  writer.append_frame(joint_frame(s, 0), bob.mesh.V);
  writer.end_clip();
  expect_error(
      [&] {
        writer.begin_clip({"c", "bob", "walk", "train", 30.0f, 0, GroundTruth::kVertices});
      },
      {path.str(), "/clips/c", "already in the file"});
  writer.commit();
  // The rejected frames left no trace: the clip has the one good frame.
  EXPECT_EQ(DatasetReader(path.str()).clip_info("c").num_frames, 1);
}

}  // namespace
}  // namespace amt
