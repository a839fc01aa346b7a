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
# Environment: AMT (the amt program, default build/app/amt), SEED (default 1), and the steps of
# each run: SEGMENTER_STEPS (12000), SKINNING_STEPS (6000, also for each Table 4 variant, so the
# three compare at the same budget), APPAREL_STEPS (4500 for the apparel module + refiner) and
# APPAREL_WINDOW (20 frames: 3 ground-truth states, then 17 frames the module rolls out on its own
# predictions; 10-frame windows at 9000 steps, the same frames in all, left it drifting in long
# rollouts, see models/pretrained/README.md).
#
# All five runs go side by side, one thread each: the segmenter, the skinning predictor and its two
# Table 4 variants, and the apparel module + refiner end to end. Every run uses AdamW at 5e-4 with a
# cosine decay to 0 (the paper's 1e-4 is for far longer training than this budget of a few thousand
# steps). Two settings go beyond the paper, both measured against it in models/pretrained/README.md:
# the skinning predictor adds a direct KL loss on the weights (--weight-loss 0.1) to the paper's
# indirect LBS loss, and the apparel module is conditioned on its skinned anchor (the network
# option skinned_anchor, on by default).
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 ]]; then
  echo "usage: scripts/train_pretrained.sh DATA_DIR [OUT_DIR=models/pretrained]" >&2
  exit 2
fi
data=$1
out=${2:-models/pretrained}
amt=${AMT:-build/app/amt}
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
common=(--data "$data" --out "$out" --seed "$seed" --lr 5e-4 --lr-schedule cosine --batch 1 --threads 1
        --checkpoint-every 1000 --validate-every 1000 --validation-samples 16)

start_all=$SECONDS
run() {  # run NAME ARGS...: one training run and its wall time
  local name=$1 start=$SECONDS
  shift
  echo "== $name: $amt train $*" >&2
  "$amt" train "$@"
  echo "== $name: wall $((SECONDS - start)) s" >&2
}

# The end-to-end run tiles Â with B̂ skinned by the ground-truth body weights (no --skinning) and
# skins the apparel anchors with them too, so it need not wait for the skinning predictor; at
# evaluation and at run time both come from the predicted weights.
pids=()
launch() {  # launch NAME ARGS...: one run in the background, its output in <out>/NAME.log
  local name=$1
  shift
  run "$name" "$@" > "$out/$name.log" 2>&1 &
  pids+=($!)
}
launch segmenter segmenter "${common[@]}" --steps "${SEGMENTER_STEPS:-12000}" --segmenter-options "$segmenter"
launch skinning skinning "${common[@]}" --steps "${SKINNING_STEPS:-6000}" --weight-loss 0.1 \
  --skinning-options "$skinning"
launch skinning_no_geodesic skinning "${common[@]}" --steps "${SKINNING_STEPS:-6000}" --weight-loss 0.1 \
  --variant no_geodesic --skinning-options "$skinning"
launch skinning_sorted skinning "${common[@]}" --steps "${SKINNING_STEPS:-6000}" --weight-loss 0.1 \
  --variant sorted --skinning-options "$skinning"
launch apparel_refiner apparel_refiner "${common[@]}" --steps "${APPAREL_STEPS:-4500}" --window "${APPAREL_WINDOW:-20}" \
  --apparel-options "$apparel" --refiner-options "$refiner"
status=0
for pid in "${pids[@]}"; do wait "$pid" || status=1; done
for name in segmenter skinning skinning_no_geodesic skinning_sorted apparel_refiner; do tail -n 2 "$out/$name.log" >&2; done
[[ $status -eq 0 ]] || { echo "train_pretrained.sh: a training run failed (logs: $out/*.log)" >&2; exit 1; }
echo "== all: wall $((SECONDS - start_all)) s; checkpoints:" >&2
ls -l "$out"/*.ckpt >&2
