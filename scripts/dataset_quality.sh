#!/usr/bin/env bash
# The dataset builder's quality gates (issue 4) on the default dataset: builds `amt`, builds the default
# dataset into data/default with two processes (--shard 0/2 and 1/2, one thread each) unless it is
# complete already (a rerun resumes an interrupted build), then runs `amt dataset check`, which prints
# one PASS/FAIL line per gate and writes data/default/quality/report.md and characters.png.
# Prints the build's wall time and frames per second. Exits non-zero when a gate fails.
#
# Environment: AMT_BUILD_DIR (default build), AMT_DATASET_DIR (default data/default), AMT_SEED (1),
# AMT_CHARACTERS (32), AMT_SHARDS (2 processes).
set -euo pipefail
cd "$(dirname "$0")/.."

build_dir=${AMT_BUILD_DIR:-build}
out=${AMT_DATASET_DIR:-data/default}
seed=${AMT_SEED:-1}
characters=${AMT_CHARACTERS:-32}
shards=${AMT_SHARDS:-2}
export OMP_WAIT_POLICY=passive

cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build_dir" -j"$(nproc)" --target amt
amt="$build_dir/app/amt"

shards_done=$( (find "$out" -maxdepth 1 -name 'character-*.h5' 2>/dev/null || true) | wc -l)
if [ "$shards_done" -lt "$characters" ]; then
  echo "dataset_quality: building $out ($characters characters, seed $seed, $shards processes; load: $(cut -d' ' -f1-3 /proc/loadavg))"
  mkdir -p "$(dirname "$out")"
  start=$(date +%s)
  pids=()
  for ((i = 0; i < shards; i++)); do
    "$amt" dataset build --out "$out" --seed "$seed" --characters "$characters" --shard "$i/$shards" --threads 1 \
      2> "$out.shard-$i.log" &
    pids+=($!)
  done
  status=0
  for pid in "${pids[@]}"; do wait "$pid" || status=1; done
  end=$(date +%s)
  for ((i = 0; i < shards; i++)); do tail -n 2 "$out.shard-$i.log"; done
  if [ "$status" -ne 0 ]; then
    echo "dataset_quality: a build process failed (logs: $out.shard-*.log)" >&2
    exit 1
  fi
  frames=$(grep -h '^built ' "$out".shard-*.log | sed -E 's/.* clips \([0-9]+ already done\), ([0-9]+) frames.*/\1/' |
    awk '{ sum += $1 } END { print sum }')
  echo "dataset_quality: built in $((end - start)) s wall, $frames frames, $((frames / (end - start + 1))) frames/s"
fi
du -sh "$out"
"$amt" dataset check "$out" --threads 2
