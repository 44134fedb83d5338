#!/usr/bin/env bash
# The Python module against the command line on one observation table: `fillgs_bench city`
# writes N Gaussians (a share S moving, one key per frame) as a fillgs 4D PLY with 20 orbit
# cameras at 1352x1014; then, one after the other on the same scene, each alone:
#   cli       `fillgs observe --mode frustum` (reading, every frame, the .npy files written);
#   python    fillgs.observe(fillgs.load_model(...), ...) from Python: the same tables returned
#             as arrays (written straight into them, no second copy); timed from the
#             interpreter's start to the tables in hand, peak memory then;
#   frames    fillgs.observe(frame_function, ...): the caller hands every frame's arrays (here
#             Model.at(t) of the same model), every Gaussian evaluated per frame and the still
#             rule measured on each as it goes (the file's static ones are found still, and so
#             are its moving ones that move less than the rule's tolerance: speeds differ there,
#             counts are compared);
# wall time and peak resident memory (the command line's by GNU time), the tables compared.
# Writes OUT/results.md; the scene lives in OUT/scratch, removed at the end.
#
#   bench/python_observe.sh [--gaussians N] [--moving S] [--frames F] [--smoke] OUT
#
# Defaults: N = 1,000,000, S = 0.1, F = 300. --smoke: N = 20,000, F = 6.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$root/build"
gaussians=1000000
moving=0.1
frames=300
out=
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build="$2"; shift 2 ;;
    --gaussians) gaussians="$2"; shift 2 ;;
    --moving) moving="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --smoke) gaussians=20000; frames=6; shift ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    -*) echo "bench/python_observe.sh: unknown option $1" >&2; exit 2 ;;
    *) out="$1"; shift ;;
  esac
done
[ -n "$out" ] || { echo "bench/python_observe.sh: give the output folder" >&2; exit 2; }
python=/usr/bin/python3
export FILLGS_SHARED_DATA="${FILLGS_SHARED_DATA:-$root/../shared/data}"
export PYTHONPATH="$build/python${PYTHONPATH:+:$PYTHONPATH}"
mkdir -p "$out"
work="$out/scratch"
rm -rf "$work"
trap 'rm -rf "$work"' EXIT
echo "writing the scene ($gaussians Gaussians, $moving moving, $frames frames) ..."
"$build/bin/fillgs_bench" city --gaussians "$gaussians" --moving "$moving" --frames "$frames" --out "$work" >/dev/null
echo "cli ..."
/usr/bin/time -f "%e %M" -o "$out/cli.time" "$build/bin/fillgs" observe --quiet --scene "$work/city.ply" --cameras "$work/cameras.json" \
  --mode frustum --frames "$frames" --tables dense --no-plots --out "$work/observe" >/dev/null
# One Python run per path: its seconds from the interpreter's start to the tables in hand and
# its peak resident memory then (the digests after, of the arrays' own buffers, uncounted),
# then the tables' digests and shapes for the comparison.
run_python() {  # name code
  echo "$1 ..."
  /usr/bin/time -f "%e %M" -o "$out/$1.gnutime" "$python" - "$work" "$frames" "$out/$1.time" >"$out/$1.txt" <<PY
import time
start = time.perf_counter()
import hashlib, resource, sys, numpy as np, fillgs
work, F = sys.argv[1], int(sys.argv[2])
model = fillgs.load_model(work + "/city.ply")
cams = fillgs.read_cameras(work + "/cameras.json")
$2
seconds = time.perf_counter() - start
with open(sys.argv[3], "w") as f:
    print("%.2f %d" % (seconds, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss), file=f)
for k in ("counts", "speed", "deficiency"):
    print(k, t[k].dtype, t[k].shape, hashlib.sha256(t[k].data).hexdigest())
PY
}
run_python python 't = fillgs.observe(model, cams, frames=F)'
run_python frames 't = fillgs.observe(lambda f: model.at(f / (F - 1)), cams, frames=F)'
# The CLI's tables, digested the same way.
"$python" - "$work/observe" >"$out/cli.txt" <<'PY'
import hashlib, sys, numpy as np
for k, f in (("counts", "count"), ("speed", "speed"), ("deficiency", "deficiency")):
    a = np.load(sys.argv[1] + "/" + f + ".npy")
    print(k, a.dtype, a.shape, hashlib.sha256(a.tobytes()).hexdigest())
PY
same() { if cmp -s "$out/$1.txt" "$out/$2.txt"; then echo "identical"; else echo "different"; fi; }
commit=$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)
machine="$(nproc) cores, $(sed -n 's/^model name\s*: //p' /proc/cpuinfo | head -1), $(awk '/MemTotal/{printf "%.0f GB", $2/1048576}' /proc/meminfo)"
read -r cli_s cli_kb <"$out/cli.time"
row() {  # name label tables
  read -r s kb <"$out/$1.time"
  echo "| $2 | $s | $(awk "BEGIN{printf \"%.0f\", $kb/1024}") | $(awk "BEGIN{printf \"%.3f\", $s/$cli_s}") | $3 |"
}
{
  echo "Command: \`bench/python_observe.sh --gaussians $gaussians --moving $moving --frames $frames OUT\` · commit $commit · $(date -u +%Y-%m-%d) · $machine."
  echo
  echo "The table of $gaussians Gaussians ($moving moving) × 20 cameras × $frames frames, \`--mode frustum\`, end to end (reading included):"
  echo
  echo "| path | seconds | peak memory (MB) | time / command line | tables |"
  echo "|---|---|---|---|---|"
  row cli "\`fillgs observe\` (writes the .npy files)" "-"
  row python "\`fillgs.observe(model, cams)\` from Python (arrays returned)" "$(same python cli) to the command line's"
  row frames "\`fillgs.observe(frame_function, cams)\`: every frame's arrays handed over by Python, the still rule on each" "counts $(cmp -s <(head -1 "$out/frames.txt") <(head -1 "$out/cli.txt") && echo identical || echo different)"
} >"$out/results.md.part"
mv "$out/results.md.part" "$out/results.md"
rm -f "$out"/*.time "$out"/*.gnutime "$out"/cli.txt "$out"/python.txt "$out"/frames.txt
echo "wrote $out/results.md"
