#include "data_tools/formats/temporary_registry.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <mutex>
#include <thread>

namespace amt {

namespace {

struct Registry {
  std::mutex mutex;
  std::vector<std::string> paths;
};

// Never destroyed: a signal may arrive while static destructors run at exit.
Registry& registry() {
  static Registry* r = new Registry;
  return *r;
}

}  // namespace

void register_temporary(const std::string& path) {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  r.paths.push_back(path);
}

void unregister_temporary(const std::string& path) {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  const auto found = std::find(r.paths.rbegin(), r.paths.rend(), path);
  if (found != r.paths.rend()) r.paths.erase(std::next(found).base());
}

std::error_code rename_registered_temporary(const std::string& temporary, const std::string& path) {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (!error) {
    const auto found = std::find(r.paths.rbegin(), r.paths.rend(), temporary);
    if (found != r.paths.rend()) r.paths.erase(std::next(found).base());
  }
  return error;
}

std::vector<std::string> registered_temporaries() {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  return r.paths;
}

int remove_registered_temporaries(bool hold) {
  Registry& r = registry();
  r.mutex.lock();
  // A thread may be creating the temporary it registered last (it blocks at its next registry call,
  // so it creates at most that one): passes repeat until two in a row find nothing left.
  std::vector<bool> removed(r.paths.size(), false);
  for (int pass = 0, quiet = 0; pass < 100 && quiet < 2; ++pass) {
    bool found = false;
    for (size_t i = r.paths.size(); i-- > 0;) {  // newest first: files inside a folder before the folder
      std::error_code ignored;
      if (std::filesystem::symlink_status(r.paths[i], ignored).type() == std::filesystem::file_type::not_found)
        continue;
      std::filesystem::remove_all(r.paths[i], ignored);
      removed[i] = found = true;
    }
    quiet = found ? 0 : quiet + 1;
    if (quiet < 2) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  r.paths.clear();
  if (!hold) r.mutex.unlock();
  return int(std::count(removed.begin(), removed.end(), true));
}

}  // namespace amt
