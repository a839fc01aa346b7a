// `amt eval` from the command line on the smallest built dataset: a predictions file and the shipped model
// scored into a report folder, bad inputs as one line naming the file, and an --out that amt did not write
// refused and left untouched. (The scores' arithmetic: tests/eval/evaluate_torch_test.cpp.)
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "tests/app/amt_cli.h"
#include "tests/predictions_file.h"

namespace amt {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

Json read_json(const fs::path& path) {
  return Json::parse(test::read_file_bytes(path));
}

// The row of metrics.json for `method`, or null.
Json row_of(const Json& metrics, const std::string& method) {
  for (const Json& row : metrics.at("rows"))
    if (row.at("method") == method) return row;
  return Json();
}

TEST(EvalCommand, ScoresAPredictionsFileAndTheShippedModelIntoAReportFolder) {
  const fs::path dir = test::temp_dir("eval_scores");
  const std::string data = test::build_tiny_dataset(dir);
  fs::create_directories(dir / "report");  // an empty folder is taken
  // A copy of the ground truth marked as predictions: zero on the held-out clip.
  test::copy_as_predictions((dir / data / "character-0000.h5").string(), (dir / "predicted.h5").string());
  const test::CommandResult truth =
      test::expect_success(dir, {"eval", "--data", data, "--predictions", "predicted.h5", "--out", "report",
                                 "--no-plots", "--no-penetration", "--quiet", "--threads", "1"});
  EXPECT_NE(truth.out.find("held-out clips, file, Predictions file: PMD 0 cm, PMD_a 0 cm, PMD_b 0 cm, ELS 1,"),
            std::string::npos)
      << truth.out;
  EXPECT_NE(truth.out.find("wrote report/report.md, report/metrics.json"), std::string::npos) << truth.out;
  EXPECT_EQ(truth.err, "");
  EXPECT_TRUE(fs::is_regular_file(dir / "report" / "report.md"));
  const Json scored = read_json(dir / "report" / "metrics.json");
  EXPECT_EQ(scored.at("format"), "amt-eval");
  EXPECT_EQ(row_of(scored, "predictions").at("pmd_cm"), 0.0);
  // The unmarked shard itself only when the user says a ground-truth file is meant.
  const test::CommandResult meant = test::expect_success(
      dir, {"eval", "--data", data, "--predictions", data + "/character-0000.h5", "--ground-truth-as-predictions",
            "--out", "report", "--no-plots", "--no-penetration", "--quiet", "--threads", "1"});
  EXPECT_NE(meant.out.find("held-out clips, file, Predictions file: PMD 0 cm,"), std::string::npos) << meant.out;

  // The shipped model into the same folder (amt's report, replaced): the skinning baseline is exact on the
  // body (the ground truth skins it with the same weights), the full model finite.
  const test::CommandResult model = test::expect_success(
      dir, {"eval", "--data", data, "--model", test::shipped_model(), "--methods", "skinning_baseline", "full",
            "--protocol", "rollout", "--out", "report", "--no-plots", "--no-penetration", "--quiet", "--threads", "1"});
  EXPECT_NE(model.out.find("held-out clips, rollout, Skinning baseline"), std::string::npos) << model.out;
  EXPECT_NE(model.out.find("held-out clips, rollout, Full model: PMD "), std::string::npos) << model.out;
  const Json metrics = read_json(dir / "report" / "metrics.json");
  EXPECT_TRUE(row_of(metrics, "predictions").is_null());  // replaced, not merged
  const Json baseline = row_of(metrics, "skinning_baseline"), full = row_of(metrics, "full");
  ASSERT_FALSE(baseline.is_null()) << metrics.dump();
  ASSERT_FALSE(full.is_null()) << metrics.dump();
  EXPECT_LT(baseline.at("pmd_b_cm").get<double>(), 1e-3);
  EXPECT_GT(baseline.at("pmd_a_cm").get<double>(), 0.1);  // the simulated apparel is not skinning
  for (const char* key : {"pmd_cm", "pmd_a_cm", "pmd_b_cm", "els"}) {
    EXPECT_TRUE(full.at(key).is_number() && std::isfinite(full.at(key).get<double>())) << key << ": " << full.dump();
  }
  EXPECT_GT(full.at("frames").get<int>(), 0);
}

TEST(EvalCommand, BadInputsAreOneLineErrorsAndWriteNoReport) {
  const fs::path dir = test::temp_dir("eval_bad_inputs");
  test::write_example_dataset(dir);  // one train character and clip: nothing held out
  std::ofstream(dir / "text.h5") << "not a dataset\n";
  fs::create_directories(dir / "empty");
  const auto eval = [](std::vector<std::string> args) {
    args.insert(args.begin(), "eval");
    args.insert(args.end(), {"--out", "report", "--no-plots", "--quiet", "--threads", "1"});
    return args;
  };
  const std::string model = test::shipped_model();
  const std::vector<test::ErrorCase> cases = {
      {eval({"--data", "missing.h5", "--model", model}), {"missing.h5: no such file or folder"}},
      {eval({"--data", "empty", "--model", model}), {"empty: no shards (expected *.h5 dataset files)"}},
      {eval({"--data", "text.h5", "--model", model}),
       {"text.h5: expected an HDF5 file", "found a file that is not HDF5"}},
      {eval({"--data", "ex.h5", "--model", model}), {"ex.h5: no held-out clips"}},
      {eval({"--data", "ex.h5", "--predictions", "missing.h5"}), {"missing.h5: no such predictions file"}},
      {eval({"--data", "ex.h5", "--predictions", "ex.h5"}),
       {"ex.h5: attribute 'predictions': missing: the file holds ground truth, which would score as perfect"}},
      {eval({"--data", "ex.h5", "--predictions", "ex.h5", "--runtime"}),
       {"--runtime: expected a model to time, found --predictions"}},
      {eval({"--data", "ex.h5", "--model", model, "--methods", "magic"}),
       {"eval: method: expected one of", "found 'magic'"}}};
  test::expect_errors_writing_nothing(dir, cases);  // no output, no bind cache or report, no temporary
}

TEST(EvalCommand, RefusesAnOutputItDidNotWriteAndLeavesItUntouched) {
  const fs::path dir = test::temp_dir("eval_out_safety");
  const std::string data = test::build_tiny_dataset(dir);  // an evaluation that would succeed and write
  test::users_folder(dir, "mine");
  std::ofstream(dir / "mine" / "report.md") << "# the user's report\n";
  std::ofstream(dir / "notes.txt") << "the user's notes\n";
  test::copy_as_predictions((dir / data / "character-0000.h5").string(), (dir / "predicted.h5").string());
  const auto eval = [&](const std::string& out) {
    return std::vector<std::string>{"eval",  "--data", data,      "--predictions", "predicted.h5",
                                    "--out", out,      "--quiet", "--no-plots",    "--no-penetration"};
  };
  test::expect_errors_writing_nothing(
      dir, {{eval("mine"),
             {"mine: --out: expected an empty folder or a report folder amt eval wrote (metrics.json of format "
              "amt-eval), found other files"}},
            {eval("notes.txt"), {"notes.txt: --out: expected a folder for the report", "found a regular file"}}});
}

}  // namespace
}  // namespace amt
