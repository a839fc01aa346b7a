#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz/ with clang (address and undefined-behaviour
# sanitizers) and runs each for a bounded time on a seed corpus.
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET ...]     (default 600 s; targets: bvh pmx gltf vmd)
# Work goes to build-fuzz/<target>/ (corpus, crash-* inputs). A crash input found here belongs in
# tests/assets/<format>/ with a regression test that loads it.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-600}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(bvh pmx gltf vmd)

out=build-fuzz
mkdir -p "$out/generated/amt"
printf '#pragma once\n#define AMT_VERSION "fuzz"\n' > "$out/generated/amt/version.h"
flags=(-std=c++17 -g -O1 -fsanitize=fuzzer,address,undefined -I. -I"$out/generated" -I/usr/include/eigen3)
core=(data_tools/geometry/mesh.cpp data_tools/geometry/skeleton.cpp data_tools/geometry/motion.cpp data_tools/geometry/lbs.cpp data_tools/formats/input_file.cpp)

for target in "${targets[@]}"; do
  dir="$out/$target"
  mkdir -p "$dir/corpus"
  case "$target" in
    bvh)
      sources=(data_tools/formats/bvh_import.cpp data_tools/formats/joint_map.cpp "${core[@]}")
      libs=()
      cp tests/assets/bvh/*.bvh "$dir/corpus/" 2>/dev/null || true
      ;;
    pmx)
      sources=(data_tools/formats/pmx_import.cpp "${core[@]}")
      libs=()
      cp data/pmx/*.pmx "$dir/corpus/"
      ;;
    gltf)
      # tinygltf compiled into the target, so the fuzzer instruments it too (Debian has no stb_image).
      sources=(-DAMT_FUZZ_TINYGLTF_FROM_SOURCE -DTINYGLTF_NO_STB_IMAGE -DTINYGLTF_NO_STB_IMAGE_WRITE
               data_tools/formats/gltf_import.cpp "${core[@]}")
      libs=()
      cp data/characters/*.glb "$dir/corpus/"
      cp tests/assets/gltf/* "$dir/corpus/" 2>/dev/null || true
      ;;
    vmd)
      sources=(data_tools/formats/vmd_import.cpp "${core[@]}")
      libs=()
      cp data/mocap/vmd/*.vmd "$dir/corpus/"
      ;;
    *)
      echo "fuzz: unknown target '$target' (expected bvh, pmx, gltf or vmd)" >&2
      exit 2
      ;;
  esac
  echo "fuzz: building $target"
  clang++ "${flags[@]}" "tests/fuzz/${target}_fuzz.cpp" "${sources[@]}" "${libs[@]}" -fopenmp -o "$dir/${target}_fuzz"
  echo "fuzz: running $target for $seconds s"
  (cd "$dir" && UBSAN_OPTIONS=halt_on_error=1 "./${target}_fuzz" -max_total_time="$seconds" -max_len=65536 \
    -print_final_stats=1 corpus 2>&1 | tail -n 25 | grep -E "DONE|stat::number_of_executed_units|ERROR|SUMMARY|crash" || true)
  if ls "$dir"/crash-* >/dev/null 2>&1; then
    echo "fuzz: $target found crashes: $(ls "$dir"/crash-*)" >&2
    exit 1
  fi
done
echo "fuzz: no crashes"
