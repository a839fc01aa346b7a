// libFuzzer entry point for the PMX reader (not built by CMake). Every input must either parse or throw amt::Error;
// anything else (a crash, a sanitizer report, another exception, an allocation past libFuzzer's limit) is a bug.
// Parsed models also go through the conversion to amt's frame, the mesh and the skinning weights.
//
// Build and run from the repository root (seeded with the PMX fixtures in data/pmx):
//   clang++ -std=c++17 -g -O1 -fsanitize=fuzzer,address,undefined -I. -I/usr/include/eigen3 \
//       tests/fuzz/pmx_fuzz.cpp data_tools/formats/pmx_import.cpp -o /tmp/pmx_fuzz
//   mkdir -p /tmp/pmx_corpus && cp data/pmx/*.pmx /tmp/pmx_corpus/
//   /tmp/pmx_fuzz -max_total_time=120 -max_len=8192 /tmp/pmx_corpus
#include <cstddef>
#include <cstdint>

#include "data_tools/geometry/error.h"
#include "data_tools/formats/pmx_import.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const amt::PmxModel model = amt::parse_pmx(data, size, "fuzz.pmx");
    const amt::PmxModel converted = amt::pmx_to_amt_frame(model);
    const amt::TriMesh mesh = amt::pmx_mesh(converted);
    if (!converted.bones.empty()) {
      const amt::SparseWeights weights = amt::pmx_skin_weights(converted);
      if (weights.num_vertices() != mesh.num_vertices() || !weights.weights.allFinite()) __builtin_trap();
    }
  } catch (const amt::Error&) {
  }
  return 0;
}
