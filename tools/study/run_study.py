#!/usr/bin/env python3
"""Accuracy against cost: sweeps fbar over a reference problem and charts error against time.

Problem (this first version): Martin & Moyce's dam break (1952), as the validation test
tests/validation/test_dam_break.cpp sets it up: a water column of width a = 0.05715 m and height 2a on a dry bed,
a slab one cell thick between slip walls (2D flow), JFluid with c0 = 10 x Ritter's front speed. Every run is a
scene file given to the fbar command line; a particle sensor (Max of Position_X, 200 samples) records the surge
front Z = front / a against T = t sqrt(2 g / a). Martin & Moyce's data bound the front from below (bed friction and
the gate delay the experiment; the simulated flow has neither) and Ritter's ideal front (dZ/dT = 2) from above, so
the experiment is not a converged answer. The error is therefore measured against the sweep's finest APIC run in
double precision: the mean |T - T_ref| at which the front reaches Martin & Moyce's gauges Z = 1.22 .. 4.11 (a
gauge not reached by T = 4.2 counts as reached then); the CSV
also has each run's mean |Z - Z_exp| / Z_exp and how many gauges it reaches between Ritter and the data. Cost: the
run's wall time (run.json) per simulated second.

Sweep: resolution (cells per a), transfer scheme (APIC, PIC-FLIP 0.95, FLIP, ASFLIP), precision (single, double).
The default is the CPU engine at small sizes (seconds per run); --gpu runs the GPU engine and larger sizes.

Writes, under --out (default docs/validation): dam_break_study.csv (one row per run), dam_break_pareto.png (error
against cost, the Pareto front marked and labelled) and dam_break_convergence.png (error against resolution per
scheme, with the observed order between the two finest pairs in the legend); with --gpu the same names ending in
_gpu. Cost: the run's wall time less the engine's set-up (which the GPU engine prints), per simulated second.

--problem bar: Bardenhagen's vibrating bar (tests/validation/vibrating_bar_case.h), a clamped
bar of L = 25 m started in its first mode; exact period T1 = 10 s. A scene file cannot start a bar in a mode, so
these runs go through fbar_study_cases (tools/study/study_cases.cu), which runs the validation case itself on either
engine. Error: |T / T1 - 1| of the period from the centre-of-mass velocity's zero crossings (2.6 periods); the CSV
also has the amplitude lost per period and the largest energy over the run. Sweep: L/dx 12.5 .. 200 (--gpu: up to
400), the four schemes, single and double (and mixed on the CPU engine). Writes vibrating_bar_study{,_gpu}.csv,
vibrating_bar_pareto{,_gpu}.png and vibrating_bar_convergence{,_gpu}.png.

--problem hydrostatic: the cb-geo hydrostatic column (tests/validation/hydrostatic_column_case.h)
from a stress-free start, through fbar_study_cases too. Error: the RMS over particle rows of the time-averaged
pressure error over rho0 g H; the CSV also has the base pressure error of the middle-half fit, the row
checkerboard and the bottom cell's error. Sweep: H/dx 5 .. 40 (--gpu: up to 80), F-bar off and on (psi 1), single,
double (and mixed on the CPU engine). Writes hydrostatic_study{,_gpu}.csv and the two charts.

--problem granular: the granular column collapse of tests/validation/granular_collapse_case.h (DruckerPrager sand,
a = 0.5, Sticky floor) to rest at 3 s. The CSV's runout_error_vs_lube is |runout / 0.6 - 1| against Lube et al.'s mean (their band is +-20 %);
the CSV also has the runout, H_inf / H0 and the kinetic energy left. The charts measure the runout against the sweep's
finest APIC double run instead (the experiment's mean is not a converged answer: the runs cross it). Sweep: H0/dx 5, 10 (--gpu: 5 .. 40), the four
schemes, the precisions as above.

--problem disks: the two elastic disks of tests/validation/two_disks_case.h (Sulsky et al. 1994) to 4.5 s. Error: the
energy lost (the continuum impact is elastic, so a converged run loses none); the CSV also has the largest energy
over E0, the restitution and the momentum drift. Sweep: R/dx 4, 8, 16 (--gpu: to 32), the four schemes.

--problem wall_pressure: the pressure on the far wall of a dam break against Lobovsky et al. (2014), with fbar's
hydrostatic start, tension cutoff and F-bar against ClaymoreUW's stress-free start (tools/study/wall_pressure.py says
how it is measured). Writes wall_pressure_study{,_gpu}.csv, wall_pressure_series{,_gpu}.csv (the finest size's
sensor histories) and the charts wall_pressure_{pareto,convergence,history,noise}{,_gpu}.png.

--problem stability: the code-built stability maps of tests/validation/stability_case.h (fbar_study_cases
--problem=stability runs them all): the CFL number and the stiffness against the scheme
(a splash with lone particles), Poisson's ratio against scheme and F-bar (a bouncing block); each run stable,
detected (fbar stopped it with a report) or silent (completed, yet its energy grew or became non-finite). CPU:
double precision; --gpu: single. Writes stability_maps{,_gpu}.csv and stability_{cfl,stiffness,poisson}{,_gpu}.png.

--problem translation: a block of water in rigid translation (tools/study/translation.py): every error is round-off,
so it charts what single, mixed and double precision deliver and cost. Writes translation_study{,_gpu}.csv,
translation_pareto{,_gpu}.png and translation_precision{,_gpu}.png.

--problem dam_break_ppc: the dam break over particles per cell (1, 8, 27) and resolution (APIC, single), against the
dam break study's reference. Writes dam_break_ppc_study{,_gpu}.csv and dam_break_ppc_pareto{,_gpu}.png.

--problem all: every problem above in turn (and the dam break's stability map): the one command that regenerates
every chart (python3 tools/study/run_study.py --problem all --gpu on a GPU machine; without --gpu, the CPU charts).

usage: run_study.py [--problem dam_break|dam_break_ppc|bar|hydrostatic|granular|disks|wall_pressure|stability|translation|all] [--fbar build/release/fbar] [--gpu] [--out docs/validation]
                    [--work /tmp/fbar_study]
"""
import argparse
import csv
import glob
import json
import math
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

