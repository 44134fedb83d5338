#!/usr/bin/env bash
# The city-scale figure: `fillgs_bench city` writes guitar.ply replicated to N Gaussians
# (a share S moving on straight lines, one key per frame) as a fillgs 4D PLY with 20 orbit
# cameras at 1352x1014; then `fillgs observe --mode frustum` builds the whole table end to end
# (reading, every frame, writing), once in the compact layout (the default) and once with
# `--tables dense` (every table [T, N], the layout observe wrote before the compact one: the
# reference of the same run), and numpy checks, frame by frame, that the compact tables are
# the dense ones cell for cell. Wall time and peak memory (GNU time), file sizes, the ratios.
# Writes OUT/results.md; the scene and the tables live in a scratch folder under OUT, removed
# at the end.
#
#   bench/city_scale.sh [--gaussians N] [--moving S] [--frames F] [--before BIN] [--smoke] OUT
#
# Defaults: N = 10,000,000, S = 0.01, F = 300. --smoke: N = 200,000, F = 4. --before BIN: also
# the observe of an earlier build (its folder of binaries; its own default tables) on the
# same scene in the same run, the reference of a change.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="$root/build/bin"
gaussians=10000000
moving=0.01
before=
frames=300
out=
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --gaussians) gaussians="$2"; shift 2 ;;
    --moving) moving="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --before) before="$2"; shift 2 ;;
    --smoke) gaussians=200000; frames=4; shift ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    -*) echo "bench/city_scale.sh: unknown option $1" >&2; exit 2 ;;
    *) out="$1"; shift ;;
  esac
done
[ -n "$out" ] || { echo "bench/city_scale.sh: give the output folder" >&2; exit 2; }
export FILLGS_SHARED_DATA="${FILLGS_SHARED_DATA:-$root/../shared/data}"
mkdir -p "$out"
work="$out/scratch"
rm -rf "$work"
trap 'rm -rf "$work"' EXIT
echo "writing the scene ($gaussians Gaussians, $moving moving, $frames frames) ..."
/usr/bin/time -f "%e %M" -o "$out/make.time" "$bin/fillgs_bench" city --gaussians "$gaussians" --moving "$moving" --frames "$frames" --out "$work" \
  | tee "$out/make.txt"
ply_mb=$(du -m "$work/city.ply" | cut -f1)
for layout in compact dense; do
  echo "observing ($layout tables) ..."
  /usr/bin/time -f "%e %M" -o "$out/observe_$layout.time" "$bin/fillgs" observe --quiet --scene "$work/city.ply" --cameras "$work/cameras.json" \
    --mode frustum --frames "$frames" --tables "$layout" --no-plots --out "$work/$layout" >/dev/null
