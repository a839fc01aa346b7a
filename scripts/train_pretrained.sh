#!/usr/bin/env bash
# Trains the shipped small model on one or more dataset folders: the apparel segmenter, the skinning predictor
# with its two Table 4 variants (no_geodesic, sorted), the apparel module (local form,
# models/apparel_dynamics.h) and then the refiner on the apparel module's rollouts. Writes
# <OUT_DIR>/<module>.ckpt and <OUT_DIR>/<module>.csv and prints the step time, throughput and wall
# time of each run.
#
#   scripts/train_pretrained.sh DATA_DIR[,DATA_DIR...] [OUT_DIR=models/pretrained]
#
# Several folders, separated by commas, train on all their shards together (validation on the held-out
# characters of all of them).
#
# Environment: AMT (the amt program, default build/app/amt), SEED (default 1), MODULES (which runs,
# default "segmenter skinning apparel": "apparel" is the apparel module followed by the refiner), and
# the steps of each run: SEGMENTER_STEPS (30000) and SEGMENTER_ARTIST_STEPS (12000) for the segmenter's two
# stages, SKINNING_STEPS (6000, also for each Table 4
# variant, so the three compare at the same budget), APPAREL_ONE_STEP_STEPS (30000), APPAREL_STEPS
# (16000), APPAREL_HANDLE_STEPS (10000) and APPAREL_FINE_HANDLE_STEPS (4000) for the apparel module's four
# stages, HANDLES_DATA (the data of the last two, default: DATA_DIR), APPAREL_OWN_STEPS (4000, each of the two runs
# of apparel_own_weights.ckpt, the module for characters with their own skin), REFINER_STEPS (2000), and
# APPAREL_SKINNING: the
# skinning checkpoint whose predicted body weights skin the apparel module's anchors and the refiner's
# body during training, as at run time (default <OUT_DIR>/skinning.ckpt; "none" for the ground-truth
# weights).
#
# The segmenter and the skinning runs go side by side, one thread each; the apparel module trains
# with one thread beside them (after the skinning runs when it uses the predictor trained here), then
# the refiner on its rollouts. Every run uses AdamW at 5e-4 with a
# cosine decay to 0 (the paper's 1e-4 is for far longer training than this budget). Settings beyond
# the paper, measured in models/pretrained/README.md: the segmenter reads welded shape features, trains on
# augmented characters (open parts, bare bodies; in a second stage artist-style remakes) and weighs the held
# rows, where a piece hangs from the body, 5 times (--segmenter-held-weight 5); the skinning predictor adds a direct KL loss on
# the weights (--weight-loss 0.1) to the paper's indirect LBS loss; the apparel module predicts the
# change of each vertex's detail vector in its anchor joint's frame (anchored where each piece
# attaches) around the inertial rule (inertia 0.6),
# with normalised inputs and target and contact inputs (its nearest body vertex), 1 mm of noise on its input
# history; first 30000 one-step steps of 4 windows, then from that network a curriculum of rollouts (5, then 20
# frames; a fifth of the windows rolled out from the rest pose) with up to 40 frames of free run on its
# own predictions before them (pushforward); the per-vertex distance as the loss. The refiner weighs its
# edge-length term 1 (--edge-weight 1) where the paper weighs it 100: at 100 it pulls the apparel towards its
# rest edge lengths, which the simulated apparel does not keep, and costs PMD.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 ]]; then
  echo "usage: scripts/train_pretrained.sh DATA_DIR[,DATA_DIR...] [OUT_DIR=models/pretrained]" >&2
  exit 2
fi
IFS=, read -r -a data <<< "$1"
out=${2:-models/pretrained}
amt=${AMT:-build/app/amt}
seed=${SEED:-1}
[[ -x "$amt" ]] || { echo "train_pretrained.sh: $amt: no amt program (build it, or set AMT)" >&2; exit 2; }
for dir in "${data[@]}"; do
  [[ -e "$dir" ]] || { echo "train_pretrained.sh: $dir: no such dataset file or folder" >&2; exit 2; }
