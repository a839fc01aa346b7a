// Atomic writes: the target changes only when the whole file is written, folders are created.
#include "data_tools/formats/atomic_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

std::string read_all(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(AtomicFile, WritesThroughATemporaryAndCreatesFolders) {
  const auto dir = std::filesystem::path(::testing::TempDir()) / ("amt_atomic_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  const std::string path = (dir / "a" / "b" / "out.txt").string();
  EXPECT_EQ(temporary_path(path), path + ".amt-tmp");
  write_file_atomically(path, "first");
  EXPECT_EQ(read_all(path), "first");
  write_file_atomically(path, "second");
  EXPECT_EQ(read_all(path), "second");
  EXPECT_FALSE(std::filesystem::exists(path + ".amt-tmp"));
  std::filesystem::remove_all(dir);
}

// amt's temporaries carry a suffix of their own: a user's "<out>.tmp" survives every write of <out>, and a stale
// "<out>.amt-tmp" (a killed run's) is replaced.
TEST(AtomicFile, AUsersDotTmpFileIsNeverTouched) {
  const auto dir = std::filesystem::path(::testing::TempDir()) / ("amt_atomic_user_tmp_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "out.json").string();
  std::ofstream(path + ".tmp") << "the user's notes";
  std::ofstream(path + ".amt-tmp") << "a killed run's half";
  write_file_atomically(path, "complete");
  EXPECT_EQ(read_all(path), "complete");
  EXPECT_EQ(read_all(path + ".tmp"), "the user's notes");
  EXPECT_FALSE(std::filesystem::exists(path + ".amt-tmp"));
  std::filesystem::remove_all(dir);
}

TEST(AtomicFile, FailuresKeepTheGoodFileAndNameThePath) {
  const auto dir = std::filesystem::path(::testing::TempDir()) / ("amt_atomic_bad_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "blocker") << "a file where a folder should be";
  const std::string blocked = (dir / "blocker" / "out.txt").string();
  try {
    write_file_atomically(blocked, "x");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(blocked + ": folder: expected to create", 0), 0u) << e.what();
  }
  // A rename onto a folder fails: the temporary is removed, the folder untouched.
  const std::string good = (dir / "good").string();
  std::filesystem::create_directories(good + "/inside");
  std::ofstream(good + ".amt-tmp") << "new";
  EXPECT_THROW(replace_with_temporary(good + ".amt-tmp", good), Error);
  EXPECT_FALSE(std::filesystem::exists(good + ".amt-tmp"));
  EXPECT_TRUE(std::filesystem::is_directory(good + "/inside"));
  std::filesystem::remove_all(dir);
}

TEST(AtomicFile, AnUnwritableLocationIsRefusedBeforeAnyWork) {
  const auto dir = std::filesystem::path(::testing::TempDir()) / ("amt_atomic_where_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "ok");
  std::ofstream(dir / "blocker") << "a file where a folder should be";
  // Writable: an existing folder, a folder to create several levels down, a file beside others.
  EXPECT_NO_THROW(check_writable_location((dir / "ok").string(), "--out"));
  EXPECT_NO_THROW(check_writable_location((dir / "new" / "deeper" / "report").string(), "--out"));
  EXPECT_NO_THROW(check_writable_location((dir / "ok" / "x.glb").string(), "--out"));
  // A regular file on the way: named, with what it is.
  const std::string blocked = (dir / "blocker" / "report").string();
  try {
    check_writable_location(blocked, "--out");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              blocked + ": --out: cannot write into " + (dir / "blocker").string() + " (a regular file, not a folder)");
  }
  // A folder without write permission (root may write anywhere, so only checked for other users).
  if (::geteuid() != 0) {
    std::filesystem::create_directories(dir / "locked");
    std::filesystem::permissions(dir / "locked",
                                 std::filesystem::perms::owner_read | std::filesystem::perms::owner_exec);
    try {
      check_writable_location((dir / "locked" / "report").string(), "--out");
      FAIL() << "expected an error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("cannot write into " + (dir / "locked").string() + " (Permission denied)"),
                std::string::npos)
          << e.what();
    }
    std::filesystem::permissions(dir / "locked", std::filesystem::perms::owner_all);
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace amt
