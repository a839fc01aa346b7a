// `amt dataset info`: the summary printed by print_dataset_info, and the command line run as a user
// runs it (exit status, one-line error on stderr).
#include "data_tools/dataset_info.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "data_tools/dataset_file.h"
#include "data_tools/error.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

std::string temp_name(const std::string& stem, const std::string& extension) {
  const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
  return (fs::path(::testing::TempDir()) /
          ("amt_info_" + std::string(test->name()) + "_" + stem + "_" + std::to_string(getpid()) + extension))
      .string();
}

// A unit square of two triangles (4 vertices) on a 3-joint chain; `apparel` vertices have mask 1.
CharacterData square(const std::string& name, const std::string& split, int apparel, bool with_rig) {
  CharacterData c;
  c.name = name;
  c.mesh.V.resize(4, 3);
  c.mesh.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;
  c.mesh.F.resize(2, 3);
  c.mesh.F << 0, 1, 2, 0, 2, 3;
  c.skeleton.names = {"root", "mid", "tip"};
  c.skeleton.parents = {-1, 0, 1};
  c.skeleton.rest_joints.resize(3, 3);
  c.skeleton.rest_joints << 0, 0, 0, 0, 1, 0, 0, 2, 0;
  c.apparel_mask.assign(4, 0);
  for (int i = 0; i < apparel; ++i) c.apparel_mask[3 - i] = 1;
  c.body_weights = MatrixXfR::Zero(4, 3);
  c.body_weights.col(0).setOnes();
  c.split = split;
  if (with_rig) {
    Rig rig;
    rig.bone_names = {"a", "b", "c"};
    rig.bone_parents = {-1, 0, 0};
    rig.rest_transforms.assign(3, Transform34::Identity());
    rig.skin_indices = MatrixXiR::Zero(4, 1);
    rig.skin_weights = MatrixXfR::Ones(4, 1);
    c.rig = rig;
  }
  return c;
}

