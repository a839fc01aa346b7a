#!/usr/bin/env bash
# Throughput of data-parallel training (README, "Training on several processes or machines"): the local
# apparel module's one-step stage (the shipped widths, 13-frame windows, batch 1 per rank) trained by 1, 2
# and 4 ranks started as local processes with one thread each, meeting at a file:// rendezvous. Prints
# one row per world size: samples per second of all ranks together, ms per step, the gradient exchange
# per step (with the wait for the slowest rank) and of it the all-reduce of the gradients alone, once the
# ranks are in step; then a projection to 8 and 32 machines from the measured step and all-reduce times. On
# the 2-core development machine the ranks share the two cores, so 4 ranks measure contention, not scaling.
#
# usage: scripts/data_parallel_scaling.sh [OUT_DIR]   (default out/scaling; STEPS=100, AMT=build/app/amt)
set -euo pipefail
amt=${AMT:-build/app/amt}
out=${1:-out/scaling}
steps=${STEPS:-100}
data=$out/data
mkdir -p "$out"

# A small dataset of its own: 4 dressed characters of about 3000 vertices, 6 procedural 40-frame clips each.
if [ ! -f "$data/manifest.json" ]; then
  "$amt" dataset build --out "$data" --characters 4 --motions "" --procedural 6 --frames 40 --vertices 3000 \
    --threads 1 > "$out/build.txt" 2>&1
fi

apparel='{"edge_widths":[48,48,48],"decoder_widths":[48],"inertia":0.6}'
args=(train apparel --data "$data" --steps "$steps" --batch 1 --window 13 --unroll 1:1 --apparel-loss distance
      --noise 0.003 --apparel-options "$apparel" --normalizer-samples 20 --validate-every 0 --checkpoint-every 0
      --threads 1 --loader-threads 0 --quiet)

echo "| ranks | samples/s (all ranks) | ms/step | gradient exchange, ms/step | of it the all-reduce, ms/step |"
echo "|---:|---:|---:|---:|---:|"
for n in 1 2 4; do
  run=$out/ranks$n
  rm -rf "$run" "$run.rendezvous"
  pids=()
  for ((r = 0; r < n; ++r)); do
    distributed=()
    if [ "$n" -gt 1 ]; then
      distributed=(--world-size "$n" --rank "$r" --rendezvous "file://$(realpath "$run").rendezvous" --dist-timeout 120)
    fi
    "$amt" "${args[@]}" --out "$run" "${distributed[@]}" > "$run.rank$r.txt" &
    pids+=($!)
  done
  for pid in "${pids[@]}"; do wait "$pid"; done
  # Rank 0's line: "apparel: steps 0 -> S, X ms/step, Y samples/s, wall W s[, N ranks, gradient exchange E ms/step]; ..."
  line=$(cat "$run.rank0.txt")
  ms=$(sed -E 's/.*, ([0-9.e+-]+) ms\/step, .*/\1/' <<< "$line")
  rate=$(sed -E 's/.* ([0-9.e+-]+) samples\/s.*/\1/' <<< "$line")
  exchange=0 allreduce=0
  if [ "$n" -gt 1 ]; then
    exchange=$(sed -E 's/.*gradient exchange ([0-9.e+-]+) ms\/step.*/\1/' <<< "$line")
    allreduce=$(sed -E 's/.*\(all-reduce of [0-9.]+ KiB ([0-9.e+-]+)\).*/\1/' <<< "$line")
    kib=$(sed -E 's/.*\(all-reduce of ([0-9.]+) KiB.*/\1/' <<< "$line")
  fi
  printf "| %d | %.1f | %.1f | %.2f | %.2f |\n" "$n" "$rate" "$ms" "$exchange" "$allreduce"
  if [ "$n" -eq 1 ]; then compute=$ms; fi
  if [ "$n" -eq 2 ]; then pair=$allreduce; fi
done
echo "gradients exchanged per step: ${kib:-?} KiB"

# Projection to W machines with one rank each: a step is the 1-rank step (the compute of one sample) plus the
# all-reduce. Gloo's ring all-reduce makes 2 (W - 1) transfers of 1/W of the gradients one after the other; at this
# size each is bound by latency, not bandwidth, so it takes (W - 1) times the 2-rank all-reduce (2 transfers).
echo
echo "| machines (projected) | ms/step | of it the all-reduce | samples/s | speed-up over 1 rank |"
echo "|---:|---:|---:|---:|---:|"
for w in 8 32; do
  awk -v w="$w" -v c="$compute" -v a="$pair" 'BEGIN {
    ar = (w - 1) * a; step = c + ar
    printf "| %d | %.1f | %.1f | %.0f | %.1fx |\n", w, step, ar, 1000 * w / step, w * c / step }'
done
