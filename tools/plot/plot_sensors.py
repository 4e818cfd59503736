#!/usr/bin/env python3
"""Plots fbar's sensor and tracker CSVs (gridTarget[i]_dev[0].csv, particleTarget[i]_model[m]_dev[0].csv,
particleTrack_model[m]_dev[0].csv) against time, one PNG per file.

    python3 tools/plot/plot_sensors.py OUTPUT_DIR [--out DIR]      every sensor / tracker CSV of a run
    python3 tools/plot/plot_sensors.py FILE.csv [FILE.csv ...] [--out DIR]

A tracker file gets one panel per attribute (its particles as lines). PNGs are named after the CSVs.
"""
import argparse
import glob
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fbar_frames import read_series, split_header  # noqa: E402

PATTERNS = ("gridTarget[[]*]_dev[[]*].csv", "particleTarget[[]*]_model[[]*]_dev[[]*].csv",
            "particleTrack_model[[]*]_dev[[]*].csv")


def files_of(paths):
    out = []
    for p in paths:
        if os.path.isdir(p):
            for pattern in PATTERNS:
                out += sorted(glob.glob(os.path.join(glob.escape(p), pattern)))
        else:
            out.append(p)
    return out


def plot(path, out_dir):
    times, columns = read_series(path)
    name = os.path.basename(path)[:-4]
    if name.startswith("particleTrack"):
        groups = {}
        for header, values in columns.items():
            attr, unit = split_header(header)
            base, _, pid = attr.partition("[")
            groups.setdefault((base, unit), []).append(("ID " + pid.rstrip("]"), values))
    else:
        groups = {split_header(h): [(None, v)] for h, v in columns.items()}
    fig, axes = plt.subplots(len(groups), 1, figsize=(7, 2.6 * len(groups)), sharex=True, squeeze=False)
    for ax, ((quantity, unit), lines) in zip(axes[:, 0], groups.items()):
        for label, values in lines:
            ax.plot(times, values, marker="." if len(times) < 60 else None, label=label)
        ax.set_ylabel(f"{quantity} [{unit}]" if unit else quantity)
        ax.grid(alpha=0.3)
        if lines[0][0] is not None:
            ax.legend(fontsize="small")
    axes[-1, 0].set_xlabel("time [s]")
    axes[0, 0].set_title(name)
    fig.tight_layout()
    target = os.path.join(out_dir or os.path.dirname(path) or ".", name + ".png")
    fig.savefig(target, dpi=110)
    plt.close(fig)
    return target


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("paths", nargs="+", help="a run's output directory, or CSV files")
    parser.add_argument("--out", help="directory for the PNGs (default: next to each CSV)")
    args = parser.parse_args(argv)
    files = files_of(args.paths)
    if not files:
        parser.error("no sensor or tracker CSV found in " + " ".join(args.paths))
    if args.out:
        os.makedirs(args.out, exist_ok=True)
    for f in files:
        print(plot(f, args.out))


if __name__ == "__main__":
    main()
