#!/usr/bin/env bash
# Which camera-times help most? On CMU Panoptic "basketball" every strategy chooses among the
# real (camera, frame) photographs of a pool of dome cameras (`fillgs finetune --pool-budget
# K`: no generative model), the chosen photographs are added at their real poses, and every
# model is judged on held-out cameras read from a camera file that training, the pool, the
# initial points and the selection never see (`--held-out`).
#
#   bench/panoptic_pool.sh [--smoke] [--test-cameras FILE] [--seeds 1,2,3] [--budgets 10,30,90] [OUT]
#       (default OUT: bench/results/video/panoptic_pool)
#
# The split, fixed from the cameras' geometry before any run (bench/results/README.md,
# "Which camera-times help most"). Azimuth and height about the dome's vertical (the mean of
# the cameras' up directions) from the mean camera centre:
#  * training: 3, 22, 7, 12 — four neighbouring cameras 52 degrees of azimuth wide at three
#    heights (-52, -26, -23, 0 degrees): a forward-facing group, as the paper's rigs are;
#  * pool: the rest of that side of the dome, 19, 23, 1, 9, 4, 5, 26, 28, 24, 21, 13
#    (-128 to +87 degrees) at every frame: 11 cameras x 30 frames = 330 camera-times;
#  * held out among the pool ("near"): 18 (-72), 2 (+12), 20 (+48), one inside each stretch
#    of pool cameras and one beside the training group; beyond it ("far"): 29 (+123),
#    11 (+149), 27 (-166), the far side;
#  * unused: 14, 16, 25, 6, 8, 17 (the rest of the far side: neither pool nor judged).
# The held-out cameras are written to OUT/test_meta.json (the dataset's own format, its
# masks linked beside it) unless --test-cameras names another camera file of the same dome
# (its images under the same ims/ folder); then every camera of that file is one split,
# "held-out", and the same file guards training and the pool.
# Budgets K = 10, 30, 90 camera-times over the fine-tuning's 3 rounds; seeds 1-3 (the
# backbone's initialisation, `random` and the training's draws). Backbone: the training
# cameras, 2,000 iterations, `--sh-degree 0 --colour-correction` (what the dense split
# gained most from), points carved from the training cameras' masks only. Dense reference:
# training + pool cameras, 3,000 iterations, the same options, seed 1. Every strategy's
# photographs are real, so they weigh 1 (`--weighting none`); FillGS's and ExploreGS's
# weights run once each (FillGS's selection, K = 30) to show what they do to real
# photographs. The control fine-tunes on the training cameras alone.
#
# Resumable (bench/lib.sh, step): rerun the same command and every finished step is reused;
# a step made by another command line stops the script. Each step that runs prints its
# seconds. Writes OUT/results.md (a table per budget, mean +- standard deviation over the
# seeds), OUT/chosen_K<k>_s<seed>.png (what each strategy chose, camera x frame) and
# OUT/compare.png. --smoke: 2 frames at 1/8 size, K = 2, seed 1, a few iterations (CI).
set -euo pipefail
cd "$(dirname "$0")/.."
source bench/lib.sh
SMOKE=0 TEST= SEEDS=1,2,3 BUDGETS=10,30,90
while [ $# -gt 0 ]; do
  case $1 in
    --smoke) SMOKE=1 ;;
    --test-cameras) TEST=$2; shift ;;
    --seeds) SEEDS=$2; shift ;;
    --budgets) BUDGETS=$2; shift ;;
    -h|--help) sed -n '2,45p' "$0"; exit 0 ;;
    -*) echo "panoptic_pool: unknown option $1" >&2; exit 1 ;;
    *) break ;;
  esac
  shift
done
FILLGS=${FILLGS:-build/bin/fillgs}
DATA=${FILLGS_SHARED_DATA:-$(cd .. && pwd)/shared/data}
P=$DATA/video/panoptic_basketball
OUT=${1:-bench/results/video/panoptic_pool}
TRAIN=3,22,7,12
POOL=19,23,1,9,4,5,26,28,24,21,13
NEAR=18,2,20 FAR=29,11,27
FRAMES=0:150:5 DOWN=4 BB=(--iterations 2000) DENSE=(--iterations 3000) FT=()
if [ $SMOKE = 1 ]; then
  FRAMES=0:150:75 DOWN=8 BB=(--iterations 40) DENSE=(--iterations 40) FT=(--iterations 30 --select-every 15) SEEDS=1 BUDGETS=2
fi
STRATEGIES=(fillgs random negative interpolation fisherrf coverage3d coverage4d)
mkdir -p "$OUT"
if [ -z "$TEST" ]; then
  # The held-out cameras in the dataset's own format, with their masks beside them.
  TEST=$OUT/test_meta.json
  if [ ! -f "$TEST" ]; then
    python3 - "$P/train_meta.json" "$TEST.tmp" "$NEAR,$FAR" <<'PY'
import json, sys
meta = json.load(open(sys.argv[1]))
keep = {int(c) for c in sys.argv[3].split(",")}
out = {"w": meta["w"], "h": meta["h"]}
for key in ("k", "w2c", "fn", "cam_id"):
    out[key] = [[v for v, c in zip(row, ids) if c in keep] for row, ids in zip(meta[key], meta["cam_id"])]
