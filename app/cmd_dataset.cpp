// `amt dataset ...` subcommands.
#include "app/commands.h"

namespace amt::app {

void add_dataset_command(CLI::App& app) {
  auto* dataset = app.add_subcommand("dataset", "Inspect and build dataset files (HDF5, format amt-dataset)");
  dataset->require_subcommand(1);
}

}  // namespace amt::app
