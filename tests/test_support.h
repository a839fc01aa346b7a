#pragma once
// Helpers shared by the test suites: scratch folders and error capture.
#include <unistd.h>

#include <filesystem>
#include <string>

#include "data_tools/error.h"

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

}  // namespace amt::test
