#pragma once
// Subcommands of the `amt` program. Each add_* registers its subcommand and the callback that runs
// it; callbacks throw amt::Error on bad input, which main prints as one line before exiting 1.
#include <CLI/CLI.hpp>
#include <string>

namespace amt::app {

/// `amt dataset info|...`: inspect and build dataset files (docs/dataset.md, "The dataset file").
void add_dataset_command(CLI::App& app);

/// `amt train <module>`: train a module on dataset shards, with checkpoints and resume.
void add_train_command(CLI::App& app);

/// `amt eval`: PMD / ELS / penetration tables of a model on held-out data, as a Markdown report.
void add_eval_command(CLI::App& app);

/// `amt bench`: speed and memory figures.
void add_bench_command(CLI::App& app);

/// `amt animate`: a character and a motion -> an animated GLB, OBJ folder or dataset file (infer/).
void add_animate_command(CLI::App& app);

/// `amt view FILES...`: a local web viewer of GLBs or of a viewer folder (data_tools/formats/viewer_folder.h).
void add_view_command(CLI::App& app);
/// `amt retarget-cloth`: apparel motion from a source body onto a target body (infer/retarget_cloth.h).
void add_retarget_cloth_command(CLI::App& app);
/// `amt refit-garment`: a garment moved onto an avatar of other proportions, intersection-free (refit/).
void add_refit_garment_command(CLI::App& app);
/// `amt convert`: a PMX model as glTF or a VRM 1.0 avatar with spring bones (data_tools/formats/pmx_gltf.h).
void add_convert_command(CLI::App& app);

/// kDefaultStrainFloor as the help of `--strain-limit` writes it ("0.7").
std::string strain_floor_text();

/// Adds the `--threads` option every subcommand has; the value is applied before the callback runs.
void add_threads_option(CLI::App& command);

}  // namespace amt::app
