// Tests of infer/runtime_benchmark_torch.h: the measurement behind `amt bench --suite runtime` and
// `amt eval --runtime` on small generated characters with a fresh model. Timings are never asserted;
// what is checked is what was measured (sizes, masks, one figure per thread count, the scratch file
// removed) and that bad options are refused.
#include "infer/runtime_benchmark_torch.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "data_tools/geometry/error.h"
#include "tests/test_support.h"
#include "tests/train/fresh_model.h"
#include "tests/train/micro_dataset.h"

namespace amt {
namespace {

TEST(RuntimeBenchmark, MeasuresTheGeneratedCharacterOnEachThreadCount) {
  test::use_one_thread();
  const auto dir = test::temp_dir("runtime_benchmark");
  const ModelBundle bundle = load_model_bundle(test::write_fresh_model(dir / "model"));
  RuntimeBenchmarkOptions o;
  o.vertices = 3000;
  o.threads = {1, 2};
  o.repeats = 2;
  o.scratch_dir = (dir / "scratch").string();
  std::filesystem::create_directories(o.scratch_dir);
  const RuntimeFigures r = measure_runtime(bundle, o, "dressed");
  EXPECT_EQ(r.label, "dressed");
  EXPECT_EQ(r.mask, "the dressed character");
  EXPECT_GT(r.vertices, 2000);
  EXPECT_LT(r.vertices, 5000);
  EXPECT_GT(r.faces, r.vertices);
  // The dressed character's mask is bound as given (about 30 % apparel).
  EXPECT_EQ(r.apparel_vertices, r.true_apparel_vertices);
  EXPECT_GT(r.true_apparel_vertices, r.vertices / 10);
  EXPECT_LT(r.true_apparel_vertices, r.vertices / 2);
  EXPECT_EQ(r.repeats, 2);
  ASSERT_EQ(r.per_thread.size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    const RuntimeThreadFigures& t = r.per_thread[k];
    EXPECT_EQ(t.threads, int(k) + 1);
    EXPECT_TRUE(std::isfinite(t.median_ms) && t.median_ms > 0) << t.median_ms;
    EXPECT_GE(t.p95_ms, t.median_ms);
    EXPECT_GT(t.apparel_ms, 0);
    EXPECT_GE(t.inside_before, t.inside_after);
    EXPECT_TRUE(std::isnan(t.reference_apparel_ms));  // not asked for
  }
  EXPECT_TRUE(std::isfinite(r.bind_seconds) && r.bind_seconds > 0);
  EXPECT_TRUE(std::filesystem::is_empty(o.scratch_dir));  // the scratch GLB is removed
  EXPECT_EQ(thread_count(), 1);                          // the caller's thread count, after measuring on 2

  o.open_parts = true;
  o.segmenter_mask = true;
  o.threads = {1};
  o.reference_apparel = true;
  const RuntimeFigures open = measure_runtime(bundle, o);
  EXPECT_EQ(open.mask, "the segmenter");
  EXPECT_NE(open.character.find(" open body parts"), std::string::npos) << open.character;
  EXPECT_GT(open.true_apparel_vertices, 0);
  ASSERT_EQ(open.per_thread.size(), 1u);
  EXPECT_TRUE(std::isnan(open.per_thread[0].reference_apparel_ms));  // the model is the global form itself
  // A local apparel module: the global form's network is timed beside it, on the same mask.
  const ModelBundle local =
      load_model_bundle(test::write_fresh_model(dir / "local", 7, canonical_joint_names(), /*local_apparel=*/true));
  const RuntimeFigures beside = measure_runtime(local, o);
  EXPECT_TRUE(std::isfinite(beside.per_thread[0].reference_apparel_ms) && beside.per_thread[0].reference_apparel_ms > 0)
      << beside.per_thread[0].reference_apparel_ms;

  o.repeats = 0;
  try {
    measure_runtime(bundle, o);
    FAIL() << "no repeats accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("at least one repeat"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace amt
