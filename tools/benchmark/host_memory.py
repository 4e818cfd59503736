#!/usr/bin/env python3
"""Peak host memory of GPU runs against what `fbar --check` plans ("host memory (run)").

Usage: host_memory.py FBAR WORKDIR CASE [CASE ...]
  CASE = <millions of particles>:<full|exterior>[:checkpoint], e.g. 150:full 150:exterior:checkpoint 1000:exterior

Each case is a JFluid box (single precision, dx = 1/512 m, 8 particles per cell, the particle count chosen by the
box's height) run for one frame of 50 steps: frames 0 and 1 written as .bgeo (every particle, or the exterior shell),
and with `checkpoint` a checkpoint at each frame. The peak resident memory of the run (the child's ru_maxrss) is
compared with --check's plan; the output folder is removed after each case. Prints a table row as each case ends.
"""
import json
import os
import re
import shutil
import subprocess
import sys
import time

DX = 1.0 / 512


def scene(millions, exterior, checkpoint, out):
    cells = millions * 1e6 / 8
    side = 500 if millions > 400 else 256  # cells per horizontal side
    height = max(1, round(cells / (side * side)))
    return {
        "simulation": {
            "domain": [2.0, 2.0, 2.0], "default_dx": DX, "default_dt": 5e-6, "gravity": [0, -9.8, 0],
            "fps": 4000, "frames": 1, "save_path": out, "save_suffix": ".bgeo", "precision": "single",
            "particles_output_exterior_only": exterior, "checkpoint_every": 1 if checkpoint else 0,
        },
        "bodies": [{
            "gpu": 0, "model": 0,
            "material": {"constitutive": "JFluid", "ppc": 8, "CFL": 0.5, "rho": 1000, "bulk_modulus": 4e4,
                         "gamma": 7.15, "viscosity": 0.01},
            "algorithm": {"type": "particles", "use_ASFLIP": False, "use_FBAR": False},
            "geometry": [{"object": "Box", "operation": "Add", "span": [side * DX, height * DX, side * DX],
                          "offset": [0.1, 0.1, 0.1]}],
            "velocity": [0, -1, 0], "output_attribs": ["ID", "Pressure"],
        }],
        "boundaries": [{"object": "Walls", "contact": "Separable", "domain_start": [0, 0, 0],
                        "domain_end": [2, 2, 2]}],
    }


def gib(text):
    m = re.match(r"([0-9.]+) (B|KiB|MiB|GiB|TiB)", text)
    scale = {"B": 0, "KiB": 1, "MiB": 2, "GiB": 3, "TiB": 4}[m.group(2)]
    return float(m.group(1)) * 1024 ** scale / 2 ** 30


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    fbar, work = sys.argv[1], sys.argv[2]
    os.makedirs(work, exist_ok=True)
    print(f"{'case':24} {'particles':>12} {'--check GiB':>12} {'peak GiB':>10} {'peak/plan':>9} {'wall s':>8} rc",
          flush=True)
    for case in sys.argv[3:]:
        parts = case.split(":")
        millions, exterior, checkpoint = float(parts[0]), parts[1] == "exterior", "checkpoint" in parts[2:]
        out = os.path.join(work, "out")
        path = os.path.join(work, "scene.json")
        with open(path, "w") as f:
            json.dump(scene(millions, exterior, checkpoint, out), f)
        check = subprocess.run([fbar, "--check", path], capture_output=True, text=True)
        planned = re.search(r"host memory \(run\)\s+([0-9.]+ \w+)", check.stdout)
        particles = re.search(r"particles\s+(\d+) in", check.stdout)
        # A fresh interpreter per run: its only child is the run, so its children's ru_maxrss is the run's peak.
        # It also samples the run's resident memory every 0.2 s: the time of the peak tells the phase (set-up,
        # steps, frames) that holds it.
        probe = ("import resource, subprocess, sys, time\n"
                 "p = subprocess.Popen(sys.argv[1:], stderr=subprocess.PIPE, text=True); t0 = time.time(); top = (0, 0)\n"
                 "while p.poll() is None:\n"
                 "    try:\n"
                 "        kb = int([l for l in open('/proc/%d/status' % p.pid) if l.startswith('VmRSS')][0].split()[1])\n"
                 "        top = max(top, (kb, time.time() - t0))\n"
                 "    except Exception: pass\n"
                 "    time.sleep(0.2)\n"
                 "sys.stderr.write(p.stderr.read()); t = time.time() - t0\n"
                 "print('peak at %.1f of %.1f s' % (top[1], t)); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
                 "sys.exit(p.returncode)")
        t0 = time.time()
        run = subprocess.run([sys.executable, "-c", probe, fbar, "--quiet", "--file", path], capture_output=True,
                             text=True)
        wall = time.time() - t0
        peak = int(run.stdout.split()[-1]) / 2 ** 20 if run.stdout.split() else float("nan")  # KiB -> GiB
        n = int(particles.group(1)) if particles else -1
        plan = gib(planned.group(1)) if planned else float("nan")
        err = (run.stderr.strip().splitlines() or [""])[-1][:80] if run.returncode else ""
        when = next((l for l in run.stdout.splitlines() if l.startswith("peak at")), "")
        print(f"{case:24} {n:12d} {plan:12.2f} {peak:10.2f} {peak / plan:9.2f} {wall:8.1f} {run.returncode} {when} {err}",
              flush=True)
        shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    main()
