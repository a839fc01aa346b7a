#!/usr/bin/env bash
# The garment refit's benchmark (issue 14): `amt refit-garment` on generated bodies of 2-6k vertices dressed
# with the dataset builder's garments of 0.6-6k vertices, one run per case. Prints a Markdown table (vertices,
# the refit's wall time and its split, surface-shape distortion, fit distance, smallest gap) and the median
# time over the cases, and writes each case's before/after picture and dressed GLB to out/bench_refit/.
#
# Environment: AMT_BUILD_DIR (default build), AMT_THREADS (2), AMT_JOBS (build jobs, default nproc).
set -euo pipefail
cd "$(dirname "$0")/.."

build_dir=${AMT_BUILD_DIR:-build}
threads=${AMT_THREADS:-2}
out=out/bench_refit
export OMP_WAIT_POLICY=passive

cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build_dir" -j"${AMT_JOBS:-$(nproc)}" --target amt >/dev/null
amt="$build_dir/app/amt"
mkdir -p "$out"

# kind, source seed, target seed, body vertices, the garment's share of the dressed mesh
cases=(
  "flared_skirt 6 2 2000 0.25"
  "flared_skirt 3 11 3000 0.3"
  "pleated_skirt 5 8 3000 0.3"
  "coat_tails 4 9 3000 0.3"
  "sleeves 3 11 4000 0.3"
  "cape 7 12 5000 0.4"
  "flared_skirt 3 11 6000 0.5"
)

echo "load before: $(cut -d' ' -f1-3 /proc/loadavg), $threads threads"
echo
echo "| garment | avatars (source -> target, vertices) | garment vertices | time | shrink / inflation / fit | outer it. | distortion RMS / max | fit distance source -> target (fitted vertices) | min gap |"
echo "|---|---|---:|---:|---|---:|---|---|---:|"
times=()
for c in "${cases[@]}"; do
  read -r kind source target vertices share <<<"$c"
  name="${kind}_${source}_${target}_${vertices}"
  log="$out/$name.log"
  "$amt" refit-garment --garment "generated:$kind" --source "generated:$source:$vertices" \
    --target "generated:$target:$vertices" --garment-share "$share" --out "$out/$name.glb" \
    --picture "$out/$name.png" --threads "$threads" >"$log" 2>"$out/$name.progress"
  garment_vertices=$(sed -n 's/^garment .*: \([0-9]*\) vertices.*/\1/p' "$out/$name.progress")
  src_v=$(sed -n 's/^source .*: \([0-9]*\) vertices.*/\1/p' "$out/$name.progress")
  tgt_v=$(sed -n 's/^target .*: \([0-9]*\) vertices.*/\1/p' "$out/$name.progress")
  # "refit G onto T in 9.8 s (shrink 0.8 s, inflation 7.8 s in 3 outer iterations, fit 1.2 s in 2 Newton ..."
  line=$(grep '^refit ' "$log")
  t=$(sed -n 's/.* in \([0-9.]*\) s (shrink.*/\1/p' <<<"$line")
  split=$(sed -n 's/.*(shrink \([0-9.]*\) s, inflation \([0-9.]*\) s in \([0-9]*\) outer.*, fit \([0-9.]*\) s in.*/\1 \/ \2 \/ \4 s/p' <<<"$line")
  outer=$(sed -n 's/.* in \([0-9]*\) outer iterations.*/\1/p' <<<"$line")
  dist=$(sed -n 's/.*RMS \([0-9.]*\), max \([0-9.]*\) over.*/\1 \/ \2/p' "$log")
  fit=$(sed -n 's/.*over the \([0-9]*\) fitted vertices): \([0-9.]*\) mm on the source, \([0-9.]*\) mm on the target/\2 -> \3 mm (\1)/p' "$log")
  gap=$(sed -n 's/.*garment-avatar: \([0-9.]*\) mm; crossing triangle pairs: \([0-9]*\)/\1 mm, \2 crossing/p' "$log")
  echo "| $kind | $source -> $target ($src_v -> $tgt_v) | $garment_vertices | $t s | $split | $outer | $dist | $fit | $gap |"
  times+=("$t")
done
median=$(printf '%s\n' "${times[@]}" | sort -g | awk '{a[NR] = $1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}')
echo
echo "median time over ${#times[@]} cases: $median s (load after: $(cut -d' ' -f1-3 /proc/loadavg))"
