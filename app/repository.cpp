#include "app/repository.h"

#include <filesystem>
#include <system_error>

#include "data_tools/geometry/error.h"

namespace amt::app {
namespace {

namespace fs = std::filesystem;

// The running program's file ("" when /proc is not mounted: then only the current folder is searched).
fs::path program_path() {
  std::error_code error;
  const fs::path exe = fs::read_symlink("/proc/self/exe", error);
  return error ? fs::path() : exe;
}

fs::path current_folder() {
  std::error_code error;
  const fs::path cwd = fs::current_path(error);
  return error ? fs::path() : cwd;
}

}  // namespace

std::string find_repository_folder(const std::string& relative) {
  std::error_code error;
  const fs::path exe = program_path();
  if (!exe.empty()) {
    for (fs::path dir = exe.parent_path(); !dir.empty(); dir = dir.parent_path()) {
      if (fs::is_directory(dir / relative, error)) return (dir / relative).string();
      if (dir == dir.root_path()) break;
    }
  }
  const fs::path cwd = current_folder();
  if (!cwd.empty() && fs::is_directory(cwd / relative, error)) return (cwd / relative).string();
  return "";
}

std::string repository_default(const std::string& relative, const std::string& option, const std::string& what) {
  const std::string found = find_repository_folder(relative);
  AMT_CHECK(!found.empty(), option, ": no default: ", relative, " is neither above the amt program (",
            program_path().string(), ") nor in the current folder (", current_folder().string(), "); pass ", option,
            " ", what);
  return found;
}

std::string repository_default_help(const std::string& relative) {
  const std::string found = find_repository_folder(relative);
  return "Default: the repository's " + relative +
         ", looked up above the amt program, then in the current folder (here: " +
         (found.empty() ? "not found" : found) + ")";
}

}  // namespace amt::app