// Two characters (one with a rig), three clips of 10 + 5 + 2 frames.
void write_dataset(const std::string& path) {
  const CharacterData bob = square("bob", "train", 1, false);
  const CharacterData ann = square("ann", "test", 2, true);
  DatasetWriter writer(path, 30.0f, bob.skeleton.names);
  writer.add_character(bob);
  writer.add_character(ann);
  const Transforms joints(3, Transform34::Identity());
  const Transforms bones(3, Transform34::Identity());
  writer.begin_clip({"bob_walk", "bob", "walk", "train", 30.0f, 0, GroundTruth::kVertices});
  for (int t = 0; t < 10; ++t) writer.append_frame(joints, bob.mesh.V);
  writer.end_clip();
  writer.begin_clip({"bob_run", "bob", "run", "train", 30.0f, 0, GroundTruth::kVertices});
  for (int t = 0; t < 5; ++t) writer.append_frame(joints, bob.mesh.V);
  writer.end_clip();
  writer.begin_clip({"ann_spin", "ann", "spin", "test", 30.0f, 0, GroundTruth::kRig});
  for (int t = 0; t < 2; ++t) writer.append_frame(joints, bones);
  writer.end_clip();
  writer.commit();
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(DatasetInfo, PrintsCountsSharesAndSplits) {
  const std::string path = temp_name("data", ".h5");
  write_dataset(path);
  std::ostringstream out;
  print_dataset_info(path, out);
  fs::remove(path);
  const std::string text = out.str();
  EXPECT_TRUE(contains(text, "amt-dataset, version 1")) << text;
  EXPECT_TRUE(contains(text, "fps       30")) << text;
  EXPECT_TRUE(contains(text, "3 joints")) << text;
  EXPECT_TRUE(contains(text, "characters: 2 (train 1, test 1)")) << text;
  EXPECT_TRUE(contains(text, "clips: 3 (train 2, test 1)")) << text;
  EXPECT_TRUE(contains(text, "25.0 %")) << text;  // bob: 1 of 4 vertices
  EXPECT_TRUE(contains(text, "50.0 %")) << text;  // ann: 2 of 4 vertices
  EXPECT_TRUE(contains(text, "3 bones")) << text;
  EXPECT_TRUE(contains(text, "totals: 2 characters (train 1, test 1), 3 clips (train 2, test 1), 17 frames")) << text;
  // One row per clip, with its frames and ground-truth form.
  std::istringstream lines(text);
  std::string line;
  int clip_rows = 0;
  while (std::getline(lines, line)) {
    if (contains(line, "bob_walk")) {
      ++clip_rows;
      EXPECT_TRUE(contains(line, " 10 ") && contains(line, "vertices") && contains(line, "train")) << line;
    }
    if (contains(line, "ann_spin")) {
      ++clip_rows;
      EXPECT_TRUE(contains(line, " 2 ") && contains(line, "rig") && contains(line, "test")) << line;
    }
  }
  EXPECT_EQ(clip_rows, 2);
}

TEST(DatasetInfo, BadFileThrows) {
  const std::string path = temp_name("bad", ".h5");
  std::ofstream(path) << "not a dataset\n";
  std::ostringstream out;
  try {
    print_dataset_info(path, out);
    ADD_FAILURE() << "expected amt::Error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), path)) << e.what();
  }
  fs::remove(path);
}

// Runs a shell command; returns its exit status.
int run(const std::string& command) {
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(DatasetInfoCommand, PrintsAGoodFile) {
  const std::string path = temp_name("data", ".h5"), out = temp_name("out", ".txt"), err = temp_name("err", ".txt");
  write_dataset(path);
  const int status =
      run(std::string("'") + AMT_BINARY + "' dataset info --threads 1 '" + path + "' >'" + out + "' 2>'" + err + "'");
  const std::string stdout_text = read_text(out), stderr_text = read_text(err);
  fs::remove(path);
  fs::remove(out);
  fs::remove(err);
  EXPECT_EQ(status, 0) << stderr_text;
  EXPECT_TRUE(contains(stdout_text, "bob")) << stdout_text;
  EXPECT_TRUE(contains(stdout_text, "characters: 2")) << stdout_text;
  EXPECT_TRUE(stderr_text.empty()) << stderr_text;
}

TEST(DatasetInfoCommand, MissingFileIsOneLineError) {
  const std::string path = temp_name("missing", ".h5"), out = temp_name("out", ".txt"), err = temp_name("err", ".txt");
  const int status =
      run(std::string("'") + AMT_BINARY + "' dataset info '" + path + "' >'" + out + "' 2>'" + err + "'");
  const std::string stderr_text = read_text(err);
  fs::remove(out);
  fs::remove(err);
  EXPECT_NE(status, 0);
  EXPECT_TRUE(contains(stderr_text, path)) << stderr_text;
  EXPECT_TRUE(contains(stderr_text, "no such file")) << stderr_text;
  ASSERT_FALSE(stderr_text.empty());
  EXPECT_EQ(stderr_text.find('\n'), stderr_text.size() - 1) << "expected one line: " << stderr_text;
}

TEST(DatasetInfoCommand, DamagedFileIsOneLineError) {
  const std::string path = temp_name("text", ".h5"), out = temp_name("out", ".txt"), err = temp_name("err", ".txt");
  std::ofstream(path) << "not a dataset\n";
  const int status =
      run(std::string("'") + AMT_BINARY + "' dataset info '" + path + "' >'" + out + "' 2>'" + err + "'");
  const std::string stderr_text = read_text(err);
  fs::remove(path);
  fs::remove(out);
  fs::remove(err);
  EXPECT_NE(status, 0);
  EXPECT_TRUE(contains(stderr_text, path)) << stderr_text;
  ASSERT_FALSE(stderr_text.empty());
  EXPECT_EQ(stderr_text.find('\n'), stderr_text.size() - 1) << "expected one line: " << stderr_text;
}

}  // namespace
}  // namespace amt
