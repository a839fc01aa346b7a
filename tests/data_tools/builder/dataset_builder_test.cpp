// Tests of data_tools/builder/dataset_builder.h on a tiny dataset (tests/data_tools/builder/tiny_build.h): 2 characters
// of about 1000 vertices x 3 procedural clips of 10 frames, settling 0.1 s, committing every 2 clips.
#include "data_tools/builder/dataset_builder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <thread>
#include <utility>
#include <vector>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/pmx_export.h"
#include "tests/data_tools/builder/pmx_humanoid.h"
#include "tests/data_tools/builder/tiny_build.h"
#include "tests/test_support.h"

namespace amt {
namespace {

using test::error_of;
using test::tiny_build_options;

namespace fs = std::filesystem;

std::string bytes_of(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Every file of a folder (name -> FNV-1a 64 of its bytes and its size), without subfolders: readable on failure.
std::map<std::string, std::string> folder_bytes(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    const std::string bytes = bytes_of(entry.path());
    uint64_t h = 0xcbf29ce484222325ULL;
    for (const char c : bytes) h = (h ^ static_cast<unsigned char>(c)) * 0x100000001b3ULL;
    files[entry.path().filename().string()] = std::to_string(bytes.size()) + " bytes, fnv " + std::to_string(h);
  }
  return files;
}

std::vector<std::string> names_of(const std::map<std::string, std::string>& files) {
  std::vector<std::string> names;
  for (const auto& [name, bytes] : files) names.push_back(name);
  return names;
}

// One uninterrupted reference build, shared by the tests.
class DatasetBuilder : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    reference_ = new fs::path(test::temp_dir("dataset_builder_reference"));
    report_ = new DatasetBuildReport(build_dataset(tiny_build_options(*reference_)));
  }
  static void TearDownTestSuite() {
    delete reference_;
    delete report_;
  }
  static fs::path* reference_;
  static DatasetBuildReport* report_;
};
fs::path* DatasetBuilder::reference_ = nullptr;
DatasetBuildReport* DatasetBuilder::report_ = nullptr;

TEST(DatasetBuilderOptions, ParsesShardsAndRejectsBadOnes) {
  EXPECT_EQ(parse_shard("1/2").index, 1);
  EXPECT_EQ(parse_shard("1/2").count, 2);
  EXPECT_EQ(parse_shard("0/1").count, 1);
  for (const char* bad : {"2/2", "-1/2", "1", "a/b", "1/0", "/2", "1/", "1/2/3", "99999999/100000000"}) {
    const std::string message = error_of([&] { parse_shard(bad); });
    EXPECT_NE(message.find("--shard: expected i/n"), std::string::npos) << bad << ": " << message;
  }
}

TEST(DatasetBuilderOptions, HeldOutSetsAreSeededAndSized) {
  const std::vector<bool> a = held_out_set(32, 8, 5), b = held_out_set(32, 8, 5), c = held_out_set(32, 8, 6);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  EXPECT_EQ(std::count(a.begin(), a.end(), true), 4);
  EXPECT_EQ(std::count(c.begin(), c.end(), true), 4);
  const std::vector<bool> two = held_out_set(2, 8, 5), one = held_out_set(1, 8, 5);
  EXPECT_EQ(std::count(two.begin(), two.end(), true), 1);
  EXPECT_EQ(one, std::vector<bool>{false});
}

