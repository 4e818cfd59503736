#!/usr/bin/env python3
"""Draws one sample of an fbar grid field (gridField[i]_frame[k].h5, .bgeo, .geo or .csv) as a map on a plane of
nodes: an attribute's component summed along the plane's normal (every node with the same two other indices), divided
by an area when given (a wall's Force_X / dx^2 is its pressure in Pa).

    python3 tools/plot/plot_grid_field.py 'output/run/gridField[0]_frame[8].h5' --attribute Force --component x \\
        --plane x --per-area 0.0004 --out wall_pressure.png

--plane x draws the y-z plane (y up), --plane y the x-z plane, --plane z the x-y plane. Prints the map's range and its
total (the sum over every node: for a wall's Force, the load cell's value).
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fbar_frames import frame_units, read_frame  # noqa: E402

AXES = {"x": 0, "y": 1, "z": 2}


def values_of(frame, attribute, component):
    """The attribute's values per point: its component `component` (x, y, z) of a vector, or the scalar."""
    if attribute in frame:
        a = np.asarray(frame[attribute], dtype=float)
        if a.ndim == 2:
            return a[:, AXES[component or "x"]]
        return a
    name = f"{attribute}_{(component or 'x').upper()}"  # a .csv's or .bgeo's component columns
    if name in frame:
        return np.asarray(frame[name], dtype=float)
    raise SystemExit(f"the frame has no attribute {attribute} (it has: {', '.join(sorted(k for k in frame if k != 'P'))})")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("frame", help="a grid field's sample file")
    parser.add_argument("--attribute", default="Force", help="Mass, Velocity, Momentum, Force, BoundaryForce, ...")
    parser.add_argument("--component", choices=list(AXES), help="a vector's component (default x)")
    parser.add_argument("--plane", choices=list(AXES), default="x", help="the normal of the plane drawn")
    parser.add_argument("--per-area", type=float, default=0.0, help="divide by this area [m^2] (dx^2: a pressure)")
    parser.add_argument("--out", help="PNG file (default: the sample's name with .png)")
    args = parser.parse_args(argv)
    frame = read_frame(args.frame)
    P = np.asarray(frame["P"], dtype=float)
    if len(P) == 0:
        raise SystemExit(f"{args.frame}: no node of mass in this sample")
    v = values_of(frame, args.attribute, args.component)
    normal = AXES[args.plane]
    h, vert = {0: (2, 1), 1: (0, 2), 2: (0, 1)}[normal]
    # The nodes' spacing from their positions (the grid's dx): the smallest non-zero gap along the drawn axes.
    gaps = np.concatenate([np.diff(np.unique(P[:, a])) for a in (h, vert)])
    gaps = gaps[gaps > 1e-12]
    dx = float(gaps.min()) if len(gaps) else 1.0
    ih = np.rint((P[:, h] - P[:, h].min()) / dx).astype(int)
    iv = np.rint((P[:, vert] - P[:, vert].min()) / dx).astype(int)
    summed = np.zeros((iv.max() + 1, ih.max() + 1))
    occupied = np.zeros(summed.shape, dtype=bool)
    np.add.at(summed, (iv, ih), v)
    occupied[iv, ih] = True
    grid = np.where(occupied, summed, np.nan)  # no node of mass there: blank
    if args.per_area > 0:
        grid = grid / args.per_area
    unit = frame_units(args.frame).get(args.attribute, "")
    vector = args.attribute not in frame or np.asarray(frame[args.attribute]).ndim == 2
    label = args.attribute + (f"_{(args.component or 'x').upper()}" if vector else "")
    if args.per_area > 0:
        forces = unit == "N" or args.attribute in ("Force", "BoundaryForce")  # .bgeo and .geo record no units
        label += f" / {args.per_area:g} m^2" + (" [Pa]" if forces else "")
    elif unit:
        label += f" [{unit}]"
    names = "xyz"
    fig, ax = plt.subplots(figsize=(6.0, 5.0))
    extent = [P[:, h].min() - dx / 2, P[:, h].max() + dx / 2, P[:, vert].min() - dx / 2, P[:, vert].max() + dx / 2]
    im = ax.imshow(grid, origin="lower", extent=extent, cmap="viridis", aspect="equal")
    fig.colorbar(im, ax=ax, label=label)
    ax.set_xlabel(f"{names[h]} [m]")
    ax.set_ylabel(f"{names[vert]} [m]")
    ax.set_title(os.path.basename(args.frame))
    out = args.out or os.path.splitext(args.frame)[0] + ".png"
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    total = float(np.nansum(summed)) / (args.per_area if args.per_area > 0 else 1.0)
    print(f"{out}: {len(P)} nodes, {label} from {np.nanmin(grid):.6g} to {np.nanmax(grid):.6g}, "
          f"sum {float(np.sum(v)):.6g}" + (f" (sum / area {total:.6g})" if args.per_area > 0 else ""))


if __name__ == "__main__":
    main()
