#!/usr/bin/python3
"""Saves small trained-looking 4D models exactly as their training code saves them, and
what PyTorch evaluates from them at several times, for fillgs's readers to match.

Formats: E-D3DGS (two settings), 4DGaussians, 4D Gaussian Splatting (Yang et al.; with and
without 4D rotations), Deformable 3D Gaussians (with and without its D-NeRF time network),
Dynamic 3D Gaussians (params.npz) and a folder of per-frame 3DGS PLYs. Each network is rebuilt here as a torch.nn.Module with the module and parameter
names of its repository, so that state_dict() gives the keys the real deformation.pth holds;
the evaluation follows each repository's renderer (the time given, raw parameters plus
deltas, then exp / normalize / sigmoid). Also writes broken files for the refusal tests.

Usage: make_model_fixtures.py OUT_DIR     (needs Debian's python3-torch and python3-numpy)

For each model OUT_DIR/<name>/expect.npz holds:
  times      [T]         model times evaluated
  means      [T, N, 3]   positions
  scales     [T, N, 3]   exp(log-scale)              (4DGS: absent, see cov)
  rotations  [T, N, 4]   unit quaternions (w,x,y,z)  (4DGS: absent, see cov)
  cov        [T, N, 9]   4DGS: the 3D covariance at that time
  opacities  [T, N]      sigmoid(logit), times 4DGS's temporal marginal
  sh         [T, N, K*3] SH coefficients, [coefficient][channel]
"""
import argparse
import itertools
import math
import os
import shutil
import sys
from argparse import Namespace

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

torch.set_default_dtype(torch.float32)


# ----------------------------------------------------------------------------- shared

def write_ply(path, columns):
    """Binary little-endian PLY, one float property per (name, array) in order."""
    names = [n for n, _ in columns]
    n = len(columns[0][1])
    data = np.stack([np.asarray(v, dtype=np.float32) for _, v in columns], axis=1)
    header = "ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % n
    header += "".join("property float %s\n" % p for p in names) + "end_header\n"
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(data.astype("<f4").tobytes())


def gaussian_columns(xyz, f_dc, f_rest, opacity, scale, rot):
    """3DGS's construct_list_of_attributes order; f_rest channel-major as 3DGS flattens it."""
    n = xyz.shape[0]
    cols = [("x", xyz[:, 0]), ("y", xyz[:, 1]), ("z", xyz[:, 2])]
    cols += [("nx", np.zeros(n)), ("ny", np.zeros(n)), ("nz", np.zeros(n))]
    dc = f_dc.transpose(0, 2, 1).reshape(n, -1)
    cols += [("f_dc_%d" % i, dc[:, i]) for i in range(dc.shape[1])]
    rest = f_rest.transpose(0, 2, 1).reshape(n, -1)
    cols += [("f_rest_%d" % i, rest[:, i]) for i in range(rest.shape[1])]
    cols += [("opacity", opacity[:, 0])]
    cols += [("scale_%d" % i, scale[:, i]) for i in range(3)]
    cols += [("rot_%d" % i, rot[:, i]) for i in range(4)]
    return cols


def random_gaussians(gen, n, sh_coeffs=16):
    xyz = (torch.rand(n, 3, generator=gen) * 2 - 1) * 1.2
    f_dc = torch.randn(n, 1, 3, generator=gen) * 0.5
    f_rest = torch.randn(n, sh_coeffs - 1, 3, generator=gen) * 0.1
    opacity = torch.randn(n, 1, generator=gen)
    scale = torch.log(torch.rand(n, 3, generator=gen) * 0.05 + 0.01)
    rot = torch.randn(n, 4, generator=gen)
    return xyz, f_dc, f_rest, opacity, scale, rot


def save_expect(path, times, means, opac, sh, scales=None, rots=None, cov=None, **extra):
    out = dict(times=np.asarray(times, np.float64), means=np.stack(means), opacities=np.stack(opac), sh=np.stack(sh), **extra)
    if scales is not None:
        out["scales"] = np.stack(scales)
        out["rotations"] = np.stack(rots)
    if cov is not None:
        out["cov"] = np.stack(cov)
    np.savez(path, **out)


def sequential_linear(sizes, relu_first):
    layers = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        if relu_first or i > 0:
            layers.append(nn.ReLU())
        layers.append(nn.Linear(a, b))
    return nn.Sequential(*layers)


def liven(module, gen, scale=0.3):
    """Trained-looking weights: random, biases included, so every head moves its value."""
    with torch.no_grad():
        for p in module.parameters():
            p.copy_(torch.randn(p.shape, generator=gen) * scale / math.sqrt(max(1, p.shape[-1])))


# ----------------------------------------------------------------------------- E-D3DGS

