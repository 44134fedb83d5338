#!/usr/bin/env bash
# Which camera-times help most? Every strategy chooses among the real (camera, frame)
# photographs of a pool of a rig's cameras (`fillgs finetune --pool-budget K`: no generative
# model), and every model is judged on held-out cameras read from a camera file that
# training, the initial points, the pool and the selection never see (`--held-out`).
#
# The protocol (bench/results/README.md, "Which camera-times help most: the exposure
# protocol", fixed before its runs):
#  * every model trains with every photograph equally likely at every stage (`--time-ramp 0`,
#    a fresh permutation of the views each epoch) for a fixed number of draws per photograph
#    (`--draws-per-view D`: the iterations follow the number of views), so neither a
#    photograph's frame nor the budget decides how often it is trained on. D is the earlier
#    control's (3,000 iterations over its training views): 25 on Panoptic (120 views), 750
#    on the static N3V frame (4 views). Each run's summary.json records every photograph's
#    draws;
#  * per seed: the backbone (the training cameras, the model every strategy chooses on), the
#    control (the training cameras alone, from the backbone's initial points) and the dense
#    reference (training and every pool photograph, the same points) — the window is dense
#    minus control, per seed;
#  * each strategy chooses K camera-times on the seed's backbone in one greedy round
#    (`finetune --pool-budget K --iterations 1 --select-every 1`: each chosen one counted as
#    an observation before the next; the one training step is discarded), then a model
#    trains on the training cameras plus those photographs (`fillgs train --camera-times`)
#    by the same rule, from the backbone's initial points, with the seed;
#  * the positive control `positive` knows the judged cameras: the pool photographs nearest
#    them, spread over the clip (bench/pool_positive.py); `negative` is the negative one;
#  * judged on every camera that is neither training nor pool, each view's metrics kept
#    (`fillgs eval --affine-fit`): the primary metric is PSNR after a per-image affine colour
#    fit; raw PSNR, foreground PSNR and SSIM are secondary; FillGS is compared with each of
#    the six other strategies, every interval printed.
#  * seed 1 also trains the backbone with the time curriculum (`--time-ramp 0.7`, fillgs
#    train's default) at the same draws: what the uniform rule costs motion learning on the
#    training cameras.
# With --warm-start, a second protocol (labelled as such, after the main one): the backbone
# fine-tuned for 2,400 iterations with the photographs added at their real poses, chosen in
# three rounds, each from the current model.
#
#   bench/pool_select.sh [--scene panoptic|n3v-static] [--smoke] [--test-cameras FILE]
#                        [--seeds 1,2,3] [--budgets ...] [--strategies a,b,..] [--no-scratch] [--warm-start]
#                        [--jobs N] [OUT]
#       (default OUT: bench/results/video/panoptic_pool_exposure or bench/results/video/n3v_static_pool_exposure)
#
# Seeds: without --seeds and --budgets, Panoptic runs K = 30 over seeds 1-10 first (every
# seed's rows before the next seed), then K = 10 and 90 over seeds 1-5; the static N3V frame
# runs K = 2, 4, 8 over seeds 1-5. --seeds or --budgets: those budgets over those seeds.
#
# --scene panoptic (the default): CMU Panoptic "basketball", 30 frames at 160x90. Azimuth and
# height about the dome's vertical (the mean of the cameras' up directions) from the mean
# camera centre:
#  * training: 3, 22, 7, 12 — four neighbouring cameras 52 degrees of azimuth wide at three
#    heights (-52, -26, -23, 0 degrees): a forward-facing group, as the paper's rigs are;
#  * pool: the rest of that side of the dome, 19, 23, 1, 9, 4, 5, 26, 28, 24, 21, 13
#    (-128 to +87 degrees) at every frame: 11 cameras x 30 frames = 330 camera-times;
#  * judged among the pool ("near"): 18 (-72), 2 (+12), 20 (+48), one inside each stretch
#    of pool cameras and one beside the training group (every other camera on that side is
#    training or pool); beyond it ("far"): 29 (+123), 11 (+149), 27 (-166) and the rest of
#    the far side, 14, 16, 25, 6, 8, 17.
#  Budgets K = 10, 30, 90 camera-times. Points carved from the training cameras' masks only.
#  The judged cameras go to OUT/test_meta.json (the dataset's own format, its masks linked
#  beside it).
# --scene n3v-static: Neural 3D Video flame_steak, frame 0 of its 21 cameras (two rows of a
#  forward-facing arc), at 1/8 size (336x252): the static case, where the pool is the
#  cameras themselves. Along the arc (x of the centres about their mean, lower row cam00-10,
#  upper row cam11-20):
#  * training: cam00, cam06 (lower, x +0.04, -1.03) and cam15, cam16 (upper, +0.52, -0.61):
#    the four middle cameras, two of each row;
#  * judged among the pool ("near"): cam05 (+1.14), cam17 (-1.75), cam08 (-3.19); beyond it
#    ("far"): cam20 (-5.77) and cam11 (+5.64), the two ends of the arc;
#  * pool: the other 12 (cam01-04, 07, 09, 10, 12-14, 18, 19): 12 camera-times.
#  Budgets K = 2, 4, 8. Initial points from COLMAP points triangulated from the four training
#  cameras only (scripts/colmap-points.sh --train-cameras, images at most 1,344 px), for
#  every model. The judged cameras go to OUT/test_cameras.json (transforms, from sparse/0).
#
# Both: `--sh-degree 0 --colour-correction`; every strategy's photographs are real, so they
# weigh 1 (`--weighting none`). A --test-cameras FILE of the same rig replaces the judged
# cameras: every camera in it is one split, "held-out", and it guards training and the pool.
#
# Resumable (bench/lib.sh, step): rerun the same command and every finished step is reused;
# a step made by another command line stops the script. Each step that runs prints its
# seconds. Across checkouts: git keeps each finished step's records (command.txt, step.txt,
# summary.json, metrics.json, pool_chosen.json and .png, the backbone's model.sha256 and the
# first seed's picture render; .gitignore), not its models. A backbone whose model is not
# here is trained again when a step still to run reads it, and must come out byte for byte
# the one its finished rows used (model.sha256), or the script stops; records made on
# another instruction set (step.txt's cpu line) are continued on it, FILLGS_INSTRUCTION_SET
# holding fillgs's kernels there (an AVX-512 machine continues AVX2 records). Every path in a
# command line is relative to the repository (the data at ../shared/data unless
# FILLGS_SHARED_DATA is set), so the records carry no machine's path.
# Writes OUT/results.md (bench/pool_select_report.py: per budget the positive control's
# verdict, the table, FillGS minus each other strategy paired by seed with 95 % intervals,
# drawn in OUT/intervals_K<k>.png, the per-camera table, the window per seed, the draws per
# chosen photograph), OUT/chosen_K<k>_s<seed>.png (what each strategy chose, camera x frame)
# and OUT/compare.png. --smoke: small images, K = 2, seed 1, a few iterations (CI).
set -euo pipefail
cd "$(dirname "$0")/.."
source bench/lib.sh
SMOKE=0 TEST= SEEDS= BUDGETS= SCENE=panoptic ONLY= NO_SCRATCH=0 WARM=0 JOBS=1
while [ $# -gt 0 ]; do
  case $1 in
    --scene) SCENE=$2; shift ;;
    --jobs) JOBS=$2; shift ;;
    --smoke) SMOKE=1 ;;
    --test-cameras) TEST=$2; shift ;;
    --seeds) SEEDS=$2; shift ;;
    --budgets) BUDGETS=$2; shift ;;
    --strategies) ONLY=$2; shift ;;
    --no-scratch) NO_SCRATCH=1 ;;
    --warm-start) WARM=1 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d'; exit 0 ;;
    -*) echo "pool_select: unknown option $1" >&2; exit 1 ;;
    *) break ;;
  esac
  shift
