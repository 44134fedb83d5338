#!/usr/bin/env bash
# A benchmark step's training again, with an earlier build and with this one, alone and one
# after the other: the seconds each takes (the ratio is the speed-up of the change) and
# whether the two train the same model byte for byte. A step of bench/pool_select.sh run
# in full (its own draws) must also give the recorded step's summary (every value but its
# seconds and peak memory) and, when the step has eval_near, the recorded near metrics: the
# change keeps the benchmark's records.
#
#   bench/train_step_speed.sh --before BIN [--bin BIN] [--root DIR] [--draws N] [--one-core] STEP OUT
#   bench/train_step_speed.sh [--bin BIN] --smoke OUT
#
# STEP: a step folder holding the command.txt of a `fillgs train` (one argument per line, as
# bench/lib.sh writes it), relative to DIR (default: this checkout), where its inputs (the
# backbone's init_points.ply, which git does not keep) must also lie: the folder
# bench/pool_select.sh ran in. --before BIN: the earlier build's fillgs; --bin BIN: this one's
# (default build/bin/fillgs). --draws N: a shorter run (--draws-per-view N; no comparison
# with the records). --one-core: each training on one core (taskset -c 0; its threads follow
# the core), as bench/pool_select.sh --jobs runs them. FILLGS_INSTRUCTION_SET is taken from the step's step.txt, as
# bench/pool_select.sh holds it. Writes OUT/results.md; the
# models live in OUT/scratch, removed at the end. --smoke: a 48x36 synthetic scene trained
# 40 iterations as its own step, the same build as before and after.
set -euo pipefail
root_here="$(cd "$(dirname "$0")/.." && pwd)"
root="$root_here"
after="$root_here/build/bin/fillgs"
before=
draws=
smoke=0
one_core=0
args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --before) before="$(cd "$(dirname "$2")" && pwd)/$(basename "$2")"; shift 2 ;;
    --root) root="$(cd "$2" && pwd)"; shift 2 ;;
    --bin) after="$(cd "$(dirname "$2")" && pwd)/$(basename "$2")"; shift 2 ;;
    --draws) draws="$2"; shift 2 ;;
    --smoke) smoke=1; shift ;;
    --one-core) one_core=1; shift ;;
    -h|--help) sed -n '2,24p' "$0"; exit 0 ;;
    -*) echo "bench/train_step_speed.sh: unknown option $1" >&2; exit 2 ;;
    *) args+=("$1"); shift ;;
  esac