A = 0.05715  # [m] column width
G = 9.81
T_END = 4.2  # [-] t sqrt(2 g / a): past the last gauge's time (3.33), so that coarse, slower fronts reach it too
FRONT_T = [0.41, 0.84, 1.19, 1.43, 1.63, 1.83, 1.98, 2.20, 2.32, 2.51, 2.65, 2.83, 2.98, 3.11, 3.33]
FRONT_Z = [1.11, 1.22, 1.44, 1.67, 1.89, 2.11, 2.33, 2.56, 2.78, 3.00, 3.22, 3.44, 3.67, 3.89, 4.11]
SCHEMES = {  # name: algorithm keys
    "APIC": {"use_ASFLIP": False},
    "PIC-FLIP 0.95": {"use_ASFLIP": True, "ASFLIP_alpha": 0.95, "ASFLIP_beta_min": 0.0, "ASFLIP_beta_max": 0.0},
    "FLIP": {"use_ASFLIP": True, "ASFLIP_alpha": 1.0, "ASFLIP_beta_min": 0.0, "ASFLIP_beta_max": 0.0},
    "ASFLIP": {"use_ASFLIP": True, "ASFLIP_alpha": 0.9, "ASFLIP_beta_min": 0.0, "ASFLIP_beta_max": 0.2},
}


def scene(cells, scheme, precision, cfl=0.5, ppc=8):
    dx = A / cells
    x0 = y0 = z0 = 2 * dx  # the walls one cell outside the column's faces, on node planes
    c0 = 10 * 2 * math.sqrt(G * 2 * A)
    domain = [x0 + 6 * A + 2 * dx, y0 + 2 * A + 4 * dx, z0 + 3 * dx]
    t_end = T_END / math.sqrt(2 * G / A)
    algorithm = dict(SCHEMES[scheme], use_FBAR=False)
    return {
        "simulation": {"domain": domain, "default_dx": dx, "gravity": [0, -G, 0], "fps": 1 / t_end, "frames": 1,
                       "precision": precision, "save_suffix": ".csv"},
        "bodies": [{"material": {"constitutive": "JFluid", "rho": 1000, "bulk_modulus": 1000 * c0 * c0, "gamma": 7,
                                 "viscosity": 1e-3, "ppc": ppc, "CFL": cfl},
                    "algorithm": algorithm,
                    "geometry": [{"object": "Box", "span": [A, 2 * A, dx], "offset": [x0, y0, z0]}],
                    "output_attribs": ["ID"]}],
        "boundaries": [{"object": "Walls", "contact": "Slip", "domain_start": [x0 - dx, y0 - dx, z0 - dx],
                        "domain_end": [x0 + 6 * A + dx, domain[1], z0 + 2 * dx]}],
        "particle-sensors": [{"attribute": "Position_X", "operation": "Max", "output_frequency": 200 / t_end,
                              "domain_start": [0, 0, 0], "domain_end": domain}],
    }, x0, t_end


def interpolate(xs, ys, x):
    for i in range(1, len(xs)):
        if xs[i] >= x:
            w = (x - xs[i - 1]) / (xs[i] - xs[i - 1])
            return ys[i - 1] + w * (ys[i] - ys[i - 1])
    return ys[-1]


def first_reach(T, Z, z):
    """The first T at which Z reaches z (linear between samples), or None."""
    for i in range(1, len(Z)):
        if Z[i] >= z:
            if Z[i] == Z[i - 1]:
                return T[i]
            return T[i - 1] + (z - Z[i - 1]) / (Z[i] - Z[i - 1]) * (T[i] - T[i - 1])
    return None


