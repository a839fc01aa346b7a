// `amt dataset info`: the summaries of a file (print_dataset_info) and of a dataset folder built by
// amt dataset build (summarise_dataset_folder: totals, missing and damaged shards), and the command
// line run as a user runs it (exit status, one-line error on stderr).
#include "data_tools/builder/dataset_info.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "data_tools/builder/dataset_builder.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/error.h"
#include "tests/data_tools/builder/tiny_build.h"
#include "tests/test_support.h"

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
    rig.response.resize(3, 3);
    rig.response << 0, 0, 0, 1, 0.5f, 0.25f, 1, 0.75f, 0.5f;  // medians of two: the upper one
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
  EXPECT_TRUE(contains(text, "amt-dataset, version 2 (checksummed)")) << text;
  EXPECT_TRUE(contains(text, "fps       30")) << text;
  EXPECT_TRUE(contains(text, "3 joints")) << text;
  EXPECT_TRUE(contains(text, "characters: 2 (train 1, test 1)")) << text;
  EXPECT_TRUE(contains(text, "clips: 3 (train 2, test 1)")) << text;
  EXPECT_TRUE(contains(text, "25.0 %")) << text;  // bob: 1 of 4 vertices
  EXPECT_TRUE(contains(text, "50.0 %")) << text;  // ann: 2 of 4 vertices
  EXPECT_TRUE(contains(text, "3 bones")) << text;
  EXPECT_TRUE(contains(text, "2 simulated, swing 0.75 / 0.50")) << text;  // ann's response: bones 1 and 2
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

// === Dataset folders

// A tiny dataset of 3 characters (one held out) x 3 procedural clips (one held out) of 10 frames, built once; each
// test works on its own copy.
class DatasetFolderInfo : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    built_ = new fs::path(test::temp_dir("dataset_info_built"));
    build_dataset(test::tiny_build_options(*built_, 3));
  }
  static void TearDownTestSuite() { delete built_; }

  fs::path copy(const std::string& name) const {
    const fs::path dir = test::temp_dir(name);
    fs::copy(*built_, dir, fs::copy_options::recursive);
    return dir;
  }
  // The shards in manifest order, the train characters' first.
  static std::vector<std::string> shards_train_first(const fs::path& dir) {
    std::vector<std::string> train, test;
    for (const PlannedCharacter& c : read_build_manifest(dir.string()).characters) {
      (c.split == "train" ? train : test).push_back(shard_path(dir.string(), c.name));
    }
    train.insert(train.end(), test.begin(), test.end());
    return train;
  }
  static uint64_t bytes_of(const std::vector<std::string>& files) {
    uint64_t bytes = 0;
    for (const std::string& file : files) bytes += fs::file_size(file);
    return bytes;
  }

  static fs::path* built_;
};
fs::path* DatasetFolderInfo::built_ = nullptr;

TEST_F(DatasetFolderInfo, CompleteFolderTotals) {
  const fs::path dir = copy("folder_complete");
  const DatasetFolderSummary summary = summarise_dataset_folder(dir.string());
  EXPECT_TRUE(summary.has_manifest);
  EXPECT_EQ(summary.expected_characters, 3);
  EXPECT_EQ(summary.expected_clips_per_character, 3);
  ASSERT_EQ(summary.shards.size(), 3u);
  for (const ShardSummary& shard : summary.shards) {
    EXPECT_EQ(shard.status, ShardStatus::kRead) << shard.problem;
    EXPECT_EQ(shard.characters.total(), 1) << shard.path;
    EXPECT_EQ(shard.clips.total(), 3) << shard.path;
    EXPECT_EQ(shard.frames, 30) << shard.path;
  }
  EXPECT_EQ(summary.num_problems(), 0);
  // Held out: 1 of 3 characters (all its clips are test clips) and 1 of 3 clips of each train character.
  EXPECT_EQ(summary.characters.train, 2);
  EXPECT_EQ(summary.characters.test, 1);
  EXPECT_EQ(summary.clips.train, 4);
  EXPECT_EQ(summary.clips.test, 5);
  EXPECT_EQ(summary.frames, 90);
  EXPECT_EQ(summary.bytes, bytes_of(shards_train_first(dir)));

  std::ostringstream out;
  print_dataset_folder_summary(summary, out);
  const std::string text = out.str();
  EXPECT_TRUE(contains(text, "manifest  3 characters x 3 clips")) << text;
  EXPECT_TRUE(contains(text, "shards: 3 of 3 ok")) << text;
  EXPECT_TRUE(contains(text, "totals: 3 characters (train 2, test 1), 9 clips (train 4, test 5), 90 frames")) << text;
  EXPECT_TRUE(contains(text, "missing, damaged or not in the manifest: none")) << text;
}

