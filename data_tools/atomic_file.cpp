#include "data_tools/atomic_file.h"

#include <filesystem>
#include <fstream>

#include "data_tools/error.h"

namespace amt {

std::string temporary_path(const std::string& path) { return path + ".tmp"; }

void create_parent_folder(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (parent.empty()) return;
  std::error_code error;
  std::filesystem::create_directories(parent, error);
  AMT_CHECK(!error, path, ": folder: expected to create ", parent.string(), ", found error: ", error.message());
}

void replace_with_temporary(const std::string& temporary, const std::string& path) {
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error) {
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
    fail(path, ": rename: expected to replace the file with ", temporary, ", found error: ", error.message());
  }
}

void write_file_atomically(const std::string& path, std::string_view bytes) {
  create_parent_folder(path);
  const std::string temporary = temporary_path(path);
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    AMT_CHECK(out.good(), temporary, ": file: expected a writable file, found none (permissions?)");
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(temporary, ignored);
      fail(temporary, ": write: expected ", bytes.size(), " bytes written, found a write error (disk full?)");
    }
  }
  replace_with_temporary(temporary, path);
}

}  // namespace amt
