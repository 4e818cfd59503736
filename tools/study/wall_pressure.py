"""Wall pressure of a dam break against Lobovsky et al. (2014): the problem run_study.py --problem wall_pressure runs.

Experiment (Lobovsky, Botia-Vera, Castellana, Mas-Soler & Souto-Iglesias 2014, J. Fluids Struct. 48:407-434): a
water column H = 0.3 m high and 0.6 m long at one end of a tank 1.61 m long and 0.15 m wide, released by a gate.
Pressure sensors on the far wall at 3, 15, 30 and 80 mm above the bed (their sensors 1-4). The reference series
are one repetition close to the median ("peak event 5" of their Fig. 18, as distributed with TNL-SPH), p / (rho g H)
against t (g / H)^(1/2) at 20 kHz, for sensors 1 and 3 (the two stored): data/lobovsky2014/README.md. The
simulation records all four heights; the errors use sensors 1 and 3.

Simulation: the same tank as a 2D slab (one cell thick between walls), JFluid rho 1000, c0 = 10 x 2 sqrt(g H)
(34.3 m/s, the weakly compressible choice of the SPH studies of this experiment), 8 ppc, Separable walls (water
does not stick to a wall; fbar's default scene uses them too). The wall pressure at a sensor's height is read from
grid sensors (Force, X, Sum) on the far wall's nodes, one per node row. A simulated sensor is a strip of the wall
two cells high around the sensor's height (from h - dx, or the bed, to 2 dx above that): the force of the node rows
it covers (each row stands for the wall strip within dx/2 of it; the row below the bed counts with the bed row, as
the bed particles' B-spline weights reach it), divided by the strip's area. A strip narrower than two cells reads
the checkerboard of alternating node rows that an impact leaves in the particle pressures, so the sensor of a grid
method is two cells high, however small the gauge (Lobovsky's are 4.5 mm). The particle pressures of the whole body are recorded too (particle sensors, Min and Max of Pressure).

Error measures (all in units of rho g H and of t* = t (g / H)^(1/2)):
 - rms: the RMS over sensors 1 and 3 and t* in [2, 7] of the difference between the simulated and the measured
   pressure, each smoothed by a centred moving average over 0.1 in t* (0.017 s). The chart's error. It measures the
   impact time, the load after it and the second impact of the returning wave together; the first impact's peak is
   a stochastic value in the experiment (Lobovsky's own point: its spread over 100 repetitions is large), so it is
   recorded (peak) and not scored.
 - impact_dt: |t*_sim - t*_exp| of the first time sensor 1 reads 0.5 rho g H.
 - plateau_error: the mean over sensors 1 and 3 of |mean_sim - mean_exp| over t* in [3, 5.5] (the load between the impact
   and the return of the reflected wave).
 - particle pressure range before the impact (t* < 2): min_p_before, max_p_before, and over the run: min_p, max_p;
   the column's hydrostatic base pressure is 1.
"""
import csv
import glob
import json
import math
import os
import re
import subprocess

H = 0.3            # [m] column height
L_COLUMN = 0.6     # [m]
L_TANK = 1.61      # [m]
TANK_TOP = 1.0     # [m] walls up to here (the run-up along the far wall reaches about 0.6 m)
G = 9.81
RHO = 1000.0
T_STAR_END = 7.0
SENSOR_HEIGHTS = [0.003, 0.015, 0.030, 0.080]  # [m] above the bed
EXP_SENSORS = (0, 2)  # the sensors (indices into SENSOR_HEIGHTS) the experiment's series cover
DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "lobovsky2014", "lobovsky2014_H300_event5.csv")
T_SCALE = math.sqrt(G / H)   # t* = t T_SCALE
P_SCALE = RHO * G * H        # 2943 Pa

