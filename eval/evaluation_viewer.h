#pragma once
// `amt eval --viewer DIR`: the clips behind an evaluation's numbers, to watch. For each subset the
// worst, median and best clip by the full model's PMD_a (eval/evaluate.h viewer_picks), each as three
// GLBs played side by side by the web viewer (data_tools/formats/viewer_folder.h): the prediction, the ground
// truth and the skinning baseline, all tinted with the ground-truth apparel mask (COLOR_0).
#include <string>

#include "eval/evaluate.h"

namespace amt {

/// What write_evaluation_viewer wrote: the folder and the number of clips (groups) in it.
struct EvaluationViewer {
  std::string dir;
  int clips = 0;
};

/// Writes the viewer folder `dir` (check_viewer_folder rules) from `result`, running `bundle` again on
/// the picked clips (their first `max_frames` frames; 0: all). `viewer_dir` is the repository's
/// viewer/. Throws amt::Error when the full model was not evaluated (nothing to pick by).
EvaluationViewer write_evaluation_viewer(const ModelBundle& bundle, const EvaluationResult& result,
                                         const std::string& dir, const std::string& viewer_dir, int max_frames);

}  // namespace amt
