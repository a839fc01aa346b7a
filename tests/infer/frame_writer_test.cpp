// Output paths of the runtime (issue 19, data loss): an OBJ folder replaces only a folder amt wrote
// (marked by .amt-output), a stale temporary of amt's is replaced and a foreign one left alone, '.'
// and '..' are refused, and no output replaces a folder, a link or a FIFO. Every refusal happens in
// check_output_writable / open_frame_writer, before any frame is computed, and touches nothing.
#include "infer/frame_writer.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "data_tools/geometry/shapes.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> names_in(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

OutputInfo tiny_info(int frames) {
  OutputInfo info;
  info.mesh = uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 6, 4);
  info.frames = frames;
  return info;
}

// Writes `frames` frames of the tiny mesh to `path` through the runtime's writer.
std::string write_frames(const std::string& path, int frames) {
  const OutputInfo info = tiny_info(frames);
  check_output_writable(path);
  auto writer = open_frame_writer(path, info);
  for (int t = 0; t < frames; ++t) writer->append(info.mesh.V * (1.0f + 0.1f * float(t)), {});
  return writer->finish();
}

// The error of writing `path`, checked at both entry points (before any work).
std::string refusal(const std::string& path) {
  const std::string checked = test::error_of([&] { check_output_writable(path); });
  const std::string opened = test::error_of([&] { open_frame_writer(path, tiny_info(2)); });
  EXPECT_EQ(checked, opened);
  EXPECT_EQ(checked.find('\n'), std::string::npos) << checked;
  return checked;
}

TEST(ObjFolderOutput, IsMarkedAndReplacesOnlyAFolderAmtWrote) {
  const fs::path dir = test::temp_dir("obj_marked");
  const std::string out = (dir / "frames").string();
  EXPECT_EQ(write_frames(out, 3), out + "/ (3 OBJ files)");
  EXPECT_EQ(names_in(out),
            (std::vector<std::string>{".amt-output", "frame_0000.obj", "frame_0001.obj", "frame_0002.obj"}));
  EXPECT_EQ(test::read_file_bytes(dir / "frames" / ".amt-output"), "amt-obj-sequence\nversion 1\nframes 3\n");
  // A second run replaces amt's own folder: two frames now, nothing left of the first run.
  write_frames(out + "/", 2);
  EXPECT_EQ(names_in(out), (std::vector<std::string>{".amt-output", "frame_0000.obj", "frame_0001.obj"}));
  EXPECT_EQ(test::read_file_bytes(dir / "frames" / ".amt-output"), "amt-obj-sequence\nversion 1\nframes 2\n");
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"frames"}));
}

TEST(ObjFolderOutput, RefusesAUsersFolderAFileAndAFolderOfAmtsHoldingAUsersFile) {
  const fs::path dir = test::temp_dir("obj_refused");
  fs::create_directories(dir / "mine");
  std::ofstream(dir / "mine" / "thesis.tex") << "years of work";
  std::string e = refusal((dir / "mine").string());
  EXPECT_NE(e.find((dir / "mine").string() + ": --out: expected no file there or an OBJ folder amt wrote (with "
                                             ".amt-output), found a folder amt did not write"),
            std::string::npos)
      << e;
  EXPECT_EQ(test::read_file_bytes(dir / "mine" / "thesis.tex"), "years of work");

  std::ofstream(dir / "notes.txt") << "notes";
  e = refusal((dir / "notes.txt").string());
  EXPECT_NE(e.find("notes.txt: --out: expected no file there or an OBJ folder amt wrote"), std::string::npos) << e;
  EXPECT_NE(e.find("found a regular file"), std::string::npos) << e;
  EXPECT_EQ(test::read_file_bytes(dir / "notes.txt"), "notes");

  const std::string out = (dir / "frames").string();
  write_frames(out, 1);
  std::ofstream(dir / "frames" / "keep.txt") << "mine";
  e = refusal(out);
  EXPECT_NE(e.find("holding a file amt did not write (keep.txt)"), std::string::npos) << e;
  EXPECT_EQ(test::read_file_bytes(dir / "frames" / "keep.txt"), "mine");
  EXPECT_TRUE(fs::exists(dir / "frames" / "frame_0000.obj"));
}

