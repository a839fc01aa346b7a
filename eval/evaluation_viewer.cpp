#include "eval/evaluation_viewer.h"

#include <cctype>
#include <cstdio>
#include <filesystem>

#include "data_tools/geometry/error.h"
#include "data_tools/formats/gltf_export.h"
#include "data_tools/formats/viewer_folder.h"

namespace amt {

namespace {

// "held-out characters" -> "held_out_characters": file names of the GLBs.
std::string slug(const std::string& text) {
  std::string out;
  for (const char ch : text) out += std::isalnum(static_cast<unsigned char>(ch)) ? ch : '_';
  return out;
}

}  // namespace

EvaluationViewer write_evaluation_viewer(const ModelBundle& bundle, const EvaluationResult& result,
                                         const std::string& dir, const std::string& viewer_dir, int max_frames) {
  const std::vector<ViewerPick> picks = viewer_picks(result);
  AMT_CHECK(!picks.empty(), dir, ": viewer: expected clips scored by the full model to pick from, found none (run the "
            "method full)");
  ViewerManifest manifest;
  manifest.title = "amt eval: " + (result.model_dir.empty() ? std::string("model") : result.model_dir);
  for (const ViewerPick& p : picks) {
    const std::string stem = slug(p.score.subset) + "_" + p.pick;
    char title[256];
    std::snprintf(title, sizeof(title), "%s, %s clip: %s (%s), full model PMD_a %.2f cm (%s)", p.score.subset.c_str(),
                  p.pick.c_str(), p.score.clip.c_str(), p.score.character.c_str(), p.score.pmd_a,
                  p.score.protocol.c_str());
    manifest.groups.push_back({title,
                               {{stem + "_prediction.glb", "prediction (full model)", "prediction"},
                                {stem + "_ground_truth.glb", "ground truth", "ground_truth"},
                                {stem + "_skinning.glb", "skinning (ground-truth weights)", "skinning"}}});
  }
  write_viewer_folder(dir, viewer_dir, manifest);  // first: it marks the folder as amt's
  for (size_t k = 0; k < picks.size(); ++k) {
    const ViewedClip clip = view_clip(bundle, result, picks[k], max_frames);
    GltfExportOptions options;
    options.apparel_mask = clip.mask;
    options.name = picks[k].score.character;
    options.clip = picks[k].score.clip;
    const auto& items = manifest.groups[k].items;
    const auto path = [&](size_t i) { return (std::filesystem::path(dir) / items[i].file).string(); };
    export_gltf_mesh_sequence(path(0), clip.F, clip.prediction, clip.fps, options);
    export_gltf_mesh_sequence(path(1), clip.F, clip.ground_truth, clip.fps, options);
    export_gltf_mesh_sequence(path(2), clip.F, clip.skinning, clip.fps, options);
  }
  return {dir, int(picks.size())};
}

}  // namespace amt
