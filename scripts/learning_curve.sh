#!/usr/bin/env bash
# The apparel module's learning curve: held-out PMD_a against the number of training characters.
# For each count K it trains the local apparel module on the first K training-character shards of
# the given dataset folders (in name order, folders in the given order), with the same short recipe
# for every K, and evaluates it on the held-out characters of the first folder (the apparel module
# on the ground-truth mask and weights, as the zero-network rules use them: method apparel_gt)
# beside the hold_offset rule. A count whose checkpoint exists is not trained again. Prints one table row per K and writes OUT_DIR/learning_curve.md.
#
#   scripts/learning_curve.sh OUT_DIR DATA_DIR [MORE_DATA_DIRS...]
#
# Environment: AMT (default build/app/amt), MODEL (the folder whose segmenter, skinning and refiner
# checkpoints complete each evaluated model, default models/pretrained), COUNTS (default
# "8 16 28"), STEPS (2000), UNROLL (1:0.5,5:1), EVAL_CLIPS (12 held-out clips), THREADS (1).
set -euo pipefail

if [[ $# -lt 2 ]]; then
  echo "usage: scripts/learning_curve.sh OUT_DIR DATA_DIR [MORE_DATA_DIRS...]" >&2
  exit 2
fi
out=$1
shift
data_dirs=("$@")
amt=${AMT:-build/app/amt}
model=${MODEL:-models/pretrained}
threads=${THREADS:-1}
[[ -x "$amt" ]] || { echo "learning_curve.sh: $amt: no amt program (build it, or set AMT)" >&2; exit 2; }
command -v python3 >/dev/null || { echo "learning_curve.sh: needs python3 to read metrics.json (apt-get install python3)" >&2; exit 2; }
export OMP_WAIT_POLICY=passive
mkdir -p "$out"

# Training-character shards in order: a shard's split is in its character record (<name>.json).
train_shards=()
for dir in "${data_dirs[@]}"; do
  for shard in "$dir"/character-*.h5; do
    record=${shard%.h5}.json
    if grep -q '"split": *"train"' "$record"; then train_shards+=("$shard"); fi
  done
done
echo "learning_curve.sh: ${#train_shards[@]} training characters in ${data_dirs[*]}" >&2

table="$out/learning_curve.md"
{
  echo "| training characters | steps | apparel module, paper (cm) | hold_offset, paper (cm) | apparel module, rollout (cm) | wall (s) |"
  echo "|---:|---:|---:|---:|---:|---:|"
} > "$table"
for count in ${COUNTS:-8 16 28}; do
  if (( count > ${#train_shards[@]} )); then
    echo "learning_curve.sh: only ${#train_shards[@]} training characters, skipping $count" >&2
    continue
  fi
  run="$out/k$count"
  mkdir -p "$run/model"
  start=$SECONDS
  [[ -f "$run/apparel.ckpt" ]] || "$amt" train apparel --data "${train_shards[@]:0:count}" --out "$run" \
    --steps "${STEPS:-2000}" --window 23 --unroll "${UNROLL:-1:0.5,5:1}" --lr 5e-4 --lr-schedule cosine \
    --threads "$threads" --checkpoint-every 0 --validate-every 0 --quiet \
    --apparel-options '{"edge_widths":[48,48,48],"decoder_widths":[48]}' > "$run/train.log" 2>&1 || true
  wall=$((SECONDS - start))
  [[ -f "$run/apparel.ckpt" ]] || { echo "learning_curve.sh: training on $count characters failed ($run/train.log)" >&2; exit 1; }
  for f in segmenter.ckpt skinning.ckpt refiner.ckpt; do cp "$model/$f" "$run/model/"; done
  cp "$run/apparel.ckpt" "$run/model/"
  "$amt" eval --data "${data_dirs[0]}" --model "$run/model" --out "$run/eval" --methods hold_offset apparel_gt \
    --max-clips "${EVAL_CLIPS:-12}" --threads "$threads" > "$run/eval.log" 2>&1
  row=$(python3 - "$run/eval/metrics.json" <<'EOF'
import json, sys
m = json.load(open(sys.argv[1]))
def get(method, protocol):
    for r in m["rows"]:
        if r["method"] == method and r["protocol"] == protocol and r["subset"] == "held-out characters":
            return r["pmd_a_cm"]
    return float("nan")
print(f'{get("apparel_gt", "paper"):.2f} | {get("hold_offset", "paper"):.2f} | {get("apparel_gt", "rollout"):.2f}')
EOF
)
  echo "| $count | ${STEPS:-2000} | $row | $wall |" | tee -a "$table"
done
echo "learning_curve.sh: wrote $table" >&2