done
FILLGS=${FILLGS:-build/bin/fillgs}
DATA=${FILLGS_SHARED_DATA:-../shared/data}
STRATEGIES=(fillgs random negative interpolation fisherrf coverage3d coverage4d positive)
[ -n "$ONLY" ] && IFS=, read -r -a STRATEGIES <<<"$ONLY"
# A list naming an item twice is refused before anything runs (a seed twice would pair a run
# with itself in the report: a zero-width interval read as "separated").
for list in "--seeds $SEEDS" "--budgets $BUDGETS" "--strategies $ONLY"; do
  twice=$(echo "${list#* }" | tr ',' '\n' | sed '/^$/d' | sort | uniq -d | head -n 1)
  if [ -n "$twice" ]; then echo "pool_select: ${list% *} ${list#* }: $twice is given twice" >&2; exit 1; fi
done
FT=() INIT=()
case $SCENE in
  panoptic)
    P=$DATA/video/panoptic_basketball TITLE="Panoptic basketball"
    OUT=${1:-bench/results/video/panoptic_pool_exposure}
    TRAIN=3,22,7,12
    POOL=19,23,1,9,4,5,26,28,24,21,13
    NEAR=18,2,20 FAR=29,11,27,14,16,25,6,8,17
    PLAN="30:1,2,3,4,5,6,7,8,9,10 10:1,2,3,4,5 90:1,2,3,4,5" WEIGHTS_K=10 PICTURE_K=30
    FRAMES=0:150:5 DOWN=4 DRAWS=25
    if [ $SMOKE = 1 ]; then
      FRAMES=0:150:75 DOWN=8 DRAWS=5 FT=(--iterations 30 --select-every 15) PLAN=2:1 WEIGHTS_K=2 PICTURE_K=2
    fi
    DS=(--images "$P/ims" --frames "$FRAMES" --downscale "$DOWN")
    CAMERAS=$P/train_meta.json
    ;;
  n3v-static)
    P=$DATA/video/n3v_flame_steak_frame0 TITLE="Neural 3D Video flame_steak, frame 0 (static)"
    OUT=${1:-bench/results/video/n3v_static_pool_exposure}
    TRAIN=cam00,cam06,cam15,cam16
    POOL=cam01,cam02,cam03,cam04,cam07,cam09,cam10,cam12,cam13,cam14,cam18,cam19
    NEAR=cam05,cam17,cam08 FAR=cam20,cam11
    PLAN="2:1,2,3,4,5 4:1,2,3,4,5 8:1,2,3,4,5" WEIGHTS_K=2 PICTURE_K=4
    DOWN=8 MAXSIDE=1344 DRAWS=750
    if [ $SMOKE = 1 ]; then
      DOWN=32 MAXSIDE=400 DRAWS=10 FT=(--iterations 30 --select-every 15) PLAN=2:1 PICTURE_K=2
    fi
    DS=(--images "$P/images" --downscale "$DOWN")
    CAMERAS=$P/sparse/0
    ;;
  *) echo "pool_select: unknown --scene $SCENE (panoptic or n3v-static)" >&2; exit 1 ;;
