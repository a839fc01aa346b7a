// `amt animate` from the command line on a tiny character (the capsules of `amt dataset example`) with the
// shipped model: the outputs asked for (GLB, OBJ folder), bad inputs as one line naming the file and what
// was expected with nothing written, and outputs that would replace what amt did not write refused with
// everything left as it was. (Signals, a full disk and the shipped model on a generated character:
// tests/infer/animate_cli_torch_test.cpp; the output rules in process: tests/infer/frame_writer_test.cpp.)
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "data_tools/builder/apparel.h"
#include "data_tools/builder/body_generator.h"
#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/obj_io.h"
#include "data_tools/geometry/shapes.h"
#include "data_tools/geometry/skeleton.h"
#include "tests/app/amt_cli.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

// `amt animate` of the example's capsules with its walk, 3 frames, into `out`, plus `extra`.
std::vector<std::string> animate(const std::string& out, const std::vector<std::string>& extra = {}) {
  std::vector<std::string> args = {"animate",
                                   "--character",
                                   "ex.h5:capsules",
                                   "--motion",
                                   "ex.h5:capsules_walk",
                                   "--model",
                                   test::shipped_model(),
                                   "--frames",
                                   "3",
                                   "--threads",
                                   "1",
                                   "--quiet"};
  if (!out.empty()) args.insert(args.end(), {"--out", out});
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

TEST(AnimateCommand, WritesTheFramesAskedForAsAGlbAndAnObjFolder) {
  const fs::path dir = test::temp_dir("animate_outputs");
  test::write_example_dataset(dir);
  // The vertex cache: every frame as computed, so the OBJ frames below are the same to rounding.
  const test::CommandResult glb = test::expect_success(dir, animate("walk.glb", {"--vertex-cache"}));
  EXPECT_EQ(glb.out.rfind("wrote walk.glb, ", 0), 0u) << glb.out;
  EXPECT_NE(glb.out.find("frames: 3 at 30 fps"), std::string::npos) << glb.out;
  EXPECT_EQ(glb.err, "");  // --quiet
  const GltfVertexAnimation frames = gltf_vertex_animation(read_gltf((dir / "walk.glb").string()), "", 30.0f);
  ASSERT_EQ(frames.frames.size(), 3u);
  for (const MatrixX3f& V : frames.frames) {
    EXPECT_TRUE(V.allFinite());
    EXPECT_LT(V.cwiseAbs().maxCoeff(), 3.0f);  // a capsule character of under 2 m near the origin
  }
  EXPECT_TRUE(fs::is_regular_file(dir / "walk.bind"));  // the bind cache beside the output

  const test::CommandResult obj = test::expect_success(dir, animate("frames", {"--bind", "none"}));
  EXPECT_EQ(obj.out.rfind("wrote frames", 0), 0u) << obj.out;
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(dir / "frames")) files.push_back(e.path().filename().string());
  std::sort(files.begin(), files.end());
  EXPECT_EQ(files, (std::vector<std::string>{".amt-output", "frame_0000.obj", "frame_0001.obj", "frame_0002.obj"}));
  const TriMesh last = read_obj((dir / "frames" / "frame_0002.obj").string());
  ASSERT_EQ(last.num_vertices(), frames.frames[2].rows());
  EXPECT_LT((last.V - frames.frames[2]).cwiseAbs().maxCoeff(), 1e-5f);  // the same model, the same frame
  // Again to the same folder: amt's own OBJ folder is replaced.
  test::expect_success(dir, animate("frames", {"--bind", "none"}));
  EXPECT_FALSE(fs::exists(dir / "frames.amt-tmp"));
}

TEST(AnimateCommand, ApparelMaskFromTheRigTheSegmenterOrAFile) {
  // A generated character's rig (its simulated apparel bones) against the segmenter and a file mask; the
  // run says which it used and animates as many apparel vertices as that mask has.
  const fs::path dir = test::temp_dir("animate_masks");
  test::write_example_dataset(dir);
  const DressedCharacter dressed = dress_character(generate_body(sample_body_params(5), int(2000 * 0.7)), 5);
  const long rig = std::count(dressed.apparel_mask.begin(), dressed.apparel_mask.end(), uint8_t(1));
  ASSERT_GT(rig, 0);
  const auto generated = [](const std::string& out, const std::string& mask) {
    std::vector<std::string> args = animate(out, {"--apparel-mask", mask});
    *(std::find(args.begin(), args.end(), "--character") + 1) = "generated:5:2000";
    return args;
  };
  const test::CommandResult from_rig = test::expect_success(dir, generated("rig.glb", "rig"));
  EXPECT_NE(from_rig.out.find(", " + std::to_string(rig) + " apparel ("), std::string::npos) << from_rig.out;
  EXPECT_NE(from_rig.out.find("mask from the rig: the dressed character's simulated apparel bones)"), std::string::npos)
      << from_rig.out;
  const test::CommandResult from_model = test::expect_success(dir, generated("model.glb", "model"));
  EXPECT_NE(from_model.out.find("mask from the segmenter)"), std::string::npos) << from_model.out;
  // auto (the default) takes the rig when the character has one, and says so; the linked topology is reported.
  const test::CommandResult from_auto = test::expect_success(dir, generated("auto.glb", "auto"));
  EXPECT_NE(from_auto.out.find(", " + std::to_string(rig) + " apparel ("), std::string::npos) << from_auto.out;
  EXPECT_NE(from_auto.out.find("mask from the rig: the dressed character's simulated apparel bones (--apparel-mask "
                               "auto: the character has a rig))"),
            std::string::npos)
      << from_auto.out;
  EXPECT_NE(from_auto.out.find("topology: "), std::string::npos) << from_auto.out;
  {
    std::ofstream mask(dir / "first.txt");
    for (size_t i = 0; i < dressed.mesh.V.rows(); ++i) mask << (i < 5 ? "1 " : "0 ");
  }
  const test::CommandResult from_file = test::expect_success(dir, generated("file.glb", "first.txt"));
  EXPECT_NE(from_file.out.find(", 5 apparel ("), std::string::npos) << from_file.out;
  EXPECT_NE(from_file.out.find("mask from the file first.txt)"), std::string::npos) << from_file.out;
}