def run(fbar, backend, cells, scheme, precision, work, cfl=0.5, ppc=8):
    s, x0, t_end = scene(cells, scheme, precision, cfl, ppc)
    label = f"{backend}_{cells}_{scheme.replace(' ', '')}_{precision}_{cfl}" + (f"_ppc{ppc}" if ppc != 8 else "")
    per_axis = round(ppc ** (1.0 / 3.0))  # particles along an axis of a cell (1, 2, 3 for ppc 1, 8, 27)
    out = os.path.join(work, label)
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, "scene.json")
    with open(path, "w") as f:
        json.dump(s, f)
    p = subprocess.run([fbar, f"--backend={backend}", f"--output={out}", path], capture_output=True, text=True)
    row = {"backend": backend, "cells_per_a": cells, "scheme": scheme, "precision": precision, "cfl": cfl,
           "ppc": ppc}
    if p.returncode != 0:
        row.update(status="failed", error_vs_experiment="", gauges_within_bounds="", wall_s="", steps="",
                   particles="", s_per_simulated_s="", message=(p.stderr.strip().splitlines() or [""])[-1], arrivals=None)
        return row
    with open(os.path.join(out, "run.json")) as f:
        meta = json.load(f)
    # The engine's set-up (sampling, device start) is not simulation: the GPU engine prints it.
    setup = re.search(r"set-up ([0-9.eE+-]+) s", p.stdout + p.stderr)
    simulate_s = meta["wall_time_s"] - (float(setup.group(1)) if setup else 0.0)
    sensor = glob.glob(os.path.join(out, "particleTarget[[]0[]]_model[[]0[]]_dev[[]0[]].csv"))[0]
    T, Z = [], []
    with open(sensor) as f:
        rows = list(csv.reader(f))[1:]
    for t, x in rows:
        T.append(float(t) * math.sqrt(2 * G / A))
        Z.append((float(x) + 0.5 * A / cells / per_axis - x0) / A)  # the front particle's edge (half a spacing)
    err = sum(abs(interpolate(T, Z, te) - ze) / ze for te, ze in zip(FRONT_T, FRONT_Z)) / len(FRONT_T)
    arrivals = [first_reach(T, Z, z) for z in FRONT_Z[1:]]
    within = sum(1 for t, te, z in zip(arrivals, FRONT_T[1:], FRONT_Z[1:]) if t is not None and (z - 1) / 2 <= t <= te)
    # Physically impossible: a front ahead of Ritter's ideal dam break (Z <= 1 + 2 T) by more than a cell, or a
    # non-finite position. A run that completes with one of these failed silently.
    row["impossible"] = "yes" if any(not math.isfinite(z) or z > 1 + 2 * t + 1.0 / cells for t, z in zip(T, Z)) else ""
    particles = int(round(cells * 2 * cells * per_axis ** 3))  # a slab one cell thick
    row.update(status="ok", error_vs_experiment=f"{err:.5f}", gauges_within_bounds=f"{within}/{len(arrivals)}",
               wall_s=f"{meta['wall_time_s']:.4f}", steps=meta["steps"], particles=particles,
               s_per_simulated_s=f"{simulate_s / t_end:.4f}", message="", arrivals=arrivals)
    return row


def against_reference(rows):
    """error = mean |T - T_ref| over the gauges, against the finest APIC double run (marked reference)."""
    ok = [r for r in rows if r["status"] == "ok"]
    ref = max((r for r in ok if r["scheme"] == "APIC" and r["precision"] == "double"), key=lambda r: r["cells_per_a"])
    for r in rows:
        r["reference"] = "yes" if r is ref else ""
        if r["status"] != "ok":
            r["error"] = ""
            continue
        # A gauge the front never reached counts as reached at the run's end (T_END): a lower bound on its error.
        reached = lambda t: T_END if t is None else t  # noqa: E731
        diffs = [abs(reached(t) - reached(tr)) for t, tr in zip(r["arrivals"], ref["arrivals"])]
        r["error"] = f"{sum(diffs) / len(diffs):.5f}"
    return ref


def pareto(points):
    """Indices of the points no other point beats in both cost and error."""
    front = []
    for i, (c, e) in enumerate(points):
        if not any((c2 <= c and e2 <= e) and (c2 < c or e2 < e) for j, (c2, e2) in enumerate(points) if j != i):
            front.append(i)
    return sorted(front, key=lambda i: points[i][0])


def draw_pareto(ax, rows, pts, style, label, colors, markers, fontsize=7, label_close=True):
    """Error against cost on log axes: each row's point (pts, as (cost, error)) drawn as style(row) = (colour key,
    marker key, marker size), the Pareto front dashed with its points labelled label(row) (label_close=False: a
    front point within 5 % in error of the last one labelled is left unlabelled), and one legend entry for each
    colour and marker key used."""
    front = pareto(pts)
    used_colors, used_markers = set(), set()
    for r, p in zip(rows, pts):
        c, m, size = style(r)
        used_colors.add(c)
        used_markers.add(m)
        ax.scatter(p[0], p[1], marker=markers[m], color=colors[c], s=size)
    ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "k--", lw=1, label="Pareto front")
    labelled = None
    for i in front:
        if not label_close and labelled is not None and abs(pts[i][1] / pts[labelled][1] - 1) < 0.05:
            continue
        labelled = i
        ax.annotate(label(rows[i]), pts[i], xytext=(4, 4), textcoords="offset points", fontsize=fontsize)
    for c, color in colors.items():
        if c in used_colors:
            ax.scatter([], [], color=color, label=c)
    for m, marker in markers.items():
        if m in used_markers:
            ax.scatter([], [], marker=marker, color="gray", label=m)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)