esac
# --seeds or --budgets: those budgets over those seeds (the plan's others where one is not given).
if [ -n "$SEEDS$BUDGETS" ]; then
  all_budgets=$(for e in $PLAN; do printf '%s,' "${e%%:*}"; done)
  all_seeds=$(for e in $PLAN; do echo "${e#*:}" | tr ',' '\n'; done | sort -n | uniq | paste -sd,)
  B=${BUDGETS:-${all_budgets%,}} S=${SEEDS:-$all_seeds}
  PLAN=$(IFS=,; for k in $B; do printf '%s:%s ' "$k" "$S"; done)
fi
# Every seed and budget of the plan, for the report.
BUDGETS=$(for e in $PLAN; do printf '%s\n' "${e%%:*}"; done | paste -sd,)
SEEDS=$(for e in $PLAN; do echo "${e#*:}" | tr ',' '\n'; done | sort -n | uniq | paste -sd,)
# The training rule of every model: each photograph equally likely at every stage, DRAWS
# draws each (the iterations follow the number of views).
RULE=(--draws-per-view "$DRAWS" --time-ramp 0)
mkdir -p "$OUT"
if [ -z "$TEST" ]; then
  # The held-out cameras in a camera file of their own.
  if [ $SCENE = panoptic ]; then
    TEST=$OUT/test_meta.json  # the dataset's own format, its masks linked beside it
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
    [ -e "$OUT/seg" ] || ln -sfn "$(cd "$P" && pwd)/seg" "$OUT/seg"  # absolute: the link sits in OUT, P is relative to the root
  else
    TEST=$OUT/test_cameras.json  # transforms.json of the held-out cameras
    if [ ! -f "$TEST" ]; then
      "$FILLGS" cameras --cameras "$CAMERAS" --out "$OUT/all_cameras.tmp.json" >/dev/null
      python3 - "$OUT/all_cameras.tmp.json" "$TEST.tmp" "$NEAR,$FAR" <<'PY'