class EDeform(nn.Module):
    """E-D3DGS's deform_network: module names as in its scene/deformation.py."""

    def __init__(self, args, width, depth):
        super().__init__()
        self.args = args
        inp = args.temporal_embedding_dim + args.gaussian_embedding_dim
        for pass_ in ("c", "f"):
            setattr(self, "feature_out_" + pass_, sequential_linear([inp] + [width] * depth, relu_first=False))
            for head, out in (("pos", 3), ("scales", 3), ("rotations", 4), ("opacity", 1), ("rgb", 48)):
                setattr(self, "%s_deform_%s" % (head, pass_), sequential_linear([width, width, out], relu_first=True))
        self.weight = nn.Parameter(torch.zeros(args.max_embeddings, args.temporal_embedding_dim))
        self.offsets = nn.Parameter(torch.zeros(30, 1))

    def temporal(self, t, rows):
        emb = F.interpolate(self.weight[None, None], size=(rows, self.args.temporal_embedding_dim), mode="bilinear", align_corners=True)
        d = self.args.temporal_embedding_dim
        grid = torch.cat([torch.arange(d).unsqueeze(-1) / (d - 1), torch.ones(d, 1) * t], dim=-1)[None, None]
        grid = (grid - 0.5) * 2
        return F.grid_sample(emb, grid, align_corners=True, mode="bilinear", padding_mode="reflection")[0, 0, 0]

    def forward(self, g, t, iteration):
        a = self.args
        nz = torch.masked_select(self.offsets, self.offsets.ne(0))
        offset = nz.mean() if nz.numel() else torch.tensor(0.0)
        t = t + offset
        lin = lambda f, to: int(f + (to - f) * min(max(iteration, 0), a.c2f_temporal_iter) / a.c2f_temporal_iter)
        rows_c = a.min_embeddings if a.use_coarse_temporal_embedding else lin(a.min_embeddings, a.max_embeddings)
        rows_f = lin(a.min_embeddings, a.max_embeddings)
        coef = float(np.clip(iteration / 1000, 0, 1)) if a.use_anneal else 1.0
        late = float(np.clip((iteration - a.deform_from_iter) / 1000, 0, 1)) if a.use_anneal else 1.0
        pts, scales, rots, opac, sh = g["xyz"], g["scale"], g["rot"], g["opacity"], g["sh"]
        for pass_, rows in (("c", rows_c), ("f", rows_f)):
            emb = self.temporal(t, rows)
            h = torch.cat([emb.expand(pts.shape[0], -1), g["embedding"]], dim=-1)
            h = getattr(self, "feature_out_" + pass_)(h)
            head = lambda n: getattr(self, "%s_deform_%s" % (n, pass_))(h)
            pts = pts + head("pos") * coef
            if not a.no_ds:
                scales = scales + head("scales") * coef * late
            if not a.no_dr:
                rots = rots + head("rotations") * coef
            if not a.no_do:
                opac = opac + head("opacity") * coef * late
            if not a.no_dc:
                sh = sh + head("rgb").view(-1, 16, 3) * late
        return pts, scales, rots, opac, sh


def still_background(net, args, emb, still, gen):
    """A share `still` of the Gaussians made still, as a trained model's background is: half of
    each pass's first-layer units keep the temporal embedding (the others see it only through
    1e-2 of their weights, the network noise a trained model leaves), and a still Gaussian's
    embedding switches those units off (ReLU), so only the noise moves it."""
    n = emb.shape[0]
    m = int(round(still * n))
    d = args.temporal_embedding_dim
    with torch.no_grad():
        for pass_ in ("c", "f"):
            w = getattr(net, "feature_out_" + pass_)[0].weight
            half = w.shape[0] // 2
            w[half:, :d] *= 1e-2
            w[:half, d] = 1.0
        emb[:m, 0] = -5.0
        emb[m:, 0] = 1.0
    return m


def still_mask(frames_values, tol=1e-3, degrees=1.0, log_scale=0.01, opacity=1 / 255, colour=1 / 255):
    """fillgs's still rule, in numpy: every frame within the tolerances of frame 0."""
    p0, s0, r0, o0, c0 = frames_values[0]
    still = np.ones(p0.shape[0], dtype=bool)
    for p, s, r, o, c in frames_values[1:]:
        still &= np.linalg.norm(p - p0, axis=1) <= tol
        still &= np.abs(np.log(s) - np.log(s0)).max(axis=1) <= log_scale
        still &= np.abs(o - o0) <= opacity
        still &= np.abs((r * r0).sum(axis=1)) >= math.cos(math.radians(degrees) / 2)
        # Colour in any direction: every SH band's change times its basis function's largest
        # value on the sphere (brute force over directions, not fillgs's table).
        d = np.abs(c - c0).reshape(c.shape[0], -1, 3)
        still &= (d * SH_BASIS_MAX[: d.shape[1], None]).sum(axis=1).max(axis=1) <= colour
    return still


def sh_basis_max():
    """max |Y_k| over 200,000 directions of each of the 16 real SH basis functions, as 3DGS's
    eval_sh evaluates them (a finer net than this only moves the fourth digit)."""
    d = np.random.default_rng(0).normal(size=(200000, 3))
    x, y, z = (d / np.linalg.norm(d, axis=1, keepdims=True)).T
    xx, yy, zz = x * x, y * y, z * z
    C1, C2 = 0.4886025119029199, [1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396]
    C3 = [-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154, -0.4570457994644658, 1.445305721320277,
          -0.5900435899266435]
    Y = [np.full_like(x, 0.28209479177387814), -C1 * y, C1 * z, -C1 * x, C2[0] * x * y, C2[1] * y * z, C2[2] * (2 * zz - xx - yy),
         C2[3] * x * z, C2[4] * (xx - yy), C3[0] * y * (3 * xx - yy), C3[1] * x * y * z, C3[2] * y * (4 * zz - xx - yy),
         C3[3] * z * (2 * zz - 3 * xx - 3 * yy), C3[4] * x * (4 * zz - xx - yy), C3[5] * z * (xx - yy), C3[6] * x * (xx - 3 * yy)]
    return np.array([np.abs(v).max() for v in Y])


SH_BASIS_MAX = sh_basis_max()


