#pragma once
// The temporaries this process is writing ("<out>.amt-tmp" files and folders, "<out>.frames.amt-tmp", ...),
// so that SIGINT and SIGTERM can remove them before the process exits (app/main.cpp). A writer
// registers a temporary before it creates it and unregisters it once the temporary is renamed into
// place or removed. Thread-safe; no LibTorch.
#include <string>
#include <system_error>
#include <vector>

namespace amt {

/// Adds `path` (a file or a folder) to the live temporaries of this process.
void register_temporary(const std::string& path);

/// Removes `path` from the live temporaries; the file itself is not touched. No-op when absent.
void unregister_temporary(const std::string& path);

/// Renames `temporary` onto `path` and unregisters it, as one step with respect to
/// remove_registered_temporaries (a signal never removes a temporary that was just renamed).
/// Returns the rename's error (the temporary stays registered then).
std::error_code rename_registered_temporary(const std::string& temporary, const std::string& path);

/// The live temporaries, oldest first (for tests).
std::vector<std::string> registered_temporaries();

/// Removes every live temporary (folders with their contents) and returns how many existed. With
/// `hold` the registry stays locked afterwards, so that a thread still writing blocks at its next
/// register or rename instead of creating new files: for the last act of a process being stopped.
int remove_registered_temporaries(bool hold = false);

}  // namespace amt
