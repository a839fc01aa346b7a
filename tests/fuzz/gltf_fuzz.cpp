// libFuzzer target for the glTF importer (data_tools/formats/gltf_import.h): parses the input bytes as a GLB or
// glTF JSON asset from memory (no folder: external files are refused, nothing is read from disk) and,
// when that succeeds, imports the skinned character, samples every clip as a motion and evaluates
// the vertex animation of the first clip. Bad input must end in amt::Error; anything else (a crash, a
// sanitizer report, another exception, a timeout or an allocation past libFuzzer's limit) is a finding.
//
// Not part of the CMake build. Two ways to build it, from the repository root with a configured build
// directory for amt/version.h (scripts/fuzz.sh writes its own):
//
// 1. Recommended: tinygltf compiled from its header into the fuzzer, so that it is instrumented too
//    (coverage feedback inside its JSON and GLB parsing, sanitizer checks on its memory accesses).
//    Debian ships no stb_image.h, so every file gets the same TINYGLTF_NO_STB_IMAGE* options:
//
//   clang++ -std=c++17 -g -O1 -fsanitize=fuzzer,address,undefined -DAMT_FUZZ_TINYGLTF_FROM_SOURCE \
//     -DTINYGLTF_NO_STB_IMAGE -DTINYGLTF_NO_STB_IMAGE_WRITE -I. -Ibuild-gltf/generated -I/usr/include/eigen3 \
//     tests/fuzz/gltf_fuzz.cpp data_tools/formats/gltf_import.cpp data_tools/geometry/motion.cpp data_tools/geometry/skeleton.cpp \
//     data_tools/geometry/mesh.cpp data_tools/geometry/lbs.cpp -fopenmp -o build-gltf/gltf_fuzz
//
// 2. Against Debian's libtinygltf (not instrumented): the same without the three -D options, with
//    -ltinygltf at the end.
//
// Run, seeded with the Fox and the test assets:
//
//   mkdir -p build-gltf/gltf_corpus && cp data/characters/Fox.glb tests/assets/gltf/*.gl* \
//     build-gltf/gltf_corpus/
//   build-gltf/gltf_fuzz -max_len=200000 -max_total_time=120 -rss_limit_mb=2048 build-gltf/gltf_corpus
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#ifdef AMT_FUZZ_TINYGLTF_FROM_SOURCE
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
#endif

#include "data_tools/geometry/error.h"
#include "data_tools/formats/gltf_import.h"

namespace {

// A frame rate that samples at most `frames` frames of a clip of `duration` seconds.
float bounded_fps(float duration, float frames) {
  if (!(duration > 0.0f)) return 30.0f;
  return std::clamp(frames / duration, 1e-6f, 30.0f);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::optional<amt::GltfAsset> asset;
  try {
    asset = amt::parse_gltf(data, size, "fuzz.glb");
  } catch (const amt::Error&) {
    return 0;
  }
  try {
    const amt::GltfCharacter character = amt::gltf_character(*asset);
    if (character.weights.num_vertices() != character.mesh.num_vertices() || !character.mesh.V.allFinite()) {
      __builtin_trap();
    }
    for (const amt::GltfAnimationInfo& clip : asset->animations()) {
      const amt::GltfMotion motion = amt::gltf_motion(*asset, character, clip.name, bounded_fps(clip.duration(), 50));
      if (motion.motion.num_frames() < 1) __builtin_trap();
    }
  } catch (const amt::Error&) {
  }
  try {
    const float duration = asset->animations().empty() ? 0.0f : asset->animations()[0].duration();
    const std::string clip = asset->animations().empty() ? "" : asset->animations()[0].name;
    amt::gltf_vertex_animation(*asset, clip, bounded_fps(duration, 10));
  } catch (const amt::Error&) {
  }
  return 0;
}