done
. "$root_here/bench/lib.sh"
if [ "$smoke" = 1 ]; then
  [ ${#args[@]} = 1 ] || { echo "bench/train_step_speed.sh: --smoke takes the output folder only" >&2; exit 2; }
  out="$(mkdir -p "${args[0]}" && cd "${args[0]}" && pwd)"
  root="$out/smoke"
  rm -rf "$root" && mkdir -p "$root/step"
  "$after" synth --out "$root/scene" --frames 3 --width 48 --height 36 --spacing 0.06 --quiet >/dev/null
  (cd "$root" && step step summary.json "$after" train --images scene --cameras scene/transforms_train.json \
    --iterations 40 --out step --quiet >/dev/null)
  step_dir=step
  before="$after"
else
  [ ${#args[@]} = 2 ] || { echo "bench/train_step_speed.sh: give STEP and OUT" >&2; exit 2; }
  [ -n "$before" ] || { echo "bench/train_step_speed.sh: give --before BIN, the earlier build's fillgs" >&2; exit 2; }
  step_dir="${args[0]}"
  out="$(mkdir -p "${args[1]}" && cd "${args[1]}" && pwd)"
fi
[ -x "$before" ] || { echo "bench/train_step_speed.sh: $before is not an executable" >&2; exit 2; }
[ -f "$root/$step_dir/command.txt" ] || { echo "bench/train_step_speed.sh: $root/$step_dir/command.txt is not there" >&2; exit 2; }
mapfile -t cmd <"$root/$step_dir/command.txt"
[ "${cmd[1]:-}" = train ] || { echo "bench/train_step_speed.sh: $root/$step_dir/command.txt is not a fillgs train" >&2; exit 2; }
hold_instruction_set "$root/$step_dir/step.txt"
scratch="$out/scratch"
rm -rf "$scratch" && mkdir -p "$scratch"

# The step's arguments with another binary, output folder and (with --draws) draws per view.
command_for() {  # binary, output folder
  local i a=("$1")
  for ((i = 1; i < ${#cmd[@]}; ++i)); do
    case "${cmd[i]}" in
      --out) a+=(--out "$2"); ((++i)) ;;
      --quiet) ;;
      --draws-per-view) a+=(--draws-per-view "${draws:-${cmd[i + 1]}}"); ((++i)) ;;
      *) a+=("${cmd[i]}") ;;
    esac
  done
  [ "$one_core" = 1 ] && a=(taskset -c 0 "${a[@]}")
  printf '%s\n' "${a[@]}" --quiet
}
declare -A seconds peak
for build in before after; do
  bin=$before
  [ $build = after ] && bin=$after
  mapfile -t run <<<"$(command_for "$bin" "$scratch/$build")"
  echo "train_step_speed: $build: ${run[*]}" >&2
  t0=$(date +%s.%N)
  (cd "$root" && /usr/bin/time -f '%M' -o "$scratch/$build.rss" "${run[@]}" >/dev/null)
  seconds[$build]=$(awk -v a="$(date +%s.%N)" -v b="$t0" 'BEGIN { printf "%.3f", a - b }')
  peak[$build]=$(tail -1 "$scratch/$build.rss")
done
hash() { sha256sum "$1" | cut -c1-16; }
same_model=no
cmp -s "$scratch/before/model.ply" "$scratch/after/model.ply" && same_model=yes

# The recorded summary and near metrics, when the step ran in full.
summary=n/a near=n/a
if [ -z "$draws" ] && [ -f "$root/$step_dir/summary.json" ]; then
  summary=$(/usr/bin/python3 -c '
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
for d in (a, b):
    d.pop("seconds", None), d.pop("peak_memory_bytes", None)
print("yes" if a == b else "no: " + ", ".join(k for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)))
' "$root/$step_dir/summary.json" "$scratch/after/summary.json")
  if [ -f "$root/$step_dir/eval_near/command.txt" ]; then
    mapfile -t ev <"$root/$step_dir/eval_near/command.txt"
    e=("$after")
    for ((i = 1; i < ${#ev[@]}; ++i)); do
      case "${ev[i]}" in
        --model) e+=(--model "$scratch/after/model.ply"); ((++i)) ;;
        --out) e+=(--out "$scratch/eval_near"); ((++i)) ;;
        *) e+=("${ev[i]}") ;;
      esac
    done
    (cd "$root" && "${e[@]}" >/dev/null)
    near=no
    cmp -s "$root/$step_dir/eval_near/metrics.json" "$scratch/eval_near/metrics.json" && near=yes
  fi
fi
ratio=$(awk -v a="${seconds[after]}" -v b="${seconds[before]}" 'BEGIN { printf "%.3f", a / b }')
{
  echo "## A benchmark step's training, the earlier build against this one"
  echo
  echo "step: \`${step_dir}\` ($(grep -c . "$root/$step_dir/command.txt") arguments; draws per view: ${draws:-as recorded}; $([ "$one_core" = 1 ] && echo "one core each: taskset -c 0" || echo "threads: every core"))"
  echo "machine: $(cpu_line); commit $(git -C "$root_here" rev-parse --short HEAD 2>/dev/null || echo unknown); $(date -u +%Y-%m-%d)"
  echo "earlier build: the \`fillgs\` of a build of commit $(git -C "$(dirname "$before")" rev-parse --short HEAD 2>/dev/null || echo unknown)"
  echo
  echo "| build | seconds | peak MB | model.ply sha256 (first 16) |"
  echo "|---|---|---|---|"
  for build in before after; do
    printf '| %s | %.1f | %d | %s |\n' "$([ $build = before ] && echo earlier || echo this)" "${seconds[$build]}" \
      $((peak[$build] / 1024)) "$(hash "$scratch/$build/model.ply")"
  done
  echo
  echo "this / earlier: **$ratio** of the time; the same model byte for byte: **$same_model**"
  echo "the recorded summary (every value but seconds and peak memory): $summary; the recorded near metrics: $near"
} >"$out/results.md.tmp"
mv "$out/results.md.tmp" "$out/results.md"
cat "$out/results.md"
rm -rf "$scratch"
[ "$same_model" = yes ] && [[ "$summary" != no* ]] && [ "$near" != no ]
