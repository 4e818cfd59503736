"""Rigid translation: the problem run_study.py --problem translation runs (the precision floor of the engines).

A square block of water (JFluid, a = 0.1 m, c0 = 20 m/s) moves at v = (2, 1, 0) m/s without gravity or walls for
0.3 s (6 block widths), a slab one cell thick. The exact motion is rigid: every particle moves at v, the pressure
stays 0. MPM's transfers reproduce a uniform velocity exactly (APIC's affine part is zero, FLIP's increment is
zero), so every error here is round-off: it measures what single, mixed and double precision cost and deliver.
Measured by particle sensors (100 Hz): the drift of the mean position from x0 + v t over dx, the spread of the
particle velocities (max - min of Velocity_X over |v|), and the largest |pressure| over rho |v|^2.
Error (the charts'): the largest of the drift and the velocity spread.
"""
import csv
import glob
import json
import math
import os
import re
import subprocess

A = 0.1
V = (2.0, 1.0, 0.0)
T_END = 0.3
C0 = 20.0
RHO = 1000.0
SCHEMES = {
    "APIC": {"use_ASFLIP": False},
    "FLIP": {"use_ASFLIP": True, "ASFLIP_alpha": 1.0, "ASFLIP_beta_min": 0.0, "ASFLIP_beta_max": 0.0},
}
SENSORS = [("Position_X", "Average"), ("Position_Y", "Average"), ("Velocity_X", "Max"), ("Velocity_X", "Min"),
           ("Pressure", "Max"), ("Pressure", "Min")]


def scene(cells, scheme, precision):
    dx = A / cells
    x0 = y0 = z0 = 4 * dx
    domain = [x0 + A + V[0] * T_END + 4 * dx, y0 + A + V[1] * T_END + 4 * dx, z0 + 5 * dx]
    body = {"material": {"constitutive": "JFluid", "rho": RHO, "bulk_modulus": RHO * C0 * C0, "gamma": 7,
                         "viscosity": 0.0, "ppc": 8, "CFL": 0.5},
            "algorithm": dict(SCHEMES[scheme], use_FBAR=False), "velocity": list(V),
            "geometry": [{"object": "Box", "span": [A, A, dx], "offset": [x0, y0, z0]}], "output_attribs": ["ID"]}
    sensors = [{"attribute": q, "operation": op, "output_frequency": 100.0, "domain_start": [0, 0, 0],
                "domain_end": domain} for q, op in SENSORS]
    return {"simulation": {"domain": domain, "default_dx": dx, "gravity": [0, 0, 0], "fps": 1 / T_END, "frames": 1,
                           "precision": precision, "save_suffix": ".csv"},
            "bodies": [body], "particle-sensors": sensors}


def read(path):
    with open(path) as f:
        rows = list(csv.reader(f))[1:]
    return [float(r[0]) for r in rows], [float(r[1]) for r in rows]


def run(fbar, backend, cells, scheme, precision, work):
    s = scene(cells, scheme, precision)
    out = os.path.join(work, f"tr_{backend}_{cells}_{scheme}_{precision}")
    os.makedirs(out, exist_ok=True)
    for old in glob.glob(os.path.join(out, "*.csv")):
        os.remove(old)
    path = os.path.join(out, "scene.json")
    with open(path, "w") as f:
        json.dump(s, f)
    p = subprocess.run([fbar, f"--backend={backend}", f"--output={out}", path], capture_output=True, text=True)
    row = dict(backend=backend, cells_per_a=cells, scheme=scheme, precision=precision)
    if p.returncode != 0:
        row.update(status="failed", message=(p.stderr.strip().splitlines() or [""])[-1])
        return row
    with open(os.path.join(out, "run.json")) as f:
        meta = json.load(f)
    setup = re.search(r"set-up ([0-9.eE+-]+) s", p.stdout + p.stderr)
    simulate_s = meta["wall_time_s"] - (float(setup.group(1)) if setup else 0.0)
    series = [read(os.path.join(out, f"particleTarget[{i}]_model[0]_dev[0].csv"))[1] for i in range(len(SENSORS))]
    t = read(os.path.join(out, "particleTarget[0]_model[0]_dev[0].csv"))[0]
    dx = A / cells
    speed = math.hypot(V[0], V[1])
    drift = max(max(abs(x - (series[0][0] + V[0] * ti)), abs(y - (series[1][0] + V[1] * ti))) / dx
                for ti, x, y in zip(t, series[0], series[1]))
    spread = max(hi - lo for hi, lo in zip(series[2], series[3])) / speed
    pressure = max(max(abs(v) for v in series[4]), max(abs(v) for v in series[5])) / (RHO * speed * speed)
    row.update(status="ok", message="", drift_over_dx=f"{drift:.4g}", velocity_spread=f"{spread:.4g}",
               pressure_over_rho_v2=f"{pressure:.4g}", error=f"{max(drift, spread):.4g}",
               wall_s=f"{meta['wall_time_s']:.3f}", steps=meta["steps"], particles=cells * cells * 8,
               s_per_simulated_s=f"{simulate_s / T_END:.4f}")
    return row


