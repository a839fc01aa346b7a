#include "eval/report.h"

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include <nlohmann/json.hpp>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/temporary_registry.h"
#include "data_tools/geometry/error.h"

extern char** environ;

namespace amt {
namespace {

namespace fs = std::filesystem;

// === Formatting

std::string fixed(double v, int digits) {
  if (!std::isfinite(v)) return "–";
  std::ostringstream out;
  out << std::fixed << std::setprecision(digits) << v;
  return out.str();
}

std::string percent(double v) {
  return std::isfinite(v) ? fixed(100.0 * v, 1) + " %" : "–";
}

const char* protocol_text(const std::string& protocol) {
  if (protocol == "paper")
    return "paper protocol (10-frame windows, 3 ground-truth apparel states, 7 predicted frames)";
  if (protocol == "rollout") return "rollout protocol (whole clip from the rest pose)";
  return "predictions file (every frame)";
}

std::string score_header() {
  return "| Subset | Method | PMD (cm) | PMD_a (cm) | PMD_b (cm) | ELS | Amplitude | Penetration | Depth (cm) | Clips "
         "/ "
         "frames |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
}

std::string score_row(const MethodScores& r) {
  const MotionScores& s = r.scores;
  std::ostringstream out;
  out << "| " << r.subset << " | " << method_label(r.method) << " | " << fixed(s.pmd, 2) << " | " << fixed(s.pmd_a, 2)
      << " | " << fixed(s.pmd_b, 2) << " | " << fixed(s.els, 3) << " | " << fixed(r.amplitude, 2) << " | "
      << percent(s.penetration_share) << " | " << fixed(s.penetration_depth_cm, 2) << " | " << s.clips << " / "
      << s.frames << " |\n";
  return out.str();
}

std::vector<std::string> subsets_of(const EvaluationResult& result) {
  std::vector<std::string> subsets;
  for (const char* s : {kHeldOutCharacters, kHeldOutArtistStyle, kHeldOutClips})
    if (result.clips.count(s)) subsets.push_back(s);
  return subsets;
}

std::vector<std::string> protocols_of(const EvaluationResult& result) {
  std::vector<std::string> protocols;
  for (const char* p : {"paper", "rollout", "file"}) {
    for (const MethodScores& r : result.rows)
      if (r.protocol == p) {
        protocols.push_back(p);
        break;
      }
  }
  return protocols;
}

// One analogue table: for each protocol, the rows of `methods` on every subset.
void write_table(std::ostringstream& md, const EvaluationResult& result, const std::string& title,
                 const std::string& intro, const std::vector<std::string>& methods) {
  md << "## " << title << "\n\n" << intro << "\n\n";
  bool any = false;
  for (const std::string& protocol : protocols_of(result)) {
    std::string rows;
    for (const std::string& subset : subsets_of(result))
      for (const std::string& m : methods)
        if (const MethodScores* r = result.find(m, protocol, subset)) rows += score_row(*r);
    if (rows.empty()) continue;
    any = true;
    md << "**" << protocol_text(protocol) << "**\n\n" << score_header() << rows << "\n";
  }
  if (!any) md << "Not evaluated (no method of this table ran).\n\n";
}

// === Falling apart

std::string worst_cell(double value, int digits, const std::string& character) {
  return std::isfinite(value) ? fixed(value, digits) + " (" + character + ")" : std::string("–");
}

// Tearing, seam gap and apparel ELS per row (mean over characters and the worst character), per character, and
// how the evaluated meshes are built.
void write_falling_apart(std::ostringstream& md, const EvaluationResult& result) {
  if (result.rows.empty()) return;
  md << "## Falling apart\n\nTearing: share of apparel edge-frames (edges with an apparel vertex) whose predicted "
        "length is off the ground truth's by more than 50 %. Seam gap: over the pairs of boundary vertices that "
        "coincide at rest (within 0.1 mm: a seam's duplicated vertices), their distance apart in the prediction "
        "beyond the ground truth's, 95th percentile and largest over pairs and frames, cm (– without such pairs). "
        "ELS_a: ELS over apparel edges. Each is the mean over the subset's "
        "characters, with the worst character beside it. Against rest lengths instead of the ground truth's: "
        "torn where GT deforms = the edge-frames torn whose ground-truth length is itself off its rest length by "
        "more than 50 % (a prediction that keeps such an edge near rest counts as torn); own stretch = the "
        "prediction's edges off their rest length by more than 50 %, whatever the ground truth does; GT's = the "
        "same share of the ground truth.\n\n"
        "| Subset | Protocol | Method | Tearing | worst | Torn where GT deforms | Own stretch | GT's | Seam gap p95 "
        "(cm) | worst | Seam gap max (cm), worst | ELS_a | worst | ELS |\n"
        "|---|---|---|---:|---|---:|---:|---:|---:|---|---|---:|---|---:|\n";
  for (const std::string& subset : subsets_of(result))
    for (const std::string& protocol : protocols_of(result))
      for (const MethodScores& r : result.rows) {
        if (r.subset != subset || r.protocol != protocol) continue;
        md << "| " << subset << " | " << protocol << " | " << method_label(r.method) << " | "
           << percent(r.separation.tearing) << " | "
           << (std::isfinite(r.worst.tearing) ? percent(r.worst.tearing) + " (" + r.worst_tearing + ")"
                                              : std::string("–"))
           << " | " << percent(r.separation.tearing_ground_truth_deformed) << " | "
           << percent(r.separation.rest_tearing) << " | " << percent(r.separation.ground_truth_rest_tearing) << " | "
           << fixed(r.separation.seam_gap_p95_cm, 3) << " | "
           << worst_cell(r.worst.seam_gap_p95_cm, 3, r.worst_seam_gap_p95) << " | "
           << worst_cell(r.worst.seam_gap_max_cm, 3, r.worst_seam_gap_max) << " | "
           << fixed(r.separation.apparel_els, 3) << " | " << worst_cell(r.worst.apparel_els, 3, r.worst_apparel_els)
           << " | " << fixed(r.scores.els, 3) << " |\n";
      }
  md << "\n";
  if (result.characters.empty()) return;
  md << "### Per character\n\nHow each evaluated mesh is built (connected parts, parts once coincident vertices are "
        "welded, share of vertices with a coincident copy) and, for the skinning baseline and the "
     << (result.predictions.empty() ? "full model" : "predictions") << ", its measures of falling apart.\n\n"
     << "| Character | Subset | Vertices | Parts | Welded parts | Coincident | Protocol | Method | Tearing | Own "
        "stretch | GT's | Seam gap p95 (cm) | Seam gap max (cm) | ELS_a |\n"
        "|---|---|---:|---:|---:|---:|---|---|---:|---:|---:|---:|---:|---:|\n";
  for (const CharacterScores& c : result.characters)
    for (const std::string& method :
         {std::string("skinning_baseline"), std::string("full"), std::string("predictions")}) {
      const auto m = c.separation.find(method);
      if (m == c.separation.end()) continue;
      for (const auto& [protocol, s] : m->second)
        md << "| " << c.character << " | " << c.subset << " | " << c.construction.vertices << " | "
           << c.construction.parts << " | " << c.construction.welded_parts << " | "
           << percent(c.construction.coincident_share) << " | " << protocol << " | " << method_label(method) << " | "
           << percent(s.tearing) << " | " << percent(s.rest_tearing) << " | " << percent(s.ground_truth_rest_tearing)
           << " | " << fixed(s.seam_gap_p95_cm, 3) << " | " << fixed(s.seam_gap_max_cm, 3) << " | "
           << fixed(s.apparel_els, 3) << " |\n";
    }
  md << "\n";
}

// === CSV

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream in(line);
  std::string cell;
  while (std::getline(in, cell, ',')) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

// === Plots

// Writes `script` to <dir>/<name>.gp, runs gnuplot on it (which writes <png>.tmp) and renames the PNG.
bool draw(const std::string& dir, const std::string& name, const std::string& script_body, ReportFiles& files) {
  const std::string terminal = gnuplot_png_terminal();
  if (terminal.empty()) {
    files.notes.push_back("gnuplot with a PNG terminal was not found: " + name + ".png was not drawn.");
    return false;
  }
  const std::string png = (fs::path(dir) / (name + ".png")).string();
  const std::string tmp = temporary_path(png);
  const std::string script_path = (fs::path(dir) / (name + ".gp")).string();
  std::ostringstream script;
  script << "set terminal " << terminal << " size 900,540\n"
         << "set output '" << tmp << "'\n"
         << script_body << "unset output\n";
  write_file_atomically(script_path, script.str());
  register_temporary(tmp);
  const bool ok = run_gnuplot(script_path);
  std::error_code ignored;
  if (!ok || !fs::exists(tmp, ignored)) {
    discard_temporary(tmp);
    files.notes.push_back("gnuplot failed on " + script_path + ": " + name + ".png was not drawn.");
    return false;
  }
  replace_with_temporary(tmp, png);
  files.plots.push_back(name + ".png");
  return true;
}

void plot_loss_curves(const ReportOptions& options, ReportFiles& files) {
  const std::vector<TrainingLog> logs = read_training_logs(options.model_dir);
  if (logs.empty()) {
    files.notes.push_back("No training logs (*.csv with step, loss columns) in " +
                          (options.model_dir.empty() ? std::string("the model folder") : options.model_dir) +
                          ": no loss curves.");
    return;
  }
  for (const TrainingLog& log : logs) {
    const int step = log.column("step"), loss = log.column("loss"), val = log.column("val_loss");
    std::ostringstream data;
    data << "# step loss val_loss\n";
    for (const auto& row : log.rows) {
      const auto at = [&](int c) { return c >= 0 && c < static_cast<int>(row.size()) ? row[c] : std::nan(""); };
      const double v = at(val);
      data << at(step) << " " << at(loss) << " " << (std::isfinite(v) ? std::to_string(v) : std::string("NaN")) << "\n";
    }
    const std::string data_path = (fs::path(options.out_dir) / ("loss_" + log.name + ".dat")).string();
    write_file_atomically(data_path, data.str());
    std::ostringstream body;
    body << "set title 'Training loss: " << log.name << "'\nset xlabel 'step'\nset ylabel 'loss'\nset logscale y\n"
         << "set grid\nset key top right\nset datafile missing 'NaN'\n"
         << "plot '" << data_path << "' using 1:2 with lines lw 1 title 'loss'";
    if (val >= 0) body << ", '" << data_path << "' using 1:3 with linespoints pt 7 ps 0.6 title 'val_loss'";
    body << "\n";
    draw(options.out_dir, "loss_" + log.name, body.str(), files);
  }
}

void plot_rollout(const EvaluationResult& result, const ReportOptions& options, ReportFiles& files) {
  std::vector<const RolloutCurve*> curves;
  for (const RolloutCurve& c : result.curves)
    if (c.method == "full" || c.method == "skinning_baseline" || c.method == "hold_offset" ||
        c.method == "apparel_gt" || c.method == "body_apparel" || c.method == "predictions")
      curves.push_back(&c);
  if (curves.empty()) {
    files.notes.push_back("No rollout was evaluated: no PMD_a-over-frames plot.");
    return;
  }
  std::ostringstream body;
  body << "set title 'PMD_a over rollout frames'\nset xlabel 'frame'\nset ylabel 'PMD_a (cm)'\nset grid\n"
       << "set key top left\nset datafile missing 'NaN'\nplot ";
  for (size_t i = 0; i < curves.size(); ++i) {
    std::ostringstream data;
    for (size_t k = 0; k < curves[i]->pmd_a.size(); ++k) {
      const double v = curves[i]->pmd_a[k];
      data << k + 1 << " " << (std::isfinite(v) ? std::to_string(v) : std::string("NaN")) << "\n";
    }
    const std::string data_path = (fs::path(options.out_dir) / ("rollout_" + std::to_string(i) + ".dat")).string();
    write_file_atomically(data_path, data.str());
    std::string label = method_label(curves[i]->method);  // '_' would be a subscript in gnuplot's enhanced text
    std::replace(label.begin(), label.end(), '_', ' ');
    body << (i ? ", " : "") << "'" << data_path << "' using 1:2 with lines lw 2 title '" << label << ", "
         << curves[i]->subset << "'";
  }
  body << "\n";
  draw(options.out_dir, "rollout_pmd_a", body.str(), files);
}

}  // namespace

// === Training logs

int TrainingLog::column(const std::string& name) const {
  const auto it = std::find(columns.begin(), columns.end(), name);
  return it == columns.end() ? -1 : static_cast<int>(it - columns.begin());
}

std::vector<TrainingLog> read_training_logs(const std::string& dir) {
  std::vector<TrainingLog> logs;
  std::error_code error;
  if (dir.empty() || !fs::is_directory(dir, error)) return logs;
  std::vector<fs::path> paths;
  for (const auto& entry : fs::directory_iterator(dir, error))
    if (entry.is_regular_file() && entry.path().extension() == ".csv") paths.push_back(entry.path());
  std::sort(paths.begin(), paths.end());
  for (const fs::path& path : paths) {
    std::ifstream in(path);
    std::string line;
    if (!std::getline(in, line)) continue;
    TrainingLog log;
    log.name = path.stem().string();
    log.columns = split_csv(line);
    if (log.columns.size() < 2 || log.columns[0] != "step" || log.columns[1] != "loss") continue;
    while (std::getline(in, line)) {
      if (line.empty()) continue;
      std::vector<double> row;
      for (const std::string& cell : split_csv(line)) {
        char* end = nullptr;
        const double v = std::strtod(cell.c_str(), &end);
        row.push_back(cell.empty() || end == cell.c_str() ? std::nan("") : v);
      }
      log.rows.push_back(std::move(row));
    }
    logs.push_back(std::move(log));
  }
  return logs;
}

// === gnuplot

std::string gnuplot_png_terminal() {
  static const std::string terminal = [] {
    FILE* pipe = popen("gnuplot -e 'set terminal' 2>&1 </dev/null", "r");
    if (!pipe) return std::string();
    std::string text;
    char buffer[4096];
    while (size_t n = fread(buffer, 1, sizeof buffer, pipe)) text.append(buffer, n);
    if (pclose(pipe) != 0) return std::string();
    std::istringstream lines(text);
    std::string line, found;
    while (std::getline(lines, line)) {
      std::istringstream words(line);
      std::string word;
      words >> word;
      if (word == "pngcairo") return std::string("pngcairo");
      if (word == "png") found = "png";
    }
    return found;
  }();
  return terminal;
}

bool run_gnuplot(const std::string& script) {
  pid_t pid = 0;
  std::string program = "gnuplot", argument = script;
  char* argv[] = {program.data(), argument.data(), nullptr};
  // gnuplot gets an empty signal mask: amt blocks SIGINT and SIGTERM in its threads (app/main.cpp).
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attributes, &none);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK);
  const int spawned = posix_spawnp(&pid, "gnuplot", nullptr, &attributes, argv, environ);
  posix_spawnattr_destroy(&attributes);
  if (spawned != 0) return false;
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return false;
  }
  return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

