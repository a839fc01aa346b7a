#pragma once
// The one check every reader makes before it opens a file: the path is a regular file (after
// following links) of bounded size. A FIFO would block the reader forever, a link to /dev/zero would
// be read until memory runs out, a folder named "x.glb" would give an error naming no file.
#include <cstdint>
#include <string>

namespace amt {

/// Largest input file amt reads, in bytes: 4 GiB, or the environment variable AMT_MAX_INPUT_BYTES
/// (a positive integer; docs/reliability.md).
uint64_t max_input_bytes();

/// Checks, with stat() and without opening it, that `path` names a regular file of at most
/// max_input_bytes(). `what` says what the file was expected to be ("a BVH motion", "an amt checkpoint").
/// Returns the file's size; throws amt::Error naming the path, what it is and what was expected.
uint64_t check_input_file(const std::string& path, const std::string& what);

}  // namespace amt
