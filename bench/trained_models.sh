#!/usr/bin/env bash
# Reads every trained-model format the field's codebases save, end to end: PyTorch saves one
# model per format with the architecture of its code's N3V configuration and N Gaussians
# (tests/make_model_fixtures.py --bench), then `fillgs info` and `fillgs observe` (ray traced,
# four cameras, every frame) run on each. Writes OUT/results.md (a table with provenance),
# OUT/results.json and each command's JSON summary; the models themselves are made in a
# scratch folder and removed.
#
#   bench/trained_models.sh [--fillgs BIN] [--gaussians N] [--frames F] [--smoke] OUT
#
# Defaults: build/bin/fillgs, N = 10000, F = 300 (per-frame PLYs: 30). --smoke: N = 200, F = 6.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
fillgs="$root/build/bin/fillgs"
gaussians=10000
frames=300
out=
while [ $# -gt 0 ]; do
  case "$1" in
    --fillgs) fillgs="$2"; shift 2 ;;
    --gaussians) gaussians="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --smoke) gaussians=200; frames=6; shift ;;
    -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
    -*) echo "bench/trained_models.sh: unknown option $1" >&2; exit 2 ;;
    *) out="$1"; shift ;;
  esac
done
[ -n "$out" ] || { echo "bench/trained_models.sh: give the output folder" >&2; exit 2; }
python="${FILLGS_TORCH_PYTHON:-/usr/bin/python3}"
mkdir -p "$out"
# The models and the observation tables are large: they live in a scratch folder, removed at the end.
work="$(mktemp -d "${TMPDIR:-/tmp}/fillgs_trained_models.XXXXXX")"
trap 'rm -rf "$work"' EXIT
models="$work/models"
command_line="bench/trained_models.sh --gaussians $gaussians --frames $frames"
echo "making the models ($gaussians Gaussians, $frames frames) ..."
"$python" "$root/tests/make_model_fixtures.py" --bench "$gaussians" --frames "$frames" "$models" >/dev/null
# Four 64x48 cameras on a circle of radius 4 around the origin, looking at it (OpenCV axes).
"$python" "$root/bench/ring_cameras.py" 4 "$out/cameras.json"
declare -A flags=(
  [e-d3dgs]=""
  [4dgaussians]="--model-frames $frames"
  [4dgs]="--model-frames $frames --model-time-range 0:$(awk "BEGIN{print $frames/30}")"
  [dynamic3dgs]=""
  [ply-frames]=""
  [deformable3dgs]="--model-frames $frames"
)
rows=()
json="["
for fmt in e-d3dgs 4dgaussians 4dgs deformable3dgs dynamic3dgs ply-frames; do
  model="$models/$fmt"
  size=$(du -sb "$model" | cut -f1)
  # shellcheck disable=SC2086  # the flags are words
  t0=$(date +%s.%N)
  "$fillgs" info --json ${flags[$fmt]} "$model" >"$out/$fmt.info.json"
  t1=$(date +%s.%N)
  # shellcheck disable=SC2086
  "$fillgs" observe --quiet --scene "$model" ${flags[$fmt]} --cameras "$out/cameras.json" --mode raytraced --no-plots --out "$work/observe-$fmt" >/dev/null
  cp "$work/observe-$fmt/summary.json" "$out/$fmt.observe.json"
  t2=$(date +%s.%N)
  read -r n dyn keys < <("$python" -c 'import json,sys; j=json.load(open(sys.argv[1])); print(j["gaussians"], j["dynamic"], j.get("keyframes", j.get("frames", 1)))' "$out/$fmt.info.json")
  read_s=$(awk "BEGIN{printf \"%.1f\", $t1-$t0}")
  obs_s=$(awk "BEGIN{printf \"%.1f\", $t2-$t1}")
  share=$(awk "BEGIN{printf \"%.0f\", 100*$dyn/$n}")
  echo "$fmt: $n Gaussians, $share% moving, $keys frames; read and sampled in $read_s s, observed in $obs_s s"
  rows+=("| $fmt | $(awk "BEGIN{printf \"%.1f\", $size/1e6}") | $n | $share % | $keys | $read_s | $obs_s |")
  json+="$( [ "$json" = "[" ] || echo ,){\"format\":\"$fmt\",\"bytes\":$size,\"gaussians\":$n,\"moving\":$dyn,\"frames\":$keys,\"read_seconds\":$read_s,\"observe_seconds\":$obs_s}"
done
json+="]"
commit=$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)
machine="$(nproc) cores, $(sed -n 's/^model name\s*: //p' /proc/cpuinfo | head -1)"
printf '%s\n' "$json" >"$out/results.json"
{
  echo "Command: \`$command_line OUT\` · commit $commit · $(date -u +%Y-%m-%d) · $machine."
  echo "Read: \`fillgs info\` (reading the files; networks and 4DGS: the still rule's sweep of 30 frames and the choice of training keys; the per-frame formats: every frame into keys)."
  echo "Observe: \`fillgs observe --mode raytraced\`, four 64×48 cameras, every frame (the time includes reading)."
  echo
  echo "| format | files (MB) | Gaussians | moving | frames | read (s) | observe (s) |"
  echo "|---|---|---|---|---|---|---|"
  printf '%s\n' "${rows[@]}"
} >"$out/results.md"
echo "wrote $out/results.md"
