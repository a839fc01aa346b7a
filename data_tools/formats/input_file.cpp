#include "data_tools/formats/input_file.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "data_tools/geometry/error.h"

namespace amt {

namespace {

constexpr uint64_t kDefaultMaxInputBytes = uint64_t(4) << 30;

const char* kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a folder";
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

}  // namespace

uint64_t max_input_bytes() {
  const char* text = std::getenv("AMT_MAX_INPUT_BYTES");
  if (text == nullptr || *text == '\0') return kDefaultMaxInputBytes;
  char* end = nullptr;
  errno = 0;
  const unsigned long long value = std::strtoull(text, &end, 10);
  AMT_CHECK(errno == 0 && end != text && *end == '\0' && value > 0 && text[0] != '-',
            "AMT_MAX_INPUT_BYTES: expected a positive number of bytes, found '", text, "'");
  return uint64_t(value);
}

uint64_t check_input_file(const std::string& path, const std::string& what) {
  AMT_CHECK(!path.empty(), "input: expected a file name (", what, "), found an empty name");
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int error = errno;
    fail(path, ": cannot open: ", error == ENOENT ? "no such file" : std::strerror(error), " (expected ", what, ")");
  }
  AMT_CHECK(S_ISREG(st.st_mode), path, ": cannot read: expected ", what, " as a regular file, found ",
            kind_of(st.st_mode));
  const uint64_t size = uint64_t(st.st_size), limit = max_input_bytes();
  AMT_CHECK(size <= limit, path, ": size: expected ", what, " of at most ", limit,
            " bytes (the limit AMT_MAX_INPUT_BYTES sets), found ", size, " bytes");
  return size;
}

}  // namespace amt
