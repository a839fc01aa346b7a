#pragma once
// Helpers shared by the test suites: scratch folders, error capture, shell commands and the glTF validator.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "data_tools/geometry/error.h"

namespace amt::test {

/// A fresh, empty folder `name` under this test process's scratch folder (in the system's temporary
/// folder, unique to the process, removed when the process exits).
inline std::filesystem::path temp_dir(const std::string& name) {
  struct Root {
    std::filesystem::path path = std::filesystem::temp_directory_path() / ("amt_test_" + std::to_string(::getpid()));
    ~Root() {
      std::error_code ignored;
      std::filesystem::remove_all(path, ignored);
    }
  };
  static const Root root;
  const auto dir = root.path / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// The message of the amt::Error that f() throws, or "" when it throws none.
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

/// The bytes of a file ("" when it cannot be read).
inline std::string read_file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

/// What a shell command printed and its exit status (-1 when a signal ended it).
struct CommandResult {
  int status = -1;
  std::string out, err;
};

/// `program` and `args` as one sh command line, each word single-quoted.
inline std::string shell_command(const std::string& program, const std::vector<std::string>& args) {
  const auto quote = [](const std::string& word) {
    std::string quoted = "'";
    for (char c : word) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return quoted + "'";
  };
  std::string command = quote(program);
  for (const std::string& a : args) command += " " + quote(a);
  return command;
}

/// Runs `command` with sh as a user runs it, capturing stdout and stderr.
inline CommandResult run_command(const std::string& command) {
  const std::filesystem::path dir = temp_dir("run_command");
  const std::string out = (dir / "out.txt").string(), err = (dir / "err.txt").string();
  const int status = std::system(("(" + command + ") >'" + out + "' 2>'" + err + "'").c_str());
  const auto read = [](const std::string& path) {
    std::ifstream in(path);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  };
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, read(out), read(err)};
}

/// Runs the Khronos glTF validator (tools/gltf-validator/validate.mjs, installed by
/// scripts/setup.sh) on a .gltf or .glb file: zero errors expected. The test fails, not skips, when
/// Node or the validator is not installed. The repository is found from AMT_TEST_ASSETS_DIR.
inline void expect_valid_gltf(const std::filesystem::path& file) {
  const std::filesystem::path repo =
      std::filesystem::path(AMT_TEST_ASSETS_DIR).lexically_normal().parent_path().parent_path();
  const std::filesystem::path tool = repo / "tools" / "gltf-validator";
  if (std::system("node --version > /dev/null 2>&1") != 0) {
    ADD_FAILURE() << "Node.js (node) is not installed, so the glTF validator cannot run: run scripts/setup.sh";
    return;
  }
  if (!std::filesystem::exists(tool / "node_modules" / "gltf-validator" / "package.json")) {
    ADD_FAILURE() << "the Khronos glTF validator is not installed in " << (tool / "node_modules").string()
                  << ": run scripts/setup.sh (it runs `npm ci` in tools/gltf-validator)";
    return;
  }
  const std::filesystem::path log = file.string() + ".validator.txt";
  const std::string command =
      "node '" + (tool / "validate.mjs").string() + "' '" + file.string() + "' > '" + log.string() + "' 2>&1";
  const int status = std::system(command.c_str());
  std::ifstream in(log);
  std::ostringstream text;
  text << in.rdbuf();
  const std::string report = text.str();
  std::cout << report;
  EXPECT_EQ(status, 0) << report;
  EXPECT_NE(report.find(": 0 errors"), std::string::npos) << report;
  std::error_code ignored;
  std::filesystem::remove(log, ignored);
}

}  // namespace amt::test
