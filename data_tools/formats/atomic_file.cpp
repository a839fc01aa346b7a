#include "data_tools/formats/atomic_file.h"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include "data_tools/formats/temporary_registry.h"
#include "data_tools/geometry/error.h"

namespace amt {

std::string temporary_path(const std::string& path) {
  return path + kTemporarySuffix;
}

void create_parent_folder(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (parent.empty()) return;
  std::error_code error;
  std::filesystem::create_directories(parent, error);
  AMT_CHECK(!error, path, ": folder: expected to create ", parent.string(), ", found error: ", error.message());
}

std::string describe_file_type(std::filesystem::file_type type) {
  using std::filesystem::file_type;
  switch (type) {
    case file_type::not_found:
      return "no file";
    case file_type::regular:
      return "a regular file";
    case file_type::directory:
      return "a folder";
    case file_type::symlink:
      return "a symbolic link";
    case file_type::block:
      return "a block device";
    case file_type::character:
      return "a character device";
    case file_type::fifo:
      return "a FIFO (named pipe)";
    case file_type::socket:
      return "a socket";
    default:
      return "a file of unknown type";
  }
}

void check_replaceable_file(const std::string& path) {
  std::error_code error;
  const auto type = std::filesystem::symlink_status(path, error).type();
  AMT_CHECK(type == std::filesystem::file_type::not_found || type == std::filesystem::file_type::regular, path,
            ": output: expected a regular file or no file to replace, found ", describe_file_type(type),
            " (amt replaces only regular files; remove it or choose another name)");
}

void check_writable_location(const std::string& path, const std::string& what) {
  namespace fs = std::filesystem;
  std::error_code error;
  fs::path at = fs::absolute(fs::path(path), error).lexically_normal();
  if (at.has_filename() && !fs::is_directory(at, error)) at = at.parent_path();
  while (!at.empty() && !fs::exists(fs::symlink_status(at, error)) && at != at.root_path()) at = at.parent_path();
  AMT_CHECK(fs::is_directory(at, error), path, ": ", what, ": cannot write into ", at.string(), " (",
            describe_file_type(fs::status(at, error).type()), ", not a folder)");
  AMT_CHECK(::access(at.c_str(), W_OK | X_OK) == 0, path, ": ", what, ": cannot write into ", at.string(), " (",
            std::strerror(errno), ")");
}

void check_output_not_input(const std::string& output, const std::string& option, const std::vector<RunInput>& inputs) {
  namespace fs = std::filesystem;
  std::error_code error;
  if (output.empty() || !fs::exists(output, error)) return;  // a new file cannot be an input
  for (const RunInput& input : inputs) {
    if (input.path.empty()) continue;
    std::vector<std::string> candidates = {input.path};
    const size_t colon = input.path.rfind(':');
    if (colon != std::string::npos && colon > 0) candidates.push_back(input.path.substr(0, colon));
    for (const std::string& candidate : candidates) {
      if (!fs::exists(candidate, error)) continue;
      AMT_CHECK(!fs::equivalent(output, candidate, error), output, ": ", option,
                ": expected a new file, found the run's own input ", candidate, " (", input.option,
                "); amt never replaces an input: choose another name");
    }
  }
}

void prepare_temporary_file(const std::string& temporary) {
  std::error_code error;
  const auto type = std::filesystem::symlink_status(temporary, error).type();
  if (type == std::filesystem::file_type::not_found) return;
  AMT_CHECK(type == std::filesystem::file_type::regular, temporary,
            ": temporary: expected no file or a stale temporary file, found ", describe_file_type(type),
            " (left alone; remove it or choose another output name)");
  std::filesystem::remove(temporary, error);
  AMT_CHECK(!error, temporary,
            ": temporary: expected to remove the stale temporary file, found error: ", error.message());
}

void discard_temporary(const std::string& temporary) {
  std::error_code ignored;
  std::filesystem::remove_all(temporary, ignored);
  unregister_temporary(temporary);
}

void replace_with_temporary(const std::string& temporary, const std::string& path) {
  std::error_code error;
  try {
    check_replaceable_file(path);
  } catch (const Error&) {
    discard_temporary(temporary);
    throw;
  }
  error = rename_registered_temporary(temporary, path);
  if (error) {
    discard_temporary(temporary);
    fail(path, ": rename: expected to replace the file with ", temporary, ", found error: ", error.message());
  }
}

void write_file_atomically(const std::string& path, std::string_view bytes) {
  create_parent_folder(path);
  const std::string temporary = temporary_path(path);
  check_replaceable_file(path);
  prepare_temporary_file(temporary);
  register_temporary(temporary);
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out.good()) {
      discard_temporary(temporary);
      fail(temporary, ": file: expected a writable file, found none (permissions?)");
    }
    errno = 0;
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) {
      const int error = errno;  // set by the failed write(2) or close(2) under the stream
      discard_temporary(temporary);
      fail(temporary, ": write: expected ", bytes.size(), " bytes written, found an error (",
           error != 0 ? std::strerror(error) : "disk full?", ")");
    }
  }
  replace_with_temporary(temporary, path);
}

}  // namespace amt