def save(fig, out, name):
    """Writes a finished chart as out/name (PNG) and frees it."""
    import matplotlib.pyplot as plt
    fig.tight_layout()
    fig.savefig(os.path.join(out, name), dpi=110)
    plt.close(fig)


def charts(rows, out, title_backend, suffix=""):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = next(r for r in rows if r["reference"])
    error_label = f"mean |T - T_ref| at the gauges (ref: APIC, double, {ref['cells_per_a']}/a)"
    # The reference's own configuration in the other precision differs from it by round-off only: left out.
    ok = [r for r in rows if r["status"] == "ok" and r["error"] and not r["reference"] and
          not (r["scheme"] == ref["scheme"] and int(r["cells_per_a"]) == int(ref["cells_per_a"]))]
    for r in ok:
        r["cells_per_a"] = int(r["cells_per_a"])
    pts = [(float(r["s_per_simulated_s"]), float(r["error"])) for r in ok]
    fig, ax = plt.subplots(figsize=(8, 5.5))
    markers = {"single": "o", "double": "s"}
    colors = {name: c for name, c in zip(SCHEMES, ["C0", "C1", "C2", "C3"])}
    draw_pareto(ax, ok, pts, lambda r: (r["scheme"], r["precision"], 18 + 3 * r["cells_per_a"]),
                lambda r: f"{r['scheme']}, {r['cells_per_a']}/a, {r['precision']}", colors, markers)
    ax.set_xlabel(f"wall time per simulated second [s] ({title_backend})")
    ax.set_ylabel(error_label)
    ax.set_title("Dam break front: error against cost (marker size: cells per a)")
    ax.legend(fontsize=8)
    save(fig, out, f"dam_break_pareto{suffix}.png")

    fig, ax = plt.subplots(figsize=(7, 5))
    for name in SCHEMES:
        for prec, style in (("double", "-"), ("single", ":")):
            rs = sorted((r for r in ok if r["scheme"] == name and r["precision"] == prec), key=lambda r: r["cells_per_a"])
            if name == ref["scheme"]:  # its finest point is the reference: the order uses the two finest others
                rs = [r for r in rs if r["cells_per_a"] < int(ref["cells_per_a"])]
            if len(rs) < 2:
                continue
            n = [r["cells_per_a"] for r in rs]
            e = [float(r["error"]) for r in rs]
            order = ""
            if len(rs) >= 3 and e[-1] > 0 and e[-2] > 0:
                order = f", order {math.log(e[-2] / e[-1]) / math.log(n[-1] / n[-2]):.2f}"
            ax.plot(n, e, style, marker="o", color=colors[name], label=f"{name} ({prec}{order})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("cells per column width a")
    ax.set_ylabel(error_label)
    ax.set_title("Dam break front: error against resolution (order between the two finest)")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    save(fig, out, f"dam_break_convergence{suffix}.png")


def stability(fbar, backend, work, out, suffix):
    """Stability map: the CFL number (fbar keeps every step within CFL x dx / (c + |v|) of the fastest particle and
    grid node, and a scene cannot ask for more than 1) against the scheme, at a/dx = 8: each run is stable, a
    failure fbar detected and reported (exit 2 with its message), or a silent failure (completed, physically
    impossible)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cells = 8
    factors = [0.2, 0.4, 0.6, 0.8, 0.9, 1.0]
    rows = []
    for scheme in SCHEMES:
        for k in factors:
            r = run(fbar, backend, cells, scheme, "double", work, cfl=k)
            state = ("detected" if r["status"] == "failed" else "silent" if r.get("impossible") else "stable")
            r["state"] = state

            rows.append(r)
            print(f"stability {scheme:14s} CFL {k:.1f}: {state} {r['message']}", flush=True)
    fields = ["scheme", "cfl", "state", "message"]
    with open(os.path.join(out, f"dam_break_stability{suffix}.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in fields})
    colors = {"stable": "#4caf50", "detected": "#ff9800", "silent": "#d32f2f"}
    fig, ax = plt.subplots(figsize=(7, 3.6))
    for i, scheme in enumerate(SCHEMES):
        for j, k in enumerate(factors):
            st = next(r["state"] for r in rows if r["scheme"] == scheme and r["cfl"] == k)
            ax.add_patch(plt.Rectangle((j, i), 0.95, 0.95, color=colors[st]))
            ax.text(j + 0.47, i + 0.47, st, ha="center", va="center", fontsize=7)
    ax.set_xlim(0, len(factors))
    ax.set_ylim(0, len(SCHEMES))
    ax.set_xticks([j + 0.47 for j in range(len(factors))], [f"{k:g}" for k in factors])
    ax.set_yticks([i + 0.47 for i in range(len(SCHEMES))], list(SCHEMES))
    ax.set_xlabel("CFL number")
    ax.set_title(f"Dam break, a/dx = {cells}, double, {backend} engine: stable / detected / silent")
    save(fig, out, f"dam_break_stability{suffix}.png")


CASE_SCHEMES = ["APIC", "PIC-FLIP", "FLIP", "ASFLIP"]
# The problems run through fbar_study_cases: how each is swept, measured and drawn.
CASES = {
    "bar": dict(
        name="Vibrating bar", prefix="vibrating_bar", group="scheme", groups=CASE_SCHEMES, group_label=lambda g: g,
        error="period_error", error_label="period error |T / T1 - 1| (exact T1 = 10 s)", res="L/dx",
        res_label="cells per bar length L/dx", cells=[12.5, 25, 50, 100, 200], gpu_cells=[12.5, 25, 50, 100, 200, 400],
        args=lambda g: [f"--scheme={g}"],
        fields=["period", "period_error", "amplitude_loss_per_period", "energy_max_over_e0", "tip_amplitude_error"]),
    "hydrostatic": dict(
        name="Hydrostatic column", prefix="hydrostatic", group="fbar", groups=["0", "1"],
        group_label=lambda g: "F-bar" if float(g) else "no F-bar",
        error="profile_rms", error_label="pressure profile error, RMS over rows / (rho0 g H)", res="H/dx",
        res_label="cells per column height H/dx", cells=[5, 10, 20, 40], gpu_cells=[5, 10, 20, 40, 80],
        args=lambda g: [f"--fbar={g}"],
        fields=["profile_rms", "base_error", "checkerboard", "bottom_cell_error"]),
    "granular": dict(
        name="Granular collapse", prefix="granular_collapse", group="scheme", groups=CASE_SCHEMES,
        group_label=lambda g: g, error="runout_error", reference=("APIC", "runout"),
        error_label="runout error |r / r_ref - 1| (ref: the finest APIC double run)", res="H0/dx",
        res_label="cells per column height H0/dx", cells=[5, 10], gpu_cells=[5, 10, 20, 40],
        args=lambda g: [f"--scheme={g}"],
        fields=["runout", "runout_error_vs_lube", "height_ratio", "kinetic_over_released"]),
    "disks": dict(
        name="Two-disk impact", prefix="two_disks", group="scheme", groups=CASE_SCHEMES, group_label=lambda g: g,
        error="energy_lost", error_label="energy lost by t = 4.5 s / E0 (the continuum impact is elastic)",
        res="R/dx", res_label="cells per disk radius R/dx", cells=[4, 8, 16], gpu_cells=[4, 8, 16, 32],
        args=lambda g: [f"--scheme={g}"],
        fields=["energy_lost", "energy_max_over_e0", "restitution", "momentum_drift"]),
}


def case_run(driver, problem, backend, cells, group, precision):
    """One run through fbar_study_cases; the JSON line it prints, or a failed row."""
    spec = CASES[problem]
    p = subprocess.run([driver, f"--problem={problem}", f"--engine={backend}", f"--precision={precision}",
                        f"--cells={cells}"] + spec["args"](group), capture_output=True, text=True)
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
    row = json.loads(lines[-1]) if lines else {"status": "failed"}
    row.update(backend=backend, cells=cells, precision=precision)
    row[spec["group"]] = group
    if p.returncode != 0 or row.get("status") != "ok":
        row["status"] = "failed"
        row["message"] = (p.stderr.strip().splitlines() or [""])[-1]
    else:
        row["s_per_simulated_s"] = row["wall_s"] / row["simulated_s"]
    return row


def case_charts(problem, rows, out, title_backend, suffix=""):
    import matplotlib
    import matplotlib.ticker
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spec = CASES[problem]
    key, err = spec["group"], spec["error"]
    if "reference" in spec:  # error against the sweep's finest run of the reference group in double precision
        group, quantity = spec["reference"]
        done = [r for r in rows if r["status"] == "ok"]
        ref = max((r for r in done if r[key] == group and r["precision"] == "double"), key=lambda r: float(r["cells"]))
        for r in done:
            r[err] = f"{abs(float(r[quantity]) / float(ref[quantity]) - 1):.6g}" if r is not ref else "0"
    ok = [r for r in rows if r["status"] == "ok" and float(r[err]) > 0]
    for r in ok:
        r["cells"] = float(r["cells"])
        r[key] = str(r[key])
    groups = [g for g in spec["groups"] if any(r[key] == g for r in ok)]
    pts = [(float(r["s_per_simulated_s"]), float(r[err])) for r in ok]
    colors = {spec["group_label"](g): c for g, c in zip(groups, ["C0", "C1", "C2", "C3"])}
    markers = {"double": "s", "mixed": "^", "single": "o"}
    fig, ax = plt.subplots(figsize=(8, 5.5))
    # The front's points at one resolution often differ by round-off in error: only the cheapest is labelled.
    draw_pareto(ax, ok, pts, lambda r: (spec["group_label"](r[key]), r["precision"], 10 + 0.3 * r["cells"]),
                lambda r: f"{spec['group_label'](r[key])}, {spec['res']} {r['cells']:g}, {r['precision']}", colors,
                markers, label_close=False)
    ax.set_xlabel(f"wall time per simulated second [s] ({title_backend})")
    ax.set_ylabel(spec["error_label"])
    ax.set_title(f"{spec['name']}: error against cost (marker size: {spec['res']})")
    ax.legend(fontsize=8)
    save(fig, out, f"{spec['prefix']}_pareto{suffix}.png")

    fig, ax = plt.subplots(figsize=(7, 5))
    styles = {"double": "-", "single": ":", "mixed": "--"}
    for g in groups:
        for prec, style in styles.items():
            rs = sorted((r for r in ok if r[key] == g and r["precision"] == prec), key=lambda r: r["cells"])
            if len(rs) < 2:
                continue
            n = [r["cells"] for r in rs]
            e = [float(r[err]) for r in rs]
            order = f", order {math.log(e[-2] / e[-1]) / math.log(n[-1] / n[-2]):.2f}" if len(rs) >= 3 else ""
            ax.plot(n, e, style, marker="o", color=colors[spec["group_label"](g)],
                    label=f"{spec['group_label'](g)} ({prec}{order})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ticks = sorted({r["cells"] for r in ok})
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xticks(ticks)
    ax.set_xticklabels([f"{t:g}" for t in ticks])
    ax.set_xlabel(spec["res_label"])
    ax.set_ylabel(spec["error_label"])
    ax.set_title(f"{spec['name']}: error against resolution (order between the two finest)")
    ax.legend(fontsize=6.5, ncol=2)
    ax.grid(True, which="both", alpha=0.3)
    save(fig, out, f"{spec['prefix']}_convergence{suffix}.png")


def case_study(a):
    spec = CASES[a.problem]
    backend = "gpu" if a.gpu else "cpu"
    suffix = "_gpu" if a.gpu else ""
    fields = (["backend", "cells", "dx", spec["group"], "precision", "status"] + spec["fields"] +
              ["wall_s", "s_per_simulated_s", "steps", "particles", "message"])
    csv_path = os.path.join(a.out, f"{spec['prefix']}_study{suffix}.csv")
    if a.replot:
        with open(csv_path) as f:
            rows = list(csv.DictReader(f))
        case_charts(a.problem, rows, a.out, f"{rows[0]['backend']} engine", suffix)
        return 0
    driver = a.driver or os.path.join(os.path.dirname(a.fbar), "fbar_study_cases")
    cells = a.cells or (spec["gpu_cells"] if a.gpu else spec["cells"])
    precisions = ("single", "double") if a.gpu else ("single", "double", "mixed")
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for n in cells:
        for g in spec["groups"]:
            for precision in precisions:
                r = case_run(driver, a.problem, backend, n, g, precision)
                rows.append(r)
                print(f"{backend} {spec['res']} {n:6g} {spec['group_label'](g):9s} {precision:6s} {r['status']:6s} "
                      f"error {r.get(spec['error'], '')!s:>12s} wall {r.get('wall_s', '')!s:>10s} s "
                      f"{r.get('message', '')}", flush=True)
                with open(csv_path, "w", newline="") as f:  # after every run: a cut-off sweep keeps its rows
                    w = csv.DictWriter(f, fieldnames=fields)
                    w.writeheader()
                    for done in rows:
                        w.writerow({k: done.get(k, "") for k in fields})
    case_charts(a.problem, rows, a.out, f"{backend} engine", suffix)
    return 0


STATE_COLORS = {"stable": "#4caf50", "detected": "#ff9800", "silent": "#d32f2f"}


def stability_maps(rows, out, title_backend, suffix=""):
    """The code-built stability maps (fbar_study_cases --problem=stability): one chart per map, rows the scheme (and
    F-bar for the Poisson map), columns the swept value, each cell stable / detected / silent."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    titles = {"cfl": ("CFL number (material.CFL)", "Splash with lone particles: the CFL number against the scheme"),
              "stiffness": ("c0 / front speed 2 sqrt(g a)", "Splash with lone particles: stiffness against the scheme"),
              "poisson": ("Poisson's ratio", "Bouncing elastic block: Poisson's ratio against scheme and F-bar")}
    for name, (xlabel, title) in titles.items():
        rs = [r for r in rows if r["map"] == name]
        if not rs:
            continue
        xs = sorted({float(r["x"]) for r in rs})
        keys = []
        for r in rs:
            k = r["scheme"] + (", F-bar" if float(r["fbar"]) else "") if name == "poisson" else r["scheme"]
            r["row"] = k
            if k not in keys:
                keys.append(k)
        fig, ax = plt.subplots(figsize=(1.2 * len(xs) + 2.5, 0.55 * len(keys) + 1.6))
        for i, k in enumerate(keys):
            for j, x in enumerate(xs):
                cell = [r for r in rs if r["row"] == k and float(r["x"]) == x]
                if not cell:
                    continue
                r = cell[0]
                ax.add_patch(plt.Rectangle((j, i), 0.95, 0.95, color=STATE_COLORS[r["state"]]))
                note = r["state"] if r["state"] != "stable" else f"{int(r['steps'])} steps"
                ax.text(j + 0.47, i + 0.47, note, ha="center", va="center", fontsize=6.5)
        ax.set_xlim(0, len(xs))
        ax.set_ylim(0, len(keys))
        ax.set_xticks([j + 0.47 for j in range(len(xs))], [f"{x:g}" for x in xs])
        ax.set_yticks([i + 0.47 for i in range(len(keys))], keys)
        ax.set_xlabel(xlabel)
        ax.set_title(f"{title} ({title_backend}, {rs[0]['precision']}): stable / detected / silent", fontsize=9)
        save(fig, out, f"stability_{name}{suffix}.png")


