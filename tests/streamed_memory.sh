#!/usr/bin/env bash
# A streamed observe's memory does not grow with the frame count; the keyed read's does (the
# control: the test could fail). The E-D3DGS fixture (300 Gaussians) observed over 40 and
# 4,000 frames (--model-frames), frustum mode, four cameras; peak memory from each run's
# summary.json. Keys over 4,000 frames hold 300 x 4,000 x 14 floats = 67 MB more than over 40.
#
#   tests/streamed_memory.sh FILLGS FIXTURES SCRATCH
set -euo pipefail
fillgs="$1" fixtures="$2" scratch="$3"
python="${FILLGS_TORCH_PYTHON:-/usr/bin/python3}"
rm -rf "$scratch" && mkdir -p "$scratch"
"$python" "$(dirname "$0")/../bench/ring_cameras.py" 4 "$scratch/cameras.json"
peak() {  # frames evaluation
  local out="$scratch/$1-$2"
  "$fillgs" observe --quiet --scene "$fixtures/ed3dgs" --model-frames "$1" --model-evaluation "$2" --cameras "$scratch/cameras.json" \
    --mode frustum --no-plots --out "$out" >/dev/null
  "$python" -c 'import json,sys; print(json.load(open(sys.argv[1]))["peak_memory_mb"])' "$out/summary.json"
}
s40=$(peak 40 streamed); s4000=$(peak 4000 streamed)
k40=$(peak 40 keys); k4000=$(peak 4000 keys)
echo "peak memory (MB): streamed 40 frames $s40, 4000 frames $s4000; keys 40 frames $k40, 4000 frames $k4000"
"$python" - "$s40" "$s4000" "$k40" "$k4000" <<'PY'
import sys
s40, s4000, k40, k4000 = map(float, sys.argv[1:])
assert k4000 - k40 >= 50, "the control: keys over 4,000 frames should hold >= 50 MB more (got %.1f)" % (k4000 - k40)
assert s4000 - s40 <= 10, "streamed: 4,000 frames hold %.1f MB more than 40" % (s4000 - s40)
PY
