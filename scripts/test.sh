#!/usr/bin/env bash
# The whole test suite from a fresh clone: installs what is missing, configures, builds, runs ctest.
# Idempotent; a second run only rebuilds what changed. AMT_BUILD_DIR picks the build folder, AMT_JOBS the
# number of build jobs and test processes (default: all cores).
set -euo pipefail
cd "$(dirname "$0")/.."

./scripts/setup.sh
build_dir=${AMT_BUILD_DIR:-build}
jobs=${AMT_JOBS:-$(nproc)}
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DAMT_BUILD_TESTS=ON
cmake --build "$build_dir" -j"$jobs"
cd "$build_dir"
ctest --output-on-failure -j"$jobs" --timeout 600
