#!/usr/bin/env python3
"""The world-unit size of one pixel on a COLMAP model, at the median depth of its points from
its first image's camera, for images WIDTH pixels wide: what a still tolerance in world units
means in pixels there (data/README.md, "Still Gaussians").

    pixel_footprint.py SPARSE_DIR WIDTH      (SPARSE_DIR: cameras.bin, images.bin, points3D.bin)
"""
import os
import struct
import sys

import numpy as np


def read_cstring(f):
    out = b""
    while (c := f.read(1)) not in (b"\0", b""):
        out += c
    return out


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sparse, width = sys.argv[1], int(sys.argv[2])
    with open(os.path.join(sparse, "cameras.bin"), "rb") as f:
        f.read(8)
        _, _, w, _ = struct.unpack("<iiQQ", f.read(24))
        fx = struct.unpack("<d", f.read(8))[0]
    with open(os.path.join(sparse, "images.bin"), "rb") as f:
        f.read(8)
        f.read(4)
        qw, qx, qy, qz = struct.unpack("<4d", f.read(32))
        t = np.array(struct.unpack("<3d", f.read(24)))
    R = np.array([[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)],
                  [2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)],
                  [2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)]])
    pts = []
    with open(os.path.join(sparse, "points3D.bin"), "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        for _ in range(n):
            d = f.read(43)
            pts.append(struct.unpack("<3d", d[8:32]))
            f.read(struct.unpack("<Q", f.read(8))[0] * 8)
    z = (np.array(pts) @ R.T + t)[:, 2]
    z = z[z > 0]
    f_at = fx * width / w
    depth = float(np.median(z))
    print("focal %.1f px at width %d; median depth %.2f world units (10th-90th percentile %.2f-%.2f); one pixel there: %.4g world units"
          % (f_at, width, depth, np.percentile(z, 10), np.percentile(z, 90), depth / f_at))


if __name__ == "__main__":
    main()