SCHEMES = {
    "APIC": {"use_ASFLIP": False},
    "PIC-FLIP 0.95": {"use_ASFLIP": True, "ASFLIP_alpha": 0.95, "ASFLIP_beta_min": 0.0, "ASFLIP_beta_max": 0.0},
    "FLIP": {"use_ASFLIP": True, "ASFLIP_alpha": 1.0, "ASFLIP_beta_min": 0.0, "ASFLIP_beta_max": 0.0},
    "ASFLIP": {"use_ASFLIP": True, "ASFLIP_alpha": 0.9, "ASFLIP_beta_min": 0.0, "ASFLIP_beta_max": 0.2},
}
# Option sets, each adding one treatment to the one before: ClaymoreUW's start (stress-free, no cutoff, no F-bar),
# then fbar's hydrostatic start, the tension cutoff at 0 Pa, and F-bar (psi 0.96, what ClaymoreUW's scenes use).
OPTIONS = {
    "rest": dict(initial_state="rest", tension_cutoff=None, fbar_psi=0.0),
    "hydrostatic": dict(initial_state="hydrostatic", tension_cutoff=None, fbar_psi=0.0),
    "hydrostatic+cutoff": dict(initial_state="hydrostatic", tension_cutoff=0.0, fbar_psi=0.0),
    "hydrostatic+cutoff+F-bar": dict(initial_state="hydrostatic", tension_cutoff=0.0, fbar_psi=0.96),
}


def sweep(gpu):
    """(cells per H, scheme, options) of the study: every option set with APIC, then the other schemes with all
    options, at the finer sizes."""
    cells = [10, 20, 40, 80, 160] if gpu else [10, 20, 40]
    runs = [(n, "APIC", o) for n in cells for o in OPTIONS]
    runs += [(n, s, "hydrostatic+cutoff+F-bar") for n in cells[1:] for s in SCHEMES if s != "APIC"]
    return runs


def geometry(cells):
    dx = H / cells
    x0 = y0 = z0 = 2 * dx
    return dx, x0, y0, z0


def strip(height, dx):
    """The wall strip a simulated sensor at `height` reads: [a, a + 2 dx] with a = max(0, height - dx) [m above the
    bed], and the weight of each node row j (at j dx; row -1 lies below the bed and joins row 0) in it: the fraction
    of the row's strip [j dx - dx/2, j dx + dx/2] (row 0: [0, dx/2]) inside the sensor's."""
    a = max(0.0, height - dx)
    b = a + 2 * dx
    weights = {}
    for j in range(0, int(math.ceil(b / dx)) + 2):
        lo, hi = max(0.0, (j - 0.5) * dx), (j + 0.5) * dx
        overlap = max(0.0, min(hi, b) - max(lo, a))
        if overlap > 0:
            weights[j] = overlap / (hi - lo)
    if 0 in weights:
        weights[-1] = weights[0]
    return a, b, weights


def scene(cells, scheme, options, precision="single"):
    dx, x0, y0, z0 = geometry(cells)
    o = OPTIONS[options]
    c0 = 10 * 2 * math.sqrt(G * H)
    t_end = T_STAR_END / T_SCALE
    x_wall = x0 + L_TANK
    domain = [x_wall + 3 * dx, y0 + TANK_TOP + 2 * dx, z0 + 3 * dx]
    material = {"constitutive": "JFluid", "rho": RHO, "bulk_modulus": RHO * c0 * c0, "gamma": 7, "viscosity": 1e-3,
                "ppc": 8, "CFL": 0.5}
    if o["tension_cutoff"] is not None:
        material["tension_cutoff"] = o["tension_cutoff"]
    algorithm = dict(SCHEMES[scheme], use_FBAR=o["fbar_psi"] > 0, FBAR_psi=o["fbar_psi"])
    rows = sorted({j for h in SENSOR_HEIGHTS for j in strip(h, dx)[2]})
    if len(rows) > 16:
        raise ValueError(f"{len(rows)} node rows: more than the 16 grid sensors a run has")
    # Node rows the sensors read: one grid sensor per row, a box 1.5 dx deep in front of the far Walls face (the
    # nodes that face acts on), one cell high around the row, the whole slab across.
    grid = [{"attribute": "Force", "operation": "Sum", "direction": [1, 0, 0], "output_frequency": 50 * cells,
             "domain_start": [x_wall - 0.5 * dx, y0 + (j - 0.45) * dx, 0],
             "domain_end": [x_wall + dx, y0 + (j + 0.45) * dx, domain[2]]} for j in rows]
    particles = [{"attribute": "Pressure", "operation": op, "output_frequency": 200.0,
                  "domain_start": [0, 0, 0], "domain_end": domain} for op in ("Min", "Max")]
    body = {"material": material, "algorithm": algorithm, "initial_state": o["initial_state"],
            "geometry": [{"object": "Box", "span": [L_COLUMN, H, dx], "offset": [x0, y0, z0]}],
            "output_attribs": ["ID"]}
    s = {"simulation": {"domain": domain, "default_dx": dx, "gravity": [0, -G, 0], "fps": 1 / t_end, "frames": 1,
                        "precision": precision, "save_suffix": ".csv"},
         "bodies": [body],
         # The walls one cell outside the tank's faces (the bed and the far wall act on the node planes y0 and
         # x_wall, as the Martin & Moyce study places them); the slab between z0 and z0 + dx.
         "boundaries": [{"object": "Walls", "contact": "Separable", "domain_start": [x0 - dx, y0 - dx, z0 - dx],
                         "domain_end": [x_wall + dx, domain[1], z0 + 2 * dx]}],
         "grid-sensors": grid, "particle-sensors": particles}
    return s, rows, t_end