done
echo "comparing the layouts cell for cell ..."
check=$(/usr/bin/python3 - "$work/compact" "$work/dense" <<'PY'
import sys, numpy as np
c, d = sys.argv[1], sys.argv[2]
L = lambda f: np.load(c + "/" + f + ".npy", mmap_mode="r")
ids, rows, static, dyn = L("dynamic_ids"), L("count_rows"), L("count_static"), L("count_dynamic")
off, cid, cval = L("count_change_offsets"), L("count_change_ids"), L("count_change_values")
count, speed, deficiency = (np.load(d + "/" + f + ".npy", mmap_mode="r") for f in ("count", "speed", "deficiency"))
sd, dd = L("speed_dynamic"), L("deficiency_dynamic")
bad = 0
for t in range(count.shape[0]):
    row = np.array(static[rows[t]])
    row[ids] = dyn[t]
    row[cid[off[t]:off[t + 1]]] = cval[off[t]:off[t + 1]]
    bad += int((row != count[t]).sum())
    for dense, mine in ((speed, sd), (deficiency, dd)):
        m = np.zeros(dense.shape[1], np.float32)
        m[ids] = mine[t]
        bad += int((m.view(np.uint32) != np.asarray(dense[t]).view(np.uint32)).sum())
print(f"{bad} cells differ over {count.shape[0]} frames" if bad else f"identical, every cell of {count.shape[0]} frames")
PY
)
echo "$check"
dense_b=$(du -b -c "$work/dense"/*.npy | tail -1 | cut -f1)
rm -rf "$work/dense"  # room for the earlier build's tables
if [ -n "$before" ]; then
  echo "observing (the earlier build in $before) ..."
  /usr/bin/time -f "%e %M" -o "$out/observe_before.time" "$before/fillgs" observe --quiet --scene "$work/city.ply" --cameras "$work/cameras.json" \
    --mode frustum --frames "$frames" --no-plots --out "$work/before" >/dev/null
fi
read -r make_s make_kb <"$out/make.time"
n=$(python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); print(j["gaussians"], j["dynamic"], j["views"])' "$work/compact/summary.json")
commit=$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)
machine="$(nproc) cores, $(sed -n 's/^model name\s*: //p' /proc/cpuinfo | head -1), $(awk '/MemTotal/{printf "%.0f GB", $2/1048576}' /proc/meminfo)"
read -r ng nd nv <<<"$n"
read -r compact_s compact_kb <"$out/observe_compact.time"
read -r dense_s dense_kb <"$out/observe_dense.time"
compact_b=$(du -b -c "$work/compact"/*.npy | tail -1 | cut -f1)
compact_mb=$(awk "BEGIN{printf \"%.1f\", $compact_b/1048576}")
dense_mb=$(awk "BEGIN{printf \"%.1f\", $dense_b/1048576}")
{
  echo "Command: \`bench/city_scale.sh --gaussians $gaussians --moving $moving --frames $frames$([ -n "$before" ] && echo " --before BIN") OUT\` · commit $commit · $(date -u +%Y-%m-%d) · $machine."
  echo
  echo "| step | what | seconds | peak memory (MB) | size on disk (MB) |"
  echo "|---|---|---|---|---|"
  echo "| \`fillgs_bench city\` | $ng Gaussians ($nd moving), one key per frame for the moving ones, as a fillgs 4D PLY; 20 cameras | $make_s | $(awk "BEGIN{printf \"%.0f\", $make_kb/1024}") | $ply_mb |"
  echo "| \`fillgs observe --mode frustum\` | the table $ng × 20 cameras × $frames frames ($nv views) end to end, compact tables (the default) | $compact_s | $(awk "BEGIN{printf \"%.0f\", $compact_kb/1024}") | $compact_mb (the tables) |"
  echo "| \`fillgs observe --mode frustum --tables dense\` | the same, every table [T, N] (the reference) | $dense_s | $(awk "BEGIN{printf \"%.0f\", $dense_kb/1024}") | $dense_mb (the tables) |"
  if [ -n "$before" ]; then
    read -r before_s before_kb <"$out/observe_before.time"
    before_b=$(du -b -c "$work/before"/*.npy | tail -1 | cut -f1)
    before_commit=$(git -C "$before" rev-parse --short HEAD 2>/dev/null || echo unknown)
    echo "| \`fillgs observe --mode frustum\`, the earlier build ($before_commit) | the same with that build's code and its default tables | $before_s | $(awk "BEGIN{printf \"%.0f\", $before_kb/1024}") | $(awk "BEGIN{printf \"%.1f\", $before_b/1048576}") (the tables) |"
  fi
  echo
  [ -n "$before" ] && echo "This build (compact) against the earlier build in this run: $(awk "BEGIN{printf \"%.3f\", $compact_s/$before_s}") of the time, $(awk "BEGIN{printf \"%.3f\", $compact_kb/$before_kb}") of the peak memory; peak memory against the scene file: $(awk "BEGIN{printf \"%.2f\", $compact_kb/1024/$ply_mb}") (this build), $(awk "BEGIN{printf \"%.2f\", $before_kb/1024/$ply_mb}") (the earlier)." && echo
  echo "Compact against dense in this run: $(awk "BEGIN{printf \"%.3f\", $compact_s/$dense_s}") of the time, $(awk "BEGIN{printf \"%.4f\", $compact_b/$dense_b}") of the bytes of the tables; the compact tables against the dense ones: $check."
} >"$out/results.md.part"
mv "$out/results.md.part" "$out/results.md"
rm -f "$out/make.time" "$out/observe_compact.time" "$out/observe_dense.time" "$out/observe_before.time" "$out/make.txt"
echo "wrote $out/results.md"
case "$check" in identical*) ;; *) echo "bench/city_scale.sh: the compact tables are not the dense ones: $check" >&2; exit 1 ;; esac
