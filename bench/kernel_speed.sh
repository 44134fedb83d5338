#!/usr/bin/env bash
# The tile kernels of an earlier build against this one's, in one run: a training iteration
# (forward, L1 + D-SSIM loss, backward) with 90,854 Gaussians at 676x507 and a 1352x1014
# render on 2 threads, each build's `fillgs_bench` run in turn for several rounds so that a
# drift of the machine falls on both. Per round: iterations/s and ms per frame of each build
# and their ratio; the median ratio under the table.
#
#   bench/kernel_speed.sh --before BENCH [--bin BENCH] [--rounds N] OUT
#   bench/kernel_speed.sh [--bin BENCH] --smoke OUT
#
# BENCH: a build's fillgs_bench (default for --bin: this checkout's build/bin/fillgs_bench).
# Writes OUT/results.md. --smoke: the benchmarks' small sizes, one round, this build against
# itself (CI).
set -euo pipefail
root_here="$(cd "$(dirname "$0")/.." && pwd)"
after="$root_here/build/bin/fillgs_bench"
before= rounds=3 smoke=0 out=
while [ $# -gt 0 ]; do
  case "$1" in
    --before) before="$(cd "$(dirname "$2")" && pwd)/$(basename "$2")"; shift 2 ;;
    --bin) after="$(cd "$(dirname "$2")" && pwd)/$(basename "$2")"; shift 2 ;;
    --rounds) rounds="$2"; shift 2 ;;
    --smoke) smoke=1; shift ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    -*) echo "bench/kernel_speed.sh: unknown option $1" >&2; exit 2 ;;
    *) [ -z "$out" ] || { echo "bench/kernel_speed.sh: one output folder only" >&2; exit 2; }; out="$1"; shift ;;
  esac
done
[ -n "$out" ] || { echo "bench/kernel_speed.sh: give the output folder" >&2; exit 2; }
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "bench/kernel_speed.sh: --rounds expects a positive count, got '$rounds'" >&2; exit 2; }
if [ "$smoke" = 1 ]; then
  before="$after" rounds=1
  train_args=(--smoke) render_args=(--smoke) train_row='^\| [0-9]+ \| [0-9]+x[0-9]+ \|' render_row='\| simd \| 2 \|'
  render_desc="its last vector row on 2 threads"
else
  [ -n "$before" ] || { echo "bench/kernel_speed.sh: give --before BENCH, the earlier build's fillgs_bench" >&2; exit 2; }
  train_args=(--gaussians 90854 --resolution 676x507) render_args=() train_row='^\| 90854 \| 676x507 \|'
  render_row='^\| 1352x1014 \| simd \| 2 \|' render_desc="its 1352x1014 vector row on 2 threads"
fi
for b in "$before" "$after"; do [ -x "$b" ] || { echo "bench/kernel_speed.sh: $b is not an executable" >&2; exit 2; }; done
. "$root_here/bench/lib.sh"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
# The last matching row's column (1-based between the bars) of a benchmark's table.
column() { grep -E "$1" | tail -1 | awk -F'|' -v c="$2" '{ gsub(/ /, "", $(c + 1)); print $(c + 1) }'; }
rows=()
for ((r = 1; r <= rounds; ++r)); do
  declare -A its=() ms=()
  for build in before after; do
    bin=$before
    [ $build = after ] && bin=$after
    echo "kernel_speed: round $r, $build" >&2
    its[$build]=$("$bin" train --only speed "${train_args[@]}" 2>/dev/null | column "$train_row" 7)
    ms[$build]=$("$bin" render "${render_args[@]}" 2>/dev/null | column "$render_row" 4)
    [ -n "${its[$build]}" ] && [ -n "${ms[$build]}" ] || { echo "bench/kernel_speed.sh: $bin printed no row to read" >&2; exit 1; }
  done
  rows+=("$r ${its[before]} ${its[after]} ${ms[before]} ${ms[after]}")
done
median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
it_ratio=$(printf '%s\n' "${rows[@]}" | awk '{ printf "%.4f\n", $3 / $2 }' | median)
ms_ratio=$(printf '%s\n' "${rows[@]}" | awk '{ printf "%.4f\n", $5 / $4 }' | median)
{
  echo "## The tile kernels: an earlier build against this one, in one run"
  echo
  echo "machine: $(cpu_line); commit $(git -C "$root_here" rev-parse --short HEAD 2>/dev/null || echo unknown); $(date -u +%Y-%m-%d)"
  echo "earlier build: the \`fillgs_bench\` of a build of commit $(git -C "$(dirname "$before")" rev-parse --short HEAD 2>/dev/null || echo unknown)"
  echo "$("$(dirname "$after")/fillgs" --version 2>/dev/null | sed -n 2p || true)"
  echo
  if [ "$smoke" = 1 ]; then
    echo "(smoke: the benchmarks' small sizes, this build against itself)"
    echo
  fi
  echo "| round | iterations/s earlier | iterations/s this | ratio | render ms earlier | render ms this | ratio |"
  echo "|---|---|---|---|---|---|---|"
  for row in "${rows[@]}"; do
    echo "$row" | awk '{ printf "| %d | %s | %s | %.2f | %s | %s | %.2f |\n", $1, $2, $3, $3 / $2, $4, $5, $5 / $4 }'
  done
  echo
  echo "median over the rounds: iterations/s **$(printf '%.2f' "$it_ratio")×** the earlier build's; render **$(printf '%.2f' "$ms_ratio")** of its time"
  echo "(the training iteration: \`fillgs_bench train --only speed ${train_args[*]}\`, its last vector row; the render: \`fillgs_bench render ${render_args[*]}\`, $render_desc)"
} >"$out/results.md.tmp"
mv "$out/results.md.tmp" "$out/results.md"
cat "$out/results.md"
