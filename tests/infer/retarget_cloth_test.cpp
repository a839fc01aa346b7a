// The `amt retarget-cloth` job on a tiny garment pair set: a dataset-clip source onto the other body of the
// pair (written as a dataset file and read back), an OBJ-sequence source, and the errors: different apparel
// connectivity naming both files, a source shorter than the target motion, a missing OBJ frame; --help.
#include "infer/retarget_cloth.h"

#include <gtest/gtest.h>

#include <iostream>

#include "data_tools/builder/garment_pairs.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/obj_io.h"
#include "tests/data_tools/builder/tiny_build.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

// One pair, one procedural clip of 6 frames, built once for the suite.
const std::string& pair_set() {
  static const std::string path = [] {
    const fs::path dir = test::temp_dir("retarget_cloth_pairs");
    GarmentPairOptions o;
    o.build = test::tiny_build_options(dir / "pairs.h5");
    o.build.procedural = 1;
    o.build.frames = 6;
    o.pairs = 1;
    build_garment_pairs(o);
    return o.build.out;
  }();
  return path;
}

std::string clip_of(const std::string& character) {
  const DatasetReader reader(pair_set());
  for (const std::string& clip : reader.clip_names())
    if (reader.clip_info(clip).character == character) return clip;
  return "";
}

RetargetClothOptions pair_options(const fs::path& out) {
  RetargetClothOptions o;
  o.source = pair_set() + ":" + clip_of("pair-00-a");
  o.target = pair_set() + ":pair-00-b";
  o.out = out.string();
  o.verbose = false;
  return o;
}

TEST(RetargetCloth, CarriesTheApparelOfOneBodyOntoTheOtherAndWritesADatasetFile) {
  const fs::path dir = test::temp_dir("retarget_cloth_h5");
  RetargetClothOptions o = pair_options(dir / "b.h5");
  o.target_motion.spec = pair_set() + ":" + clip_of("pair-00-b");  // the motion the pair set simulated b under
  const RetargetClothSummary s = retarget_cloth(o);
  EXPECT_EQ(s.frames, 6);
  EXPECT_GT(s.apparel_vertices, 0);
  EXPECT_LE(s.after.inside, s.before.inside);
  const DatasetReader written((dir / "b.h5").string());
  ASSERT_EQ(written.clip_names().size(), 1u);
  const MatrixX3f V = written.read_vertices(written.clip_names()[0], 0, 6);
  EXPECT_TRUE(V.allFinite());
  EXPECT_FALSE(fs::exists(dir / "b.h5.amt-tmp"));

  // Checked against the pair set's own simulation of the target body under the same motion: the retargeted
  // apparel lies near it, far nearer than the target's rest apparel (what a job that moved nothing would write),
  // and the body is the target's, posed.
  const DatasetReader pairs(pair_set());
  const CharacterData b = pairs.read_character("pair-00-b");
  const int N = b.mesh.num_vertices();
  ASSERT_EQ(V.rows(), 6 * N);
  const MatrixX3f truth = pairs.read_vertices(clip_of("pair-00-b"), 0, 6);
  double retargeted = 0, rest = 0, body = 0;
  int apparel = 0, bare = 0;
  for (int t = 0; t < 6; ++t) {
    for (int i = 0; i < N; ++i) {
      const Eigen::Index row = Eigen::Index(t) * N + i;
      if (b.apparel_mask[size_t(i)]) {
        retargeted += (V.row(row) - truth.row(row)).norm();
        rest += (b.mesh.V.row(i) - truth.row(row)).norm();
        ++apparel;
      } else {
        body += (V.row(row) - truth.row(row)).norm();
        ++bare;
      }
    }
  }
  ASSERT_GT(apparel, 0);
  retargeted /= apparel, rest /= apparel, body /= std::max(bare, 1);
  std::cout << "apparel " << 100 * retargeted << " cm from the target's own simulation (rest apparel: " << 100 * rest
            << " cm); body " << 100 * body << " cm\n";
  EXPECT_LT(retargeted, 0.5 * rest);
  EXPECT_LT(retargeted, 0.05);  // metres: within centimetres of the simulation
  EXPECT_LT(body, 1e-4);
}

TEST(RetargetCloth, ReadsAnObjSequenceAndNamesAMissingFrame) {
  const fs::path dir = test::temp_dir("retarget_cloth_obj");
  const DatasetReader reader(pair_set());
  const CharacterData a = reader.read_character("pair-00-a");
  const std::string clip = clip_of("pair-00-a");
  std::vector<MatrixX3f> frames;
  const MatrixX3f all = reader.read_vertices(clip, 0, 6);
  for (int t = 0; t < 6; ++t)
    frames.push_back(all.middleRows(Eigen::Index(t) * a.mesh.num_vertices(), a.mesh.num_vertices()));
  write_obj_sequence((dir / "source").string(), a.mesh.F, frames);
  RetargetClothOptions o = pair_options(dir / "b.glb");
  o.source = (dir / "source").string();
  o.source_character = pair_set() + ":pair-00-a";
  o.target_motion.spec = pair_set() + ":" + clip;
  EXPECT_EQ(retarget_cloth(o).frames, 6);
  fs::remove(dir / "source" / "frame_0002.obj");
  o.out = (dir / "c.glb").string();
  const std::string message = test::error_of([&] { retarget_cloth(o); });
  EXPECT_NE(message.find("frame_0002.obj: --source: missing OBJ frame 2"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(dir / "c.glb"));
}

TEST(RetargetCloth, DifferentConnectivityAndShortSourcesGiveClearErrors) {
  const fs::path dir = test::temp_dir("retarget_cloth_errors");
  // The target's apparel with one vertex fewer, in another file.
  CharacterData b = DatasetReader(pair_set()).read_character("pair-00-b");
  for (auto& m : b.apparel_mask)
    if (m) {
      m = 0;
      break;
    }
  const std::string other = (dir / "other.h5").string();
  {
    DatasetWriter writer(other, 30.0f, DatasetReader(pair_set()).joint_names());
    writer.add_character(b);
    writer.commit();
  }
  RetargetClothOptions o = pair_options(dir / "x.glb");
  o.target = other + ":pair-00-b";
  std::string message = test::error_of([&] { retarget_cloth(o); });
  EXPECT_NE(message.find(other + ":pair-00-b against " + pair_set() + ":pair-00-a: apparel connectivity differs"),
            std::string::npos)
      << message;
  // A target motion longer than the source: BVH walk of the test assets has more frames than 6.
  o = pair_options(dir / "x.glb");
  o.target_motion.spec = std::string(AMT_ASSET_DIR) + "/mocap/cmu/" + [] {
    for (const auto& e : fs::directory_iterator(std::string(AMT_ASSET_DIR) + "/mocap/cmu"))
      if (e.path().extension() == ".bvh") return e.path().filename().string();
    return std::string();
  }();
  message = test::error_of([&] { retarget_cloth(o); });
  EXPECT_NE(message.find(": --source: has 6 frames, the target motion"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(dir / "x.glb"));
}

TEST(RetargetCloth, HelpDocumentsTheCommand) {
  const test::CommandResult r = test::run_command(std::string(AMT_BINARY) + " retarget-cloth --help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("--target-motion"), std::string::npos);
  EXPECT_NE(r.out.find("detail vectors"), std::string::npos);
}

}  // namespace
}  // namespace amt
