#pragma once
// One place that sets how many threads the project's numeric code uses.

namespace amt {

/// Sets the worker threads of OpenMP (geometry loops), LibTorch's intra-op pool and OpenBLAS to n.
/// Debian's OpenBLAS is the pthread build, whose pool LibTorch does not size: it is set here through
/// openblas_set_num_threads when the loaded BLAS provides it. Call once at start-up (`--threads`).
void set_thread_count(int n);

/// The number of threads set_thread_count last set (the hardware concurrency before any call).
int thread_count();

}  // namespace amt
