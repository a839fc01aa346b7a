// `amt dataset build`, `check`, `info` and `preview` from the command line on the smallest dataset (one
// 1000-vertex character, two 4-frame procedural clips): what each prints and writes, bad inputs as one
// line naming the file or option with nothing written, and a --out that amt did not write refused and
// left untouched. (More of `info`, on a good, missing and damaged file and on folders:
// tests/data_tools/builder/dataset_info_test.cpp DatasetInfoCommand.* and DatasetFolderInfo.*; resuming and
// damaged shards: tests/data_tools/builder/dataset_builder_test.cpp.)
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/gltf_import.h"
#include "tests/app/amt_cli.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

TEST(DatasetBuildCommand, BuildsATinyDatasetThatInfoCheckAndPreviewRead) {
  const fs::path dir = test::temp_dir("dataset_build_tiny");
  const test::CommandResult built = test::expect_success(dir, test::tiny_build());
  EXPECT_EQ(built.out, "wrote data\n");
  EXPECT_NE(built.err.find("built 1 characters (0 already done), 2 clips (0 already done)"), std::string::npos)
      << built.err;
  for (const char* file : {"manifest.json", "character-0000.h5", "character-0000.json"})
    EXPECT_TRUE(fs::is_regular_file(dir / "data" / file)) << file;
  const std::string shard = (dir / "data" / "character-0000.h5").string();
  const DatasetReader reader(shard);
  ASSERT_EQ(reader.character_names().size(), 1u);
  ASSERT_EQ(reader.clip_names().size(), 2u);

  // info: the folder's totals, one held-out clip.
  const test::CommandResult info = test::expect_success(dir, {"dataset", "info", "data", "--threads", "1"});
  EXPECT_NE(info.out.find("totals: 1 character (train 1, test 0), 2 clips (train 1, test 1)"), std::string::npos)
      << info.out;
  EXPECT_NE(info.out.find("missing, damaged or not in the manifest: none"), std::string::npos) << info.out;

  // check: every gate passes on this simulation, the report is written into the folder.
  const test::CommandResult check = test::expect_success(dir, {"dataset", "check", "data", "--threads", "1"});
  for (const char* gate : {"PASS apparel lag", "PASS no NaN", "PASS no explosion", "PASS no jump", "PASS penetration"})
    EXPECT_NE(check.out.find(gate), std::string::npos) << gate << " not in: " << check.out;
  EXPECT_NE(check.out.find("wrote data/quality/report.md"), std::string::npos) << check.out;
  EXPECT_TRUE(fs::is_regular_file(dir / "data" / "quality" / "report.md"));

  // preview: 3 frames of the first clip as a GLB whose frames are the clip's vertices.
  const test::CommandResult preview = test::expect_success(
      dir, {"dataset", "preview", "data/character-0000.h5", "--out", "preview.glb", "--frames", "3", "--threads", "1"});
  EXPECT_EQ(preview.out, "wrote preview.glb (3 frames)\n");
  const GltfVertexAnimation frames = gltf_vertex_animation(read_gltf((dir / "preview.glb").string()), "", 30.0f);
  ASSERT_EQ(frames.frames.size(), 3u);
  const MatrixX3f first = reader.read_vertices(reader.clip_names()[0], 0, 1);
  EXPECT_LT((frames.frames[0] - first).cwiseAbs().maxCoeff(), 1e-5f);

  // artist-style: the character remade (coincident copies at its seams, more vertices) with its two clips, into a
  // new shard; onto its own input it is refused.
  const test::CommandResult remade = test::expect_success(
      dir, {"dataset", "artist-style", "data/character-0000.h5", "--out", "remade.h5", "--vertices", "0", "--quiet",
            "--threads", "1"});
  EXPECT_EQ(remade.out.rfind("wrote remade.h5: 1 characters remade artist-style (", 0), 0u) << remade.out;
  EXPECT_NE(remade.out.find("), 2 clips, "), std::string::npos) << remade.out;
  const DatasetReader again_remade((dir / "remade.h5").string());
  EXPECT_GT(again_remade.read_character("character-0000").mesh.num_vertices(),
            reader.read_character("character-0000").mesh.num_vertices());
  test::expect_one_line_error(
      test::run_amt(dir, {"dataset", "artist-style", "data/character-0000.h5", "--out", "data/character-0000.h5"}),
      {"data/character-0000.h5", "the output is the input"});

  // The same build again: everything already done, nothing rewritten.
  const std::string bytes = test::read_file_bytes(shard);
  const test::CommandResult again = test::expect_success(dir, test::tiny_build());
  EXPECT_NE(again.err.find("built 0 characters (1 already done), 0 clips (2 already done)"), std::string::npos)
      << again.err;
  EXPECT_EQ(test::read_file_bytes(shard), bytes);
}

TEST(DatasetBuildCommand, BadSettingsAndOutputsAreRefusedAndLeaveTheFolderUntouched) {
  const fs::path dir = test::temp_dir("dataset_build_bad");
  test::users_folder(dir, "mine");
  std::ofstream(dir / "notes.txt") << "the user's notes\n";
  const auto build = [](const std::map<std::string, std::string>& changed) { return test::tiny_build(changed); };
  test::expect_errors_writing_nothing(
      dir, {{build({{"--shard", "2/1"}}), {"--shard: expected i/n", "found '2/1'"}},
            {build({{"--vertices", "10"}}), {"--vertices: expected 1000 to", "found 10"}},
            {build({{"--motions", "missing"}}), {"missing: --motions: no such folder"}},
            {build({{"--procedural", "0"}}), {"expected motions: a --motions folder or --procedural > 0"}},
            {build({{"--out", "notes.txt"}}), {"notes.txt: --out: expected a folder"}},
            {build({{"--out", "mine"}}),
             {"mine: --out: expected an empty folder or one amt dataset build wrote (manifest.json), found "
              "notes.txt without a manifest"}}});
}