import json, os, sys
t = json.load(open(sys.argv[1]))
keep = set(sys.argv[3].split(","))
t["frames"] = [f for f in t["frames"] if os.path.splitext(os.path.basename(f["file_path"]))[0] in keep]
assert len(t["frames"]) == len(keep), "held-out cameras missing"
json.dump(t, open(sys.argv[2], "w"), indent=1)
PY
      rm "$OUT/all_cameras.tmp.json"
      mv "$TEST.tmp" "$TEST"
    fi
  fi
  SPLITS=(near far) SPLIT_CAMS=($NEAR $FAR)
else
  SPLITS=(held-out) SPLIT_CAMS=(all)
fi
if [ $SCENE = n3v-static ]; then
  # Initial points from COLMAP, each model from the images it trains on: the backbone's from
  # the training cameras alone, the dense reference's from the training and pool cameras.
  colmap_points() {  # folder, cameras
    step "$OUT/$1" sparse/points3D.bin bash scripts/colmap-points.sh --images "$P/images" --cameras "$CAMERAS" --train-cameras "$2" \
      --max-image-size $MAXSIDE --fillgs "$FILLGS" --out "$OUT/$1"
  }
  colmap_points points $TRAIN
  INIT=(--points "$OUT/points/sparse/points3D.bin")
fi
TRAIN_DS=("${DS[@]}" --cameras "$CAMERAS" --held-out "$TEST")
OPTS=(--sh-degree 0 --colour-correction)

# The picture (fixed before any run): the first near (or held-out) camera at the clip's middle
# frame; every row of the first seed renders it when it is evaluated, so that the picture
# needs no model a later checkout lacks.
cam=${NEAR%%,*}
if [ $SCENE = panoptic ]; then
  [ "${SPLIT_CAMS[0]}" = all ] && cam=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['cam_id'][0][0])" "$TEST")
  NF=$(ls "$P/ims/$cam" | wc -l)
  STEP=${FRAMES##*:}
  SRC=$(( (NF / 2) / STEP * STEP ))
  truth="$P/ims/$cam/$(printf '%06d' $SRC).jpg" render=$(printf '%s_%06d.png' "$cam" $SRC)
else
  [ "${SPLIT_CAMS[0]}" = all ] && cam=$(python3 -c "import json,os,sys; print(os.path.splitext(os.path.basename(json.load(open(sys.argv[1]))['frames'][0]['file_path']))[0])" "$TEST")
  SRC=0 truth="$P/images/$cam.png" render="${cam}_${cam}.png"  # eval names a render <camera>_<image>
fi
evaluate() {  # model folder
  local m=$1/model.ply
  for k in "${!SPLITS[@]}"; do
    local sel=()
    [ "${SPLIT_CAMS[$k]}" = all ] || sel=(--select-cameras "${SPLIT_CAMS[$k]}")
    local cmd=("$FILLGS" eval --model "$m" "${DS[@]}" --cameras "$TEST" "${sel[@]}" --splits "${SPLITS[$k]}" --no-renders --affine-fit
      --out "$1/eval_${SPLITS[$k]}" --quiet)
    finished "$1/eval_${SPLITS[$k]}" metrics.json "${cmd[@]}" || have_model "$1"
    step "$1/eval_${SPLITS[$k]}" metrics.json "${cmd[@]}" >/dev/null
  done
  if [ "$1" != "${1#$OUT/s${seeds[0]}/}" ] && [ ! -f "$1/picture/renders/picture/$render" ]; then
    have_model "$1"
    rm -rf "$1/picture.tmp"
    "$FILLGS" eval --model "$m" "${DS[@]}" --cameras "$TEST" --select-cameras "$cam" --splits picture --out "$1/picture.tmp" --quiet >/dev/null
    rm -rf "$1/picture"
    mv "$1/picture.tmp" "$1/picture"
  fi
}
have_model() {  # model folder: a step still to run reads its model.ply
  [ -f "$1/model.ply" ] && return 0
  case $1 in
    */backbone)
      if [ "$JOBS" = 1 ]; then
        backbone_again "$(basename "$(dirname "$1")")"
      else  # jobs that need it at once: the first trains it again, the others wait for it
        (
          flock 9
          [ -f "$1/model.ply" ] || backbone_again "$(basename "$(dirname "$1")")"
        ) 9>"${TMPDIR:-/tmp}/pool_select.$$.backbone.lock"
      fi ;;
    *) echo "pool_select: $1/model.ply is not here (git keeps a run's records, not its model) and a step still to run reads it; delete $1 to train it again" >&2
       exit 1 ;;
  esac
}

