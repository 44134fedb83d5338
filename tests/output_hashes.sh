#!/usr/bin/env bash
# Runs every fillgs command on the synthetic scene and prints one line per output file:
# its SHA-256 and its path. Two builds whose lists agree write the same bytes:
# a refactor must leave every output as it was.
#
#   tests/output_hashes.sh BIN WORKDIR > hashes.txt
#   diff <(tests/output_hashes.sh old/fillgs /tmp/a) <(tests/output_hashes.sh build/bin/fillgs /tmp/b)
#
# What is measured rather than computed is left out of the hash, nothing else: in JSON files
# the keys that hold wall time, rates and memory (seconds, ms_per_view, peak_memory_bytes,
# iterations_per_second, ...) are dropped before hashing; the run report's tables end with
# seconds and are hashed without that column, the reports without their "Seconds per phase"
# section; paths are written relative to WORKDIR.
set -euo pipefail
bin=$(realpath "$1")
work=$(realpath -m "$2")
rm -rf "$work"
mkdir -p "$work"
cd "$work"
q=(--quiet --threads 2)
run() { "$bin" "$@" > "$work/log_$1.txt" 2>&1 || { echo "output_hashes: fillgs $* failed:" >&2; cat "$work/log_$1.txt" >&2; exit 1; }; }

run synth --out scene --frames 6 --width 64 --height 48 "${q[@]}"
run info scene/scene.ply --json
"$bin" info scene/scene.ply --json > info.json
run render --scene scene/scene.ply --cameras scene/transforms_train.json --out render_rgb "${q[@]}"
run render --scene scene/scene.ply --cameras scene/transforms_interpolation.json --out render_depth --channel depth --time 0.4 "${q[@]}"
run convert --scene scene/scene.ply --out convert_3dgs.ply --to 3dgs --time 0.5
run convert --scene scene/scene.ply --out convert_frames --to frames --frames 3
run cameras --cameras scene/transforms_train.json --out cameras_colmap --to colmap
run observe --scene scene/scene.ply --cameras scene/transforms_train.json --out observe_frustum "${q[@]}"
run observe --scene scene/scene.ply --cameras scene/transforms_train.json --out observe_ray --mode raytraced --stride 2 "${q[@]}"
run explore --scene scene/scene.ply --cameras scene/transforms_train.json --out explore --frames 6 "${q[@]}"
run select --scene scene/scene.ply --cameras scene/transforms_train.json --out select --trajectories 2 --views 3 "${q[@]}"
# Every strategy and every weighting (their classes), small.
for strategy in fillgs random negative interpolation fisherrf coverage3d coverage4d; do
  run select --scene scene/scene.ply --cameras scene/transforms_train.json --out "select_$strategy" --strategy "$strategy" \
    --trajectories 2 --views 2 --no-renders "${q[@]}"
done
run train --images scene --cameras scene/transforms_train.json --out train --iterations 60 "${q[@]}"
run finetune --model train/model.ply --images scene --cameras scene/transforms_train.json --out finetune --iterations 20 --select-every 10 \
  --trajectories 1 --refiner oracle --truth scene/scene.ply "${q[@]}"
for weighting in fillgs none no-consistency no-covisibility 3dgs-enhancer exploregs ua-4dgs; do
  run finetune --model train/model.ply --images scene --cameras scene/transforms_train.json --out "finetune_$weighting" --iterations 4 \
    --select-every 4 --trajectories 1 --refiner oracle --truth scene/scene.ply --artifact-strength 0.5 --weighting "$weighting" "${q[@]}"
done
run eval --model finetune/model.ply --images scene --cameras scene/transforms_interpolation.json,scene/transforms_extrapolation.json \
  --truth scene/scene.ply --out eval "${q[@]}"
run run --smoke --out run_smoke "${q[@]}"

# Hash every output, what is measured removed.
python3 - "$work" <<'EOF2'
import csv, hashlib, io, json, os, re, sys
work = sys.argv[1]
def timed(key):
    return "seconds" in key or key.startswith("s_") or key.startswith("peak_memory") or key in ("ms_per_view", "iterations_per_second")
def strip(x):
    if isinstance(x, dict): return {k: strip(v) for k, v in x.items() if not timed(k)}
    if isinstance(x, list): return [strip(v) for v in x]
    if isinstance(x, str): return x.replace(work, "WORK")
    return x
def without_timing_section(text):
    # The report's "Seconds per phase" section: everything up to the next heading.
    return re.sub(r"(Seconds per phase.*?)(?=<h2|\n## |\Z)", "", text, flags=re.S)
for root, dirs, files in os.walk(work):
    dirs.sort()
    for name in sorted(files):
        path = os.path.join(root, name)
        rel = os.path.relpath(path, work)
        if name.startswith("log_") or "time_per_phase" in name: continue
        data = open(path, "rb").read()
        if name.endswith(".json"):
            data = json.dumps(strip(json.loads(data)), sort_keys=True).encode()
        elif name.endswith(".csv"):
            rows = list(csv.reader(io.StringIO(data.decode())))
            keep = [i for i, h in enumerate(rows[0]) if not timed(h)] if rows else []
            data = "\n".join(",".join(r[i] for i in keep if i < len(r)) for r in rows).encode()
        elif name.endswith((".md", ".html")):
            text = without_timing_section(data.decode().replace(work, "WORK"))
            text = re.sub(r"\| [0-9.]+ \|$", "| T |", text, flags=re.M)  # the run report's seconds column
            text = re.sub(r"<td>[0-9.]+</td></tr>", "<td>T</td></tr>", text)
            text = re.sub(r"<figure><img alt=\"time_per_phase.*?</figure>", "", text, flags=re.S)
            data = re.sub(r"\d+(\.\d+)? s\b", "T s", text).encode()
        elif name.endswith(".vdb") and len(data) > 57:
            data = data[:21] + data[57:]  # the file's random UUID (36 characters after the header)
        print(hashlib.sha256(data).hexdigest(), rel)
EOF2