// === Report

std::string report_markdown(const EvaluationResult& result, const ReportOptions& options,
                            const std::vector<std::string>& plots, const std::vector<std::string>& plot_notes) {
  std::ostringstream md;
  md << "# amt evaluation report\n\n";
  if (!options.command.empty()) md << "Command: `" << options.command << "`\n\n";
  md << "- Data: ";
  for (size_t i = 0; i < result.shards.size(); ++i) md << (i ? ", " : "") << "`" << result.shards[i] << "`";
  md << "\n";
  if (!result.model_dir.empty()) md << "- Model: `" << result.model_dir << "`\n";
  if (!result.predictions.empty()) md << "- Predictions: `" << result.predictions << "`\n";
  for (const auto& [subset, n] : result.clips) md << "- " << subset << ": " << n << " clip(s)\n";
  md << "- Apparel stretch limit: "
     << (result.options.strain_limit > 0 ? "every apparel mesh edge between " + fixed(kDefaultStrainFloor, 2) +
                                               " and " + fixed(result.options.strain_limit, 2) +
                                               " times its rest length in the methods that run the apparel module "
                                               "(`--strain-limit`)"
                                         : std::string("off (`--strain-limit 0`): the apparel module's raw output"))
     << "\n";
  md << "- Apparel swing: "
     << (!result.options.calibrate_swing ? std::string("the apparel module as trained (`--swing-calibration off`)")
         : result.options.fit_swing
             ? std::string("fitted per apparel piece on other clips of each character's own physics, else "
                           "calibrated on its rig's response (`--swing-calibration on`; notes below)")
             : std::string("calibrated on each character's own physics where its rig carries a response and the "
                           "apparel module knows its training data's least lively apparel (`--swing-calibration "
                           "probe`)"))
     << "\n";
  md << "- Wall time: " << fixed(result.seconds, 1) << " s\n\n";
  md << "Metrics: PMD, PMD_a (ground-truth apparel vertices), PMD_b (body vertices) in cm, "
        "averaged over vertices, then frames, then clips; ELS = mean of 1 - | |e_pred| / |e_gt| - 1 | over edges "
        "(1 is perfect); penetration = share of ground-truth apparel vertices inside the predicted body surface "
        "(winding number) and their mean depth. Falling apart (below): tearing, seam gap and ELS over apparel "
        "edges.\n\n";
  if (result.options.artist_style) {
    const ArtistStyleOptions& a = result.options.artist_style_options;
    md << "Subset **" << kHeldOutArtistStyle << "**: the held-out characters remade as artists build models "
       << "(`data_tools/builder/artist_style.h`: open body parts, UV islands of about " << a.island_faces
       << " faces with coincident seam copies, hair cut into strips, double-sided strips and panels, layered "
          "panels; "
       << (a.target_vertices > 0 ? "subdivided to about " + std::to_string(a.target_vertices) + " vertices"
                                 : std::string("no subdivision"))
       << ", seed " << a.seed
       << ") with their ground truth remade by the same map; every method binds the remade "
          "mesh.\n\n";
  }

  // Segmentation.
  if (!result.segmentation.empty()) {
    md << "## Apparel segmentation\n\nBare body: each character's largest connected part (a procedural "
          "character's naked body) segmented alone; the share of its vertices called apparel. Open parts: the "
          "character remade as real models are built (open, overlapping body parts with duplicated seams, holes "
          "under the clothes, a hair cap; `open_parts_example`), dressed (IoU) and bare (share called apparel).\n\n"
          "| Subset | IoU | F1 | Precision | Recall | Bare body called apparel | Open parts IoU | Bare open parts "
          "called apparel |\n|---|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const auto& [subset, s] : result.segmentation) {
      const auto bare = result.bare_apparel_share.find(subset);
      const auto open = result.open_parts.find(subset);
      const bool has_open = open != result.open_parts.end();
      md << "| " << subset << " | " << fixed(s.iou, 3) << " | " << fixed(s.f1, 3) << " | " << fixed(s.precision, 3)
         << " | " << fixed(s.recall, 3) << " | "
         << (bare == result.bare_apparel_share.end() ? std::string("–") : percent(bare->second)) << " | "
         << (has_open ? fixed(open->second.first, 3) : std::string("–")) << " | "
         << (has_open ? percent(open->second.second) : std::string("–")) << " |\n";
    }
    md << "\n";
  }

  if (!result.predictions.empty()) {
    write_table(md, result, "Predictions file", "Predicted vertices of the file scored against the ground truth.",
                {"predictions"});
  } else {
    write_table(md, result, "Table 2 analogue: baselines",
                "The skinning baseline deforms the whole character, apparel included, by LBS with the ground-truth "
                "body weights (what the paper's NBS / SPT baselines do); the two zero-network rules on the "
                "ground-truth mask and weights: hold_offset carries each apparel vertex's detail vector (its offset "
                "from its skinned anchor, in the frame of the anchor's dominant joint) unchanged, inertial lets it "
                "continue with its last velocity, damped by a fitted inertia; LBS with the predicted weights of "
                "every vertex; the inertial rule on the predicted mask and weights (the full model's inputs); the full "
                "model. Amplitude = mean |Â - S| / mean |A_gt - S| over apparel vertices, S "
                "the apparel skinned with the ground-truth body weights (0: glued to the body, 1: as lively as the "
                "simulation).",
                {"skinning_baseline", "hold_offset", "inertial", "apparel_gt", "lbs_predicted", "body_apparel",
                 "inertial_predicted", "full"});
    write_table(md, result, "Table 3 analogue: ablation of the modules",
                "Body module only (every vertex skinned with predicted weights), body + apparel modules (no "
                "refiner), the full model, and the full model with the ground-truth apparel mask.",
                {"lbs_predicted", "body_apparel", "full", "full_gt_mask"});
    write_table(md, result, "Table 4 analogue: geodesic variants of the skinning predictor",
                "The full model with the ground-truth apparel mask and each skinning predictor variant: geodesic "
                "attention (the paper's), without geodesic distances, joints sorted by geodesic distance.",
                {"full_gt_mask", "no_geodesic", "sort_by_geodesic"});
    if (std::any_of(result.rows.begin(), result.rows.end(),
                    [](const MethodScores& r) { return r.method.rfind("cloth_retarget", 0) == 0; })) {
      write_table(md, result, "Cloth retargeting on garment pairs",
                  "Clips whose character shares its garment (apparel connectivity) and motion with another body of "
                  "the file (amt dataset pairs): the other body's simulated apparel retargeted onto this body "
                  "(body-oriented apparel + detail vectors, cloth-retargeting paper 2.2; detail vectors shortened, "
                  "3.1; without and with the push-out of 3.2), scored against this body's own simulation, beside "
                  "rigid skinning and the learned model on the same clips.",
                  {"skinning_baseline", "hold_offset", "full", "cloth_retarget_unresolved", "cloth_retarget"});
    }
  }

  // Paper protocol per horizon: the teacher-forced one-step error (horizon 1) next to the error a few
  // frames into the window's own rollout.
  if (!result.horizons.empty()) {
    size_t longest = 0;
    for (const RolloutCurve& c : result.horizons) longest = std::max(longest, c.pmd_a.size());
    md << "## Paper protocol per predicted frame\n\nPMD_a (cm) of the k-th predicted frame of the windows (k = 1: "
          "one step from 3 ground-truth states, teacher forced; k > 1: rolled out on the method's own "
          "predictions).\n\n| Subset | Method |";
    for (size_t k = 1; k <= longest; ++k) md << " " << k << " |";
    md << "\n|---|---|";
    for (size_t k = 1; k <= longest; ++k) md << "---:|";
    md << "\n";
    for (const RolloutCurve& c : result.horizons) {
      md << "| " << c.subset << " | " << method_label(c.method) << " |";
      for (size_t k = 0; k < longest; ++k)
        md << " " << (k < c.pmd_a.size() ? fixed(c.pmd_a[k], 2) : std::string("–")) << " |";
      md << "\n";
    }
    md << "\n";
  }

  // Rollout drift.
  bool rollout_header = false;
  for (const RolloutCurve& c : result.curves) {
    if (!rollout_header) {
      md << "## Rollout drift\n\nPMD_a (cm) at rollout frame k (the k-th predicted frame, after a "
         << kDefaultLeadInFrames << "-frame lead-in from the rest pose), averaged over the clips that long.\n\n"
         << "| Subset | Method |";
      for (int f : result.options.rollout_frames) md << " frame " << f << " |";
      md << "\n|---|---|";
      for (size_t i = 0; i < result.options.rollout_frames.size(); ++i) md << "---:|";
      md << "\n";
      rollout_header = true;
    }
    md << "| " << c.subset << " | " << method_label(c.method) << " |";
    for (int f : result.options.rollout_frames) {
      if (f >= 1 && f <= static_cast<int>(c.pmd_a.size()) && c.clips[f - 1] > 0)
        md << " " << fixed(c.pmd_a[f - 1], 2) << " (" << c.clips[f - 1] << " clips) |";
      else
        md << " – (no clip that long) |";
    }
    md << "\n";
  }
  if (rollout_header) md << "\n";

  // Per character.
  if (!result.characters.empty()) {
    const std::string main = result.predictions.empty() ? "full" : "predictions";
    md << "## Per character\n\n| Character | Subset | Vertices | Apparel | IoU | Open parts IoU | Protocol | "
          "Baseline PMD_a | "
       << method_label(main)
       << " PMD | PMD_a | PMD_b | ELS |\n|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|\n";
    for (const CharacterScores& c : result.characters) {
      for (const std::string& protocol : protocols_of(result)) {
        const auto m = c.scores.find(main);
        if (m == c.scores.end() || !m->second.count(protocol)) continue;
        const MotionScores& s = m->second.at(protocol);
        double baseline = std::nan("");
        const auto b = c.scores.find("skinning_baseline");
        if (b != c.scores.end() && b->second.count(protocol)) baseline = b->second.at(protocol).pmd_a;
        md << "| " << c.character << " | " << c.subset << " | " << c.num_vertices << " | " << c.num_apparel << " | "
           << (result.predictions.empty() ? fixed(c.segmentation.iou, 3) : std::string("–")) << " | "
           << (std::isfinite(c.open_parts_iou) ? fixed(c.open_parts_iou, 3) : std::string("–")) << " | " << protocol
           << " | " << fixed(baseline, 2) << " | " << fixed(s.pmd, 2) << " | " << fixed(s.pmd_a, 2) << " | "
           << fixed(s.pmd_b, 2) << " | " << fixed(s.els, 3) << " |\n";
      }
    }
    md << "\n";
  }

  write_falling_apart(md, result);

  // Runtime on generated characters (amt eval --runtime).
  if (!result.runtime.empty()) {
    md << "## Runtime\n\nThe whole per-frame step of `amt animate` (the pipeline, penetration resolution, GLB "
          "output) on generated characters, medians over the timed frames after a lead-in; milliseconds.\n\n";
    for (const RuntimeFigures& r : result.runtime) {
      md << "**" << r.label << "**: " << r.character << ", " << r.vertices << " vertices, " << r.faces
         << " faces; apparel mask from " << r.mask << ": " << r.apparel_vertices << " vertices ("
         << percent(r.vertices > 0 ? double(r.apparel_vertices) / r.vertices : std::nan("")) << "; as built "
         << r.true_apparel_vertices << ", "
         << percent(r.vertices > 0 ? double(r.true_apparel_vertices) / r.vertices : std::nan("")) << "); bind "
         << fixed(r.bind_seconds, 2) << " s; " << r.repeats
         << " timed frames; peak resident memory of the process so far " << fixed(r.peak_resident_mb, 0) << " MB.\n\n"
         << "| Threads | Per frame | p95 | LBS | Apparel network | Refiner | Penetration | Output | Inside before -> "
            "after | Inside tests carried over |\n|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|\n";
      for (const RuntimeThreadFigures& t : r.per_thread)
        md << "| " << t.threads << " | " << fixed(t.median_ms, 2) << " | " << fixed(t.p95_ms, 2) << " | "
           << fixed(t.lbs_ms, 2) << " | " << fixed(t.apparel_ms, 2) << " | " << fixed(t.refiner_ms, 2) << " | "
           << fixed(t.penetration_ms, 2) << " | " << fixed(t.output_ms, 2) << " | " << percent(t.inside_before)
           << " -> " << percent(t.inside_after) << " | " << percent(t.carried_share) << " |\n";
      md << "\n";
      std::string reference;
      for (const RuntimeThreadFigures& t : r.per_thread) {
        if (!std::isfinite(t.reference_apparel_ms)) continue;
        reference += std::string(reference.empty() ? "" : ", ") + fixed(t.reference_apparel_ms, 2) + " ms on " +
                     std::to_string(t.threads) + " thread" + (t.threads > 1 ? "s" : "") + " (the apparel network " +
                     fixed(t.apparel_ms / t.reference_apparel_ms, 2) + "x it)";
      }
      if (!reference.empty())
        md << "The global apparel form's network (the form the local one replaced, at the widths it was shipped "
              "with), timed beside the model's frame by frame on the same character and mask: "
           << reference << ".\n\n";
    }
  }

  // Targets of the apparel dynamics (paper protocol, rollout protocol, drift) and of the paper.
  if (result.predictions.empty()) {
    md << "## Targets\n\n";
    bool any = false;
    for (const RuntimeFigures& r : result.runtime) {
      for (const RuntimeThreadFigures& t : r.per_thread) {
        if (r.target_ms <= 0 || t.threads != r.target_threads || !std::isfinite(t.median_ms)) continue;
        any = true;
        md << "- runtime, " << r.label << ": per frame on " << t.threads << " thread" << (t.threads > 1 ? "s" : "")
           << " = " << fixed(t.median_ms, 2) << " ms (target <= " << fixed(r.target_ms, 0)
           << " ms): " << (t.median_ms <= r.target_ms ? "met" : "NOT met") << "\n";
      }
      for (const RuntimeThreadFigures& t : r.per_thread) {
        if (r.target_apparel_reference_ratio <= 0 || t.threads != 1 || !(t.reference_apparel_ms > 0)) continue;
        any = true;
        const double ratio = t.apparel_ms / t.reference_apparel_ms;
        md << "- runtime, " << r.label
           << ": apparel network / the global form's timed beside it on 1 thread = " << fixed(ratio, 2)
           << " (target <= " << fixed(r.target_apparel_reference_ratio, 2)
           << "): " << (ratio <= r.target_apparel_reference_ratio ? "met" : "NOT met") << "\n";
      }
      if (r.target_bind_seconds > 0 && std::isfinite(r.bind_seconds)) {
        any = true;
        md << "- runtime, " << r.label << ": bind = " << fixed(r.bind_seconds, 2)
           << " s (target <= " << fixed(r.target_bind_seconds, 0)
           << " s): " << (r.bind_seconds <= r.target_bind_seconds ? "met" : "NOT met") << "\n";
      }
    }
    const auto pmd_a = [&](const char* method, const char* protocol, const std::string& subset) {
      const MethodScores* r = result.find(method, protocol, subset);
      return r ? r->scores.pmd_a : std::nan("");
    };
    const auto check = [&](const std::string& what, double value, double bound, bool at_most) {
      if (!std::isfinite(value)) return;
      any = true;
      md << "- " << what << " = " << fixed(value, 3) << " (target " << (at_most ? "<= " : ">= ") << fixed(bound, 2)
         << "): " << ((at_most ? value <= bound : value >= bound) ? "met" : "NOT met") << "\n";
    };
    for (const std::string& subset : subsets_of(result)) {
      const double full = pmd_a("full", "paper", subset), base = pmd_a("skinning_baseline", "paper", subset);
      const double rule = std::fmin(pmd_a("hold_offset", "paper", subset), pmd_a("inertial", "paper", subset));
      check(subset + ": full PMD_a / skinning baseline, paper protocol", full / base, 0.40, true);
      check(subset + ": full PMD_a / better zero-network rule, paper protocol", full / rule, 0.75, true);
      check(subset + ": apparel module (GT mask + weights) PMD_a / better zero-network rule, paper protocol",
            pmd_a("apparel_gt", "paper", subset) / rule, 0.75, true);
      check(subset + ": apparel module (GT mask + weights) PMD_a / skinning baseline, rollout protocol",
            pmd_a("apparel_gt", "rollout", subset) / pmd_a("skinning_baseline", "rollout", subset), 0.80, true);
      // Like for like: the full model against the inertial rule on its own inputs (the predicted mask and
      // weights), so that segmentation and skinning errors do not decide the comparison. At most 1 in the
      // rollouts: learned apparel must not lose to the rule it is built around.
      check(subset + ": full PMD_a / inertial rule on the predicted mask and weights, paper protocol",
            full / pmd_a("inertial_predicted", "paper", subset), 0.75, true);
      check(subset + ": full PMD_a / inertial rule on the predicted mask and weights, rollout protocol",
            pmd_a("full", "rollout", subset) / pmd_a("inertial_predicted", "rollout", subset), 1.0, true);
      check(subset + ": full PMD_a / skinning baseline, rollout protocol",
            pmd_a("full", "rollout", subset) / pmd_a("skinning_baseline", "rollout", subset), 0.80, true);
      if (const MethodScores* r = result.find("full", "rollout", subset)) {
        check(subset + ": full dynamics amplitude, rollout protocol (0.8 to 1.25)", r->amplitude, 0.8, false);
        check(subset + ": full dynamics amplitude, rollout protocol (0.8 to 1.25)", r->amplitude, 1.25, true);
      }
      for (const RolloutCurve& c : result.curves) {
        if (c.method != "full" || c.subset != subset || c.pmd_a.size() < 300 || c.clips[299] == 0) continue;
        check(subset + ": full PMD_a at rollout frame 300 / frame 10", c.pmd_a[299] / c.pmd_a[9], 1.5, true);
      }
      if (const MethodScores* r = result.find("full", "paper", subset))
        check(subset + ": full ELS", r->scores.els, 0.94, false);
      const auto seg = result.segmentation.find(subset);
      if (seg != result.segmentation.end()) {
        any = true;
        md << "- " << subset << ": segmentation IoU = " << fixed(seg->second.iou, 3)
           << " (target >= 0.9): " << (seg->second.iou >= 0.9 ? "met" : "NOT met") << "\n";
        const auto bare = result.bare_apparel_share.find(subset);
        if (bare != result.bare_apparel_share.end() && std::isfinite(bare->second))
          md << "- " << subset << ": bare body called apparel = " << fixed(100 * bare->second, 1)
             << " % (target <= 5 %): " << (bare->second <= 0.05 ? "met" : "NOT met") << "\n";
        const auto open = result.open_parts.find(subset);
        if (open != result.open_parts.end() && std::isfinite(open->second.second))
          md << "- " << subset << ": bare open parts called apparel = " << fixed(100 * open->second.second, 1)
             << " % (target <= 5 %): " << (open->second.second <= 0.05 ? "met" : "NOT met") << "\n";
      }
      // Table 3 ordering: PMD decreases from body only to full + GT mask.
      const std::vector<std::string> order = {"lbs_predicted", "body_apparel", "full", "full_gt_mask"};
      std::vector<double> pmd;
      for (const std::string& m : order)
        if (const MethodScores* r = result.find(m, "paper", subset)) pmd.push_back(r->scores.pmd);
      if (pmd.size() == order.size()) {
        any = true;
        const bool holds = pmd[0] >= pmd[1] && pmd[1] >= pmd[2] && pmd[2] >= pmd[3];
        md << "- " << subset
           << ": Table 3 ordering of PMD (body only >= body + apparel >= full >= full + GT mask): " << fixed(pmd[0], 2)
           << ", " << fixed(pmd[1], 2) << ", " << fixed(pmd[2], 2) << ", " << fixed(pmd[3], 2) << ": "
           << (holds ? "holds" : "does NOT hold") << "\n";
      }
      const MethodScores* attention = result.find("full_gt_mask", "paper", subset);
      const MethodScores* no_g = result.find("no_geodesic", "paper", subset);
      const MethodScores* sorted = result.find("sort_by_geodesic", "paper", subset);
      if (attention && no_g && sorted) {
        any = true;
        const bool holds =
            attention->scores.pmd_b <= no_g->scores.pmd_b && attention->scores.pmd_b <= sorted->scores.pmd_b;
        md << "- " << subset
           << ": Table 4 ordering of PMD_b (G + attention best): " << fixed(attention->scores.pmd_b, 2) << " vs w/o G "
           << fixed(no_g->scores.pmd_b, 2) << ", sort by G " << fixed(sorted->scores.pmd_b, 2) << ": "
           << (holds ? "holds" : "does NOT hold") << "\n";
      }
    }
    if (!any) md << "The paper protocol was not run or had no clip: no target can be checked.\n";
    md << "\n";
  }

  if (!plots.empty()) {
    md << "## Plots\n\n";
    for (const std::string& p : plots) md << "![" << p << "](" << p << ")\n\n";
  }
  if (!result.notes.empty() || !plot_notes.empty()) {
    md << "## Notes\n\n";
    for (const std::string& n : result.notes) md << "- " << n << "\n";
    for (const std::string& n : plot_notes) md << "- " << n << "\n";
    md << "\n";
  }
  md << "Machine-readable figures: `metrics.json`.\n";
  return md.str();
}

