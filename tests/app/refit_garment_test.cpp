// `amt refit-garment` from the command line: the builder's flared skirt refit from one small generated body
// onto another, written as a rigged GLB of the dressed target with a picture; bad inputs as one line naming
// the file or option and what was expected, with nothing written. (The refit itself, its intersection
// checks and its figures: tests/refit/garment_refit_test.cpp.)
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/obj_io.h"
#include "tests/app/amt_cli.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

// `amt refit-garment` of `garment` from generated body 3 onto generated body 11 (about 2000 vertices each)
// into `out`, plus `extra` (--quiet: only the one line of an error on stderr).
std::vector<std::string> refit_args(const std::string& garment, const std::string& out,
                                    const std::vector<std::string>& extra = {}) {
  std::vector<std::string> args = {
      "refit-garment", "--garment", garment,     "--source", "generated:3:2000", "--target", "generated:11:2000",
      "--out",         out,         "--threads", "1"};
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

TEST(RefitGarmentCommand, DressesAGeneratedBodyWithTheBuildersSkirtAsARiggedGlb) {
  const fs::path dir = test::temp_dir("refit_garment_glb");
  const test::CommandResult r =
      test::expect_success(dir, refit_args("generated:flared_skirt", "dressed.glb", {"--picture", "refit.png"}));
  // Progress per outer iteration and fit step, then the summary with its figures.
  EXPECT_NE(r.err.find("inflation 0: energy "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(", min distance "), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("surface-shape distortion"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("fit distance"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("wrote dressed.glb"), std::string::npos) << r.out;
  EXPECT_GT(fs::file_size(dir / "refit.png"), 1000u);
  EXPECT_FALSE(fs::exists(dir / "dressed.glb.amt-tmp"));
  // The dressed target: the body's vertices, then the skirt's, skinned on the 22 canonical joints.
  const GltfCharacter dressed = gltf_character(read_gltf((dir / "dressed.glb").string()));
  EXPECT_EQ(dressed.skeleton.num_joints(), 22);
  EXPECT_GT(dressed.mesh.num_vertices(), 2500);
  EXPECT_EQ(dressed.weights.num_vertices(), dressed.mesh.num_vertices());
  EXPECT_TRUE(dressed.mesh.V.allFinite());
}

TEST(RefitGarmentCommand, BadInputsAreOneLineErrorsNamingTheFileAndWriteNothing) {
  const fs::path dir = test::temp_dir("refit_garment_bad_inputs");
  const auto quiet = [](const std::string& garment, const std::string& out) {
    return refit_args(garment, out, {"--quiet"});
  };
  // A sheet through every generated body at 60 cm; a face on a line; a NaN; a folder; a 2-joint skeleton.
  std::ofstream(dir / "sheet.obj") << "v -1 0.6 -1\nv 1 0.6 -1\nv 1 0.6 1\nv -1 0.6 1\nf 1 2 3\nf 1 3 4\n";
  std::ofstream(dir / "flat.obj") << "v 0 0.6 0\nv 0.1 0.6 0\nv 0.2 0.6 0\nv 0 0.7 0\nf 1 2 3\nf 2 1 4\n";
  std::ofstream(dir / "nan.obj") << "v 0 0.6 0\nv nan 0.6 0\nv 0 0.7 0\nf 1 2 3\n";
  fs::create_directories(dir / "folder.obj");
  std::ofstream(dir / "stick.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  std::ofstream(dir / "stick.joints.json")
      << R"({"joints":[{"name":"a","parent":null,"position":[0,0,0]},{"name":"b","parent":"a","position":[0,1,0]}]})";
  std::vector<std::string> onto_stick = quiet("sheet.obj", "out.glb");
  onto_stick[6] = "stick.obj";  // --target
  std::vector<std::string> from_stick = quiet("generated:flared_skirt", "out.glb");
  from_stick[4] = "stick.obj";  // --source
  test::expect_errors_writing_nothing(
      dir, {{quiet("sheet.obj", "out.glb"),
             {"--garment sheet.obj on --source generated:3:2000: garment face 0 crosses the source avatar's face",
              "the garment must start intersection-free with it"}},
            {quiet("flat.obj", "out.glb"),
             {"--garment flat.obj: face 0 (vertices 0, 1, 2) is degenerate, expected a triangle of non-zero area"}},
            {quiet("nan.obj", "out.glb"), {"nan.obj:2: v: expected 3 finite numbers, found 'nan'"}},
            {quiet("folder.obj", "out.glb"), {"folder.obj: ", "expected a garment mesh", "found a folder"}},
            {onto_stick, {"stick.obj: skeleton: could not match canonical joints", "--target-joint-map FILE"}},
            {from_stick, {"stick.obj: skeleton: could not match canonical joints", "--source-joint-map FILE"}},
            {quiet("generated:skirt", "out.glb"),
             {"--garment generated:skirt: kind 'skirt', expected one of ", "flared_skirt"}},
            {quiet("sheet.obj", "out.ply"), {"--out out.ply: expected an .obj", "found the extension '.ply'"}},
            {quiet("sheet.obj", "folder.obj"), {"folder.obj: ", "found a folder"}},
            // The output onto the run's own garment: refused before any work, the garment kept.
            {quiet("sheet.obj", "sheet.obj"),
             {"sheet.obj: --out: expected a new file, found the run's own input sheet.obj (--garment); amt never "
              "replaces an input"}}});
}

}  // namespace
}  // namespace amt