def read_series(path):
    with open(path) as f:
        rows = list(csv.reader(f))[1:]
    return [float(r[0]) for r in rows], [float(r[1]) for r in rows]


def smooth(t, y, width):
    """Centred moving average over `width` (same units as t), on the samples' own times."""
    out = []
    j0 = j1 = 0
    acc = 0.0
    for i, ti in enumerate(t):
        while j1 < len(t) and t[j1] <= ti + 0.5 * width:
            acc += y[j1]
            j1 += 1
        while t[j0] < ti - 0.5 * width:
            acc -= y[j0]
            j0 += 1
        out.append(acc / (j1 - j0))
    return out


def interp(t, y, x):
    if x <= t[0]:
        return y[0]
    for i in range(1, len(t)):
        if t[i] >= x:
            w = (x - t[i - 1]) / (t[i] - t[i - 1])
            return y[i - 1] + w * (y[i] - y[i - 1])
    return y[-1]


def resample(t, y, grid):
    """y(t) (t increasing) linearly interpolated at the increasing times `grid`."""
    out, i = [], 1
    for x in grid:
        while i < len(t) - 1 and t[i] < x:
            i += 1
        if x <= t[0]:
            out.append(y[0])
        elif x >= t[-1]:
            out.append(y[-1])
        else:
            w = (x - t[i - 1]) / (t[i] - t[i - 1])
            out.append(y[i - 1] + w * (y[i] - y[i - 1]))
    return out


def experiment():
    """t* and p / (rho g H) of the measured sensors (data/lobovsky2014): {sensor index: series}."""
    with open(DATA) as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")][1:]
    t = [float(r[0]) for r in rows]
    return t, {k: [float(r[1 + i]) for r in rows] for i, k in enumerate(EXP_SENSORS)}


def first_above(t, y, level):
    for i in range(1, len(t)):
        if y[i] >= level:
            return t[i - 1] + (level - y[i - 1]) / (y[i] - y[i - 1]) * (t[i] - t[i - 1])
    return None


def measure(t, sim, exp_t, exp):
    """The error measures of one run: t (t*), sim and exp the four simulated sensors, exp the measured ones."""
    ts = [2.0 + 0.01 * k for k in range(501)]  # t* in [2, 7]
    diffs = []
    for k in EXP_SENSORS:
        a = smooth(t, sim[k], 0.1)
        b = smooth(exp_t, exp[k], 0.1)
        diffs += [(interp(t, a, x) - interp(exp_t, b, x)) ** 2 for x in ts]
    rms = math.sqrt(sum(diffs) / len(diffs))
    t_sim, t_exp = first_above(t, sim[0], 0.5), first_above(exp_t, exp[0], 0.5)
    plateau = []
    for k in EXP_SENSORS:
        ms = [y for x, y in zip(t, sim[k]) if 3.0 <= x <= 5.5]
        me = [y for x, y in zip(exp_t, exp[k]) if 3.0 <= x <= 5.5]
        plateau.append(abs(sum(ms) / len(ms) - sum(me) / len(me)))
    return dict(rms=rms, impact_dt=abs(t_sim - t_exp) if t_sim is not None else float("nan"),
                impact_t=t_sim if t_sim is not None else float("nan"), plateau_error=sum(plateau) / len(plateau))