TEST_F(DatasetBuilder, WritesOneShardPerCharacterWithEveryClip) {
  EXPECT_EQ(report_->characters_built, 2);
  EXPECT_EQ(report_->clips_built, 6);
  EXPECT_EQ(report_->frames, 60);
  EXPECT_FALSE(report_->interrupted);
  EXPECT_EQ(names_of(folder_bytes(*reference_)),
            (std::vector<std::string>{"character-0000.h5", "character-0000.json", "character-0001.h5",
                                      "character-0001.json", "manifest.json"}));
  const DatasetReader reader((*reference_ / "character-0001.h5").string());
  EXPECT_EQ(reader.character_names(), std::vector<std::string>{"character-0001"});
  ASSERT_EQ(reader.clip_names().size(), 3u);
  EXPECT_EQ(reader.clip_names()[0], "character-0001__proc-run-001");  // sorted by name
  EXPECT_EQ(reader.clip_names()[2], "character-0001__proc-walk-000");
  const ClipInfo info = reader.clip_info("character-0001__proc-run-001");
  EXPECT_EQ(info.num_frames, 10);
  EXPECT_EQ(info.ground_truth, GroundTruth::kRig);
  EXPECT_EQ(info.motion, "proc-run-001");
  // Frame 0 is the character's rest pose: identity rotations at the rest joints.
  const CharacterData character = reader.read_character("character-0001");
  const Transforms first = reader.read_joint_transforms("character-0001__proc-run-001", 0, 1);
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    EXPECT_TRUE(first[j].leftCols<3>().isIdentity(1e-6f));
    EXPECT_TRUE(first[j].col(3).transpose().isApprox(character.skeleton.rest_joints.row(j), 1e-6f));
  }
  ASSERT_TRUE(character.rig.has_value());
  // The rig's physics response: the body's bones follow the animation (all zeros), the apparel chains'
  // bones are simulated, and those below a chain's first bone swing off rigid skinning during the probe.
  const Rig& rig = *character.rig;
  ASSERT_EQ(rig.response.rows(), rig.num_bones());
  int moved = 0;
  float largest = 0;
  for (int b = 0; b < rig.num_bones(); ++b) {
    if (b < kCanonicalJointCount) EXPECT_TRUE(rig.response.row(b).isZero()) << rig.bone_names[b];
    moved += rig.response(b, 0) == 1.0f;
    largest = std::max(largest, rig.response(b, 1));
  }
  EXPECT_GT(moved, 0);
  EXPECT_GT(largest, 0.05f);
}

TEST_F(DatasetBuilder, SplitsNeverShareCharactersOrClips) {
  std::set<std::string> train_characters, test_characters, train_motions, test_motions, held_characters;
  for (const char* shard : {"character-0000.h5", "character-0001.h5"}) {
    const DatasetReader reader((*reference_ / shard).string());
    for (const std::string& name : reader.character_names()) {
      if (reader.read_character(name).split == "test") held_characters.insert(name);
    }
    for (const std::string& clip : reader.clip_names()) {
      const ClipInfo info = reader.clip_info(clip);
      (info.split == "train" ? train_characters : test_characters).insert(info.character);
      (info.split == "train" ? train_motions : test_motions).insert(info.motion);
    }
  }
  // One held-out character (1 of 2) and one held-out clip (1 of 3, at least one).
  ASSERT_EQ(held_characters.size(), 1u);
  for (const std::string& c : held_characters) EXPECT_EQ(train_characters.count(c), 0u) << c;
  std::set<std::string> held_motions;
  for (const std::string& m : test_motions) {
    if (!train_motions.count(m)) held_motions.insert(m);
  }
  EXPECT_EQ(held_motions.size(), 1u);
  // Every motion of a train clip is trained on by every train character; a held-out motion by none.
  EXPECT_EQ(train_motions.size(), 2u);
  EXPECT_EQ(train_characters.size(), 1u);
}

TEST_F(DatasetBuilder, SameSeedGivesByteIdenticalShards) {
  const fs::path again = test::temp_dir("dataset_builder_again");
  // A second later, so that anything time-dependent (HDF5 object modification times) would show.
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  build_dataset(tiny_build_options(again));
  EXPECT_EQ(folder_bytes(again), folder_bytes(*reference_));
}

TEST_F(DatasetBuilder, TwoShardProcessesBuildTheSameDataset) {
  const fs::path dir = test::temp_dir("dataset_builder_shards");
  DatasetBuildOptions o = tiny_build_options(dir);
  o.shard = parse_shard("1/2");
  const DatasetBuildReport second = build_dataset(o);
  EXPECT_EQ(second.characters_total, 1);
  EXPECT_TRUE(fs::exists(dir / "character-0001.h5"));
  EXPECT_FALSE(fs::exists(dir / "character-0000.h5"));
  o.shard = parse_shard("0/2");
  build_dataset(o);
  EXPECT_EQ(folder_bytes(dir), folder_bytes(*reference_));
}