void check_report_folder(const std::string& dir) {
  AMT_CHECK(!dir.empty(), "eval: --out: expected an output folder, found nothing");
  check_writable_location(dir, "--out");
  std::error_code error;
  const fs::file_status status = fs::symlink_status(dir, error);
  if (!fs::exists(status)) return;
  AMT_CHECK(fs::is_directory(status), dir,
            ": --out: expected a folder for the report (absent, empty, or written by amt ", "eval), found ",
            describe_file_type(status.type()));
  if (fs::is_empty(dir, error) && !error) return;
  const fs::path metrics = fs::path(dir) / "metrics.json";
  std::string format;
  if (fs::is_regular_file(fs::symlink_status(metrics, error))) {
    std::ifstream in(metrics);
    try {
      const nlohmann::json j = nlohmann::json::parse(in);
      if (j.is_object()) format = j.value("format", "");
    } catch (const nlohmann::json::exception&) {
      format.clear();
    }
  }
  AMT_CHECK(format == "amt-eval", dir, ": --out: expected an empty folder or a report folder amt eval wrote ",
            "(metrics.json of format amt-eval), found other files: name a new folder");
}

ReportFiles write_report(const EvaluationResult& result, const ReportOptions& options) {
  check_report_folder(options.out_dir);
  std::error_code error;
  fs::create_directories(options.out_dir, error);
  AMT_CHECK(fs::is_directory(options.out_dir, error), options.out_dir, ": cannot create the output folder (",
            error.message(), ")");
  ReportFiles files;
  // metrics.json first: it marks the folder as amt's, so a run interrupted while drawing the plots is
  // replaced by the next run instead of refused.
  files.json = (fs::path(options.out_dir) / "metrics.json").string();
  write_file_atomically(files.json, evaluation_json(result));
  if (options.plots) {
    plot_loss_curves(options, files);
    plot_rollout(result, options, files);
  }
  files.markdown = (fs::path(options.out_dir) / "report.md").string();
  write_file_atomically(files.markdown, report_markdown(result, options, files.plots, files.notes));
  return files;
}

}  // namespace amt
