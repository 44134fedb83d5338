#!/usr/bin/env python3
"""Observation counts and the motion-aware deficiency of a model your own PyTorch code
evaluates, frame by frame, handed to fillgs without saving anything.

The model here is a 4DGaussians-architecture deformation network (HexPlane grid + MLP heads,
the layout of its scene/deformation.py) built by tests/make_model_fixtures.py and saved as
4DGaussians' training saves it; the script loads its state dict back into the PyTorch module,
evaluates it at every frame on the CPU, and gives fillgs each frame's Gaussians. It then runs
`fillgs observe` on the saved folder and prints how far the two tables are apart: the
counts agree exactly; speed and deficiency as far as fillgs's evaluation of the network is
from PyTorch's (float32 sums in another order) allows.

    examples/observe_torch_model.py [--gaussians N] [--frames F] [--cameras C] [--fillgs PATH] OUT

Needs Debian's python3-torch and the module (PYTHONPATH=build/python, or installed with
`cmake --install build --component python`)."""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np
import torch

import fillgs

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "tests"))
sys.path.insert(0, os.path.join(here, "..", "bench"))
import make_model_fixtures as fixtures  # noqa: E402  (the 4DGaussians module and its saver)


def read_gaussians(path):
    """A 3DGS-layout binary PLY (float properties only) as 3DGS's load_ply reads it."""
    with open(path, "rb") as f:
        names = []
        while True:
            line = f.readline().decode("ascii").strip()
            if line.startswith("element vertex"):
                n = int(line.split()[2])
            elif line.startswith("property float"):
                names.append(line.split()[2])
            elif line == "end_header":
                break
        data = np.frombuffer(f.read(n * 4 * len(names)), dtype="<f4").reshape(n, len(names))
    col = {name: data[:, i] for i, name in enumerate(names)}
    stack = lambda prefix, k: np.stack([col[f"{prefix}{i}"] for i in range(k)], axis=1).astype(np.float32)
    rest = stack("f_rest_", 45).reshape(n, 3, 15).transpose(0, 2, 1)  # stored channel-major
    shs = np.concatenate([stack("f_dc_", 3)[:, None, :], rest], axis=1)
    return dict(xyz=np.stack([col["x"], col["y"], col["z"]], 1).astype(np.float32), scale=stack("scale_", 3),
                rot=stack("rot_", 4), opacity=col["opacity"][:, None].astype(np.float32), shs=np.ascontiguousarray(shs))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--gaussians", type=int, default=2000)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--cameras", type=int, default=12)
    ap.add_argument("--fillgs", default=os.path.join(here, "..", "build", "bin", "fillgs"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)

    # 1. A model as 4DGaussians saves it (your training run's folder).
    run = os.path.join(a.out, "4dgaussians")
    if not os.path.isdir(run):
        fixtures.make_4dgaussians(a.out, "4dgaussians", seed=7, n=a.gaussians, frames=a.frames, expect=False)
    it = os.path.join(run, "point_cloud", "iteration_14000")

    # 2. Your code: the network and the canonical Gaussians back in PyTorch.
    args = eval(open(os.path.join(run, "cfg_args")).read(), {"Namespace": argparse.Namespace})
    net = fixtures.FourDDeform(args)
    net.load_state_dict(torch.load(os.path.join(it, "deformation.pth")))
    net.eval()
    g = read_gaussians(os.path.join(it, "point_cloud.ply"))  # the canonical Gaussians, as its load_ply reads them
    xyz = torch.from_numpy(g["xyz"])
    scales = torch.from_numpy(g["scale"])
    rots = torch.from_numpy(g["rot"])
    opac = torch.from_numpy(g["opacity"])
    shs = torch.from_numpy(g["shs"])
    n = xyz.shape[0]

    def frame(f):
        """Frame f's Gaussians, as your renderer would get them (4DGaussians: time f / F)."""
        with torch.no_grad():
            p, s, r, o, sh = net(xyz, scales, rots, opac, shs, torch.full((n, 1), f / a.frames))
        return dict(means=p.numpy(), log_scales=s.numpy(), quaternions=r.numpy(), opacity_logits=o[:, 0].numpy(), sh=sh.numpy())

    # 3. Cameras: a ring around the scene (any rig fillgs reads, or fillgs.Cameras(K, w2c, w, h)).
    cams_path = os.path.join(a.out, "cameras.json")
    subprocess.run([sys.executable, os.path.join(here, "..", "bench", "ring_cameras.py"), str(a.cameras), cams_path, "--wave"], check=True)
    cams = fillgs.read_cameras(cams_path)

    tables = fillgs.observe(frame, cams, frames=a.frames, still_tolerance=0.0)  # every Gaussian moving, as step 4
    D = tables["deficiency"]
    print(f"{n} Gaussians x {a.frames} frames x {len(cams)} cameras: deficiency sum {D.sum():.6g}, "
          f"most deficient Gaussian {int(D.sum(0).argmax())}, least observed frame {int(tables['counts'].sum(1).argmin())}")

    # 4. The same model from disk through the command line: every Gaussian moving (no still
    # rule), as the frame function hands every Gaussian over.
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([a.fillgs, "observe", "--quiet", "--no-plots", "--scene", run, "--model-frames", str(a.frames), "--still-tolerance", "0",
                        "--cameras", cams_path, "--out", tmp], check=True)
        written = fillgs.load_observation(tmp, dense=True)  # the compact files as [T, N] tables
        counts, deficiency = written["counts"], written["deficiency"]
    same_counts = counts.shape == tables["counts"].shape and bool((counts == tables["counts"]).all())
    # How far fillgs's own evaluation of the saved network is from PyTorch's, in positions; a
    # speed is a difference of two positions over two frames, so deficiency can differ by up
    # to that gap times (F - 1).
    saved = fillgs.load_model(run, frames=a.frames, still_tolerance=0.0)
    position_gap = max(float(np.abs(saved.at(f / (a.frames - 1))["means"] - frame(f)["means"]).max()) for f in range(a.frames))
    gap = float(np.abs(deficiency - D).max())
    bound = max(position_gap, 1e-7) * (a.frames - 1)
    print(f"against `fillgs observe` on the saved model: counts {'identical' if same_counts else 'DIFFERENT'}; positions within "
          f"{position_gap:.3g} of PyTorch's, deficiency within {gap:.3g} (bound {bound:.3g}; largest value {float(np.abs(deficiency).max()):.3g})")
    sys.exit(0 if same_counts and gap <= bound else 1)


if __name__ == "__main__":
    main()
