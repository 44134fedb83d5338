#!/usr/bin/env python3
"""Writes N cameras of 64x48 on a circle of radius 4 around the origin, looking at it, as a
transforms.json (camera-to-world in OpenGL axes): the benchmarks' and tests' cameras for the
trained models, whose Gaussians lie within the unit cube.

    ring_cameras.py N OUT.json [--wave]    (--wave: heights 0.3 cos 3a instead of 0.3)
"""
import json
import math
import sys


def main():
    args = [a for a in sys.argv[1:] if a != "--wave"]
    wave = "--wave" in sys.argv[1:]
    if len(args) != 2:
        sys.exit(__doc__)
    n, path = int(args[0]), args[1]
    frames = []
    for i in range(n):
        a = 2 * math.pi * i / n
        c = [4 * math.sin(a), 0.3 * math.cos(3 * a) if wave else 0.3, -4 * math.cos(a)]
        z = [-v / math.sqrt(sum(x * x for x in c)) for v in c]  # forward: to the origin
        x = [z[2], 0.0, -z[0]]
        norm = math.sqrt(sum(v * v for v in x))
        x = [v / norm for v in x]
        y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]]
        m = [[x[0], -y[0], -z[0], c[0]], [x[1], -y[1], -z[1], c[1]], [x[2], -y[2], -z[2], c[2]], [0, 0, 0, 1]]
        frames.append({"file_path": "cam%02d" % i, "transform_matrix": m})
    with open(path, "w") as f:
        json.dump({"camera_angle_x": 0.9, "w": 64, "h": 48, "frames": frames}, f, indent=1)


if __name__ == "__main__":
    main()