def run(fbar, backend, cells, scheme, options, work, precision="single"):
    s, rows, t_end = scene(cells, scheme, options, precision)
    label = f"wp_{backend}_{cells}_{scheme.replace(' ', '')}_{options}_{precision}"
    out = os.path.join(work, label)
    os.makedirs(out, exist_ok=True)
    for old in glob.glob(os.path.join(out, "*.csv")):
        os.remove(old)
    path = os.path.join(out, "scene.json")
    with open(path, "w") as f:
        json.dump(s, f, indent=1)
    p = subprocess.run([fbar, f"--backend={backend}", f"--output={out}", path], capture_output=True, text=True)
    row = dict(backend=backend, cells_per_h=cells, scheme=scheme, options=options, precision=precision)
    if p.returncode != 0:
        row.update(status="failed", message=(p.stderr.strip().splitlines() or [""])[-1])
        return row, None
    with open(os.path.join(out, "run.json")) as f:
        meta = json.load(f)
    setup = re.search(r"set-up ([0-9.eE+-]+) s", p.stdout + p.stderr)
    simulate_s = meta["wall_time_s"] - (float(setup.group(1)) if setup else 0.0)
    dx, x0, y0, z0 = geometry(cells)
    force = {}
    for i, j in enumerate(rows):
        t, f = read_series(os.path.join(out, f"gridTarget[{i}]_dev[0].csv"))
        force[j] = f
    t = [x * T_SCALE for x in t]
    sim = []
    for h in SENSOR_HEIGHTS:
        a, b, weights = strip(h, dx)
        area = (b - a) * dx  # the strip's height x the slab's thickness dx
        sim.append([sum(w * force[j][i] for j, w in weights.items()) / area / P_SCALE for i in range(len(t))])
    tp, pmin = read_series(os.path.join(out, "particleTarget[0]_model[0]_dev[0].csv"))
    _, pmax = read_series(os.path.join(out, "particleTarget[1]_model[0]_dev[0].csv"))
    tp = [x * T_SCALE for x in tp]
    before = [i for i, x in enumerate(tp) if x < 2.0]
    t_imp = first_above(t, sim[0], 0.5)
    peak = max((y for x, y in zip(t, sim[0]) if t_imp is not None and x <= t_imp + 0.5), default=float("nan"))
    row.update(status="ok", message="", wall_s=f"{meta['wall_time_s']:.3f}", steps=meta["steps"],
               particles=int(round(2 * cells * cells * 8)), s_per_simulated_s=f"{simulate_s / t_end:.4f}",
               peak=f"{peak:.4f}", min_p_before=f"{min(pmin[i] for i in before) / P_SCALE:.4f}",
               max_p_before=f"{max(pmax[i] for i in before) / P_SCALE:.4f}",
               min_p=f"{min(pmin) / P_SCALE:.4f}", max_p=f"{max(pmax) / P_SCALE:.4f}")
    # The histories kept for scoring and charts: smoothed over 0.02 t*, on a grid of 0.01 t*.
    grid = [round(0.01 * k, 2) for k in range(int(T_STAR_END / 0.01) + 1)]
    kept = [resample(t, smooth(t, sim[k], 0.02), grid) for k in range(4)]
    return row, (grid, kept)


def score(rows, series):
    """The measures against the experiment (rms, impact_dt, plateau_error) of every row with a history."""
    exp_t, exp = experiment()
    for r in rows:
        key = label_of(r)
        if r["status"] != "ok" or key not in series:
            continue
        t, sim = series[key]
        m = measure(t, sim, exp_t, exp)
        r.update(rms=f"{m['rms']:.5f}", impact_dt=f"{m['impact_dt']:.4f}", impact_t=f"{m['impact_t']:.4f}",
                 plateau_error=f"{m['plateau_error']:.5f}")