TEST_F(DatasetFolderInfo, MissingTruncatedDuplicateAndUnknownShardsAreListed) {
  const fs::path dir = copy("folder_damaged");
  const std::vector<std::string> shards = shards_train_first(dir);
  const std::string& kept = shards[0];  // a train character
  const std::string& missing = shards[1];
  const std::string& truncated = shards[2];
  fs::remove(missing);
  // The interrupted build's part file of the missing shard.
  const std::string part = fs::path(missing).replace_extension(".part").string();
  std::ofstream(part) << "";
  fs::resize_file(truncated, fs::file_size(truncated) / 2);
  const std::string duplicate = (dir / "stray.h5").string();
  fs::copy_file(kept, duplicate);
  // A shard of another build: its character renamed.
  const std::string unknown = (dir / "zz_other.h5").string();
  {
    DatasetReader reader(kept);
    DatasetWriter writer(unknown, reader.fps(), reader.joint_names());
    CharacterData character = reader.read_character(reader.character_names()[0]);
    character.name = "someone-else";
    writer.add_character(character);
    writer.commit();
  }

  const DatasetFolderSummary summary = summarise_dataset_folder(dir.string());
  ASSERT_EQ(summary.shards.size(), 5u);
  EXPECT_EQ(summary.num_problems(), 4);
  std::map<std::string, const ShardSummary*> by_path;
  for (const ShardSummary& shard : summary.shards) by_path[shard.path] = &shard;
  ASSERT_EQ(by_path.size(), 5u);
  EXPECT_EQ(by_path[kept]->status, ShardStatus::kRead) << by_path[kept]->problem;
  EXPECT_EQ(by_path[missing]->status, ShardStatus::kMissing);
  EXPECT_EQ(by_path[missing]->problem.rfind(missing + ": missing (", 0), 0u) << by_path[missing]->problem;
  EXPECT_TRUE(contains(by_path[missing]->problem, fs::path(part).filename().string())) << by_path[missing]->problem;
  EXPECT_EQ(by_path[truncated]->status, ShardStatus::kDamaged);
  EXPECT_EQ(by_path[truncated]->problem.rfind(truncated + ": ", 0), 0u) << by_path[truncated]->problem;
  // The missing shard names its character's index in the manifest, which says which --shard i/n process makes it.
  const int index = by_path[missing]->manifest_index;
  EXPECT_EQ(fs::path(missing).stem().string(), read_build_manifest(dir.string()).characters.at(index).name);
  EXPECT_TRUE(contains(by_path[missing]->problem, "(character " + std::to_string(index) + " of 3, made by the build " +
                                                      "process --shard i/n with i = " + std::to_string(index) +
                                                      " mod n; "))
      << by_path[missing]->problem;
  EXPECT_EQ(by_path[duplicate]->status, ShardStatus::kDuplicate);
  EXPECT_EQ(by_path[duplicate]->problem, duplicate + ": holds " + fs::path(kept).stem().string() + " again, whose " +
                                             "shard is " + fs::path(kept).filename().string() +
                                             " (a duplicate: training would draw it twice as often; remove it)");
  EXPECT_EQ(by_path[unknown]->status, ShardStatus::kUnexpected);
  EXPECT_EQ(summary.shards.back().path, unknown);  // after the manifest's shards, sorted by name
  for (const ShardSummary& shard : summary.shards) {
    EXPECT_EQ(shard.problem.find('\n'), std::string::npos) << shard.problem;
  }
  // Totals count the shard that was read; the size counts every shard present.
  EXPECT_EQ(summary.characters.train, 1);
  EXPECT_EQ(summary.characters.test, 0);
  EXPECT_EQ(summary.clips.train, 2);
  EXPECT_EQ(summary.clips.test, 1);
  EXPECT_EQ(summary.frames, 30);
  EXPECT_EQ(summary.bytes, bytes_of({kept, truncated, duplicate, unknown}));

  std::ostringstream out;
  print_dataset_folder_summary(summary, out);
  const std::string text = out.str();
  EXPECT_TRUE(contains(text, "shards: 1 of 5 ok")) << text;
  EXPECT_TRUE(contains(text, "totals: 1 character (train 1, test 0), 3 clips (train 2, test 1), 30 frames")) << text;
  EXPECT_TRUE(contains(text, "missing, damaged or not in the manifest: 4 of 5 shards")) << text;
  for (const ShardSummary& shard : summary.shards) {
    if (shard.status == ShardStatus::kRead) continue;
    EXPECT_TRUE(contains(text, "  " + shard.problem + "\n")) << text;
  }

  // The completeness report of amt dataset check: the counts, then each problem under its kind.
  std::ostringstream completeness;
  print_dataset_completeness(summary, completeness);
  const std::string report = completeness.str();
  EXPECT_EQ(report.rfind("completeness: 3 characters in manifest.json, 1 shard whole, 1 missing, 1 damaged, "
                         "1 duplicate, 1 not in manifest\n",
                         0),
            0u)
      << report;
  EXPECT_TRUE(contains(report, "  missing: " + by_path[missing]->problem + "\n")) << report;
  EXPECT_TRUE(contains(report, "  duplicate: " + by_path[duplicate]->problem + "\n")) << report;
  EXPECT_TRUE(contains(report, "  not in manifest: " + by_path[unknown]->problem + "\n")) << report;
}

