#include "data_tools/formats/viewer_folder.h"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <system_error>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/geometry/error.h"
#include "data_tools/formats/input_file.h"

namespace amt {

namespace fs = std::filesystem;

std::string viewer_manifest_json(const ViewerManifest& manifest) {
  nlohmann::json groups = nlohmann::json::array();
  for (const ViewerGroup& group : manifest.groups) {
    nlohmann::json items = nlohmann::json::array();
    for (const ViewerItem& item : group.items)
      items.push_back({{"file", item.file}, {"label", item.label}, {"role", item.role}});
    groups.push_back({{"title", group.title}, {"items", items}});
  }
  const nlohmann::json json = {{"format", "amt-viewer"}, {"version", 1}, {"title", manifest.title}, {"groups", groups}};
  return json.dump(1) + "\n";
}

std::vector<std::pair<std::string, std::string>> viewer_page_files(const std::string& viewer_dir) {
  // The page and what its import map reaches: three.js's module build and the three add-ons viewer.js
  // imports, with those add-ons' own imports (GLTFLoader uses BufferGeometryUtils and SkeletonUtils).
  static const char* const kPage[] = {"index.html", "viewer.js"};
  static const char* const kThree[] = {"LICENSE",
                                       "build/three.module.js",
                                       "build/three.core.js",
                                       "examples/jsm/loaders/GLTFLoader.js",
                                       "examples/jsm/controls/OrbitControls.js",
                                       "examples/jsm/utils/BufferGeometryUtils.js",
                                       "examples/jsm/utils/SkeletonUtils.js"};
  std::vector<std::pair<std::string, std::string>> files;
  std::error_code error;
  for (const char* name : kPage) {
    const fs::path source = fs::path(viewer_dir) / name;
    AMT_CHECK(fs::is_regular_file(source, error), source.string(), ": expected the viewer page, found none");
    files.emplace_back(name, source.string());
  }
  for (const char* name : kThree) {
    const fs::path source = fs::path(viewer_dir) / "node_modules" / "three" / name;
    AMT_CHECK(fs::is_regular_file(source, error), source.string(),
              ": expected three.js installed for the viewer, found none: run scripts/setup.sh (it runs `npm ci` in ",
              viewer_dir, ")");
    files.emplace_back(std::string("three/") + name, source.string());
  }
  return files;
}

void check_viewer_folder(const std::string& dir, bool to_write) {
  std::error_code error;
  const fs::file_status status = fs::symlink_status(dir, error);
  if (!fs::exists(status)) return;
  AMT_CHECK(fs::is_directory(status), dir, ": expected a folder for the viewer (absent, empty, or written by amt), found ",
            describe_file_type(status.type()));
  if (fs::is_empty(dir, error) && !error) return;
  const fs::path manifest = fs::path(dir) / kViewerManifestName;
  std::string format;
  if (fs::is_regular_file(fs::symlink_status(manifest, error))) {
    std::ifstream in(manifest);
    try {
      format = nlohmann::json::parse(in).value("format", "");
    } catch (const nlohmann::json::exception&) {
      format.clear();
    }
  }
  AMT_CHECK(format == "amt-viewer", dir, ": expected an empty folder or a viewer folder amt wrote (", kViewerManifestName,
            " of format amt-viewer), found other files: name a new folder");
  if (!to_write) return;
  // recursive_directory_iterator does not follow links: each is seen as the link it is.
  for (fs::recursive_directory_iterator it(dir, error), end; !error && it != end; it.increment(error)) {
    AMT_CHECK(!it->is_symlink(error), it->path().string(),
              ": a symbolic link inside the viewer folder: amt never writes through one (it would replace the file "
              "it points to); remove it or name a new folder");
  }
}

void write_viewer_folder(const std::string& dir, const std::string& viewer_dir, const ViewerManifest& manifest) {
  const auto files = viewer_page_files(viewer_dir);
  check_viewer_folder(dir);
  // The manifest first: it marks the folder as amt's, so a run interrupted while writing the rest (or
  // the GLBs after it) is replaced by the next run instead of refused.
  write_file_atomically((fs::path(dir) / kViewerManifestName).string(), viewer_manifest_json(manifest));
  for (const auto& [relative, source] : files) {
    check_input_file(source, "a file of the viewer page");
    std::ifstream in(source, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    AMT_CHECK(in.good() || in.eof(), source, ": read: expected the file's bytes, found an error");
    write_file_atomically((fs::path(dir) / relative).string(), bytes.str());
  }
}

}  // namespace amt
