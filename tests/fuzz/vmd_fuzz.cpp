// libFuzzer entry point for the VMD reader (not built by CMake; scripts/fuzz.sh builds it). Every input must either
// parse or throw amt::Error; anything else (a crash, a sanitizer report, another exception) is a bug. Parsed motions
// also go through the per-bone tracks and the Bézier sampling between their keys, whose poses must be finite.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "data_tools/formats/vmd_import.h"
#include "data_tools/geometry/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const amt::VmdMotion motion = amt::parse_vmd(data, size, "fuzz.vmd");
    for (const auto& [name, track] : amt::vmd_bone_tracks(motion)) {
      if (track.empty()) continue;
      const float last = float(track.back().frame);
      for (const float frame : {0.0f, 0.5f * last, last + 1.0f}) {
        const amt::VmdBonePose pose = amt::vmd_sample(track, frame);
        if (!pose.translation.allFinite() || !std::isfinite(pose.rotation.w())) __builtin_trap();
      }
    }
  } catch (const amt::Error&) {
  }
  return 0;
}