TEST(ObjFolderOutput, RefusesTheCurrentFolderAndTheFoldersAboveIt) {
  const fs::path dir = test::temp_dir("obj_current");
  fs::create_directories(dir / "work");
  std::ofstream(dir / "work" / "data.txt") << "data";
  const fs::path before = fs::current_path();
  fs::current_path(dir / "work");
  for (const std::string& out :
       std::vector<std::string>{".", "./", "..", "../", "sub/..", (dir / "work").string(), dir.string()}) {
    const std::string e = refusal(out);
    EXPECT_EQ(e.rfind(out + ": --out: expected a new folder for the OBJ files, found ", 0), 0u) << out << ": " << e;
  }
  fs::current_path(before);
  EXPECT_EQ(names_in(dir / "work"), (std::vector<std::string>{"data.txt"}));
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"work"}));
}

TEST(ObjFolderOutput, ReplacesAStaleTemporaryOfAmtsAndLeavesAForeignOneAlone) {
  const fs::path dir = test::temp_dir("obj_stale");
  // A killed run's temporary: the marker (written first) and some frames.
  fs::create_directories(dir / "frames.amt-tmp");
  std::ofstream(dir / "frames.amt-tmp" / ".amt-output") << "amt-obj-sequence\nversion 1\nframes 0\n";
  std::ofstream(dir / "frames.amt-tmp" / "frame_0000.obj") << "v 0 0 0\n";
  write_frames((dir / "frames").string(), 2);
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"frames"}));
  EXPECT_EQ(names_in(dir / "frames"), (std::vector<std::string>{".amt-output", "frame_0000.obj", "frame_0001.obj"}));
  // A folder named like the temporary that amt did not write.
  fs::create_directories(dir / "other.amt-tmp");
  std::ofstream(dir / "other.amt-tmp" / "backup.obj") << "v 1 2 3\n";
  const std::string e = refusal((dir / "other").string());
  EXPECT_NE(e.find((dir / "other.amt-tmp").string() + ": --out: expected no file there or the temporary folder of an "
                                                      "interrupted amt run, found a folder amt did not write"),
            std::string::npos)
      << e;
  EXPECT_EQ(test::read_file_bytes(dir / "other.amt-tmp" / "backup.obj"), "v 1 2 3\n");
  EXPECT_FALSE(fs::exists(dir / "other"));
}

TEST(FileOutput, NeverReplacesAFolderALinkOrAFifo) {
  const fs::path dir = test::temp_dir("file_targets");
  fs::create_directories(dir / "a.glb" / "inside");
  std::string e = refusal((dir / "a.glb").string());
  EXPECT_NE(
      e.find((dir / "a.glb").string() + ": output: expected a regular file or no file to replace, found a folder"),
      std::string::npos)
      << e;
  fs::create_directories(dir / "b.h5");
  e = refusal((dir / "b.h5").string());
  EXPECT_NE(e.find("found a folder"), std::string::npos) << e;
  EXPECT_TRUE(fs::is_directory(dir / "a.glb" / "inside"));
  // A FIFO at the output is refused at once (opening it would block).
  ASSERT_EQ(::mkfifo((dir / "c.glb").c_str(), 0600), 0);
  e = refusal((dir / "c.glb").string());
  EXPECT_NE(e.find("found a FIFO"), std::string::npos) << e;
  // A link as the temporary would be written through: refused, its target untouched.
  std::ofstream(dir / "precious.txt") << "precious";
  fs::create_symlink(dir / "precious.txt", dir / "d.glb.amt-tmp");
  e = refusal((dir / "d.glb").string());
  EXPECT_NE(e.find("d.glb.amt-tmp: temporary: expected no file or a stale temporary file, found a symbolic link"),
            std::string::npos)
      << e;
  fs::create_symlink(dir / "precious.txt", dir / "e.glb.frames.amt-tmp");
  e = refusal((dir / "e.glb").string());
  EXPECT_NE(e.find("e.glb.frames.amt-tmp: temporary:"), std::string::npos) << e;
  EXPECT_EQ(test::read_file_bytes(dir / "precious.txt"), "precious");
  // A stale regular temporary of a killed run is replaced.
  std::ofstream(dir / "f.glb.frames.amt-tmp") << "stale";
  std::ofstream(dir / "f.glb.amt-tmp") << "stale";
  std::ofstream(dir / "f.glb.tmp") << "the user's own";  // not amt's suffix: never touched
  write_frames((dir / "f.glb").string(), 2);
  EXPECT_FALSE(fs::exists(dir / "f.glb.frames.amt-tmp"));
  EXPECT_FALSE(fs::exists(dir / "f.glb.amt-tmp"));
  EXPECT_EQ(test::read_file_bytes(dir / "f.glb.tmp"), "the user's own");
  EXPECT_GT(fs::file_size(dir / "f.glb"), 100u);
}

}  // namespace
}  // namespace amt