def stability_study(a):
    """fbar_study_cases --problem=stability on one engine: every map's runs, the CSV and the charts."""
    backend = "gpu" if a.gpu else "cpu"
    suffix = "_gpu" if a.gpu else ""
    csv_path = os.path.join(a.out, f"stability_maps{suffix}.csv")
    fields = ["engine", "precision", "map", "case", "scheme", "fbar", "x_name", "x", "state", "energy_gain", "steps",
              "particles", "wall_s", "simulated_s", "message"]
    if a.replot:
        with open(csv_path) as f:
            rows = list(csv.DictReader(f))
        stability_maps(rows, a.out, f"{rows[0]['engine']} engine", suffix)
        return 0
    driver = a.driver or os.path.join(os.path.dirname(a.fbar), "fbar_study_cases")
    precision = "single" if a.gpu else "double"
    p = subprocess.run([driver, "--problem=stability", f"--engine={backend}", f"--precision={precision}"],
                       capture_output=True, text=True)
    rows = [json.loads(ln) for ln in p.stdout.splitlines() if ln.startswith("{")]
    if p.returncode != 0 or not rows:
        print(p.stderr)
        return 1
    os.makedirs(a.out, exist_ok=True)
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in fields})
    for r in rows:
        print(f"{r['map']:9s} {r['scheme']:14s} F-bar {r['fbar']:g} {r['x_name']} {r['x']:<7g} {r['state']:8s} "
              f"gain {r['energy_gain']:+.3g} {r['steps']} steps {r['message']}")
    silent = [r for r in rows if r["state"] == "silent"]
    print(f"{len(rows)} runs, {len(silent)} silent")
    stability_maps(rows, a.out, f"{backend} engine", suffix)
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fbar", default=os.path.join(ROOT, "build", "release", "fbar"))
    ap.add_argument("--gpu", action="store_true", help="the GPU engine and larger sizes")
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "validation"))
    ap.add_argument("--work", default="/tmp/fbar_study")
    ap.add_argument("--cells", type=float, nargs="+",
                    help="cells per a (default 4 6 8 12 16 24, --gpu: 8 12 16 24 32 48); --problem bar: L/dx")
    ap.add_argument("--replot", action="store_true", help="draw the charts again from the CSV in --out, run nothing")
    ap.add_argument("--stability", action="store_true", help="the stability map (CFL number against scheme) only")
    ap.add_argument("--problem", choices=PROBLEMS + ["all"], default="dam_break",
                    help="one problem, or all: every problem in turn (and the dam break's stability map), which "
                         "regenerates every chart of docs/validation.md for the engine chosen")
    ap.add_argument("--driver", help="fbar_study_cases (default: beside --fbar)")
    a = ap.parse_args()
    if a.problem != "all":
        return run_problem(a)
    failed = []
    for problem in PROBLEMS:
        # (the dam break's stability map has no --replot: its chart is drawn as its runs end)
        for stability_map in ([False, True] if problem == "dam_break" and not a.replot else [False]):
            one = argparse.Namespace(**vars(a))
            one.problem, one.stability, one.cells = problem, stability_map, None
            print(f"== {problem}{' (stability map)' if stability_map else ''}{' --gpu' if a.gpu else ''}", flush=True)
            try:
                if run_problem(one):
                    failed.append(problem)
            except FileNotFoundError as e:  # --replot of a study this engine has no CSV of (granular: GPU only)
                if not a.replot:
                    raise
                print(f"   skipped: {e.filename} not found", flush=True)
    if failed:
        print("failed: " + ", ".join(failed))
    return 1 if failed else 0


