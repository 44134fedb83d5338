#!/usr/bin/env python3
"""Select -> an external refiner -> weights, driven from Python: the virtual views FillGS
chooses for a model, rendered, refined by an outside program, and weighted by how far the
real observations support each pixel, saved as arrays a trainer of your own reads.

    examples/select_refine_weights.py --model MODEL --images DIR --cameras FILE
        [--train-cameras a,b] [--trajectories K] [--strategy fillgs] [--weighting fillgs]
        [--refiner-command 'oiiotool --wildcardoff --evaloff {in} --median 3x3 -o {out}'] OUT

The refiner command runs once per rendered view, {in} and {out} PNG paths (the default, a
3x3 median by OpenImageIO's oiiotool, stands in for a generative model). OUT/weighted_views.npz
holds, per refined view: images [V,H,W,3] float32, weights [V,H,W] float32 (the loss weight:
multiply your photometric loss by it), K [V,3,3], world_to_camera [V,4,4] (OpenCV axes),
time [V] in [0, 1]; OUT/renders and OUT/refined keep the PNGs.

Needs the module (PYTHONPATH=build/python, or installed with `cmake --install build
--component python`)."""
import argparse
import os
import re
import shlex
import subprocess
import sys

import numpy as np

import fillgs


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--model", required=True, help="any model fillgs reads")
    ap.add_argument("--images", required=True, help="the training images folder")
    ap.add_argument("--cameras", required=True, help="the training cameras")
    ap.add_argument("--train-cameras", default="", help="rig cameras trained on (default: all)")
    ap.add_argument("--trajectories", type=int, default=2)
    ap.add_argument("--strategy", default="fillgs")
    ap.add_argument("--weighting", default="fillgs")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--refiner-command", default="oiiotool --wildcardoff --evaloff {in} --median 3x3 -o {out}")
    a = ap.parse_args()
    words = shlex.split(a.refiner_command)
    if not words or any(w in (";", "|", "||", "&", "&&", ">", ">>", "<") for w in words):
        sys.exit(f"--refiner-command {a.refiner_command!r}: a program and its arguments, run without a shell (no ; | & > <)")

    model = fillgs.load_model(a.model)
    views = fillgs.load_views(a.images, a.cameras, train_cameras=[c for c in a.train_cameras.split(",") if c])
    print(f"{model.size} Gaussians ({len(model.dynamic_ids)} moving); {len(views['images'])} observed views over {views['frames']} frames")

    # 1. Select: trajectories of virtual poses, each rendered over its patch frames.
    sel = fillgs.select(model, views["cameras"], frames=views["frames"], strategy=a.strategy, trajectories=a.trajectories,
                        seed=a.seed, images=views["images"])
    arrays = [t.views().arrays() for t in sel["trajectories"]]
    if not arrays:
        sys.exit("select chose no trajectory: " + "; ".join(sel["notes"]))
    cams = {k: np.concatenate([x[k] for x in arrays]) for k in ("K", "world_to_camera", "width", "height", "time")}
    virtual = fillgs.Cameras(cams["K"], cams["world_to_camera"], cams["width"], cams["height"], time=cams["time"])
    print(f"{len(sel['trajectories'])} trajectories ({a.strategy}), {len(virtual)} virtual views")

    # 2. Render each virtual view and refine it with the external command.
    for d in ("renders", "refined"):
        os.makedirs(os.path.join(a.out, d), exist_ok=True)
    refined = []
    for i in range(len(virtual)):
        rendered = fillgs.render(model, virtual, index=i, t=float(cams["time"][i]))["colour"]
        src = os.path.join(a.out, "renders", f"view{i:04d}.png")
        dst = os.path.join(a.out, "refined", f"view{i:04d}.png")
        fillgs.write_image(src, rendered)
        # Without a shell, as `fillgs finetune --refiner` runs one: the template is split into
        # words first, then each word's {in} and {out} are the paths, whatever they contain.
        # One pass, so that a path holding "{out}" is not substituted again.
        cmd = [re.sub(r"\{in\}|\{out\}", lambda m: src if m.group() == "{in}" else dst, w) for w in words]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0 or not os.path.exists(dst):
            sys.exit(f"refiner failed on {src}: {r.stderr.strip() or 'no output written'}")
        refined.append(fillgs.read_image(dst)[:, :, :3])

    # 3. The weights: trust only pixels that agree with the real observations.
    w = fillgs.weights(model, views["cameras"], views["images"], refined, virtual, weighting=a.weighting, frames=views["frames"])
    weights = np.stack([x["weight"] for x in w])
    out = os.path.join(a.out, "weighted_views.npz")
    tmp = out + ".tmp.npz"
    np.savez(tmp, images=np.stack(refined).astype(np.float32), weights=weights.astype(np.float32), K=cams["K"],
             world_to_camera=cams["world_to_camera"], time=cams["time"])
    os.replace(tmp, out)
    print(f"weights ({a.weighting}): mean {weights.mean():.3f}, {100 * (weights > 0).mean():.1f}% of pixels above 0 -> {out}")


if __name__ == "__main__":
    main()
