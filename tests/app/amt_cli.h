#pragma once
// Helpers of the command-line tests (tests/app/): the built amt program (AMT_BINARY, injected by CMake)
// run in a scratch folder as a user runs it, the checks every failure must pass (status, one line naming
// the file or option), snapshots of folders that must stay untouched, and tiny inputs made by amt itself.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "tests/test_support.h"

namespace amt::test {

/// The checkout's shipped model.
inline std::string shipped_model() {
  return (std::filesystem::path(AMT_ASSET_DIR).parent_path() / "models" / "pretrained").string();
}

/// Runs `amt args...` with `dir` as the current folder (paths in `args` may be relative to it).
inline CommandResult run_amt(const std::filesystem::path& dir, const std::vector<std::string>& args) {
  return run_command("cd " + shell_command(dir.string(), {}) + " && " + shell_command(AMT_BINARY, args));
}

/// `amt args...` in `dir` must succeed; returns what it printed.
inline CommandResult expect_success(const std::filesystem::path& dir, const std::vector<std::string>& args) {
  const CommandResult r = run_amt(dir, args);
  EXPECT_EQ(r.status, 0) << shell_command("amt", args) << "\n" << r.err;
  return r;
}

inline size_t line_count(const std::string& text) {
  return size_t(std::count(text.begin(), text.end(), '\n'));
}

/// A failed run: exit status `status` (1: amt's errors, 2: command-line errors), nothing on stdout, and
/// one line on stderr, "amt: error: " followed by a message holding every one of `fragments` (the file,
/// the field or option, what was expected).
inline void expect_one_line_error(const CommandResult& r, const std::vector<std::string>& fragments, int status = 1) {
  EXPECT_EQ(r.status, status) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err.rfind("amt: error: ", 0), 0u) << r.err;
  EXPECT_EQ(line_count(r.err), 1u) << "expected one line: " << r.err;
  for (const std::string& f : fragments)
    EXPECT_NE(r.err.find(f), std::string::npos) << "no '" << f << "' in: " << r.err;
}

/// A run that must fail: its arguments and the fragments its one line must hold.
struct ErrorCase {
  std::vector<std::string> args;
  std::vector<std::string> fragments;
};

std::map<std::string, std::string> snapshot(const std::filesystem::path& dir);

/// Runs every case in `dir`, each a one-line error with `status` (expect_one_line_error), and expects
/// the folder byte for byte as it was before them: nothing written, nothing removed.
inline void expect_errors_writing_nothing(const std::filesystem::path& dir, const std::vector<ErrorCase>& cases,
                                          int status = 1) {
  const auto before = snapshot(dir);
  for (const ErrorCase& c : cases) {
    SCOPED_TRACE(shell_command("amt", c.args));
    expect_one_line_error(run_amt(dir, c.args), c.fragments, status);
  }
  EXPECT_EQ(snapshot(dir), before);
}

/// Everything under `dir`: relative path -> bytes of each file, "<folder>/" -> "" for each folder.
inline std::map<std::string, std::string> snapshot(const std::filesystem::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir)) {
    const std::string relative = std::filesystem::relative(e.path(), dir).string();
    if (e.is_directory()) {
      files[relative + "/"] = "";
    } else {
      files[relative] = read_file_bytes(e.path());
    }
  }
  return files;
}

/// A user's folder `dir/name` holding notes.txt; returns its path.
inline std::filesystem::path users_folder(const std::filesystem::path& dir, const std::string& name) {
  const std::filesystem::path folder = dir / name;
  std::filesystem::create_directories(folder);
  std::ofstream(folder / "notes.txt") << "the user's notes\n";
  return folder;
}

/// `amt dataset example`: dir/ex.h5, a capsule character of about 220 vertices (ex.h5:capsules) with a
/// 6-frame walk (ex.h5:capsules_walk). Returns "ex.h5" (relative to dir).
inline std::string write_example_dataset(const std::filesystem::path& dir) {
  expect_success(dir, {"dataset", "example", "--out", "ex.h5", "--vertices", "300", "--frames", "6", "--threads", "1"});
  return "ex.h5";
}

/// The arguments of `amt dataset build` of the smallest dataset into "data": one 1000-vertex dressed
/// character simulated under two procedural clips (one of them held out) of 4 frames, on one thread,
/// with the options in `changed` given other values (or added).
inline std::vector<std::string> tiny_build(const std::map<std::string, std::string>& changed = {}) {
  std::map<std::string, std::string> options = {{"--out", "data"},     {"--characters", "1"}, {"--motions", ""},
                                                {"--procedural", "2"}, {"--frames", "4"},     {"--vertices", "1000"},
                                                {"--threads", "1"}};
  for (const auto& [option, value] : changed) options[option] = value;
  std::vector<std::string> args = {"dataset", "build"};
  for (const auto& [option, value] : options) args.insert(args.end(), {option, value});
  return args;
}

/// Runs tiny_build() in `dir`; returns "data" (the dataset folder, relative to dir).
inline std::string build_tiny_dataset(const std::filesystem::path& dir) {
  expect_success(dir, tiny_build());
  return "data";
}

}  // namespace amt::test
