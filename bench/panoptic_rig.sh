#!/usr/bin/env bash
# The comparison on real video with the real-capture refiner: CMU Panoptic
# "basketball", a sparse split of two neighbouring dome cameras, every strategy fine-tuned
# with `--refiner rig` (the photograph of the nearest pool camera at its real pose, no
# generative model), evaluated on held-out cameras between the pair (interpolation) and
# beyond it (extrapolation); "moving" is the foreground PSNR inside Panoptic's masks.
#
#   bench/panoptic_rig.sh [--smoke] [--monocular] [OUT]
#       (default OUT: bench/results/video/panoptic_rig, or panoptic_mono with --monocular)
#
# The split, fixed from the cameras' geometry before any run (bench/results/README.md, "Real captured video"):
# train on 18 and 12 (the y = -2.4 ring, 72 degrees apart in azimuth); the dome cameras inside
# their azimuth arc alternate held-out / pool in azimuth order (4 held out, 3 pool, 22 held
# out, 7 pool); those beyond the arc within 60 degrees alternate by angular distance from it
# (9 held out, 2 pool, 5 held out, 1 pool, 26 held out, 20 pool, 28 held out, 23 pool); the
# far side is pool. The rig refiner accepts a pool camera within half the training baseline
# (1.5 of the pair's 2.98 world units) and 30 degrees of the virtual view's axis.
#
# --monocular (the paper's supplementary protocol for the Nvidia scenes: one image per time
# step, cycling through 8 cameras of a rig; fixed before any run). Panoptic's height rings
# hold 4-5 cameras, so the 8 are a contiguous azimuth arc of the dome across heights: the 10
# cameras in azimuth order 23, 1, 9, 18, 4, 3, 22, 7, 12, 2 (-32 to +102 degrees, around the
# sparse pair 18, 12) without 4 and 22, which stay the interpolation test cameras as in the
# sparse split. Frame f of the training set is camera [f mod 8] of 23, 1, 9, 18, 3, 7, 12, 2
# (azimuth order). The cameras beyond the arc within 60 degrees alternate held-out / pool by
# angular distance from it (19 held out, 5 pool, 16 held out, 14 pool, 26 held out, 20 pool,
# 28 held out, 27 pool, 24 held out): extrapolation 19, 16, 26, 28, 24; the far side is pool.
# No pool camera lies inside the arc (every camera there is trained on or held out), so the
# rig refiner can serve only virtual views near the arc's ends; it keeps the sparse split's
# tolerances. The dense reference trains on every camera but the held-out ones, all frames.
#
# Rows: the two-camera backbone; the dense reference (pair + pool, every camera but the
# held-out ones, 3,000 iterations); no-refinement (the same fine-tuning, real views only);
# each strategy (FillGS with its weights, the baselines with ExploreGS's); FillGS's views
# with ExploreGS's weights and with none.
#
# Resumable: a finished step (its summary.json or metrics.json) is reused only when it was
# made by the same command line, kept beside it in command.txt; a step made with other options
# stops the script with one line (another OUT, or delete the step). Writes OUT/results.md. --smoke: 2 frames at 1/8 size and a few iterations (CI: it must not rot).
set -euo pipefail
cd "$(dirname "$0")/.."
SMOKE=0 MONO=0
while [ $# -gt 0 ]; do
  case $1 in
    --smoke) SMOKE=1 ;;
    --monocular) MONO=1 ;;
    *) break ;;
  esac
  shift
done
FILLGS=${FILLGS:-build/bin/fillgs}
DATA=${FILLGS_SHARED_DATA:-$(cd .. && pwd)/shared/data}
P=$DATA/video/panoptic_basketball
if [ $MONO = 1 ]; then
  OUT=${1:-bench/results/video/panoptic_mono}
  TRAIN=23,1,9,18,3,7,12,2
  CYCLE=(--monocular-cycle $TRAIN)
  INTERP=4,22
  EXTRAP=19,16,26,28,24
  POOL=5,14,20,27,29,17,25,11,6,8,21,13
  PICTURE=(22 19)  # one interpolation and the nearest extrapolation camera
else
  OUT=${1:-bench/results/video/panoptic_rig}
  TRAIN=18,12
  CYCLE=()
  INTERP=4,22
  EXTRAP=9,5,26,28
  POOL=3,7,2,1,20,23,29,17,25,11,6,8,27,14,16,19,24,21,13
  PICTURE=(22 9)
fi
FRAMES=0:150:5 DOWN=4 BB=(--iterations 2000) FT=()
if [ $SMOKE = 1 ]; then FRAMES=0:150:75 DOWN=8 BB=(--iterations 40 --init-points 3000) FT=(--iterations 30 --select-every 15 --trajectories 1); fi
STRATEGIES=(fillgs random negative interpolation fisherrf coverage3d coverage4d)
mkdir -p "$OUT"
DS=(--images "$P/ims" --cameras "$P/train_meta.json" --frames "$FRAMES" --downscale "$DOWN")

source bench/lib.sh  # step (the working folder is the repository root)

step "$OUT/backbone" summary.json "$FILLGS" train "${DS[@]}" "${CYCLE[@]}" --train-cameras $TRAIN "${BB[@]}" --out "$OUT/backbone" --quiet

evaluate() {  # model folder
  for split in interpolation extrapolation; do
    local cams=$INTERP
    [ $split = extrapolation ] && cams=$EXTRAP
    step "$1/eval_$split" metrics.json "$FILLGS" eval --model "$1/model.ply" "${DS[@]}" --select-cameras $cams --splits $split --no-renders \
      --ls-gain --out "$1/eval_$split" --quiet >/dev/null
  done
}

