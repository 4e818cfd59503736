#!/usr/bin/env python3
"""A scene that places bodies on GPUs (bodies[].gpu) on several ranks against one rank, on either engine.

usage: mpi_placement_test.py FBAR MPIEXEC SCENE WORKDIR SPREAD_MODELS [--engine=cpu|gpu]

SCENE is tests/scenes/good/placed_bodies.json: a body on gpu 0 and one on gpu 1 (both model 0), and SPREAD_MODELS
(comma-separated model ids) whose bodies have "gpu": "all". One rank writes model[m]_dev[gpu] for every body; on N
ranks a placed body is written by its own rank only (the same name) and a spread body by every rank
(model[m]_dev[rank]).
- cpu (default): `mpirun -np 2|3 fbar --backend=cpu`; states agree with one rank's to 1e-12 (double precision).
- gpu: `fbar --backend=gpu --gpus=2|3` (threads; ranks beyond the visible GPUs share them) and, with two GPUs and a
  launcher, `mpirun -np 2`; states and sensors bit for bit (the order-free sums). Exit 77 (skipped) without a CUDA
  device.
Checks the file names, that every particle of each body is there once, the states, and the sensor CSVs (reduced
over the ranks, each node counted once) to 1e-8 of each column's largest value.
"""
import glob
import json
import os
import re
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import frames_by_id  # noqa: E402

fbar, mpiexec, scene, work, spread_arg = sys.argv[1:6]
engine = "cpu"
for arg in sys.argv[6:]:
    if arg.startswith("--engine="):
        engine = arg.split("=", 1)[1]
spread = {int(m) for m in spread_arg.split(",") if m}
gpus = frames_by_id.visible_gpus_or_skip() if engine == "gpu" else 0
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
env = dict(os.environ, OMP_NUM_THREADS="1", OMP_WAIT_POLICY="PASSIVE", NCCL_NVLS_ENABLE="0")
name = re.compile(r"model\[(\d+)\]_dev\[(\d+)\]_frame\[(\d+)\]\.csv$")


def run(label, ranks, mpi):
    out = os.path.join(work, label)
    cmd = [fbar, f"--backend={engine}", "--quiet", f"--output={out}", scene]
    if engine == "gpu" and not mpi:
        cmd += [f"--gpus={ranks}", "--keep-gpus"]  # placing scenes keep their ranks anyway
    if mpi:
        cmd = [mpiexec, "-np", str(ranks), "--oversubscribe", "--allow-run-as-root", "-x", "NCCL_NVLS_ENABLE"] + cmd
    p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        sys.exit(f"{label}: exit {p.returncode}\n{p.stdout}\n{p.stderr}")
    with open(os.path.join(out, "run.json")) as f:
        meta = json.load(f)
    assert meta["status"] == "completed" and meta["ranks"] == ranks, meta
    frame = meta["frames_written"]
    bodies, files = {}, []
    for path in glob.glob(os.path.join(glob.escape(out), "model*_frame*.csv")):
        m = name.search(os.path.basename(path))
        if not m or int(m.group(3)) != frame:
            continue
        model, dev = int(m.group(1)), int(m.group(2))
        files.append((model, dev))
        key = ("spread", model) if model in spread else ("placed", model, dev)
        frames_by_id.read_frame(path, bodies.setdefault(key, {}), f"{label} {key}")
    return meta["steps"], sorted(files), bodies, frames_by_id.read_sensors(out)


steps1, files1, one, sensors1 = run("ranks1", 1, False)
cases = [("ranks2", 2, engine == "cpu"), ("ranks3", 3, engine == "cpu")]
if engine == "gpu" and gpus >= 2 and mpiexec:
    cases.append(("mpi2", 2, True))
# The GPU engine's order-free sums give one rank's bits on any rank count; the CPU engine sums in another order.
tol_x, tol_v, tol_sensor = (1e-12, 1e-12, 1e-8) if engine == "cpu" else (0.0, 0.0, 0.0)
for label, n, mpi in cases:
    steps, files, many, sensors = run(label, n, mpi)
    assert steps == steps1, f"{label}: {steps} steps, one rank {steps1}"
    expected = sorted([f for f in files1 if f[0] not in spread] + [(m, r) for m in spread for r in range(n)])
    assert files == expected, f"{label}: frame files {files}, expected {expected}"
    assert many.keys() == one.keys(), f"{label}: bodies {sorted(many)} against {sorted(one)}"
    dx = dv = 0.0
    for key, particles in one.items():
        assert many[key].keys() == particles.keys(), f"{label}: {key} has other particles"
        for pid, state in particles.items():
            dx = frames_by_id.nan_max([dx] + [abs(a - b) for a, b in zip(many[key][pid][:3], state[:3])])
            dv = frames_by_id.nan_max([dv] + [abs(a - b) for a, b in zip(many[key][pid][3:], state[3:])])
    worst, where = frames_by_id.max_sensor_difference(sensors, sensors1, label)
    print(f"{label}: files {files}, {sum(len(b) for b in many.values())} particles, {steps} steps, max |dx| {dx:.3g} m, "
          f"max |dv| {dv:.3g} m/s, sensors {worst:.3g} ({where})")
    assert dx <= tol_x and dv <= tol_v, "states differ"  # False for NaN too
    assert worst <= tol_sensor, "sensor values differ"
print("ok")
