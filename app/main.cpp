// amt: apparel-aware motion transfer. Thin program over the folder libraries; see README.md.
#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <H5public.h>
#include <torch/version.h>
#include <unistd.h>

#include <cstdlib>
#include <iostream>
#include <thread>

#include "amt/version.h"
#include "app/commands.h"
#include "data_tools/error.h"
#include "data_tools/threads.h"

namespace amt::app {

void add_threads_option(CLI::App& command) {
  auto* threads = command.add_option("--threads", "Worker threads (default: all cores)")
                      ->check(CLI::Range(1, 1024))
                      ->default_val(std::max(1u, std::thread::hardware_concurrency()));
  command.parse_complete_callback([threads] { set_thread_count(threads->as<int>()); });
}

}  // namespace amt::app

namespace {

std::string version_text() {
  unsigned h5_major = 0, h5_minor = 0, h5_release = 0;
  H5get_libversion(&h5_major, &h5_minor, &h5_release);
  return "amt " AMT_VERSION " (LibTorch " + std::string(TORCH_VERSION) + ", HDF5 " + std::to_string(h5_major) + "." +
         std::to_string(h5_minor) + "." + std::to_string(h5_release) + ", Eigen " + std::to_string(EIGEN_WORLD_VERSION) +
         "." + std::to_string(EIGEN_MAJOR_VERSION) + "." + std::to_string(EIGEN_MINOR_VERSION) + ")";
}

// OpenMP's worker threads spin for a while after each parallel region by default. Next to
// OpenBLAS's own worker, that is three busy threads on a 2-core machine, and a 2-thread animation of
// a 50k-vertex character ran at 39 ms per frame against 21 ms with passive waiting (amt bench
// --suite runtime, same machine, back to back). libgomp reads OMP_WAIT_POLICY once, when it is
// loaded, before main: so a run that did not choose a policy restarts itself once with "passive".
// A user's own choice is left alone.
void prefer_passive_openmp_waiting(char** argv) {
  if (std::getenv("OMP_WAIT_POLICY") != nullptr) return;
  if (setenv("OMP_WAIT_POLICY", "passive", 0) != 0) return;
  execv("/proc/self/exe", argv);  // returns only on failure: then run on with the default policy
}

}  // namespace

int main(int argc, char** argv) {
  prefer_passive_openmp_waiting(argv);
  CLI::App app{"amt: apparel-aware motion transfer for stylized characters"};
  app.set_version_flag("--version", version_text());
  app.require_subcommand(1);
  amt::app::add_dataset_command(app);
  amt::app::add_train_command(app);
  amt::app::add_eval_command(app);
  amt::app::add_animate_command(app);
  amt::app::add_bench_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const amt::Error& e) {
    std::cerr << "amt: error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "amt: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