TEST_F(DatasetBuilder, InterruptedBuildResumesWithoutRedoingCommittedClips) {
  const fs::path dir = test::temp_dir("dataset_builder_resume");
  DatasetBuildOptions o = tiny_build_options(dir);
  o.stop_after_clips = 3;  // clips 0, 1 committed; clip 2 simulated but lost, as with a kill
  const DatasetBuildReport first = build_dataset(o);
  EXPECT_TRUE(first.interrupted);
  EXPECT_EQ(first.clips_built, 2);
  // Only the committed part is there: no *.h5 file a trainer would read, no temporary.
  EXPECT_EQ(names_of(folder_bytes(dir)), (std::vector<std::string>{"character-0000.part", "manifest.json"}));
  EXPECT_EQ(DatasetReader((dir / "character-0000.part").string()).clip_names().size(), 2u);

  o.stop_after_clips = -1;
  const DatasetBuildReport second = build_dataset(o);
  EXPECT_FALSE(second.interrupted);
  EXPECT_EQ(second.clips_skipped, 2);
  EXPECT_EQ(second.clips_built, 4);
  EXPECT_EQ(second.frames, 40);
  EXPECT_EQ(folder_bytes(dir), folder_bytes(*reference_));

  // A third run finds everything done.
  const DatasetBuildReport third = build_dataset(o);
  EXPECT_EQ(third.characters_skipped, 2);
  EXPECT_EQ(third.clips_built, 0);
  EXPECT_EQ(third.frames, 0);
}

TEST_F(DatasetBuilder, RejectsAFolderBuiltWithOtherSettings) {
  const fs::path dir = test::temp_dir("dataset_builder_other");
  fs::copy(*reference_, dir);
  const auto before = folder_bytes(dir);
  DatasetBuildOptions o = tiny_build_options(dir);
  o.seed = 12;
  const std::string message = error_of([&] { build_dataset(o); });
  EXPECT_NE(message.find("built with other settings (settings.seed: 12 here, 11 in the folder)"), std::string::npos)
      << message;
  o = tiny_build_options(dir);
  o.frames = 11;
  EXPECT_NE(error_of([&] { build_dataset(o); }).find("settings.frames"), std::string::npos);
  EXPECT_EQ(folder_bytes(dir), before);
}

// A manifest with nothing built beside it (a run that failed before its first shard) does not block a rerun with
// other settings: it is replaced, and the folder then describes the new build.
// A part file that cannot be resumed is rebuilt from the character's first clip: cut short (a full disk, a copy
// that stopped), or with a flipped byte in a committed clip (caught by HDF5's checksums). The result equals the
// uninterrupted build.
TEST_F(DatasetBuilder, ADamagedOrTruncatedPartIsRebuiltNotTrusted) {
  for (const bool truncate : {true, false}) {
    const fs::path dir = test::temp_dir(truncate ? "dataset_builder_part_cut" : "dataset_builder_part_flip");
    DatasetBuildOptions o = tiny_build_options(dir);
    o.stop_after_clips = 3;  // clips 0, 1 committed in character-0000.part
    build_dataset(o);
    const fs::path part = dir / "character-0000.part";
    std::string bytes = test::read_file_bytes(part);
    ASSERT_GT(bytes.size(), 4096u);
    if (truncate) {
      bytes.resize(bytes.size() / 2);
    } else {
      // A byte in the middle of the last committed clip's data, which is where most of the file's bytes are.
      bytes[bytes.size() * 3 / 4] = char(bytes[bytes.size() * 3 / 4] ^ 0x5a);
    }
    std::ofstream(part, std::ios::binary | std::ios::trunc) << bytes;
    o.stop_after_clips = -1;
    const DatasetBuildReport resumed = build_dataset(o);
    ASSERT_EQ(resumed.damaged.size(), 1u) << (truncate ? "truncated" : "flipped");
    EXPECT_NE(resumed.damaged[0].find("character-0000.part"), std::string::npos) << resumed.damaged[0];
    EXPECT_EQ(resumed.clips_skipped, 0);
    EXPECT_EQ(resumed.clips_built, 6);
    EXPECT_EQ(folder_bytes(dir), folder_bytes(*reference_)) << (truncate ? "truncated" : "flipped");
  }
}

TEST_F(DatasetBuilder, AManifestWithNothingBuiltUnderItIsReplaced) {
  const fs::path dir = test::temp_dir("dataset_builder_manifest_only");
  fs::create_directories(dir);
  fs::copy_file(*reference_ / "manifest.json", dir / "manifest.json");
  DatasetBuildOptions o = tiny_build_options(dir);
  o.seed = 12;
  const DatasetBuildReport report = build_dataset(o);
  EXPECT_EQ(report.characters_built, 2);
  EXPECT_NE(test::read_file_bytes(dir / "manifest.json").find("\"seed\": 12"), std::string::npos);
  // Now shards lie beside it: the original settings are refused.
  o.seed = 11;
  EXPECT_NE(error_of([&] { build_dataset(o); }).find("built with other settings (settings.seed: 11 here, 12 in the"),
            std::string::npos);
}

