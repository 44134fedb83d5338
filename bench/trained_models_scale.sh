#!/usr/bin/env bash
# Trained models at scale: models saved by PyTorch with E-D3DGS's and 4DGaussians' N3V
# architectures (tests/make_model_fixtures.py --bench), N Gaussians x F frames, and an E-D3DGS
# model whose background (80 %) is still but for network noise. Pieces, each skipped when its
# result is already in OUT (the run resumes where it was stopped):
#   networks   fillgs_bench networks: the dense kernel against the reference products;
#   observe    `fillgs observe` (frustum and ray traced, 20 cameras, every frame) streamed
#              (default) and as fillgs read them before (keys at every frame, reference
#              products: --model-evaluation keys --network-kernel eigen), and on the same
#              Gaussians written as a fillgs 4D PLY; wall time and peak memory (GNU time);
#   still      `fillgs info --still-sweep S --still-recheck R`: still Gaussians, rechecked ones
#              and seconds, for sweeps of 10, 30 and F frames alone and 30 with rechecks;
#   few        `observe --frames 4` streamed, against all frames;
#   before     with --before BIN: the streamed frustum piece by BIN/fillgs (an earlier build)
#              in the same run.
# The streamed frustum pieces are also set against the network alone: N x F Gaussian-frames at
# the dense kernel's rate measured by the networks piece.
# Writes OUT/results.md (tables with provenance) from the pieces' files.
#
#   bench/trained_models_scale.sh [--gaussians N] [--frames F] [--formats A,B] [--before BIN] [--smoke] [--report-only] OUT
#
# --report-only: results.md from the pieces there, pieces not run shown as "-".
# --streamed-frustum-only: networks, frustum streamed and --frames 4 only (sizes whose keys
# would not fit in memory: 1,000,000 Gaussians x 300 frames of keys are 16.8 GB).
# --frustum-only: those and the frustum piece on the fillgs 4D PLY.
#
# Defaults: N = 200000, F = 300, formats e-d3dgs,4dgaussians,e-d3dgs-still. --smoke: N = 300, F = 6.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="$root/build/bin"
gaussians=200000
frames=300
formats=e-d3dgs,4dgaussians,e-d3dgs-still
report_only=0
streamed_only=0
with_ply=0
before=
out=
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --before) before="$(cd "$2" && pwd)"; shift 2 ;;
    --gaussians) gaussians="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --formats) formats="$2"; shift 2 ;;
    --smoke) gaussians=300; frames=6; shift ;;
    --report-only) report_only=1; shift ;;
    --streamed-frustum-only) streamed_only=1; shift ;;
    --frustum-only) streamed_only=1; with_ply=1; shift ;;
    -h|--help) sed -n '2,27p' "$0"; exit 0 ;;
    -*) echo "bench/trained_models_scale.sh: unknown option $1" >&2; exit 2 ;;
    *) out="$1"; shift ;;
  esac
done
[ -n "$out" ] || { echo "bench/trained_models_scale.sh: give the output folder" >&2; exit 2; }
python="${FILLGS_TORCH_PYTHON:-/usr/bin/python3}"
mkdir -p "$out/pieces"
models="$out/pieces/models-$gaussians-$frames"
if [ "$report_only" = 0 ] && [ ! -f "$models/.complete" ]; then
  echo "making the models ($gaussians Gaussians, $frames frames: $formats) ..."
  "$python" "$root/tests/make_model_fixtures.py" --bench "$gaussians" --frames "$frames" --formats "$formats" "$models" >/dev/null
  touch "$models/.complete"
fi
# 20 cameras, 64x48, on a circle of radius 4 around the origin, looking at it.
"$python" "$root/bench/ring_cameras.py" 20 "$out/pieces/cameras.json" --wave
# Each piece's commit and date, for the report's provenance.
ran() { echo "$1 $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown) $(date -u +%Y-%m-%d)" >>"$out/pieces/commits.txt"; }
flags_of() { case "$1" in 4dgaussians) echo "--model-frames $frames" ;; *) echo "" ;; esac; }
# One observe run: its seconds and peak memory into a piece file, unless it is there.
observe() {  # piece-name scene extra-flags... (OBSERVE_BIN: another build's folder)
  local name="$1" piece="$out/pieces/$1.txt" scene="$2" use="${OBSERVE_BIN:-$bin}"; shift 2
  { [ -f "$piece" ] || [ "$report_only" = 1 ]; } && return 0
  if [ "$streamed_only" = 1 ]; then
    case "$name" in *.frustum.streamed|*.frustum.streamed-before|*.frustum.few) ;; *.frustum.fillgs-ply) [ "$with_ply" = 1 ] || return 0 ;; *) return 0 ;; esac
  fi
  echo "  $name ..."
  local tmp="$out/pieces/$name.run"
  rm -rf "$tmp"
  /usr/bin/time -f "%e %M" -o "$tmp.time" "$use/fillgs" observe --quiet --scene "$scene" --cameras "$out/pieces/cameras.json" --no-plots --out "$tmp" "$@" >/dev/null
  read -r secs kb <"$tmp.time"
  local moving; moving=$("$python" -c 'import json,sys; j=json.load(open(sys.argv[1])); print(j["dynamic"])' "$tmp/summary.json" 2>/dev/null || echo "")
  echo "$secs $kb $moving" >"$piece.part" && mv "$piece.part" "$piece" && ran "$name"
  rm -rf "$tmp" "$tmp.time"
}
if [ "$report_only" = 0 ] && [ ! -f "$out/pieces/networks.md" ]; then
  echo "networks ..."
  "$bin/fillgs_bench" networks --models "$models" --model-frames "$frames" >"$out/pieces/networks.md.part"
  mv "$out/pieces/networks.md.part" "$out/pieces/networks.md" && ran networks
