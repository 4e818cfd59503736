#!/usr/bin/env python3
"""A packed sweep's throughput against one large run on the same GPU (docs/benchmarks/*-sweep-throughput.md).

    python3 tools/benchmark/sweep_throughput.py FBAR WORKDIR [--cases 64] [--jobs 4,8,15] [--steps-time 0.05]

Writes a water-column scene (JFluid dam break in a tank, one floor load cell, one frame at the end) in two sizes:
a case of about 250k particles (dx = 1 cm) and one run of about 16M (dx = 2.5 mm, the same tank 4x finer), and
runs, one after the other on the same GPU:
  * the 16M run alone (fbar --file), the reference, and the same as a sweep of one case;
  * the sweep of --cases cases (each the 250k scene with another column position, density and bulk modulus:
    the same particle count) one case at a time (--jobs=1) and packed (--jobs=N for each N given).
Particle-steps per second = sum over runs of particles x steps / the whole command's wall time (set-up, sampling
and the frame included, for the sweep as for the large run). Prints a table and writes WORKDIR/throughput.csv.
"""
import argparse
import csv
import itertools
import json
import os
import re
import shutil
import subprocess
import sys
import time


def scene(dx, duration):
    # A 0.56 x 0.28 x 0.20 m column in a 1.28 x 0.48 x 0.32 m tank: 0.031 m^3, 250,880 particles at dx = 1 cm, 8 ppc.
    return {
        "simulation": {"domain": [1.32, 0.52, 0.36], "default_dx": dx, "fps": 1.0 / duration, "frames": 1,
                       "save_suffix": ".bgeo"},
        "bodies": [{
            "material": {"constitutive": "JFluid", "ppc": 8, "CFL": 0.5, "rho": 1000, "bulk_modulus": 2e6,
                         "gamma": 7.1, "viscosity": 0.001},
            "algorithm": {"use_ASFLIP": False, "use_FBAR": False},
            "geometry": [{"object": "Box", "span": [0.56, 0.28, 0.20], "offset": [0.04, 0.04, 0.06]}],
            "output_attribs": ["ID"],
        }],
        "boundaries": [{"object": "Walls", "contact": "Separable", "domain_start": [0.02, 0.02, 0.02],
                        "domain_end": [1.30, 0.50, 0.34]}],
        "grid-sensors": [{"attribute": "Force", "operation": "Sum", "direction": "X+", "output_frequency": 1000,
                          "domain_start": [1.26, 0, 0], "domain_end": [1.32, 0.52, 0.36]}],
    }


def run(cmd, what):
    """The command's wall time [s]; its output is printed when it fails (completed_steps then says which case)."""
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        print(f"{what}: exit {p.returncode}\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}", flush=True)
    return wall


def completed_steps(run_dir, what):
    """The steps of the run whose run.json is in run_dir; exits when it did not complete (no figure then)."""
    with open(os.path.join(run_dir, "run.json")) as f:
        r = json.load(f)
    if r["status"] != "completed":
        sys.exit(f"{what} did not complete ({r['status']}): the figures would not mean anything")
    return r["steps"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("fbar")
    ap.add_argument("work")
    ap.add_argument("--cases", type=int, default=64)
    ap.add_argument("--jobs", default="4,8,15")
    ap.add_argument("--duration", type=float, default=0.25, help="simulated time of a case [s]")
    ap.add_argument("--skip-alone", action="store_true", help="no one-at-a-time sweep")
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    with open(os.path.join(a.work, "case.json"), "w") as f:
        json.dump(scene(0.01, a.duration), f)
    # The large run: 4x finer, so a quarter of the simulated time takes about as many steps per cell crossed.
    with open(os.path.join(a.work, "large.json"), "w") as f:
        json.dump(scene(0.0025, a.duration / 4), f)
    # Cases of one size: 4 column positions x 4 densities x 4 bulk moduli (the first --cases of them).
    values = {"x": [0.04, 0.08, 0.12, 0.16], "rho": [900, 1000, 1100, 1200], "K": [1e6, 2e6, 3e6, 4e6]}
    combos = list(itertools.product(*values.values()))[: a.cases]
    sweep = {"scene": "case.json", "design": "cases", "parameters": [
        {"name": "x", "path": "bodies[0].geometry[0].offset[0]"},
        {"name": "rho", "path": "bodies[0].material.rho"},
        {"name": "K", "path": "bodies[0].material.bulk_modulus"}],
        "cases": [dict(zip(values, c)) for c in combos]}
    with open(os.path.join(a.work, "s.sweep.json"), "w") as f:
        json.dump(sweep, f)

    # The large run as a sweep of one case: the same command path, and its plan's particle count.
    with open(os.path.join(a.work, "large.sweep.json"), "w") as f:
        json.dump({"scene": "large.json", "design": "cases", "parameters": [
            {"name": "rho", "path": "bodies[0].material.rho"}], "cases": [{"rho": 1000}]}, f)
    rows = []
    # The reference: the large scene through `fbar --file`, the path a single run takes (its particle count from
    # --check, which counts them as the engine samples them).
    check = subprocess.run([a.fbar, "--check", os.path.join(a.work, "large.json")], capture_output=True, text=True)
    m = re.search(r"particles\s+(\d+) in \d+ body", check.stdout)
    if not m:
        sys.exit("fbar --check large.json printed no particle count:\n" + check.stdout[-2000:])
    out = os.path.join(a.work, "large_out")
    wall = run([a.fbar, "--backend=gpu", "--quiet", f"--output={out}", os.path.join(a.work, "large.json")], "large")
    steps = completed_steps(out, "the large run")
    rows.append(("one run (--file)", 1, int(m.group(1)), steps, wall, int(m.group(1)) * steps / wall))
    runs = [("one run (--sweep)", "large.sweep.json", 1)]
    runs += [(f"sweep, {len(combos)} cases", "s.sweep.json", j) for j in ([] if a.skip_alone else [1])]
    runs += [(f"sweep, {len(combos)} cases", "s.sweep.json", int(j)) for j in a.jobs.split(",") if j]
    for name, file, j in runs:
        folder = os.path.join(a.work, f"{file.split('.')[0]}_jobs{j}")
        wall = run([a.fbar, f"--sweep={os.path.join(a.work, file)}", "--backend=gpu", f"--jobs={j}",
                    f"--output={folder}"], f"{file} --jobs={j}")
        with open(os.path.join(folder, "sweep_plan.csv"), newline="") as f:
            plan = list(csv.DictReader(f))
        total = steps_sum = 0
        for k, row in enumerate(plan):
            s = completed_steps(os.path.join(folder, f"case_{k:04d}"), f"{file} --jobs={j}: case {k}")
            total += int(row["particles"]) * s
            steps_sum += s
        rows.append((name, j, int(plan[0]["particles"]), steps_sum // len(plan), wall, total / wall))
    reference = rows[0][-1]
    with open(os.path.join(a.work, "throughput.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["run", "jobs", "particles per run", "steps per run", "wall [s]", "particle-steps/s",
                    "of one run"])
        for r in rows:
            w.writerow(list(r) + [r[-1] / reference])
    print(f"{'run':<22}{'jobs':>5}{'particles':>12}{'steps':>8}{'wall [s]':>10}{'p-steps/s':>12}{'of one run':>12}")
    for r in rows:
        print(f"{r[0]:<22}{r[1]:>5}{r[2]:>12,}{r[3]:>8}{r[4]:>10.2f}{r[5]:>12.3e}{r[5] / reference:>12.2f}")


if __name__ == "__main__":
    main()