done
export OMP_WAIT_POLICY=passive
mkdir -p "$out"

# The small configuration: network widths of the shipped model.
segmenter='{"encoder_widths":[32,64,128],"decoder_widths":[64,32]}'
skinning='{"feature_widths":[32,32],"attention_widths":[16,16],"head_encoder_widths":[32,64,128],"head_decoder_widths":[64,32]}'
apparel='{"edge_widths":[48,48,48],"decoder_widths":[48],"inertia":0.6}'
refiner='{"hidden_widths":[32,32]}'
unbatched=(--data "${data[@]}" --seed "$seed" --lr-schedule cosine --threads 1 --validation-samples 16)
base=("${unbatched[@]}" --batch 1)
common=("${base[@]}" --out "$out" --lr 5e-4 --checkpoint-every 1000 --validate-every 1000)

start_all=$SECONDS
run() {  # run NAME ARGS...: one training run and its wall time
  local name=$1 start=$SECONDS
  shift
  echo "== $name: $amt train $*" >&2
  "$amt" train "$@" || { echo "== $name: failed after $((SECONDS - start)) s" >&2; return 1; }
  echo "== $name: wall $((SECONDS - start)) s" >&2
}

# The apparel module's anchors and the refiner's body are skinned with the skinning predictor's
# weights (APPAREL_SKINNING), as at evaluation and at run time.
modules=" ${MODULES:-segmenter skinning apparel} "
pids=()
names=()
launch() {  # launch NAME ARGS...: one run in the background, its output in <out>/NAME.log
  local name=$1
  shift
  run "$name" "$@" > "$out/$name.log" 2>&1 &
  pids+=($!)
  names+=("$name")
}
if [[ $modules == *" segmenter "* ]]; then
  # Two stages: the segmenter on the characters as built and their augmentations (into <out>/segmenter_base/),
  # then fine-tuned from it with 30 % of its steps on the characters remade as artists build models
  # (--segmenter-artist-style 0.3: UV seams with coincident copies, hair strips, double-sided and layered panels).
  segmenter_stages() {
    run segmenter_base segmenter "${base[@]}" --out "$out/segmenter_base" --lr 5e-4 --checkpoint-every 1000 \
      --validate-every 1000 --steps "${SEGMENTER_STEPS:-30000}" --segmenter-held-weight 5 \
      --segmenter-options "$segmenter" &&
      run segmenter segmenter "${base[@]}" --out "$out" --lr 2e-4 --checkpoint-every 1000 --validate-every 1000 \
        --steps "${SEGMENTER_ARTIST_STEPS:-12000}" --segmenter-held-weight 5 \
        --init "$out/segmenter_base/segmenter.ckpt" --segmenter-artist-style 0.3
  }
  segmenter_stages > "$out/segmenter.log" 2>&1 &
  pids+=($!)
  names+=(segmenter)
fi
if [[ $modules == *" skinning "* ]]; then
  launch skinning skinning "${common[@]}" --steps "${SKINNING_STEPS:-6000}" --weight-loss 0.1 \
    --skinning-options "$skinning"
  skinning_pid=${pids[-1]}
  launch skinning_no_geodesic skinning "${common[@]}" --steps "${SKINNING_STEPS:-6000}" --weight-loss 0.1 \
    --variant no_geodesic --skinning-options "$skinning"
  launch skinning_sorted skinning "${common[@]}" --steps "${SKINNING_STEPS:-6000}" --weight-loss 0.1 \
    --variant sorted --skinning-options "$skinning"
