#pragma once
// The web viewer's side in C++ (the page itself is the repository's viewer/: index.html, viewer.js and
// three.js from npm, installed by scripts/setup.sh). A viewer manifest says what the page plays
// ("viewer.json", format "amt-viewer", version 1: a title and groups of files, one group playing at a
// time, side by side); a viewer folder is a folder anyone can serve statically: the page, the three.js
// modules it imports, the manifest and the GLBs (`amt animate --html DIR`, `amt eval --viewer DIR`,
// opened with `amt view DIR`).
#include <string>
#include <utility>
#include <vector>

namespace amt {

// === The manifest

/// One file of a group. `file` is relative to the page (a GLB mesh sequence of data_tools/formats/gltf_export.h);
/// `role` is "prediction", "ground_truth" or "skinning" (the page compares every item to the group's
/// ground truth: PMD_a per frame); `label` is shown above it.
struct ViewerItem {
  std::string file, label, role;
};

/// Files played together, side by side in this order, on one clock.
struct ViewerGroup {
  std::string title;
  std::vector<ViewerItem> items;
};

/// What the page plays: `viewer.json`.
struct ViewerManifest {
  std::string title;
  std::vector<ViewerGroup> groups;
};

/// The manifest's file name in a viewer folder.
inline constexpr const char* kViewerManifestName = "viewer.json";

/// The manifest as JSON text: {"format": "amt-viewer", "version": 1, "title", "groups": [{"title", "items":
/// [{"file", "label", "role"}]}]}.
std::string viewer_manifest_json(const ViewerManifest& manifest);

// === The page

/// The files the page needs, as (path relative to the page, source file) pairs: index.html and viewer.js
/// from `viewer_dir` (the repository's viewer/), and the three.js modules it imports from
/// viewer_dir/node_modules/three, under "three/". Throws amt::Error naming the missing file and saying to
/// run scripts/setup.sh when three.js is not installed.
std::vector<std::pair<std::string, std::string>> viewer_page_files(const std::string& viewer_dir);

// === A viewer folder

/// Checks, before any work, that `dir` may become a viewer folder: it does not exist, is empty, or holds a
/// viewer.json of format "amt-viewer" (a folder amt wrote before, whose files are replaced); anything else
/// (a file, a folder of the user's) is refused with amt::Error naming it. With `to_write`, a symbolic link
/// anywhere inside it is refused too, naming it: a writer would follow it and replace a file elsewhere
/// (`amt view`, which only reads, passes false and refuses links when serving). Creates nothing.
void check_viewer_folder(const std::string& dir, bool to_write = true);

/// Writes the page (viewer_page_files) and the manifest into `dir` (created when missing), each file to a
/// temporary name and renamed. The GLBs are the caller's: written into `dir` before or after.
void write_viewer_folder(const std::string& dir, const std::string& viewer_dir, const ViewerManifest& manifest);

}  // namespace amt
