#!/usr/bin/env python3
"""Plots a sweep's gathered tables (fbar --sweep: sweep_table.csv and sweep_summary.csv in the sweep's folder).

    python3 tools/plot/plot_sweep.py SWEEP_DIR --sensor S [--quantity Q] [--color-by P] [--out FILE.png]
        one sensor's time series, one line per completed case, coloured by parameter P (default: the first)
    python3 tools/plot/plot_sweep.py SWEEP_DIR --sensor S --against P [--statistic peak|mean|impulse]
                                     [--group-by P2] [--out FILE.png]
        a statistic of the sensor per case (sweep_summary.csv) against parameter P, one series per value of P2
    python3 tools/plot/plot_sweep.py SWEEP_DIR --list      the sensors, quantities and parameters there are

S is a sensor's file name without .csv ("gridTarget[0]_dev[0]"; a unique prefix such as "gridTarget[0]" will do),
Q a quantity's column header ("Force_x [N]"; default: the sensor's only or first). A parameter whose labels are all
numbers is plotted as numbers, otherwise as categories in the order the cases give them.
"""
import argparse
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

FIXED = ("sensor", "quantity")


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise SystemExit(f"plot_sweep: {path} is empty")
    return rows[0], rows[1:]


def parameters_of(header):
    """The parameter columns: between 'case' and 'sensor' (tables) or 'status' (sweep_cases.csv)."""
    end = header.index("sensor") if "sensor" in header else header.index("status")
    return header[1:end]


def as_number(text):
    try:
        return float(text)
    except ValueError:
        return math.nan


def pick(name, choices, what):
    if name is None:
        return choices[0]
    if name in choices:
        return name
    starts = [c for c in choices if c.startswith(name)]
    if len(starts) == 1:
        return starts[0]
    raise SystemExit(f"plot_sweep: no {what} '{name}' (there are: {', '.join(choices)})")


def numeric(labels):
    return all(not math.isnan(as_number(x)) for x in labels)


def series(sweep_dir, sensor, quantity, color_by, out):
    header, rows = read_csv(os.path.join(sweep_dir, "sweep_table.csv"))
    params = parameters_of(header)
    s_col, q_col = header.index("sensor"), header.index("quantity")
    sensor = pick(sensor, sorted({r[s_col] for r in rows}), "sensor")
    quantity = pick(quantity, sorted({r[q_col] for r in rows if r[s_col] == sensor}), "quantity")
    color_by = pick(color_by, params, "parameter") if params else None
    p_col = header.index(color_by) if color_by else None
    cases = {}
    for r in rows:
        if r[s_col] == sensor and r[q_col] == quantity:
            c = cases.setdefault(r[0], {"label": r[p_col] if p_col else "", "t": [], "v": []})
            c["t"].append(float(r[-2]))
            c["v"].append(as_number(r[-1]))
    if not cases:
        raise SystemExit(f"plot_sweep: no rows of {sensor} / {quantity}")
    labels = [c["label"] for c in cases.values()]
    cmap = plt.get_cmap("viridis")
    if numeric(labels):
        lo, hi = min(map(float, labels)), max(map(float, labels))
        color = {x: cmap(0.0 if hi == lo else (float(x) - lo) / (hi - lo)) for x in labels}
    else:
        order = list(dict.fromkeys(labels))
        color = {x: cmap(i / max(1, len(order) - 1)) for i, x in enumerate(order)}
    fig, ax = plt.subplots(figsize=(7.5, 4))
    shown = set()
    for case, c in cases.items():
        first = c["label"] not in shown
        shown.add(c["label"])
        ax.plot(c["t"], c["v"], color=color[c["label"]], lw=1.0, alpha=0.85,
                label=f"{color_by} = {c['label']}" if first and color_by else None)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(quantity)
    ax.set_title(f"{sensor}: {len(cases)} cases")
    ax.grid(alpha=0.3)
    if color_by and len(shown) <= 12:
        ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    return out


def statistic(sweep_dir, sensor, quantity, against, group_by, stat, out):
    header, rows = read_csv(os.path.join(sweep_dir, "sweep_summary.csv"))
    params = parameters_of(header)
    s_col, q_col = header.index("sensor"), header.index("quantity")
    stat_col = {"peak": header.index("peak"), "mean": header.index("mean"),
                "impulse": header.index("impulse [value s]")}[stat]
    sensor = pick(sensor, sorted({r[s_col] for r in rows}), "sensor")
    quantity = pick(quantity, sorted({r[q_col] for r in rows if r[s_col] == sensor}), "quantity")
    against = pick(against, params, "parameter")
    a_col = header.index(against)
    g_col = header.index(pick(group_by, params, "parameter")) if group_by else None
    chosen = [r for r in rows if r[s_col] == sensor and r[q_col] == quantity]
    if not chosen:
        raise SystemExit(f"plot_sweep: no summary of {sensor} / {quantity}")
    xs = [r[a_col] for r in chosen]
    categories = None if numeric(xs) else list(dict.fromkeys(xs))
    fig, ax = plt.subplots(figsize=(6.5, 4))
    groups = {}
    for r in chosen:
        groups.setdefault(r[g_col] if g_col is not None else "", []).append(r)
    for name, members in groups.items():
        pts = sorted((float(r[a_col]) if categories is None else categories.index(r[a_col]), as_number(r[stat_col]))
                     for r in members)
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", lw=1.0,
                label=f"{header[g_col]} = {name}" if g_col is not None else None)
    if categories is not None:
        ax.set_xticks(range(len(categories)))
        ax.set_xticklabels(categories)
    ax.set_xlabel(against)
    ax.set_ylabel(f"{stat} of {quantity}" + (" s" if stat == "impulse" else ""))
    ax.set_title(f"{sensor}: {stat} per case")
    ax.grid(alpha=0.3)
    if g_col is not None:
        ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sweep_dir")
    ap.add_argument("--sensor")
    ap.add_argument("--quantity")
    ap.add_argument("--color-by")
    ap.add_argument("--against")
    ap.add_argument("--group-by")
    ap.add_argument("--statistic", default="peak", choices=("peak", "mean", "impulse"))
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--out")
    a = ap.parse_args(argv)
    if a.list:
        header, rows = read_csv(os.path.join(a.sweep_dir, "sweep_table.csv"))
        s_col, q_col = header.index("sensor"), header.index("quantity")
        print("parameters:", ", ".join(parameters_of(header)))
        for s, q in sorted({(r[s_col], r[q_col]) for r in rows}):
            print(f"{s}: {q}")
        return 0
    if not a.sensor:
        ap.error("--sensor is required (--list shows them)")
    stem = a.sensor.replace("[", "").replace("]", "")
    if a.against:
        out = a.out or os.path.join(a.sweep_dir, f"sweep_{stem}_{a.statistic}_vs_{a.against}.png")
        print(statistic(a.sweep_dir, a.sensor, a.quantity, a.against, a.group_by, a.statistic, out))
    else:
        out = a.out or os.path.join(a.sweep_dir, f"sweep_{stem}.png")
        print(series(a.sweep_dir, a.sensor, a.quantity, a.color_by, out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