FIELDS = ["backend", "cells_per_h", "scheme", "options", "precision", "status", "rms", "impact_dt", "impact_t",
          "plateau_error", "peak", "min_p_before", "max_p_before", "min_p", "max_p", "wall_s", "s_per_simulated_s",
          "steps", "particles", "message"]


def write_series(path, series):
    """The simulated sensor histories of every run (smoothed over 0.02 t*, every 0.01 t*): one row per t*, one
    column per run and sensor ("<run> | sensor <k>"). --replot scores and draws from them."""
    labels = list(series)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_star"] + [f"{label} | sensor {k + 1}" for label in labels for k in range(4)])
        grid = series[labels[0]][0] if labels else []
        for i, x in enumerate(grid):
            w.writerow([f"{x:.2f}"] + [f"{series[label][1][k][i]:.4f}" for label in labels for k in range(4)])


def read_series_file(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    t = [float(r[0]) for r in body]
    series = {}
    for c, name in enumerate(head[1:], start=1):
        label, sensor = name.rsplit(" | sensor ", 1)
        series.setdefault(label, (t, [None] * 4))[1][int(sensor) - 1] = [float(r[c]) for r in body]
    return series


def label_of(r):
    return f"{r['scheme']}, {r['options']}, H/dx {int(r['cells_per_h'])}"


def charts(rows, series, out, title_backend, suffix, draw_pareto, save):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r["status"] == "ok"]
    for r in ok:
        r["cells_per_h"] = int(r["cells_per_h"])
    # Error against cost, the Pareto front labelled.
    pts = [(float(r["s_per_simulated_s"]), float(r["rms"])) for r in ok]
    colors = {o: c for o, c in zip(OPTIONS, ["C0", "C1", "C2", "C3"])}
    markers = {"APIC": "o", "PIC-FLIP 0.95": "s", "FLIP": "^", "ASFLIP": "D"}
    fig, ax = plt.subplots(figsize=(8.5, 5.5))
    draw_pareto(ax, ok, pts, lambda r: (r["options"], r["scheme"], 12 + 0.6 * r["cells_per_h"]),
                lambda r: f"{r['scheme']}, {r['options']}, {r['cells_per_h']}", colors, markers, fontsize=6.5)
    ax.set_xlabel(f"wall time per simulated second [s] ({title_backend})")
    ax.set_ylabel("RMS of p / (rho g H) against Lobovsky et al. 2014, sensors 1 and 3, t* 2-7")
    ax.set_title("Dam break wall pressure: error against cost (marker size: H/dx)")
    ax.legend(fontsize=7)
    save(fig, out, f"wall_pressure_pareto{suffix}.png")

    # Convergence per option set (APIC).
    fig, ax = plt.subplots(figsize=(7, 5))
    for o in OPTIONS:
        rs = sorted((r for r in ok if r["scheme"] == "APIC" and r["options"] == o), key=lambda r: r["cells_per_h"])
        if len(rs) < 2:
            continue
        n = [r["cells_per_h"] for r in rs]
        e = [float(r["rms"]) for r in rs]
        ax.plot(n, e, marker="o", color=colors[o], label=f"APIC, {o}")
    for s in SCHEMES:
        if s == "APIC":
            continue
        rs = sorted((r for r in ok if r["scheme"] == s), key=lambda r: r["cells_per_h"])
        if len(rs) >= 2:
            ax.plot([r["cells_per_h"] for r in rs], [float(r["rms"]) for r in rs], ":", marker=markers[s],
                    color="gray", label=f"{s}, all options")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("cells per column height H/dx")
    ax.set_ylabel("RMS of p / (rho g H) against the experiment")
    ax.set_title("Dam break wall pressure: error against resolution")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    save(fig, out, f"wall_pressure_convergence{suffix}.png")

    # Time histories at the finest size: the four option sets (APIC) against the experiment.
    finest = max(r["cells_per_h"] for r in ok)
    exp_t, exp = experiment()
    fig, axes = plt.subplots(4, 1, figsize=(8, 10), sharex=True)
    for k, ax in enumerate(axes):
        if k in exp:
            ax.plot(exp_t, exp[k], color="0.6", lw=0.6, label="Lobovsky et al. 2014 (one repetition)")
        for o in OPTIONS:
            key = f"APIC, {o}, H/dx {finest}"
            if key in series:
                t, sim = series[key]
                ax.plot(t, sim[k], color=colors[o], lw=0.9, label=o)
        ax.set_ylabel(f"sensor {k + 1}: p / rho g H")
        ax.set_xlim(1.5, 7)
        ax.grid(True, alpha=0.3)
        ax.text(0.01, 0.9, f"{1000 * SENSOR_HEIGHTS[k]:g} mm above the bed", transform=ax.transAxes, fontsize=8)
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel("t (g / H)^1/2")
    fig.suptitle(f"Far-wall pressure, APIC, H/dx {finest} ({title_backend}), smoothed over 0.02 t*")
    save(fig, out, f"wall_pressure_history{suffix}.png")

    # The particle pressure range before the impact, per option set (the noise the options remove).
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for o in OPTIONS:
        rs = sorted((r for r in ok if r["scheme"] == "APIC" and r["options"] == o), key=lambda r: r["cells_per_h"])
        if not rs:
            continue
        n = [r["cells_per_h"] for r in rs]
        ax.plot(n, [float(r["max_p_before"]) for r in rs], "-", marker="o", color=colors[o], label=f"{o}: max")
        ax.plot(n, [float(r["min_p_before"]) for r in rs], "--", marker="v", color=colors[o], label=f"{o}: min")
    ax.axhline(1.0, color="k", lw=0.6)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xscale("log")
    ax.set_xlabel("cells per column height H/dx")
    ax.set_ylabel("particle pressure / (rho g H), t* < 2")
    ax.set_title("Particle pressure range before the impact (hydrostatic base: 1)")
    ax.legend(fontsize=6.5, ncol=2)
    ax.grid(True, alpha=0.3)
    save(fig, out, f"wall_pressure_noise{suffix}.png")


