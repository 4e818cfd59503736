#!/usr/bin/env python3
"""Output overhead of the GPU engine: a run writing frames every 100 steps against the same steps
writing only the last frame.

Scene: scenes/dam_break_3d.json at a finer default_dx (0.00225: 16M JFluid particles, single precision), sensors
removed, output_attribs ID, Velocity_Magnitude, Pressure, J, .bgeo. A probe run measures the CFL dt at rest; then
  every100  fps = 1 / (100 dt), `frames` frames (a frame every 100 steps; --every N: every N steps),
  end       fps = 1 / (100 dt frames), one frame (the same steps, one frame at the end).
Both also write frame 0. Printed per variant: steps, ms/step of the last progress line (the step loop, setup
excluded), the step loop's wait for the writer, and wall time of the whole command; overhead = every100 / end - 1
of ms/step (the target is 0.05).

usage: output_overhead.py [--fbar build/release/fbar] [--dx 0.00225] [--frames 8] [--every 100] [--target DIR]...
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def scene(dx, fps, frames, save):
    with open(os.path.join(ROOT, "scenes", "dam_break_3d.json")) as f:
        s = json.load(f)
    s.pop("grid-sensors", None)
    s.pop("particle-sensors", None)
    s["simulation"].update({"default_dx": dx, "fps": fps, "frames": frames, "save_path": save})
    s["bodies"][0]["output_attribs"] = ["ID", "Velocity_Magnitude", "Pressure", "J"]
    return s


def run(fbar, s, out, label):
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    path = os.path.join(out, "scene.json")
    with open(path, "w") as f:
        json.dump(s, f)
    t0 = time.time()
    p = subprocess.run([fbar, "--backend=gpu", "--output=" + out, path], capture_output=True, text=True)
    wall = time.time() - t0
    log = p.stdout + p.stderr
    with open(out + ".log", "w") as f:
        f.write(log)
    if p.returncode != 0:
        sys.exit(f"{label}: fbar exited {p.returncode}\n{log[-3000:]}")
    lines = [l for l in log.splitlines() if "ms/step" in l]
    last = lines[-1]
    ms = float(re.search(r"([0-9.eE+-]+) ms/step", last).group(1))
    wait = float(re.search(r"output wait ([0-9.eE+-]+) s", last).group(1))
    steps = int(re.search(r"steps = (\d+)", last).group(1))
    dt = float(re.search(r"dt = ([0-9.eE+-]+) s", last).group(1))
    with open(os.path.join(out, "run.json")) as f:
        meta = json.load(f)
    size = sum(os.path.getsize(os.path.join(out, n)) for n in os.listdir(out) if n.endswith(".bgeo"))
    return {"label": label, "steps": steps, "ms": ms, "wait": wait, "wall": wall, "dt": dt,
            "run_wall": meta["wall_time_s"], "bytes": size}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fbar", default=os.path.join(ROOT, "build", "release", "fbar"))
    ap.add_argument("--dx", type=float, default=0.00225)
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--every", type=int, default=100, help="steps between two frames")
    ap.add_argument("--target", action="append", default=None, help="output folder (repeat for several)")
    a = ap.parse_args()
    targets = a.target or ["/tmp/fbar_output_bench"]
    probe = run(a.fbar, scene(a.dx, 1.0 / (20 * 1e-5), 1, targets[0]), targets[0] + "_probe", "probe")
    dt = probe["dt"]
    print(f"probe: dt at rest {dt:.4g} s", flush=True)
    rows = []
    for target in targets:
        label = f"every{a.every}"
        end = run(a.fbar, scene(a.dx, 1.0 / (a.every * dt * a.frames), 1, target), target + "_end", "end")
        every = run(a.fbar, scene(a.dx, 1.0 / (a.every * dt), a.frames, target), target + "_" + label, label)
        rows.append((target, end, every))
    print("| target | variant | steps | ms/step | output wait [s] | wall [s] | frame bytes |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
    for target, end, every in rows:
        for r in (end, every):
            print(f"| {target} | {r['label']} | {r['steps']} | {r['ms']:.3f} | {r['wait']:.3f} | {r['wall']:.2f} | "
                  f"{r['bytes'] / 1e9:.2f} GB |")
    for target, end, every in rows:
        print(f"{target}: overhead {every['label']} vs end: {every['ms'] / end['ms'] - 1:+.3f} (ms/step)")


if __name__ == "__main__":
    main()