finetune() {  # id, extra finetune options
  local id=$1
  shift
  step "$OUT/$id" summary.json "$FILLGS" finetune --model "$OUT/backbone/model.ply" "${DS[@]}" "${CYCLE[@]}" --train-cameras $TRAIN \
    --out "$OUT/$id" --refiner rig --pool-cameras $POOL --rig-max-distance 1.5 --rig-max-angle 30 --motion-rates repair "${FT[@]}" "$@" --quiet
  evaluate "$OUT/$id"
}

evaluate "$OUT/backbone"
# The dense reference: every camera but the held-out ones (pair + pool), as the dense split
# trains (3,000 iterations).
DENSE_IT=(--iterations 3000)
[ $SMOKE = 1 ] && DENSE_IT=("${BB[@]}")
step "$OUT/dense" summary.json "$FILLGS" train "${DS[@]}" --train-cameras $TRAIN,$POOL "${DENSE_IT[@]}" --out "$OUT/dense" --quiet
evaluate "$OUT/dense"
finetune no-refinement --trajectories 0
for s in "${STRATEGIES[@]}"; do
  w=exploregs
  [ $s = fillgs ] && w=fillgs
  finetune "$s" --strategy $s --weighting $w
done
# FillGS's views under the baselines' weights (the selection alone against theirs) and
# unweighted (a real photograph needs no mask): the paper's Table 4 question on real data.
finetune fillgs.w-exploregs --strategy fillgs --weighting exploregs
finetune fillgs.w-none --strategy fillgs --weighting none

# The table: every number a metrics.json or summary.json gives a key ("key": number, one a
# line as fillgs writes them); the first, their sum (the per-round seconds) or their mean.
numbers() { sed -n "s/^ *\"$2\": \([-0-9.eE+]*\),\{0,1\}$/\1/p" "$1"; }
value() { numbers "$1" "$2" | head -n 1; }
total() { numbers "$1" "$2" | awk '{s += $1} END {printf "%.0f", s}'; }
mean() { numbers "$1" "$2" | awk '{s += $1; n++} END {if (n) printf "%.3f", s / n}'; }
fmt() { if [ -z "$1" ]; then echo -; else printf "%.${2:-2}f" "$1"; fi; }
{
  echo "| Method | Interp PSNR | SSIM | foreground | gain-corrected | Extrap PSNR | SSIM | foreground | gain-corrected | views added | dropped | mean weight | seconds: select / render + refine / weights / train / total |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"
  for id in backbone dense no-refinement "${STRATEGIES[@]}" fillgs.w-exploregs fillgs.w-none; do
    row="| $id"
    for split in interpolation extrapolation; do
      m=$OUT/$id/eval_$split/metrics.json
      row="$row | $(fmt "$(value "$m" psnr)") | $(fmt "$(value "$m" ssim)" 3) | $(fmt "$(value "$m" psnr_moving)") | $(fmt "$(value "$m" psnr_ls_gain)")"
    done
    S=$OUT/$id/summary.json
    if [ $id = backbone ] || [ $id = dense ]; then
      row="$row | – | – | – | training $(fmt "$(value "$S" seconds)" 0)"
    else
      rr=$(awk -v a="$(total "$S" render)" -v b="$(total "$S" refine)" 'BEGIN {printf "%.0f", a + b}')
      row="$row | $(value "$S" virtual_views) | $(value "$S" virtual_views_dropped) | $(mean "$S" mean_weight) | $(total "$S" select) / $rr / $(total "$S" weights) / $(fmt "$(value "$S" train)" 0) / $(fmt "$(value "$S" total)" 0)"
    fi
    echo "$row |"
  done
} >"$OUT/results.md.tmp"
mv "$OUT/results.md.tmp" "$OUT/results.md"
cat "$OUT/results.md"

# The picture: ground truth | backbone | FillGS | the best baseline (highest mean of the two
# splits' PSNR) at held-out cameras PICTURE (22 between the training cameras, 9 or 19 beyond
# them), the clip's middle frame (fixed before any run).
best=$(for s in random negative interpolation fisherrf coverage3d coverage4d; do
  echo "$s $(value "$OUT/$s/eval_interpolation/metrics.json" psnr) $(value "$OUT/$s/eval_extrapolation/metrics.json" psnr)"
done | awk '{m = ($2 + $3) / 2; if (NR == 1 || m > b) {b = m; n = $1}} END {print n}')
NF=$(ls "$P/ims/${PICTURE[0]}" | wc -l)
SRC=$(( (NF / 2) / ${FRAMES##*:} * ${FRAMES##*:} ))  # a source frame the --frames step keeps
for id in backbone fillgs "$best"; do
  if [ ! -d "$OUT/$id/picture" ]; then
    "$FILLGS" eval --model "$OUT/$id/model.ply" "${DS[@]}" --select-cameras "${PICTURE[0]},${PICTURE[1]}" --splits picture --out "$OUT/$id/picture.tmp" --quiet >/dev/null
    mv "$OUT/$id/picture.tmp" "$OUT/$id/picture"
  fi
done
rows=()
for cam in "${PICTURE[@]}"; do
  name=$(printf '%s_%06d.png' $cam $SRC)
  W=$(( 640 / DOWN )) H=$(( 360 / DOWN ))
  rows+=("$P/ims/$cam/$(printf '%06d' $SRC).jpg" --resize ${W}x$H)
  for id in backbone fillgs "$best"; do rows+=("$OUT/$id/picture/renders/picture/$name"); done
done
oiiotool --nosoftwareattrib "${rows[@]}" --mosaic 4x2 --resize 200% -o "$OUT/compare.png"
echo "picture: ground truth | backbone | fillgs | $best at cameras ${PICTURE[0]} and ${PICTURE[1]}, source frame $SRC -> $OUT/compare.png"