fi
if [[ $modules == *" apparel "* ]]; then
  # The apparel module (63-frame windows: 3 ground-truth states, up to 40 free-run frames without
  # gradient and up to 20 rolled-out frames with it), then
  # the refiner on its rollouts.
  # Two stages: many cheap one-step (teacher-forced, noised) steps, where the network learns the
  # dynamics, then the rollout curriculum from that network (--init), where it learns to stay stable
  # on its own predictions. The one-step stage writes into <out>/apparel_one_step/, the rollout stage into
  # <out>/apparel_vertices/ (the per-vertex module). A third stage fine-tunes that network on handles 3 cm
  # apart (--handle-spacing 0.03: the module moves the handles and every vertex follows them, so seams and
  # strip bundles cannot come apart) on HANDLES_DATA (comma-separated folders; default: the data above), into
  # <out>/apparel_handles_3cm/, and a fourth that one on handles 2 cm apart, at half the learning rate, into
  # <out>/apparel_handles_2cm/. The last two stages fine-tune it on HANDLES_DATA plus its characters remade as
  # artists build models (`amt dataset artist-style`: UV seams with coincident copies, hair strips, double-sided and
  # layered panels, about 20k vertices; 16 clips each, written to ARTIST_DATA, default <out>/artist_style_data,
  # about 7 GB for data/default), 4000 steps into <out>/apparel_artist_style/, then 6000 more (seed + 1) into <out>.
  anchor_skinning=${APPAREL_SKINNING:-$out/skinning.ckpt}
  IFS=, read -r -a handles_data <<< "${HANDLES_DATA:-$1}"
  skinning_args=()
  [[ $anchor_skinning == none ]] || skinning_args=(--skinning "$anchor_skinning")
  artist_data=${ARTIST_DATA:-$out/artist_style_data}
  artist_style_data() {  # the first HANDLES_DATA folder's shards remade artist-style (kept when already there)
    mkdir -p "$artist_data"
    local shard name
    for shard in "${handles_data[0]}"/*.h5; do
      name=$(basename "$shard")
      [[ -f $artist_data/$name ]] && continue
      "$amt" dataset artist-style "$shard" --out "$artist_data/$name" --max-clips 16 --threads 1 --quiet || return 1
    done
  }
  own_weights_module() {
    # apparel_own_weights.ckpt: the module for characters with their own skin (amt animate --skin-weights auto on a
    # PMX, skinned glTF or VRM), whose anchors come from those weights: the shipped module fine-tuned with half of
    # the characters on ground-truth anchors (--anchor-truth-share 0.5; all of them without a predictor), two runs
    # of APPAREL_OWN_STEPS (4000) each, seeds + 2 and + 3.
    local share=()
    [[ ${#skinning_args[@]} -gt 0 ]] && share=(--anchor-truth-share 0.5)
    local init=$out/apparel.ckpt stage k
    for k in 1 2; do
      stage=apparel_own_weights_$k
      run "$stage" apparel --data "${handles_data[@]}" "$artist_data" --seed "$((seed + 1 + k))" \
        --lr-schedule cosine --threads 1 --validation-samples 16 --batch 1 "${skinning_args[@]}" "${share[@]}" \
        --out "$out/$stage" --checkpoint-every 500 --validate-every 1000 --init "$init" --handle-spacing 0.02 \
        --lr 1e-4 --steps "${APPAREL_OWN_STEPS:-4000}" --window 63 --free-run 40 --apparel-loss distance \
        --unroll 5:0.3,20:1 || return 1
      init=$out/$stage/apparel.ckpt
    done
    cp "$init" "$out/apparel_own_weights.ckpt"
  }
  apparel_then_refiner() {
    # The predictor trained here must be written before the apparel module reads it.
    if [[ -n ${skinning_pid:-} && $anchor_skinning == "$out/skinning.ckpt" ]]; then
      while kill -0 "$skinning_pid" 2> /dev/null; do sleep 10; done
    fi
    if [[ $anchor_skinning != none && ! -f $anchor_skinning ]]; then
      echo "train_pretrained.sh: $anchor_skinning: no skinning checkpoint for the apparel anchors" \
        "(train the skinning module first, or set APPAREL_SKINNING=none)" >&2
      return 1
    fi
    run apparel_one_step apparel "${unbatched[@]}" --batch 4 "${skinning_args[@]}" --out "$out/apparel_one_step" \
      --lr 5e-4 --steps "${APPAREL_ONE_STEP_STEPS:-30000}" --validate-every 5000 --checkpoint-every 5000 --window 13 \
      --unroll 1:1 --apparel-loss distance --apparel-form local --noise 0.001 --apparel-options "$apparel" &&
      run apparel_vertices apparel "${base[@]}" "${skinning_args[@]}" --out "$out/apparel_vertices" \
        --checkpoint-every 1000 --validate-every 1000 --init "$out/apparel_one_step/apparel.ckpt" --lr 2e-4 \
        --steps "${APPAREL_STEPS:-16000}" --window 63 --free-run 40 --apparel-loss distance --unroll 5:0.3,20:1 \
        --noise 0.001 --rest-start 0.2 &&
      run apparel_handles_3cm apparel --data "${handles_data[@]}" --seed "$seed" --lr-schedule cosine --threads 1 \
        --validation-samples 16 --batch 1 "${skinning_args[@]}" --out "$out/apparel_handles_3cm" \
        --checkpoint-every 500 --validate-every 1000 --init "$out/apparel_vertices/apparel.ckpt" \
        --handle-spacing 0.03 --lr 2e-4 --steps "${APPAREL_HANDLE_STEPS:-10000}" --window 63 --free-run 40 \
        --apparel-loss distance --unroll 5:0.3,20:1 &&
      run apparel_handles_2cm apparel --data "${handles_data[@]}" --seed "$seed" --lr-schedule cosine --threads 1 \
        --validation-samples 16 --batch 1 "${skinning_args[@]}" --out "$out/apparel_handles_2cm" \
        --checkpoint-every 500 --validate-every 1000 --init "$out/apparel_handles_3cm/apparel.ckpt" \
        --handle-spacing 0.02 --lr 1e-4 --steps "${APPAREL_FINE_HANDLE_STEPS:-4000}" --window 63 --free-run 40 \
        --apparel-loss distance --unroll 5:0.3,20:1 &&
      artist_style_data &&
      run apparel_artist_style apparel --data "${handles_data[@]}" "$artist_data" --seed "$seed" \
        --lr-schedule cosine --threads 1 --validation-samples 16 --batch 1 "${skinning_args[@]}" \
        --out "$out/apparel_artist_style" --checkpoint-every 500 --validate-every 1000 \
        --init "$out/apparel_handles_2cm/apparel.ckpt" --handle-spacing 0.02 --lr 1e-4 \
        --steps "${APPAREL_ARTIST_STEPS:-4000}" --window 63 --free-run 40 --apparel-loss distance \
        --unroll 5:0.3,20:1 &&
      run apparel apparel --data "${handles_data[@]}" "$artist_data" --seed "$((seed + 1))" --lr-schedule cosine \
        --threads 1 --validation-samples 16 --batch 1 "${skinning_args[@]}" --out "$out" --checkpoint-every 500 \
        --validate-every 1000 --init "$out/apparel_artist_style/apparel.ckpt" --handle-spacing 0.02 --lr 1e-4 \
        --steps "${APPAREL_ARTIST_MORE_STEPS:-6000}" --window 63 --free-run 40 --apparel-loss distance \
        --unroll 5:0.3,20:1 &&
      own_weights_module &&
      run refiner refiner "${common[@]}" "${skinning_args[@]}" --steps "${REFINER_STEPS:-2000}" \
        --apparel "$out/apparel.ckpt" --edge-weight 1 \
        --refiner-options "$refiner"
  }
  apparel_then_refiner > "$out/apparel.log" 2>&1 &
  pids+=($!)
  names+=(apparel)
fi
status=0
for pid in "${pids[@]}"; do wait "$pid" || status=1; done
for name in "${names[@]}"; do tail -n 2 "$out/$name.log" >&2; done
[[ $status -eq 0 ]] || { echo "train_pretrained.sh: a training run failed (logs: $out/*.log)" >&2; exit 1; }
echo "== all: wall $((SECONDS - start_all)) s; checkpoints:" >&2
ls -l "$out"/*.ckpt >&2
