#include "data_tools/builder/dataset_preview.h"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/error.h"
#include "data_tools/formats/gltf_export.h"

namespace amt {

int export_dataset_preview(const std::string& dataset_path, const std::string& out_path,
                           const DatasetPreviewOptions& options) {
  std::string extension = std::filesystem::path(out_path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  AMT_CHECK(extension == ".glb" || extension == ".gltf", out_path, ": --out: expected a .glb or .gltf file, found ",
            extension.empty() ? std::string("no extension") : "extension '" + extension + "'");
  const DatasetReader reader(dataset_path);
  AMT_CHECK(!reader.clip_names().empty(), dataset_path, ": /clips: expected at least one clip to preview, found none");
  const std::string clip = options.clip.empty() ? reader.clip_names().front() : options.clip;
  AMT_CHECK(reader.has_clip(clip), dataset_path, ": /clips/", clip, ": missing (expected one of the file's ",
            reader.clip_names().size(), " clips, e.g. '", reader.clip_names().front(), "')");
  const ClipInfo info = reader.clip_info(clip);
  AMT_CHECK(options.first_frame >= 0 && options.first_frame < info.num_frames, dataset_path, ": /clips/", clip,
            ": first frame: expected a frame in [0, ", info.num_frames, "), found ", options.first_frame);
  const int available = info.num_frames - options.first_frame;
  const int count = options.max_frames > 0 ? std::min(options.max_frames, available) : available;

  const CharacterData character = reader.read_character(info.character);
  const int N = character.mesh.num_vertices();
  std::vector<MatrixX3f> frames;
  frames.reserve(static_cast<size_t>(count));
  constexpr int kChunk = 32;  // frames per read: bounded memory on the reading side
  for (int t = 0; t < count; t += kChunk) {
    const int n = std::min(kChunk, count - t);
    const MatrixX3f block = reader.read_vertices(clip, options.first_frame + t, n);
    for (int k = 0; k < n; ++k) frames.emplace_back(block.middleRows(static_cast<Eigen::Index>(k) * N, N));
  }
  GltfExportOptions export_options;
  export_options.name = info.character;
  export_options.clip = clip;
  export_options.apparel_mask = character.apparel_mask;  // the ground-truth mask, tinted (COLOR_0)
  export_gltf_mesh_sequence(out_path, character.mesh.F, frames, info.fps, export_options);
  return count;
}

}  // namespace amt
