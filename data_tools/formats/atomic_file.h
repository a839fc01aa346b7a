#pragma once
// Writing files so that no partial output ever replaces a good file: everything the project writes
// goes to "<path>.amt-tmp" first and is renamed onto the path only when complete. The suffix is amt's own, so a
// stale temporary of a killed run can be replaced without ever touching a user's "<path>.amt-tmp".
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace amt {

/// The suffix of amt's temporaries.
inline constexpr const char* kTemporarySuffix = ".amt-tmp";

/// The temporary name a file is written under before it replaces `path`: "<path>.amt-tmp".
std::string temporary_path(const std::string& path);

/// Creates the folder that will hold `path` (and its parents) when missing; throws amt::Error
/// naming the folder when it cannot.
void create_parent_folder(const std::string& path);

/// What kind of file a status describes, for messages: "a folder", "a symbolic link", "a FIFO", ...
std::string describe_file_type(std::filesystem::file_type type);

/// Checks that a file amt writes may replace whatever is at `path`: nothing, or a regular file (never
/// a folder, a symbolic link, a FIFO, a socket or a device). Throws amt::Error naming the path and
/// what is there otherwise.
void check_replaceable_file(const std::string& path);

/// Checks, before any work, that amt can write `path` (a file or folder to create or replace): the nearest folder
/// that exists on the way to it (the path itself when it is a folder) is a folder amt may write into. Throws
/// amt::Error "<path>: <what>: cannot write into <folder> (<reason>)" otherwise: a read-only folder or file
/// system, or a regular file where a folder would have to be.
void check_writable_location(const std::string& path, const std::string& what);

/// An output of a run and the inputs it must not replace: throws amt::Error "<output>: <option>: expected a new
/// file, found the run's own input <input> (<its option>); amt never replaces an input: choose another name" when
/// `output` is the same file as one of `inputs` (same file on disk, whatever the spelling: links, "./", hard
/// links). An input "file.h5:name" (a dataset character or clip) is its file. Inputs that do not exist are skipped.
struct RunInput {
  std::string path, option;
};
void check_output_not_input(const std::string& output, const std::string& option, const std::vector<RunInput>& inputs);

/// Makes `temporary` ready to be created: removes a stale regular file left by a killed run; throws
/// amt::Error naming it when it is anything else (a folder, a link that would be written through, a
/// FIFO that would block), which is left alone.
void prepare_temporary_file(const std::string& temporary);

/// Removes `temporary` (a file or a folder) and takes it off the live temporaries
/// (data_tools/formats/temporary_registry.h). Never throws.
void discard_temporary(const std::string& temporary);

/// Renames `temporary` onto `path`, replacing an old regular file in one step (check_replaceable_file
/// first) and takes it off the live temporaries. On failure the temporary is removed and amt::Error
/// names both.
void replace_with_temporary(const std::string& temporary, const std::string& path);

/// Writes `bytes` to temporary_path(path) (creating the parent folder; registered as a live
/// temporary while it exists) and renames it onto path.
void write_file_atomically(const std::string& path, std::string_view bytes);

}  // namespace amt
