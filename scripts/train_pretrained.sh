#!/usr/bin/env bash
# Trains the shipped small model (issue 5) on a dataset folder: the apparel segmenter, the skinning
# predictor with its two Table 4 variants (no_geodesic, sorted), and the apparel module + refiner
# end to end, in about half an hour on this 2-core machine. Writes <OUT_DIR>/<module>.ckpt and
# <OUT_DIR>/<module>.csv (segmenter, skinning, skinning_no_geodesic, skinning_sorted, apparel +
# refiner with the log apparel_refiner.csv), about 1.8 MB of checkpoints in all, and prints the step
# time, throughput and wall time of each module.
#
#   scripts/train_pretrained.sh DATA_DIR [OUT_DIR=models/pretrained]
#
# Environment: AMT (the amt program, default build/app/amt), THREADS (default 2), SEED (default 1).
#
# Sizing, measured on a 4,800-vertex character with 32 % apparel (10-frame windows, 4-frame skinning
# samples), small configuration below, 2 threads: segmenter 20-26 ms/step, skinning 200-260 ms/step
# (no_geodesic 170, sorted 36), apparel + refiner 112-212 ms/step, the lower figures on a quieter
# machine, the higher ones while other jobs shared the 2 cores. With the variants trained beside
# the main chain, the whole run took 31 minutes (segmenter 10, then the apparel + refiner run 21).
# The learning rate is 5e-4 rather than the paper's 1e-4 because this budget is a few thousand steps.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 ]]; then
  echo "usage: scripts/train_pretrained.sh DATA_DIR [OUT_DIR=models/pretrained]" >&2
  exit 2
fi
data=$1
out=${2:-models/pretrained}
amt=${AMT:-build/app/amt}
threads=${THREADS:-2}
seed=${SEED:-1}
[[ -x "$amt" ]] || { echo "train_pretrained.sh: $amt: no amt program (build it, or set AMT)" >&2; exit 2; }
[[ -e "$data" ]] || { echo "train_pretrained.sh: $data: no such dataset file or folder" >&2; exit 2; }
export OMP_WAIT_POLICY=passive
mkdir -p "$out"

# The small configuration: network widths of the shipped model.
segmenter='{"encoder_widths":[32,64,128],"decoder_widths":[64,32]}'
skinning='{"feature_widths":[32,32],"attention_widths":[16,16],"head_encoder_widths":[32,64,128],"head_decoder_widths":[64,32]}'
apparel='{"motion_widths":[64],"motion_code":16,"edge_widths":[32,32,64],"decoder_widths":[32]}'
refiner='{"hidden_widths":[32,32]}'
common=(--data "$data" --out "$out" --seed "$seed" --lr 5e-4 --batch 1
        --checkpoint-every 500 --validate-every 500 --validation-samples 16)

start_all=$SECONDS
run() {  # run NAME ARGS...: one training run and its wall time
  local name=$1 start=$SECONDS
  shift
  echo "== $name: $amt train $*" >&2
  "$amt" train "$@"
  echo "== $name: wall $((SECONDS - start)) s" >&2
}

# The segmenter first (2 threads), then four runs side by side on one thread each: the skinning
# predictor, its two Table 4 variants, and the apparel module + refiner end to end. The end-to-end
# run tiles Â with B̂ skinned by the ground-truth body weights (no --skinning), so it need not wait
# for the skinning predictor; at evaluation B̂ comes from the predicted weights.
run segmenter segmenter "${common[@]}" --threads "$threads" --steps 4000 --segmenter-options "$segmenter"
pids=()
run skinning skinning "${common[@]}" --threads 1 --steps 4000 --skinning-options "$skinning" \
  > "$out/skinning.log" 2>&1 & pids+=($!)
run skinning_no_geodesic skinning "${common[@]}" --threads 1 --steps 2500 --variant no_geodesic \
  --skinning-options "$skinning" > "$out/skinning_no_geodesic.log" 2>&1 & pids+=($!)
run skinning_sorted skinning "${common[@]}" --threads 1 --steps 2500 --variant sorted \
  --skinning-options "$skinning" > "$out/skinning_sorted.log" 2>&1 & pids+=($!)
run apparel_refiner apparel_refiner "${common[@]}" --threads 1 --steps 8000 --window 10 \
  --apparel-options "$apparel" --refiner-options "$refiner" > "$out/apparel_refiner.log" 2>&1 & pids+=($!)
status=0
for pid in "${pids[@]}"; do wait "$pid" || status=1; done
for name in skinning skinning_no_geodesic skinning_sorted apparel_refiner; do tail -n 2 "$out/$name.log" >&2; done
[[ $status -eq 0 ]] || { echo "train_pretrained.sh: a training run failed (logs: $out/*.log)" >&2; exit 1; }
echo "== all: wall $((SECONDS - start_all)) s; checkpoints:" >&2
ls -l "$out"/*.ckpt >&2
