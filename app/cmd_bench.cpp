// `amt bench`: speed and memory figures.
#include "app/commands.h"

namespace amt::app {

void add_bench_command(CLI::App& app) {
  auto* bench = app.add_subcommand("bench", "Speed and memory figures");
  add_threads_option(*bench);
}

}  // namespace amt::app
