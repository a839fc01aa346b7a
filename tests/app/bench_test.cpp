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

}  // namespace
}  // namespace amt
