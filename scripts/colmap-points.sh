#!/usr/bin/env bash
# Initial points for a calibrated rig, made by COLMAP as its users do (data/README.md, "Real captured video"):
# SIFT features, exhaustive matching, and triangulation with the rig's known poses
# (`colmap point_triangulator`, no pose is re-estimated). The result, OUT/sparse/points3D.bin
# (+ .txt), is what `fillgs train --points` reads.
#
#   scripts/colmap-points.sh --images DIR --cameras C --out OUT [--train-cameras a,b,...]
#                            [--max-image-size N] [--fillgs BIN]
#
# DIR holds one image per camera named as the cameras name them (the N3V frame-0 layout:
# images/cam00.png …); C is any camera file fillgs reads. --train-cameras keeps only those
# cameras, so a sparse split's points come from its training cameras alone. Needs `colmap`
# (Debian colmap, CPU SIFT) and python3's sqlite3 (the ids of COLMAP's database must be the
# model's: the known poses are rewritten with the database's image and camera ids, and the
# database's intrinsics with the known ones before matching). OUT must not exist.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
images= cameras= out= train= max_size=3200 fillgs="$root/build/bin/fillgs"
while [ $# -gt 0 ]; do
  case "$1" in
    --images) images="$2"; shift 2 ;;
    --cameras) cameras="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --train-cameras) train="$2"; shift 2 ;;
    --max-image-size) max_size="$2"; shift 2 ;;
    --fillgs) fillgs="$2"; shift 2 ;;
    -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
    *) echo "colmap-points: unknown option $1" >&2; exit 1 ;;
  esac
done
[ -n "$images" ] && [ -n "$cameras" ] && [ -n "$out" ] || { echo "colmap-points: --images, --cameras and --out are required" >&2; exit 1; }
command -v colmap >/dev/null || { echo "colmap-points: no 'colmap' program (apt-get install colmap, or scripts/install-deps.sh)" >&2; exit 1; }
[ -e "$out" ] && { echo "colmap-points: $out exists; choose a new folder" >&2; exit 1; }
# Built in a staging folder, moved into place when every step succeeded.
stage="$(dirname "$out")/.$(basename "$out").partial-$$"
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/images" "$stage/known" "$stage/sparse"
log="$stage/colmap.log"

"$fillgs" cameras --cameras "$cameras" --to colmap --out "$stage/all" >/dev/null
# The images COLMAP sees: every camera's, or the training cameras' only.
/usr/bin/python3 - "$stage/all/images.txt" "$images" "$stage/images" "$train" <<'PY'
import os, sys
images_txt, src, dst, train = sys.argv[1:5]
keep = set(train.split(",")) if train else None
names = [l.split()[9] for l in open(images_txt) if l.strip() and not l.startswith("#") and len(l.split()) == 10]
chosen = [n for n in names if keep is None or os.path.splitext(n)[0] in keep or n in keep]
if keep is not None and len(chosen) != len(keep):
    sys.exit("colmap-points: --train-cameras names %s, the cameras have %s" % (sorted(keep), names))
for n in chosen:
    if not os.path.exists(os.path.join(src, n)): sys.exit("colmap-points: %s: no image %s" % (src, n))
    os.symlink(os.path.abspath(os.path.join(src, n)), os.path.join(dst, n))
PY

t0=$(date +%s)
echo "colmap-points: features ($(ls "$stage/images" | wc -l) images, max side $max_size)"
colmap feature_extractor --database_path "$stage/database.db" --image_path "$stage/images" \
  --ImageReader.camera_model PINHOLE --SiftExtraction.use_gpu 0 --SiftExtraction.max_image_size "$max_size" >>"$log" 2>&1 \
  || { echo "colmap-points: feature_extractor failed (log $log)" >&2; trap - EXIT; exit 1; }

# The known model with the database's ids, and the database's intrinsics set to the known ones.
/usr/bin/python3 - "$stage/database.db" "$stage/all" "$stage/known" <<'PY'
import sqlite3, struct, sys
db_path, src, dst = sys.argv[1:4]
cams = {}
for l in open(src + "/cameras.txt"):
    f = l.split()
    if f and not l.startswith("#"): cams[f[0]] = f[1:]
poses = {}
for l in open(src + "/images.txt"):
    f = l.split()
    if len(f) == 10 and not l.startswith("#"): poses[f[9]] = f
db = sqlite3.connect(db_path)
rows = db.execute("SELECT image_id, name, camera_id FROM images").fetchall()
with open(dst + "/cameras.txt", "w") as c, open(dst + "/images.txt", "w") as i:
    for image_id, name, camera_id in rows:
        p = poses[name]
        model, w, h, *params = cams[p[8]]
        if model != "PINHOLE": sys.exit("colmap-points: camera %s is %s, expected PINHOLE" % (name, model))
        c.write("%d PINHOLE %s %s %s\n" % (camera_id, w, h, " ".join(params)))
        i.write("%d %s %d %s\n\n" % (image_id, " ".join(p[1:8]), camera_id, name))
        # PINHOLE is model 1; params fx fy cx cy as doubles; prior_focal_length so COLMAP trusts them.
        db.execute("UPDATE cameras SET model=1, width=?, height=?, params=?, prior_focal_length=1 WHERE camera_id=?",
                   (int(w), int(h), struct.pack("<4d", *map(float, params)), camera_id))
db.commit()
open(dst + "/points3D.txt", "w").close()
PY

echo "colmap-points: matching"
colmap exhaustive_matcher --database_path "$stage/database.db" --SiftMatching.use_gpu 0 >>"$log" 2>&1 \
  || { echo "colmap-points: exhaustive_matcher failed (log $log)" >&2; trap - EXIT; exit 1; }
echo "colmap-points: triangulating with the known poses"
# COLMAP ignores tracks seen by two images only (noisier); with two cameras there are no others.
ignore_two_view=1
[ "$(ls "$stage/images" | wc -l)" -le 2 ] && ignore_two_view=0
colmap point_triangulator --Mapper.tri_ignore_two_view_tracks $ignore_two_view \
  --database_path "$stage/database.db" --image_path "$stage/images" --input_path "$stage/known" \
  --output_path "$stage/sparse" >>"$log" 2>&1 \
  || { echo "colmap-points: point_triangulator failed (log $log)" >&2; trap - EXIT; exit 1; }
colmap model_converter --input_path "$stage/sparse" --output_path "$stage/sparse" --output_type TXT >>"$log" 2>&1
points=$(grep -vc '^#' "$stage/sparse/points3D.txt" || true)
rm -rf "$stage/all" "$stage/images"
trap - EXIT
mv "$stage" "$out"
echo "colmap-points: $points points in $out/sparse ($(( $(date +%s) - t0 )) s); fillgs train --points $out/sparse/points3D.bin"
