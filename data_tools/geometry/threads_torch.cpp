#include <ATen/Parallel.h>
#include <dlfcn.h>
#include <omp.h>

#include <algorithm>
#include <thread>

#include "data_tools/geometry/threads.h"

namespace amt {

namespace {
int current_threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

void set_thread_count(int n) {
  n = std::max(1, n);
  omp_set_num_threads(n);
  at::set_num_threads(n);
  // The BLAS is whatever libblas.so.3 the system's alternatives point at; only OpenBLAS has this.
  using SetThreads = void (*)(int);
  if (auto openblas = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) openblas(n);
  current_threads = n;
}

int thread_count() { return current_threads; }

}  // namespace amt