PROBLEMS = ["dam_break", "dam_break_ppc", "bar", "hydrostatic", "granular", "disks", "wall_pressure", "stability",
            "translation"]


def ppc_study(a):
    """The dam break of --problem dam_break swept over particles per cell (1, 8, 27) and resolution, APIC in single
    precision, against the same reference as that study (its finest APIC double run at 8 ppc, run here again)."""
    backend = "gpu" if a.gpu else "cpu"
    suffix = "_gpu" if a.gpu else ""
    csv_path = os.path.join(a.out, f"dam_break_ppc_study{suffix}.csv")
    fields = ["backend", "cells_per_a", "ppc", "scheme", "precision", "status", "reference", "error",
              "error_vs_experiment", "wall_s", "s_per_simulated_s", "steps", "particles", "message"]
    if a.replot:
        with open(csv_path) as f:
            rows = list(csv.DictReader(f))
    else:
        cells = [int(c) for c in a.cells] if a.cells else ([16, 32, 48] if a.gpu else [8, 16, 24])
        os.makedirs(a.out, exist_ok=True)
        rows = [run(a.fbar, backend, max(cells), "APIC", "double", a.work)]
        for n in cells:
            for ppc in (1, 8, 27):
                r = run(a.fbar, backend, n, "APIC", "single", a.work, ppc=ppc)
                rows.append(r)
                print(f"{backend} {n:3d}/a ppc {ppc:2d} {r['status']:6s} wall {r['wall_s']:>8s} s {r['message']}",
                      flush=True)
        against_reference(rows)
        with open(csv_path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=fields)
            w.writeheader()
            for r in rows:
                w.writerow({k: r.get(k, "") for k in fields})
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ref = next(r for r in rows if r["reference"])
    # The reference's configuration in single precision differs from it by round-off only: left out.
    ok = [r for r in rows if r["status"] == "ok" and r["error"] != "" and not r["reference"] and
          not (int(r["ppc"]) == 8 and int(r["cells_per_a"]) == int(ref["cells_per_a"]))]
    colors = {"1 ppc": "C0", "8 ppc": "C1", "27 ppc": "C2"}
    label = f"mean |T - T_ref| at the gauges (ref: APIC, double, {ref['cells_per_a']}/a, 8 ppc)"
    fig, ax = plt.subplots(figsize=(7, 4.5))
    pts = [(float(r["s_per_simulated_s"]), float(r["error"])) for r in ok]
    draw_pareto(ax, ok, pts, lambda r: (f"{int(r['ppc'])} ppc", "APIC single", 10 + 0.6 * int(r["cells_per_a"])),
                lambda r: f"{int(r['ppc'])} ppc, {r['cells_per_a']}/a", colors, {"APIC single": "o"})
    ax.set_xlabel(f"wall time per simulated second [s] ({rows[0]['backend']} engine)")
    ax.set_ylabel(label, fontsize=8)
    ax.set_title("Dam break: particles per cell (marker size: cells per a)")
    ax.legend(fontsize=8)
    save(fig, a.out, f"dam_break_ppc_pareto{suffix}.png")
    return 0


