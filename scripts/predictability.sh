#!/usr/bin/env bash
# How far the dataset's ground truth is determined by the body's motion: the held-out characters of a
# dataset rebuilt with one physics setting changed (the substep halved, apparel damping or stiffness
# scaled by 1.2), each scored against the original with `amt eval --predictions`. A small PMD_a means
# that the apparel's motion follows from the body's motion and its own build (no chaos, little
# sensitivity to the exact parameters): a good enough simulator of it would reach that error in
# whole-clip rollouts, so an error far above it is the model's, not the data's.
#
#   scripts/predictability.sh OUT_DIR [DATA_DIR=data/default]
#
# The dataset must have been built with the builder's defaults (seed 1, 32 characters, 120 frames);
# SEED and CHARACTERS say otherwise. Writes OUT_DIR/<variant>/ (shards) and OUT_DIR/<variant>.eval/
# (report.md, metrics.json) and prints one line per variant.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 ]]; then
  echo "usage: scripts/predictability.sh OUT_DIR [DATA_DIR=data/default]" >&2
  exit 2
fi
out=$1
data=${2:-data/default}
amt=${AMT:-build/app/amt}
[[ -x "$amt" ]] || { echo "predictability.sh: $amt: no amt program (build it, or set AMT)" >&2; exit 2; }
[[ -d "$data" ]] || { echo "predictability.sh: $data: no such dataset folder" >&2; exit 2; }
seed=${SEED:-1}
characters=${CHARACTERS:-32}
mkdir -p "$out"

# The held-out characters of the dataset: their records say split "test".
held_out=()
for record in "$data"/character-*.json; do
  if grep -q '"split": *"test"' "$record"; then
    name=$(basename "$record" .json)
    held_out+=($((10#${name#character-})))
  fi
done
(( ${#held_out[@]} > 0 )) || { echo "predictability.sh: $data: no held-out character" >&2; exit 2; }

declare -A variants=(
  [substep_half]="--physics-step 0.00208333"
  [damping_1.2]="--apparel-damping 1.2"
  [stiffness_1.2]="--apparel-stiffness 1.2"
)
for variant in substep_half damping_1.2 stiffness_1.2; do
  for c in "${held_out[@]}"; do
    # shellcheck disable=SC2086  # the variant's flags are meant to split
    "$amt" dataset build --out "$out/$variant" --seed "$seed" --characters "$characters" \
      ${variants[$variant]} --shard "$c/$characters" --threads 1 > "$out/$variant.build.log" 2>&1
  done
  shards=("$out/$variant"/character-*.h5)
  for shard in "${shards[@]}"; do
    name=$(basename "$shard" .h5)
    "$amt" eval --data "$data" --predictions "$shard" --ground-truth-as-predictions --out "$out/$variant.eval/$name" --no-penetration \
      --no-plots --quiet --threads 1 > /dev/null
  done
  python3 - "$variant" "$out/$variant.eval" <<'EOF'
import glob, json, sys
variant, folder = sys.argv[1], sys.argv[2]
rows = []
for path in sorted(glob.glob(folder + "/*/metrics.json")):
    m = json.load(open(path))
    for r in m["rows"]:
        if r["method"] == "predictions":
            rows.append((r["pmd_a_cm"], r["clips"], r["frames"]))
# The mean over clips, as amt eval averages (vertices, then frames, then clips).
clips = sum(c for _, c, _ in rows)
pmd_a = sum(p * c for p, c, _ in rows) / clips
print(f"{variant}: PMD_a {pmd_a:.2f} cm against the original ground truth "
      f"({len(rows)} characters, {clips} clips, {sum(f for _, _, f in rows)} frames)")
EOF
done