json.dump(out, open(sys.argv[2], "w"))
PY
    mv "$TEST.tmp" "$TEST"
  fi
  [ -e "$OUT/seg" ] || ln -s "$P/seg" "$OUT/seg"
  SPLITS=(near far) SPLIT_CAMS=($NEAR $FAR)
else
  SPLITS=(held-out) SPLIT_CAMS=(all)
fi
DS=(--images "$P/ims" --frames "$FRAMES" --downscale "$DOWN")
TRAIN_DS=("${DS[@]}" --cameras "$P/train_meta.json" --held-out "$TEST")
OPTS=(--sh-degree 0 --colour-correction)

evaluate() {  # model folder
  for k in "${!SPLITS[@]}"; do
    local sel=()
    [ "${SPLIT_CAMS[$k]}" = all ] || sel=(--select-cameras "${SPLIT_CAMS[$k]}")
    step "$1/eval_${SPLITS[$k]}" metrics.json "$FILLGS" eval --model "$1/model.ply" "${DS[@]}" --cameras "$TEST" "${sel[@]}" \
      --splits "${SPLITS[$k]}" --no-renders --ls-gain --out "$1/eval_${SPLITS[$k]}" --quiet >/dev/null
  done
}

step "$OUT/dense" summary.json "$FILLGS" train "${TRAIN_DS[@]}" --train-cameras $TRAIN,$POOL "${DENSE[@]}" "${OPTS[@]}" --seed 1 \
  --out "$OUT/dense" --quiet
evaluate "$OUT/dense"
IFS=, read -r -a seeds <<<"$SEEDS"
IFS=, read -r -a budgets <<<"$BUDGETS"
for s in "${seeds[@]}"; do
  S=$OUT/s$s
  step "$S/backbone" summary.json "$FILLGS" train "${TRAIN_DS[@]}" --train-cameras $TRAIN "${BB[@]}" "${OPTS[@]}" --seed "$s" \
    --out "$S/backbone" --quiet
  evaluate "$S/backbone"
  finetune() {  # id, extra finetune options
    local id=$1
    shift
    step "$S/$id" summary.json "$FILLGS" finetune --model "$S/backbone/model.ply" "${TRAIN_DS[@]}" --train-cameras $TRAIN \
      --seed "$s" --out "$S/$id" "${FT[@]}" "$@" --quiet
    evaluate "$S/$id"
  }
  finetune control --trajectories 0
  for K in "${budgets[@]}"; do
    for st in "${STRATEGIES[@]}"; do
      finetune "$st.K$K" --pool-cameras $POOL --pool-budget "$K" --strategy "$st" --weighting none
    done
  done
  # What FillGS's and ExploreGS's weights do to real photographs (FillGS's selection).
  K=${budgets[$(( ${#budgets[@]} / 2 ))]}
  for w in fillgs exploregs; do
    finetune "fillgs.K$K.w-$w" --pool-cameras $POOL --pool-budget "$K" --strategy fillgs --weighting $w
  done
done

python3 bench/panoptic_pool_report.py "$OUT" --seeds "$SEEDS" --budgets "$BUDGETS" --splits "$(IFS=,; echo "${SPLITS[*]}")" >/dev/null
# What every strategy chose, side by side (camera x frame, first seed).
for K in "${budgets[@]}"; do
  pics=()
  for st in "${STRATEGIES[@]}"; do
    [ -f "$OUT/s${seeds[0]}/$st.K$K/pool_chosen.png" ] && pics+=("$OUT/s${seeds[0]}/$st.K$K/pool_chosen.png")
  done
  [ ${#pics[@]} -gt 0 ] && oiiotool "${pics[@]}" --mosaic 4x2 -o "$OUT/chosen_K${K}_s${seeds[0]}.png"
done
cat "$OUT/results.md"

# The picture: ground truth | backbone | the best strategy at the middle budget | FillGS,
# at the first near (or held-out) camera, the clip's middle frame, seed 1 (fixed before any run).
K=${budgets[$(( ${#budgets[@]} / 2 ))]}
best=$(sed -n 's/^best at K='"$K"': //p' "$OUT/results.md" | head -n 1)
S=$OUT/s${seeds[0]}
cam=${NEAR%%,*}
[ "${SPLIT_CAMS[0]}" = all ] && cam=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['cam_id'][0][0])" "$TEST")
NF=$(ls "$P/ims/$cam" | wc -l)
STEP=${FRAMES##*:}
SRC=$(( (NF / 2) / STEP * STEP ))
tiles=("$P/ims/$cam/$(printf '%06d' $SRC).jpg" --resize $(( 640 / DOWN ))x$(( 360 / DOWN )))
for id in backbone "$best" "fillgs.K$K"; do
  if [ ! -d "$S/$id/picture" ]; then
    "$FILLGS" eval --model "$S/$id/model.ply" "${DS[@]}" --cameras "$TEST" --select-cameras "$cam" --splits picture --out "$S/$id/picture.tmp" --quiet >/dev/null
    mv "$S/$id/picture.tmp" "$S/$id/picture"
  fi
  tiles+=("$S/$id/picture/renders/picture/$(printf '%s_%06d.png' "$cam" $SRC)")
done
oiiotool "${tiles[@]}" --mosaic 4x1 --resize 200% -o "$OUT/compare.png"
echo "picture: ground truth | backbone | $best | fillgs.K$K at held-out camera $cam, source frame $SRC -> $OUT/compare.png"
