#pragma once
// `amt dataset preview`: one clip of a dataset as an animated glTF to look at in any viewer.
#include <string>

namespace amt {

/// Options of a preview export.
struct DatasetPreviewOptions {
  std::string clip;      // clip name; empty: the first clip of the file
  int first_frame = 0;   // first frame exported
  int max_frames = 300;  // at most this many frames (0: all)
};

/// Reads the clip's ground-truth vertices frame by frame from `dataset_path` and writes them to
/// `out_path` (.glb or .gltf) as a mesh sequence at the clip's fps (data_tools/formats/gltf_export.h).
/// Returns the number of frames written. Throws amt::Error on a missing clip or bad frame range.
int export_dataset_preview(const std::string& dataset_path, const std::string& out_path,
                           const DatasetPreviewOptions& options = {});

}  // namespace amt
