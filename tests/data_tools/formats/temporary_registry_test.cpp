// The live temporaries that SIGINT and SIGTERM remove (app/main.cpp): registered files and folders
// go, renamed and unregistered ones stay.
#include "data_tools/formats/temporary_registry.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "data_tools/formats/atomic_file.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

TEST(TemporaryRegistry, RemovesWhatIsLiveAndNothingElse) {
  const fs::path dir = test::temp_dir("temporary_registry");
  const std::string file = (dir / "a.glb.tmp").string(), folder = (dir / "frames.amt-tmp").string();
  const std::string renamed = (dir / "b.h5.tmp").string(), kept = (dir / "c.ckpt.tmp").string();
  for (const std::string& p : {file, renamed, kept}) {
    register_temporary(p);
    std::ofstream(p) << "x";
  }
  register_temporary(folder);
  fs::create_directories(fs::path(folder) / "inner");
  std::ofstream(fs::path(folder) / "inner" / "frame_0000.obj") << "v 0 0 0\n";
  register_temporary((dir / "never_created.tmp").string());
  ASSERT_FALSE(rename_registered_temporary(renamed, (dir / "b.h5").string()));
  unregister_temporary(kept);
  EXPECT_EQ(registered_temporaries(), (std::vector<std::string>{file, folder, (dir / "never_created.tmp").string()}));
  EXPECT_EQ(remove_registered_temporaries(), 2);  // the file and the folder; the third never existed
  EXPECT_TRUE(registered_temporaries().empty());
  EXPECT_FALSE(fs::exists(file));
  EXPECT_FALSE(fs::exists(folder));
  EXPECT_TRUE(fs::exists(dir / "b.h5"));
  EXPECT_TRUE(fs::exists(kept));
}

TEST(TemporaryRegistry, AtomicWritesRegisterOnlyWhileTheyWrite) {
  const fs::path dir = test::temp_dir("temporary_registry_atomic");
  write_file_atomically((dir / "notes.json").string(), "{}");
  EXPECT_TRUE(registered_temporaries().empty());
  // A failed rename (onto a folder) removes and unregisters the temporary.
  fs::create_directories(dir / "folder");
  EXPECT_THROW(write_file_atomically((dir / "folder").string(), "x"), Error);
  EXPECT_TRUE(registered_temporaries().empty());
  EXPECT_FALSE(fs::exists(dir / "folder.tmp"));
}

}  // namespace
}  // namespace amt
