// --threads reaches every pool: OpenMP, LibTorch's intra-op threads.
#include "data_tools/geometry/threads.h"

#include <ATen/Parallel.h>
#include <gtest/gtest.h>
#include <omp.h>

namespace amt {
namespace {

TEST(Threads, SetThreadCountReachesOpenMpAndLibTorch) {
  set_thread_count(1);
  EXPECT_EQ(omp_get_max_threads(), 1);
  EXPECT_EQ(at::get_num_threads(), 1);
  EXPECT_EQ(thread_count(), 1);
  set_thread_count(2);
  EXPECT_EQ(omp_get_max_threads(), 2);
  EXPECT_EQ(at::get_num_threads(), 2);
  set_thread_count(0);  // clamped to one thread
  EXPECT_EQ(thread_count(), 1);
}

}  // namespace
}  // namespace amt
