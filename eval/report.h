#pragma once
// The evaluation report (issue 5): <out>/report.md with the Table 2-4 analogues, the rollout figures,
// a per-character table and the targets; <out>/metrics.json (evaluation_json); PNG plots drawn by
// gnuplot (loss curves from the model folder's training logs, PMD_a over rollout frames). Every file
// is written to a temporary name and renamed.
#include <string>
#include <vector>

#include "eval/evaluate.h"

namespace amt {

// === Training logs

/// One training log <model>/<name>.csv: the columns and the rows (as numbers; empty cells are NaN).
struct TrainingLog {
  std::string name;
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;
  /// Index of a column, or -1.
  int column(const std::string& name) const;
};

/// Reads every *.csv of `dir` whose header starts with "step,loss" (the trainer's logs), sorted by
/// name. Unreadable or foreign CSV files are skipped. Missing folder: no logs.
std::vector<TrainingLog> read_training_logs(const std::string& dir);

// === gnuplot

/// The PNG terminal of the installed gnuplot: "pngcairo" when it has one, else "png", else "" (no
/// gnuplot, or no PNG terminal).
std::string gnuplot_png_terminal();

/// Runs gnuplot (as a child process, no shell) on the script file `script`. Returns true when it
/// exited with status 0; its error output goes to stderr.
bool run_gnuplot(const std::string& script);

// === Report

/// Where and how to write the report.
struct ReportOptions {
  /// Output folder (created if missing).
  std::string out_dir;
  /// Model folder whose *.csv training logs are plotted ("" or missing: no loss plots).
  std::string model_dir;
  /// The command line that produced the evaluation, quoted in the report.
  std::string command;
  /// Draw the PNG plots (when gnuplot is there).
  bool plots = true;
};

/// What write_report wrote.
struct ReportFiles {
  std::string markdown, json;
  std::vector<std::string> plots;
  /// Why some plots are missing (no gnuplot, no logs).
  std::vector<std::string> notes;
};

/// The Markdown text of the report; `plots` are the PNG file names (relative to the report) to embed.
std::string report_markdown(const EvaluationResult& result, const ReportOptions& options,
                            const std::vector<std::string>& plots, const std::vector<std::string>& plot_notes);

/// Checks, before any work, that `dir` may become a report folder: it does not exist, is empty, or holds
/// a metrics.json of format "amt-eval" (a folder amt eval wrote before, whose report files are replaced).
/// Anything else (a file, a folder of the user's) is refused with amt::Error naming it. Creates nothing.
void check_report_folder(const std::string& dir);

/// Writes <out>/metrics.json (first: it marks the folder as amt's), the plots and <out>/report.md after
/// check_report_folder. Throws amt::Error when the folder is refused or a file cannot be written; a
/// failing gnuplot only drops its plot (noted in the report).
ReportFiles write_report(const EvaluationResult& result, const ReportOptions& options);

}  // namespace amt
