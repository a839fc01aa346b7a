#pragma once
// A full disk without root or a mount, for the tests of write failures: lowers this process's file
// size limit (RLIMIT_FSIZE) and ignores SIGXFSZ, so that a write past the limit fails with EFBIG
// ("File too large") as a write to a full disk fails with ENOSPC. Restores both when destroyed.
#include <sys/resource.h>

#include <csignal>

namespace amt::test {

class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    if (getrlimit(RLIMIT_FSIZE, &previous_) != 0 || (previous_.rlim_max != RLIM_INFINITY && previous_.rlim_max < bytes))
      return;
    previous_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit limit = previous_;
    limit.rlim_cur = bytes;
    active_ = setrlimit(RLIMIT_FSIZE, &limit) == 0;
  }
  ~FileSizeLimit() {
    if (!active_) return;
    setrlimit(RLIMIT_FSIZE, &previous_);
    std::signal(SIGXFSZ, previous_handler_);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;
  /// False when the limit could not be set (the test should skip, saying so).
  bool active() const { return active_; }

 private:
  rlimit previous_{};
  void (*previous_handler_)(int) = SIG_DFL;
  bool active_ = false;
};

}  // namespace amt::test