TEST(AnimateCommand, BadInputsAreOneLineErrorsNamingTheFileAndWriteNothing) {
  const fs::path dir = test::temp_dir("animate_bad_inputs");
  test::write_example_dataset(dir);
  fs::create_directories(dir / "folder.bvh");
  std::ofstream(dir / "truncated.bvh") << "HIERARCHY\nROOT hips\n{\n  OFFSET 0 0\n";
  std::ofstream(dir / "mask.json") << "[1, 0\n";
  const Skeleton skeleton = canonical_skeleton();  // an OBJ character: no rig that names apparel
  write_obj((dir / "capsules.obj").string(), capsule_character(skeleton.rest_joints, skeleton.parents, 600));
  write_joints_json(joints_sidecar_path((dir / "capsules.obj").string()), skeleton);
  const auto with = [](std::vector<std::string> args, const std::string& option, const std::string& value) {
    for (size_t k = 0; k + 1 < args.size(); ++k) {
      if (args[k] == option) args[k + 1] = value;
    }
    return args;
  };
  const std::vector<test::ErrorCase> cases = {
      {with(animate("out.glb"), "--character", "missing.obj"), {"missing.obj: character: expected a file, found none"}},
      {with(animate("out.glb"), "--motion", "folder.bvh"), {"folder.bvh: ", "found a folder"}},
      {with(animate("out.glb"), "--motion", "truncated.bvh"),
       {"truncated.bvh:4: OFFSET of joint 'hips': expected 3 numbers", "found end of file"}},
      {with(animate("out.glb"), "--character", "ex.h5:nobody"), {"ex.h5: /characters/nobody: expected a character"}},
      {animate("out.glb", {"--apparel-mask", "mask.json"}), {"mask.json: apparel mask: expected a JSON array of 0/1"}},
      {with(animate("out.glb", {"--apparel-mask", "rig"}), "--character", "capsules.obj"),
       {"capsules.obj: --apparel-mask rig: the character's rig names no apparel"}},
      {with(animate("out.glb"), "--model", (dir / "folder.bvh").string()),
       {"folder.bvh/segmenter.ckpt: no such checkpoint"}}};
  test::expect_errors_writing_nothing(dir, cases);  // no output, no bind cache or report, no temporary
}

TEST(AnimateCommand, RefusesOutputsThatWouldReplaceWhatAmtDidNotWriteAndLeavesThemUntouched) {
  const fs::path dir = test::temp_dir("animate_out_safety");
  test::write_example_dataset(dir);
  test::users_folder(dir, "mine");
  test::users_folder(dir, "album.glb");
  std::ofstream(dir / "notes.txt") << "the user's notes\n";
  // An OBJ folder onto a user's folder, onto a regular file, onto the current folder; a GLB onto a folder.
  test::expect_errors_writing_nothing(
      dir,
      {{animate("mine"),
        {"mine: --out: expected no file there or an OBJ folder amt wrote (with .amt-output), found a folder amt "
         "did not write"}},
       {animate("notes.txt"), {"notes.txt: --out: ", "found a regular file"}},
       {animate("."), {".: --out: expected a new folder for the OBJ files, found the name of the current folder"}},
       {animate("album.glb"), {"album.glb: output: expected a regular file or no file to replace, found a folder"}},
       {animate(""), {"--out: expected an output (or --html DIR), found none"}}});
}

TEST(AnimateCommand, AnOutputThatIsOneOfTheRunsInputsIsRefusedAndTheInputKept) {
  const fs::path dir = test::temp_dir("animate_onto_input");
  test::write_example_dataset(dir);
  std::ofstream(dir / "map.json") << "{}\n";
  std::ofstream(dir / "mask.txt") << "0\n";
  fs::create_symlink("ex.h5", dir / "link.h5");
  const std::string onto = "amt never replaces an input: choose another name";
  test::expect_errors_writing_nothing(
      dir,
      {// --out onto the character's shard, also spelled through a link and "./"; the bind cache onto it; the
       // picture onto the joint map; the bind cache onto the mask file.
       {animate("ex.h5"), {"ex.h5: --out: expected a new file, found the run's own input ex.h5 (--character); ", onto}},
       {animate("link.h5"), {"link.h5: --out: expected a new file, found the run's own input ex.h5 (--character)"}},
       {animate("./ex.h5"), {"./ex.h5: --out: expected a new file, found the run's own input ex.h5"}},
       {animate("x.glb", {"--bind", "ex.h5"}), {"ex.h5: --bind: expected a new file, found the run's own input ex.h5"}},
       {animate("x.glb", {"--motion-joint-map", "map.json", "--picture", "map.json"}),
        {"map.json: --picture: expected a new file, found the run's own input map.json (--motion-joint-map)"}},
       {animate("x.glb", {"--apparel-mask", "mask.txt", "--bind", "mask.txt"}),
        {"mask.txt: --bind: expected a new file, found the run's own input mask.txt (--apparel-mask)"}},
       // Two outputs onto one file.
       {animate("x.glb", {"--picture", "x.glb"}),
        {"x.glb: --picture: expected a file of its own, found the run's --out output"}}});
}

}  // namespace
}  // namespace amt
