// The amt program's command line itself: an unknown command or option, a missing or invalid value is
// one line naming it and the help to read, with status 2 (amt's own errors have status 1), and nothing is
// written; --help and --version succeed.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "tests/app/amt_cli.h"

namespace amt {
namespace {

TEST(Usage, UnknownCommandsAndOptionsAndBadValuesAreOneLineErrors) {
  const auto dir = test::temp_dir("usage_errors");
  test::expect_errors_writing_nothing(
      dir,
      {{{}, {"A subcommand is required", "(amt --help lists the options)"}},
       {{"frob"},
        {"expected a command (dataset, train, eval, animate, bench, view, retarget-cloth, refit-garment, convert), "
         "found "
         "'frob'"}},
       {{"dataset", "frob"}, {"found 'frob'", "(amt dataset --help lists the options)"}},
       {{"animate", "--character", "x.glb", "--motion", "y.bvh", "--bogus"},
        {"not expected: --bogus", "(amt animate --help lists the options)"}},
       {{"animate", "--motion", "y.bvh", "--out", "z.glb"}, {"--character is required"}},
       {{"dataset", "build", "--out", "built", "--characters", "many"}, {"--characters", "many"}},
       {{"bench", "--repeats", "0"}, {"--repeats", "0", "(amt bench --help lists the options)"}},
       {{"train", "refiner", "--data", "d", "--out", "o", "--edge-weight", "-1"},
        {"--edge-weight", "-1", "(amt train --help lists the options)"}}},
      2);
}

TEST(Usage, HelpAndVersionSucceed) {
  const auto dir = test::temp_dir("usage_help");
  const test::CommandResult help = test::expect_success(dir, {"--help"});
  for (const char* command : {"dataset", "train", "eval", "animate", "bench", "view", "retarget-cloth", "convert"})
    EXPECT_NE(help.out.find(command), std::string::npos) << command << " not in: " << help.out;
  const test::CommandResult version = test::expect_success(dir, {"--version"});
  EXPECT_EQ(version.out.rfind("amt ", 0), 0u) << version.out;
  EXPECT_NE(version.out.find("LibTorch"), std::string::npos) << version.out;
  EXPECT_EQ(version.err, "");
}

}  // namespace
}  // namespace amt
