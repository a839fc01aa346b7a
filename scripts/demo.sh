#!/usr/bin/env bash
# The main job on bundled defaults. Until the runtime (`amt animate`) lands this runs the most
# complete job that exists: it writes an example dataset (capsule stand-in character, procedural
# walk, rigid skinning) to out/demo.h5, summarises it, exports its clip as an animated glTF to
# out/demo.glb (opens in three.js or Blender) and runs the core benchmark.
set -euo pipefail
cd "$(dirname "$0")/.."

./scripts/setup.sh
build_dir=${AMT_BUILD_DIR:-build}
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build_dir" -j"$(nproc)" --target amt

amt="$build_dir/app/amt"
mkdir -p out
echo "demo: the runtime (amt animate) is not built yet; running the most complete job that exists:"
echo "demo: an example dataset from the core pieces -> out/demo.h5"
"$amt" dataset example --out out/demo.h5
"$amt" dataset info out/demo.h5
"$amt" dataset preview out/demo.h5 --out out/demo.glb
"$amt" bench --repeats 10
echo "demo: wrote out/demo.h5 and out/demo.glb"
