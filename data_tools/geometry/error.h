#pragma once
// Errors on bad input: one exception type whose message is the one line `amt` prints before it
// exits non-zero. Messages name the file, the field, what was found and what was expected.
#include <sstream>
#include <stdexcept>
#include <string>

namespace amt {

/// Bad input or a failed operation the user can act on. what() is a complete one-line message.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

namespace detail {
template <typename... Parts>
std::string concat(const Parts&... parts) {
  std::ostringstream out;
  (out << ... << parts);
  return out.str();
}
}  // namespace detail

/// Throws amt::Error with the concatenated parts: fail("a.h5: /characters/x/faces: ", "expected ...").
template <typename... Parts>
[[noreturn]] void fail(const Parts&... parts) {
  throw Error(detail::concat(parts...));
}

}  // namespace amt

/// Checks a condition on input data; throws amt::Error built from the remaining arguments.
#define AMT_CHECK(cond, ...)                    \
  do {                                          \
    if (!(cond)) ::amt::fail(__VA_ARGS__);      \
  } while (0)
