// `amt bench` in its smallest setting: the figures of each suite asked for are printed and the run
// succeeds (the figures themselves are not asserted: benchmarks never fail on timing); an unknown suite
// is refused.
#include <gtest/gtest.h>

#include <string>

#include "tests/app/amt_cli.h"

namespace amt {
namespace {

TEST(BenchCommand, TinyRunsPrintTheFiguresOfEachSuite) {
  const auto dir = test::temp_dir("bench");
  const test::CommandResult r = test::expect_success(
      dir, {"bench", "--suite", "lbs", "geodesic", "--vertices", "100", "--repeats", "1", "--threads", "1"});
  EXPECT_EQ(r.out.rfind("amt bench: 1 threads\n", 0), 0u) << r.out;
  EXPECT_NE(r.out.find("\nlbs "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(" vertices, 4 influences: median "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\ngeodesic "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\npeak resident memory: "), std::string::npos) << r.out;
  EXPECT_EQ(test::line_count(r.out), 4u) << r.out;
  EXPECT_EQ(r.err, "");
  // The skinning suite (the training run that the skinning predictor's unit test checks, timed here).
  const test::CommandResult skinning = test::expect_success(dir, {"bench", "--suite", "skinning", "--repeats", "1"});
  EXPECT_NE(skinning.out.find("\nskinning  overfit of f_s on a 22-vertex bar through LBS, 500 AdamW steps"),
            std::string::npos)
      << skinning.out;
  test::expect_one_line_error(test::run_amt(dir, {"bench", "--suite", "nope"}),
                              {"--suite: nope not in {lbs,geodesic,runtime,cloth,skinning,segmenter}"}, 2);
  test::expect_one_line_error(test::run_amt(dir, {"bench", "--suite", "segmenter"}),
                              {"bench --suite segmenter: --data: expected dataset shards or folders, found none"});
  EXPECT_TRUE(test::snapshot(dir).empty());  // a benchmark writes nothing where it runs
}

// The runtime, cloth and segmenter suites on tiny inputs: each prints its figures, finite and in range.
TEST(BenchCommand, TinyRunsOfTheRuntimeClothAndSegmenterSuites) {
  const auto dir = test::temp_dir("bench_suites");
  const test::CommandResult runtime = test::expect_success(
      dir, {"bench", "--suite", "runtime", "--runtime-sizes", "2000", "--runtime-threads", "1", "--repeats", "2"});
  EXPECT_NE(runtime.out.find("runtime   "), std::string::npos) << runtime.out;
  const size_t frame = runtime.out.find(" thread: per frame median ");
  ASSERT_NE(frame, std::string::npos) << runtime.out;
  const double median_ms = std::stod(runtime.out.substr(frame + std::string(" thread: per frame median ").size()));
  EXPECT_GT(median_ms, 0.0);
  EXPECT_LT(median_ms, 10000.0);
  EXPECT_EQ(runtime.out.find("nan"), std::string::npos) << runtime.out;

  const test::CommandResult cloth =
      test::expect_success(dir, {"bench", "--suite", "cloth", "--cloth-vertices", "1500", "--repeats", "3"});
  EXPECT_NE(cloth.out.find("retargeting steps 3-6, 3.1, relaxation median "), std::string::npos) << cloth.out;
  EXPECT_NE(cloth.out.find("retargeting with push-out (3.2) median "), std::string::npos) << cloth.out;
  EXPECT_NE(cloth.out.find("cloth     registration of both sides: median "), std::string::npos) << cloth.out;
  EXPECT_EQ(cloth.out.find("nan"), std::string::npos) << cloth.out;

  const auto data = test::temp_dir("bench_suites_data");
  const std::string folder = (data / test::build_tiny_dataset(data)).string();
  const test::CommandResult segmenter =
      test::expect_success(dir, {"bench", "--suite", "segmenter", "--data", folder, "--split", "train"});
  EXPECT_NE(segmenter.out.find("segmenter "), std::string::npos) << segmenter.out;
  EXPECT_NE(segmenter.out.find("vertices; open parts"), std::string::npos) << segmenter.out;
  EXPECT_TRUE(test::snapshot(dir).empty());
  // An artist's model (Godette's VRM springs, written as a dataset file) is scored as built, not remade of open parts.
  const std::string godette = (data / "godette.h5").string();
  test::expect_success(dir, {"animate", "--character", std::string(AMT_ASSET_DIR) + "/characters/Godette.vrm",
                             "--motion", std::string(AMT_ASSET_DIR) + "/mocap/cmu/05_01.bvh", "--apparel",
                             "spring-bones", "--frames", "2", "--out", godette});
  const test::CommandResult artist =
      test::expect_success(dir, {"bench", "--suite", "segmenter", "--data", godette, "--split", "test"});
  EXPECT_NE(artist.out.find("segmenter Godette            8067 vertices; open parts      -:  as built IoU "),
            std::string::npos)
      << artist.out;
  EXPECT_NE(artist.out.find("not laid out as the builder's characters: scored as built only;"), std::string::npos)
      << artist.out;
  EXPECT_EQ(artist.out.find("bare body"), std::string::npos) << artist.out;
}

}  // namespace
}  // namespace amt
