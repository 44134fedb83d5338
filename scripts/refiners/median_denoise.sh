#!/usr/bin/env bash
# An example external refiner for `fillgs finetune --refiner external`:
#   --refiner-command 'bash scripts/refiners/median_denoise.sh {in} {out}'
# It reads a patch folder written by fillgs (patch.json and f<frame>_v<view>.png, view 0
# being the observed photograph) and writes every rendered view (view >= 1), denoised by a
# 3x3 median filter, into the output folder under the same name. A generative refiner
# (a video diffusion model) follows the same protocol: read the 12 images in the order
# patch.json gives, write the refined rendered views with the same names and sizes.
set -euo pipefail
in="$1"
out="$2"
[ -f "$in/patch.json" ] || { echo "median_denoise: $in/patch.json is missing" >&2; exit 2; }
mkdir -p "$out"
shopt -s nullglob
count=0
for img in "$in"/f*_v*.png; do
  name="$(basename "$img")"
  case "$name" in *_v0.png) continue ;; esac  # the observed view is not refined
  oiiotool "$img" --median 3x3 -o "$out/$name"
  count=$((count + 1))
done
echo "median_denoise: refined $count images from $in"
