#!/usr/bin/env python3
"""fbar --sweep through the command line (ctest Cli.SweepSharesAndPlots), on the CPU engine:

  * a Latin-hypercube sweep of 6 cases runs (exit 0) and tools/plot/plot_sweep.py draws a sensor across the cases
    and a summary against a parameter (PNG files that are PNGs), and --list names the sensors;
  * a factorial sweep of 4 cases run as a Slurm job array of 2 tasks (SLURM_ARRAY_TASK_ID / _COUNT): each task runs
    its two cases and gathers nothing; `--gather` afterwards writes the table of all four, byte for byte the table of
    the same sweep run in one go;
  * the same sweep under `mpirun -np 2` (when MPIEXEC is given): each rank runs its cases, rank 0 gathers, the same
    bytes again.

usage: sweep_tools_test.py FBAR WORKDIR [MPIEXEC]. Exit 77 (skipped, with the reason) without matplotlib.
"""
import json
import os
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
PLOT = os.path.join(HERE, "..", "..", "tools", "plot", "plot_sweep.py")
try:
    import matplotlib  # noqa: F401
except ImportError as e:
    print(f"skipped: {e} (pip install -r tools/plot/requirements.txt)")
    sys.exit(77)

fbar, work = sys.argv[1], sys.argv[2]
mpiexec = sys.argv[3] if len(sys.argv) > 3 else ""
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
env = dict(os.environ, OMP_NUM_THREADS="1", OMP_WAIT_POLICY="PASSIVE")
for k in ("SLURM_ARRAY_TASK_ID", "SLURM_ARRAY_TASK_COUNT", "SLURM_ARRAY_TASK_MIN", "SLURM_ARRAY_TASK_STEP"):
    env.pop(k, None)

base = {
    "simulation": {"domain": [0.4, 0.4, 0.4], "default_dx": 0.05, "default_dt": 1e-3, "fps": 100, "frames": 2,
                   "save_suffix": ".csv"},
    "bodies": [{
        "material": {"constitutive": "JFluid", "rho": 1000, "bulk_modulus": 2e5, "viscosity": 0.001},
        "algorithm": {"use_ASFLIP": False, "use_FBAR": False},
        "geometry": [{"object": "Box", "span": [0.1, 0.1, 0.1], "offset": [0.15, 0.1, 0.15]}],
        "output_attribs": ["ID"],
    }],
    "boundaries": [{"object": "Walls", "contact": "Separable", "domain_start": [0.05, 0.05, 0.05],
                    "domain_end": [0.35, 0.35, 0.35]}],
    "grid-sensors": [{"attribute": "Force", "operation": "Sum", "direction": "Y-", "output_frequency": 500,
                      "domain_start": [0, 0, 0], "domain_end": [0.4, 0.08, 0.4]}],
}
with open(os.path.join(work, "base.json"), "w") as f:
    json.dump(base, f)


def write_sweep(name, design):
    path = os.path.join(work, name + ".sweep.json")
    with open(path, "w") as f:
        json.dump(dict({"scene": "base.json", "output": name}, **design), f)
    return path


def fbar_run(args, extra_env=None, launcher=()):
    p = subprocess.run(list(launcher) + [fbar, "--backend=cpu"] + args, env=dict(env, **(extra_env or {})),
                       capture_output=True, text=True, timeout=600)
    return p


def must(p, what):
    if p.returncode != 0:
        sys.exit(f"{what}: exit {p.returncode}\n{p.stdout}\n{p.stderr}")
    return p


def is_png(path):
    with open(path, "rb") as f:
        return f.read(8) == b"\x89PNG\r\n\x1a\n"


def read(path):
    with open(path, "rb") as f:
        return f.read()


# 1. A sampled sweep and its plots.
lhs = write_sweep("lhs", {"design": "latin_hypercube", "samples": 6, "seed": 3, "parameters": [
    {"name": "rho", "path": "bodies[0].material.rho", "uniform": [900, 1200]},
    {"name": "K", "path": "bodies[0].material.bulk_modulus", "log_uniform": [1e5, 1e6]}]})
must(fbar_run([f"--sweep={lhs}", "--quiet"]), "latin hypercube sweep")
lhs_dir = os.path.join(work, "lhs")
cases = read(os.path.join(lhs_dir, "sweep_cases.csv")).decode().splitlines()
if len(cases) != 7 or any(",completed," not in c for c in cases[1:]):
    sys.exit("sweep_cases.csv:\n" + "\n".join(cases))
listed = must(subprocess.run([sys.executable, PLOT, lhs_dir, "--list"], capture_output=True, text=True), "--list")
if "gridTarget[0]_dev[0]: Force [N]" not in listed.stdout or "parameters: rho, K" not in listed.stdout:
    sys.exit("plot_sweep --list:\n" + listed.stdout)
pngs = []
for args in (["--sensor", "gridTarget[0]", "--color-by", "rho"],
             ["--sensor", "gridTarget[0]", "--against", "rho", "--statistic", "mean"]):
    p = must(subprocess.run([sys.executable, PLOT, lhs_dir] + args, capture_output=True, text=True),
             "plot_sweep " + " ".join(args))
    pngs.append(p.stdout.strip())
for png in pngs:
    if not os.path.isfile(png) or not is_png(png):
        sys.exit(f"plot_sweep did not write a PNG: {png}")
# The summary the second plot drew: one row per case, every one with samples and a finite, non-zero mean.
summary = [line.split(",") for line in read(os.path.join(lhs_dir, "sweep_summary.csv")).decode().splitlines()[1:]]
if len(summary) != 6 or not all(int(r[5]) > 0 and r[8] not in ("nan", "0") for r in summary):
    sys.exit(f"sweep_summary.csv: {summary}")

# 2. One go, a Slurm job array of two tasks, then --gather: the same table.
factorial = {"parameters": [{"name": "rho", "path": "bodies[0].material.rho", "values": [1000, 1100]},
                            {"name": "x", "path": "bodies[0].geometry[0].offset[0]", "range": [0.12, 0.18],
                             "count": 2}]}
whole = write_sweep("whole", factorial)
must(fbar_run([f"--sweep={whole}", "--quiet"]), "factorial sweep")
reference = read(os.path.join(work, "whole", "sweep_table.csv"))
array = write_sweep("array", factorial)
for task in (0, 1):
    p = must(fbar_run([f"--sweep={array}"], {"SLURM_ARRAY_TASK_ID": str(task), "SLURM_ARRAY_TASK_COUNT": "2"}),
             f"array task {task}")
    if "2 cases to run (Slurm array task %d of 2)" % task not in p.stdout or "--gather" not in p.stdout:
        sys.exit(f"array task {task}:\n{p.stdout}")
    if os.path.exists(os.path.join(work, "array", "sweep_table.csv")):
        sys.exit(f"array task {task} gathered before every task ended")
must(fbar_run([f"--sweep={array}", "--gather"]), "--gather")
if read(os.path.join(work, "array", "sweep_table.csv")) != reference:
    sys.exit("the job array's gathered table differs from the sweep run in one go")

# 3. Two MPI ranks: each runs its cases, rank 0 gathers.
if mpiexec:
    ranks = write_sweep("ranks", factorial)
    must(fbar_run([f"--sweep={ranks}", "--quiet"], launcher=(mpiexec, "-np", "2", "--oversubscribe",
                                                              "--allow-run-as-root")), "mpirun -np 2")
    if read(os.path.join(work, "ranks", "sweep_table.csv")) != reference:
        sys.exit("the two ranks' table differs from the sweep run in one go")
print("ok")