fi
IFS=, read -r -a fmts <<<"$formats"
# The pieces in order of what they tell: frustum (streamed, on the fillgs 4D PLY), the still
# rule, a few frames, ray traced, then as fillgs read them before (keys, reference products).
make_ply() {  # the same Gaussians as a fillgs 4D PLY (a key at every frame)
  local ply="$out/pieces/$1.fillgs.ply"
  if [ "$report_only" = 0 ] && { [ "$streamed_only" = 0 ] || [ "$with_ply" = 1 ]; } && [ ! -f "$ply" ]; then
    # shellcheck disable=SC2046  # the flags are words
    "$bin/fillgs" convert --scene "$models/$1" $(flags_of "$1") --to fillgs --out "$ply" >/dev/null
  fi
  echo "$ply"
}
# shellcheck disable=SC2046  # the flags are words
for fmt in "${fmts[@]}"; do
  observe "$fmt.frustum.streamed" "$models/$fmt" --mode frustum $(flags_of "$fmt")
  [ -n "$before" ] && OBSERVE_BIN="$before" observe "$fmt.frustum.streamed-before" "$models/$fmt" --mode frustum $(flags_of "$fmt")
  observe "$fmt.frustum.fillgs-ply" "$(make_ply "$fmt")" --mode frustum --frames "$frames"