TEST_F(DatasetFolderInfo, CompletenessOfACompleteFolder) {
  std::ostringstream out;
  print_dataset_completeness(summarise_dataset_folder(copy("folder_whole").string()), out);
  EXPECT_EQ(out.str(), "completeness: 3 characters in manifest.json, 3 shards whole: complete (every character has "
                       "its shard, none is duplicated)\n");
}

TEST(DatasetFolderInfoWithoutBuild, FolderWithoutManifestIsSummarisedFromItsShards) {
  const fs::path dir = test::temp_dir("folder_no_manifest");
  write_dataset((dir / "a.h5").string());
  const DatasetFolderSummary summary = summarise_dataset_folder(dir.string());
  EXPECT_FALSE(summary.has_manifest);
  ASSERT_EQ(summary.shards.size(), 1u);
  EXPECT_EQ(summary.num_problems(), 0);
  EXPECT_EQ(summary.characters.total(), 2);
  EXPECT_EQ(summary.clips.train, 2);
  EXPECT_EQ(summary.clips.test, 1);
  EXPECT_EQ(summary.frames, 17);
}

TEST(DatasetFolderInfoWithoutBuild, EmptyFolderAndDamagedManifestThrow) {
  const fs::path empty = test::temp_dir("folder_empty");
  const std::string none = test::error_of([&] { summarise_dataset_folder(empty.string()); });
  EXPECT_TRUE(contains(none, empty.string() + ": no manifest.json and no *.h5 shard")) << none;
  const fs::path dir = test::temp_dir("folder_bad_manifest");
  std::ofstream(dir / "manifest.json") << "{";
  const std::string message = test::error_of([&] { summarise_dataset_folder(dir.string()); });
  EXPECT_TRUE(contains(message, (dir / "manifest.json").string() + ": not valid JSON")) << message;
}

TEST_F(DatasetFolderInfo, CommandSummarisesAFolderAndFailsOnDamage) {
  const fs::path dir = copy("folder_command");
  const std::string out = temp_name("out", ".txt"), err = temp_name("err", ".txt");
  const std::string command =
      std::string("'") + AMT_BINARY + "' dataset info '" + dir.string() + "' >'" + out + "' 2>'" + err + "'";
  EXPECT_EQ(run(command), 0) << read_text(err);
  EXPECT_TRUE(contains(read_text(out), "totals: 3 characters (train 2, test 1), 9 clips")) << read_text(out);
  EXPECT_TRUE(read_text(err).empty()) << read_text(err);

  fs::remove(shards_train_first(dir)[1]);
  EXPECT_NE(run(command), 0);
  const std::string stdout_text = read_text(out), stderr_text = read_text(err);
  fs::remove(out);
  fs::remove(err);
  EXPECT_TRUE(contains(stdout_text, "totals: 2 characters")) << stdout_text;
  EXPECT_TRUE(contains(stdout_text, ": missing")) << stdout_text;
  EXPECT_TRUE(contains(stderr_text, dir.string() + ": 1 of 3 shards missing, damaged or not in the manifest"))
      << stderr_text;
  ASSERT_FALSE(stderr_text.empty());
  EXPECT_EQ(stderr_text.find('\n'), stderr_text.size() - 1) << "expected one line: " << stderr_text;
}

}  // namespace
}  // namespace amt
