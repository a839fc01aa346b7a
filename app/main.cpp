// amt: apparel-aware motion transfer. Thin program over the folder libraries; see README.md.
#include <H5public.h>
#include <pthread.h>
#include <torch/version.h>
#include <unistd.h>
#include <CLI/CLI.hpp>
#include <Eigen/Core>

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include "amt/version.h"
#include "app/commands.h"
#include "data_tools/geometry/error.h"
#include "data_tools/formats/temporary_registry.h"
#include "data_tools/geometry/threads.h"

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
         std::to_string(h5_minor) + "." + std::to_string(h5_release) + ", Eigen " +
         std::to_string(EIGEN_WORLD_VERSION) + "." + std::to_string(EIGEN_MAJOR_VERSION) + "." +
         std::to_string(EIGEN_MINOR_VERSION) + ")";
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

// SIGINT, SIGTERM, SIGHUP (a closed terminal or ssh session) and SIGQUIT remove the temporaries of the run they
// interrupt (data_tools/formats/temporary_registry.h) and end the process with 128 + the signal, as a shell reports
// a process killed by it (SIGQUIT without its core dump).
//
// The signals are blocked in the main thread before it starts any thread, so every thread amt starts
// (LibTorch's, OpenMP's, the sample loaders) inherits the block, and one dedicated thread takes them
// with sigwait(): the removal runs in an ordinary thread, free of async-signal-safety limits. A thread
// a shared library started before main (OpenBLAS starts its workers when it is loaded) does not block
// them; should the kernel pick such a thread, the handler installed for it only forwards the signal
// to the dedicated thread with pthread_kill (async-signal-safe).
pthread_t g_signal_thread;

void forward_to_signal_thread(int signal) {
  pthread_kill(g_signal_thread, signal);
}

constexpr int kTerminationSignals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT};

const char* signal_name(int signal) {
  switch (signal) {
    case SIGINT: return "SIGINT";
    case SIGTERM: return "SIGTERM";
    case SIGHUP: return "SIGHUP";
    case SIGQUIT: return "SIGQUIT";
    default: return "a signal";
  }
}

void remove_temporaries_on_termination_signals() {
  sigset_t signals;
  sigemptyset(&signals);
  for (const int signal : kTerminationSignals) sigaddset(&signals, signal);
  if (pthread_sigmask(SIG_BLOCK, &signals, nullptr) != 0) return;
  std::thread waiter([signals] {
    int signal = 0;
    if (sigwait(&signals, &signal) != 0) return;
    // Keeps the registry locked: a thread still writing blocks instead of creating new files.
    const int removed = amt::remove_registered_temporaries(/*hold=*/true);
    char line[160];
    const int n = std::snprintf(line, sizeof(line), "\namt: stopped by %s; removed %d temporary file%s\n",
                                signal_name(signal), removed, removed == 1 ? "" : "s");
    if (n > 0) (void)!write(STDERR_FILENO, line, size_t(n));
    _exit(128 + signal);  // no exit handlers: other threads may be inside HDF5 or LibTorch
  });
  g_signal_thread = waiter.native_handle();
  waiter.detach();
  struct sigaction forward;
  std::memset(&forward, 0, sizeof(forward));
  forward.sa_handler = forward_to_signal_thread;
  sigemptyset(&forward.sa_mask);
  forward.sa_flags = SA_RESTART;
  for (const int signal : kTerminationSignals) sigaction(signal, &forward, nullptr);
}

// The deepest subcommand the command line reached (the program itself when none).
const CLI::App* deepest_command(const CLI::App& app) {
  const CLI::App* at = &app;
  for (auto parsed = at->get_subcommands(); !parsed.empty(); parsed = at->get_subcommands()) at = parsed.front();
  return at;
}

// The one-line message of a command-line error, with the help that lists the options ("amt dataset build
// --help"). An unknown command is named with the known ones (CLI11 only says that one is required).
std::string usage_error(const CLI::App& app, const CLI::ParseError& e) {
  const CLI::App* at = deepest_command(app);
  std::string command = "amt";
  for (const CLI::App* p = at; p != &app && p != nullptr; p = p->get_parent()) command.insert(3, " " + p->get_name());
  std::string message = e.what();
  const std::vector<std::string> rest = at->remaining();
  if (at->get_require_subcommand_min() > 0 && at->get_subcommands().empty() && !rest.empty()) {
    message = "expected a command (";
    const auto known = at->get_subcommands([](const CLI::App*) { return true; });
    for (size_t k = 0; k < known.size(); ++k) message += (k > 0 ? ", " : "") + known[k]->get_name();
    message += "), found '" + rest.front() + "'";
  }
  std::replace(message.begin(), message.end(), '\n', ' ');
  return message + " (" + command + " --help lists the options)";
}

}  // namespace

int main(int argc, char** argv) {
  prefer_passive_openmp_waiting(argv);
  remove_temporaries_on_termination_signals();
  CLI::App app{"amt: apparel-aware motion transfer for stylized characters"};
  app.set_version_flag("--version", version_text());
  app.require_subcommand(1);
  amt::app::add_dataset_command(app);
  amt::app::add_train_command(app);
  amt::app::add_eval_command(app);
  amt::app::add_animate_command(app);
  amt::app::add_bench_command(app);
  amt::app::add_view_command(app);
  amt::app::add_retarget_cloth_command(app);
  amt::app::add_refit_garment_command(app);
  amt::app::add_convert_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version print what they asked for; a command-line error (an unknown option or
    // subcommand, a missing or invalid value) is one line like amt's other errors, with status 2.
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
    std::cerr << "amt: error: " << usage_error(app, e) << "\n";
    return 2;
  } catch (const amt::Error& e) {
    std::cerr << "amt: error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "amt: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
