#!/usr/bin/env bash
# The first city-scale figure: `fillgs_bench city` writes guitar.ply replicated to N Gaussians
# (a share S moving on straight lines, one key per frame) as a fillgs 4D PLY with 20 orbit
# cameras at 1352x1014; then `fillgs observe --mode frustum` builds the whole table end to end
# (reading, every frame, writing count / speed / deficiency). Wall time and peak memory (GNU
# time), file sizes. Writes OUT/results.md; the scene and the tables live in a scratch folder
# under OUT, removed at the end.
#
#   bench/city_scale.sh [--gaussians N] [--moving S] [--frames F] [--smoke] OUT
#
# Defaults: N = 10,000,000, S = 0.01, F = 300. --smoke: N = 200,000, F = 4.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="$root/build/bin"
gaussians=10000000
moving=0.01
frames=300
out=
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --gaussians) gaussians="$2"; shift 2 ;;
    --moving) moving="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --smoke) gaussians=200000; frames=4; shift ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
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
echo "observing ..."
/usr/bin/time -f "%e %M" -o "$out/observe.time" "$bin/fillgs" observe --quiet --scene "$work/city.ply" --cameras "$work/cameras.json" --mode frustum \
  --frames "$frames" --no-plots --out "$work/observe" >/dev/null
tables_mb=$(du -m -c "$work/observe"/*.npy | tail -1 | cut -f1)
read -r make_s make_kb <"$out/make.time"
read -r obs_s obs_kb <"$out/observe.time"
n=$(python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); print(j["gaussians"], j["dynamic"], j["views"])' "$work/observe/summary.json")
commit=$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)
machine="$(nproc) cores, $(sed -n 's/^model name\s*: //p' /proc/cpuinfo | head -1), $(awk '/MemTotal/{printf "%.0f GB", $2/1048576}' /proc/meminfo)"
read -r ng nd nv <<<"$n"
{
  echo "Command: \`bench/city_scale.sh --gaussians $gaussians --moving $moving --frames $frames OUT\` · commit $commit · $(date -u +%Y-%m-%d) · $machine."
  echo
  echo "| step | what | seconds | peak memory (MB) | size on disk (MB) |"
  echo "|---|---|---|---|---|"
  echo "| \`fillgs_bench city\` | $ng Gaussians ($nd moving), one key per frame for the moving ones, as a fillgs 4D PLY; 20 cameras | $make_s | $(awk "BEGIN{printf \"%.0f\", $make_kb/1024}") | $ply_mb |"
  echo "| \`fillgs observe --mode frustum\` | the table $ng × 20 cameras × $frames frames ($nv views) end to end: reading, every frame, writing | $obs_s | $(awk "BEGIN{printf \"%.0f\", $obs_kb/1024}") | $tables_mb (the tables) |"
} >"$out/results.md.part"
mv "$out/results.md.part" "$out/results.md"
rm -f "$out/make.time" "$out/observe.time" "$out/make.txt"
echo "wrote $out/results.md"
