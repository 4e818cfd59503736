#!/usr/bin/env python3
"""Renders one fbar particle frame (.bgeo, .geo, .csv or .h5) as a PNG: the particles projected on two axes, coloured by an
attribute.

    python3 tools/plot/render_frame.py FRAME [--color Pressure] [--axes x y] [--out frame.png]

Without --color the particles are coloured by the third axis (depth). Several frames of several ranks
(model[0]_dev[*]_frame[12].bgeo) may be given together: they are drawn as one. .h5 frames need h5py.
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fbar_frames import read_frame  # noqa: E402

AXES = {"x": 0, "y": 1, "z": 2}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("frames", nargs="+", help=".bgeo, .geo, .csv or .h5 frame files (one per rank)")
    parser.add_argument("--color", help="attribute to colour by (e.g. Pressure, Velocity_Magnitude)")
    parser.add_argument("--axes", nargs=2, default=["x", "y"], choices=list(AXES), help="horizontal, vertical axis")
    parser.add_argument("--out", help="PNG file (default: the first frame's name with .png)")
    parser.add_argument("--size", type=float, default=0.0, help="marker size (default: from the particle count)")
    args = parser.parse_args(argv)
    frames = [read_frame(f) for f in args.frames]
    P = np.concatenate([f["P"] for f in frames])
    h, v = AXES[args.axes[0]], AXES[args.axes[1]]
    depth = 3 - h - v
    if args.color:
        missing = [f for f, fr in zip(args.frames, frames) if args.color not in fr]
        if missing:
            parser.error(f"{missing[0]} has no attribute {args.color} (it has {', '.join(sorted(frames[0]))})")
        c = np.concatenate([np.asarray(f[args.color], dtype=np.float64).reshape(len(f["P"]), -1)[:, 0]
                            for f in frames])
        label = args.color
    else:
        c = P[:, depth]
        label = "xyz"[depth] + " [m]"
    order = np.argsort(P[:, depth])  # far particles first
    size = args.size or max(0.05, min(12.0, 1e5 / max(1, len(P))))
    fig, ax = plt.subplots(figsize=(8, 5))
    sc = ax.scatter(P[order, h], P[order, v], c=c[order], s=size, cmap="viridis", linewidths=0)
    ax.set_aspect("equal")
    ax.set_xlabel(args.axes[0] + " [m]")
    ax.set_ylabel(args.axes[1] + " [m]")
    ax.set_title(f"{os.path.basename(args.frames[0])}: {len(P)} particles")
    fig.colorbar(sc, ax=ax, label=label)
    fig.tight_layout()
    out = args.out or os.path.splitext(args.frames[0])[0] + ".png"
    fig.savefig(out, dpi=120)
    print(out)


if __name__ == "__main__":
    main()
