// `amt dataset ...` subcommands.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "app/commands.h"
#include "app/repository.h"
#include "data_tools/formats/atomic_file.h"
#include "data_tools/builder/artist_style_dataset.h"
#include "data_tools/builder/dataset_builder.h"
#include "data_tools/builder/dataset_info.h"
#include "data_tools/builder/dataset_preview.h"
#include "data_tools/builder/dataset_quality.h"
#include "data_tools/geometry/error.h"
#include "data_tools/builder/example_dataset.h"
#include "data_tools/builder/garment_pairs.h"
#include "data_tools/builder/pmx_character_export.h"
#include "data_tools/formats/pmx_export.h"

namespace amt::app {
namespace {

// `amt dataset info FILE|DIR`: prints the summary of a dataset file, or of a dataset folder with the shards its
// manifest names that are missing or damaged (then it fails, after the summary).
void add_info_command(CLI::App& dataset) {
  auto* info = dataset.add_subcommand(
      "info", "Summarise a dataset file, or a dataset folder (totals, size, missing or damaged shards): characters, "
              "clips, frames and splits");
  auto path = std::make_shared<std::string>();
  // Existence is checked in the callback, not with CLI::ExistingPath, so that a missing path is
  // reported as the one-line amt error.
  info->add_option("PATH", *path, "Dataset file (HDF5, format amt-dataset) or folder written by amt dataset build")
      ->required();
  add_threads_option(*info);
  info->callback([path] {
    std::error_code error;
    AMT_CHECK(std::filesystem::exists(*path, error), *path,
              ": no such file or folder (expected a dataset file or folder written by amt)");
    if (!std::filesystem::is_directory(*path, error)) {
      print_dataset_info(*path, std::cout);
      return;
    }
    const DatasetFolderSummary summary = summarise_dataset_folder(*path);
    print_dataset_folder_summary(summary, std::cout);
    const int problems = summary.num_problems();
    AMT_CHECK(problems == 0, *path, ": ", problems, " of ", summary.shards.size(),
              " shards missing, damaged or not in the manifest (listed above)");
  });
}

// `amt dataset example --out FILE`: a small dataset from the core pieces (no apparel physics).
void add_example_command(CLI::App& dataset) {
  auto* example = dataset.add_subcommand(
      "example", "Write a small example dataset: capsule stand-in character, procedural walk, rigid skinning");
  auto path = std::make_shared<std::string>();
  auto options = std::make_shared<ExampleDatasetOptions>();
  example->add_option("--out", *path, "Output file (written to a temporary name, then renamed)")->required();
  example->add_option("--vertices", options->vertices, "Approximate vertex count of the character")
      ->capture_default_str();
  example->add_option("--frames", options->frames, "Frames of the walk clip")->capture_default_str();
  example->add_option("--fps", options->fps, "Frame rate")->capture_default_str();
  add_threads_option(*example);
  example->callback([path, options] {
    write_example_dataset(*path, *options);
    std::cout << "wrote " << *path << "\n";
  });
}

// `amt dataset preview FILE --out X.glb`: a clip as an animated glTF.
void add_preview_command(CLI::App& dataset) {
  auto* preview = dataset.add_subcommand("preview", "Export one clip's ground truth as an animated glTF (.glb/.gltf)");
  auto path = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto options = std::make_shared<DatasetPreviewOptions>();
  preview->add_option("FILE", *path, "Dataset file (HDF5, format amt-dataset)")->required();
  preview->add_option("--out", *out, "Output .glb or .gltf (written to a temporary name, then renamed)")->required();
  preview->add_option("--clip", options->clip, "Clip name (default: the first clip)");
  preview->add_option("--first-frame", options->first_frame, "First frame")->capture_default_str();
  preview->add_option("--frames", options->max_frames, "At most this many frames (0: all)")->capture_default_str();
  add_threads_option(*preview);
  preview->callback([path, out, options] {
    std::error_code error;
    AMT_CHECK(std::filesystem::exists(*path, error), *path, ": no such file (expected a dataset file written by amt)");
    const int frames = export_dataset_preview(*path, *out, *options);
    std::cout << "wrote " << *out << " (" << frames << " frames)\n";
  });
}

// The motions of `amt dataset build` when --motions is not given: the 20 CMU clips in the repository.
constexpr const char* kDefaultMotions = "data/mocap/cmu";

// The apparel physics settings of a build: `amt dataset build` and `amt dataset export-pmx` (which must dress a
// character as the build did) take the same ones.
void add_apparel_physics_options(CLI::App& command, ApparelOptions& apparel) {
  command.add_option("--apparel-damping", apparel.damping_scale,
                     "Scale on the damping of apparel bodies (ApparelOptions::damping_scale)")
      ->capture_default_str();
  command.add_option("--apparel-stiffness", apparel.stiffness_scale,
                     "Scale on the angular spring stiffness of apparel joints (ApparelOptions::stiffness_scale)")
      ->capture_default_str();
  command.add_option("--apparel-variation", apparel.physics_variation,
                     "Per-piece spread of apparel mass, damping and stiffness: factors log-uniform in [1/(1+v), 1+v] "
                     "(ApparelOptions::physics_variation; 0 = every piece of a kind alike)")
      ->capture_default_str();
}

// `amt dataset build --out DIR ...`: characters x motions simulated into shards (data_tools/builder/dataset_builder.h).
void add_build_command(CLI::App& dataset) {
  auto* build = dataset.add_subcommand(
      "build", "Build a dataset: procedural dressed characters and PMX models (--pmx) simulated under every motion "
               "clip, one HDF5 shard per character (seeded, resumable, --shard i/n for several processes)");
  auto options = std::make_shared<DatasetBuildOptions>();
  auto shard = std::make_shared<std::string>("0/1");
  build->add_option("--out", options->out, "Output folder (shards, manifest.json, character records)")->required();
  build->add_option("--seed", options->seed, "Seed of characters, apparel, splits and procedural motions")
      ->capture_default_str();
  auto* characters = build->add_option("--characters", options->characters,
                                       "Number of procedural characters (default 32, or 0 with --pmx)");
  build->add_option("--pmx", options->pmx,
                    "PMX models (files or folders of *.pmx), each a character simulated with its own rigid bodies "
                    "and joints; alone or beside --characters N");
  build->add_option("--pmx-metres-per-unit", options->pmx_metres_per_unit,
                    "Metres per PMX unit of the --pmx models (MMD's 0.08; physics runs in their units)")
      ->capture_default_str();
  build->add_option("--character-joint-map", options->character_joint_map,
                    "JSON map {canonical joint: bone name} for --pmx models whose bones the MMD name table cannot map");
  auto* motions = build->add_option(
      "--motions", options->motions,
      "Folder of BVH files (every *.bvh); \"\" for none. " + repository_default_help(kDefaultMotions));
  build->add_option("--procedural", options->procedural, "Number of procedural motion clips")->capture_default_str();
  build->add_option("--frames", options->frames, "Frames per clip (30 fps)")->capture_default_str();
  build->add_option("--vertices", options->vertices, "Target vertex count of each body before dressing")
      ->capture_default_str();
  add_apparel_physics_options(*build, options->apparel);
  build->add_option("--physics-step", options->physics_step, "Physics substep in seconds")->capture_default_str();
  build->add_option("--solver-iterations", options->solver_iterations, "Constraint solver iterations per substep")
      ->capture_default_str();
  build->add_option("--shard", *shard, "Build characters c with c % n == i (i/n)")->capture_default_str();
  add_threads_option(*build);
  build->callback([options, shard, motions, characters] {
    if (characters->count() == 0 && !options->pmx.empty()) options->characters = 0;
    if (motions->count() == 0) {
      options->motions = repository_default(kDefaultMotions, "--motions",
                                            "FOLDER (BVH files), or --motions \"\" for procedural motions only");
    }
    options->shard = parse_shard(*shard);
    options->progress = &std::cerr;
    const DatasetBuildReport report = build_dataset(*options);
    print_build_report(report, std::cerr);
    std::cout << "wrote " << options->out << "\n";
  });
}

// `amt dataset pairs --out FILE`: bodies dressed in pairs with one garment template, simulated under the same
// clips (data_tools/builder/garment_pairs.h): the test bed of `amt retarget-cloth` and of `amt eval`'s cloth_retarget.
void add_pairs_command(CLI::App& dataset) {
  auto* pairs = dataset.add_subcommand(
      "pairs", "Build a garment pair set: pairs of bodies dressed with one garment template (identical apparel "
               "connectivity), each simulated under the same clips, in one HDF5 file");
  auto options = std::make_shared<GarmentPairOptions>();
  DatasetBuildOptions& b = options->build;
  b.procedural = 2;
  b.frames = 90;
  pairs->add_option("--out", b.out, "Output dataset file (.h5; written to a temporary name, then renamed)")->required();
  pairs->add_option("--pairs", options->pairs, "Number of body pairs")->capture_default_str();
  pairs->add_option("--seed", b.seed, "Seed of bodies, garments and procedural motions")->capture_default_str();
  pairs->add_option("--motions", b.motions, "Folder of BVH files (every *.bvh) simulated besides the procedural clips");
  pairs->add_option("--procedural", b.procedural, "Number of procedural motion clips")->capture_default_str();
  pairs->add_option("--frames", b.frames, "Frames per clip (30 fps)")->capture_default_str();
  pairs->add_option("--vertices", b.vertices, "Target vertex count of each body before dressing")
      ->capture_default_str();
  add_threads_option(*pairs);
  pairs->callback([options] {
    options->build.progress = &std::cerr;
    const GarmentPairReport report = build_garment_pairs(*options);
    std::cout << "wrote " << options->build.out << ": " << report.characters << " characters, " << report.clips
              << " clips, " << report.frames << " frames in " << report.seconds << " s\n";
  });
}

// `amt dataset check DIR`: first whether the folder holds every shard its manifest names, once, whole (the union
// of the --shard i/n processes' work; dataset_info.h), then the quality gates of the dataset
// (data_tools/builder/dataset_quality.h).
void add_check_command(CLI::App& dataset) {
  auto* check = dataset.add_subcommand(
      "check", "Completeness of a built dataset folder (every character of manifest.json has its shard, whole, none "
               "twice), then its quality gates: apparel lag, explosions, jumps, penetration; variety table and "
               "picture in a Markdown report");
  check->alias("quality");
  auto dir = std::make_shared<std::string>();
  auto options = std::make_shared<QualityOptions>();
  check->add_option("DIR", *dir, "Dataset folder written by amt dataset build")->required();
  check->add_option("--report", options->report_dir, "Folder for report.md and characters.png (default DIR/quality)");
  check->add_option("--penetration-stride", options->penetration_stride,
                    "Measure penetration on every k-th frame of each clip")
      ->capture_default_str();
  add_threads_option(*check);
  check->callback([dir, options] {
    std::error_code error;
    const std::filesystem::file_status status = std::filesystem::status(*dir, error);
    AMT_CHECK(std::filesystem::exists(status), *dir,
              ": no such folder (expected a dataset folder written by amt dataset build)");
    AMT_CHECK(std::filesystem::is_directory(status), *dir,
              ": expected a dataset folder written by amt dataset build, found ", describe_file_type(status.type()));
    if (std::filesystem::exists(std::filesystem::path(*dir) / "manifest.json", error)) {
      const DatasetFolderSummary summary = summarise_dataset_folder(*dir);
      print_dataset_completeness(summary, std::cout);
      const int problems = summary.num_problems();
      AMT_CHECK(problems == 0, *dir, ": incomplete: ", problems, " of ", summary.shards.size(),
                " shards missing, damaged, duplicated or not in the manifest (listed above); the gates run on a "
                "complete dataset");
    }
    QualityOptions run = *options;
    if (run.report_dir.empty()) run.report_dir = (std::filesystem::path(*dir) / "quality").string();
    run.progress = &std::cerr;
    const DatasetQuality quality = check_dataset(*dir, run);
    write_quality_report(quality, run);
    print_gates(quality, std::cout);
    std::cout << "wrote " << run.report_dir << "/report.md\n";
    const int failed = quality.failed_gates();
    AMT_CHECK(failed == 0, *dir, ": ", failed, " quality gate", failed == 1 ? "" : "s", " failed (see ",
              run.report_dir, "/report.md)");
  });
}

// `amt dataset export-pmx --seed S --character I --out FILE.pmx`: character I of the dataset `amt dataset build
// --seed S` makes, dressed, as an MMD model with its physics rig (test data for the PMX paths).
void add_export_pmx_command(CLI::App& dataset) {
  auto* export_pmx = dataset.add_subcommand(
      "export-pmx", "Write a character of a dataset build as an MMD model (PMX 2.0) with its apparel physics rig");
  auto options = std::make_shared<DatasetBuildOptions>();
  auto index = std::make_shared<int>(0);
  auto export_options = std::make_shared<PmxCharacterExportOptions>();
  export_pmx->add_option("--out", options->out, "Output .pmx file (written to a temporary name, then renamed)")
      ->required();
  export_pmx->add_option("--seed", options->seed, "Seed of the dataset build (as amt dataset build --seed)")
      ->capture_default_str();
  export_pmx->add_option("--character", *index, "Index of the character (character-0007 is 7)")->capture_default_str();
  export_pmx->add_option("--vertices", options->vertices, "Target vertex count of the body before dressing")
      ->capture_default_str();
  export_pmx->add_option("--metres-per-unit", export_options->metres_per_unit,
                         "Metres per PMX unit (0.1 makes MMD's gravity the builder's)")
      ->capture_default_str();
  add_apparel_physics_options(*export_pmx, options->apparel);
  add_threads_option(*export_pmx);
  export_pmx->callback([options, index, export_options] {
    const std::string& out = options->out;
    std::string extension = std::filesystem::path(out).extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    AMT_CHECK(extension == ".pmx", out, ": --out: expected a file name ending in .pmx");
    AMT_CHECK(*index >= 0 && *index < 100000, "dataset export-pmx: --character: expected 0 to 99999, found ", *index);
    AMT_CHECK(options->vertices >= kMinBodyVertices && options->vertices <= kMaxBodyVertices,
              "dataset export-pmx: --vertices: expected ", kMinBodyVertices, " to ", kMaxBodyVertices,
              " vertices per body, found ", options->vertices);
    const float scale = export_options->metres_per_unit;
    AMT_CHECK(std::isfinite(scale) && scale > 0, "dataset export-pmx: --metres-per-unit: expected a number > 0, found ",
              scale);
    check_replaceable_file(out);  // before the minutes of dressing, not after
    options->characters = *index + 1;  // the seeds of character I do not depend on the count
    const DressedCharacter dressed = dataset_character(*options, *index);
    export_options->name = std::filesystem::path(out).stem().string();
    const PmxModel model = pmx_from_character(dressed, *export_options);
    write_pmx(model, out);
    const int apparel = static_cast<int>(std::count(dressed.apparel_mask.begin(), dressed.apparel_mask.end(), 1));
    std::cout << "wrote " << out << ": " << model.vertices.size() << " vertices (" << apparel << " apparel), "
              << model.bones.size() << " bones, " << model.rigid_bodies.size() << " rigid bodies ("
              << dressed.num_apparel_bodies() << " simulated), " << model.joints.size() << " joints\n";
  });
}

// `amt dataset artist-style FILE --out X.h5`: the shard's characters remade as artists build models.
void add_artist_style_command(CLI::App& dataset) {
  auto* remake = dataset.add_subcommand(
      "artist-style",
      "Remake a shard's characters as artists build models (UV seams with coincident copies, hair strips, "
      "double-sided and layered panels, open body parts), with their clips' ground truth, into a new shard");
  auto in = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto options = std::make_shared<ArtistStyleDatasetOptions>();
  options->remake.target_vertices = 20000;  // as amt eval --artist-style
  remake->add_option("FILE", *in, "Dataset shard (HDF5, format amt-dataset)")->required();
  remake->add_option("--out", *out, "Output shard (.h5; written to a temporary name, then renamed)")->required();
  remake->add_option("--character", options->character, "Only this character (default: every one)");
  remake->add_option("--max-clips", options->max_clips, "At most this many clips per character (0: all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  remake->add_option("--vertices", options->remake.target_vertices,
                     "Vertices the remake is subdivided to (0: no subdivision; as amt eval --artist-style-vertices)")
      ->capture_default_str();
  remake->add_option("--seed", options->remake.seed, "Seed of the remake (as amt eval --artist-style-seed)")
      ->capture_default_str();
  remake->add_flag("--quiet", [options](int64_t) { options->progress = false; }, "No progress lines");
  add_threads_option(*remake);
  remake->callback([in, out, options] {
    const ArtistStyleDatasetSummary s = write_artist_style_dataset(*in, *out, *options);
    std::cout << "wrote " << *out << ": " << s.characters << " characters remade artist-style ("
              << s.vertices / std::max(s.characters, 1) << " vertices each on average), " << s.clips << " clips, "
              << s.frames << " frames\n";
  });
}

}  // namespace

void add_dataset_command(CLI::App& app) {
  auto* dataset = app.add_subcommand("dataset", "Inspect and build dataset files (HDF5, format amt-dataset)");
  dataset->require_subcommand(1);
  add_info_command(*dataset);
  add_example_command(*dataset);
  add_preview_command(*dataset);
  add_build_command(*dataset);
  add_pairs_command(*dataset);
  add_check_command(*dataset);
  add_export_pmx_command(*dataset);
  add_artist_style_command(*dataset);
}

}  // namespace amt::app