def run_problem(a):
    if a.problem == "dam_break_ppc":
        return ppc_study(a)
    if a.problem == "stability":
        return stability_study(a)
    if a.problem == "translation":
        import translation  # tools/study/translation.py
        return translation.study(a, draw_pareto, save)
    if a.problem == "wall_pressure":
        import wall_pressure  # tools/study/wall_pressure.py
        return wall_pressure.study(a, draw_pareto, save)
    if a.problem in CASES:
        return case_study(a)
    suffix = "_gpu" if a.gpu else ""  # the CPU study's files are dam_break_*.{csv,png}, the GPU's dam_break_*_gpu.*
    if a.stability:
        os.makedirs(a.out, exist_ok=True)
        stability(a.fbar, "gpu" if a.gpu else "cpu", a.work, a.out, suffix)
        return 0
    if a.replot:
        with open(os.path.join(a.out, f"dam_break_study{suffix}.csv")) as f:
            rows = list(csv.DictReader(f))
        charts(rows, a.out, f"{rows[0]['backend']} engine", suffix)
        return 0
    backend = "gpu" if a.gpu else "cpu"
    cells = [int(c) for c in a.cells] if a.cells else ([8, 12, 16, 24, 32, 48] if a.gpu else [4, 6, 8, 12, 16, 24])
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for n in cells:
        for scheme in SCHEMES:
            for precision in ("single", "double"):
                r = run(a.fbar, backend, n, scheme, precision, a.work)
                rows.append(r)
                print(f"{backend} {n:3d}/a {scheme:14s} {precision:6s} {r['status']:6s} "
                      f"vs data {r['error_vs_experiment']:>8s} within bounds {r['gauges_within_bounds']:>6s} "
                      f"wall {r['wall_s']:>8s} s {r['message']}", flush=True)
    ref = against_reference(rows)
    print(f"reference: {ref['scheme']}, {ref['precision']}, {ref['cells_per_a']}/a")
    for r in rows:
        print(f"  {r['cells_per_a']:3d}/a {r['scheme']:14s} {r['precision']:6s} error {r['error']:>8s} "
              f"{'(reference)' if r['reference'] else ''}")
    fields = ["backend", "cells_per_a", "scheme", "precision", "status", "reference", "error", "error_vs_experiment",
              "gauges_within_bounds", "wall_s", "s_per_simulated_s", "steps", "particles", "message"]
    with open(os.path.join(a.out, f"dam_break_study{suffix}.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in fields})
    charts(rows, a.out, f"{backend} engine", suffix)
    return 0


if __name__ == "__main__":
    sys.exit(main())
