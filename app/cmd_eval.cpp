// `amt eval`: scores a trained model (or a file of predictions) on a dataset's held-out characters
// and clips and writes <out>/report.md, <out>/metrics.json and PNG plots (eval/evaluate.h,
// eval/report.h).
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <algorithm>

#include "amt/version.h"
#include "app/commands.h"
#include "app/repository.h"
#include "data_tools/formats/viewer_folder.h"
#include "data_tools/geometry/error.h"
#include "eval/evaluate.h"
#include "eval/evaluation_viewer.h"
#include "eval/report.h"
#include "infer/runtime_benchmark_torch.h"
#include "train/samples.h"

namespace amt::app {
namespace {

struct EvalCommand {
  std::vector<std::string> data;
  std::string model;  // empty: the repository's models/pretrained (app/repository.h)
  std::string out;
  std::string protocol = "both";
  std::string predictions;
  std::string viewer;  // empty: no viewer folder
  int viewer_frames = 120;
  EvaluateOptions options;
  bool no_plots = false, quiet = false;
  bool runtime = false;  // also measure the runtime (measure_runtime) for the report
  int runtime_repeats = 30;
  std::string command_line;
};

void print_summary(const EvaluationResult& result, const ReportFiles& files) {
  for (const MethodScores& r : result.rows) {
    if (r.method != "full" && r.method != "skinning_baseline" && r.method != "predictions" &&
        r.method != "cloth_retarget" && r.method != "cloth_retarget_unresolved")
      continue;
    std::cout << r.subset << ", " << r.protocol << ", " << method_label(r.method) << ": PMD " << r.scores.pmd
              << " cm, PMD_a " << r.scores.pmd_a << " cm, PMD_b " << r.scores.pmd_b << " cm, ELS " << r.scores.els
              << ", penetration " << 100.0 * r.scores.penetration_share << " %, tearing "
              << 100.0 * r.separation.tearing << " % (against rest lengths " << 100.0 * r.separation.rest_tearing
              << " %, the ground truth's " << 100.0 * r.separation.ground_truth_rest_tearing
              << " %; torn where the ground truth deforms " << 100.0 * r.separation.tearing_ground_truth_deformed
              << " %), seam gap p95 " << r.separation.seam_gap_p95_cm << " cm (worst " << r.worst.seam_gap_p95_cm
              << " cm, " << (r.worst_seam_gap_p95.empty() ? "-" : r.worst_seam_gap_p95) << "), ELS_a "
              << r.separation.apparel_els << "\n";
  }
  std::cout << "wrote " << files.markdown << ", " << files.json;
  for (const std::string& p : files.plots) std::cout << ", " << p;
  std::cout << std::endl;
}

// The runtime figures of the report (--runtime): the stand-in for a real model of issue 17 (about 14.5k
// vertices of open, overlapping parts, the segmenter's mask; targets 16 ms per frame on 2 threads and a
// 5 s bind) and the 20k-vertex dressed character of issue 18 (the dressed mask; 12 ms on 2 threads, the
// apparel network at most 1.5x the global form's cost).
std::vector<RuntimeFigures> eval_runtime(const ModelBundle& bundle, int repeats, bool quiet) {
  std::vector<RuntimeFigures> figures;
  RuntimeBenchmarkOptions real;
  real.vertices = 14500;
  real.open_parts = true;
  real.segmenter_mask = true;
  real.repeats = repeats;
  if (!quiet)
    std::cerr << "eval: runtime on a real-mesh stand-in (" << real.vertices << " vertices, open parts)" << std::endl;
  figures.push_back(measure_runtime(bundle, real, "real-mesh stand-in, segmenter mask"));
  figures.back().target_ms = 16, figures.back().target_bind_seconds = 5;
  RuntimeBenchmarkOptions dressed;
  dressed.vertices = 20000;
  dressed.repeats = repeats;
  dressed.reference_apparel = true;
  if (!quiet) std::cerr << "eval: runtime on a dressed character (" << dressed.vertices << " vertices)" << std::endl;
  figures.push_back(measure_runtime(bundle, dressed, "20k-vertex dressed character, dressed mask"));
  figures.back().target_ms = 12;
  // At most 1.5x the cost of the global apparel form this module replaced, timed beside it (issue 18). That
  // form measured 3.4x LBS on one thread, a ratio LBS's 0.5-0.7 ms made too noisy to hold a target to.
  figures.back().target_apparel_reference_ratio = 1.5;
  return figures;
}

void run(const EvalCommand& command) {
  // The output and viewer folders are checked before the evaluation, which can take hours.
  check_report_folder(command.out);
  std::string viewer_dir;
  if (!command.viewer.empty()) {
    AMT_CHECK(command.predictions.empty(),
              "--viewer: expected a model to run on the picked clips, found --predictions");
    const auto& methods = command.options.methods;
    AMT_CHECK(methods.empty() || std::find(methods.begin(), methods.end(), "full") != methods.end(),
              "--viewer: expected the method full among --methods (the clips are picked by its PMD_a)");
    viewer_dir = find_repository_folder("viewer");
    AMT_CHECK(!viewer_dir.empty(),
              "--viewer: expected the repository's viewer/ folder above the amt program or in the "
              "current folder, found none: run amt from a checkout");
    viewer_page_files(viewer_dir);
    check_viewer_folder(command.viewer);
  }
  AMT_CHECK(!command.options.artist_style || command.predictions.empty(),
            "--artist-style: expected a model to run on the remade characters, found --predictions (a file of "
            "predictions is of the characters as built)");
  AMT_CHECK(!command.runtime || command.predictions.empty(),
            "--runtime: expected a model to time, found --predictions (a file of predictions has no runtime)");
  EvaluateOptions options = command.options;
  options.paper = command.protocol == "paper" || command.protocol == "both";
  options.rollout = command.protocol == "rollout" || command.protocol == "both";
  options.progress = !command.quiet;
  const std::vector<std::string> shards = resolve_shards(command.data);
  EvaluationResult result;
  ReportOptions report;
  report.out_dir = command.out;
  report.command = command.command_line;
  report.plots = !command.no_plots;
  if (!command.predictions.empty()) {
    result = evaluate_predictions(shards, command.predictions, options);
  } else {
    const std::string model = !command.model.empty()
                                  ? command.model
                                  : repository_default("models/pretrained", "--model", "FOLDER (trained model)");
    const ModelBundle bundle = load_model_bundle(model);
    report.model_dir = model;
    result = evaluate_model(bundle, shards, options);
    if (command.runtime) {
      result.runtime = eval_runtime(bundle, command.runtime_repeats, command.quiet);
      for (const RuntimeFigures& r : result.runtime)
        for (const RuntimeThreadFigures& t : r.per_thread)
          std::cout << "runtime, " << r.label << " (" << r.vertices << " vertices, " << r.apparel_vertices
                    << " apparel): " << t.threads << " thread" << (t.threads > 1 ? "s" : "") << " " << t.median_ms
                    << " ms per frame (apparel network " << t.apparel_ms << " ms), bind " << r.bind_seconds << " s\n";
    }
    print_summary(result, write_report(result, report));
    if (!command.viewer.empty()) {
      const EvaluationViewer viewer =
          write_evaluation_viewer(bundle, result, command.viewer, viewer_dir, command.viewer_frames);
      std::cout << "wrote the viewer folder " << viewer.dir << " (" << viewer.clips
                << " clips: prediction, ground truth and skinning): open it with amt view " << viewer.dir << std::endl;
    }
    return;
  }
  print_summary(result, write_report(result, report));
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto* eval = app.add_subcommand(
      "eval",
      "PMD / ELS / penetration tables (paper Tables 2-4) on held-out characters and clips: report.md, "
      "metrics.json, PNG plots");
  auto command = std::make_shared<EvalCommand>();
  EvaluateOptions& o = command->options;
  eval->add_option("--data", command->data, "Dataset shards: *.h5 files or folders of them")->required();
  eval->add_option(
          "--model", command->model,
          "Model folder with segmenter/skinning/apparel/refiner.ckpt. " + repository_default_help("models/pretrained"))
      ->capture_default_str();
  eval->add_option("--out", command->out, "Output folder for report.md, metrics.json and the plots")->required();
  eval->add_option("--protocol", command->protocol,
                   "paper (10-frame windows, 3 ground-truth states), rollout (whole clip from the rest pose), or both")
      ->check(CLI::IsMember({"paper", "rollout", "both"}))
      ->capture_default_str();
  eval->add_option("--max-clips", o.max_clips, "Evaluate at most N clips per subset (0: all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  eval->add_option("--methods", o.methods,
                   "Methods to run (default: all the model supports): skinning_baseline, lbs_predicted, "
                   "body_apparel, full, full_gt_mask, no_geodesic, sort_by_geodesic; cloth_retarget and "
                   "cloth_retarget_unresolved on the clips of garment pairs (amt dataset pairs)");
  eval->add_option("--predictions", command->predictions,
                   "Score a dataset file of predicted vertices (amt animate --out x.h5) instead of running a model");
  eval->add_flag("--ground-truth-as-predictions", o.ground_truth_as_predictions,
                 "With --predictions: also score a ground-truth dataset file (e.g. one rebuilt with other physics, "
                 "against the original); without it such a file is refused, as it would score perfect");
  eval->add_option("--viewer", command->viewer,
                   "Also write a viewer folder: the worst, median and best clip of each subset by the full model's "
                   "PMD_a, prediction beside ground truth and skinning (open it with amt view DIR)");
  eval->add_option("--viewer-frames", command->viewer_frames, "Frames per clip in the viewer folder (0: all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  eval->add_flag(
      "--no-penetration", [command](int64_t) { command->options.penetration = false; },
      "Skip the penetration measure (a winding-number tree per frame)");
  eval->add_flag(
      "--runtime", command->runtime,
      "Also measure the per-frame runtime (as amt bench --suite runtime) on a real-mesh stand-in (14.5k "
      "vertices of open parts, the segmenter's mask) and a 20k-vertex dressed character, on 1 and 2 threads, "
      "for the report's Runtime section and targets");
  eval->add_option("--runtime-repeats", command->runtime_repeats, "Timed frames per runtime figure")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  eval->add_flag("--artist-style", o.artist_style,
                 "Evaluate the held-out characters remade as artists build models (UV seams with coincident copies, "
                 "hair strips, double-sided and layered panels; data_tools/builder/artist_style.h), ground truth "
                 "remade with them, as the subset 'held-out characters, artist-style'");
  o.artist_style_options.target_vertices = 20000;
  eval->add_option("--artist-style-vertices", o.artist_style_options.target_vertices,
                   "Vertices the artist-style remake is subdivided to (0: no subdivision; else >= 1000)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  eval->add_option("--artist-style-seed", o.artist_style_options.seed, "Seed of the artist-style remake")
      ->capture_default_str();
  eval->add_flag("--rig-handles", o.rig_handles,
                 "On characters whose rig has apparel bones, the methods on the ground-truth mask move the apparel "
                 "module's handles at the rig's own bones instead of handles picked automatically");
  eval->add_option("--strain-limit", o.strain_limit,
                   "Largest stretch of an apparel edge over its rest length that the learned apparel's output is "
                   "limited to, each edge also at least " +
                       strain_floor_text() + " times its rest length (0: off, the apparel module's raw output)")
      ->check(CLI::Number & (CLI::IsMember({0.0f}) | CLI::Range(1.01f, 100.0f)))
      ->capture_default_str();
  eval->add_option_function<std::string>(
          "--swing-calibration",
          [&o](const std::string& value) {
            o.calibrate_swing = value != "off";
            o.fit_swing = value == "on";
          },
          "Scale the learned apparel's swing, per piece, to the character's own physics: on (fitted on another "
          "clip of the character, else from its rig's physics response), probe (from the response only) or off "
          "(the apparel module as trained)")
      ->check(CLI::IsMember({"on", "probe", "off"}))
      ->default_str("on");
  eval->add_flag("--no-plots", command->no_plots, "Do not run gnuplot");
  eval->add_flag("--quiet", command->quiet, "No progress line");
  add_threads_option(*eval);
  eval->callback([command] {
    std::string line = "amt eval --data";
    for (const std::string& d : command->data) line += " " + d;
    if (command->predictions.empty() && !command->model.empty())
      line += " --model " + command->model;
    else
      line += " --predictions " + command->predictions;
    line += " --out " + command->out + " --protocol " + command->protocol;
    if (command->options.max_clips > 0) line += " --max-clips " + std::to_string(command->options.max_clips);
    if (command->runtime) line += " --runtime";
    if (command->options.artist_style)
      line += " --artist-style --artist-style-vertices " +
              std::to_string(command->options.artist_style_options.target_vertices);
    command->command_line = line;
    run(*command);
  });
}

}  // namespace amt::app
