// `amt dataset ...` subcommands.
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "app/commands.h"
#include "data_tools/dataset_info.h"
#include "data_tools/dataset_preview.h"
#include "data_tools/error.h"
#include "data_tools/example_dataset.h"

namespace amt::app {
namespace {

// `amt dataset info FILE`: prints the summary of a dataset file.
void add_info_command(CLI::App& dataset) {
  auto* info = dataset.add_subcommand("info", "Summarise a dataset file: characters, clips, frames and splits");
  auto path = std::make_shared<std::string>();
  // Existence is checked in the callback, not with CLI::ExistingFile, so that a missing file is
  // reported as the one-line amt error.
  info->add_option("FILE", *path, "Dataset file (HDF5, format amt-dataset)")->required();
  add_threads_option(*info);
  info->callback([path] {
    std::error_code error;
    AMT_CHECK(std::filesystem::exists(*path, error), *path, ": no such file (expected a dataset file written by amt)");
    print_dataset_info(*path, std::cout);
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

}  // namespace

void add_dataset_command(CLI::App& app) {
  auto* dataset = app.add_subcommand("dataset", "Inspect and build dataset files (HDF5, format amt-dataset)");
  dataset->require_subcommand(1);
  add_info_command(*dataset);
  add_example_command(*dataset);
  add_preview_command(*dataset);
}

}  // namespace amt::app