FIELDS = ["backend", "cells_per_a", "scheme", "precision", "status", "error", "drift_over_dx", "velocity_spread",
          "pressure_over_rho_v2", "wall_s", "s_per_simulated_s", "steps", "particles", "message"]


def charts(rows, out, title_backend, suffix, draw_pareto, save):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r["status"] == "ok"]
    floor = 1e-17  # an exact zero drawn at the axis' floor
    pts = [(float(r["s_per_simulated_s"]), max(float(r["error"]), floor)) for r in ok]
    colors = {"single": "C0", "mixed": "C1", "double": "C2"}
    markers = {"APIC": "o", "FLIP": "^"}
    fig, ax = plt.subplots(figsize=(8, 5.5))
    draw_pareto(ax, ok, pts, lambda r: (r["precision"], r["scheme"], 10 + 0.6 * int(r["cells_per_a"])),
                lambda r: f"{r['scheme']}, {r['precision']}, a/dx {r['cells_per_a']}", colors, markers)
    ax.set_xlabel(f"wall time per simulated second [s] ({title_backend})")
    ax.set_ylabel("max(position drift / dx, velocity spread / |v|)")
    ax.set_title("Rigid translation (exact: zero error): round-off against cost")
    ax.legend(fontsize=8)
    save(fig, out, f"translation_pareto{suffix}.png")

    fig, ax = plt.subplots(figsize=(7, 5))
    for prec, c in colors.items():
        for scheme, m in markers.items():
            rs = sorted((r for r in ok if r["precision"] == prec and r["scheme"] == scheme),
                        key=lambda r: int(r["cells_per_a"]))
            if rs:
                ax.plot([int(r["cells_per_a"]) for r in rs], [max(float(r["error"]), floor) for r in rs],
                        marker=m, color=c, label=f"{scheme}, {prec}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("cells per block width a/dx")
    ax.set_ylabel("max(position drift / dx, velocity spread / |v|)")
    ax.set_title("Rigid translation: the precision floor against resolution")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    save(fig, out, f"translation_precision{suffix}.png")


def study(a, draw_pareto, save):
    backend = "gpu" if a.gpu else "cpu"
    suffix = "_gpu" if a.gpu else ""
    csv_path = os.path.join(a.out, f"translation_study{suffix}.csv")
    if a.replot:
        with open(csv_path) as f:
            rows = list(csv.DictReader(f))
        charts(rows, a.out, f"{rows[0]['backend']} engine", suffix, draw_pareto, save)
        return 0
    cells = [int(c) for c in a.cells] if a.cells else ([16, 32, 64, 128] if a.gpu else [8, 16, 32])
    precisions = ("single", "mixed", "double")
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for n in cells:
        for scheme in SCHEMES:
            for precision in precisions:
                r = run(a.fbar, backend, n, scheme, precision, a.work)
                rows.append(r)
                print(f"{backend} a/dx {n:4d} {scheme:5s} {precision:6s} {r['status']:6s} error {r.get('error', ''):>9s} "
                      f"drift {r.get('drift_over_dx', ''):>9s} spread {r.get('velocity_spread', ''):>9s} "
                      f"p {r.get('pressure_over_rho_v2', ''):>9s} wall {r.get('wall_s', '')} s {r.get('message', '')}",
                      flush=True)
                with open(csv_path, "w", newline="") as f:
                    w = csv.DictWriter(f, fieldnames=FIELDS)
                    w.writeheader()
                    for done in rows:
                        w.writerow({k: done.get(k, "") for k in FIELDS})
    charts(rows, a.out, f"{backend} engine", suffix, draw_pareto, save)
    return 0
