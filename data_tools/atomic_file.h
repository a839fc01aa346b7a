#pragma once
// Writing files so that no partial output ever replaces a good file: everything the project writes
// goes to "<path>.tmp" first and is renamed onto the path only when complete.
#include <string>
#include <string_view>

namespace amt {

/// The temporary name a file is written under before it replaces `path`: "<path>.tmp".
std::string temporary_path(const std::string& path);

/// Creates the folder that will hold `path` (and its parents) when missing; throws amt::Error
/// naming the folder when it cannot.
void create_parent_folder(const std::string& path);

/// Renames `temporary` onto `path`, replacing any old file in one step. On failure the temporary is
/// removed and amt::Error names both.
void replace_with_temporary(const std::string& temporary, const std::string& path);

/// Writes `bytes` to temporary_path(path) (creating the parent folder) and renames it onto path.
void write_file_atomically(const std::string& path, std::string_view bytes);

}  // namespace amt
