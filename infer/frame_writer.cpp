#include "infer/frame_writer.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "data_tools/atomic_file.h"
#include "data_tools/dataset_file.h"
#include "data_tools/error.h"
#include "data_tools/obj_io.h"
#include "infer/glb_stream_writer.h"

namespace amt {

namespace {

std::string lower_extension(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

std::string megabytes(uintmax_t bytes) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f MB", double(bytes) / 1e6);
  return text;
}

class GlbWriter : public FrameWriter {
 public:
  GlbWriter(const std::string& path, const OutputInfo& info)
      : path_(path), writer_(path, info.mesh.F, info.mesh.num_vertices(), info.fps, info.character, info.clip) {}
  void append(const MatrixX3f& V, const Transforms&) override { writer_.append(V); }
  std::string finish() override { return path_ + ", " + megabytes(writer_.finish()); }
  int num_frames() const override { return writer_.num_frames(); }

 private:
  std::string path_;
  GlbStreamWriter writer_;
};

class DatasetFrameWriter : public FrameWriter {
 public:
  DatasetFrameWriter(const std::string& path, const OutputInfo& info)
      : path_(path), writer_(path, info.fps, info.skeleton.names) {
    CharacterData c;
    c.name = info.character;
    c.mesh = info.mesh;
    c.skeleton = info.skeleton;
    c.apparel_mask = info.apparel_mask;
    c.body_weights = info.weights;
    c.split = "test";
    writer_.add_character(c);
    ClipInfo clip;
    clip.name = info.clip;
    clip.character = info.character;
    clip.motion = info.motion;
    clip.split = "test";
    clip.fps = info.fps;
    clip.ground_truth = GroundTruth::kVertices;
    writer_.begin_clip(clip);
  }
  void append(const MatrixX3f& V, const Transforms& T) override { writer_.append_frame(T, V), ++frames_; }
  std::string finish() override {
    writer_.end_clip();
    writer_.commit();
    return path_ + ", " + megabytes(std::filesystem::file_size(path_));
  }
  int num_frames() const override { return frames_; }

 private:
  std::string path_;
  DatasetWriter writer_;
  int frames_ = 0;
};

class ObjFolderWriter : public FrameWriter {
 public:
  ObjFolderWriter(const std::string& folder, const OutputInfo& info)
      : folder_(folder), temporary_(temporary_path(folder)), F_(info.mesh.F) {
    digits_ = 4;
    for (int n = info.frames; n >= 10000; n /= 10) ++digits_;
    std::error_code error;
    std::filesystem::remove_all(temporary_, error);
    std::filesystem::create_directories(temporary_, error);
    AMT_CHECK(!error, folder, ": output: expected a writable folder, found an error creating ", temporary_, " (",
              error.message(), ")");
  }
  ~ObjFolderWriter() override {
    if (!finished_) {
      std::error_code ignored;
      std::filesystem::remove_all(temporary_, ignored);
    }
  }
  void append(const MatrixX3f& V, const Transforms&) override {
    char name[32];
    std::snprintf(name, sizeof(name), "frame_%0*d.obj", digits_, frames_);
    write_obj((std::filesystem::path(temporary_) / name).string(), TriMesh{V, F_});
    ++frames_;
  }
  std::string finish() override {
    AMT_CHECK(frames_ > 0, folder_, ": frames: expected at least 1 frame, found none");
    std::error_code error;
    std::filesystem::remove_all(folder_, error);
    AMT_CHECK(!error, folder_, ": output: expected to replace the old folder, found an error (", error.message(), ")");
    std::filesystem::rename(temporary_, folder_, error);
    AMT_CHECK(!error, folder_, ": output: expected to rename ", temporary_, " onto it, found an error (",
              error.message(), ")");
    finished_ = true;
    return folder_ + "/ (" + std::to_string(frames_) + " OBJ files)";
  }
  int num_frames() const override { return frames_; }

 private:
  std::string folder_, temporary_;
  MatrixX3i F_;
  int digits_ = 4, frames_ = 0;
  bool finished_ = false;
};

}  // namespace

std::string output_kind(const std::string& path) {
  AMT_CHECK(!path.empty(), "--out: expected an output path, found none");
  const std::string e = lower_extension(path);
  if (e == ".glb") return "glb";
  if (e == ".h5" || e == ".hdf5") return "h5";
  AMT_CHECK(e != ".gltf", path, ": --out: expected .glb (binary glTF), .h5 or a folder for OBJ files, found .gltf");
  AMT_CHECK(e != ".obj", path, ": --out: expected a folder for the OBJ sequence (frame_0000.obj, ...), found a .obj ",
            "file name");
  return "obj";
}

void check_output_writable(const std::string& path) {
  output_kind(path);
  try {
    create_parent_folder(path);
  } catch (const Error& e) {
    fail(path, ": --out: expected a writable location, found that its folder cannot be created (", e.what(), ")");
  }
  const std::string probe = temporary_path(path);
  std::FILE* f = std::fopen(probe.c_str(), "wb");
  AMT_CHECK(f != nullptr, path, ": --out: expected a writable location, found that ", probe, " cannot be created");
  std::fclose(f);
  std::error_code ignored;
  std::filesystem::remove(probe, ignored);
}

std::unique_ptr<FrameWriter> open_frame_writer(const std::string& path, const OutputInfo& info) {
  const std::string kind = output_kind(path);
  // The folder must be creatable and writable before any work: probe it with a temporary file.
  try {
    create_parent_folder(path);
  } catch (const Error&) {
    fail(path, ": --out: expected a writable location, found that its folder cannot be created");
  }
  if (kind == "glb") return std::make_unique<GlbWriter>(path, info);
  if (kind == "h5") return std::make_unique<DatasetFrameWriter>(path, info);
  return std::make_unique<ObjFolderWriter>(path, info);
}

}  // namespace amt
