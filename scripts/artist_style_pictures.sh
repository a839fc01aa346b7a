#!/usr/bin/env bash
# Before / after pictures of an artist-style character (docs/figures/artist_style_before.png, _after.png):
# held-out character-0028 of the default dataset remade as artists build models (`amt dataset artist-style`:
# UV seams with coincident copies, hair strips, double-sided and layered panels, about 20k vertices), animated
# with its first clip by the segmenter's mask (`--apparel-mask model`, no rig used), four frames each:
#   before: the model as shipped before apparel moved on handles: the apparel module that moves every apparel
#           vertex (models/pretrained/apparel_vertices.ckpt) with the refiner after it, the segmenter before its
#           artist-style fine-tune (models/pretrained/segmenter_base.ckpt), the shipped skinning predictor;
#           (no stretch limit: `--strain-limit 0`);
#   after:  the shipped model as `amt animate` runs it (the apparel module on handles with the stretch limit, no
#           refiner).
# Builds `amt` and the held-out shard if missing (the default dataset's character 28: seed 1, `--shard 28/32`).
#
# Environment: AMT_BUILD_DIR (default build), AMT_DATASET_DIR (default data/default), AMT_OUT (default
# out/artist_style_pictures), AMT_FIGURES (default docs/figures).
set -euo pipefail
cd "$(dirname "$0")/.."

build_dir=${AMT_BUILD_DIR:-build}
data=${AMT_DATASET_DIR:-data/default}
out=${AMT_OUT:-out/artist_style_pictures}
figures=${AMT_FIGURES:-docs/figures}
character=character-0028

cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build_dir" -j"$(nproc)" --target amt
amt="$build_dir/app/amt"

if [ ! -f "$data/$character.h5" ]; then
  "$amt" dataset build --out "$data" --shard 28/32 --threads 1
fi
mkdir -p "$out" "$figures"
"$amt" dataset artist-style "$data/$character.h5" --out "$out/$character.h5" --max-clips 1 --quiet
clip=$("$amt" dataset info "$out/$character.h5" | awk -v c="$character" '$2 == c && $NF == "test" { print $1; exit }')

before="$out/model_before"
mkdir -p "$before"
for f in skinning refiner; do cp models/pretrained/$f.ckpt "$before/"; done
cp models/pretrained/apparel_vertices.ckpt "$before/apparel.ckpt"
cp models/pretrained/segmenter_base.ckpt "$before/segmenter.ckpt"

for run in before after; do
  model=$([ "$run" = before ] && echo "$before" || echo models/pretrained)
  # before: as it ran then, the refiner after the module and no stretch limit
  extra=$([ "$run" = before ] && echo "--refiner --strain-limit 0" || true)
  "$amt" animate --character "$out/$character.h5:$character" --motion "$out/$character.h5:$clip" \
    --model "$model" --apparel-mask model --bind none --threads 1 $extra \
    --out "$out/$run.glb" --picture "$figures/artist_style_$run.png"
done
echo "artist_style_pictures: wrote $figures/artist_style_before.png and $figures/artist_style_after.png"