TEST_F(DatasetBuilder, ManifestReadsBackThePlan) {
  const BuildManifest manifest = read_build_manifest(reference_->string());
  ASSERT_EQ(manifest.characters.size(), 2u);
  EXPECT_EQ(manifest.characters[0].name, "character-0000");
  EXPECT_EQ(manifest.characters[1].name, "character-0001");
  // Two characters: one held out (held_out_set), with different seeds.
  EXPECT_NE(manifest.characters[0].split, manifest.characters[1].split);
  EXPECT_NE(manifest.characters[0].body_seed, manifest.characters[1].body_seed);
  EXPECT_EQ(manifest.clips_per_character, 3);
  EXPECT_EQ(manifest.frames_per_character, 30);
}

TEST_F(DatasetBuilder, DamagedManifestGivesOneLineErrors) {
  const fs::path dir = test::temp_dir("dataset_builder_bad_manifest");
  const std::string path = (dir / "manifest.json").string();
  const std::string head = R"({"format": "amt-dataset-build", "version": 1, )";
  const std::string character = R"("split": "train", "body_seed": 1, "apparel_seed": 2)";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"{", "not valid JSON"},
      {R"({"format": "amt-dataset", "version": 1})", "format: expected 'amt-dataset-build', found \"amt-dataset\""},
      {head + R"("clips": []})", "characters: expected an array"},
      {head + R"("characters": [{"name": "../x", )" + character + R"(}], "clips": []})",
       "characters.0.name: expected a character name without '/', found \"../x\""},
      {head + R"("characters": [{"name": "c", "split": "dev", "body_seed": 1, "apparel_seed": 2}], "clips": []})",
       "characters.0.split: expected train or test"},
      {head + R"("characters": [{"name": "c", )" + character + R"(}], "clips": [{"frames": -3}]})",
       "clips.0.frames: expected a frame count, found -3"},
  };
  for (const auto& [text, expected] : cases) {
    std::ofstream(path) << text;
    const std::string message = error_of([&] { read_build_manifest(dir.string()); });
    EXPECT_NE(message.find(path + ": " + expected), std::string::npos) << text << ": " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

TEST_F(DatasetBuilder, DamagedFinishedShardIsFoundAndRebuilt) {
  const fs::path dir = test::temp_dir("dataset_builder_damaged");
  fs::copy(*reference_, dir);
  const fs::path shard = dir / "character-0001.h5";
  // Flip one byte of the rest joints (stored uncompressed: their bytes are in the file as written).
  const MatrixX3f joints = DatasetReader(shard.string()).read_character("character-0001").skeleton.rest_joints;
  std::string bytes = bytes_of(shard);
  const size_t at = bytes.find(std::string(reinterpret_cast<const char*>(joints.data()), 12));
  ASSERT_NE(at, std::string::npos);
  bytes[at + 1] ^= 0x10;
  std::ofstream(shard, std::ios::binary | std::ios::trunc) << bytes;
  EXPECT_NE(error_of([&] { DatasetReader(shard.string()).verify(); }).find("rest_joints: damaged data"),
            std::string::npos);

  const DatasetBuildReport r = build_dataset(tiny_build_options(dir));
  ASSERT_EQ(r.damaged.size(), 1u);
  EXPECT_EQ(r.damaged[0].rfind(shard.string() + ": /characters/character-0001/rest_joints: damaged data", 0), 0u)
      << r.damaged[0];
  EXPECT_EQ(r.characters_skipped, 1);
  EXPECT_EQ(r.characters_built, 1);
  EXPECT_EQ(folder_bytes(dir), folder_bytes(*reference_));
  EXPECT_EQ(DatasetReader(shard.string()).verify(),
            DatasetReader((*reference_ / "character-0001.h5").string()).verify());
}

TEST_F(DatasetBuilder, BadInputGivesOneLineErrorsAndLeavesFinishedShardsIntact) {
  const fs::path dir = test::temp_dir("dataset_builder_bad");
  fs::copy(*reference_, dir);
  const auto before = folder_bytes(dir);
  const fs::path empty = test::temp_dir("dataset_builder_no_bvh");
  const fs::path broken = test::temp_dir("dataset_builder_broken_bvh");
  std::ofstream(broken / "broken.bvh") << "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n";
  struct Case {
    std::string what;
    std::function<void(DatasetBuildOptions&)> change;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {"empty motion folder", [&](DatasetBuildOptions& o) { o.motions = empty.string(); }, "has no .bvh file"},
      {"unreadable BVH", [&](DatasetBuildOptions& o) { o.motions = broken.string(); }, "broken.bvh"},
      {"zero vertices", [](DatasetBuildOptions& o) { o.vertices = 0; }, "--vertices: expected 1000 to"},
      {"bad shard",
       [](DatasetBuildOptions& o) {
         o.shard = {3, 2};
       },
       "--shard"},
      {"no characters", [](DatasetBuildOptions& o) { o.characters = 0; }, "--characters"},
  };
  for (const Case& c : cases) {
    DatasetBuildOptions o = tiny_build_options(dir);
    c.change(o);
    const std::string message = error_of([&] { build_dataset(o); });
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.what << ": " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << c.what;
    EXPECT_EQ(folder_bytes(dir), before) << c.what;
  }
}

// The command's default motions are found when it runs (app/repository.h), not at a path compiled in.
TEST(DatasetBuildCommand, DefaultMotionsAreFoundAboveTheProgramOrInTheCurrentFolder) {
  const fs::path elsewhere = fs::canonical(test::temp_dir("build_command_elsewhere"));
  const std::string in_elsewhere = "cd '" + elsewhere.string() + "' && ";
  // The checkout's program, run from another folder, finds the checkout's data/ (and models/).
  test::CommandResult help = test::run_command(in_elsewhere + "'" + AMT_BINARY + "' dataset build --help");
  EXPECT_EQ(help.status, 0) << help.err;
  EXPECT_NE(help.out.find("(here: " AMT_ASSET_DIR "/mocap/cmu)"), std::string::npos) << help.out;
  help = test::run_command(in_elsewhere + "'" + AMT_BINARY + "' animate --help");
  EXPECT_NE(help.out.find("(here: " + fs::path(AMT_ASSET_DIR).parent_path().string() + "/models/pretrained)"),
            std::string::npos)
      << help.out;

  // A copy of the program outside any checkout has no default: it says what to pass, and writes nothing.
  const fs::path program = fs::canonical(test::temp_dir("build_command_copy")) / "amt";
  fs::copy_file(AMT_BINARY, program);
  fs::permissions(program, fs::perms::owner_all);
  const test::CommandResult failed =
      test::run_command(in_elsewhere + "'" + program.string() + "' dataset build --out built --threads 1");
  EXPECT_EQ(failed.status, 1);
  EXPECT_EQ(failed.err, "amt: error: --motions: no default: data/mocap/cmu is neither above the amt program (" +
                            program.string() + ") nor in the current folder (" + elsewhere.string() +
                            "); pass --motions FOLDER (BVH files), or --motions \"\" for procedural motions only\n");
  EXPECT_FALSE(fs::exists(elsewhere / "built"));
  // Run from a folder that has data/mocap/cmu, the copy takes that one.
  fs::create_directories(elsewhere / "data" / "mocap" / "cmu");
  help = test::run_command(in_elsewhere + "'" + program.string() + "' dataset build --help");
  EXPECT_NE(help.out.find("(here: " + (elsewhere / "data" / "mocap" / "cmu").string() + ")"), std::string::npos)
      << help.out;
}

// PMX models beside procedural characters: planned after them, resumed like them, the same bytes in the end.
TEST(DatasetBuilderPmx, MixedWithProceduralCharactersResumesToTheSameBytes) {
  const fs::path root = test::temp_dir("dataset_builder_pmx");
  const std::string model = (root / "humanoid.pmx").string();
  write_pmx(test::pmx_humanoid(), model);
  DatasetBuildOptions o = tiny_build_options(root / "reference", 1);
  o.pmx = {model};
  const DatasetBuildReport reference = build_dataset(o);
  EXPECT_EQ(reference.characters_built, 2);
  EXPECT_EQ(names_of(folder_bytes(root / "reference")),
            (std::vector<std::string>{"character-0000.h5", "character-0000.json", "manifest.json", "pmx-0000.h5",
                                      "pmx-0000.json"}));

  o.out = (root / "resumed").string();
  o.stop_after_clips = 4;  // the procedural character's 3 clips, then the model's first clip, lost uncommitted
  EXPECT_TRUE(build_dataset(o).interrupted);
  EXPECT_FALSE(fs::exists(root / "resumed" / "pmx-0000.part"));
  o.stop_after_clips = -1;
  const DatasetBuildReport resumed = build_dataset(o);
  EXPECT_EQ(resumed.characters_skipped, 1);
  EXPECT_EQ(resumed.clips_built, 3);
  EXPECT_EQ(folder_bytes(root / "resumed"), folder_bytes(root / "reference"));
}

}  // namespace
}  // namespace amt
