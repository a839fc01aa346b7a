#!/usr/bin/env bash
# `amt animate`'s default path against each rig's own physics, the measurement behind the rig tables of
# docs/runtime.md: eleven rigs (Godette's VRM spring bones and PMX exports of held-out characters 5 and 13 of the
# default dataset, as built, with 4x and 16x apparel springs and with 0.5x and 3x damping) x five CMU clips that are
# in neither calibration motion. Each rig's own physics (`amt animate --apparel physics`, or `spring-bones` for the
# VRM) is the ground truth; the learned output and rigid skinning are scored against it by `amt eval --protocol
# rollout`, and scripts/rig_benchmark.py prints the table (PMD_a / rigid skinning mean and worst clip, dynamics
# amplitude, tearing, apparel ELS).
#
#   scripts/rig_benchmark.sh OUT [VARIANT [amt animate options ...]]
#
# OUT keeps the exports, the ground truth and the skinning scores between runs (they are made once); VARIANT
# (default "default") names the folder of this run's predictions, so variants made with other options sit side by
# side: scripts/rig_benchmark.sh out/rigs calm --swing-calibration off. Environment: AMT (the binary, default
# build/app/amt), RIGS and CLIPS (space-separated subsets of the defaults), JOBS (parallel runs, default the number of
# cores; each runs on one thread). About 25 minutes for a variant on 2 cores, 50 the first time.
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ $# -lt 1 ]]; then
  sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
out=$1
variant=${2:-default}
shift $(($# < 2 ? $# : 2))
amt=${AMT:-build/app/amt}
rigs=${RIGS:-"godette m5 m5_d05 m5_d3 m5_s4 m5_s16 m13 m13_d05 m13_d3 m13_s4 m13_s16"}
clips=${CLIPS:-"02_04 05_07 06_01 07_05 08_04"}
jobs=${JOBS:-$(nproc)}
[[ -x $amt ]] || { echo "rig_benchmark: $amt: not built (cmake --build build)" >&2; exit 1; }
mkdir -p "$out/rigs" "$out/truth" "$out/skinning" "$out/$variant"

# The rig's model file: Godette's VRM, or character 5 or 13 of the default dataset (seed 1) exported as PMX.
rig_file() {
  case $1 in
    godette) echo data/characters/Godette.vrm ;;
    *) echo "$out/rigs/$1/$1.pmx" ;;
  esac
}
for rig in $rigs; do
  [[ $rig == godette ]] && continue
  file=$(rig_file "$rig")
  [[ -f $file ]] && continue
  character=${rig%%_*}
  character=${character#m}
  extra=()
  case $rig in
    *_s*) extra=(--apparel-stiffness "${rig##*_s}") ;;
    *_d05) extra=(--apparel-damping 0.5) ;;
    *_d*) extra=(--apparel-damping "${rig##*_d}") ;;
  esac
  mkdir -p "$(dirname "$file")"
  "$amt" dataset export-pmx --seed 1 --character "$character" "${extra[@]}" --out "$file" > /dev/null
done

# One line per (rig, clip) run; each line is done by a shell of its own, JOBS at a time.
run_one() {
  local rig=$1 clip=$2 variant=$3
  shift 3
  local file physics=physics
  file=$(rig_file "$rig")
  [[ $rig == godette ]] && physics=spring-bones
  local motion=data/mocap/cmu/$clip.bvh truth=$out/truth/$rig/$clip.h5 skin=$out/skinning/$rig/$clip
  mkdir -p "$out/truth/$rig" "$out/skinning/$rig" "$out/$variant/$rig"
  if [[ ! -f $truth ]]; then
    "$amt" animate --character "$file" --motion "$motion" --apparel "$physics" --threads 1 --out "$truth" > /dev/null
  fi
  if [[ ! -f $skin/metrics.json ]]; then
    rm -rf "$skin"
    "$amt" eval --data "$truth" --methods skinning_baseline --protocol rollout --threads 1 --out "$skin" > /dev/null
  fi
  local pred=$out/$variant/$rig/$clip.h5 scored=$out/$variant/$rig/$clip
  rm -rf "$pred" "${pred%.h5}.bind" "$scored"
  "$amt" animate --character "$file" --motion "$motion" --threads 1 --out "$pred" "$@" > "$out/$variant/$rig/$clip.log"
  "$amt" eval --data "$truth" --predictions "$pred" --protocol rollout --threads 1 --out "$scored" > /dev/null
  echo "$rig $clip done"
}
export -f run_one rig_file
export out amt
for rig in $rigs; do
  for clip in $clips; do
    printf '%s\0' "$rig $clip $variant${*:+ $*}"
  done
done | xargs -0 -P "$jobs" -I{} bash -c 'set -euo pipefail; run_one {}'
python3 scripts/rig_benchmark.py "$out" "$variant"
