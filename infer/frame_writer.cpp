#include "infer/frame_writer.h"

#include <fcntl.h>
#include <stdio.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/gltf_export.h"
#include "data_tools/formats/obj_io.h"
#include "data_tools/formats/temporary_registry.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/motion.h"
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
      : path_(path),
        writer_(path, info.mesh.F, info.mesh.num_vertices(), info.fps, info.character, info.clip, info.apparel_mask) {}
  void append(const MatrixX3f& V, const Transforms&) override { writer_.append(V); }
  std::string finish() override { return path_ + ", " + megabytes(writer_.finish()); }
  int num_frames() const override { return writer_.num_frames(); }

 private:
  std::string path_;
  GlbStreamWriter writer_;
};

// A skinned animation (the construction at the top of infer/frame_writer.h): the canonical joints' node transforms
// come from the frame's joint transforms, the handles' from a fit to its vertices; finish() writes the GLB and says
// how far the skin is from the frames it was given.
class SkinnedGlbWriter : public FrameWriter {
 public:
  SkinnedGlbWriter(const std::string& path, const OutputInfo& info)
      : path_(path),
        info_(info),
        body_(info.skeleton),
        fit_(info.mesh.V, info.skin->apparel),
        is_apparel_(size_t(info.mesh.num_vertices()), 0) {
    const OutputSkin& skin = *info.skin;
    const int N = info.mesh.num_vertices(), J = body_.num_joints(), H = skin.apparel.num_handles();
    AMT_CHECK(skin.body.num_vertices() == N, path, ": skin: expected body weights of ", N, " vertices, found ",
              skin.body.num_vertices());
    AMT_CHECK(skin.handle_parents.size() == size_t(H), path, ": skin: expected a parent joint per handle (", H,
              "), found ", skin.handle_parents.size());
    // The output's skeleton: the canonical joints, then the handles under their body joints.
    skeleton_ = body_;
    skeleton_.rest_joints.conservativeResize(J + H, 3);
    for (int h = 0; h < H; ++h) {
      const int32_t p = skin.handle_parents[size_t(h)];
      AMT_CHECK(p >= 0 && p < J, path, ": skin: expected handle parents among the ", J, " joints, found ", p);
      char name[32];
      std::snprintf(name, sizeof(name), "apparel_handle_%04d", h);
      skeleton_.names.emplace_back(name);
      skeleton_.parents.push_back(p);
      skeleton_.rest_joints.row(J + h) = skin.apparel.rest.row(h);
    }
    weights_ = skin.body;
    for (size_t r = 0; r < skin.apparel.vertices.size(); ++r) {
      const int32_t v = skin.apparel.vertices[r];
      is_apparel_[size_t(v)] = 1;
      weights_.indices.row(v).setZero();
      weights_.weights.row(v).setZero();
      // The vertex's heaviest handles, at most 4 (glTF's JOINTS_0), renormalised by the exporter.
      std::vector<std::pair<float, int32_t>> slots;
      for (Eigen::Index k = 0; k < skin.apparel.weights.cols(); ++k) {
        if (skin.apparel.weights(Eigen::Index(r), k) > 0)
          slots.emplace_back(skin.apparel.weights(Eigen::Index(r), k), skin.apparel.handles(Eigen::Index(r), k));
      }
      std::stable_sort(slots.begin(), slots.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
      for (size_t k = 0; k < slots.size() && k < size_t(kMaxInfluences); ++k) {
        weights_.indices(v, Eigen::Index(k)) = J + slots[k].second;
        weights_.weights(v, Eigen::Index(k)) = slots[k].first;
      }
    }
    for (int v = 0; v < N; ++v) {
      if (!is_apparel_[size_t(v)]) body_rows_.push_back(v);
    }
    animation_.fps = info.fps;
    animation_.translated.assign(size_t(J + H), 0);
    for (int j = 0; j < J + H; ++j) animation_.translated[size_t(j)] = skeleton_.parents[size_t(j)] < 0 || j >= J;
  }

  void append(const MatrixX3f& V, const Transforms& T) override {
    const OutputSkin& skin = *info_.skin;
    const int H = skin.apparel.num_handles();
    AMT_CHECK(V.rows() == info_.mesh.num_vertices() && V.allFinite(), path_, ": frame ", frames_,
              ": expected finite positions of ", info_.mesh.num_vertices(), " vertices");
    append_node_frame(body_, T, animation_);
    // Handles: global rotation and position fitted to the frame, stored relative to the parent joint.
    fallback_.resize(size_t(H));
    for (int h = 0; h < H; ++h)
      fallback_[size_t(h)] =
          Eigen::Quaternionf(Eigen::Matrix3f(T[size_t(skin.handle_parents[size_t(h)])].leftCols<3>()));
    fit_.fit(V, fallback_, rotations_, positions_);
    for (int h = 0; h < H; ++h) {
      const Transform34& P = T[size_t(skin.handle_parents[size_t(h)])];
      const Eigen::Matrix3f Rp = P.leftCols<3>();
      animation_.rotations.emplace_back(Eigen::Matrix3f(Rp.transpose() * rotations_[size_t(h)].toRotationMatrix()));
      animation_.translations.push_back(Rp.transpose() * (positions_.row(h).transpose() - P.col(3)));
    }
    // What the skin gives back, against what was computed.
    linear_blend_skinning(info_.mesh.V, skin.body, skinning_matrices(body_, T), skinned_);
    fit_.skin_vertices(rotations_, positions_, skinned_);
    body_error_.add(V, skinned_, body_rows_);
    apparel_error_.add(V, skinned_, skin.apparel.vertices);
    ++frames_;
  }

  std::string finish() override {
    AMT_CHECK(frames_ > 0, path_, ": expected at least one frame, found none");
    GltfExportOptions options;
    options.name = info_.character;
    options.clip = info_.clip;
    options.apparel_mask = info_.apparel_mask;
    export_gltf_skinned_animation(path_, info_.mesh, skeleton_, weights_, animation_, options);
    char text[320];
    std::snprintf(text, sizeof(text),
                  ", %s, skinned: %d joints and %d apparel handles; the skin is off the computed frames by %.2f cm "
                  "at p95 and %.2f cm at most on the apparel, %.2f cm at p95 on the body (--vertex-cache writes them "
                  "exactly)",
                  megabytes(std::filesystem::file_size(path_)).c_str(), body_.num_joints(),
                  info_.skin->apparel.num_handles(), 100.0 * apparel_error_.quantile(0.95),
                  100.0 * apparel_error_.max(), 100.0 * body_error_.quantile(0.95));
    return path_ + text;
  }
  int num_frames() const override { return frames_; }

 private:
  std::string path_;
  OutputInfo info_;
  Skeleton body_, skeleton_;
  SparseWeights weights_;
  HandleFit fit_;
  std::vector<uint8_t> is_apparel_;
  std::vector<int32_t> body_rows_;
  NodeAnimation animation_;
  Quaternions fallback_, rotations_;
  MatrixX3f positions_, skinned_;
  FitError body_error_, apparel_error_;
  int frames_ = 0;
};

class DatasetFrameWriter : public FrameWriter {
 public:
  DatasetFrameWriter(const std::string& path, const OutputInfo& info)
      : path_(path), writer_(path, info.fps, info.skeleton.names) {
    writer_.mark_predictions(info.made_by);
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

// === OBJ folders: amt replaces a folder only when it wrote it
//
// Every OBJ folder amt writes holds the marker file kObjMarker ("amt-obj-sequence", its version and
// frame count), written first into the temporary folder "<out>.amt-tmp". A folder, or a temporary left
// by a killed run, is amt's when it holds the marker and nothing but frame_*.obj files: only such a
// folder is replaced (the output) or removed (the stale temporary). Anything else is refused.

constexpr const char* kObjMarker = ".amt-output";
constexpr const char* kObjFormat = "amt-obj-sequence";
constexpr int kObjFormatVersion = 1;

namespace fs = std::filesystem;

// True for "frame_<digits>.obj".
bool is_frame_file_name(const std::string& name) {
  const std::string prefix = "frame_", suffix = ".obj";
  if (name.size() <= prefix.size() + suffix.size() || name.rfind(prefix, 0) != 0) return false;
  if (name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0) return false;
  const std::string digits = name.substr(prefix.size(), name.size() - prefix.size() - suffix.size());
  return std::all_of(digits.begin(), digits.end(), [](unsigned char c) { return std::isdigit(c); });
}

// True when `path` is a small regular file whose first line is kObjFormat.
bool is_obj_marker(const fs::path& path) {
  std::error_code error;
  if (fs::symlink_status(path, error).type() != fs::file_type::regular) return false;
  if (fs::file_size(path, error) > 4096 || error) return false;
  std::ifstream in(path);
  std::string first;
  return std::getline(in, first) && first == kObjFormat;
}

// Why `path` is not a folder amt may replace or remove: "" when it is amt's OBJ folder, else what is
// there ("a folder amt did not write (no .amt-output in it)", "a regular file", ...). `exists` tells
// whether anything is there at all.
std::string foreign_obj_folder(const fs::path& path, bool& exists) {
  std::error_code error;
  const fs::file_type type = fs::symlink_status(path, error).type();
  exists = type != fs::file_type::not_found;
  if (!exists) return "";
  if (type != fs::file_type::directory) return describe_file_type(type);
  if (!is_obj_marker(path / kObjMarker)) return std::string("a folder amt did not write (no ") + kObjMarker + " in it)";
  for (fs::directory_iterator it(path, error), end; !error && it != end; it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (name == kObjMarker) continue;
    if (!is_frame_file_name(name) || it->symlink_status(error).type() != fs::file_type::regular) {
      return "a folder of amt's holding a file amt did not write (" + name + ")";
    }
  }
  if (error) return "a folder that cannot be listed (" + error.message() + ")";
  return "";
}

// The OBJ output folder named by `path` without trailing separators ("frames/" -> "frames").
// Refuses names of the current folder or one of its parents ('.', '..', 'a/..', '/').
std::string obj_folder_path(const std::string& path) {
  fs::path p = fs::path(path).lexically_normal();
  while (!p.empty() && p.filename().empty() && p != p.root_path()) p = p.parent_path();
  const std::string name = p.filename().string();
  AMT_CHECK(!p.empty() && name != "." && name != ".." && p != p.root_path(), path,
            ": --out: expected a new folder for the OBJ files, found the name of the current folder or one above "
            "it (amt never replaces a folder it did not write)");
  std::error_code error;
  const fs::path target = fs::weakly_canonical(p, error), here = fs::current_path(error);
  if (!error) {
    const auto [t, h] = std::mismatch(target.begin(), target.end(), here.begin(), here.end());
    AMT_CHECK(t != target.end(), path, ": --out: expected a new folder for the OBJ files, found the current folder ",
              "or a folder that contains it (amt never replaces a folder it did not write)");
  }
  return p.string();
}

// Checks before any work that the OBJ folder `folder` (obj_folder_path) and its temporary can be
// written: each is absent or amt's. Throws amt::Error naming the path otherwise.
void check_obj_folder_target(const std::string& folder, const std::string& temporary) {
  bool exists = false;
  const std::string target = foreign_obj_folder(folder, exists);
  AMT_CHECK(target.empty(), folder, ": --out: expected no file there or an OBJ folder amt wrote (with ", kObjMarker,
            "), found ", target, "; remove it or choose another --out");
  const std::string stale = foreign_obj_folder(temporary, exists);
  AMT_CHECK(stale.empty(), temporary, ": --out: expected no file there or the temporary folder of an interrupted ",
            "amt run, found ", stale, "; amt leaves it alone: remove it or choose another --out");
}

void write_obj_marker(const fs::path& folder, int frames) {
  const std::string text = std::string(kObjFormat) + "\nversion " + std::to_string(kObjFormatVersion) + "\nframes " +
                           std::to_string(frames) + "\n";
  write_file_atomically((folder / kObjMarker).string(), text);
}

class ObjFolderWriter : public FrameWriter {
 public:
  ObjFolderWriter(const std::string& folder, const OutputInfo& info)
      : folder_(obj_folder_path(folder)), temporary_(temporary_path(folder_)), F_(info.mesh.F) {
    digits_ = 4;
    for (int n = info.frames; n >= 10000; n /= 10) ++digits_;
    check_obj_folder_target(folder_, temporary_);
    std::error_code error;
    register_temporary(temporary_);
    created_ = true;
    fs::remove_all(temporary_, error);  // a stale temporary of amt's (checked above)
    AMT_CHECK(!error, temporary_, ": --out: expected to remove the stale temporary folder, found an error (",
              error.message(), ")");
    fs::create_directories(temporary_, error);
    AMT_CHECK(!error, folder_, ": output: expected a writable folder, found an error creating ", temporary_, " (",
              error.message(), ")");
    write_obj_marker(temporary_, 0);  // first, so that a killed run's temporary is recognised as amt's
  }
  ~ObjFolderWriter() override {
    if (created_ && !finished_) discard_temporary(temporary_);
  }
  void append(const MatrixX3f& V, const Transforms&) override {
    char name[32];
    std::snprintf(name, sizeof(name), "frame_%0*d.obj", digits_, frames_);
    write_obj((fs::path(temporary_) / name).string(), TriMesh{V, F_});
    ++frames_;
  }
  std::string finish() override {
    AMT_CHECK(frames_ > 0, folder_, ": frames: expected at least 1 frame, found none");
    write_obj_marker(temporary_, frames_);
    // Checked again: the target may have changed during the run.
    bool exists = false;
    const std::string target = foreign_obj_folder(folder_, exists);
    AMT_CHECK(target.empty(), folder_, ": --out: expected no file there or an OBJ folder amt wrote (with ", kObjMarker,
              "), found ", target, "; the output is not written");
    std::error_code error;
    if (exists) {
      // Swap the new folder and the old one in one step, then remove the old one (now the temporary).
      if (::renameat2(AT_FDCWD, temporary_.c_str(), AT_FDCWD, folder_.c_str(), RENAME_EXCHANGE) == 0) {
        fs::remove_all(temporary_, error);
        unregister_temporary(temporary_);
        finished_ = true;
        AMT_CHECK(!error, temporary_, ": output: expected to remove the replaced folder, found an error (",
                  error.message(), ")");
        return describe();
      }
      fs::remove_all(folder_, error);  // a file system without RENAME_EXCHANGE: remove, then rename
      AMT_CHECK(!error, folder_, ": output: expected to replace the old folder, found an error (", error.message(),
                ")");
    }
    error = rename_registered_temporary(temporary_, folder_);
    AMT_CHECK(!error, folder_, ": output: expected to rename ", temporary_, " onto it, found an error (",
              error.message(), ")");
    finished_ = true;
    return describe();
  }
  int num_frames() const override { return frames_; }

 private:
  std::string describe() const { return folder_ + "/ (" + std::to_string(frames_) + " OBJ files)"; }

  std::string folder_, temporary_;
  MatrixX3i F_;
  int digits_ = 4, frames_ = 0;
  bool created_ = false, finished_ = false;
};

// Checks a file output (.glb, .h5) and its temporaries: each is absent or a regular file.
void check_file_target(const std::string& path, const std::string& kind) {
  check_replaceable_file(path);
  prepare_temporary_file(temporary_path(path));
  if (kind == "glb") prepare_temporary_file(GlbStreamWriter::frames_temporary_path(path));
}

}  // namespace

std::string output_kind(const std::string& path) {
  AMT_CHECK(!path.empty(), "--out: expected an output path, found none");
  const std::string e = lower_extension(path);
  if (e == ".glb") return "glb";
  if (e == ".h5" || e == ".hdf5") return "h5";
  if (e == ".vrm") return "vrm";
  AMT_CHECK(e != ".gltf", path, ": --out: expected .glb (binary glTF), .h5 or a folder for OBJ files, found .gltf");
  AMT_CHECK(e != ".obj", path, ": --out: expected a folder for the OBJ sequence (frame_0000.obj, ...), found a .obj ",
            "file name");
  return "obj";
}

void check_output_writable(const std::string& path) {
  const std::string kind = output_kind(path);
  const std::string target = kind == "obj" ? obj_folder_path(path) : path;
  if (kind == "obj") {
    check_obj_folder_target(target, temporary_path(target));
  } else {
    check_file_target(path, kind);
  }
  try {
    create_parent_folder(target);
  } catch (const Error& e) {
    fail(path, ": --out: expected a writable location, found that its folder cannot be created (", e.what(), ")");
  }
  // A probe file beside the output (for an OBJ folder, inside its parent).
  const std::string probe = kind == "obj" ? target + ".probe" + kTemporarySuffix : temporary_path(path);
  prepare_temporary_file(probe);
  register_temporary(probe);
  std::FILE* f = std::fopen(probe.c_str(), "wb");
  if (f == nullptr) unregister_temporary(probe);
  AMT_CHECK(f != nullptr, path, ": --out: expected a writable location, found that ", probe, " cannot be created");
  std::fclose(f);
  discard_temporary(probe);
}

std::unique_ptr<FrameWriter> open_frame_writer(const std::string& path, const OutputInfo& info) {
  const std::string kind = output_kind(path);
  // What is at the output must be replaceable and its folder creatable before any frame is computed.
  const std::string target = kind == "obj" ? obj_folder_path(path) : path;
  if (kind != "obj") check_file_target(path, kind);  // an OBJ folder is checked by its writer
  try {
    create_parent_folder(target);
  } catch (const Error&) {
    fail(path, ": --out: expected a writable location, found that its folder cannot be created");
  }
  AMT_CHECK(kind != "vrm", path, ": --out: a .vrm keeps the avatar's own skeleton and is written by --apparel ",
            "spring-bones from a VRM avatar; use .glb");
  if (kind == "glb" && info.skin) return std::make_unique<SkinnedGlbWriter>(path, info);
  if (kind == "glb") return std::make_unique<GlbWriter>(path, info);
  if (kind == "h5") return std::make_unique<DatasetFrameWriter>(path, info);
  return std::make_unique<ObjFolderWriter>(path, info);
}

}  // namespace amt
