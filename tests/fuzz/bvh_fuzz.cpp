// libFuzzer target for the BVH importer (data_tools/formats/bvh_import.h): parses the input bytes as a BVH
// file from memory and, when that succeeds, runs the whole import onto the canonical skeleton (unit
// detection, conversion, joint mapping, composition, resampling). Bad input must end in amt::Error;
// anything else (a crash, a sanitizer report, another exception) is a finding. Not part of the CMake
// build. Build and run from the repository root, with a configured build directory for amt/version.h:
//
//   clang++ -std=c++17 -g -O1 -fsanitize=fuzzer,address,undefined -I. -Ibuild-bvh/generated \
//     -I/usr/include/eigen3 tests/fuzz/bvh_fuzz.cpp data_tools/formats/bvh_import.cpp data_tools/formats/joint_map.cpp \
//     data_tools/geometry/motion.cpp data_tools/geometry/skeleton.cpp -o build-bvh/bvh_fuzz
//   mkdir -p build-bvh/bvh_corpus && cp tests/assets/bvh/*.bvh tests/assets/bvh/bad/*.bvh build-bvh/bvh_corpus/
//   build-bvh/bvh_fuzz -max_len=8192 -max_total_time=120 build-bvh/bvh_corpus
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "data_tools/formats/bvh_import.h"
#include "data_tools/geometry/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  amt::BvhFile file;
  try {
    file = amt::parse_bvh(text, "fuzz.bvh");
  } catch (const amt::Error&) {
    return 0;
  }
  try {
    amt::BvhImportOptions options;
    // Resampling a clip whose frame time is long makes many frames (up to resample_motion's bound of
    // 1 000 000): correct, but it would slow the search down, so long clips keep the file's rate.
    if (file.num_frames * file.frame_time * 30.0 > 10000.0) options.fps = std::nullopt;
    amt::bvh_to_canonical(file, options);
  } catch (const amt::Error&) {
  }
  return 0;
}
