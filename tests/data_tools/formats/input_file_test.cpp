// Inputs are regular files of bounded size, checked with stat() before they are opened (issue 19: a
// FIFO hung the BVH reader, a link to /dev/zero was read until the kernel stopped the process, a
// folder named x.glb gave an error naming no file).
#include "data_tools/formats/input_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "data_tools/formats/bvh_import.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/joint_map.h"
#include "data_tools/formats/obj_io.h"
#include "data_tools/formats/pmx_import.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

// Every reader refuses `path` with `found` (a FIFO, a character device, a folder) in a message that
// starts with the path.
void expect_every_reader_refuses(const fs::path& dir, const std::string& stem, const std::string& found) {
  const auto expect = [&](const std::string& extension, const std::string& what, auto&& read) {
    const std::string path = (dir / (stem + extension)).string();
    const std::string e = test::error_of([&] { read(path); });
    EXPECT_EQ(e, path + ": cannot read: expected " + what + " as a regular file, found " + found);
  };
  expect(".bvh", "a BVH motion", [](const std::string& p) { read_bvh(p); });
  expect(".glb", "a glTF or GLB asset", [](const std::string& p) { read_gltf(p); });
  expect(".pmx", "a PMX model", [](const std::string& p) { read_pmx(p); });
  expect(".obj", "an OBJ file", [](const std::string& p) { read_obj(p); });
  expect(".json", "a joint map", [](const std::string& p) { read_joint_map(p); });
  expect(".h5", "an amt-dataset HDF5 file", [](const std::string& p) { DatasetReader reader(p); });
}

TEST(InputFile, AFifoIsRefusedWithoutBeingOpened) {
  // Opening a FIFO for reading blocks until a writer comes: that this test ends shows none is opened.
  const fs::path dir = test::temp_dir("input_fifo");
  for (const char* extension : {".bvh", ".glb", ".pmx", ".obj", ".json", ".h5"}) {
    ASSERT_EQ(::mkfifo((dir / (std::string("take") + extension)).c_str(), 0600), 0);
  }
  expect_every_reader_refuses(dir, "take", "a FIFO (named pipe)");
}

TEST(InputFile, ALinkToDevZeroIsRefused) {
  const fs::path dir = test::temp_dir("input_dev_zero");
  for (const char* extension : {".bvh", ".glb", ".pmx", ".obj", ".json", ".h5"}) {
    fs::create_symlink("/dev/zero", dir / (std::string("zero") + extension));
  }
  expect_every_reader_refuses(dir, "zero", "a character device");
}

TEST(InputFile, AFolderNamedLikeAFileIsNamedInTheError) {
  const fs::path dir = test::temp_dir("input_folder");
  for (const char* extension : {".bvh", ".glb", ".pmx", ".obj", ".json", ".h5"}) {
    fs::create_directories(dir / (std::string("x") + extension));
  }
  expect_every_reader_refuses(dir, "x", "a folder");
  const std::string missing = (dir / "missing.bvh").string();
  EXPECT_EQ(test::error_of([&] { read_bvh(missing); }),
            missing + ": cannot open: no such file (expected a BVH motion)");
}

TEST(InputFile, TheSizeLimitIsFourGibibytesAndAnEnvironmentVariableSetsIt) {
  EXPECT_EQ(max_input_bytes(), uint64_t(4) << 30);
  const fs::path dir = test::temp_dir("input_size");
  const std::string path = (dir / "walk.bvh").string();
  std::ofstream(path) << std::string(100, 'x');
  ASSERT_EQ(setenv("AMT_MAX_INPUT_BYTES", "64", 1), 0);
  EXPECT_EQ(test::error_of([&] { read_bvh(path); }),
            path +
                ": size: expected a BVH motion of at most 64 bytes (the limit AMT_MAX_INPUT_BYTES sets), found 100 "
                "bytes");
  ASSERT_EQ(setenv("AMT_MAX_INPUT_BYTES", "100", 1), 0);
  EXPECT_EQ(check_input_file(path, "a BVH motion"), 100u);
  ASSERT_EQ(setenv("AMT_MAX_INPUT_BYTES", "4k", 1), 0);
  EXPECT_EQ(test::error_of([&] { check_input_file(path, "a BVH motion"); }),
            "AMT_MAX_INPUT_BYTES: expected a positive number of bytes, found '4k'");
  ASSERT_EQ(unsetenv("AMT_MAX_INPUT_BYTES"), 0);
  EXPECT_EQ(check_input_file(path, "a BVH motion"), 100u);
}

}  // namespace
}  // namespace amt