TEST(DatasetCheckCommand, AMissingFolderAFileAndAFolderWithoutShardsAreOneLineErrors) {
  const fs::path dir = test::temp_dir("dataset_check_bad");
  test::users_folder(dir, "mine");
  std::ofstream(dir / "data.h5") << "a file, not a folder\n";
  test::expect_errors_writing_nothing(
      dir, {{{"dataset", "check", "missing"}, {"missing: no such folder"}},
            {{"dataset", "check", "data.h5"}, {"data.h5: expected a dataset folder", "found a regular file"}},
            {{"dataset", "check", "mine"}, {"mine: no shard (expected *.h5 files written by amt dataset build)"}}});
}

// The shards of two build processes (--shard 0/2 and 1/2) into one folder: with one of them run, check names the
// missing character and the process that makes it, and fails before the gates; with both, the folder is complete; a
// copied shard is a duplicate.
TEST(DatasetCheckCommand, ReportsTheShardsMissingFromTheUnionOfBuildProcesses) {
  const fs::path dir = test::temp_dir("dataset_check_union");
  test::expect_success(dir, test::tiny_build({{"--characters", "2"}, {"--shard", "0/2"}}));
  const test::CommandResult half = test::run_amt(dir, {"dataset", "check", "data", "--threads", "1"});
  EXPECT_EQ(half.status, 1) << half.err;
  EXPECT_EQ(half.out.rfind("completeness: 2 characters in manifest.json, 1 shard whole, 1 missing, 0 damaged, 0 "
                           "duplicate, 0 not in manifest\n  missing: data/character-0001.h5: missing (character 1 of 2, "
                           "made by the build process --shard i/n with i = 1 mod n; rerun that process",
                           0),
            0u)
      << half.out;
  EXPECT_EQ(half.out.find("PASS"), std::string::npos) << half.out;
  EXPECT_EQ(half.err, "amt: error: data: incomplete: 1 of 2 shards missing, damaged, duplicated or not in the manifest "
                      "(listed above); the gates run on a complete dataset\n");
  EXPECT_FALSE(fs::exists(dir / "data" / "quality"));

  test::expect_success(dir, test::tiny_build({{"--characters", "2"}, {"--shard", "1/2"}}));
  fs::copy_file(dir / "data" / "character-0000.h5", dir / "data" / "copy.h5");
  const test::CommandResult copied = test::run_amt(dir, {"dataset", "check", "data", "--threads", "1"});
  EXPECT_EQ(copied.status, 1);
  EXPECT_NE(copied.out.find("  duplicate: data/copy.h5: holds character-0000 again, whose shard is character-0000.h5"),
            std::string::npos)
      << copied.out;
  fs::remove(dir / "data" / "copy.h5");
  const test::CommandResult whole = test::expect_success(dir, {"dataset", "check", "data", "--threads", "1"});
  EXPECT_EQ(whole.out.rfind("completeness: 2 characters in manifest.json, 2 shards whole: complete", 0), 0u)
      << whole.out;
}

TEST(DatasetInfoCommand, AFolderThatHoldsNoDatasetIsAOneLineError) {
  const fs::path dir = test::temp_dir("dataset_info_bad");
  test::users_folder(dir, "mine");
  test::expect_errors_writing_nothing(dir,
                                      {{{"dataset", "info", "mine"}, {"mine: no manifest.json and no *.h5 shard"}}});
}

TEST(DatasetPreviewCommand, BadInputsAreOneLineErrorsAndAFolderIsNeverReplaced) {
  const fs::path dir = test::temp_dir("dataset_preview_bad");
  const std::string data = test::write_example_dataset(dir);
  std::ofstream(dir / "text.h5") << "not a dataset\n";
  fs::create_directories(dir / "folder.h5");
  test::users_folder(dir, "album.glb");
  const auto preview = [](const std::string& file, const std::string& out, const std::vector<std::string>& extra = {}) {
    std::vector<std::string> args = {"dataset", "preview", file, "--out", out, "--threads", "1"};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  };
  test::expect_errors_writing_nothing(
      dir, {{preview("missing.h5", "p.glb"), {"missing.h5: no such file"}},
            {preview("folder.h5", "p.glb"), {"folder.h5: ", "found a folder"}},
            {preview("text.h5", "p.glb"), {"text.h5: expected an HDF5 file", "not HDF5"}},
            {preview(data, "p.glb", {"--clip", "dance"}), {"ex.h5: /clips/dance: missing"}},
            {preview(data, "p.glb", {"--first-frame", "50"}), {"ex.h5: /clips/capsules_walk: first frame"}},
            {preview(data, "album.glb"),
             {"album.glb: output: expected a regular file or no file to replace, found a folder"}},
            {preview(data, "p.txt"), {"p.txt: --out: expected a .glb or .gltf file, found extension '.txt'"}},
            {preview(data, "p"), {"p: --out: expected a .glb or .gltf file, found no extension"}}});
}

}  // namespace
}  // namespace amt