def study(a, draw_pareto, save):
    backend = "gpu" if a.gpu else "cpu"
    suffix = "_gpu" if a.gpu else ""
    csv_path = os.path.join(a.out, f"wall_pressure_study{suffix}.csv")
    series_path = os.path.join(a.out, f"wall_pressure_series{suffix}.csv")
    if a.replot:
        with open(csv_path) as f:
            rows = list(csv.DictReader(f))
        series = read_series_file(series_path)
        score(rows, series)
        write_rows(csv_path, rows)
        charts(rows, series, a.out, f"{rows[0]['backend']} engine", suffix, draw_pareto, save)
        return 0
    os.makedirs(a.out, exist_ok=True)
    runs = sweep(a.gpu)
    if a.cells:
        runs = [r for r in runs if r[0] in [int(c) for c in a.cells]]
    rows, series = [], {}
    for cells, scheme, options in runs:
        r, hist = run(a.fbar, backend, cells, scheme, options, a.work)
        rows.append(r)
        if hist:
            series[label_of(r)] = hist
        print(f"{backend} H/dx {cells:4d} {scheme:14s} {options:26s} {r['status']:6s} peak {r.get('peak', ''):>7s} "
              f"p before [{r.get('min_p_before', '')}, {r.get('max_p_before', '')}] p [{r.get('min_p', '')}, "
              f"{r.get('max_p', '')}] wall {r.get('wall_s', '')} s {r.get('message', '')}", flush=True)
        write_rows(csv_path, rows)  # after every run: a cut-off sweep keeps its rows
        write_series(series_path, series)
    if not os.path.exists(DATA):  # the scores need the experiment's series
        print(f"{DATA} not found: rows and histories written, scores and charts left to --replot")
        return 0
    score(rows, series)
    write_rows(csv_path, rows)
    charts(rows, series, a.out, f"{backend} engine", suffix, draw_pareto, save)
    return 0


def write_rows(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for done in rows:
            w.writerow({k: done.get(k, "") for k in FIELDS})