def make_ed3dgs(out, name, seed, iteration, hidden, n=300, frames=12, gdim=8, expect=True, still=0.0):
    gen = torch.Generator().manual_seed(seed)
    args = Namespace(net_width=hidden["width"], defor_depth=hidden["depth"], min_embeddings=hidden["min"], max_embeddings=hidden["max"],
                     no_ds=False, no_dr=False, no_do=hidden["no_do"], no_dc=False, temporal_embedding_dim=hidden["tdim"],
                     gaussian_embedding_dim=gdim, use_coarse_temporal_embedding=hidden["coarse_emb"], no_c2f_temporal_embedding=False,
                     no_coarse_deform=False, no_fine_deform=False, total_num_frames=frames, c2f_temporal_iter=hidden["c2f"],
                     deform_from_iter=hidden["deform_from"], use_anneal=True, zero_temporal=False, sh_degree=3, loader="dynerf",
                     source_path="data/n3v/cook_spinach", model_path="output/" + name, iterations=iteration, lambda_dssim=1.0,
                     kplanes_config={"grid_dimensions": 2, "resolution": [64, 64, 64, 25]}, multires=[1, 2], save_iterations=[iteration])
    net = EDeform(args, hidden["width"], hidden["depth"])
    liven(net, gen)
    with torch.no_grad():
        net.weight.copy_(torch.randn(net.weight.shape, generator=gen) * 0.5)
        net.offsets[:4, 0] = torch.tensor([0.0, 0.01, -0.02, 0.015])
    xyz, f_dc, f_rest, opacity, scale, rot = random_gaussians(gen, n)
    emb = torch.randn(n, gdim, generator=gen) * 0.5
    if still:
        still_background(net, args, emb, still, gen)
    run = os.path.join(out, name)
    it_dir = os.path.join(run, "point_cloud", "iteration_%d" % iteration)
    os.makedirs(it_dir)
    # An older iteration the reader must not take.
    os.makedirs(os.path.join(run, "point_cloud", "iteration_%d" % (iteration // 2)))
    with open(os.path.join(run, "cfg_args"), "w") as f:
        f.write(str(Namespace(**vars(args))))
    cols = gaussian_columns(xyz.numpy(), f_dc.numpy(), f_rest.numpy(), opacity.numpy(), scale.numpy(), rot.numpy())
    cols += [("embedding_%d" % i, emb[:, i].numpy()) for i in range(emb.shape[1])]
    write_ply(os.path.join(it_dir, "point_cloud.ply"), cols)
    torch.save(net.state_dict(), os.path.join(it_dir, "deformation.pth"))
    if not expect:
        return run
    g = dict(xyz=xyz, scale=scale, rot=rot, opacity=opacity, sh=torch.cat([f_dc, f_rest], 1), embedding=emb)
    # Frame times f / F (its dynerf loader) and times between frames.
    times = [0.0, 1 / frames, 5 / frames, (frames - 1) / frames, 0.237, 0.61]
    M, S, R, O, SH = [], [], [], [], []
    with torch.no_grad():
        for t in times:
            p, s, r, o, sh = net(g, t, iteration)
            M.append(p.numpy()); S.append(torch.exp(s).numpy()); R.append(F.normalize(r).numpy())
            O.append(torch.sigmoid(o)[:, 0].numpy()); SH.append(sh.reshape(n, -1).numpy())
    extra = {}
    if still:
        # The rule at every frame f / F, by PyTorch's values: which Gaussians are still, and how
        # far the still ones' network noise moves them.
        per_frame = []
        with torch.no_grad():
            for f in range(frames):
                p, s, r, o, sh = net(g, f / frames, iteration)
                per_frame.append((p.numpy(), torch.exp(s).numpy(), F.normalize(r).numpy(), torch.sigmoid(o)[:, 0].numpy(), sh.reshape(n, -1).numpy()))
        mask = still_mask(per_frame)
        drift = max(np.linalg.norm(v[0] - per_frame[0][0], axis=1)[mask].max() for v in per_frame[1:])
        extra = dict(still=mask.astype(np.float64), still_drift=np.array([drift]))
    save_expect(os.path.join(run, "expect.npz"), times, M, O, SH, S, R, **extra)
    return run


# ----------------------------------------------------------------------------- 4DGaussians

class HexPlaneField(nn.Module):
    def __init__(self, bounds, config, multires):
        super().__init__()
        self.aabb = nn.Parameter(torch.tensor([[bounds] * 3, [-bounds] * 3]), requires_grad=False)
        self.grids = nn.ModuleList()
        for res in multires:
            reso = [r * res for r in config["resolution"][:3]] + config["resolution"][3:]
            planes = nn.ParameterList()
            for comb in itertools.combinations(range(4), 2):
                planes.append(nn.Parameter(torch.empty([1, config["output_coordinate_dim"]] + [reso[c] for c in comb[::-1]])))
            self.grids.append(planes)

    def forward(self, pts, t):
        pts = (pts - self.aabb[0]) * (2.0 / (self.aabb[1] - self.aabb[0])) - 1.0
        pts = torch.cat([pts, t], -1)
        feats = []
        for planes in self.grids:
            f = 1.0
            for ci, comb in enumerate(itertools.combinations(range(4), 2)):
                coords = pts[..., comb].view(1, 1, -1, 2)
                s = F.grid_sample(planes[ci], coords, align_corners=True, mode="bilinear", padding_mode="border")
                f = f * s.view(planes[ci].shape[1], -1).transpose(0, 1)
            feats.append(f)
        return torch.cat(feats, -1)


class Deformation(nn.Module):
    def __init__(self, args):
        super().__init__()
        self.args = args
        self.grid = HexPlaneField(args.bounds, args.kplanes_config, args.multires)
        feat = args.kplanes_config["output_coordinate_dim"] * len(args.multires)
        W = args.net_width
        self.feature_out = sequential_linear([feat] + [W] * max(1, args.defor_depth), relu_first=False)
        self.pos_deform = sequential_linear([W, W, 3], True)
        self.scales_deform = sequential_linear([W, W, 3], True)
        self.rotations_deform = sequential_linear([W, W, 4], True)
        self.opacity_deform = sequential_linear([W, W, 1], True)
        self.shs_deform = sequential_linear([W, W, 48], True)


class FourDDeform(nn.Module):
    """4DGaussians' deform_network (scene/deformation.py): names, buffers and timenet kept."""

    def __init__(self, args):
        super().__init__()
        self.timenet = nn.Sequential(nn.Linear(2 * args.timebase_pe + 1, args.timenet_width), nn.ReLU(), nn.Linear(args.timenet_width, args.timenet_output))
        self.deformation_net = Deformation(args)
        self.register_buffer("time_poc", torch.FloatTensor([2 ** i for i in range(args.timebase_pe)]))
        self.register_buffer("pos_poc", torch.FloatTensor([2 ** i for i in range(args.posebase_pe)]))
        self.register_buffer("rotation_scaling_poc", torch.FloatTensor([2 ** i for i in range(args.scale_rotation_pe)]))
        self.register_buffer("opacity_poc", torch.FloatTensor([2 ** i for i in range(args.opacity_pe)]))

    def forward(self, pts, scales, rots, opac, shs, t):
        d, a = self.deformation_net, self.deformation_net.args
        h = d.feature_out(d.grid(pts, t))
        out_pts = pts if a.no_dx else pts + d.pos_deform(h)
        out_s = scales if a.no_ds else scales + d.scales_deform(h)
        out_r = rots if a.no_dr else rots + d.rotations_deform(h)
        out_o = opac if a.no_do else opac + d.opacity_deform(h)
        out_sh = shs if a.no_dshs else shs + d.shs_deform(h).reshape(shs.shape[0], 16, 3)
        return out_pts, out_s, out_r, out_o, out_sh


def make_4dgaussians(out, name, seed, n=300, frames=10, iteration=14000, width=32, channels=8, reso=(8, 6), depth=1, expect=True):
    gen = torch.Generator().manual_seed(seed)
    args = Namespace(net_width=width, timebase_pe=4, defor_depth=depth, posebase_pe=10, scale_rotation_pe=2, opacity_pe=2, timenet_width=64,
                     timenet_output=32, bounds=1.6, plane_tv_weight=0.0002, time_smoothness_weight=0.001, l1_time_planes=0.0001,
                     kplanes_config={"grid_dimensions": 2, "input_coordinate_dim": 4, "output_coordinate_dim": channels, "resolution": [reso[0]] * 3 + [reso[1]]},
                     multires=[1, 2], no_dx=False, no_grid=False, no_ds=False, no_dr=False, no_do=False, no_dshs=False, empty_voxel=False,
                     grid_pe=0, static_mlp=False, apply_rotation=False, sh_degree=3, model_path="output/" + name, source_path="data/x")
    net = FourDDeform(args)
    liven(net, gen)
    with torch.no_grad():
        for planes in net.deformation_net.grid.grids:
            for ci, comb in enumerate(itertools.combinations(range(4), 2)):
                p = planes[ci]
                if 3 in comb:
                    p.copy_(1.0 + 0.3 * torch.randn(p.shape, generator=gen))
                else:
                    p.copy_(0.1 + 0.4 * torch.rand(p.shape, generator=gen))
    xyz, f_dc, f_rest, opacity, scale, rot = random_gaussians(gen, n)
    with torch.no_grad():  # set_aabb(xyz_max, xyz_min) as 4DGaussians' training does
        net.deformation_net.grid.aabb.copy_(torch.stack([xyz.max(0).values, xyz.min(0).values]))
    run = os.path.join(out, name)
    it_dir = os.path.join(run, "point_cloud", "iteration_%d" % iteration)
    os.makedirs(it_dir)
    with open(os.path.join(run, "cfg_args"), "w") as f:
        f.write(str(Namespace(**vars(args))))
    write_ply(os.path.join(it_dir, "point_cloud.ply"), gaussian_columns(xyz.numpy(), f_dc.numpy(), f_rest.numpy(), opacity.numpy(), scale.numpy(), rot.numpy()))
    torch.save(net.state_dict(), os.path.join(it_dir, "deformation.pth"))
    torch.save(torch.ones(n, dtype=torch.bool), os.path.join(it_dir, "deformation_table.pth"))
    torch.save(torch.zeros(n, 3), os.path.join(it_dir, "deformation_accum.pth"))
    if not expect:
        return run
    times = [0.0, 1 / frames, 4 / frames, (frames - 1) / frames, 0.333, 0.05]
    M, S, R, O, SH = [], [], [], [], []
    with torch.no_grad():
        for t in times:
            p, s, r, o, sh = net(xyz, scale, rot, opacity, torch.cat([f_dc, f_rest], 1), torch.full((n, 1), t))
            M.append(p.numpy()); S.append(torch.exp(s).numpy()); R.append(F.normalize(r).numpy())
            O.append(torch.sigmoid(o)[:, 0].numpy()); SH.append(sh.reshape(n, -1).numpy())
    save_expect(os.path.join(run, "expect.npz"), times, M, O, SH, S, R)
    return run


# ----------------------------------------------------------------------------- 4DGS (Yang et al.)

def rotation_4d(l, r):
    """4DGS's build_rotation_4d: left and right isoclinic rotations, rows and columns flipped."""
    a, b, c, d = F.normalize(l).unbind(-1)
    p, q, r_, s = F.normalize(r).unbind(-1)
    Ml = torch.stack([a, -b, -c, -d, b, a, -d, c, c, d, a, -b, d, -c, b, a]).view(4, 4, -1).permute(2, 0, 1)
    Mr = torch.stack([p, q, r_, s, -q, p, -s, r_, -r_, s, p, -q, -s, -r_, q, p]).view(4, 4, -1).permute(2, 0, 1)
    return (Ml @ Mr).flip(1, 2)


def quat_matrix(q):
    w, x, y, z = F.normalize(q).unbind(-1)
    return torch.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1).view(-1, 3, 3)


def make_4dgs(out, name, seed, rot_4d, n=300, frames=10, duration=(0.0, 2.0), iteration=7000, expect=True, edit=None):
    gen = torch.Generator().manual_seed(seed)
    xyz, f_dc, f_rest, opacity, scale, rot = random_gaussians(gen, n, sh_coeffs=48)
    t = torch.rand(n, 1, generator=gen) * (duration[1] - duration[0]) + duration[0]
    scaling_t = torch.log(torch.rand(n, 1, generator=gen) * 0.5 + 0.2)
    rot_r = torch.randn(n, 4, generator=gen)
    if edit:  # set chosen Gaussians' values, in place
        edit(dict(xyz=xyz, f_dc=f_dc, f_rest=f_rest, opacity=opacity, scale=scale, rot=rot, t=t, scaling_t=scaling_t, rot_r=rot_r))
    params = [nn.Parameter(x.clone()) for x in (xyz, f_dc, f_rest, scale, rot, opacity, t, scaling_t, rot_r)]
    opt = torch.optim.Adam([{"params": [p], "lr": 1e-3, "name": nm} for p, nm in
                            zip(params, ["xyz", "f_dc", "f_rest", "scaling", "rotation", "opacity", "t", "scaling_t", "rotation_r"])], lr=0.0, eps=1e-15)
    sum(p.sum() for p in params).backward()
    opt.step()  # an optimiser state with exp_avg tensors, as a real checkpoint holds
    with torch.no_grad():
        for p, x in zip(params, (xyz, f_dc, f_rest, scale, rot, opacity, t, scaling_t, rot_r)):
            p.copy_(x)
    P = dict(zip(["xyz", "f_dc", "f_rest", "scaling", "rotation", "opacity", "t", "scaling_t", "rotation_r"], params))
    capture = (3, P["xyz"], P["f_dc"], P["f_rest"], P["scaling"], P["rotation"], P["opacity"], torch.zeros(n), torch.zeros(n, 1),
               torch.zeros(n, 1), torch.zeros(n, 1), opt.state_dict(), 5.0, P["t"], P["scaling_t"], P["rotation_r"], rot_4d,
               torch.empty(0), 2)
    run = os.path.join(out, name)
    os.makedirs(run)
    torch.save((capture, iteration), os.path.join(run, "chkpnt%d.pth" % iteration))
    if not expect:
        return run
    span = duration[1] - duration[0]
    times = [duration[0] + f * span / frames for f in (0, 1, 4, frames - 1)] + [duration[0] + 0.37 * span, duration[0] + 0.81 * span]
    M, O, SH, C = [], [], [], []
    with torch.no_grad():
        for tau in times:
            if rot_4d:
                L = rotation_4d(rot, rot_r) @ torch.diag_embed(torch.exp(torch.cat([scale, scaling_t], 1)))
                S = L @ L.transpose(1, 2)
                c12 = S[:, 0:3, 3:4]
                ct = S[:, 3:4, 3:4]
                cov = S[:, :3, :3] - c12 @ c12.transpose(1, 2) / ct
                mean = xyz + c12.squeeze(-1) / ct.squeeze(-1) * (tau - t)
                sigma = S[:, 3, 3].unsqueeze(1)
            else:
                R = quat_matrix(rot)
                cov = R @ torch.diag_embed(torch.exp(scale) ** 2) @ R.transpose(1, 2)
                mean = xyz
                sigma = torch.exp(scaling_t)
            marginal = torch.exp(-0.5 * (t - tau) ** 2 / sigma)
            shs = torch.cat([f_dc, f_rest], 1)  # [N, 48, 3]
            dt = (t - tau)  # eval_shfs_4d's dirs_t = t_mean - timestamp
            eff = shs[:, :16] + torch.cos(2 * math.pi * dt / span)[..., None] * shs[:, 16:32] + \
                torch.cos(2 * math.pi * 2 * dt / span)[..., None] * shs[:, 32:48]
            M.append(mean.numpy()); C.append(cov.reshape(n, 9).numpy())
            O.append((torch.sigmoid(opacity) * marginal)[:, 0].numpy()); SH.append(eff.reshape(n, -1).numpy())
    save_expect(os.path.join(run, "expect.npz"), times, M, O, SH, cov=C)
    return run


# ----------------------------------------------------------------------------- Deformable 3D Gaussians

def short_lived_4dgs(v):
    """4DGS Gaussians each still but for one property (axis-aligned time: positions never move):
    0, 4, 5 live about a frame (sigma_t half a frame of 30 fps) at frames 75, 107 and 139 of 300,
    between the still rule's sweep frames (72, 82, ..., 103, 113, 134, 144); 1 and 3 are lit
    throughout and still; 2 changes colour only in a band above the DC (the time term of SH
    coefficient 5). Opacity logit 1.96: 0.877 where lit."""
    v["f_rest"].zero_()
    v["opacity"].fill_(1.96)
    v["t"][:, 0] = torch.tensor([75.0, 0.0, 0.0, 0.0, 107.0, 139.0]) / 30.0
    v["scaling_t"][:, 0] = math.log((0.5 / 30.0) ** 2)  # its code's variance: exp(_scaling_t)
    v["scaling_t"][1:4, 0] = math.log(1e6)
    v["f_rest"][2, 15 + 5, 0] = 0.5  # channel 16 + 5: coefficient 5's first time band (f_rest holds channels 1..47)


def embed(x, freqs):
    """Its Embedder: the input, then sin and cos of each octave."""
    out = [x]
    for f in 2.0 ** torch.linspace(0.0, freqs - 1, freqs):
        out += [torch.sin(x * f), torch.cos(x * f)]
    return torch.cat(out, -1)


class DeformNetwork(nn.Module):
    """Deformable-3D-Gaussians' utils/time_utils.py DeformNetwork (not 6-DoF)."""

    def __init__(self, D, W, is_blender):
        super().__init__()
        self.t_multires = 6 if is_blender else 10
        self.skips = [D // 2]
        xyz_in, t_in = 3 * 21, 1 + 2 * self.t_multires
        self.is_blender = is_blender
        if is_blender:
            self.timenet = nn.Sequential(nn.Linear(t_in, 256), nn.ReLU(inplace=True), nn.Linear(256, 30))
            t_in = 30
        self.linear = nn.ModuleList([nn.Linear(xyz_in + t_in, W)] +
                                    [nn.Linear(W, W) if i not in self.skips else nn.Linear(W + xyz_in + t_in, W) for i in range(D - 1)])
        self.gaussian_warp = nn.Linear(W, 3)
        self.gaussian_rotation = nn.Linear(W, 4)
        self.gaussian_scaling = nn.Linear(W, 3)

    def forward(self, x, t):
        t_emb = embed(t, self.t_multires)
        if self.is_blender:
            t_emb = self.timenet(t_emb)
        x_emb = embed(x, 10)
        h = torch.cat([x_emb, t_emb], -1)
        for i, l in enumerate(self.linear):
            h = F.relu(l(h))
            if i in self.skips:
                h = torch.cat([x_emb, t_emb, h], -1)
        return self.gaussian_warp(h), self.gaussian_rotation(h), self.gaussian_scaling(h)


def make_deformable3dgs(out, name, seed, is_blender, n=300, frames=9, iteration=40000, width=32, expect=True):
    gen = torch.Generator().manual_seed(seed)
    net = DeformNetwork(8, width, is_blender)
    liven(net, gen, scale=0.2)
    xyz, f_dc, f_rest, opacity, scale, rot = random_gaussians(gen, n)
    run = os.path.join(out, name)
    pc = os.path.join(run, "point_cloud", "iteration_%d" % iteration)
    os.makedirs(pc)
    os.makedirs(os.path.join(run, "deform", "iteration_%d" % iteration))
    args = Namespace(sh_degree=3, source_path="data/x", model_path="output/" + name, is_blender=is_blender, is_6dof=False, eval=True)
    with open(os.path.join(run, "cfg_args"), "w") as f:
        f.write(str(args))
    write_ply(os.path.join(pc, "point_cloud.ply"), gaussian_columns(xyz.numpy(), f_dc.numpy(), f_rest.numpy(), opacity.numpy(), scale.numpy(), rot.numpy()))
    torch.save(net.state_dict(), os.path.join(run, "deform", "iteration_%d" % iteration, "deform.pth"))  # DeformModel.save_weights
    if not expect:
        return run
    times = [f / (frames - 1) for f in (0, 1, 4, frames - 1)] + [0.3, 0.77]  # its loaders: fid = frame / (F - 1)
    M, S, R, O, SH = [], [], [], [], []
    with torch.no_grad():
        for t in times:
            d_xyz, d_rot, d_scale = net(xyz, torch.full((n, 1), t))
            M.append((xyz + d_xyz).numpy())
            S.append(torch.abs(torch.exp(scale) + d_scale).numpy())  # the covariance sees the square
            R.append(F.normalize(F.normalize(rot) + d_rot).numpy())
            O.append(torch.sigmoid(opacity)[:, 0].numpy())
            SH.append(torch.cat([f_dc, f_rest], 1).reshape(n, -1).numpy())
    save_expect(os.path.join(run, "expect.npz"), times, M, O, SH, S, R)
    return run


# ----------------------------------------------------------------------------- Dynamic 3D Gaussians, PLY frames

def make_dynamic3dgs(out, name, seed, n=250, frames=8, expect=True):
    gen = np.random.default_rng(seed)
    base = gen.uniform(-1, 1, (n, 3))
    vel = gen.normal(0, 0.05, (n, 3))
    vel[: n // 3] = 0  # a third never moves: fillgs must find them static
    means = np.stack([base + f * vel for f in range(frames)]).astype(np.float32)
    rgb = np.clip(gen.uniform(0, 1, (n, 3)) + np.arange(frames)[:, None, None] * 0.02 * (np.arange(n) >= n // 3)[None, :, None], 0, 1).astype(np.float32)
    q0 = gen.normal(size=(n, 4))
    rots = np.stack([q0 + f * 0.05 * (np.arange(n) >= n // 3)[:, None] for f in range(frames)]).astype(np.float32)
    params = dict(means3D=means, rgb_colors=rgb, unnorm_rotations=rots,
                  log_scales=np.log(gen.uniform(0.01, 0.05, (n, 3))).astype(np.float32),
                  logit_opacities=gen.normal(0, 1, (n, 1)).astype(np.float32),
                  seg_colors=np.tile(np.array([[1.0, 0.0, 0.0]], np.float32), (n, 1)),
                  cam_m=np.zeros((27, 3), np.float32), cam_c=np.zeros((27, 3), np.float32))
    run = os.path.join(out, name)
    os.makedirs(run)
    np.savez(os.path.join(run, "params"), **params)  # save_params in its helpers.py
    if not expect:
        return run
    times = list(range(frames))
    C0 = 0.28209479177387814
    M = [means[f] for f in times]
    S = [np.exp(params["log_scales"]) for _ in times]
    R = [rots[f] / np.linalg.norm(rots[f], axis=1, keepdims=True) for f in times]
    O = [1 / (1 + np.exp(-params["logit_opacities"][:, 0])) for _ in times]
    SH = [(rgb[f] - 0.5) / C0 for f in times]
    save_expect(os.path.join(run, "expect.npz"), times, M, O, SH, S, R)
    return run


def make_ply_frames(out, name, seed, n=200, frames=6, expect=True):
    gen = torch.Generator().manual_seed(seed)
    xyz, f_dc, f_rest, opacity, scale, rot = random_gaussians(gen, n, sh_coeffs=4)
    moving = (torch.arange(n) >= n // 2).float()[:, None]
    run = os.path.join(out, name)
    os.makedirs(run)
    M, S, R, O, SH = [], [], [], [], []
    for f in range(frames):
        x = xyz + f * 0.03 * moving * torch.tensor([1.0, -0.5, 0.2])
        dc = f_dc + f * 0.05 * moving[:, :, None]
        sc = scale + f * 0.01 * moving
        op = opacity - f * 0.1 * moving
        r = rot + f * 0.02 * moving
        write_ply(os.path.join(run, "time_%05d.ply" % f), gaussian_columns(x.numpy(), dc.numpy(), f_rest.numpy(), op.numpy(), sc.numpy(), r.numpy()))
        if expect:
            M.append(x.numpy()); S.append(torch.exp(sc).numpy()); R.append(F.normalize(r).numpy())
            O.append(torch.sigmoid(op)[:, 0].numpy()); SH.append(torch.cat([dc, f_rest], 1).reshape(n, -1).numpy())
    if not expect:
        return run
    save_expect(os.path.join(run, "expect.npz"), list(range(frames)), M, O, SH, S, R)
    return run


# ----------------------------------------------------------------------------- broken files

def make_broken(out, ed3dgs_run):
    """Copies of the E-D3DGS run with one thing wrong each (the refusal tests)."""
    pc = os.path.join(ed3dgs_run, "point_cloud")
    it = [d for d in os.listdir(pc) if os.path.exists(os.path.join(pc, d, "deformation.pth"))][0]
    def variant(tag):
        dst = os.path.join(out, "broken_" + tag)
        shutil.copytree(ed3dgs_run, dst)
        return os.path.join(dst, "point_cloud", it, "deformation.pth")
    pth = variant("shape")
    sd = torch.load(pth)
    sd["pos_deform_f.3.weight"] = torch.zeros(5, sd["pos_deform_f.3.weight"].shape[1])
    torch.save(sd, pth)
    pth = variant("missing")
    sd = torch.load(pth)
    del sd["scales_deform_c.1.bias"]
    torch.save(sd, pth)
    pth = variant("truncated")
    data = open(pth, "rb").read()
    open(pth, "wb").write(data[: len(data) * 2 // 3])
    pth = variant("not_state_dict")
    torch.save([1, 2.5, "three"], pth)


def make_hostile(out, prefix, ed3dgs_run, fourdg_run, fourdgs_run):
    """Copies with values that are finite but would become indices out of range: an E-D3DGS
    camera time offset of 3e38 (its grid coordinate 2t - 1 overflows float32 to infinity), a
    4DGaussians aabb of extent 1e-45 (its scale 2 / extent is infinite in float32), 4DGS active
    SH degrees of NaN and 1e300 and 2^31 - 1 SH channels. Written as prefix + tag (the refusal
    tests, the fuzz seeds)."""
    def copy(run, tag):
        dst = os.path.join(out, prefix + tag)
        shutil.copytree(run, dst)
        return dst
    def deformation(run):  # the newest iteration's, as the readers take it
        pc = os.path.join(run, "point_cloud")
        its = [d for d in os.listdir(pc) if os.path.exists(os.path.join(pc, d, "deformation.pth"))]
        return os.path.join(pc, max(its, key=lambda d: int(d.split("_")[1])), "deformation.pth")
    pth = deformation(copy(ed3dgs_run, "offsets_huge"))
    sd = torch.load(pth)
    sd["offsets"][1, 0] = 3e38
    torch.save(sd, pth)
    pth = deformation(copy(fourdg_run, "aabb"))
    sd = torch.load(pth)
    sd["deformation_net.grid.aabb"][0, 0] = 0.0
    sd["deformation_net.grid.aabb"][1, 0] = 1e-45
    torch.save(sd, pth)
    src = [f for f in os.listdir(fourdgs_run) if f.startswith("chkpnt")][0]
    for tag, degree in (("nan", float("nan")), ("huge", 1e300)):
        dst = os.path.join(out, prefix + "4dgs_degree_" + tag)
        os.makedirs(dst)
        capture, iteration = torch.load(os.path.join(fourdgs_run, src))
        torch.save(((degree,) + tuple(capture[1:]), iteration), os.path.join(dst, src))
    # No Gaussians, but 2^31 - 1 SH channels claimed by an empty _features_rest (the count
    # plus one wrapped to -2^31 in an int).
    dst = os.path.join(out, prefix + "4dgs_sh_huge")
    os.makedirs(dst)
    capture, iteration = torch.load(os.path.join(fourdgs_run, src))
    capture = list(capture)
    for i in (1, 2, 4, 5, 6, 13, 14, 15):
        capture[i] = capture[i][:0]
    capture[3] = torch.empty(0, 2147483647, 3)
    torch.save((tuple(capture), iteration), os.path.join(dst, src))


BENCH_FORMATS = ("e-d3dgs", "4dgaussians", "4dgs", "dynamic3dgs", "ply-frames", "deformable3dgs", "e-d3dgs-still")


def make_bench(out, n, frames, formats=BENCH_FORMATS[:6]):
    """Models with the architectures of each code's N3V (dynerf) configuration and n Gaussians,
    no expected values: bench/trained_models.sh times fillgs on them. e-d3dgs-still: E-D3DGS
    whose background (80 % of the Gaussians) is still but for network noise."""
    os.makedirs(out)
    ed = dict(width=128, depth=1, min=30, max=150, tdim=256, c2f=10000, deform_from=5000, coarse_emb=True, no_do=False)
    if "e-d3dgs" in formats:
        make_ed3dgs(out, "e-d3dgs", 21, 80000, ed, n=n, frames=frames, gdim=32, expect=False)
    if "e-d3dgs-still" in formats:
        make_ed3dgs(out, "e-d3dgs-still", 27, 80000, ed, n=n, frames=frames, gdim=32, expect=False, still=0.8)
    if "4dgaussians" in formats:
        make_4dgaussians(out, "4dgaussians", 22, n=n, frames=frames, iteration=14000, width=128, channels=16, reso=(64, 150), depth=0, expect=False)
    if "4dgs" in formats:
        make_4dgs(out, "4dgs", 23, rot_4d=True, n=n, frames=frames, duration=(0.0, frames / 30.0), iteration=30000, expect=False)
    if "dynamic3dgs" in formats:
        make_dynamic3dgs(out, "dynamic3dgs", 24, n=n, frames=frames, expect=False)
    if "ply-frames" in formats:
        make_ply_frames(out, "ply-frames", 25, n=n, frames=min(frames, 30), expect=False)
    if "deformable3dgs" in formats:
        make_deformable3dgs(out, "deformable3dgs", 26, is_blender=False, n=n, frames=frames, width=256, expect=False)


def make_dtypes(out):
    """Tensors of every dtype a state dict may hold, one of them a transposed view (strides
    (1, 3)), and their values as float64 written by NumPy: the .pth reader's conversions."""
    base = torch.tensor([[1.5, -2.0, 65504.0], [6.0e-8, 0.1, -0.0]])
    sd = {"f32": base, "f64": base.double(), "f16": base.half(), "bf16": base.bfloat16(), "i64": torch.tensor([-3, 0, 2 ** 40]),
          "i32": torch.tensor([-7, 5], dtype=torch.int32), "u8": torch.tensor([0, 255], dtype=torch.uint8),
          "bool": torch.tensor([True, False, True]), "t": base.t()}
    d = os.path.join(out, "dtypes")
    os.makedirs(d)
    torch.save(sd, os.path.join(d, "tensors.pth"))
    np.savez(os.path.join(d, "expect.npz"), **{k: v.float().numpy().astype(np.float64) for k, v in sd.items()})


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--bench", type=int, metavar="N", help="only benchmark models of N Gaussians (see make_bench)")
    ap.add_argument("--frames", type=int, default=300, help="--bench: frames each model covers")
    ap.add_argument("--formats", default=",".join(BENCH_FORMATS[:6]), help="--bench: the models made, of " + ",".join(BENCH_FORMATS))
    a = ap.parse_args()
    out = a.out
    if os.path.exists(out):
        shutil.rmtree(out)
    torch.manual_seed(0)
    if a.bench:
        formats = a.formats.split(",")
        unknown = [f for f in formats if f not in BENCH_FORMATS]
        if unknown:
            ap.error("--formats: unknown %s (known: %s)" % (",".join(unknown), ",".join(BENCH_FORMATS)))
        make_bench(out, a.bench, a.frames, formats)
        print("benchmark models in", out)
        return 0
    os.makedirs(out)
    ed = make_ed3dgs(out, "ed3dgs", 1, 14000, dict(width=24, depth=2, min=5, max=16, tdim=16, c2f=10000, deform_from=5000, coarse_emb=True, no_do=False))
    make_ed3dgs(out, "ed3dgs_still", 5, 14000, dict(width=24, depth=2, min=5, max=16, tdim=16, c2f=10000, deform_from=5000, coarse_emb=True, no_do=False),
                still=0.6)
    make_ed3dgs(out, "ed3dgs_early", 2, 5600, dict(width=16, depth=1, min=4, max=20, tdim=12, c2f=10000, deform_from=5000, coarse_emb=False, no_do=True))
    fourdg = make_4dgaussians(out, "4dgaussians", 3)
    fourdgs = make_4dgs(out, "4dgs", 4, rot_4d=True)
    make_4dgs(out, "4dgs_3drot", 5, rot_4d=False)
    make_4dgs(out, "4dgs_short_lived", 14, rot_4d=False, n=6, frames=300, duration=(0.0, 10.0), expect=False, edit=short_lived_4dgs)
    make_dynamic3dgs(out, "dynamic3dgs", 6)
    make_deformable3dgs(out, "deformable3dgs", 8, is_blender=False)
    make_deformable3dgs(out, "deformable3dgs_blender", 9, is_blender=True)
    make_ply_frames(out, "ply_frames", 7)
    # Models fine-tuning must keep (tests/test_keep_model.cpp): 2,000 Gaussians, 60 frames, the
    # networks' widths of the benchmark's models halved.
    keep = dict(width=64, depth=1, min=30, max=150, tdim=64, c2f=10000, deform_from=5000, coarse_emb=True, no_do=False)
    make_ed3dgs(out, "ed3dgs_keep", 31, 80000, keep, n=2000, frames=60, gdim=32, expect=False)
    make_4dgaussians(out, "4dgaussians_keep", 32, n=2000, frames=60, iteration=14000, width=64, channels=16, reso=(64, 150), depth=0, expect=False)
    make_broken(out, ed)
    make_hostile(out, "broken_", ed, fourdg, fourdgs)
    make_dtypes(out)
    # Tiny copies: the fuzz harnesses' seeds (tests/fuzz, bench/fuzz).
    fz = os.path.join(out, "fuzz")
    os.makedirs(fz)
    make_ed3dgs(fz, "ed3dgs", 11, 100, dict(width=4, depth=1, min=2, max=4, tdim=4, c2f=50, deform_from=0, coarse_emb=True, no_do=False), n=3, frames=3)
    make_4dgaussians(fz, "4dgaussians", 12, n=3, frames=3, iteration=100, width=4, channels=2, reso=(2, 2))
    make_4dgs(fz, "4dgs", 13, rot_4d=True, n=3, frames=3, iteration=100)
    make_dynamic3dgs(fz, "dynamic3dgs", 14, n=3, frames=2)
    make_ply_frames(fz, "ply_frames", 15, n=3, frames=2)
    make_deformable3dgs(fz, "deformable3dgs", 16, is_blender=False, n=3, frames=3, iteration=100, width=4)
    make_hostile(fz, "hostile_", os.path.join(fz, "ed3dgs"), os.path.join(fz, "4dgaussians"), os.path.join(fz, "4dgs"))
    print("model fixtures in", out)


if __name__ == "__main__":
    sys.exit(main())