IFS=, read -r -a seeds <<<"$SEEDS"
IFS=, read -r -a budgets <<<"$BUDGETS"
# Records made on another instruction set are continued on it: seed 1's backbone is the
# first step every run makes (bench/lib.sh, hold_instruction_set).
hold_instruction_set "$OUT/s1/backbone/step.txt"
backbone_command() {  # seed, output folder -> BCMD
  BCMD=("$FILLGS" train "${TRAIN_DS[@]}" --train-cameras $TRAIN "${RULE[@]}" "${INIT[@]}" "${OPTS[@]}" --seed "$1" --out "$2" --quiet)
}
backbone_files() { ls model.ply init_points.ply 2>/dev/null; }  # what model.sha256 records (in the folder)
# A record vouches for exactly the files named after it: one line each, no other (a record
# cut to its first line would check init_points.ply and let any model.ply through).
sha256_covers() {  # record, files
  local record=$1
  shift
  local named
  named=$(sed -n 's/^[0-9a-f]\{64\}  \(.*\)$/\1/p' "$record" | sort)
  if [ "$named" != "$(printf '%s\n' "$@" | sort)" ] || [ "$(wc -l <"$record")" -ne $# ]; then
    echo "pool_select: $record names $(echo $named | tr -d '\n' | sed 's/^$/nothing/'), not exactly the backbone's $*" >&2
    return 1
  fi
}
backbone() {  # seed: the backbone, from the training cameras alone
  local S=$OUT/s$1
  backbone_command "$1" "$S/backbone"
  step "$S/backbone" summary.json "${BCMD[@]}"
  [ -f "$S/backbone/model.sha256" ] || (cd "$S/backbone" && sha256sum $(backbone_files) >model.sha256.tmp && mv model.sha256.tmp model.sha256)
  evaluate "$S/backbone"
}
backbone_again() {  # "s<seed>": its backbone trained again where git kept only its records
  local S=$OUT/$1
  [ -f "$S/backbone/model.sha256" ] || { echo "pool_select: $S/backbone has no model.ply and no model.sha256; delete $S/backbone" >&2; exit 1; }
  echo "pool_select: $S/backbone/model.ply is not here (git keeps the records, not the models): training it again" >&2
  backbone_command "${1#s}" "$S/backbone.again"
  rm -rf "$S/backbone.again"
  "${BCMD[@]}"
  if ! sha256_covers "$S/backbone/model.sha256" $(cd "$S/backbone.again" && backbone_files) ||
    ! (cd "$S/backbone.again" && sha256sum --check --quiet ../backbone/model.sha256); then
    echo "pool_select: $S/backbone trained again is not the model its finished rows used (model.sha256); delete $OUT/$1 to run the seed again" >&2
    exit 1
  fi
  (cd "$S/backbone.again" && mv $(backbone_files) ../backbone/)
  rm -rf "$S/backbone.again"
}
# A step that reads seed SEED's backbone (its model or its initial points).
bstep() {  # seed, step's arguments
  local s=$1
  shift
  finished "$@" || have_model "$OUT/s$s/backbone"
  step "$@"
}
# --jobs N: a seed's trainings from scratch (the control, the dense reference, each strategy's
# choice and training) run N at a time, each on one core of its own (taskset -c; fillgs's
# threads follow the process's cores), after the seed's backbone and before the next seed.
# Results do not depend on the thread count, so the records are those of --jobs 1; a step's
# seconds are then one core's.
[[ "$JOBS" =~ ^[1-9][0-9]*$ ]] || { echo "pool_select: --jobs expects a positive count, got '$JOBS'" >&2; exit 1; }
[ "$JOBS" = 1 ] || command -v taskset >/dev/null || { echo "pool_select: --jobs $JOBS needs taskset (util-linux)" >&2; exit 1; }
declare -A JOB_SLOT=()  # running job's pid -> its core
JOB_FAILED=0
wait_job() {  # waits for one running job to end; frees its core
  local pid=
  wait -n -p pid "${!JOB_SLOT[@]}" || JOB_FAILED=1
  unset "JOB_SLOT[$pid]"
}
run_job() {  # runs "$@" (a function of this script) now, or with --jobs in the background on a free core
  if [ "$JOBS" = 1 ]; then
    "$@"
    return
  fi
  [ ${#JOB_SLOT[@]} -lt "$JOBS" ] || wait_job
  local core used c
  for ((core = 0; ; ++core)); do
    used=0
    for c in "${JOB_SLOT[@]}"; do [ "$c" = "$core" ] && used=1; done
    [ $used = 0 ] && break
  done
  ( STEP_RUNNER=(taskset -c "$((core % $(nproc)))"); "$@" ) &
  JOB_SLOT[$!]=$core
}
wait_jobs() {  # every running job; stops the script when one failed
  while [ ${#JOB_SLOT[@]} -gt 0 ]; do wait_job; done
  [ $JOB_FAILED = 0 ] || { echo "pool_select: a step run with --jobs $JOBS failed (above)" >&2; exit 1; }
}
# Initial points of every model trained from scratch, the dense reference's included: the
# backbone's (COLMAP points of the training cameras, or the points its views gave, saved
# beside it), so that the rows differ only in their photographs.
scratch_points() {  # seed
  if [ ${#INIT[@]} -gt 0 ]; then echo "${INIT[1]}"; else echo "$OUT/s$1/backbone/init_points.ply"; fi
}
# Trained from scratch by the rule on the training cameras and the photographs a selection
# chose (none: the training cameras alone).
scratch() {  # seed, id, cameras, extra train options
  local s=$1 id=$2 cams=$3
  shift 3
  bstep "$s" "$OUT/s$s/$id" summary.json "$FILLGS" train "${TRAIN_DS[@]}" --train-cameras "$cams" "$@" "${RULE[@]}" --points "$(scratch_points "$s")" "${OPTS[@]}" \
    --seed "$s" --out "$OUT/s$s/$id" --quiet
  evaluate "$OUT/s$s/$id"
}
# The cameras as transforms.json, for the positive control's geometry.
for f in "$CAMERAS:rig_cameras" "$TEST:judged_cameras"; do
  [ -f "$OUT/${f##*:}.json" ] || { "$FILLGS" cameras --cameras "${f%:*}" --out "$OUT/${f##*:}.tmp.json" >/dev/null && mv "$OUT/${f##*:}.tmp.json" "$OUT/${f##*:}.json"; }
done
JUDGED=$(IFS=:; echo "${SPLIT_CAMS[*]}")
# Per seed, once: the backbone and the dense reference (the control is a row of its own, below).
seed_references() {  # seed
  local s=$1
  backbone "$s"
  run_job scratch "$s" dense $TRAIN,$POOL  # the longest: first, when jobs share the cores
}
control_rows() {  # seed: the control; seed 1 also the curriculum's backbone, both judged on the training cameras
  local s=$1
  scratch "$s" scratch.control $TRAIN
  if [ "$s" = 1 ]; then
    bstep 1 "$OUT/s1/backbone.curriculum" summary.json "$FILLGS" train "${TRAIN_DS[@]}" --train-cameras $TRAIN --draws-per-view "$DRAWS" \
      --time-ramp 0.7 --points "$(scratch_points 1)" "${OPTS[@]}" --seed 1 --out "$OUT/s1/backbone.curriculum" --quiet
    evaluate "$OUT/s1/backbone.curriculum"
    for m in scratch.control backbone.curriculum; do
      local cmd=("$FILLGS" eval --model "$OUT/s1/$m/model.ply" "${DS[@]}" --cameras "$CAMERAS" --select-cameras $TRAIN --splits train
        --no-renders --affine-fit --out "$OUT/s1/$m/eval_train" --quiet)
      finished "$OUT/s1/$m/eval_train" metrics.json "${cmd[@]}" || have_model "$OUT/s1/$m"
      step "$OUT/s1/$m/eval_train" metrics.json "${cmd[@]}" >/dev/null
    done
  fi
}
# One strategy's row at budget K: its choice, then its model trained from scratch.
strategy_row() {  # seed, strategy, K
  local s=$1 st=$2 K=$3
  if [ "$st" = positive ]; then
    # Allowed to know the judged cameras: the pool photographs nearest them, spread over the clip.
    local frames
    frames=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['frames'])" "$OUT/s$s/backbone/summary.json")
    step "$OUT/s$s/choose.positive.K$K" pool_chosen.json python3 bench/pool_positive.py --rig "$OUT/rig_cameras.json" \
      --held-out "$OUT/judged_cameras.json" --splits "$JUDGED" --pool $POOL --frames "$frames" --budget "$K" \
      --out "$OUT/s$s/choose.positive.K$K/pool_chosen.json"
  else
    # K camera-times chosen on the backbone in one greedy round.
    bstep "$s" "$OUT/s$s/choose.$st.K$K" summary.json "$FILLGS" finetune --model "$OUT/s$s/backbone/model.ply" "${TRAIN_DS[@]}" --train-cameras $TRAIN \
      --seed "$s" --out "$OUT/s$s/choose.$st.K$K" --iterations 1 --select-every 1 --pool-cameras $POOL --pool-budget "$K" --strategy "$st" \
      --weighting none --quiet
  fi
  scratch "$s" "scratch.$st.K$K" $TRAIN --camera-times "$OUT/s$s/choose.$st.K$K/pool_chosen.json"
}
# With --jobs, a seed's rows start longest first, so that the row left running alone at the
# end is a short one: the dense reference, the two choices that cost most (FisherRF's and
# coverage3d's: 21 s and 10 s in s2/choose.*.K30/summary.json, the next 5 s), the other rows as
# listed, then the control (no photographs) and the positive control (no choice to make);
# seed 1's control row also trains the curriculum's backbone, and starts right after the
# dense reference. The records do not depend on the order.
JOB_ORDER=()
for st in fisherrf coverage3d "${STRATEGIES[@]}"; do
  [[ " ${STRATEGIES[*]} " == *" $st "* && " ${JOB_ORDER[*]} " != *" $st "* && $st != positive ]] && JOB_ORDER+=("$st")
done
JOB_ORDER+=(control)
[[ " ${STRATEGIES[*]} " == *" positive "* ]] && JOB_ORDER+=(positive)
row_job() {  # seed, row of JOB_ORDER, K
  if [ "$2" = control ]; then run_job control_rows "$1"; else run_job strategy_row "$1" "$2" "$3"; fi
}
# The main protocol: budget by budget as the plan lists them, every seed's rows before the next seed.
if [ $NO_SCRATCH = 0 ]; then
  for entry in $PLAN; do
    K=${entry%%:*}
    IFS=, read -r -a plan_seeds <<<"${entry#*:}"
    for s in "${plan_seeds[@]}"; do
      seed_references "$s"
      [ "$s" = 1 ] && run_job control_rows "$s"  # seed 1's trains two models
      for row in "${JOB_ORDER[@]}"; do
        [ "$s" = 1 ] && [ "$row" = control ] && continue
        row_job "$s" "$row" "$K"
      done
      wait_jobs
    done
  done
fi
# The backbone fine-tuned (the warm start; with --pool-budget the selection runs in its rounds), at
# the rates the benchmark was calibrated with (repair: fillgs's own backbones).
finetune() {  # seed, id, extra finetune options
  local s=$1 id=$2
  shift 2
  bstep "$s" "$OUT/s$s/$id" summary.json "$FILLGS" finetune --model "$OUT/s$s/backbone/model.ply" "${TRAIN_DS[@]}" --train-cameras $TRAIN \
    --seed "$s" --out "$OUT/s$s/$id" --motion-rates repair "${FT[@]}" "$@" --quiet
  evaluate "$OUT/s$s/$id"
}
if [ $WARM = 1 ]; then
  for entry in $PLAN; do
    K=${entry%%:*}
    IFS=, read -r -a plan_seeds <<<"${entry#*:}"
    for s in "${plan_seeds[@]}"; do
      backbone "$s"
      finetune "$s" control --trajectories 0
      for st in "${STRATEGIES[@]}"; do
        [ "$st" = positive ] && continue  # the warm start selects in its own rounds, on the library's strategies
        finetune "$s" "$st.K$K" --pool-cameras $POOL --pool-budget "$K" --strategy "$st" --weighting none
      done
      # What FillGS's and ExploreGS's weights do to real photographs (FillGS's selection), once:
      # seed 1 at the smallest budget, where FillGS is among the strategies asked for.
      if [ "$s" = 1 ] && [ "$K" = "$WEIGHTS_K" ] && [[ " ${STRATEGIES[*]} " == *" fillgs "* ]]; then
        for w in fillgs exploregs; do
          finetune "$s" "fillgs.K$WEIGHTS_K.w-$w" --pool-cameras $POOL --pool-budget "$WEIGHTS_K" --strategy fillgs --weighting $w
        done
      fi
    done
  done
fi

python3 bench/pool_select_report.py "$OUT" --title "$TITLE" --seeds "$SEEDS" --budgets "$BUDGETS" --splits "$(IFS=,; echo "${SPLITS[*]}")" \
  --strategies "$(IFS=,; echo "${STRATEGIES[*]}")" >/dev/null
# What every strategy chose, side by side (camera x frame, first seed).
for K in "${budgets[@]}"; do
  pics=()
  for st in "${STRATEGIES[@]}"; do
    for d in "choose.$st.K$K" "$st.K$K"; do  # the main protocol's selection where it ran
      if [ -f "$OUT/s${seeds[0]}/$d/pool_chosen.png" ]; then
        pics+=("$OUT/s${seeds[0]}/$d/pool_chosen.png")
        break
      fi
    done
  done
  [ ${#pics[@]} -gt 0 ] && oiiotool --nosoftwareattrib "${pics[@]}" --mosaic 4x2 -o "$OUT/chosen_K${K}_s${seeds[0]}.png"
done
cat "$OUT/results.md"

# The picture (fixed before any run): ground truth | the control | the positive control |
# random | FillGS, trained from scratch at PICTURE_K (the middle default budget), at the first
# near (or held-out) camera, the clip's middle frame, the first seed; a row that did not run
# is left out.
K=$PICTURE_K
S=$OUT/s${seeds[0]}
tiles=("$truth")
ids=()
for id in scratch.control "scratch.positive.K$K" "scratch.random.K$K" "scratch.fillgs.K$K"; do
  [ -f "$S/$id/summary.json" ] && ids+=("$id")
done
if [ ${#ids[@]} -lt 2 ]; then
  echo "picture: no table at K = $K among these runs; $OUT/compare.png left as it was"
  exit 0
fi
for id in "${ids[@]}"; do
  evaluate "$S/$id"  # its picture, where an older run did not render one
  tiles+=("$S/$id/picture/renders/picture/$render")
done
# The photograph at the renders' size.
size=$(oiiotool --info "${tiles[1]}" | sed -n 's/.* \([0-9]*\) x *\([0-9]*\).*/\1x\2/p' | head -n 1)
tiles=("${tiles[0]}" --resize "$size" "${tiles[@]:1}")
oiiotool --nosoftwareattrib "${tiles[@]}" --mosaic "$((${#ids[@]} + 1))x1" --resize 200% -o "$OUT/compare.png"
tiles_named=$(printf ' | %s' "${ids[@]}")
echo "picture: ground truth$tiles_named at held-out camera $cam, source frame $SRC -> $OUT/compare.png"
