#!/usr/bin/env bash
# Training a whole Neural 3D Video scene within this machine's memory: 21
# cameras x 300 frames at 1352x1014 is 26 GB of 8-bit frames, more than the machine holds
# beside anything else, so `fillgs train` keeps what exceeds --image-memory (default a
# quarter of the machine) in its image cache file and reads images back when drawn.
# `../shared/data` has frame 0 of flame_steak only; `fillgs_bench n3v-rig` writes the
# stand-in (the real rig's 21 cameras and photographs as camNN.mp4 + poses_bounds.npy, a
# painted disc moving over the frames). The training starts from the frame-0 COLMAP
# model's 7,298 points, without flow keys unless FLOW=1 (below). Writes OUT/results.md: images, peak resident memory (summary.json
# and /usr/bin/time), seconds per phase.
#
#   bench/n3v_memory.sh [--smoke] [OUT]      (default OUT: /tmp/fillgs_n3v_memory)
#
# Resumable: the rig and a finished training are reused. --smoke: 4 frames at 84x62, 20
# iterations, every image through the cache file (--image-memory 0); CI runs it.
set -euo pipefail
cd "$(dirname "$0")/.."
smoke=0
if [ "${1:-}" = --smoke ]; then smoke=1; shift; fi
out="${1:-/tmp/fillgs_n3v_memory}"
fillgs="${FILLGS:-build/bin/fillgs}"
bench="${FILLGS_BENCH:-$(dirname "$fillgs")/fillgs_bench}"
export FILLGS_SHARED_DATA="${FILLGS_SHARED_DATA:-$(cd .. && pwd)/shared/data}"
points="$FILLGS_SHARED_DATA/video/n3v_flame_steak_frame0/sparse/0/points3D.bin"
mkdir -p "$out"
# --no-flow-keys: placing motion keys by optical flow runs Farneback flow on every camera's
# frame steps at full resolution, which is most of a short run's time here (bench/results/README.md); memory
# is what this measures. FLOW=1 keeps the flow keys.
flow=(--no-flow-keys)
[ "${FLOW:-0}" = 1 ] && flow=()
if [ $smoke = 1 ]; then rig_args=(--smoke); train_args=(--iterations 20 --image-memory 0 "${flow[@]}"); else rig_args=(); train_args=(--iterations "${ITERATIONS:-300}" "${flow[@]}"); fi

if [ ! -f "$out/rig/poses_bounds.npy" ]; then
  rm -rf "$out/rig"
  start=$(date +%s)
  "$bench" n3v-rig "${rig_args[@]}" --out "$out/rig"
  echo $(( $(date +%s) - start )) > "$out/rig_seconds"
fi
if [ ! -f "$out/model/summary.json" ]; then
  /usr/bin/time -v -o "$out/time.txt" "$fillgs" train --images "$out/rig" --cameras "$out/rig/poses_bounds.npy" \
    --points "$points" "${train_args[@]}" --out "$out/model"
fi

python3 - "$out" <<'PY'
import json, os, re, sys
out = sys.argv[1]
s = json.load(open(os.path.join(out, "model", "summary.json")))
t = open(os.path.join(out, "time.txt")).read()
rss_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", t).group(1))
wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", t).group(1)
rig_s = open(os.path.join(out, "rig_seconds")).read().strip() if os.path.exists(os.path.join(out, "rig_seconds")) else "?"
img = s["images"]
rows = [
    "| what | value |", "|---|---|",
    "| views (cameras x frames) | %s (%s x %s) |" % (s["views"], len(s["cameras"]), s["frames"]),
    "| 8-bit images | %.2f GB, %s |" % (img["bytes"] / 1e9, "in the image cache file" if img["spilled"] else "in memory"),
    "| peak memory (summary.json) | %.0f MB |" % (s["peak_memory_bytes"] / 1048576),
    "| maximum resident set (/usr/bin/time) | %.0f MB |" % (rss_kb / 1024),
    "| iterations; training seconds (summary.json) | %s; %.1f |" % (s["iterations"], s["seconds"]),
    "| train wall time, loading included (/usr/bin/time) | %s |" % wall,
    "| writing the stand-in rig | %s s |" % rig_s,
]
text = "\n".join(rows) + "\n"
tmp = os.path.join(out, ".results.md.tmp")
open(tmp, "w").write(text)
os.replace(tmp, os.path.join(out, "results.md"))
print(text, end="")
PY
