#!/usr/bin/env python3
"""The pool benchmark's positive control: a selection that is allowed to know the held-out
cameras. Its K camera-times are the pool photographs nearest to the judged cameras, spread
over the clip (the rule is fixed before any run, bench/results/README.md):

  * the judged cameras are taken in turn, one split after the other (near 1, far 1, near 2,
    far 2, ..., the rest of the longer split), so that a small K reaches every split;
  * choice i (0 .. K-1) goes to judged camera i mod H at frame floor((i + 1/2) F / K) of the
    F frames, so that each judged camera's photographs spread over the clip;
  * its camera is the pool camera whose centre is nearest that judged camera's centre and
    that was not already chosen at that frame.

Writes OUT ({"cameras": pool, "chosen": [{"camera", "frame", "round", "score"}]}, the form
`fillgs train --camera-times` and the report read; the score is minus the centres' distance).

    python3 bench/pool_positive.py --rig all.json --held-out held.json --splits 18,2,20:29,11 \
        --pool 19,23,1 --frames 30 --budget 30 --out pool_chosen.json
transforms.json files (`fillgs cameras` writes them); --splits lists each split's cameras,
splits separated by ':' ("all": every camera of --held-out as one split).
"""
import argparse
import json
import math
import os
import sys


def fail(message):
    sys.stderr.write(f"pool_positive: {message}\n")
    sys.exit(1)


def centres(path):
    """{camera name: its centre} of a transforms.json (a camera's name: the folder of its image
    where it has one, as Panoptic's, else the image's name without extension)."""
    try:
        with open(path) as f:
            frames = json.load(f)["frames"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        fail(f"{path}: not a transforms.json with frames ({e})")
    out = {}
    for i, fr in enumerate(frames):
        try:
            fp, m = fr["file_path"], fr["transform_matrix"]
            c = (float(m[0][3]), float(m[1][3]), float(m[2][3]))
        except (KeyError, TypeError, IndexError, ValueError):
            fail(f"{path}: frame {i} has no file_path or 4x4 transform_matrix")
        if not all(math.isfinite(x) for x in c):
            fail(f"{path}: frame {i} has a centre that is not finite")
        folder = os.path.dirname(fp)
        name = os.path.basename(folder) if folder else os.path.splitext(os.path.basename(fp))[0]
        out.setdefault(name, c)
    return out


def choose(rig, held, splits, pool, frames, budget):
    """The positive control's camera-times, as the module's docstring lays them out."""
    order = []
    for j in range(max(len(s) for s in splits)):
        order += [s[j] for s in splits if j < len(s)]
    taken, chosen = set(), []
    for i in range(budget):
        h = order[i % len(order)]
        f = min(frames - 1, (2 * i + 1) * frames // (2 * budget))
        near = sorted(pool, key=lambda p: (math.dist(held[h], rig[p]), p))
        free = [p for p in near if (p, f) not in taken]
        if not free:  # every pool camera taken at this frame: the next frame that has one
            f = next((g for g in range(frames) if any((p, g) not in taken for p in pool)), None)
            free = [p for p in near if (p, f) not in taken]
        p = free[0]
        taken.add((p, f))
        chosen.append({"camera": p, "frame": f, "round": 0, "score": -math.dist(held[h], rig[p]), "held_out": h})
    return chosen


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rig", required=True, help="transforms.json of the rig's cameras (the pool's among them)")
    ap.add_argument("--held-out", required=True, help="transforms.json of the judged cameras")
    ap.add_argument("--splits", required=True, help="each split's cameras, splits separated by ':' ('all': every held-out camera)")
    ap.add_argument("--pool", required=True, help="the pool cameras, comma-separated")
    ap.add_argument("--frames", type=int, required=True, help="the clip's frames")
    ap.add_argument("--budget", type=int, required=True, help="K, the camera-times to choose")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    rig, held = centres(a.rig), centres(a.held_out)
    pool = [p for p in a.pool.split(",") if p]
    splits = [sorted(held) if s == "all" else [c for c in s.split(",") if c] for s in a.splits.split(":")]
    for name in pool:
        if name not in rig:
            fail(f"{a.rig}: no pool camera {name}")
    for s in splits:
        for name in s:
            if name not in held:
                fail(f"{a.held_out}: no held-out camera {name}")
    if not pool or not any(splits):
        fail("--pool and --splits need a camera each")
    if a.frames < 1 or a.budget < 1 or a.budget > a.frames * len(pool):
        fail(f"--budget {a.budget} camera-times from {len(pool)} pool cameras x {a.frames} frames")
    chosen = choose(rig, held, splits, pool, a.frames, a.budget)
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    tmp = a.out + ".tmp"
    with open(tmp, "w") as f:
        json.dump({"cameras": pool, "chosen": chosen, "rule": "positive control: the pool camera nearest each judged camera, spread over the clip"}, f, indent=1)
    os.replace(tmp, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