done
# The still rule (--still-sweep S, --still-recheck R): how many Gaussians it finds still, how
# many it rechecks at every frame, and its time: sweeps of 10, 30 and every frame alone (R = 1),
# and the default sweep of 30 with its recheck at 0.5 (the default) and 0.25 of a tolerance.
still_runs="10:1 30:1 $frames:1 30:0.5 30:0.25"
for fmt in "${fmts[@]}"; do
  for run in $still_runs; do
    sweep=${run%%:*} recheck=${run##*:}
    piece="$out/pieces/$fmt.still-$sweep-$recheck.txt"
    { [ -f "$piece" ] || [ "$report_only" = 1 ] || [ "$streamed_only" = 1 ]; } && continue
    echo "  $fmt.still-$sweep-$recheck ..."
    # shellcheck disable=SC2046
    /usr/bin/time -f "%e %M" -o "$piece.time" "$bin/fillgs" info --json --still-sweep "$sweep" --still-recheck "$recheck" $(flags_of "$fmt") "$models/$fmt" >"$piece.json"
    read -r secs kb <"$piece.time"
    echo "$secs $kb $("$python" -c 'import json,re,sys; j=json.load(open(sys.argv[1])); m=[re.search(r"for the (\d+) whose", n) for n in j["notes"]]; m=[x.group(1) for x in m if x]; print(j["static"], m[0] if m else 0)' "$piece.json")" >"$piece.part"
    mv "$piece.part" "$piece" && rm -f "$piece.time" "$piece.json" && ran "$fmt.still-$sweep-$recheck"
  done
done
# shellcheck disable=SC2046
for fmt in "${fmts[@]}"; do observe "$fmt.frustum.few" "$models/$fmt" --mode frustum --frames 4 $(flags_of "$fmt"); done
# shellcheck disable=SC2046
for fmt in "${fmts[@]}"; do
  observe "$fmt.raytraced.streamed" "$models/$fmt" --mode raytraced $(flags_of "$fmt")
  observe "$fmt.raytraced.fillgs-ply" "$(make_ply "$fmt")" --mode raytraced --frames "$frames"
done
# As fillgs read them before (the slowest pieces, last).
# shellcheck disable=SC2046
for mode in frustum raytraced; do
  for fmt in "${fmts[@]}"; do observe "$fmt.$mode.keys-eigen" "$models/$fmt" --mode "$mode" $(flags_of "$fmt") --model-evaluation keys --network-kernel eigen; done
done
# A piece's three numbers, or "-" for a piece not run (a run stopped by its time limit).
piece() { if [ -f "$out/pieces/$1.txt" ]; then cat "$out/pieces/$1.txt"; else echo "- - -"; fi; }
mb() { [ "$1" = - ] && echo - || awk "BEGIN{printf \"%.0f\", $1/1024}"; }
ratio() { { [ "$1" = - ] || [ "$2" = - ]; } && echo - || awk "BEGIN{printf \"%.2f\", $1/$2}"; }
# The commits and dates the pieces ran at (HEAD today when none is recorded).
commit=$( { [ -f "$out/pieces/commits.txt" ] && awk '{print $2}' "$out/pieces/commits.txt" | sort -u | paste -sd, - ; } || git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)
dates=$( { [ -f "$out/pieces/commits.txt" ] && awk '{print $3}' "$out/pieces/commits.txt" | sort -u | paste -sd, - ; } || date -u +%Y-%m-%d)
machine="$(nproc) cores, $(sed -n 's/^model name\s*: //p' /proc/cpuinfo | head -1), $(awk '/MemTotal/{printf "%.0f GB", $2/1048576}' /proc/meminfo)"
{
  echo "Command: \`bench/trained_models_scale.sh --gaussians $gaussians --frames $frames --formats $formats$([ "$streamed_only" = 1 ] && { [ "$with_ply" = 1 ] && echo " --frustum-only" || echo " --streamed-frustum-only"; })$([ -n "$before" ] && echo " --before BIN") OUT\` · commit $commit · $dates · $machine."
  echo
  echo "Networks (\`fillgs_bench networks\`, $gaussians Gaussians):"
  echo
  [ -f "$out/pieces/networks.md" ] && sed -n '/^dense kernel/p;/^|/p' "$out/pieces/networks.md"
  echo
  echo "\`fillgs observe\`, 20 cameras of 64×48, all $frames frames unless said; wall time (reading included) and peak resident memory (\"-\": a piece not run):"
  echo
  echo "| model | mode | read as | moving Gaussians | seconds | peak memory (MB) | vs keys + reference: time | memory |"
  echo "|---|---|---|---|---|---|---|---|"
  for fmt in "${fmts[@]}"; do
    for mode in frustum raytraced; do
      read -r s0 k0 _ < <(piece "$fmt.$mode.keys-eigen")
      for how in keys-eigen streamed fillgs-ply; do
        read -r s k m < <(piece "$fmt.$mode.$how")
        label=$(case $how in keys-eigen) echo "keys at every frame, reference products (before)" ;; streamed) echo "streamed, dense kernel" ;; fillgs-ply) echo "the same Gaussians as a fillgs 4D PLY" ;; esac)
        echo "| $fmt | $mode | $label | $m | $s | $(mb "$k") | $(ratio "$s0" "$s") | $(ratio "$k0" "$k") |"
      done
    done
    read -r s k m < <(piece "$fmt.frustum.few")
    echo "| $fmt | frustum | streamed, \`--frames 4\` | $m | $s | $(mb "$k") | | |"
  done
  echo
  echo "Streamed frustum \`observe\` against its network alone ($gaussians × $frames Gaussian-frames at the dense kernel's rate above)$([ -n "$before" ] && echo "; \"before\": the same piece by an earlier build ($(git -C "$before/../.." rev-parse --short HEAD 2>/dev/null || echo "another build")) in the same run"):"
  echo
  echo "| model | network alone (s) | observe (s) | observe / network | before: observe (s) | before / network |"
  echo "|---|---|---|---|---|---|"
  for fmt in "${fmts[@]}"; do
    rate=$(awk -F'|' -v f="$fmt" '$2 ~ "^ *"f" *$" {gsub(/ /, "", $6); print $6}' "$out/pieces/networks.md" 2>/dev/null | head -1)
    alone=$( [ -n "$rate" ] && awk "BEGIN{printf \"%.4g\", $gaussians * $frames / $rate}" || echo -)
    read -r s _ _ < <(piece "$fmt.frustum.streamed")
    read -r sb _ _ < <(piece "$fmt.frustum.streamed-before")
    echo "| $fmt | $alone | $s | $(ratio "$s" "$alone") | $sb | $(ratio "$sb" "$alone") |"
  done
  echo
  echo "The still rule (\`fillgs info --still-sweep S --still-recheck R\`: reading, the sweep, the recheck, the training keys' choice):"
  echo
  echo "| model | sweep frames | recheck above (share of a tolerance) | still Gaussians | rechecked at every frame | seconds | peak memory (MB) |"
  echo "|---|---|---|---|---|---|---|"
  for fmt in "${fmts[@]}"; do
    for run in $still_runs; do
      sweep=${run%%:*} recheck=${run##*:}
      if [ -f "$out/pieces/$fmt.still-$sweep-$recheck.txt" ]; then read -r s k st rc <"$out/pieces/$fmt.still-$sweep-$recheck.txt"; else s=- k=- st=- rc=-; fi
      echo "| $fmt | $sweep | $([ "$recheck" = 1 ] && echo "none" || echo "$recheck") | $st | $rc | $s | $(mb "$k") |"
    done
  done
} >"$out/results.md.part"
mv "$out/results.md.part" "$out/results.md"
echo "wrote $out/results.md"
